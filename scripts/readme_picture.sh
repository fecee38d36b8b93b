#!/usr/bin/env bash
# Makes the README's picture from the demo's map, so it never goes stale:
#   docs/images/demo_plan.png   the corridor's mobility map from above with a footstep
#                               plan up its stairs (mobmap plan --png)
# Runs the demo first when maps/demo/corridor.ot is missing (bash scripts/demo.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
exe=build/apps/mobmap
map=maps/demo/corridor.ot
[ -f "$map" ] || "$exe" demo --out maps/demo --quiet
mkdir -p docs/images
# From the corridor's start to the top of its stairs (20 cm risers: --max-step 0.2).
"$exe" plan "$map" --from 1 0 0 --to 7.05 0.9 0.68 --max-step 0.2 --png docs/images/demo_plan.png --max-pixels 1000 >/dev/null
echo "wrote docs/images/demo_plan.png"
