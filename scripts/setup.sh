#!/usr/bin/env bash
# Installs what mobmap needs to build and test on Debian 12, and nothing that is
# already there. Safe to run again. Needs root (or sudo) only when something is missing.
#   bash scripts/setup.sh [fuzz]
set -euo pipefail

packages=(
  g++ cmake make pkg-config ccache
  libeigen3-dev liboctomap-dev libpcl-dev libopenni2-dev libcgal-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev libpng-dev nlohmann-json3-dev libyaml-cpp-dev
  # the pictures: Cairo draws them (PNG, SVG, PDF) with the fonts fontconfig finds
  libcairo2-dev fonts-dejavu-core
  pybind11-dev python3-dev python3-numpy python3-pytest
  libcpp-httplib-dev libjs-three
  # `export --layers` writes GeoTIFF through GDAL; the tests read it back with gdalinfo
  libgdal-dev gdal-bin
  # ROS 2 bags: sqlite3 storage, MCAP chunks compressed with lz4 or zstd
  libsqlite3-dev liblz4-dev libzstd-dev
  # ROS 1 bags: bz2 chunks
  libbz2-dev
  # The tests' ROS 1 bag writer: Debian's rosbag_storage (catkin: its CMake configuration
  # needs it) and the message types
  librosbag-storage-dev catkin libsensor-msgs-dev libtf2-msgs-dev
  # mobmap_node (ROS 1 Noetic from Debian) and its test: roscore, roslaunch, rosbag play,
  # and rospy with the message types the test listens with
  ros-core libroscpp-dev libtf2-ros-dev libimage-transport-dev libnav-msgs-dev libstd-srvs-dev
  libgeometry-msgs-dev python3-rospy python3-nav-msgs python3-std-srvs python3-geometry-msgs
  python3-actionlib-msgs python3-sensor-msgs
  # mobmap_ros2 (Cyclone DDS and its IDL compiler) and its test's Fast DDS participant
  cyclonedds-dev cyclonedds-tools libfastrtps-dev iproute2
  # the viewer's test draws the page in headless Chromium
  chromium
)
# `setup.sh fuzz`: also clang and its libFuzzer / sanitizer runtimes (scripts/fuzz.sh).
if [ "${1:-}" = fuzz ]; then
  packages+=(clang libclang-rt-14-dev)
fi

# The tests' bag writers (tests/recordings) run on Node.js; Debian's when the machine has none.
if ! command -v npm >/dev/null 2>&1; then
  packages+=(nodejs npm)
fi

# The npm packages that write the tests' bags, as package-lock.json pins them.
npm_fixtures() {
  local dir
  dir="$(cd "$(dirname "$0")/.." && pwd)/tests/recordings"
  if [ ! -d "$dir/node_modules" ] || [ "$dir/package-lock.json" -nt "$dir/node_modules" ]; then
    echo "setup: installing the bag writers of $dir (npm ci)"
    (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error) && touch "$dir/node_modules"
  fi
}

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages are installed"
  npm_fixtures
  exit 0
fi

echo "setup: installing ${missing[*]}"
if [ "$(id -u)" -eq 0 ]; then
  as_root=()
elif command -v sudo >/dev/null 2>&1; then
  as_root=(sudo)
else
  echo "setup: these packages are missing and installing them needs root: ${missing[*]}" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
"${as_root[@]}" apt-get update -q
"${as_root[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
npm_fixtures
