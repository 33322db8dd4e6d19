# Work-precision diagram from bench_work_precision's CSV:
#   gnuplot -e "csv='out/bench/work_precision.csv'; out='docs/figures/work_precision'" \
#           scripts/plot_work_precision.gp
# One panel per example: time per full step (ns, log) against the largest error versus the
# reference (log); one line per method, its points the Newton tolerances (peers: their own
# accuracy settings). Failed runs have no point.
if (!exists("csv")) csv = 'out/bench/work_precision.csv'
if (!exists("out")) out = 'docs/figures/work_precision'

set datafile separator ','
examples = "slider_crank slider_crank_lecture offset_slider_crank four_bar quick_return"
methods = "generated finite-difference complex-step generic solvespace simbody"
colors = "#1b7837 #d6604d #4393c3 #762a83 #e08214 #000000"
points = "7 5 9 11 13 15"

set logscale xy
set format x "10^{%L}"
set format y "10^{%L}"
set grid xtics ytics mxtics mytics lc rgb "#dddddd"
set key top left font ",9" spacing 1.0
set xlabel "largest error vs 40-digit reference (scaled)"
set ylabel "ns per step (position + velocity + acceleration)"
set xrange [1e-17:1e-3]
set yrange [1e1:1e7]

sel(ex, m, col) = (strcol(1) eq ex && strcol(2) eq m && strcol(9) eq "ok") ? column(col) : NaN
err(ex, m) = (v = sel(ex, m, 8), v != v ? NaN : (v < 1e-17 ? 1e-17 : v))

do for [fmt in "png svg"] {
  if (fmt eq "png") {
    set terminal pngcairo size 1500,950 font "sans,10"
    set output out.'.png'
  } else {
    set terminal svg size 1500,950 font "sans,10" dynamic background rgb "white"
    set output out.'.svg'
  }
  set multiplot layout 2,3 title "kinegen work-precision: ns per full step against largest error (log-log); points are Newton tolerances 1e-4 .. 1e-14"
  do for [e = 1:words(examples)] {
    ex = word(examples, e)
    set title ex noenhanced
    plot for [m = 1:words(methods)] csv using (err(ex, word(methods, m))):(sel(ex, word(methods, m), 4)) \
         with linespoints lw 1.5 pt (word(points, m)+0) ps 1.0 lc rgb word(colors, m) title word(methods, m)
  }
  unset multiplot
  unset output
}
