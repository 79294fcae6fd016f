#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang, AddressSanitizer and
# UndefinedBehaviorSanitizer in build-fuzz/, then runs each for a bounded time on a copy
# of its corpus (fuzz/corpus/<name>/ is never grown). Exits non-zero if any fuzzer finds
# a crash; its reproducer is left in the printed folder.
#
#   scripts/fuzz.sh [SECONDS] [NAME...]     SECONDS per target (default: $FUZZ_SECONDS or 20)
#   FUZZ_JOBS=N      build parallelism (default: nproc)
#   FUZZ_ARGS="..."  extra libFuzzer flags for every run (e.g. "-rss_limit_mb=4096")
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build="$root/build-fuzz"
seconds=${1:-${FUZZ_SECONDS:-20}}
shift $(( $# > 0 ? 1 : 0 ))
all=(scene obj ply image stage_result coordinator)
names=("$@")
[ ${#names[@]} -gt 0 ] || names=("${all[@]}")

sanitizers="-fsanitize=address,undefined -fno-sanitize-recover=undefined"
if [ ! -f "$build/CMakeCache.txt" ]; then
  CC=clang CXX=clang++ cmake -S "$root" -B "$build" -G Ninja \
    -DCMAKE_BUILD_TYPE=Fuzz \
    -DCMAKE_CXX_FLAGS="-O1 -gline-tables-only -fno-omit-frame-pointer -fsanitize=fuzzer-no-link $sanitizers" \
    -DCMAKE_EXE_LINKER_FLAGS="$sanitizers" \
    -DTESSERA_FUZZ=ON -DTESSERA_BUILD_TESTS=OFF -DTESSERA_BUILD_BENCH=OFF >/dev/null
fi
targets=()
for n in "${names[@]}"; do targets+=("${n}_fuzzer"); done
start=$(date +%s)
cmake --build "$build" --target "${targets[@]}" -j"${FUZZ_JOBS:-$(nproc)}"
echo "fuzz: build took $(( $(date +%s) - start )) s"

work=$(mktemp -d "${TMPDIR:-/tmp}/tessera-fuzz.XXXXXX")
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:symbolize=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$root/fuzz/lsan.supp}
failed=()
for n in "${names[@]}"; do
  corpus="$work/$n/corpus"
  mkdir -p "$corpus" "$work/$n/artifacts"
  cp "$root/fuzz/corpus/$n/"* "$corpus/" 2>/dev/null || true
  dict=()
  [ -f "$root/fuzz/$n.dict" ] && dict=("-dict=$root/fuzz/$n.dict")
  log="$work/$n/log.txt"
  set +e
  # shellcheck disable=SC2086
  "$build/fuzz/${n}_fuzzer" "$corpus" -max_total_time="$seconds" -timeout=120 -print_final_stats=1 \
    -artifact_prefix="$work/$n/artifacts/" "${dict[@]}" ${FUZZ_ARGS:-} >"$log" 2>&1
  rc=$?
  set -e
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n1)
  if [ $rc -ne 0 ]; then
    failed+=("$n")
    echo "fuzz: $n FAILED (exit $rc) after ${execs:-?} executions; log and reproducer in $work/$n"
    grep -m1 -B2 -A30 "ERROR\|runtime error\|fuzz: \|deadly signal" "$log" || tail -n 40 "$log"
  else
    echo "fuzz: $n ok, ${execs:-?} executions in ${seconds} s"
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: crashes in: ${failed[*]}"
  exit 1
fi
rm -rf "$work"
