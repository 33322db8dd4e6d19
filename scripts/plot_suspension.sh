#!/usr/bin/env bash
# Plots a suspension corner's curves with gnuplot (Debian: gnuplot-nox): toe, camber, caster and
# kingpin inclination in degrees against wheel travel (the file's own motion, rack held), and
# against rack travel at the design height (one analysis per rack position, `--param`).
#
#   scripts/plot_suspension.sh KINEGEN FILE.yaml OUT.png [--rack PARAM --rack-range MM]
#
# FILE.yaml has a `suspension:` block and drives its wheel travel over t in [0, 1] (as
# examples/spatial/double_wishbone.yaml does). --rack names the parameter that sets the rack's
# position (metres) and --rack-range its half range in millimetres (default 60); without --rack,
# only the wheel-travel panel is drawn.
set -euo pipefail

usage() {
  echo "usage: $0 KINEGEN FILE.yaml OUT.png [--rack PARAM] [--rack-range MM]" >&2
  exit 2
}
[[ $# -ge 3 ]] || usage
kinegen=$1 yaml=$2 out=$3
shift 3
rack="" range=60
while [[ $# -gt 0 ]]; do
  case $1 in
    --rack) [[ $# -ge 2 ]] || usage; rack=$2; shift 2 ;;
    --rack-range) [[ $# -ge 2 ]] || usage; range=$2; shift 2 ;;
    *) usage ;;
  esac
done
[[ $out == *.png ]] || { echo "error: $out: the output must end in .png" >&2; exit 2; }
command -v gnuplot >/dev/null || { echo "error: gnuplot not found (apt-get install gnuplot-nox)" >&2; exit 2; }
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT

# Prints the named columns of a kinegen CSV, space-separated, the header left out.
columns() {
  awk -F, -v want="$2" 'NR == 1 { n = split(want, w, " "); for (i = 1; i <= NF; ++i) at[$i] = i;
    for (k = 1; k <= n; ++k) if (!(w[k] in at)) { print "error: no column " w[k] > "/dev/stderr"; exit 2 }
    next }
    { line = ""; for (k = 1; k <= n; ++k) line = line (k > 1 ? " " : "") $(at[w[k]]); print line }' "$1"
}
angles="toe camber caster kpi"
"$kinegen" analyze "$yaml" --t0 0 --t1 1 --steps 160 -o "$dir/travel.csv"
columns "$dir/travel.csv" "wheel_travel $angles" >"$dir/travel.dat"
panels=1
if [[ -n $rack ]]; then
  panels=2
  : >"$dir/rack.dat"
  design_t=$(sed -n 's/^ *design_t: *\([0-9.eE+-]*\).*/\1/p' "$yaml")
  design_t=${design_t:-0}
  for k in $(seq -20 20); do
    position=$(awk -v k="$k" -v r="$range" 'BEGIN { printf "%.6f", k * r / 20000 }')
    "$kinegen" analyze "$yaml" --t0 "$design_t" --t1 "$design_t" --steps 1 \
      --param "$rack=$position" -o "$dir/one.csv"
    columns "$dir/one.csv" "$angles" | head -n 1 | sed "s/^/$position /" >>"$dir/rack.dat"
  done
fi
name=$(basename "$yaml" .yaml)
{
  echo "set terminal pngcairo size $((520 * panels)),440 font 'sans,10'"
  echo "set output '$out'"
  echo "set multiplot layout 1,$panels title '$name' noenhanced"
  echo "set grid; set key top left; set autoscale xfix; set ylabel 'angle (deg)'"
  echo "d = 180 / pi"
  echo "set xlabel 'wheel travel (mm), rack held'"
  echo "plot '$dir/travel.dat' u (\$1*1000):(\$2*d) w l lw 2 t 'toe', \
    '' u (\$1*1000):(\$3*d) w l lw 2 t 'camber', '' u (\$1*1000):(\$4*d) w l lw 2 t 'caster', \
    '' u (\$1*1000):(\$5*d) w l lw 2 t 'kingpin inclination'"
  if [[ -n $rack ]]; then
    echo "set xlabel 'rack travel (mm), design height'"
    echo "plot '$dir/rack.dat' u (\$1*1000):(\$2*d) w l lw 2 t 'toe', \
      '' u (\$1*1000):(\$3*d) w l lw 2 t 'camber', '' u (\$1*1000):(\$4*d) w l lw 2 t 'caster', \
      '' u (\$1*1000):(\$5*d) w l lw 2 t 'kingpin inclination'"
  fi
  echo "unset multiplot"
} | gnuplot
