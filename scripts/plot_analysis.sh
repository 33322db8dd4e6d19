#!/usr/bin/env bash
# Plots a `kinegen analyze` CSV against time with gnuplot (Debian: gnuplot-nox): coordinates,
# velocities and accelerations in three panels, one curve per column.
#
#   scripts/plot_analysis.sh FILE.csv [-o OUT.png|OUT.svg] [--only NAME[,NAME...]]
#   scripts/plot_analysis.sh FILE.csv [MORE.csv...] --columns COL[,COL...] [--ylabel TEXT] [-o OUT]
#
# OUT defaults to FILE.png; its extension picks PNG or SVG. --only keeps the columns of the
# named bodies and points (e.g. --only rocker,P). Lengths and angles share a panel: x, y in the
# file's length unit, phi in radians (likewise for velocities and accelerations).
# --columns plots exactly the named columns (any of the CSV's, e.g. motor.effort or
# d(P.x)/d(a)) in one panel, from every file given (each curve titled file: column).
set -euo pipefail

usage() {
  echo "usage: $0 FILE.csv [-o OUT.png|OUT.svg] [--only NAME[,NAME...]]" >&2
  echo "       $0 FILE.csv [MORE.csv...] --columns COL[,COL...] [--ylabel TEXT] [-o OUT]" >&2
  exit 2
}
[[ $# -ge 1 ]] || usage
csv=$1; shift
files=("$csv")
out="${csv%.csv}.png"
only=""
columns=""
ylabel="value"
while [[ $# -gt 0 ]]; do
  case $1 in
    -o|--output) [[ $# -ge 2 ]] || usage; out=$2; shift 2 ;;
    --only) [[ $# -ge 2 ]] || usage; only=$2; shift 2 ;;
    --columns) [[ $# -ge 2 ]] || usage; columns=$2; shift 2 ;;
    --ylabel) [[ $# -ge 2 ]] || usage; ylabel=$2; shift 2 ;;
    -*) usage ;;
    *) files+=("$1"); shift ;;
  esac
done
[[ ${#files[@]} -eq 1 || -n $columns ]] || { echo "error: more than one CSV needs --columns" >&2; exit 2; }
command -v gnuplot >/dev/null || { echo "error: gnuplot not found (apt-get install gnuplot-nox)" >&2; exit 2; }
for f in "${files[@]}"; do
  [[ -r $f ]] || { echo "error: $f: cannot read" >&2; exit 2; }
  [[ $(head -n 1 "$f") == t,* ]] || { echo "error: $f: not a kinegen analyze CSV (no 't' column first)" >&2; exit 2; }
done
header=$(head -n 1 "$csv")

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

# Gnuplot strings are single-quoted; a quote in a name or label would end them.
for text in "$ylabel" "$columns" "${files[@]}"; do
  [[ $text != *"'"* ]] || { echo "error: quotes are not allowed in names and labels" >&2; exit 2; }
done

tmp="$out.tmp-plot-$$"
trap 'rm -f "$tmp"' EXIT

# The lines both kinds of plot start with, for terminal $1 (into the temporary file).
preamble() {
  cat <<GNUPLOT
set terminal $1
set output '$tmp'
set datafile separator ','
set termoption noenhanced
set autoscale xfix
set key outside right top
set grid
GNUPLOT
}

# The picture is written whole, then renamed into place.
finish() {
  mv "$tmp" "$out"
  trap - EXIT
  echo "wrote $out" >&2
}

if [[ -n $columns ]]; then
  # The named columns, found by name in each file's own header.
  clause=""
  IFS=, read -ra wanted <<<"$columns"
  for f in "${files[@]}"; do
    IFS=, read -ra names <<<"$(head -n 1 "$f")"
    for col in "${wanted[@]}"; do
      i=0 found=0
      for name in "${names[@]}"; do
        i=$((i + 1))
        if [[ $name == "$col" ]]; then found=$i; break; fi
      done
      [[ $found -gt 0 ]] || { echo "error: $f: no column '$col'" >&2; exit 2; }
      title=$col
      [[ ${#files[@]} -gt 1 ]] && title="$(basename "$f" .csv): $col"
      clause+="${clause:+, }'$f' using 1:$found with lines lw 1.5 title '$title'"
    done
  done
  {
    preamble "${terminal/900,900/900,450}"
    cat <<GNUPLOT
set title '$(basename "$csv")'
set xlabel 't'
set ylabel '$ylabel'
plot $clause
GNUPLOT
  } | gnuplot
  finish
  exit 0
fi

{
  preamble "$terminal"
  cat <<GNUPLOT
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
} | gnuplot
finish
