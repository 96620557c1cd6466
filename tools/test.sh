#!/usr/bin/env bash
# Install, build and run every test: a normal build, then the same suite
# under AddressSanitizer + UndefinedBehaviorSanitizer.
# SPDX-License-Identifier: GPL-2.0-or-later
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
jobs=$(nproc)

echo "== build and test (Release, as the default run builds)"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$jobs"
ctest --test-dir build --output-on-failure -j"$jobs"

echo "== build and test (AddressSanitizer + UndefinedBehaviorSanitizer)"
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DTS_SANITIZE=ON >/dev/null
cmake --build build-asan -j"$jobs"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan --output-on-failure -j"$jobs"

echo "== fuzz the recipe parser, the dictionary format and a sketch in tiles as bytes (libFuzzer, bounded time)"
tools/fuzz.sh "${TS_FUZZ_SECONDS:-60}"
tools/fuzz.sh "${TS_FUZZ_SECONDS:-60}" dictionary
tools/fuzz.sh "${TS_FUZZ_SECONDS:-60}" sketch_tiles
