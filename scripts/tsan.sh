#!/usr/bin/env bash
# Builds the libraries and the concurrency tests with ThreadSanitizer into ./build-tsan
# and runs them: queries from several threads on an idle map (mapping_test), one
# pipeline serving several threads (perception_test, as `mobmap build` uses it), and
# the tests around them; then the whole `mobmap build` (two frames in perception while
# the main thread reads results and fuses) on a simulated corridor; then `serve` and
# `serve --live` under a bounded loopback load (scripts/serve_load.py: six clients of
# mixed requests, two trickling ones), with cpp-httplib compiled in from Debian's source
# package of the installed version so that it is instrumented too (an uninstrumented
# library hides the synchronisation inside it from TSan). About 20 minutes on 2 cores.
#   bash scripts/tsan.sh
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
launcher=()
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1

# cpp-httplib's single header, from Debian's source package of the installed version
# (its own apt lists under build-tsan/apt: the system's sources are not touched), with
# Debian's patches applied.
httplib_dir="$PWD/build-tsan/cpp-httplib"
if [ ! -f "$httplib_dir/httplib.h" ]; then
  apt_dir="$PWD/build-tsan/apt"
  mkdir -p "$apt_dir/lists/partial" "$apt_dir/parts" "$apt_dir/src"
  printf 'Types: deb-src\nURIs: http://deb.debian.org/debian\nSuites: bookworm bookworm-updates\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n\nTypes: deb-src\nURIs: http://deb.debian.org/debian-security\nSuites: bookworm-security\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
    > "$apt_dir/parts/debian-src.sources"
  apt_opts=(-q -o Dir::Etc::SourceList=/dev/null -o Dir::Etc::SourceParts="$apt_dir/parts" -o Dir::State::Lists="$apt_dir/lists")
  apt-get "${apt_opts[@]}" update >/dev/null
  version=$(dpkg-query -W -f='${source:Version}' libcpp-httplib-dev)
  (cd "$apt_dir/src" && apt-get "${apt_opts[@]}" source --download-only "cpp-httplib=$version" >/dev/null 2>&1)
  rm -rf "$apt_dir/unpacked" && mkdir -p "$apt_dir/unpacked"
  tar xf "$apt_dir"/src/cpp-httplib_*.orig.tar.* -C "$apt_dir/unpacked"
  tar xf "$apt_dir"/src/cpp-httplib_*.debian.tar.* -C "$apt_dir/unpacked"
  upstream=$(find "$apt_dir/unpacked" -maxdepth 2 -name httplib.h -printf '%h\n' -quit)
  if [ -f "$apt_dir/unpacked/debian/patches/series" ]; then
    while read -r patch; do
      [ -n "$patch" ] && [ "${patch#\#}" = "$patch" ] && patch -s -d "$upstream" -p1 < "$apt_dir/unpacked/debian/patches/$patch"
    done < "$apt_dir/unpacked/debian/patches/series"
  fi
  mkdir -p "$httplib_dir" && cp "$upstream/httplib.h" "$httplib_dir/httplib.h"
fi

cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMOBMAP_BUILD_PYTHON=OFF "${launcher[@]}" \
  -DMOBMAP_HTTPLIB_HEADER_DIR="$httplib_dir" \
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

# `mobmap serve ARGS` on a free loopback port under serve_load.py, then Ctrl-C: it must
# stop cleanly (exit 0, or 130 for a --live build still fusing: its frames are saved), and
# TSan ends it with exit code 66 at its first report.
serveUnderLoad() {
  local log="$run_dir/serve.log"
  ./build-tsan/apps/mobmap serve "$@" --port 0 > "$log" 2>&1 &
  local pid=$!
  local port=""
  while [ -z "$port" ]; do  # the line that says where it serves
    if ! kill -0 "$pid" 2>/dev/null; then cat "$log"; echo "tsan.sh: serve $* ended before serving" >&2; exit 1; fi
    port=$(grep -o 'http://127\.0\.0\.1:[0-9]*' "$log" | head -n 1 | sed 's/.*://' || true)
    [ -z "$port" ] && sleep 0.2
  done
  python3 scripts/serve_load.py --port "$port" --clients 6 --requests 150 --tricklers 2
  kill -INT "$pid"
  local status=0
  wait "$pid" || status=$?
  if [ "$status" -ne 0 ] && [ "$status" -ne 130 ]; then cat "$log"; echo "tsan.sh: serve $* exited with $status" >&2; exit 1; fi
  echo "tsan.sh: serve $*: no data races reported"
}
serveUnderLoad "$run_dir/map.ot"
serveUnderLoad --live "$run_dir/seq" --out "$run_dir/live.ot" --quiet
echo "tsan.sh: no data races reported"
