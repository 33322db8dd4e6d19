#!/usr/bin/env bash
# Sets everything up, then runs the main job: a position, velocity and acceleration analysis of
# the four-bar over one crank turn, and the generated header for it.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh >/dev/null
mkdir -p out
build/codegen/kinegen analyze examples/four_bar.yaml --t0 0 --t1 6.283185307179586 --steps 72 \
  -o out/four_bar.csv
build/codegen/kinegen generate examples/four_bar.yaml -o out
echo "four-bar, every 12th row of out/four_bar.csv (t, crank.phi, coupler.phi, rocker.phi, P.x, P.y):"
awk -F, 'NR == 1 || (NR - 2) % 12 == 0 { printf "%-22s %-22s %-22s %-22s %-22s %-22s\n", $1, $4, $13, $22, $(NF-5), $(NF-4) }' out/four_bar.csv
echo "wrote out/four_bar.csv and out/four_bar.hpp"
