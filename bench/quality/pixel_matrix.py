#!/usr/bin/python3
# pixel_matrix.py - the quality matrix of `terrasynth pixel`: every DEM of
# ../shared/data/dem x seeds, unguided, judged by the independent yardstick
# ../shared/eval/terrain_metrics.py (seam_lap, seam_grad <= 1.2, slope_w1 <= 3 degrees), and
# guided by a blurred copy of another part of the same DEM (structure_r >= 0.6).  Prints one
# line per case, then the worst of every figure and how many cases meet each goal; with
# several --variant strings, the same matrix for each (A/B comparisons in one run).
#
#   /usr/bin/python3 bench/quality/pixel_matrix.py [--terrasynth BIN] [--seeds 2,3]
#        [--size 384] [--variant '--pca-energy 1' ...] [--guided] [--out DIR]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SHARED = os.path.join(os.path.dirname(ROOT), "shared")
DEM = os.path.join(SHARED, "data", "dem")
METRICS = os.path.join(SHARED, "eval", "terrain_metrics.py")


def metrics(out, exemplar, guide=None):
    cmd = ["/usr/bin/python3", METRICS, "--out", out, "--exemplar", exemplar]
    if guide:
        cmd += ["--sketch", guide]
    p = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return json.loads(p.stdout)


def gdal_size(path):
    """(width, height) of a raster, by gdalinfo (this script imports no GDAL)."""
    p = subprocess.run(["gdalinfo", path], capture_output=True, text=True, check=True)
    m = re.search(r"Size is (\d+), (\d+)", p.stdout)
    return int(m.group(1)), int(m.group(2))


