#!/usr/bin/env bash
# Makes the pictures in docs/images from the simulator, so they never go stale:
#   docs/images/corridor_level_0.png   the corridor's floor level (export --layers --layer-pictures)
# Needs a built mobmap (bash scripts/build.sh --target mobmap).
set -euo pipefail
cd "$(dirname "$0")/.."
exe=build/apps/mobmap
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$exe" simulate --out "$work/seq" --noise none --quiet
"$exe" build "$work/seq" --frames 0:239:3 --out "$work/corridor.ot" --quiet
"$exe" export "$work/corridor.ot" --layers "$work/layers" --layer-pictures --max-pixels 1200
mkdir -p docs/images
cp "$work/layers/level_0_view.png" docs/images/corridor_level_0.png
echo "wrote docs/images/corridor_level_0.png"
