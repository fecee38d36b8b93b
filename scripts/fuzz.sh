#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) into ./build-fuzz and runs each
# for SECONDS (default 30) on its corpus in tests/fuzz/corpus/, which it grows.
#   bash scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-30}
command -v clang++ >/dev/null || { echo "fuzz.sh: needs clang++ (apt-get install clang libclang-rt-14-dev)" >&2; exit 1; }
mkdir -p build-fuzz
flags=(-std=c++17 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -Igp/include -Iperception/include -Imapping/include -Iapps/src -I/usr/include/eigen3 -Ibuild-fuzz)
for d in /usr/include/mrpt/*/include; do flags+=("-I$d"); done
cmake -DIN=apps/default.yaml -DOUT=build-fuzz/default_yaml.inc -P apps/embed.cmake
clang++ "${flags[@]}" tests/fuzz/fuzz_map_reader.cpp mapping/src/mobility_octree.cpp mapping/src/map_io.cpp \
  -loctomap -loctomath -o build-fuzz/fuzz_map_reader
clang++ "${flags[@]}" tests/fuzz/fuzz_config.cpp apps/src/config.cpp apps/src/files.cpp \
  gp/src/rule_table.cpp gp/src/gaussian_process.cpp gp/src/mobility_model.cpp perception/src/pipeline.cpp \
  perception/src/stages.cpp perception/src/neighbours.cpp perception/src/camera.cpp perception/src/delaunay_roughness.cpp \
  mapping/src/mobility_map.cpp mapping/src/mobility_octree.cpp mapping/src/gravity.cpp \
  -lyaml-cpp -loctomap -loctomath -lmrpt-poses -lmrpt-math -lmrpt-core -lgmp -lmpfr -o build-fuzz/fuzz_config
for target in map_reader config; do
  mkdir -p "tests/fuzz/corpus/$target"
  echo "== fuzz_$target for ${seconds}s"
  ./build-fuzz/fuzz_$target "tests/fuzz/corpus/$target" -max_total_time="$seconds" -max_len=65536 -rss_limit_mb=2048 \
    -print_final_stats=1 2>&1 | grep -E "stat::number_of_executed_units|stat::peak_rss_mb|ERROR|SUMMARY|crash-|Done" || true
done
