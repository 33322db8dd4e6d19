#!/usr/bin/env bash
# ctest build_progress: scripts/build_progress.sh (scripts/demo.sh's view of the build) condenses
# cmake's percentage lines, one per tenth in a log and one line rewritten in place on a
# terminal, and passes compiler warnings and errors through whole.
set -euo pipefail
filter="$(dirname "$0")/../scripts/build_progress.sh"
input='-- Configuring done
-- Build files have been written to: /x/build
[  0%] Embedding the block-solver kernels
[  1%] Building CXX object codegen/CMakeFiles/kinegen_codegen.dir/src/base/format.cpp.o
[  4%] Building CXX object codegen/CMakeFiles/kinegen_codegen.dir/src/base/diagnostics.cpp.o
[ 12%] Building CXX object codegen/CMakeFiles/kinegen_codegen.dir/src/analysis/analysis.cpp.o
/x/codegen/src/analysis/analysis.cpp:3:1: warning: unused variable [-Wunused]
[ 14%] Building CXX object codegen/CMakeFiles/kinegen_codegen.dir/src/analysis/check.cpp.o
[ 55%] Linking CXX static library libkinegen_codegen.a
[100%] Built target kinegen'
want='  [  0%] embedding kernels
  [ 12%] building analysis.cpp
/x/codegen/src/analysis/analysis.cpp:3:1: warning: unused variable [-Wunused]
  [ 55%] linking libkinegen_codegen.a
  [100%] built kinegen'
got=$(printf '%s\n' "$input" | "$filter" --no-tty)
if [[ "$got" != "$want" ]]; then
  printf 'log mode: got\n%s\nwanted\n%s\n' "$got" "$want" >&2
  exit 1
fi
# On a terminal: each progress line rewrites the last (\r, erase), a warning starts a new line.
got=$(printf '%s\n' "$input" | "$filter" --tty | tr '\r\033' '|~')
want_tty='|~[K  [  0%] embedding kernels|~[K  [  1%] building format.cpp|~[K  [  4%] building diagnostics.cpp|~[K  [ 12%] building analysis.cpp
/x/codegen/src/analysis/analysis.cpp:3:1: warning: unused variable [-Wunused]
|~[K  [ 14%] building check.cpp|~[K  [ 55%] linking libkinegen_codegen.a|~[K  [100%] built kinegen'
if [[ "$got" != "$want_tty" ]]; then
  printf 'terminal mode: got\n%s\nwanted\n%s\n' "$got" "$want_tty" >&2
  exit 1
fi
echo "build_progress: ok"
