#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) into ./build-fuzz and runs each
# for SECONDS (default 30) on its seeds in tests/fuzz/corpus/TARGET and the inputs earlier
# runs grew in build-fuzz/corpus/TARGET (where new ones go: the seeds are tracked files).
# Exits non-zero if any target finds a crash (the input is saved as build-fuzz/crash-*).
#   bash scripts/fuzz.sh [SECONDS] [TARGET...]      targets: map_reader config poses pipeline api mcap cdr db3 ros1
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-30}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(map_reader config poses pipeline api mcap cdr db3 ros1)
bash scripts/setup.sh fuzz
mkdir -p build-fuzz/obj
# -ffp-contract=off as perception/CMakeLists.txt sets it (its vector kernels match the
# portable loops bit for bit only without fused multiply-adds).
flags=(-std=c++17 -O1 -g -ffp-contract=off -fsanitize=address,undefined -fno-sanitize-recover=undefined
       -Iutil/include -Ibuilder/include -Igp/include -Iperception/include -Iperception/src -Imapping/include -Isources/include -Isources/src -Iapps/src -I/usr/include/eigen3 -I/usr/include/openni2 -Ibuild-fuzz)
cmake -DIN=apps/default.yaml -DOUT=build-fuzz/default_yaml.inc -P apps/embed.cmake
# The viewer's files (serve's API hands them out), as apps/CMakeLists.txt embeds them.
for asset in apps/viewer/index.html:viewer_index_html apps/viewer/viewer.js:viewer_js \
             /usr/share/javascript/three/three.min.js:three_min_js \
             /usr/share/javascript/three/examples/js/controls/OrbitControls.js:orbit_controls_js; do
  cmake -DIN="${asset%%:*}" -DOUT="build-fuzz/${asset##*:}.inc" -DDELIM=mobmapjs -P apps/embed.cmake
done

# Each source is compiled once, again when it or any first-party header is newer than
# its object (a header change can change a struct's layout under an old object).
# (sort reads all its input: a reader that stops early, as head does, would let the writer die of
# SIGPIPE once the list outgrows one pipe write, and pipefail would end the script with 141.)
newest_header=$(find util builder gp perception mapping sources apps sim tests/fuzz -name '*.hpp' -printf '%T@ %p\n' |
  sort -n | tail -n 1 | cut -d' ' -f2-)
