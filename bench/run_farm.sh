#!/usr/bin/env bash
# Farm benchmarks: (1) the same Cornell box jobs (path tracing, and photon mapping with
# an irradiance cache) rendered locally with 2 threads and by the farm on 2 workers x 1
# thread; (2) coordinator throughput with trivial tasks and 8 concurrent workers, and
# coordinator memory with ~100,000 queued tasks.
# Usage: bench/run_farm.sh [build-dir]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target tessera tessera-coordinator tessera-worker bench_coordinator
cli=$build/cli/tessera
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT

scene=$root/scenes/cornell-box/scene.json
# Local render vs. the farm's job time for one set of render options.
compare() {
    local name=$1
    shift
    local t0 t1 t2 job_s
    t0=$(date +%s.%N)
    "$cli" render "$scene" -o "$work/local-$name.exr" --threads 2 -q "$@"
    t1=$(date +%s.%N)
    "$cli" farm "$scene" --workers 2 --threads-per-worker 1 -o "$work/farm-$name" "$@" \
        >/dev/null 2>"$work/farm-$name.log"
    t2=$(date +%s.%N)
    # The job's own time (submission to last frame written), as the CLI reports it.
    job_s=$(sed -n 's/.* tasks in \([0-9.]*\)s.*/\1/p' "$work/farm-$name.log" | tail -1)
    awk -v n="$name" -v a="$t0" -v b="$t1" -v c="$t2" -v j="${job_s:-0}" 'BEGIN {
        printf "farm overhead (%s): local (2 threads) %.2f s; farm (2 workers x 1 thread) job %.2f s, ratio %.3f;\n", n, b - a, j, j / (b - a)
        printf "               whole tessera farm command (process start and stop included) %.2f s, ratio %.3f\n", c - b, (c - b) / (b - a) }'
}
compare path --spp 32 --width 512 --height 512
# A multi-stage plan: photon batches, three irradiance passes, tiles; merges in between.
compare photon-ic --spp 8 --width 256 --height 256 --integrator photon --irradiance-cache \
    --photons 200000 --caustic-photons 50000 --photon-batches 16

"$build/coordinator/tessera-coordinator" --listen 127.0.0.1:0 --port-file "$work/port" \
    --state "$work/state" --output "$work/out" --log-level warn --max-tasks 200000 &
coord=$!
for _ in $(seq 100); do [ -s "$work/port" ] && break; sleep 0.1; done
addr=127.0.0.1:$(cat "$work/port")
"$cli" submit "$root/scenes/furnace/scene.json" --coordinator "$addr" \
    --width 316 --height 316 --tile-size 1 --spp 1 >/dev/null
rss=$(awk '/VmRSS/ {print $2}' /proc/$coord/status)
awk -v r="$rss" 'BEGIN { printf "coordinator memory with 99856 queued tasks: %.1f MiB resident\n", r / 1024 }'
"$build/bench/bench_coordinator" --coordinator "$addr" --workers 8 --seconds 20
hwm=$(awk '/VmHWM/ {print $2}' /proc/$coord/status)
awk -v r="$hwm" 'BEGIN { printf "coordinator peak memory: %.1f MiB\n", r / 1024 }'
