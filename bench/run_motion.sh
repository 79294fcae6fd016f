#!/usr/bin/env bash
# Motion blur's cost and noise (bench_pt), on frame 3 of scenes/animated-cornell and on
# bench/moving-bar.json (a bar moving about 7 pixels and turning 10 degrees in one shutter,
# so that its edges move 1 to 13 pixels, seen by its direct light alone, so that motion is
# the only source of noise):
#   - cost: the scene with its shutter open against a copy with the shutter closed, at
#     equal samples (seconds, rays/s);
#   - noise: the three time samplers at equal samples, RMSE against a long reference:
#     space-time stratified (render.time_sampler "stratified"), the pixel sampler's own
#     time dimension ("sampler") and independent uniform times ("independent").
# References are rendered once into $REF_DIR (kept out of git).
#
#   bench/run_motion.sh [build-dir]     REF_DIR (./bench-references), THREADS (all),
#                                       REPEAT (4), SPP (16), REF_SPP (1024) apply.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
ref_dir=${REF_DIR:-$root/bench-references}
threads=${THREADS:-0}
repeat=${REPEAT:-4}
spp=${SPP:-16}
ref_spp=${REF_SPP:-1024}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target tessera bench_pt
mkdir -p "$ref_dir"
tessera="$build/cli/tessera"
work=$(mktemp -d "${TMPDIR:-/tmp}/tessera-motion.XXXXXX")
trap 'rm -rf "$work"' EXIT

# A copy of scene $1 in $2 with the camera's shutter closed; mesh paths stay valid
# because the copy sits beside the original.
closed_copy() {
  python3 - "$1" "$2" <<'PY'
import json, sys
scene = json.load(open(sys.argv[1]))
scene["camera"]["shutter"] = [0, 0]
json.dump(scene, open(sys.argv[2], "w"))
PY
}

run() {  # name scene frame width height emitter
  local name=$1 scene=$2 frame=$3 w=$4 h=$5 emitter=$6
  local ref="$ref_dir/$name-${w}x$h-f$frame-$ref_spp.exr"
  [ -f "$ref" ] || "$tessera" render "$scene" -o "$ref" --frame "$frame" --width "$w" \
    --height "$h" --spp "$ref_spp" --threads "$threads"
  echo "== $name, frame $frame: time samplers at $spp spp"
  "$build/bench/bench_pt" "$scene" "$ref" --threads "$threads" --repeat "$repeat" \
    --emitter "$emitter" --frame "$frame" \
    "spp=$spp time_sampler=independent" "spp=$spp time_sampler=sampler" \
    "spp=$spp time_sampler=stratified"
  local closed
  closed="$(dirname "$scene")/.closed-shutter-$name.json"
  closed_copy "$scene" "$closed"
  echo "== $name, frame $frame: shutter open (above) against closed, $spp spp"
  "$build/bench/bench_pt" "$closed" "$ref" --threads "$threads" --repeat "$repeat" \
    --emitter "$emitter" --frame "$frame" "spp=$spp" || true
  rm -f "$closed"
}

run animated-cornell "$root/scenes/animated-cornell/scene.json" 3 256 256 1.5
run moving-bar "$root/bench/moving-bar.json" 0 128 128 100
