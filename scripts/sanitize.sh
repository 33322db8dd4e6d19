#!/usr/bin/env bash
# Builds the C++ tests with AddressSanitizer and UndefinedBehaviorSanitizer (g++) in build-asan/
# and runs every C++ test that reaches library code there (CTest label `cxx`: the unit tests,
# one entry per file, the allocation test, the examples' programs, analyze and check of every
# example). Any sanitizer report fails the run. What is not C++ or only compiles (the Python
# module, the page, pip, the strict compile, the benchmarks) is left to the Release build.
#   scripts/sanitize.sh [build | test]   (after scripts/setup.sh has installed the packages;
#                                         one stage only, as scripts/test.sh runs them)
set -euo pipefail
cd "$(dirname "$0")/.."
stage=${1:-all}
case "$stage" in
  all | build | test) ;;
  *) echo "usage: scripts/sanitize.sh [build | test]" >&2; exit 2 ;;
esac
jobs="${JOBS:-$(nproc)}"
# Set before the build too: the build runs the instrumented kinegen to generate test headers.
# Leak checking is off: libcln keeps a few bytes of static data unreleased at exit (LeakSanitizer
# reports 26 bytes allocated inside libcln.so.6 when kinegen generates a header).
# alloc_dealloc_mismatch is off because tests/alloc replaces the global operator new with
# malloc to count allocations, and ASan then sees its own operator new paired with free.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=0:abort_on_error=1:strict_string_checks=1:alloc_dealloc_mismatch=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
# UBSan without its null, alignment and vptr checks: a null dereference is a SEGV that ASan
# reports with its stack, a use of a destroyed object is ASan's use-after-free, and x86 reads
# misaligned data correctly; the three instrument every pointer access and every virtual call,
# and cost 40% of the compile of a test file (test_closed_form.cpp 11.5 -> 7.8 s). The checks
# that ASan cannot stand in for stay: signed overflow, shifts, array bounds, bool and enum
# loads, returns, unreachable.
flags="-fsanitize=address,undefined -fno-sanitize=null,alignment,vptr"
flags+=" -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
# -O1 -g1 (line tables for the reports' stacks): RelWithDebInfo's own -O2 -g would follow
# CMAKE_CXX_FLAGS and win, so they are set here. They halve the instrumented compile
# (test_dynamics.cpp 12.1 -> 6.3 s).
if [[ $stage != test ]]; then
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS="$flags" \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" -DKINEGEN_BUILD_BENCHMARKS=OFF \
  -DKINEGEN_STRICT_COMPILE=OFF -DKINEGEN_BUILD_PYTHON=OFF -DKINEGEN_CXX_TESTS=ON >/dev/null
cmake --build build-asan -j"$jobs"
fi
if [[ $stage != build ]]; then
  ctest --test-dir build-asan --output-on-failure -j"$jobs" -L cxx
fi
