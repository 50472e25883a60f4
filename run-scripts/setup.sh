#!/usr/bin/env bash
# Installs the system packages contact-par needs (Debian) and builds it in release mode.
#   bash run-scripts/setup.sh            # packages + release build
#   bash run-scripts/setup.sh --deps     # packages only
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
# The python3 packages are the tests': VTK's readers (tests/vtk_reader.rs), SciPy and
# Gmsh for the independent Newton solver of tests/tolerance.rs (run-scripts/pdas_friction.py).
PKGS="openmpi-bin libopenmpi-dev libmetis-dev libmumps-dev libclang-dev pkg-config python3-vtk9 python3-scipy python3-gmsh"
missing=""
for p in $PKGS; do
  dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
  echo "setup: installing$missing"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
fi

if [ "${1:-}" = "--deps" ]; then exit 0; fi
cargo build --release --workspace
echo "setup: built target/release/contact-par"
