#!/usr/bin/env bash
# Sampling of measured BRDFs at equal samples (bench_gi): a measured sphere on a diffuse floor
# (bench/measured-objects.json), lit by a square area light and a uniform sky, with the
# measured material's directions sampled by the cosine, through an analytic fit (a Lambertian
# term and a GGX lobe) and through the factored representation. Two BRDFs: a MERL file of a
# glossy GGX-like material written by bench/make_merl (alpha 0.1, Schlick Fresnel from a
# gold-like f0, a little diffuse), and a Cornell car paint ($PAINT.brdf in $BRDFS, default
# ../shared/data/brdfs/cayman.brdf; not part of the repository: skipped when absent). Each
# against a path-traced reference of the same scene (factored sampling, REF_SPP samples per
# pixel), rendered once into $REF_DIR under a name that holds a hash of the BRDF file and of
# the scene. Columns as bench_gi's: seconds, samples/s, RMSE, bias, RMSE^2 x seconds (MSE x s,
# lower is better); then each sampler's RMSE over the cosine's.
#
#   bench/run_measured.sh [build-dir]   REF_DIR (./bench-references), THREADS (all), SPP (16),
#                                       REF_SPP (1024), SCALE (image size divisor, 1: 256x192),
#                                       BRDFS, PAINT (cayman) apply.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
ref_dir=${REF_DIR:-$root/bench-references}
threads=${THREADS:-0}
spp=${SPP:-16}
ref_spp=${REF_SPP:-1024}
scale=${SCALE:-1}
brdfs=${BRDFS:-$root/../shared/data/brdfs}
paint=${PAINT:-cayman}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target tessera bench_gi make_merl
mkdir -p "$ref_dir"
work=$(mktemp -d "${TMPDIR:-/tmp}/tessera-measured.XXXXXX")
trap 'rm -rf "$work"' EXIT
scene_template=$root/bench/measured-objects.json
w=$((256 / scale)); h=$((192 / scale))

compare() {  # name brdf-file
  local name=$1 file=$2 ext=${2##*.}
  variant() {  # sampling -> scene file
    local dir="$work/$name-$1"
    mkdir -p "$dir"
    ln -sf "$file" "$dir/brdf.$ext"
    sed -e "s|\"file\": \"brdf.binary\", \"sampling\": \"factored\"|\"file\": \"brdf.$ext\", \"sampling\": \"$1\"|" \
      "$scene_template" > "$dir/scene.json"
    echo "$dir/scene.json"
  }
  local key
  key=$(cat "$file" "$scene_template" | sha256sum | cut -c1-12)
  local ref="$ref_dir/measured-$name-$key-${w}x${h}-path-$ref_spp.exr"
  [ -f "$ref" ] || "$build/cli/tessera" render "$(variant factored)" -o "$ref" \
    --width "$w" --height "$h" --spp "$ref_spp" --seed 7777 --threads "$threads" -q
  echo "== $name ($(basename "$file")), ${w}x${h}, $spp spp, reference $ref_spp spp"
  printf "%-9s %9s %11s %10s %9s %12s\n" sampling seconds samples/s RMSE bias "RMSE^2*s"
  local lines="" line
  for s in cosine fit factored; do
    # bench_gi's last line: the configuration's two words, then its figures.
    line=$("$build/bench/bench_gi" "$(variant $s)" "$ref" --threads "$threads" --emitter 1e30 \
      "integrator=path spp=$spp" | tail -1 |
      awk -v s="$s" '{ printf "%-9s %9s %11s %10s %9s %12s\n", s, $3, $4, $5, $6, $7 }')
    echo "$line"
    lines+="$line"$'\n'
  done
  printf "%s" "$lines" | awk '{ rmse[$1] = $4 }
    END { printf "RMSE / cosine RMSE: fit %.3f, factored %.3f\n", rmse["fit"] / rmse["cosine"],
          rmse["factored"] / rmse["cosine"] }'
}

"$build/bench/make_merl" "$work/glossy.binary" >/dev/null
compare glossy-ggx "$work/glossy.binary"
if [ -f "$brdfs/$paint.brdf" ]; then
  compare "$paint" "$brdfs/$paint.brdf"
else
  echo "no car-paint BRDF $brdfs/$paint.brdf: skipped (set BRDFS to a folder holding $paint.brdf)"
fi
