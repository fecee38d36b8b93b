"""Reading depth frames in Python with numpy alone: 16-bit depth PNGs and the 7-Scenes
layout that `mobmap simulate` writes (frame-NNNNNN.depth.png + .pose.txt,
camera-intrinsics.txt, gravity-direction.txt)."""

import struct
import zlib
from pathlib import Path

import numpy as np


def read_depth_png(path):
    """A 16-bit greyscale PNG (millimetres, as Kinect and 7-Scenes store depth) as a (H, W)
    uint16 array, ready for LiveMapper.push and analyze. ValueError for other PNGs."""
    data = Path(path).read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG file")
    pos, idat, width, height = 8, [], 0, 0
    while pos + 8 <= len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, bits, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (bits, colour, interlace) != (16, 0, 0):
                raise ValueError(f"{path}: not a 16-bit greyscale PNG without interlacing")
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + length
    try:
        raw = np.frombuffer(zlib.decompress(b"".join(idat)), dtype=np.uint8)
    except zlib.error as e:
        raise ValueError(f"{path}: image data is corrupt or cut short ({e})") from None
    stride = 2 * width
    if raw.size != height * (stride + 1):
        raise ValueError(f"{path}: image data is cut short")
    lines = raw.reshape(height, stride + 1)
    out = np.zeros((height, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.uint8)
    for r in range(height):
        kind, cur = lines[r, 0], lines[r, 1:]
        if kind == 0:  # None
            row = cur
        elif kind == 1:  # Sub: a running sum along each byte of the 2-byte pixels
            row = np.empty(stride, dtype=np.uint8)
            for lane in (0, 1):
                row[lane::2] = np.cumsum(cur[lane::2], dtype=np.uint64) & 0xFF
        elif kind == 2:  # Up
            row = cur + prev  # uint8 arithmetic wraps as PNG's does
        elif kind in (3, 4):  # Average, Paeth: each byte needs the one just decoded
            c_, p_ = cur.tolist(), prev.tolist()
            dec = [0] * stride
            for i in range(stride):
                a = dec[i - 2] if i >= 2 else 0
                b = p_[i]
                if kind == 3:
                    pred = (a + b) >> 1
                else:
                    c = p_[i - 2] if i >= 2 else 0
                    pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                    pred = a if pa <= pb and pa <= pc else b if pb <= pc else c
                dec[i] = (c_[i] + pred) & 0xFF
            row = np.array(dec, dtype=np.uint8)
        else:
            raise ValueError(f"{path}: unknown PNG filter {kind}")
        out[r] = row
        prev = row
    return out.view(">u2").astype(np.uint16).reshape(height, width)


def read_intrinsics(directory):
    """(fx, fy, cx, cy) from a folder's camera-intrinsics.txt (a 3x3 matrix)."""
    k = np.loadtxt(Path(directory) / "camera-intrinsics.txt")
    return (k[0, 0], k[1, 1], k[0, 2], k[1, 2])


def read_gravity(directory):
    """Gravity (down, world frame) from a folder's gravity-direction.txt, or None."""
    path = Path(directory) / "gravity-direction.txt"
    return np.loadtxt(path).reshape(3) if path.exists() else None


def seven_scenes_frames(directory):
    """(number, depth, T_world_camera) for each frame-NNNNNN.depth.png of a folder, in order."""
    for depth in sorted(Path(directory).glob("frame-*.depth.png")):
        number = int(depth.name[len("frame-"):-len(".depth.png")])
        pose = np.loadtxt(str(depth).replace(".depth.png", ".pose.txt"))
        yield number, read_depth_png(depth), pose
