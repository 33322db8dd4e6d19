#!/usr/bin/env bash
# Sets everything up, builds, and runs the whole test suite; then builds everything again with
# AddressSanitizer and UndefinedBehaviorSanitizer (scripts/sanitize.sh, build-asan/) and runs
# the whole suite there too. KINEGEN_SKIP_SANITIZE=1 skips the second part (quicker locally).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
ctest --test-dir build --output-on-failure -j"$(nproc)"
if [[ "${KINEGEN_SKIP_SANITIZE:-0}" != 1 ]]; then
  scripts/sanitize.sh
fi
