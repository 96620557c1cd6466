#!/usr/bin/python3
# bench_ppa_tiled.py - `terrasynth ppa --tile-size` (DEMs larger than memory):
# on SIZE x SIZE mirror mosaics of a real DEM (Big Tujunga, UTM 30 m), the PPA in one piece
# and in tiles, in the same run: wall seconds, peak memory, bytes per cell, cells per second,
# and whether the two rasters are the same bytes (they must be).  Sizes where the whole run
# would not fit in memory are run in tiles only.
#
#   /usr/bin/python3 bench/bench_ppa_tiled.py [--sizes 4096,8192,16384] [--tile 2048]
#        [--whole-max 8192] [--terrasynth BIN]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse
import multiprocessing
import os
import sys
import tempfile

import numpy as np
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_amplify import DEM, ROOT, spawn  # noqa: E402
from bench_ppa_grass import mosaic  # noqa: E402

gdal.UseExceptions()


def same(a, b):
    """Do rasters a and b hold the same cells?  Compared in strips (they may be large)."""
    da, db = gdal.Open(a), gdal.Open(b)
    ba, bb = da.GetRasterBand(1), db.GetRasterBand(1)
    w, h = da.RasterXSize, da.RasterYSize
    if (w, h) != (db.RasterXSize, db.RasterYSize):
        return False
    for y in range(0, h, 1024):
        n = min(1024, h - y)
        if not np.array_equal(ba.ReadAsArray(0, y, w, n), bb.ReadAsArray(0, y, w, n)):
            return False
    return True


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="4096,8192,16384")
    ap.add_argument("--tile", type=int, default=2048)
    ap.add_argument("--whole-max", type=int, default=8192,
                    help="largest size also run in one piece")
    ap.add_argument("--terrasynth",
                    default=os.path.join(ROOT, "build", "gdal_driver", "terrasynth"))
    a = ap.parse_args()
    src = os.path.join(DEM, "mountains_bigtujunga_ca_30m.tif")
    if not os.path.exists(src):
        print("bench_ppa_tiled: skipped: ../shared/data/dem not present")
        return
    print("%-7s %-6s %9s %9s %8s %10s  %s" % ("size", "run", "seconds", "peak MB", "B/cell",
                                             "Mcells/s", "same bytes as one piece"))
    with tempfile.TemporaryDirectory() as d:
        for size in [int(s) for s in a.sizes.split(",")]:
            dem = os.path.join(d, "mosaic_%d.tif" % size)
            # made in a child: a spawned run's peak would count this Python's pages (a
            # 16384^2 mosaic is GBs of arrays), as spawn's docstring warns
            child = multiprocessing.get_context("fork").Process(target=mosaic,
                                                                args=(src, size, dem))
            child.start()
            child.join()
            if child.exitcode != 0:
                sys.exit("bench_ppa_tiled: the mosaic of %d failed" % size)
            cells = size * size
            whole = os.path.join(d, "whole_%d.tif" % size)
            runs = []
            if size <= a.whole_max:
                runs.append(("whole", whole, []))
            runs.append(("tiles", os.path.join(d, "tiles_%d.tif" % size),
                         ["--tile-size", str(a.tile)]))
            for name, out, extra in runs:
                t, mb, _ = spawn([a.terrasynth, "ppa", dem, out, "--both", "-q",
                                  "--max-memory", "64G"] + extra)
                eq = ""
                if name == "tiles":
                    eq = ("yes" if same(whole, out) else "NO") if size <= a.whole_max else \
                        "(not run in one piece)"
                print("%-7d %-6s %9.2f %9.0f %8.1f %10.2f  %s" % (
                    size, name, t, mb, mb * 1048576.0 / cells, cells / t / 1e6, eq),
                    flush=True)
                if name == "whole":
                    pass
                else:
                    os.remove(out)
            if os.path.exists(whole):
                os.remove(whole)
            os.remove(dem)


if __name__ == "__main__":
    main()
