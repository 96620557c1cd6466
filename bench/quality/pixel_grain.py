#!/usr/bin/python3
# pixel_grain.py - does `terrasynth pixel` keep the exemplar's grain?  Every DEM of
# ../shared/data/dem (not ETOPO5) x seeds, unguided, with four turns (--rotations 4) and by
# default (--rotations -1): the gradients' orientation coherence (|sum |g|^2 e^(2i theta)| /
# sum |g|^2, Gaussian derivatives at sigma 2 cells, as ../shared/eval/realism_metrics.py
# measures it) of the output and of the exemplar, and their ratio.  Goal: >= 0.6 where the
# exemplar's is >= 0.25.
#
#   /usr/bin/python3 bench/quality/pixel_grain.py [--terrasynth BIN] [--seeds 2,3] [--size 384]
#
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse
import glob
import os
import subprocess
import sys
import tempfile

import numpy as np
from osgeo import gdal
from scipy import ndimage

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
DEM = os.path.join(os.path.dirname(ROOT), "shared", "data", "dem")


def coherence(path):
    ds = gdal.Open(path)
    b = ds.GetRasterBand(1)
    a = b.ReadAsArray().astype(np.float64)
    if b.GetNoDataValue() is not None:
        a[a == b.GetNoDataValue()] = np.nan
    ok = np.isfinite(a)
    a = np.where(ok, a, np.nanmean(a))
    gx = ndimage.gaussian_filter(a, 2, order=(0, 1))
    gy = ndimage.gaussian_filter(a, 2, order=(1, 0))
    return abs(((gx + 1j * gy) ** 2)[ok].sum()) / (gx * gx + gy * gy)[ok].sum()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build/gdal_driver/terrasynth"))
    ap.add_argument("--seeds", default="2,3")
    ap.add_argument("--size", type=int, default=384)
    a = ap.parse_args()
    dems = [p for p in sorted(glob.glob(os.path.join(DEM, "*.tif"))) if "etopo" not in p]
    if not dems:
        print("skipped: ../shared/data/dem not present")
        return 0
    met = total = 0
    with tempfile.TemporaryDirectory() as tmp:
        for p in dems:
            name = os.path.basename(p)[:-4]
            extra = ["--cell-size", "10"] if "nocrs" in name else []
            ce, res = coherence(p), {}
            for rot in ("4", "-1"):
                cs = []
                for s in a.seeds.split(","):
                    out = os.path.join(tmp, "%s_%s_%s.tif" % (name, rot, s))
                    subprocess.run([a.terrasynth, "pixel", "--exemplar", p, "--size",
                                    "%dx%d" % (a.size, a.size), "--seed", s, "--rotations", rot,
                                    out, "-q"] + extra, check=True)
                    cs.append(coherence(out))
                res[rot] = float(np.mean(cs))
            goal = ""
            if ce >= 0.25:
                total += 1
                ok = res["-1"] >= 0.6 * ce
                met += ok
                goal = "  goal >= 0.6: %s" % ("met" if ok else "MISS")
            print("%-42s exemplar %.3f  four turns %.3f (%.2f)  default %.3f (%.2f)%s" % (
                name, ce, res["4"], res["4"] / ce, res["-1"], res["-1"] / ce, goal), flush=True)
    print("grained exemplars (>= 0.25) keeping >= 0.6 of their grain by default: %d of %d"
          % (met, total))
    return 0


if __name__ == "__main__":
    sys.exit(main())
