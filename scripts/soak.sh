#!/usr/bin/env bash
# Soak: streams FRAMES frames (default 10000) of the synthetic corridor, walked back and
# forth, from the test OpenNI2 driver (a live sensor at 8 Hz, so that rendering frames
# nobody reads does not starve mobmap of CPU) through `mobmap build`
# with the true trajectory, sampling the process's resident memory every 5 s. Once the
# first pass has mapped the corridor the map stops growing, so memory must stop too:
# the script fails if resident memory grows more than 10 % between the first sample
# after a quarter of the frames and the end. Needs a Release build in ./build.
#   bash scripts/soak.sh [FRAMES] [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-10000}
out=${2:-/tmp/mobmap-soak}
sim=build/openni-sim
[ -x build/apps/mobmap ] && [ -f "$sim/OpenNI2/Drivers/libMobmapSimDevice.so.0" ] || {
  echo "soak.sh: build first (bash scripts/build.sh)" >&2; exit 1; }
mkdir -p "$out"
rm -f "$out/soak.ot" "$out/memory.tsv"
# The device streams long enough for the run (mobmap takes the frames it can).
device_frames=$((frames * 4 + 3000))
export LD_LIBRARY_PATH=$PWD/$sim MOBMAP_SIM_FRAMES=$device_frames MOBMAP_SIM_LOOP=240 \
       MOBMAP_SIM_NOISE=kinect MOBMAP_SIM_POSES=$out/poses.txt MOBMAP_SIM_FPS=8
start=$(date +%s)
# The driver writes the trajectory when the device opens; mobmap reads it after that.
: > "$out/poses.txt"
./build/apps/mobmap build --device mobmap-sim://corridor --intrinsics 585,585,320,240 --poses "$out/poses.txt" \
  --max-pose-gap 0.05 --frames "0:$((frames - 1))" --out "$out/soak.ot" --force > "$out/build.log" 2>&1 &
pid=$!
printf "seconds\tframes\trss_mb\n" > "$out/memory.tsv"
while kill -0 "$pid" 2>/dev/null; do
  rss=$(awk '/VmRSS/ {print $2}' "/proc/$pid/status" 2>/dev/null || echo 0)
  done_frames=$(grep -o 'build [0-9]*/' "$out/build.log" | tail -1 | tr -dc 0-9 || true)
  printf "%d\t%s\t%.1f\n" $(( $(date +%s) - start )) "${done_frames:-0}" "$(echo "$rss / 1024" | bc -l)" >> "$out/memory.tsv"
  sleep 5
done
wait "$pid"
status=$?
cat "$out/build.log" | tail -4
column -t "$out/memory.tsv" | awk 'NR == 1 || NR % 6 == 2'
awk -v q=$((frames / 4)) 'NR > 1 && $2 >= q && !base { base = $3 } NR > 1 { last = $3; peak = ($3 > peak ? $3 : peak) }
  END { if (!base) { print "soak.sh: too short to judge (no memory sample after a quarter of the frames)"; exit 2 }
        printf "resident memory: %.1f MB after a quarter of the frames, %.1f MB at the end (peak %.1f), growth %.1f %%\n",
               base, last, peak, 100 * (last - base) / base; exit (last > 1.10 * base) }' "$out/memory.tsv" || {
  echo "soak.sh: memory grew more than 10 % after the map was complete, or the run was too short" >&2; exit 1; }
exit $status
