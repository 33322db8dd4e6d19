#!/usr/bin/env bash
# Dynamics work-precision benchmark (issue 24): installs the benchmark packages (Simbody),
# builds bench_dynamics, runs it (table to the terminal and out/bench/dynamics.txt, data to
# out/bench/dynamics.csv) and draws docs/figures/dynamics_work_precision.png.
# Options are passed to the benchmark (--quick: two tolerances, no 20 s N-four-bar run).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/bench_setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DKINEGEN_BUILD_BENCHMARKS=ON
cmake --build build -j"$(nproc)" --target bench_dynamics
mkdir -p out/bench docs/figures
csv=out/bench/dynamics.csv
build/bench/bench_dynamics "$csv" "$@" | tee out/bench/dynamics.txt
gnuplot -e "csv='$csv'; out='docs/figures/dynamics_work_precision'" scripts/plot_dynamics_bench.gp
echo "wrote $csv, out/bench/dynamics.txt and docs/figures/dynamics_work_precision.png"
