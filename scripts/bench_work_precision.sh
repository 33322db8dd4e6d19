#!/usr/bin/env bash
# Work-precision benchmark: installs the benchmark packages, builds bench_work_precision,
# runs it (table to the terminal and out/bench/work_precision.txt, data to
# out/bench/work_precision.csv) and draws docs/figures/work_precision.{png,svg}.
# Options are passed to the benchmark (--quick: a 10x shorter run for trying things out).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/bench_setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DKINEGEN_BUILD_BENCHMARKS=ON
cmake --build build -j"$(nproc)" --target bench_work_precision
mkdir -p out/bench docs/figures
csv=out/bench/work_precision.csv
build/bench/bench_work_precision "$csv" "$@" | tee out/bench/work_precision.txt
gnuplot -e "csv='$csv'; out='docs/figures/work_precision'" scripts/plot_work_precision.gp
echo "wrote $csv, out/bench/work_precision.txt, docs/figures/work_precision.png and .svg"
