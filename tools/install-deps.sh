#!/usr/bin/env bash
# Install TerraSynth's build and test dependencies from Debian (bookworm).
# SPDX-License-Identifier: GPL-2.0-or-later
set -euo pipefail
PKGS=(build-essential cmake pkg-config libgdal-dev gdal-bin python3-gdal python3-numpy
      python3-scipy time  # time: peak memory of a run (tests/robustness/test_limits.py, bench)
      libproj-dev proj-bin libgeographiclib-dev libfftw3-dev python3-pytest clang
      libclang-rt-14-dev
      python3-qgis qgis-providers qgis  # QGIS provider tests (tests/qgis; qgis = qgis_process)
      python3-dask python3-distributed)  # terrasynth-dask, the Dask runner (tests/cli)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO=sudo
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get -o DPkg::Lock::Timeout=600 update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get -o DPkg::Lock::Timeout=600 install -y -q \
  --no-install-recommends "${missing[@]}"
