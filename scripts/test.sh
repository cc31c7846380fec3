#!/usr/bin/env bash
# Installs dependencies, builds, and runs every test label (unit, integration, scenario, bench
# smoke runs). Bench targets run in a short form here; scripts/bench.sh runs them fully.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
BUILD_DIR=${BUILD_DIR:-build}
ctest --test-dir "$BUILD_DIR" --output-on-failure --parallel 2 --timeout 900 "$@"
