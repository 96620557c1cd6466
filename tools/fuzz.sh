#!/usr/bin/env bash
# Build and run a libFuzzer target for a bounded time (default 60 s): the recipe
# parser, the dictionary format or a sketch in tiles as bytes:
# tools/fuzz.sh [SECONDS] [recipe|dictionary|sketch_tiles]
# SPDX-License-Identifier: GPL-2.0-or-later
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
target=${2:-recipe}
command -v clang >/dev/null || { echo "fuzz: clang not installed"; exit 1; }
out=build-fuzz
mkdir -p "$out/corpus"
cp tests/fuzz/corpus/* "$out/corpus/"
san="-fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined"
cc="clang -std=c11 -D_GNU_SOURCE -D_POSIX_C_SOURCE=200809L -O1 -g $san -Wall -Wextra -Werror"
inc="-I algorithms/include -I algorithms/src/base -I algorithms/src/ppa -I algorithms/src/fill -I algorithms/src/sketch -I gdal_driver/io -I gdal_driver/jobs -I gdal_driver/recipe $(pkg-config --cflags gdal proj fftw3f fftw3)"
version=$(sed -n 's/^project(TerraSynth VERSION \([0-9.]*\).*/\1/p' CMakeLists.txt)
# A fuzzer of the core alone (tests/fuzz/fuzz_NAME.c) built and run on the seeds in CORPUS.
core_fuzz() {
  name=$1 corpus=$2 what=$3
  $cc -I algorithms/include -DTS_BUILDING_LIBRARY -o "$out/fuzz_$name" \
    "tests/fuzz/fuzz_$name.c" algorithms/src/*.c algorithms/src/*/*.c \
    -I algorithms/src/base -I algorithms/src/ppa -I algorithms/src/fill -I algorithms/src/sketch \
    -I algorithms/src/pixel -I algorithms/src/amplify \
    -DTS_VERSION_STRING="\"$version\"" $(pkg-config --cflags --libs fftw3f fftw3) -lm -lpthread
  ASAN_OPTIONS=detect_leaks=1 "$out/fuzz_$name" -max_total_time="$secs" \
    -rss_limit_mb=4096 -timeout=20 "$corpus" 2>&1 | tail -n 5
  echo "fuzz: $secs s of $what without a crash"
}
if [ "$target" = dictionary ] || [ "$target" = sketch_tiles ]; then
  cli=build/gdal_driver/terrasynth
  [ -x "$cli" ] || { echo "fuzz: build the CLI first (it makes the seeds)"; exit 1; }
fi
if [ "$target" = dictionary ]; then
  # seeds: the dictionaries of a small build (the file's 16-byte header cut)
  mkdir -p "$out/dict_corpus"
  for f in 2 3; do
    "$cli" dictionary build "$out/seed$f.tsd" --exemplar data/jacksboro_fault_dem.tif \
      --resolution 45 --factor $f --atoms 64 -q 2>/dev/null || true
    [ -f "$out/seed$f.tsd" ] && tail -c +17 "$out/seed$f.tsd" > "$out/dict_corpus/seed$f" &&
      rm -f "$out/seed$f.tsd"
  done
  core_fuzz dictionary "$out/dict_corpus" dictionaries
  exit 0
fi
if [ "$target" = sketch_tiles ]; then
  # seeds: the coarse passes of two small recipes (K = 1 and 2; the file's 8-byte header cut)
  mkdir -p "$out/tiles_corpus"
  for k in 1 2; do
    "$cli" synth --exemplar data/jacksboro_fault_dem.tif --sketch \
      data/sketches/ridges_valleys.geojson --resolution 0.0025 --tiled 128 --patch-size 32 \
      --overlap 8 --amplify-factor $k --seed 1 --recipe "$out/seed$k.tsyn" -q 2>/dev/null || true
    [ -f "$out/seed$k.tsyn.coarse" ] && tail -c +9 "$out/seed$k.tsyn.coarse" > "$out/tiles_corpus/seed$k"
    rm -f "$out/seed$k.tsyn" "$out/seed$k.tsyn.coarse"
  done
  core_fuzz sketch_tiles "$out/tiles_corpus" "sketches in tiles"
  exit 0
fi
# the parser and everything it calls (core included) built instrumented
$cc $inc -DTS_BUILDING_LIBRARY -DTS_VERSION_STRING="\"$version\"" -o "$out/fuzz_recipe" \
  tests/fuzz/fuzz_recipe.c gdal_driver/recipe/*.c gdal_driver/jobs/*.c gdal_driver/io/*.c \
  algorithms/src/*.c algorithms/src/*/*.c \
  $(pkg-config --libs gdal proj fftw3f fftw3) -lm -lpthread
# a recipe can name inputs that do not exist: GDAL's own allocations are not ours
ASAN_OPTIONS=detect_leaks=1 "$out/fuzz_recipe" -max_total_time="$secs" -rss_limit_mb=4096 \
  -timeout=20 "$out/corpus" 2>&1 | tail -n 5
echo "fuzz: $secs s without a crash"
