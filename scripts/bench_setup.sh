#!/usr/bin/env bash
# Installs the benchmark-only Debian packages: the peers (SolveSpace's solver library,
# Simbody), gnuplot for the figures, Google Benchmark. Safe to run again; the test suite
# needs none of them.
set -euo pipefail
packages=(libslvs1-dev libsimbody-dev gnuplot-nox libbenchmark-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  SUDO=""
  [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  $SUDO apt-get update
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
fi
