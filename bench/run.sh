#!/usr/bin/env bash
# Builds and runs the benchmarks. Usage: bench/run.sh [build-dir]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target bench_cornell
"$build/bench/bench_cornell" --spp 16 --threads 2 --size 512
