#!/usr/bin/env bash
# Builds the whole project with AddressSanitizer + UndefinedBehaviorSanitizer into
# ./build-asan and runs the test suite there. Slow (~10 min on 2 cores); not part of CI.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
launcher=()
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# The Python module is left out: an instrumented extension cannot load into an
# uninstrumented interpreter.
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMOBMAP_BUILD_PYTHON=OFF "${launcher[@]}" \
  -DCMAKE_CXX_FLAGS="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
cmake --build build-asan -j2
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
# OpenNI2's libraries leak a few hundred bytes of their own; nothing of ours is suppressed.
export LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1
# The find_package consumer test is left out: it builds an uninstrumented project
# against these instrumented static libraries, which cannot link.
ctest --test-dir build-asan --output-on-failure -j2 -E "Install.ConsumerProject" "$@"
