#!/usr/bin/env bash
# Install, build, and run the main job on the default data in data/, all into out/:
# a terrain that follows a drawing of ridges and valleys given as lines (the
# headline job, with its streams as lines), one that follows the lambda sketch of
# Zhou et al. 2007 (Fig. 10a), both in the style of the Jacksboro fault DEM; the ridge and valley
# axes of the DEM as a raster, GeoPackage lines and a preview; the DEM averaged
# to cells 4 times coarser and amplified back to its own cells with the detail
# of the real terrain; a 1024 x 1024 terrain grown cell by cell in its style.
# SPDX-License-Identifier: GPL-2.0-or-later
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"
mkdir -p out
T=build/gdal_driver/terrasynth
$T synth --sketch data/sketches/ridges_valleys.geojson --like data/sketches/ridges_valleys.tif \
  --exemplar data/jacksboro_fault_dem.tif --seed 1 out/drawn.tif --preview out/drawn.png \
  --flow-lines out/drawn_streams.gpkg --flow-km2 0.5
$T synth --sketch data/sketches/lambda_ridges.tif \
  --exemplar data/jacksboro_fault_dem.tif --seed 1 out/lambda.tif --preview out/lambda.png
$T ppa data/jacksboro_fault_dem.tif out/jacksboro_axes.tif --both \
  --lines out/jacksboro_axes.gpkg --preview out/jacksboro_axes.png
gdalwarp -q -overwrite -tr 0.0033333333333333 0.0033333333333333 -r average \
  data/jacksboro_fault_dem.tif out/jacksboro_coarse.tif
$T amplify out/jacksboro_coarse.tif out/jacksboro_x4.tif \
  --exemplar data/jacksboro_fault_dem.tif --factor 4 --preview out/jacksboro_x4.png
$T pixel --exemplar data/jacksboro_fault_dem.tif --size 1024x1024 \
  --seed 1 out/pixel.tif --preview out/pixel.png
echo "wrote out/drawn.tif and out/drawn.png (the drawing of ridges and valleys as terrain),"
echo "out/drawn_streams.gpkg (its streams, with their Strahler order),"
echo "out/lambda.tif and out/lambda.png (the lambda sketch as terrain), out/jacksboro_axes.tif,"
echo "out/jacksboro_axes.gpkg and out/jacksboro_axes.png (ridges and valleys of the DEM),"
echo "out/jacksboro_x4.tif and out/jacksboro_x4.png (the DEM, averaged 4 x 4, amplified back),"
echo "out/pixel.tif and out/pixel.png (a terrain grown cell by cell in the DEM's style)"
