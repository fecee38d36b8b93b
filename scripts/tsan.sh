#!/usr/bin/env bash
# Builds the libraries and the concurrency tests with ThreadSanitizer into ./build-tsan
# and runs them: queries from several threads on an idle map (mapping_test), one
# pipeline serving several threads (perception_test, as `mobmap build` uses it), and
# the tests around them; then the whole `mobmap build` (two frames in perception while
# the main thread reads results and fuses) on a simulated corridor. About 9 minutes on
# 2 cores.
#   bash scripts/tsan.sh
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
launcher=()
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMOBMAP_BUILD_PYTHON=OFF "${launcher[@]}" \
  -DCMAKE_CXX_FLAGS="-fsanitize=thread -fno-omit-frame-pointer" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread" -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=thread" >/dev/null
cmake --build build-tsan -j2 --target mapping_test perception_test mobmap
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$PWD/tests/tsan.supp"
./build-tsan/tests/mapping_test --gtest_filter='MobilityMap.*:MapFiles.*:LiveMapper.*'
./build-tsan/tests/perception_test --gtest_filter='FramePipeline.*'
run_dir=$(mktemp -d)
trap 'rm -rf "$run_dir"' EXIT
./build-tsan/apps/mobmap simulate --out "$run_dir/seq" --frames 12 --quiet
./build-tsan/apps/mobmap build "$run_dir/seq" --out "$run_dir/map.ot" --quiet
echo "tsan.sh: no data races reported"
