#!/usr/bin/python3
# make_jacksboro.py - build data/jacksboro_fault_dem.tif, TerraSynth's own
# small real DEM, from the USGS Jacksboro fault sample shipped by Debian's
# python-matplotlib-data package.
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
#
# This program is free software; you can redistribute it and/or modify it
# under the terms of the GNU General Public License as published by the Free
# Software Foundation; either version 2 of the License, or (at your option)
# any later version.  This program is distributed in the hope that it will be
# useful, but WITHOUT ANY WARRANTY; without even the implied warranty of
# MERCHANTABILITY or FITNESS FOR A PARTICULAR PURPOSE.  See the GNU General
# Public License for more details.
#
# Usage (Debian's interpreter: it has numpy and osgeo):
#   apt-get -o DPkg::Lock::Timeout=600 install -y python-matplotlib-data
#   /usr/bin/python3 data/make_jacksboro.py [--npz FILE] [OUTPUT.tif]
#
# The output is byte-for-byte reproducible for a given input file and GDAL
# version (checked with GDAL 3.6.2): no timestamps are written, and the file
# is produced under a temporary name and renamed into place.  See README.md.

import argparse
import hashlib
import os
import sys

NPZ_DEFAULT = "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz"
NPZ_SHA256 = "d493f50a33e82a4420494c54d1fca1539d177bdc27ab190bc5fe6e92f62fb637"
NODATA = -32768
DESCRIPTION = ("Jacksboro fault DEM, Campbell/Anderson counties TN, USA; USGS 3 "
               "arc-second (most likely NED), public domain; from Debian "
               "python-matplotlib-data 3.6.3-1 sample_data/jacksboro_fault_dem.npz; "
               "EPSG:4326, north edge = npz ymax, row 0 north; made by TerraSynth "
               "data/make_jacksboro.py")


def die(msg):
    sys.stderr.write("make_jacksboro: %s\n" % msg)
    sys.exit(1)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description="Build jacksboro_fault_dem.tif from "
                                 "matplotlib's sample data.")
    ap.add_argument("--npz", default=NPZ_DEFAULT, help="input npz (default: %(default)s)")
    ap.add_argument("output", nargs="?", default=os.path.join(here, "jacksboro_fault_dem.tif"),
                    help="output GeoTIFF (default: data/jacksboro_fault_dem.tif)")
    args = ap.parse_args()

    if not os.path.isfile(args.npz):
        die("%s not found; install it with:\n"
            "  apt-get -o DPkg::Lock::Timeout=600 install -y python-matplotlib-data"
            % args.npz)
    try:
        import numpy as np
        from osgeo import gdal, osr
    except ImportError as e:
        die("%s; run this script with /usr/bin/python3 (Debian's python3-numpy "
            "and python3-gdal)" % e)
    gdal.UseExceptions()

    with open(args.npz, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    if digest != NPZ_SHA256:
        sys.stderr.write("make_jacksboro: warning: %s has sha256 %s, expected %s "
                         "(python-matplotlib-data 3.6.3-1); output will differ from "
                         "README.md\n" % (args.npz, digest, NPZ_SHA256))

    with np.load(args.npz) as npz:
        z = np.ascontiguousarray(npz["elevation"])
        xmin, xmax = float(npz["xmin"]), float(npz["xmax"])
        npz_ymin, npz_ymax = float(npz["ymin"]), float(npz["ymax"])
        dx, dy = float(npz["dx"]), float(npz["dy"])

    if z.dtype != np.int16 or z.ndim != 2:
        die("unexpected elevation array %s %s" % (z.dtype, z.shape))
    h, w = z.shape
    # Latitude: "ymax" (36.44625) is the NORTH edge and row 0 is north; the
    # stored "ymin" (36.73292) is wrong: it is ymax + h*dy, one raster height
    # NORTH of ymax, where it should be ymax - h*dy.  Checked against two
    # landmarks (README.md): the DEM maximum, 1076 m, falls on Cross Mountain
    # (1077 m, 36.19833 N 84.23056 W) and the 305 m lake / 255 m river step
    # falls on Norris Dam (about 36.224 N 84.092 W) only with this reading.
    north = npz_ymax
    south = north - h * dy
    # Bounds are cell edges (area): width*dx must span xmin..xmax exactly and
    # the stored pair of latitudes must be one raster height apart.
    if abs((xmax - xmin) - w * dx) > 1e-9 or abs(abs(npz_ymin - npz_ymax) - h * dy) > 1e-9:
        die("bounds do not match the grid: %d x %d cells of %g x %g deg over "
            "x %g..%g, y %g..%g" % (w, h, dx, dy, xmin, xmax, npz_ymin, npz_ymax))
    if not npz_ymin > npz_ymax:
        die("unexpected npz latitudes ymin=%g ymax=%g: this is not the known "
            "python-matplotlib-data 3.6.3-1 file" % (npz_ymin, npz_ymax))
    if (z == NODATA).any():
        die("elevation contains the nodata value %d" % NODATA)

    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)

    mem = gdal.GetDriverByName("MEM").Create("", w, h, 1, gdal.GDT_Int16)
    # Row 0 is north (as matplotlib's imshow shows it; the landmarks agree).
    mem.SetGeoTransform((xmin, dx, 0.0, north, 0.0, -dy))
    mem.SetSpatialRef(srs)
    mem.SetMetadataItem("AREA_OR_POINT", "Area")
    mem.SetMetadataItem("TIFFTAG_IMAGEDESCRIPTION", DESCRIPTION)
    band = mem.GetRasterBand(1)
    band.SetNoDataValue(NODATA)
    band.SetUnitType("m")
    band.WriteArray(z)

    out = os.path.abspath(args.output)
    tmp = out + ".tmp.tif"
    opts = ["COMPRESS=DEFLATE", "PREDICTOR=2", "ZLEVEL=9", "TILED=YES",
            "BLOCKXSIZE=256", "BLOCKYSIZE=256"]
    try:
        # No PAM side-car: everything lives in the TIFF itself.
        gdal.SetConfigOption("GDAL_PAM_ENABLED", "NO")
        ds = gdal.GetDriverByName("GTiff").CreateCopy(tmp, mem, strict=1, options=opts)
        ds = None
        os.replace(tmp, out)
    except Exception as e:  # noqa: BLE001 - report any GDAL/OS failure plainly
        if os.path.exists(tmp):
            os.remove(tmp)
        die("cannot write %s: %s" % (out, e))
    mem = None

    with open(out, "rb") as f:
        sha = hashlib.sha256(f.read()).hexdigest()
    print("%s: %d x %d Int16, EPSG:4326, lon %.8f..%.8f, lat %.8f..%.8f, "
          "elevation %d..%d m" % (out, w, h, xmin, xmax, south, north, int(z.min()),
                                  int(z.max())))
    print("sha256 %s" % sha)
    return 0


if __name__ == "__main__":
    sys.exit(main())
