#!/usr/bin/env bash
# What CI runs (.ci/run): sets everything up and builds in build/ (Release), runs the suite
# there, then builds the C++ tests with AddressSanitizer and UndefinedBehaviorSanitizer in
# build-asan/ and runs them there (scripts/sanitize.sh). The C++ unit tests are compiled once,
# in the sanitizer build; everything else (Python, the page, pip, the installed package, the
# docs' code blocks, the strict compile of every generated header) runs in the Release pass.
# Prints each pass's wall time. The sanitizer build runs beside the Release tests (see below).
# KINEGEN_SKIP_SANITIZE=1 skips the sanitizer pass and then runs the C++ unit tests in the
# Release build instead.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS
pass() {  # pass NAME COMMAND...: runs it and prints its wall time
  local name=$1 t0=$SECONDS
  shift
  echo "=== $name"
  "$@"
  echo "=== $name: $((SECONDS - t0)) s (total $((SECONDS - start)) s)"
}
# Explicit either way: build/ caches the option, and a cached OFF must not silently drop the
# C++ unit tests from a later run with the sanitizer pass skipped.
cxx_tests=OFF
[[ "${KINEGEN_SKIP_SANITIZE:-0}" == 1 ]] && cxx_tests=ON
pass "setup and Release build" env KINEGEN_CMAKE_ARGS="-DKINEGEN_CXX_TESTS=$cxx_tests" \
  scripts/setup.sh
if [[ "${KINEGEN_SKIP_SANITIZE:-0}" == 1 ]]; then
  pass "Release tests" ctest --test-dir build --output-on-failure -j"$(nproc)"
  echo "=== all passes: $((SECONDS - start)) s"
  exit 0
fi
# The sanitizer build compiles beside the Release tests, at a lower priority: those tests leave
# the cores idle much of the time (headless Chromium, pip, a consumer project's configure), and
# the build takes what they leave. Its output goes to build-asan.log, shown if it fails.
mkdir -p build-asan
nice -n 10 scripts/sanitize.sh build >build-asan.log 2>&1 &
asan_build=$!
trap 'pkill -P "$asan_build" 2>/dev/null; kill "$asan_build" 2>/dev/null || true' EXIT
pass "Release tests (the sanitizer build compiling beside them)" \
  ctest --test-dir build --output-on-failure -j"$(nproc)"
sanitizer_build() {
  wait "$asan_build" || { tail -n 60 build-asan.log; return 1; }
}
pass "sanitizer build: the rest after the Release tests" sanitizer_build
trap - EXIT
pass "sanitizer C++ tests" scripts/sanitize.sh test
echo "=== all passes: $((SECONDS - start)) s"
