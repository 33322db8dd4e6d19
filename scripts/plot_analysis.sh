#!/usr/bin/env bash
# Plots a `kinegen analyze` CSV against time with gnuplot (Debian: gnuplot-nox): coordinates,
# velocities and accelerations in three panels, one curve per column.
#
#   scripts/plot_analysis.sh FILE.csv [-o OUT.png|OUT.svg] [--only NAME[,NAME...]]
#
# OUT defaults to FILE.png; its extension picks PNG or SVG. --only keeps the columns of the
# named bodies and points (e.g. --only rocker,P). Lengths and angles share a panel: x, y in the
# file's length unit, phi in radians (likewise for velocities and accelerations).
set -euo pipefail

usage() { echo "usage: $0 FILE.csv [-o OUT.png|OUT.svg] [--only NAME[,NAME...]]" >&2; exit 2; }
[[ $# -ge 1 ]] || usage
csv=$1; shift
out="${csv%.csv}.png"
only=""
while [[ $# -gt 0 ]]; do
  case $1 in
    -o|--output) [[ $# -ge 2 ]] || usage; out=$2; shift 2 ;;
    --only) [[ $# -ge 2 ]] || usage; only=$2; shift 2 ;;
    *) usage ;;
  esac
done
[[ -r $csv ]] || { echo "error: $csv: cannot read" >&2; exit 2; }
command -v gnuplot >/dev/null || { echo "error: gnuplot not found (apt-get install gnuplot-nox)" >&2; exit 2; }
header=$(head -n 1 "$csv")
[[ $header == t,* ]] || { echo "error: $csv: not a kinegen analyze CSV (no 't' column first)" >&2; exit 2; }

case $out in
  *.svg) terminal="svg size 900,900 dynamic background rgb 'white' font 'sans,11'" ;;
  *.png) terminal="pngcairo size 900,900 font 'sans,10'" ;;
  *) echo "error: $out: the output must end in .png or .svg" >&2; exit 2 ;;
esac

# The gnuplot "plot" clause for the columns whose suffix is one of $1 (e.g. "x y phi").
plot_clause() {
  local suffixes=" $1 " clause="" i=0 name body field
  IFS=, read -ra names <<<"$header"
  for name in "${names[@]}"; do
    i=$((i + 1))
    [[ $name == t ]] && continue
    body=${name%.*}; field=${name##*.}
    [[ $suffixes == *" $field "* ]] || continue
    if [[ -n $only && ",$only," != *",$body,"* ]]; then continue; fi
    clause+="${clause:+, }'$csv' using 1:$i with lines lw 1.5 title '$name'"
  done
  echo "${clause:-NaN notitle}"
}

tmp="$out.tmp-plot-$$"
trap 'rm -f "$tmp"' EXIT
gnuplot <<GNUPLOT
set terminal $terminal
set output '$tmp'
set datafile separator ','
set termoption noenhanced
set autoscale xfix
set key outside right top
set grid
set multiplot layout 3,1 title '$(basename "$csv")'
set ylabel 'position (x, y; phi in rad)'
plot $(plot_clause "x y phi")
set ylabel 'velocity (vx, vy, omega)'
plot $(plot_clause "vx vy omega")
set ylabel 'acceleration (ax, ay, alpha)'
set xlabel 't'
plot $(plot_clause "ax ay alpha")
unset multiplot
GNUPLOT
mv "$tmp" "$out"   # written whole, then renamed into place
trap - EXIT
echo "wrote $out" >&2