# The stale ones are compiled on every core at once; a failed compile stops the script.
compile_flags=$(printf '%q ' "${flags[@]}")
export compile_flags
objects() {
  local stale=()
  for src in "$@"; do
    local o="build-fuzz/obj/${src//\//_}.o"
    if [ ! -f "$o" ] || [ "$src" -nt "$o" ] || [ "$newest_header" -nt "$o" ]; then stale+=("$src"); fi
  done
  if [ ${#stale[@]} -gt 0 ]; then
    printf '%s\n' "${stale[@]}" | xargs -P "$(nproc)" -I{} bash -c \
      'src={}; eval clang++ $compile_flags -fsanitize=fuzzer-no-link -c "$src" -o "build-fuzz/obj/${src//\//_}.o"' >&2 ||
      return 1
  fi
  for src in "$@"; do echo "build-fuzz/obj/${src//\//_}.o"; done
}
# A module's sources as its CMakeLists.txt lists them (SOURCES up to the *_DEPS line), so
# a file added there is never missing here.
module_sources() {
  sed -n '/mobmap_add_module/,/_DEPS/p' "$1/CMakeLists.txt" | grep -o 'src/[A-Za-z0-9_/]*\.cpp' | sed "s|^|$1/|"
}
mapfile -t util < <(module_sources util)
mapfile -t gp < <(module_sources gp)
mapfile -t perception < <(module_sources perception)
mapfile -t mapping < <(module_sources mapping)
# The bag readers: the sources module without the folder, PCD and OpenNI2 readers.
mapfile -t bag_sources < <(module_sources sources |
  grep -v -E '^sources/src/(dataset|trajectory_files|pcd|openni|sequence|recording_sequence|adjusted)\.cpp$')
link() {  # link TARGET SOURCES... -- LIBS...
  local target=$1; shift
  local srcs=() libs=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do srcs+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  libs=("$@")
  echo "== building fuzz_$target"
  objects "${srcs[@]}" > build-fuzz/objects.txt
  mapfile -t objs < build-fuzz/objects.txt
  clang++ "${flags[@]}" -fsanitize=fuzzer "${objs[@]}" "${libs[@]}" -o "build-fuzz/fuzz_$target"
}
for target in "${targets[@]}"; do
  case $target in
    map_reader) link map_reader tests/fuzz/fuzz_map_reader.cpp "${mapping[@]}" "${perception[@]}" "${gp[@]}" "${util[@]}" \
                  -- -loctomap -loctomath -lgmp -lmpfr ;;
    config) link config tests/fuzz/fuzz_config.cpp builder/src/config.cpp sources/src/text.cpp "${gp[@]}" "${perception[@]}" \
              "${mapping[@]}" "${util[@]}" \
              -- -lyaml-cpp -loctomap -loctomath -lgmp -lmpfr ;;
    poses) link poses tests/fuzz/fuzz_poses.cpp sources/src/trajectory_files.cpp sources/src/dataset.cpp sources/src/text.cpp \
             sources/src/png.cpp perception/src/camera.cpp mapping/src/gravity.cpp "${util[@]}" -- -lpng -lyaml-cpp ;;
    pipeline) link pipeline tests/fuzz/fuzz_pipeline.cpp "${gp[@]}" "${perception[@]}" "${util[@]}" -- -lgmp -lmpfr ;;
    api) link api tests/fuzz/fuzz_api.cpp apps/src/serve/api.cpp apps/src/serve/viewer_assets.cpp apps/src/answers/answers.cpp \
           "${mapping[@]}" "${perception[@]}" "${gp[@]}" "${util[@]}" \
           -- -loctomap -loctomath -lgmp -lmpfr ;;
    mcap|cdr|db3|ros1) link "$target" "tests/fuzz/fuzz_$target.cpp" "${bag_sources[@]}" perception/src/camera.cpp \
                    mapping/src/pose_samples.cpp "${util[@]}" \
                    -- -lpng -lz -lbz2 -lyaml-cpp -lsqlite3 -llz4 -lzstd ;;
    *) echo "fuzz.sh: unknown target $target" >&2; exit 2 ;;
  esac
done

# What one input may cost. The recording readers read files from strangers: an input
# (at most 64 KiB) must finish within 10 s and 1 GiB of RSS, no allocation over 160 MiB
# (a chunk holds at most 128 MiB); the cost of a decompression bomb or an endless query
# is then a finding, not a slow run. The others keep the ceilings they were fuzzed with.
ceilings() {
  case $1 in
    mcap|cdr|db3|ros1) echo "-rss_limit_mb=1024 -malloc_limit_mb=160 -timeout=10" ;;
    *) echo "-rss_limit_mb=2048 -timeout=20" ;;
  esac
}
failed=()
for target in "${targets[@]}"; do
  mkdir -p "tests/fuzz/corpus/$target" "build-fuzz/corpus/$target"
  echo "== fuzz_$target for ${seconds}s ($(ceilings "$target"))"
  set +e
  # libFuzzer adds what it finds to the first folder.
  # shellcheck disable=SC2046  # the ceilings are separate words
  (cd build-fuzz && "./fuzz_$target" "corpus/$target" "../tests/fuzz/corpus/$target" -max_total_time="$seconds" -max_len=65536 \
     $(ceilings "$target") -print_final_stats=1 > "fuzz_$target.log" 2>&1)
  status=$?
  set -e
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb|ERROR|SUMMARY|crash-|timeout-|Done" "build-fuzz/fuzz_$target.log" || true
  [ $status -eq 0 ] || failed+=("$target")
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz.sh: crashes in ${failed[*]} (logs and inputs in build-fuzz/)" >&2
  exit 1
fi
