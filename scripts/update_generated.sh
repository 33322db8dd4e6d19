#!/usr/bin/env bash
# Regenerates the committed headers in generated/ from examples/*.yaml and examples/*/*.yaml.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build >/dev/null
cmake --build build --target kinegen -j"$(nproc)" >/dev/null
rm -f generated/*.hpp
for mech in examples/*.yaml examples/*/*.yaml; do
  # Spatial examples are not committed as headers yet (see cmake/check_generated.cmake).
  [[ $mech == examples/spatial/* ]] && continue
  build/codegen/kinegen generate "$mech" -o generated
done
