#!/usr/bin/env bash
# One command for a new user: install dependencies, build in Release, run `mobmap demo`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh --target mobmap
./build/apps/mobmap demo --out maps/demo "$@"
