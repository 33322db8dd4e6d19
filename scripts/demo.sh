#!/usr/bin/env bash
# Sets everything up, then runs the main job: a position, velocity and acceleration analysis of
# the four-bar over one crank turn, and the generated header for it. One line per stage, and
# the build's progress (scripts/build_progress.sh); each stage's whole output goes to
# out/setup.log, whose last lines are shown when a stage fails. It builds only what it runs,
# the `kinegen` executable (scripts/test.sh builds the rest in the same build/).
#   demo.sh [--targets]   --targets: print the build targets, one a line, and do nothing else
#                         (the test demo_targets checks they leave the tests out)
set -euo pipefail
cd "$(dirname "$0")/.."
targets=(kinegen)
case "${1:-}" in
  --targets) printf '%s\n' "${targets[@]}"; exit 0 ;;
  "") ;;
  *) echo "usage: scripts/demo.sh [--targets]" >&2; exit 2 ;;
esac
mkdir -p out
log=out/setup.log
: >"$log"
# Each stage's line says how long the one before took (SECONDS: bash's clock, whole seconds).
last=$SECONDS
stage() {
  printf 'demo: %s\n' "$*"
}
took() {
  printf 'demo:   (%d s)\n' "$((SECONDS - last))"
  last=$SECONDS
}
failed() {
  printf 'demo: %s failed; the last lines of %s:\n' "$1" "$log" >&2
  tail -n 30 "$log" >&2
  exit 1
}
stage "installing packages (only those missing; apt-get may ask for your password)"
scripts/setup.sh packages >>"$log" 2>&1 || failed "installing packages"
took
stage "building kinegen (minutes on 2 cores; less when done before)"
scripts/setup.sh build "${targets[@]}" 2>&1 | tee -a "$log" | scripts/build_progress.sh ||
  failed "building"
took
stage "analyzing the four-bar over one crank turn, and generating its header"
build/codegen/kinegen analyze examples/four_bar.yaml --t0 0 --t1 6.283185307179586 --steps 72 \
  -o out/four_bar.csv
build/codegen/kinegen generate examples/four_bar.yaml -o out
echo "four-bar, every 12th row of out/four_bar.csv (t, crank.phi, coupler.phi, rocker.phi, P.x, P.y):"
awk -F, 'NR == 1 || (NR - 2) % 12 == 0 { printf "%-22s %-22s %-22s %-22s %-22s %-22s\n", $1, $4, $13, $22, $(NF-5), $(NF-4) }' out/four_bar.csv
echo "wrote out/four_bar.csv and out/four_bar.hpp"
took
printf 'demo: done in %d s\n' "$SECONDS"
