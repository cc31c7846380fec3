#!/usr/bin/env bash
# Installs the test-only npm clients from the committed lock file. Skips when they are already installed for this
# lock file, so the tests also run without network once installed.
set -euo pipefail
cd "$(dirname "$0")"
if ! command -v npm >/dev/null 2>&1; then
  echo "npm not found: install Node.js 18+ with npm to run the ecosystem tests" >&2
  exit 1
fi
if [ -f node_modules/.package-lock.json ] && [ node_modules/.package-lock.json -nt package-lock.json ]; then
  echo "npm packages already installed"
  exit 0
fi
npm ci --no-audit --no-fund
