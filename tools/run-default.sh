#!/usr/bin/env bash
# Install, build, and run the main job on the default data in data/: a
# terrain that follows the lambda sketch (Zhou et al. 2007, Fig. 10a) in the
# style of the Jacksboro fault DEM, with its preview; and the ridge and valley
# axes of the DEM as a raster, GeoPackage lines and a preview; the DEM
# averaged to cells 4 times coarser and amplified back to its own cells with
# the detail of the real terrain; a 1024 x 1024
# terrain grown cell by cell in its style (pixel synthesis); all in out/.
# SPDX-License-Identifier: GPL-2.0-or-later
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"
mkdir -p out
build/gdal_driver/terrasynth ppa data/jacksboro_fault_dem.tif out/jacksboro_axes.tif --both \
  --lines out/jacksboro_axes.gpkg --preview out/jacksboro_axes.png
build/gdal_driver/terrasynth synth --sketch data/sketches/lambda_ridges.tif \
  --exemplar data/jacksboro_fault_dem.tif --seed 1 out/lambda.tif --preview out/lambda.png
gdalwarp -q -overwrite -tr 0.0033333333333333 0.0033333333333333 -r average \
  data/jacksboro_fault_dem.tif out/jacksboro_coarse.tif
build/gdal_driver/terrasynth amplify out/jacksboro_coarse.tif out/jacksboro_x4.tif \
  --exemplar data/jacksboro_fault_dem.tif --factor 4 --preview out/jacksboro_x4.png
build/gdal_driver/terrasynth pixel --exemplar data/jacksboro_fault_dem.tif --size 1024x1024 \
  --seed 1 out/pixel.tif --preview out/pixel.png
echo "wrote out/lambda.tif and out/lambda.png (the terrain), out/jacksboro_axes.tif,"
echo "out/jacksboro_axes.gpkg and out/jacksboro_axes.png (ridges and valleys of the DEM),"
echo "out/jacksboro_x4.tif and out/jacksboro_x4.png (the DEM, averaged 4 x 4, amplified back),"
echo "out/pixel.tif and out/pixel.png (a terrain grown cell by cell in the DEM's style)"
