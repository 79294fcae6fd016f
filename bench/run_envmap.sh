#!/usr/bin/env bash
# Environment-map sampling at equal samples and at equal time (bench_gi), on two scenes: a
# diffuse sphere on a diffuse floor (bench/envmap-diffuse.json: shadows matter) and a
# diffuse and a glossy sphere on the floor (bench/envmap-objects.json). Each under a
# procedural sky (bench/make_envmap: a small bright sun, two windows, a sky and a ground)
# and under each light probe found in $MAPS (default ../shared/data/envmaps: Grace
# Cathedral and Vogl's hall; not part of the repository). The map's light is sampled
# uniformly, by the cosine, by its 2D distribution, by structured importance sampling (300
# and 64 strata) and through the structured light set (300 and 64 directional lights,
# biased). Each against a path-traced reference of the same scene at REF_SPP samples per
# pixel, rendered once into $REF_DIR. Columns as bench_gi's: seconds, RMSE, bias,
# RMSE^2 x seconds (lower is better: error per second).
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
cmake --build "$build" -j"$(nproc)" --target tessera bench_gi make_envmap
mkdir -p "$ref_dir"
work=$(mktemp -d "${TMPDIR:-/tmp}/tessera-envmap.XXXXXX")
trap 'rm -rf "$work"' EXIT

"$build/bench/make_envmap" "$work/procedural_sky.exr" 1024
for map in "$work/procedural_sky.exr" "$maps"/grace_latlong.exr "$maps"/tungsten_vogl_envmap.hdr; do
  [ -f "$map" ] || continue
  name=$(basename "$map"); name=${name%.*}
  # Grace Cathedral is dim (mean ~0.016): pbrt's scenes scale it by 8.
  scale=1; [ "$name" = grace_latlong ] && scale=8
  for objects in diffuse objects; do
    variant() {  # sampling [strata] -> scene file
      local dir="$work/$name-$objects-$1${2:+-$2}"
      mkdir -p "$dir"
      ln -sf "$map" "$dir/map${map##*/$name}"
      local light="\"type\": \"environment\", \"file\": \"map${map##*/$name}\", \"scale\": $scale, \"sampling\": \"$1\""
      [ -n "${2:-}" ] && light="$light, \"strata\": $2"
      sed -e "s|\"type\": \"environment\", \"file\": \"map.hdr\", \"scale\": 1, \"sampling\": \"distribution\"|$light|" \
        "$root/bench/envmap-$objects.json" > "$dir/scene.json"
      echo "$dir/scene.json"
    }
    ref="$ref_dir/envmap-$name-$objects-path-$ref_spp.exr"
    [ -f "$ref" ] || "$build/cli/tessera" render "$(variant distribution)" -o "$ref" \
      --spp "$ref_spp" --seed 7777 --threads "$threads" -q
    echo "== $name (x$scale), $objects, $spp spp"
    for s in uniform cosine distribution "structured 300" "structured 64" "lightset 300" "lightset 64"; do
      # shellcheck disable=SC2086
      scene=$(variant $s)
      "$build/bench/bench_gi" "$scene" "$ref" --threads "$threads" --emitter 1e30 \
        "integrator=path spp=$spp" | tail -1 | sed "s|^integrator=path spp=$spp|$s|"
    done
  done
done
