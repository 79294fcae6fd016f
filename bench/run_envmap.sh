#!/usr/bin/env bash
# Environment-map sampling at equal samples and at equal time (bench_gi): a diffuse and a
# glossy sphere on a diffuse floor (bench/envmap-objects.json: shadows matter) under each
# light probe found in $MAPS (default ../shared/data/envmaps: Grace Cathedral and Vogl's
# hall; not part of the repository), with the map's light sampled uniformly, by the cosine,
# by its 2D distribution and by structured importance sampling (300 and 64 strata). Each
# against a path-traced reference of the same scene at REF_SPP samples per pixel, rendered
# once into $REF_DIR. Columns as bench_gi's: seconds, RMSE, bias, RMSE^2 x seconds (lower is
# better: error per second).
#
#   bench/run_envmap.sh [build-dir]     REF_DIR (./bench-references), THREADS (all),
#                                       SPP (16), REF_SPP (1024), MAPS apply.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
ref_dir=${REF_DIR:-$root/bench-references}
threads=${THREADS:-0}
spp=${SPP:-16}
ref_spp=${REF_SPP:-1024}
maps=${MAPS:-$root/../shared/data/envmaps}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target tessera bench_gi
mkdir -p "$ref_dir"
work=$(mktemp -d "${TMPDIR:-/tmp}/tessera-envmap.XXXXXX")
trap 'rm -rf "$work"' EXIT

found=0
for map in "$maps"/grace_latlong.exr "$maps"/tungsten_vogl_envmap.hdr; do
  [ -f "$map" ] || continue
  found=1
  name=$(basename "$map"); name=${name%.*}
  # Grace Cathedral is dim (mean ~0.016): pbrt's scenes scale it by 8.
  scale=1; [ "$name" = grace_latlong ] && scale=8
  variant() {  # sampling [strata] -> scene file
    local dir="$work/$name-$1${2:+-$2}"
    mkdir -p "$dir"
    ln -sf "$map" "$dir/map${map##*/$name}"
    local light="\"type\": \"environment\", \"file\": \"map${map##*/$name}\", \"scale\": $scale, \"sampling\": \"$1\""
    [ -n "${2:-}" ] && light="$light, \"strata\": $2"
    sed -e "s|\"type\": \"environment\", \"file\": \"map.hdr\", \"scale\": 1, \"sampling\": \"distribution\"|$light|" \
      "$root/bench/envmap-objects.json" > "$dir/scene.json"
    echo "$dir/scene.json"
  }
  ref="$ref_dir/envmap-$name-path-$ref_spp.exr"
  [ -f "$ref" ] || "$build/cli/tessera" render "$(variant distribution)" -o "$ref" \
    --spp "$ref_spp" --seed 7777 --threads "$threads" -q
  echo "== $name (x$scale), $spp spp"
  for s in uniform cosine distribution "structured 300" "structured 64"; do
    # shellcheck disable=SC2086
    scene=$(variant $s)
    "$build/bench/bench_gi" "$scene" "$ref" --threads "$threads" --emitter 1e30 \
      "integrator=path spp=$spp" | tail -1 | sed "s|^integrator=path spp=$spp|$s|"
  done
done
[ "$found" = 1 ] || echo "no light probe in $maps: set MAPS to a folder holding grace_latlong.exr or tungsten_vogl_envmap.hdr"
