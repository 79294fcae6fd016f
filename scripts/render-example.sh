#!/usr/bin/env bash
# The main job: builds Tessera and renders the Cornell box to out/cornell-box.exr
# (and a PNG preview beside it). Extra arguments go to `tessera render`.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/build.sh"
mkdir -p "$root/out"
"$root/build/cli/tessera" render "$root/scenes/cornell-box/scene.json" \
    -o "$root/out/cornell-box.exr" "$@"
