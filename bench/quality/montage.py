#!/usr/bin/python3
# montage.py - hillshade montages of the quality matrix: for each sketch a row of
# the sketch and one hillshaded output per exemplar (first seed), to look at.
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import math
import os

import numpy as np
from osgeo import gdal
from PIL import Image


def _read(path):
    ds = gdal.Open(path)
    b = ds.GetRasterBand(1)
    a = b.ReadAsArray().astype(np.float64)
    nd = b.GetNoDataValue()
    if nd is not None:
        a[a == nd] = np.nan
    return a, ds.GetGeoTransform(), ds.GetSpatialRef()


def hillshade(path, cell=30.0):
    a, gt, srs = _read(path)
    a = np.where(np.isfinite(a), a, np.nanmean(a))
    px, py = abs(gt[1]), abs(gt[5])
    if srs is not None and srs.IsGeographic():
        lat = gt[3] + gt[5] * a.shape[0] / 2
        px *= 111320.0 * math.cos(math.radians(lat))
        py *= 110574.0
    elif srs is None:
        px = py = cell
    gy, gx = np.gradient(a, py, px)
    slope = np.arctan(np.hypot(gx, gy))
    aspect = np.arctan2(-gx, gy)
    az, alt = math.radians(315), math.radians(45)
    h = np.sin(alt) * np.cos(slope) + np.cos(alt) * np.sin(slope) * np.cos(az - aspect)
    t = (a - a.min()) / max(a.max() - a.min(), 1e-9)
    v = np.clip(h, 0, 1) * (0.55 + 0.45 * t)
    return Image.fromarray(np.uint8(255 * v)).convert("RGB")


def grey(path):
    a, _, _ = _read(path)
    a = (a - np.nanmin(a)) / max(np.nanmax(a) - np.nanmin(a), 1e-9)
    return Image.fromarray(np.uint8(255 * np.nan_to_num(a))).convert("RGB")


def write_all(out_dir, sk_dir, rows, size=360, prefix="montage_"):
    by_sketch = {}
    for r in rows:
        by_sketch.setdefault(r["sketch"], [])
        if all(o["exemplar"] != r["exemplar"] for o in by_sketch[r["sketch"]]):
            by_sketch[r["sketch"]].append(r)
    for sk, rs in by_sketch.items():
        img = Image.new("RGB", (size * (1 + len(rs)), size), "white")
        img.paste(grey(os.path.join(sk_dir, sk)).resize((size, size)), (0, 0))
        for i, r in enumerate(rs):
            img.paste(hillshade(os.path.join(out_dir, r["tag"] + ".tif")).resize((size, size)),
                      (size * (i + 1), 0))
        img.save(os.path.join(out_dir, prefix + sk[:-4] + ".png"))
