#!/usr/bin/env bash
# The main job: builds Tessera, starts a local farm (a coordinator and two workers on
# 127.0.0.1), renders the Cornell box through it and writes out/cornell-box.0000.exr
# (and a PNG preview beside it). Extra arguments go to `tessera farm`.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/build.sh"
mkdir -p "$root/out"
"$root/build/cli/tessera" farm "$root/scenes/cornell-box/scene.json" --workers 2 \
    -o "$root/out" "$@"
