#!/usr/bin/env bash
# Plots a `kinegen simulate` CSV of one of the dynamics examples (examples/dynamics/) with
# gnuplot (Debian: gnuplot-nox): the quantities that tell each example's story, in panels,
# with the energy columns in the last one.
#
#   scripts/plot_dynamics.sh EXAMPLE FILE.csv [-o OUT.png]
#
# EXAMPLE: pendulum, press_flywheel, cam_liftoff, four_bar_damped or andrews (the CSV must be
# that example's, --forces for cam_liftoff). OUT defaults to FILE.png.
set -euo pipefail
usage() { echo "usage: $0 EXAMPLE FILE.csv [-o OUT.png]" >&2; exit 2; }
[[ $# -ge 2 ]] || usage
example=$1 csv=$2; shift 2
out="${csv%.csv}.png"
while [[ $# -gt 0 ]]; do
  case $1 in
    -o|--output) [[ $# -ge 2 ]] || usage; out=$2; shift 2 ;;
    *) usage ;;
  esac
done
command -v gnuplot >/dev/null || { echo "error: gnuplot not found (apt-get install gnuplot-nox)" >&2; exit 2; }
[[ -r $csv ]] || { echo "error: $csv: cannot read" >&2; exit 2; }
[[ $(head -n 1 "$csv") == t,* ]] || { echo "error: $csv: not a kinegen simulate CSV" >&2; exit 2; }
for text in "$csv" "$out"; do
  [[ $text != *"'"* ]] || { echo "error: quotes are not allowed in file names" >&2; exit 2; }
done

# c('name'): a column by its header name.
preamble() {
  cat <<GNUPLOT
set terminal pngcairo size 900,$1 font 'sans,10'
set output '$out.tmp'
set datafile separator ','
set termoption noenhanced
set key autotitle columnheader outside right top
set grid
set autoscale xfix
c(name) = column(name)
f = '$csv'
GNUPLOT
}
energy_panel() {
  cat <<GNUPLOT
set ylabel 'energy (J)'
set xlabel 't (s)'
plot f using (c('t')):(c('energy.kinetic')) with lines lw 1.5 title 'kinetic', \
     f using (c('t')):(c('energy.potential')) with lines lw 1.5 title 'potential', \
     f using (c('t')):(c('energy.work')) with lines lw 1.5 title 'work', \
     f using (c('t')):(c('energy.balance')) with lines lw 1.5 title 'balance'
GNUPLOT
}

case $example in
  pendulum)
    { preamble 700; cat <<GNUPLOT
set multiplot layout 2,1 title 'pendulum: a rod released from horizontal'
set ylabel 'angle (rad), rate (rad/s)'
plot f using (c('t')):(c('theta')) with lines lw 1.5 title 'theta', \
     f using (c('t')):(c('theta.v')) with lines lw 1.5 title 'theta.v'
GNUPLOT
      energy_panel; echo "unset multiplot"; } | gnuplot ;;
  press_flywheel)
    { preamble 900; cat <<GNUPLOT
set multiplot layout 3,1 title 'press with a flywheel: run-up, and the speed drop at each forming stroke'
set ylabel 'crank speed (rpm)'
plot f using (c('t')):(c('crank.omega')*60/(2*pi)) with lines lw 1.5 title 'crank'
set ylabel 'ram position (m)'
plot f using (c('t')):(c('tool.x')) with lines lw 1.5 title 'tool.x', \
     0.23 with lines dt 2 lc rgb 'gray' title 'workpiece contact'
GNUPLOT
      energy_panel; echo "unset multiplot"; } | gnuplot ;;
  cam_liftoff)
    { preamble 900; cat <<GNUPLOT
set multiplot layout 3,1 title 'cam run-up until the follower lifts off (stop_when: -contact.fn)'
set ylabel 'cam speed (rad/s)'
plot f using (c('t')):(c('cam.omega')) with lines lw 1.5 title 'cam'
set ylabel 'contact force (N)'
plot f using (c('t')):(c('contact.fn')) with lines lw 1 title 'contact.fn', \
     0 with lines dt 2 lc rgb 'gray' notitle
GNUPLOT
      energy_panel; echo "unset multiplot"; } | gnuplot ;;
  four_bar_damped)
    { preamble 700; cat <<GNUPLOT
set multiplot layout 2,1 title 'four-bar under gravity, a damper on the rocker bearing: settling to rest'
set ylabel 'crank angle (rad), rate (rad/s)'
plot f using (c('t')):(c('theta')) with lines lw 1.5 title 'theta', \
     f using (c('t')):(c('theta.v')) with lines lw 1.5 title 'theta.v'
GNUPLOT
      energy_panel; echo "unset multiplot"; } | gnuplot ;;
  andrews)
    { preamble 700; cat <<GNUPLOT
set multiplot layout 2,1 title "Andrews' squeezing mechanism (Hairer and Wanner II, VII.7)"
set ylabel 'angle (rad)'
plot f using (c('t')):(c('beta') - 2*pi*floor((c('beta') + pi)/(2*pi))) with points pt 7 ps 0.3 title 'beta mod 2 pi', \
     f using (c('t')):(c('Theta') - 2*pi*floor((c('Theta') + pi)/(2*pi))) with points pt 7 ps 0.3 title 'Theta mod 2 pi', \
     f using (c('t')):(c('gamma')) with lines lw 1.5 title 'gamma', \
     f using (c('t')):(c('Phi')) with lines lw 1.5 title 'Phi', \
     f using (c('t')):(c('delta')) with lines lw 1.5 title 'delta', \
     f using (c('t')):(c('Omega')) with lines lw 1.5 title 'Omega', \
     f using (c('t')):(c('epsilon')) with lines lw 1.5 title 'epsilon'
GNUPLOT
      energy_panel; echo "unset multiplot"; } | gnuplot ;;
  *) echo "error: unknown example '$example'" >&2; exit 2 ;;
esac
mv "$out.tmp" "$out"
echo "wrote $out" >&2
