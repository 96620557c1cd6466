#!/usr/bin/env bash
# Install, build, and run the main job on the default data in data/:
# the ridge and valley axes of the Jacksboro fault DEM, as a raster,
# GeoPackage lines and a preview PNG in out/.
# SPDX-License-Identifier: GPL-2.0-or-later
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"
mkdir -p out
build/gdal_driver/terrasynth ppa data/jacksboro_fault_dem.tif out/jacksboro_axes.tif --both \
  --lines out/jacksboro_axes.gpkg --preview out/jacksboro_axes.png
echo "wrote out/jacksboro_axes.tif, out/jacksboro_axes.gpkg, out/jacksboro_axes.png"
