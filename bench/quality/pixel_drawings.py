#!/usr/bin/python3
# pixel_drawings.py - `terrasynth pixel` guided by drawings: three grey-level
# drawings (an X of bright ridges, a Y of dark valleys on a bright ground, a bright ring),
# read with --guide-heights quantile (and stretch), over crops of five DEMs of ../shared/data/dem x seeds,
# judged by the independent yardstick ../shared/eval/terrain_metrics.py: structure_r (goal
# >= 0.6 with a guide), and slope_w1 and the worse of seam_lap / seam_grad for what the
# drawing does to the style.  One line per drawing x DEM x weight, then the counts.
#
#   /usr/bin/python3 bench/quality/pixel_drawings.py [--terrasynth BIN] [--seeds 1,2,3]
#        [--weights 0.5] [--heights quantile,stretch] [--size 256] [--out DIR] [--extra ARGS]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from osgeo import gdal

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SHARED = os.path.join(os.path.dirname(ROOT), "shared")
DEM = os.path.join(SHARED, "data", "dem")
METRICS = os.path.join(SHARED, "eval", "terrain_metrics.py")

# (name, file, gdal_translate -srcwin): crops of a few hundred cells, so that each exemplar
# holds several ridges and valleys and a run takes a second or two
CROPS = (("jacksboro", "hills_jacksboro_tn_3arcsec.tif", (100, 60, 256, 256)),
         ("bigtujunga", "mountains_bigtujunga_ca_30m.tif", (200, 200, 384, 384)),
         ("zion", "canyon_zion_ut_srtm90m.tif", (100, 100, 384, 384)),
         ("mackay", "mountains_mackay_id_30m.tif", (100, 100, 384, 384)),
         ("sthelens", "volcano_st_helens_30m.tif", (50, 50, 277, 384)))


def drawings(n):
    """Grey levels 0..255 as a person might draw them: lines of a Gaussian profile."""
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float64)
    c = n / 2.0

    def seg(x0, y0, x1, y1):
        vx, vy = x1 - x0, y1 - y0
        t = np.clip(((xx - x0) * vx + (yy - y0) * vy) / (vx * vx + vy * vy), 0, 1)
        return np.hypot(xx - x0 - t * vx, yy - y0 - t * vy)

    x = np.minimum(np.abs(xx - yy), np.abs(xx + yy - (n - 1))) / np.sqrt(2)
    y = np.minimum(np.minimum(seg(c, c, c, n - 1), seg(c, c, 10, 10)), seg(c, c, n - 10, 10))
    ring = np.abs(np.hypot(xx - c, yy - c) - n * 0.3)
    return {"X ridges": 30 + 200 * np.exp(-(x / 12.0) ** 2),
            "Y valleys": 220 - 190 * np.exp(-(y / 10.0) ** 2),
            "ring": 30 + 200 * np.exp(-(ring / 12.0) ** 2)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build", "gdal_driver",
                                                         "terrasynth"))
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--weights", default="0.5")
    ap.add_argument("--heights", default="quantile,stretch")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--out", default=None)
    ap.add_argument("--extra", default="",
                    help="more options for every run (A/B: '--guide-mode add')")
    a = ap.parse_args()
    if not os.path.isdir(DEM) or not os.path.exists(METRICS):
        print("pixel_drawings: skipped: ../shared absent")
        return 0
    gdal.UseExceptions()
    work = a.out or tempfile.mkdtemp(prefix="ts_drawings_")
    os.makedirs(work, exist_ok=True)
    seeds = [int(s) for s in a.seeds.split(",")]
    weights = [(h, float(w)) for h in a.heights.split(",") for w in a.weights.split(",")]
    n = a.size
    rows = []
    for en, f, win in CROPS:
        ex = os.path.join(work, en + ".tif")
        subprocess.run(["gdal_translate", "-q", "-srcwin", *map(str, win),
                        os.path.join(DEM, f), ex], check=True)
        src = gdal.Open(ex)
        for dn, img in drawings(n).items():
            g = os.path.join(work, "guide_%s_%s.tif" % (dn.replace(" ", "_"), en))
            ds = gdal.GetDriverByName("GTiff").Create(g, n, n, 1, gdal.GDT_Byte)
            ds.SetGeoTransform(src.GetGeoTransform())
            ds.SetProjection(src.GetProjection())
            ds.GetRasterBand(1).WriteArray(img.astype(np.uint8))
            ds = None
            for how, w in weights:
                r, s1, se = [], [], []
                for seed in seeds:
                    out = os.path.join(work, "out.tif")
                    subprocess.run([a.terrasynth, "pixel", "--exemplar", ex, "--guide", g,
                                    "--guide-heights", how, "--guide-weight", str(w),
                                    "--seed", str(seed), out, "-q"] + a.extra.split(),
                                   check=True)
                    m = json.loads(subprocess.run(
                        [sys.executable, METRICS, "--out", out, "--exemplar", ex, "--sketch", g],
                        check=True, capture_output=True, text=True).stdout)
                    r.append(m["structure_r"])
                    s1.append(m["slope_w1_deg"])
                    se.append(max(m["seam_lap"], m["seam_grad"]))
                rows.append((how, r, s1, se))
                print("%-10s %-10s %-8s %.2f  structure_r %s  slope_w1 %s  seams %s" % (
                    dn, en, how, w, " ".join("%.2f" % v for v in r),
                    " ".join("%.1f" % v for v in s1), " ".join("%.2f" % v for v in se)),
                    flush=True)
    for how in dict.fromkeys(h for h, _ in weights):
        allr = [v for hh, r, _, _ in rows if hh == how for v in r]
        alls = [v for hh, _, s, _ in rows if hh == how for v in s]
        alle = [v for hh, _, _, e in rows if hh == how for v in e]
        print("%s: structure_r >= 0.6 in %d of %d (worst %.2f, mean %.2f); slope_w1 <= 3 in %d "
              "of %d (worst %.1f, mean %.1f); seams <= 1.2 in %d of %d (worst %.2f)" % (
                  how, sum(v >= 0.6 for v in allr), len(allr), min(allr), np.mean(allr),
                  sum(v <= 3 for v in alls), len(alls), max(alls), np.mean(alls),
                  sum(v <= 1.2 for v in alle), len(alle), max(alle)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