def dems():
    # not the global ETOPO5 grid: its rows reach past the poles (refused, rightly)
    return sorted(f for f in os.listdir(DEM) if f.endswith(".tif") and "etopo5" not in f)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build", "gdal_driver",
                                                         "terrasynth"))
    ap.add_argument("--seeds", default="2,3")
    ap.add_argument("--size", type=int, default=384)
    ap.add_argument("--variant", action="append", default=None)
    ap.add_argument("--guided", action="store_true",
                    help="also guided runs (structure_r against the guide)")
    ap.add_argument("--only", default="", help="DEMs whose names hold one of these (A,B,...)")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    if not os.path.isdir(DEM) or not os.path.exists(METRICS):
        print("pixel_matrix: skipped: ../shared is not present")
        return 0
    variants = a.variant or [""]
    seeds = [int(s) for s in a.seeds.split(",")]
    tmp = a.out or tempfile.mkdtemp(prefix="pixel_matrix_")
    os.makedirs(tmp, exist_ok=True)
    for var in variants:
        rows = []
        for f in dems():
            if a.only and not any(o in f for o in a.only.split(",")):
                continue
            ex = os.path.join(DEM, f)
            # a DEM without a CRS: its cell size from its name (..._20m_nocrs.tif)
            cs = re.search(r"_(\d+)m_nocrs", f)
            extra = ["--cell-size", cs.group(1)] if cs else []
            for seed in seeds:
                out = os.path.join(tmp, "u_%s_%d.tif" % (f[:-4], seed))
                t0 = time.time()
                subprocess.run([a.terrasynth, "pixel", "--exemplar", ex, "--size",
                                "%dx%d" % (a.size, a.size), "--seed", str(seed), "-q", out]
                               + extra + shlex.split(var), check=True)
                dt = time.time() - t0
                m = metrics(out, ex)
                row = {"case": "%s seed %d" % (f[:-4], seed), "seam_lap": m["seam_lap"],
                       "seam_grad": m["seam_grad"], "slope_w1_deg": m["slope_w1_deg"],
                       "s": dt}
                if a.guided:
                    guide = os.path.join(tmp, "g_%s.tif" % f[:-4])
                    gex, gextra = ex, extra
                    if cs:
                        # `--cell-size` is the cell of every raster without a CRS, the guide's
                        # too, whose cells are 4 x the DEM's: the DEM and its guide given a
                        # metric CRS instead (a UTM zone: any would do), each its own cells
                        gex, gextra = os.path.join(tmp, "crs_" + f), []
                        if not os.path.exists(gex):
                            w, h = gdal_size(ex)
                            m = int(cs.group(1))
                            subprocess.run(["gdal_translate", "-q", "-a_srs", "EPSG:32631",
                                            "-a_ullr", "0", str(m * h), str(m * w), "0", ex,
                                            gex], check=True)
                    if not os.path.exists(guide):
                        # a blurred, mirrored copy of the DEM at the output's size: shapes the
                        # exemplar's own coordinates cannot simply copy
                        # (size cells wide, square cells: cells of other shapes are no use)
                        subprocess.run(["gdal_translate", "-q", "-outsize", str(a.size), "0",
                                        "-r", "average", gex, guide + ".v.tif"],
                                       check=True)
                        subprocess.run(["/usr/bin/python3", "-c", GUIDE_PY, guide + ".v.tif",
                                        guide], check=True)
                    gout = os.path.join(tmp, "g_%s_%d.tif" % (f[:-4], seed))
                    subprocess.run([a.terrasynth, "pixel", "--exemplar", gex, "--guide", guide,
                                    "--seed", str(seed), "-q", gout] + gextra +
                                   shlex.split(var), check=True)
                    gm = metrics(gout, gex, guide)
                    row["structure_r"] = gm["structure_r"]
                    row["g_seams"] = max(gm["seam_lap"], gm["seam_grad"])
                    row["g_slope"] = gm["slope_w1_deg"]
                    # the style at the output's cells: the guide's grid is the DEM averaged to
                    # the output's size (cells 1.3-5 x the DEM's), where slopes are gentler by
                    # construction; the same average, unmirrored, is the DEM at those cells
                    at = metrics(gout, guide + ".v.tif")
                    row["g_slope_at"] = at["slope_w1_deg"]
                    row["g_seams_at"] = max(at["seam_lap"], at["seam_grad"])
                rows.append(row)
                print("[%s] %-48s seam_lap %.2f seam_grad %.2f slope_w1 %.2f%s  %.1f s"
                      % (var or "default", row["case"], row["seam_lap"], row["seam_grad"],
                         row["slope_w1_deg"],
                         (" guided: structure_r %.3f slope_w1 %.2f seams %.2f (at its cells "
                          "%.2f, %.2f)" % (row["structure_r"], row["g_slope"], row["g_seams"],
                                           row["g_slope_at"], row["g_seams_at"]))
                         if "structure_r" in row else "", dt), flush=True)
        if not rows:
            continue
        n = len(rows)
        ok_seam = sum(r["seam_lap"] <= 1.2 and r["seam_grad"] <= 1.2 for r in rows)
        ok_w1 = sum(r["slope_w1_deg"] <= 3 for r in rows)
        line = ("[%s] worst: seam_lap %.2f seam_grad %.2f slope_w1 %.2f; mean slope_w1 %.2f; "
                "seams <= 1.2: %d/%d; slope_w1 <= 3: %d/%d; mean %.2f s"
                % (var or "default", max(r["seam_lap"] for r in rows),
                   max(r["seam_grad"] for r in rows), max(r["slope_w1_deg"] for r in rows),
                   sum(r["slope_w1_deg"] for r in rows) / n, ok_seam, n, ok_w1, n,
                   sum(r["s"] for r in rows) / n))
        if a.guided:
            line += ("; guided: structure_r min %.3f, >= 0.6: %d/%d; slope_w1 <= 3: %d/%d "
                     "(mean %.2f); seams <= 1.2: %d/%d; against the DEM at the output's cells: "
                     "slope_w1 <= 3: %d/%d (mean %.2f), seams <= 1.2: %d/%d" % (
                         min(r["structure_r"] for r in rows),
                         sum(r["structure_r"] >= 0.6 for r in rows), n,
                         sum(r["g_slope"] <= 3 for r in rows), n,
                         sum(r["g_slope"] for r in rows) / n,
                         sum(r["g_seams"] <= 1.2 for r in rows), n,
                         sum(r["g_slope_at"] <= 3 for r in rows), n,
                         sum(r["g_slope_at"] for r in rows) / n,
                         sum(r["g_seams_at"] <= 1.2 for r in rows), n))
        print(line, flush=True)
    return 0


GUIDE_PY = r"""
import sys
from osgeo import gdal
src = gdal.Open(sys.argv[1])
a = src.GetRasterBand(1).ReadAsArray().astype('float32')
nd = src.GetRasterBand(1).GetNoDataValue()
import numpy as np
if nd is not None:
    a[a == nd] = np.nan
a = np.where(np.isnan(a), np.nanmean(a), a)[:, ::-1].T.copy()
drv = gdal.GetDriverByName('GTiff')
out = drv.Create(sys.argv[2], a.shape[1], a.shape[0], 1, gdal.GDT_Float32)
out.SetGeoTransform(src.GetGeoTransform())
out.SetProjection(src.GetProjection())
out.GetRasterBand(1).WriteArray(a)
out = None
"""

if __name__ == "__main__":
    sys.exit(main())
