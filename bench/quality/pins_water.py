#!/usr/bin/python3
# pins_water.py - a pinned window and a lake in sketch terrains, in one piece and in tiles:
# whether the pinned cells are the pinned DEM's window at the output's cells (when the DEM's
# cells are the output's) and the lake's cells its level, how many cells touching the lake lie
# below it, and the mean step between 4-neighbours across the pin's border over the mean step
# 3 to 20 cells outside it (1: no trace of the border).
#
#   bench/quality/pins_water.py [--terrasynth BIN] [--seeds 1,2] [--extra "--tiled 256"]
#                               [--both "--drainage keep"]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse
import os
import subprocess
import tempfile

import numpy as np
from osgeo import gdal
from scipy import ndimage

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
DEM = os.path.join(ROOT, "..", "shared", "data", "dem")
CASES = [  # sketch, exemplar, pin window of the exemplar (x, y, w, h), at (X, Y), lake level
    # (about the 5th to 10th percentile of the land: a lake in its low ground)
    ("ridges_valleys.tif", "hills_jacksboro_tn_3arcsec.tif", (100, 100, 80, 60), (300, 80), 300),
    ("lambda_valleys.tif", "hills_jacksboro_tn_3arcsec.tif", (200, 150, 90, 70), (250, 150), 400),
    ("lambda_valleys.tif", "mountains_bigtujunga_ca_30m.tif", (500, 300, 100, 80), (250, 150), 800),
    ("ridges_valleys.tif", "mountains_mackay_id_30m.tif", (300, 200, 100, 80), (60, 60), 1900),
]


def lake_for(sketch, path):
    """An elliptic lake round (0.3 W, 0.7 H) on the sketch's grid."""
    sk = gdal.Open(sketch)
    W, H = sk.RasterXSize, sk.RasterYSize
    yy, xx = np.mgrid[0:H, 0:W]
    m = (((yy - 0.7 * H) / (0.08 * H)) ** 2 + ((xx - 0.3 * W) / (0.12 * W)) ** 2 < 1)
    ds = gdal.GetDriverByName("GTiff").Create(path, W, H, 1, gdal.GDT_Byte)
    ds.SetGeoTransform(sk.GetGeoTransform())
    ds.SetProjection(sk.GetProjection())
    ds.GetRasterBand(1).WriteArray(m.astype(np.uint8))
    ds = None
    return m


def judge(out, ex, win, at, lake, level, same_cells):
    a = gdal.Open(out).ReadAsArray().astype(np.float64)
    x0, y0, w, h = win
    X, Y = at
    pm = np.zeros(a.shape, bool)
    pm[Y:Y + h, X:X + w] = True
    exact = "-"
    if same_cells:
        pin = gdal.Open(ex).ReadAsArray()[y0:y0 + h, x0:x0 + w].astype(np.float32)
        exact = "yes" if np.array_equal(a[Y:Y + h, X:X + w].astype(np.float32), pin) else "NO"
    shore = ndimage.binary_dilation(lake, np.ones((3, 3))) & ~lake
    dx, dy = np.abs(np.diff(a, axis=1)), np.abs(np.diff(a, axis=0))
    across = np.concatenate([dx[pm[:, 1:] != pm[:, :-1]], dy[pm[1:, :] != pm[:-1, :]]])
    ring = ndimage.binary_dilation(pm, iterations=20) & ~ndimage.binary_dilation(pm, iterations=3)
    near = np.concatenate([dx[ring[:, 1:] & ring[:, :-1]], dy[ring[1:, :] & ring[:-1, :]]])
    return (exact, "yes" if (a[lake] == level).all() else "NO", int((a[shore] < level).sum()),
            across.mean() / near.mean())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build/gdal_driver/terrasynth"))
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--extra", default="--tiled 256", help="options of the second run")
    ap.add_argument("--both", default="", help="options of both runs")
    a = ap.parse_args()
    print("| sketch | exemplar | seed | run | pin exact | lake exact | shore below | "
          "border step / beside |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for sk, exn, win, at, level in CASES:
            sketch = os.path.join(ROOT, "data", "sketches", sk)
            ex = os.path.join(DEM, exn)
            if not os.path.exists(ex):
                print("skipped: %s not found" % ex)
                continue
            lake = lake_for(sketch, os.path.join(tmp, "lake.tif"))
            same = abs(gdal.Open(ex).GetGeoTransform()[1] -
                       gdal.Open(sketch).GetGeoTransform()[1]) < 1e-9
            for seed in a.seeds.split(","):
                for name, extra in (("one piece", []), (a.extra, a.extra.split())):
                    out = os.path.join(tmp, "o.tif")
                    subprocess.run([a.terrasynth, "synth", "--exemplar", ex, "--sketch", sketch,
                                    "--seed", seed, "--water", os.path.join(tmp, "lake.tif"),
                                    "--water-level", str(level), "--pin",
                                    "%s:%d,%d,%d,%d@%d,%d" % ((ex,) + win + at), *extra,
                                    *a.both.split(), out, "-q"], check=True)
                    r = judge(out, ex, win, at, lake, level, same)
                    print("| %s | %s | %s | %s | %s | %s | %d | %.2f |" % (
                        sk, exn, seed, name, *r))


if __name__ == "__main__":
    main()
