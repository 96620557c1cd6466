#!/usr/bin/python3
# lattice.py - how strongly a DEM repeats at given periods: for each period P (cells), the
# spectrum's power at that frequency along the rows and along the columns over the median of
# its neighbours (+-2..6 frequency bins). Natural terrain gives 1-8; a lattice of patches at
# step P tens to hundreds.
#
#   bench/quality/lattice.py --periods 48,24,16 [--window X,Y,N] DEM.tif [DEM2.tif ...]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse

import numpy as np
from osgeo import gdal
from scipy import ndimage


def prominence(z, periods):
    """(rows, columns) prominence at each period of the square high-passed cells z."""
    n = min(z.shape) // 2 * 2
    z = z[:n, :n]
    z = np.where(np.isfinite(z), z, np.nanmean(z))
    hp = z - ndimage.uniform_filter(z, 65)
    f = np.abs(np.fft.fft2(hp * np.outer(np.hanning(n), np.hanning(n)))) ** 2
    # repetition along x (columns' frequency) and along y, within 2 bins of the axis
    fx = f[:3, :].sum(0) + f[-2:, :].sum(0)
    fy = f[:, :3].sum(1) + f[:, -2:].sum(1)
    out = []
    for p in periods:
        k = int(round(n / p))
        r = []
        for s in (fx, fy):
            around = np.r_[s[k - 6:k - 1], s[k + 2:k + 7]]
            r.append(s[k - 1:k + 2].max() / np.median(around))
        out.append(tuple(r))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--periods", required=True, help="periods in cells, comma-separated")
    ap.add_argument("--window", help="X,Y,N: the N x N cells at column X, row Y")
    ap.add_argument("dems", nargs="+")
    a = ap.parse_args()
    periods = [float(v) for v in a.periods.split(",")]
    for path in a.dems:
        ds = gdal.Open(path)
        if a.window:
            x, y, n = (int(v) for v in a.window.split(","))
            z = ds.GetRasterBand(1).ReadAsArray(x, y, n, n).astype(float)
        else:
            z = ds.GetRasterBand(1).ReadAsArray().astype(float)
        nd = ds.GetRasterBand(1).GetNoDataValue()
        if nd is not None:
            z[z == nd] = np.nan
        print(path, "  ".join("P%g: %.1f / %.1f" % (p, r[0], r[1])
                              for p, r in zip(periods, prominence(z, periods))))


if __name__ == "__main__":
    main()
