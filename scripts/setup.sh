#!/usr/bin/env bash
# Installs what kinegen needs to build and test, from Debian packages, and configures and
# builds it in build/. Safe to run again.
#   setup.sh [packages | build [TARGET ...]]   one stage only (scripts/demo.sh shows them one by
#                                              one); with targets, the build makes only those
#                                              and what they need (the demo: `kinegen` alone)
set -euo pipefail
cd "$(dirname "$0")/.."
stage=${1:-all}
case "$stage" in
  all | packages) (($# <= 1)) || stage=usage ;;
  build) ;;
  *) stage=usage ;;
esac
if [[ $stage == usage ]]; then
  echo "usage: scripts/setup.sh [packages | build [TARGET ...]]" >&2
  exit 2
fi
targets=("${@:2}")
if [[ $stage != build ]]; then
  packages=(g++ cmake make pkg-config libginac-dev libcln-dev libeigen3-dev catch2
            libyaml-cpp-dev libcli11-dev python3
            libsundials-dev  # CVODE for kinegen simulate, IDA for the dynamics benchmark's peer
            pybind11-dev python3-dev python3-numpy python3-pytest  # the Python module and its tests
            python3-scipy python3-matplotlib                       # examples/python
            libpng-dev chromium gnuplot-nox  # pictures: animate test (PNG decode, headless render), plots
            zlib1g-dev  # kinegen view: the run deflated in the page
            python3-venv python3-setuptools python3-wheel  # pip install . (offline) and its test
            python3-yaml)  # scripts/check_doc_blocks.py reads the docs' YAML excerpts
  missing=()
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  # kinegen view's page (viewer/: uPlot, and playwright-core for its tests) comes from npm. Node
  # from elsewhere (NodeSource's nodejs bundles npm, and conflicts with Debian's npm) is kept.
  command -v node >/dev/null || missing+=(nodejs)
  command -v npm >/dev/null || missing+=(npm)
  if ((${#missing[@]})); then
    SUDO=""
    [[ $(id -u) -ne 0 ]] && SUDO="sudo"
    $SUDO apt-get update
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
  fi
  # The versions viewer/package-lock.json pins.
  (cd viewer && npm ci --no-audit --no-fund)
fi
if [[ $stage != packages ]]; then
  # KINEGEN_CMAKE_ARGS: more options for the configure step (scripts/test.sh passes some). The
  # demo passes none and names its targets instead: build/ caches options, and a demo that
  # turned the tests off would leave them off for a later scripts/test.sh.
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release ${KINEGEN_CMAKE_ARGS:-}
  if ((${#targets[@]})); then
    cmake --build build -j"$(nproc)" --target "${targets[@]}"
  else
    cmake --build build -j"$(nproc)"
  fi
fi
