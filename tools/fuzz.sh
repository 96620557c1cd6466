#!/usr/bin/env bash
# Build and run the libFuzzer target for the recipe parser for a bounded
# time (default 60 s): tools/fuzz.sh [SECONDS]
# SPDX-License-Identifier: GPL-2.0-or-later
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
command -v clang >/dev/null || { echo "fuzz: clang not installed"; exit 1; }
out=build-fuzz
mkdir -p "$out/corpus"
cp tests/fuzz/corpus/* "$out/corpus/"
san="-fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined"
cc="clang -std=c11 -D_GNU_SOURCE -D_POSIX_C_SOURCE=200809L -O1 -g $san -Wall -Wextra -Werror"
inc="-I algorithms/include -I algorithms/src/base -I algorithms/src/ppa -I algorithms/src/fill -I algorithms/src/sketch -I gdal_driver/io -I gdal_driver/jobs -I gdal_driver/recipe $(pkg-config --cflags gdal proj fftw3f)"
# the parser and everything it calls (core included) built instrumented
version=$(sed -n 's/^project(TerraSynth VERSION \([0-9.]*\).*/\1/p' CMakeLists.txt)
$cc $inc -DTS_BUILDING_LIBRARY -DTS_VERSION_STRING="\"$version\"" -o "$out/fuzz_recipe" \
  tests/fuzz/fuzz_recipe.c gdal_driver/recipe/*.c gdal_driver/jobs/*.c gdal_driver/io/*.c \
  algorithms/src/*.c algorithms/src/*/*.c \
  $(pkg-config --libs gdal proj fftw3f) -lm -lpthread
# a recipe can name inputs that do not exist: GDAL's own allocations are not ours
ASAN_OPTIONS=detect_leaks=1 "$out/fuzz_recipe" -max_total_time="$secs" -rss_limit_mb=4096 \
  -timeout=20 "$out/corpus" 2>&1 | tail -n 5
echo "fuzz: $secs s without a crash"
