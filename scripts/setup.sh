#!/usr/bin/env bash
# Installs every build, test and run dependency from Debian's packages. Safe to run twice.
set -euo pipefail

packages=(
  build-essential cmake ninja-build ccache pkg-config git
  clang-format clang-tidy
  libboost-dev libboost-program-options-dev
  libprotobuf-dev protobuf-compiler
  libeigen3-dev libccd-dev libfcl-dev liboctomap-dev libdynamicedt3d-dev
  libcgal-dev libgmp-dev libmpfr-dev
  libpcl-dev
  libyaml-cpp-dev zlib1g-dev libzstd-dev liblz4-dev libjemalloc-dev
  libcli11-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3
  python3-protobuf python3-venv
  libssl-dev libsqlite3-dev
  clang libclang-rt-14-dev
  redis-server redis-tools
  chromium
)
# The ecosystem tests' npm clients (tests/ecosystem) need Node.js 18+ with npm. A node that is already installed (e.g.
# NodeSource's, which bundles npm and conflicts with Debian's npm package) is used as it is.
command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1 || packages+=(nodejs npm)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages already installed"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: done"
