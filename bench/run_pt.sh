#!/usr/bin/env bash
# Error per second of the path tracer (bench_pt) on scenes/cornell-box, scenes/glass-caustic
# and scenes/veach-mis: sampler, filter, filter sampling, Russian roulette and Embree ISA
# settings side by side, each rendered REPEAT times interleaved with the others. The
# references are rendered once into $REF_DIR (kept out of git); they serve to mask
# emitters and for the RMSE(ref) column, while MSE x seconds uses the variance between
# renders with different seeds (bench/bench_pt.cpp says why).
#
#   bench/run_pt.sh [build-dir]     REF_DIR (./bench-references), THREADS (all), REPEAT (4),
#                                   SPP (64), REF_SPP (1024), SCENES ("cornell glass veach")
#                                   apply.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
ref_dir=${REF_DIR:-$root/bench-references}
threads=${THREADS:-0}
repeat=${REPEAT:-4}
spp=${SPP:-64}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target tessera bench_pt bench_cornell
mkdir -p "$ref_dir"
tessera="$build/cli/tessera"

reference() {  # scene output width height spp max-depth
  [ -f "$2" ] || "$tessera" render "$1" -o "$2" --width "$3" --height "$4" --spp "$5" \
    --max-depth "$6" --threads "$threads"
}

configs() {  # max-depth; the settings compared, first the old defaults (filter.type 3: tent)
  local d="spp=$spp max_depth=$1"
  echo "$d sampler=stratified filter.type=0 rr_threshold=1"
  echo "$d sampler=independent filter.type=0 rr_threshold=1"
  echo "$d sampler=sobol filter.type=0 rr_threshold=1"
  echo "$d sampler=sobol filter.type=0 rr_threshold=0.5"
  echo "$d sampler=sobol filter.type=0 rr_threshold=0.25"
  echo "$d sampler=sobol filter.type=0 rr_threshold=0.1"
  echo "$d sampler=sobol filter.type=3 filter.sampling=splat rr_threshold=0.25"
  echo "$d sampler=sobol filter.type=3 filter.sampling=importance rr_threshold=0.25"
  echo "$d sampler=sobol filter.type=0 rr_threshold=0.25 isa=max_isa=sse4.2"
  echo "$d sampler=sobol filter.type=0 rr_threshold=0.25 isa="
}

run() {  # scene reference emitter-luminance max-depth
  mapfile -t list < <(configs "$4")
  "$build/bench/bench_pt" "$1" "$2" --threads "$threads" --repeat "$repeat" --emitter "$3" \
    "${list[@]}"
}

for s in ${SCENES:-cornell glass veach}; do
  case $s in
    cornell)
      echo "== Cornell box"
      "$build/bench/bench_cornell" --spp 16 --threads "${threads/#0/$(nproc)}"
      ref="$ref_dir/cornell-256-d64-${REF_SPP:-1024}.exr"
      reference "$root/scenes/cornell-box/scene.json" "$ref" 256 256 "${REF_SPP:-1024}" 64
      run "$root/scenes/cornell-box/scene.json" "$ref" 1.5 64 ;;
    glass)
      echo "== glass caustic"
      ref="$ref_dir/glass-caustic-256x192-d64-${REF_SPP:-1024}.exr"
      reference "$root/scenes/glass-caustic/scene.json" "$ref" 256 192 "${REF_SPP:-1024}" 64
      run "$root/scenes/glass-caustic/scene.json" "$ref" 50 64 ;;
    veach)
      echo "== Veach MIS"
      # The scene's own depth: three bounces, as in Veach's figure.
      ref="$ref_dir/veach-mis-384x216-d3-${REF_SPP:-1024}.exr"
      reference "$root/scenes/veach-mis/scene.json" "$ref" 384 216 "${REF_SPP:-1024}" 3
      run "$root/scenes/veach-mis/scene.json" "$ref" 50 3 ;;
  esac
done
