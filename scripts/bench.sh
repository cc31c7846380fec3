#!/usr/bin/env bash
# Builds and runs every benchmark in full, one after the other in one go, printing the figures.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
BUILD_DIR=${BUILD_DIR:-build}
for bench in bench_himm bench_queries; do
  echo "== $bench"
  "$BUILD_DIR/tests/bench/$bench" --benchmark_counters_tabular=true "$@"
done
