#!/usr/bin/env bash
# Scaling benchmark (not a test): for each mechanism family and size N, writes the mechanism
# (scripts/mechanism_family.py), generates its header, compiles bench/scale_step.cpp on it with
# g++ -O2, and times a full step. Prints a table and writes out/bench/scale.csv; with --plot
# also docs/figures/scale.svg and scale.png (gnuplot).
#
#   scripts/bench_scale.sh [--n "10 30 100 300 1000"] [--families "fourbar_chain ..."]
#                          [--compile-max N] [--dense-max NQ] [--plot] [--plot-only]
#
# Columns: family, N, nq; generation wall time [s] and peak memory [MB] of `kinegen generate`;
# compile time [s] of the generated functions alone (phi, phi_q, nu, gamma for double) and one
# evaluation of all four [ns]; compile time [s] of the block-solver step program and ns per
# full step (position to 1e-10 scaled step, velocity, acceleration; Taylor predictor; mean
# Newton iterations of the largest block); the dense Newton step [ns] for nq <= --dense-max.
# Sizes above --compile-max are generated only (compiling them takes minutes).
set -euo pipefail
cd "$(dirname "$0")/.."

sizes="10 30 100 300 1000"
families="fourbar_chain scissor_lift closed_chain"
compile_max=1000
dense_max=400
plot=0
measure=1
while (($#)); do
  case "$1" in
    --n) sizes="$2"; shift 2 ;;
    --families) families="$2"; shift 2 ;;
    --compile-max) compile_max="$2"; shift 2 ;;
    --dense-max) dense_max="$2"; shift 2 ;;
    --plot) plot=1; shift ;;
    --plot-only) plot=1; measure=0; shift ;;  # plot an existing out/bench/scale.csv
    *) echo "error: unknown option '$1' (see the header of $0)" >&2; exit 2 ;;
  esac
done

kinegen=build/codegen/kinegen
if [[ ! -x $kinegen ]]; then
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build build --target kinegen -j2 >/dev/null
fi
work=out/bench/scale
mkdir -p "$work" out/bench
csv=out/bench/scale.csv
eigen=$(pkg-config --cflags eigen3)
cxx=(g++ -O2 -std=c++17 $eigen -Iruntime/include)

# Wall seconds and peak MB of a command, as "SECONDS MB"; the command's output goes to $log.
timed() {
  local log=$1
  shift
  /usr/bin/time -f "%e %M" -o "$work/time.txt" "$@" >"$log" 2>&1 || return 1
  awk '{printf "%s %.0f\n", $1, $2 / 1024}' "$work/time.txt"
}
field() { awk -v k="$1" '{for (i = 1; i < NF; ++i) if ($i == k) print $(i + 1)}' "$2"; }

if ((measure)); then
echo "family,N,nq,gen_s,gen_mb,compile_functions_s,eval_ns,compile_step_s,step_ns,iterations,dense_step_ns" >"$csv"
printf "%-14s %5s %6s %7s %6s %9s %10s %9s %10s %5s %12s\n" family N nq gen_s gen_MB \
  compile_fn eval_ns compile_st step_ns iter dense_ns
for family in $families; do
  for n in $sizes; do
    name=${family}_$n
    python3 scripts/mechanism_family.py "$family" "$n" -o "$work/$name.yaml"
    read -r gen_s gen_mb < <(timed "$work/$name.gen.log" $kinegen generate "$work/$name.yaml" -o "$work")
    nq=$(sed -n 's/.*static constexpr int nq = \([0-9]*\);.*/\1/p' "$work/$name.hpp" | head -1)
    defs=(-DKINEGEN_SCALE_HEADER="\"$name.hpp\"" -DKINEGEN_SCALE_MODEL="$name" -I"$work")
    cfn=- eval_ns=- cst=- step_ns=- iter=- dense=-
    if ((n <= compile_max)); then
      if read -r cfn _ < <(timed "$work/$name.cfn.log" "${cxx[@]}" -DKINEGEN_SCALE_FUNCTIONS_ONLY \
        "${defs[@]}" bench/scale_step.cpp -o "$work/$name.fn"); then
        "$work/$name.fn" 200 3 >"$work/$name.fn.out" && eval_ns=$(field ns_per_evaluation "$work/$name.fn.out")
      fi
      if read -r cst _ < <(timed "$work/$name.cst.log" "${cxx[@]}" "${defs[@]}" bench/scale_step.cpp \
        -o "$work/$name.step"); then
        if "$work/$name.step" 300 3 >"$work/$name.step.out"; then
          step_ns=$(field ns_per_step "$work/$name.step.out")
          iter=$(field iterations "$work/$name.step.out")
        fi
      fi
      if ((nq <= dense_max)); then
        if timed "$work/$name.cd.log" "${cxx[@]}" -DKINEGEN_SCALE_DYNAMIC "${defs[@]}" \
          bench/scale_step.cpp -o "$work/$name.dense" >/dev/null; then
          "$work/$name.dense" 30 3 >"$work/$name.dense.out" && dense=$(field ns_per_step "$work/$name.dense.out")
        fi
      fi
    fi
    echo "$family,$n,$nq,$gen_s,$gen_mb,$cfn,$eval_ns,$cst,$step_ns,$iter,$dense" >>"$csv"
    printf "%-14s %5s %6s %7s %6s %9s %10s %9s %10s %5s %12s\n" "$family" "$n" "$nq" "$gen_s" \
      "$gen_mb" "$cfn" "$eval_ns" "$cst" "$step_ns" "$iter" "$dense"
  done
done
echo "wrote $csv"
fi

if ((plot)); then
  mkdir -p docs/figures
  for term in "svg size 1100,420 dynamic font 'sans,12'" "pngcairo size 1100,420 font 'sans,10'"; do
    ext=${term%% *}; ext=${ext/pngcairo/png}
    gnuplot <<EOF
set terminal $term
set output 'docs/figures/scale.$ext'
set termoption noenhanced
set datafile separator ','
set datafile missing '-'
set key top left
set logscale xy
set grid
set xlabel 'coordinates nq'
set multiplot layout 1,3
set title 'kinegen generate [s]'
plot for [f in "$families"] '$csv' using (strcol(1) eq f ? \$3 : NaN):4 with linespoints title f
set title 'g++ -O2, generated functions [s]'
plot for [f in "$families"] '$csv' using (strcol(1) eq f ? \$3 : NaN):6 with linespoints title f
set title 'full step, block solver [ns]'
plot for [f in "$families"] '$csv' using (strcol(1) eq f ? \$3 : NaN):9 with linespoints title f
unset multiplot
EOF
  done
  echo "wrote docs/figures/scale.svg, docs/figures/scale.png"
fi
