#!/usr/bin/env bash
# The main job: builds Tessera, starts a local farm (a coordinator and two workers on
# 127.0.0.1), renders frames 0-11 of the animated Cornell box (motion blur) through it
# and writes out/animated-cornell.0000.exr ... .0011.exr (each with a PNG preview) and
# the movie preview out/animated-cornell.mp4. Extra arguments go to `tessera farm`.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/build.sh"
mkdir -p "$root/out"
"$root/build/cli/tessera" farm "$root/scenes/animated-cornell/scene.json" --workers 2 \
    --frames 0-11 -o "$root/out" "$@"
