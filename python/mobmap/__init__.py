"""Mobility maps for legged robots (Genesio et al.): build a map as `mobmap build` does,
open one, ask it about points and soles in numpy, plan footsteps, or map while you query
(LiveMapper)."""

from ._mobmap import (  # noqa: F401
    FREE,
    SURFACE,
    UNKNOWN,
    LiveMapper,
    Map,
    MapIoError,
    PlanInputError,
    Recording,
    RecordingError,
    analyze,
    build,
    open_map,
    open_recording,
    plan,
    reachable,
)

__all__ = ["build", "open_map", "Map", "plan", "reachable", "LiveMapper", "analyze", "open_recording", "Recording",
           "MapIoError", "PlanInputError", "RecordingError",
           "UNKNOWN", "FREE", "SURFACE"]
