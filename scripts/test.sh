#!/usr/bin/env bash
# Builds Tessera and runs every test (unit, statistical, render). Extra arguments go
# to ctest, e.g. `-L unit` for the quick ones only.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/build.sh"
ctest --test-dir "$root/build" --output-on-failure -j"$(nproc)" --timeout 900 "$@"
