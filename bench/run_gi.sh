#!/usr/bin/env bash
# Error per second of the global-illumination integrators (bench_gi) against converged
# path-traced references, which are rendered once and kept in $REF_DIR.
#
#   bench/run_gi.sh [build-dir]        REF_DIR (default ./bench-references), CORNELL_SPP
#                                      (2048), CAUSTIC_SPP (4096) and THREADS (all) apply.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
ref_dir=${REF_DIR:-$root/bench-references}
threads=${THREADS:-0}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target tessera bench_gi
mkdir -p "$ref_dir"
tessera="$build/cli/tessera"
cornell="$root/scenes/cornell-box/scene.json"
caustic="$root/scenes/glass-caustic/scene.json"
cornell_ref="$ref_dir/cornell-512-path-${CORNELL_SPP:-2048}.exr"
caustic_ref="$ref_dir/glass-caustic-256x192-path-${CAUSTIC_SPP:-4096}.exr"
[ -f "$cornell_ref" ] || "$tessera" render "$cornell" -o "$cornell_ref" --spp "${CORNELL_SPP:-2048}" \
  --threads "$threads"
[ -f "$caustic_ref" ] || "$tessera" render "$caustic" -o "$caustic_ref" --width 256 --height 192 \
  --spp "${CAUSTIC_SPP:-4096}" --threads "$threads"

echo "== irradiance cache on the Cornell box: error against time"
"$build/bench/bench_gi" "$cornell" "$cornell_ref" --threads "$threads" \
  "integrator=irradiance-cache spp=4 ic.accuracy=0.3 ic.samples=128" \
  "integrator=irradiance-cache spp=8 ic.accuracy=0.25 ic.samples=256" \
  "integrator=irradiance-cache spp=16 ic.accuracy=0.2 ic.samples=256" \
  "integrator=irradiance-cache spp=20 ic.accuracy=0.4 ic.samples=768" \
  "integrator=irradiance-cache spp=32 ic.accuracy=0.15 ic.samples=512" \
  "integrator=irradiance-cache spp=16 ic.accuracy=0.2 ic.samples=256 ic.gradients=0" \
  "integrator=irradiance-cache spp=16 ic.accuracy=0.2 ic.samples=256 ic.passes=0"

echo "== final gather: through the irradiance cache against brute force"
"$build/bench/bench_gi" "$cornell" "$cornell_ref" --threads "$threads" \
  "integrator=photon spp=16 ic=1" \
  "integrator=photon spp=4 gather=16" \
  "integrator=photon spp=16 gather=16"

echo "== equal time: path tracing against photon mapping"
"$build/bench/bench_gi" "$cornell" "$cornell_ref" --threads "$threads" \
  "integrator=path spp=16" "integrator=path spp=64" "integrator=photon spp=16 ic=1"
"$build/bench/bench_gi" "$caustic" "$caustic_ref" --threads "$threads" --emitter 50 \
  "integrator=path spp=16" "integrator=path spp=64" "integrator=path spp=256" \
  "integrator=photon spp=4 ic=1" "integrator=photon spp=16 ic=1"
