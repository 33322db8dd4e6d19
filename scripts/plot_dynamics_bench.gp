# Work-precision diagram of the dynamics benchmark (bench_dynamics's CSV):
#   gnuplot -e "csv='out/bench/dynamics.csv'; out='docs/figures/dynamics_work_precision'" \
#           scripts/plot_dynamics_bench.gp
# One panel per problem: run time (s, log) against the error of the free coordinate at t1
# (rad, log); one line per method, its points the tolerances (Simbody: its accuracy; the
# generated RK4: its step sizes). Failed runs have no point; the 20 s N-four-bar run, where
# the augmented method alone reaches t1 on its branch, is left to the table.
if (!exists("csv")) csv = 'out/bench/dynamics.csv'
if (!exists("out")) out = 'docs/figures/dynamics_work_precision'
set datafile separator ','
problems = system("tail -n +2 '".csv."' | cut -d, -f1 | grep -v 'both flat' | awk '!seen[$0]++' | tr ' ' '~' | tr '\n' ' '")
methods = "kinegen~minimal kinegen~augmented generated~RK4 generated~CVODE simbody generic~DAE~(IDA)"
colors = "#1b7837 #5aae61 #762a83 #c2a5cf #000000 #d6604d"
points = "7 5 9 11 13 15"
set logscale xy
set format x "10^{%L}"
set format y "10^{%L}"
set grid xtics ytics mxtics mytics lc rgb "#dddddd"
set key top right font ",9"
set xlabel "error of z at t1 (rad)"
set ylabel "run time (s)"
set termoption noenhanced
tilde(s) = system("echo '".s."' | tr '~' ' '")
sel(p, m, col) = (strcol(1) eq p && strcol(2) eq m && strcol(8) eq "1") ? column(col) : NaN
err(p, m) = (v = sel(p, m, 5), v != v ? NaN : (v < 1e-16 ? 1e-16 : v))
n = words(problems)
set terminal pngcairo size 1400,(n > 2 ? 1000 : 520) font "sans,10"
set output out.'.png'
set multiplot layout (n > 2 ? 2 : 1),2 title "kinegen dynamics work-precision: run time against the error at t1 (log-log); points are tolerances 1e-4 .. 1e-12 (generated RK4: steps h = 1e-2 .. 1e-4)"
do for [i = 1:n] {
  p = tilde(word(problems, i))
  set title p noenhanced
  plot for [j = 1:words(methods)] csv using (err(p, tilde(word(methods, j)))):(sel(p, tilde(word(methods, j)), 4)) \
       with linespoints lw 1.5 pt int(word(points, j)) ps 1.2 lc rgb word(colors, j) title tilde(word(methods, j))
}
unset multiplot
