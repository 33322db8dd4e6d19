#!/usr/bin/env bash
# Fuzzes the loader, the expression parser, the symbolic pipeline, the emitter and a short run
# (analyze, or simulate for a file with free:) with libFuzzer, under AddressSanitizer and
# UndefinedBehaviorSanitizer.
#   scripts/fuzz.sh [SECONDS] [extra libFuzzer options...]   (default 600 s)
# Builds with clang in build-fuzz/; the seed corpus is examples/*.yaml, examples/*/*.yaml,
# tests/mechanisms/*.yaml, tests/stability/*.yaml and fuzz/seeds/*.yaml (the driver
# forms: pieces, period, table, input), with the format's words in fuzz/mechanism.dict; the
# growing corpus lives in build-fuzz/corpus, crashes in build-fuzz/artifacts.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-600}"
shift || true
cxx="${CXX_FUZZ:-$(command -v clang++ || command -v clang++-14)}"
flags="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined"
# RelWithDebInfo's own flags (-O2 -g) would follow CMAKE_CXX_FLAGS and win: set them here.
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER="$cxx" \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DKINEGEN_BUILD_PYTHON=OFF \
  -DCMAKE_CXX_FLAGS="$flags" -DKINEGEN_BUILD_TESTS=OFF -DKINEGEN_BUILD_BENCHMARKS=OFF \
  -DKINEGEN_BUILD_FUZZ=ON >/dev/null
cmake --build build-fuzz -j2 --target fuzz_mechanism
mkdir -p build-fuzz/corpus build-fuzz/seeds build-fuzz/artifacts
cp examples/*.yaml examples/*/*.yaml tests/mechanisms/*.yaml build-fuzz/seeds/
cp tests/stability/*.yaml build-fuzz/seeds/ 2>/dev/null || true
cp fuzz/seeds/*.yaml build-fuzz/seeds/
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
build-fuzz/fuzz/fuzz_mechanism build-fuzz/corpus build-fuzz/seeds \
  -max_total_time="$seconds" -max_len=8192 -timeout=20 -rss_limit_mb=4096 \
  -artifact_prefix=build-fuzz/artifacts/ -dict=fuzz/mechanism.dict -print_final_stats=1 "$@"
