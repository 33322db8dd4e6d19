#!/usr/bin/env bash
# The dynamics examples' figures (docs/figures/dynamics_*.png): each example simulated by
# `kinegen simulate` and plotted by scripts/plot_dynamics.sh; the press and the four-bar also
# animated from their simulated motion (the free coordinate's column as an --input table, so
# that `animate` replays it).
#   scripts/make_dynamics_figures.sh [path/to/kinegen]   (default: build/codegen/kinegen)
set -euo pipefail
cd "$(dirname "$0")/.."
kinegen=${1:-build/codegen/kinegen}
out=docs/figures
mkdir -p "$out"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
ex=examples/dynamics
"$kinegen" simulate $ex/pendulum.yaml --t1 6 --steps 600 --rtol 1e-10 -o "$dir/pendulum.csv"
"$kinegen" simulate $ex/press_flywheel.yaml --t1 6 --steps 1200 -o "$dir/press_flywheel.csv"
"$kinegen" simulate $ex/cam_liftoff.yaml --t1 5 --steps 1000 --forces -o "$dir/cam_liftoff.csv"
"$kinegen" simulate $ex/four_bar_damped.yaml --t1 20 --steps 2000 -o "$dir/four_bar_damped.csv"
"$kinegen" simulate $ex/andrews.yaml --t1 0.03 --steps 600 --rtol 1e-12 -o "$dir/andrews.csv"
for name in pendulum press_flywheel cam_liftoff four_bar_damped andrews; do
  scripts/plot_dynamics.sh $name "$dir/$name.csv" -o "$out/dynamics_$name.png"
done
# `animate` replays a simulated motion: the free coordinate as a table (t,value).
table() { awk -F, -v col="$2" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == col) c = i;
  print "t,value"; next } { print $1 "," $c }' "$1"; }
table "$dir/press_flywheel.csv" theta > "$dir/press_theta.csv"
"$kinegen" animate $ex/press_flywheel.yaml --t0 0 --t1 6 --steps 300 --width 480 \
  --input theta="$dir/press_theta.csv" -o "$out/dynamics_press_flywheel.svg"
table "$dir/four_bar_damped.csv" theta > "$dir/four_bar_theta.csv"
"$kinegen" animate $ex/four_bar_damped.yaml --t0 0 --t1 10 --steps 300 --width 480 \
  --input theta="$dir/four_bar_theta.csv" -o "$out/dynamics_four_bar_damped.svg"
