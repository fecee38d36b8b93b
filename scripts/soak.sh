#!/usr/bin/env bash
# Soak: streams FRAMES frames (default 10000) of the synthetic corridor, walked back and
# forth, from the test OpenNI2 driver (a live sensor at 30 Hz) through `mobmap build`
# with the true trajectory, sampling the process's resident memory every 10 s. Once the
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
# The device streams long enough for the run (it runs at 30 Hz, mobmap takes what it can).
device_frames=$((frames * 12 + 3000))
export LD_LIBRARY_PATH=$PWD/$sim MOBMAP_SIM_FRAMES=$device_frames MOBMAP_SIM_LOOP=240 \
       MOBMAP_SIM_NOISE=kinect MOBMAP_SIM_POSES=$out/poses.txt
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
  sleep 10
done
wait "$pid"
status=$?
cat "$out/build.log" | tail -4
column -t "$out/memory.tsv" | awk 'NR == 1 || NR % 6 == 2'
awk -v q=$((frames / 4)) 'NR > 1 && $2 >= q && !base { base = $3 } NR > 1 { last = $3; peak = ($3 > peak ? $3 : peak) }
  END { printf "resident memory: %.1f MB after a quarter of the frames, %.1f MB at the end (peak %.1f), growth %.1f %%\n",
               base, last, peak, 100 * (last - base) / base; exit (last > 1.10 * base) }' "$out/memory.tsv" || {
  echo "soak.sh: memory grew more than 10 % after the map was complete" >&2; exit 1; }
exit $status
