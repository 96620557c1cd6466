#!/usr/bin/python3
# drainage_matrix.py - does every method's output drain as real land does, and what does the
# drainage stage cost?  Every DEM of ../shared/data/dem (not ETOPO5) x seeds x method (synth
# free, synth --tiled 128, synth with a sketch, pixel, amplify x4 of the DEM's own average, one
# run: it takes no seed),
# each as synthesised (--drainage keep) and by default (breach), judged by
# ../shared/eval/realism_metrics.py (GRASS: the share of cells r.fill.dir raises by > 1 m,
# the r.geomorphon landform histogram).  Goals: closed depressions <= 1.5 x the exemplar's
# share + 0.2 percentage points; landforms within TV 0.06 of the exemplar's.  Also printed:
# the sharpest creases (99.9th percentile of |Laplacian|, output over exemplar), the share of
# flat cells (slope under 0.5 degrees: the flat lakes a fill leaves; exemplar / kept /
# breached), the share of cells the stage changes, their mean change, and the stage's time.
# The sketch sets its own grid (3 arcsec), so its rows are judged again against each exemplar
# averaged to the output's cells (a second table).
#
#   apt-get install grass-core
#   /usr/bin/python3 bench/quality/drainage_matrix.py [--seeds 1,2,3] [--size 256] [--jobs 2]
#
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse
import concurrent.futures as cf
import glob
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np
from osgeo import gdal

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SHARED = os.path.join(os.path.dirname(ROOT), "shared")
DEM = os.path.join(SHARED, "data", "dem")
sys.path.insert(0, os.path.join(SHARED, "eval"))
sys.path.insert(0, os.path.join(ROOT, "tests", "cli"))
sys.path.insert(0, os.path.join(ROOT, "tests"))
METHODS = ("synth", "tiled", "sketch", "pixel", "amplify")


def read(path):
    ds = gdal.Open(path)
    b = ds.GetRasterBand(1)
    a = b.ReadAsArray().astype(np.float64)
    if b.GetNoDataValue() is not None:
        a[a == b.GetNoDataValue()] = np.nan
    return a


def in_pits(a):
    """Share of the cells a full priority-flood from the edge raises by more than 1 m (the
    test's written-out flood: r.fill.dir fills in one pass and leaves nested depressions)."""
    from test_drainage import filled
    d = filled(a) - a
    return float((d[np.isfinite(d)] > 1.0).mean())


def flat_share(path, cell=None):
    """Share of the cells with data whose slope (central differences) is under 0.5 degrees;
    `cell`: metres per cell of a raster without a CRS."""
    cx, cy = ground_cells(path, cell)
    gy, gx = np.gradient(read(path), cy, cx)
    s = np.hypot(gx, gy)
    s = s[np.isfinite(s)]
    return float((s < np.tan(np.radians(0.5))).mean()) if s.size else 0.0


def ground_cells(path, cell=None):
    """Metres per cell in x and in y (geographic grids at their middle row); `cell`: metres
    per cell of a raster without a CRS."""
    ds = gdal.Open(path)
    gt = ds.GetGeoTransform()
    srs = ds.GetSpatialRef()
    if srs is None:
        return cell, cell
    cx, cy = abs(gt[1]), abs(gt[5])
    if srs.IsGeographic():
        lat = np.radians(gt[3] + gt[5] * ds.RasterYSize / 2)
        cx, cy = cx * 111320.0 * np.cos(lat), cy * 110574.0
    return cx, cy


def ground_cell(path, cell=None):
    """Metres per cell (the mean of x and y)."""
    cx, cy = ground_cells(path, cell)
    return 0.5 * (cx + cy)


def averaged_to(p, metres, tmp):
    """The DEM averaged to cells of `metres` (in its own CRS, or its own cells without one):
    the exemplar as a synthesis on such a grid sees it."""
    own = ground_cell(p, cell_of(os.path.basename(p)))
    ds = gdal.Open(p)
    k = metres / own
    out = os.path.join(tmp, os.path.basename(p)[:-4] + "_at_%dm.tif" % round(metres))
    gdal.Translate(out, ds, width=max(1, round(ds.RasterXSize / k)),
                   height=max(1, round(ds.RasterYSize / k)), resampleAlg="average")
    return out


def crease(a):
    lap = a[1:-1, 2:] + a[1:-1, :-2] + a[2:, 1:-1] + a[:-2, 1:-1] - 4 * a[1:-1, 1:-1]
    return np.percentile(np.abs(lap[np.isfinite(lap)]), 99.9)


def judge(path, tmp, cell=None):
    """(sink share, landform histogram) by the yardstick's own GRASS run; a raster
    without a CRS (which GRASS cannot take) judged as a copy in UTM with cells of `cell` m."""
    import realism_metrics
    t = tempfile.mkdtemp(dir=tmp)
    if not gdal.Open(path).GetProjection():
        copy = os.path.join(t, "utm.tif")
        gdal.Translate(copy, path, outputSRS="EPSG:32631")
        ds = gdal.Open(copy, gdal.GA_Update)
        ds.SetGeoTransform([500000.0, cell, 0.0, 5000000.0, 0.0, -cell])
        ds = None
        path = copy
    try:
        forms, sink = realism_metrics.forms(os.path.abspath(path), 10, t)
    finally:
        shutil.rmtree(t, ignore_errors=True)
    return sink, forms


def cell_of(name):
    """Metres per cell of a DEM of ../shared without a CRS (its name says)."""
    return 10.0 if "10m" in name else 20.0


def crop_exemplar(p, size, tmp, name):
    """The exemplar's central size x size cells (the amplify case's truth) and its 4 x 4
    average (the input)."""
    ds = gdal.Open(p)
    w, h = ds.RasterXSize, ds.RasterYSize
    s = min(size, w, h) // 4 * 4
    x0, y0 = (w - s) // 2, (h - s) // 2
    truth = os.path.join(tmp, name + "_truth.tif")
    coarse = os.path.join(tmp, name + "_coarse.tif")
    gdal.Translate(truth, ds, srcWin=[x0, y0, s, s])
    gt = gdal.Open(truth).GetGeoTransform()
    gdal.Warp(coarse, truth, xRes=gt[1] * 4, yRes=abs(gt[5]) * 4, resampleAlg="average")
    return truth, coarse


def one(job):
    bin_, method, p, seed, size, tmp, sketch, options = job
    name = os.path.basename(p)[:-4]
    extra = ["--cell-size", "%g" % cell_of(name)] if "nocrs" in name else []
    row = {"method": method, "dem": name, "seed": seed}
    for mode in ("keep", "breach"):
        out = os.path.join(tmp, "%s_%s_%s_%s.tif" % (method, name, seed, mode))
        if method == "amplify":
            truth, coarse = crop_exemplar(p, size, tmp, "%s_%s_%s" % (name, seed, mode))
            cmd = [bin_, "amplify", coarse, out, "--exemplar", p, "--factor", "4"]
        else:
            cmd = [bin_, "pixel" if method == "pixel" else "synth", "--exemplar", p, "--seed",
                   str(seed), out]
            if method == "sketch":
                cmd += ["--sketch", sketch]
            else:
                cmd += ["--size", "%dx%d" % (size, size)]
            if method == "tiled":
                cmd += ["--tiled", "128"]
        r = subprocess.run(cmd + extra + ["--drainage", mode] + (options if mode == "breach" else []),
                           capture_output=True, text=True)
        if r.returncode != 0:
            row["error"] = r.stderr.strip().splitlines()[-1]
            return row
        m = re.search(r"drainage: .*; ([\d.]+) s", r.stdout)
        if m:
            row["seconds"] = float(m.group(1))
        a = read(out)
        row[mode] = a
        row[mode + "_sink"], row[mode + "_forms"] = judge(out, tmp, cell_of(name))
        row[mode + "_flood"] = in_pits(a)
        row[mode + "_flat"] = flat_share(out, cell_of(name))
    k, b = row["keep"], row["breach"]
    ok = np.isfinite(k)
    ch = b[ok] != k[ok]
    row["changed"] = float(ch.mean())
    row["mean_change"] = float(np.abs(b[ok][ch] - k[ok][ch]).mean()) if ch.any() else 0.0
    row["raised"] = bool((b[ok] > k[ok]).any())
    del row["keep"], row["breach"]
    row["crease_keep"], row["crease_breach"] = crease(k), crease(b)
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build/gdal_driver/terrasynth"))
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--options", default="", help="drainage options for the breached runs, "
                    "e.g. '--drainage-radius 128'")
    a = ap.parse_args()
    dems = [p for p in sorted(glob.glob(os.path.join(DEM, "*.tif"))) if "etopo" not in p]
    if not dems or not shutil.which("grass"):
        print("skipped: needs ../shared/data/dem and GRASS (apt-get install grass-core)")
        return 0
    import realism_metrics  # noqa: F401  (the yardstick, ../shared/eval)
    sketch = os.path.join(ROOT, "data", "sketches", "ridges_valleys.tif")
    with tempfile.TemporaryDirectory() as tmp:
        ex = {}
        for p in dems:
            ex[p] = judge(p, tmp, cell_of(os.path.basename(p))) + (
                crease(read(p)), flat_share(p, cell_of(os.path.basename(p))))
        jobs = [(a.terrasynth, m, p, int(s), a.size, tmp, sketch, a.options.split())
                for m in a.methods.split(",") for p in dems
                for s in (a.seeds.split(",")[:1] if m == "amplify" else a.seeds.split(","))]
        with cf.ThreadPoolExecutor(a.jobs) as pool:
            rows = list(pool.map(one, jobs))
    print("| method | DEM | depressions (r.fill.dir): exemplar / kept / breached (goal) | "
          "full flood: kept / breached | landforms TV kept / breached | creases kept / breached "
          "| flat cells: exemplar / kept / breached | cells changed | mean change m | stage s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    met = total = tv_met = 0
    for m in a.methods.split(","):
        for p in dems:
            rs = [r for r in rows if r["method"] == m and r["dem"] == os.path.basename(p)[:-4]]
            bad = [r for r in rs if "error" in r]
            if bad:  # (a DEM too small for a sketch's patches at its resolution)
                print("| %s | %s | not run: %s |" % (m, rs[0]["dem"], bad[0]["error"]))
                continue
            se, fe, ce, flat_e = ex[p]
            goal = 1.5 * se + 0.002
            ok = sum(r["breach_sink"] <= goal for r in rs)
            tvk = np.mean([0.5 * np.abs(np.array(r["keep_forms"]) - fe).sum() for r in rs])
            tvb = [0.5 * np.abs(np.array(r["breach_forms"]) - fe).sum() for r in rs]
            met += ok
            total += len(rs)
            tv_met += sum(t <= 0.06 for t in tvb)
            print("| %s | %s | %.2f %% / %.2f %% / %.2f %% (%d of %d <= %.2f %%) | %.1f %% / %.1f %%"
                  " | %.3f / %.3f | %.2f / %.2f | %.2f %% / %.2f %% / %.2f %% | %.2f %% | %.1f | %.2f |" % (
                      m, rs[0]["dem"], 100 * se, 100 * np.mean([r["keep_sink"] for r in rs]),
                      100 * np.mean([r["breach_sink"] for r in rs]), ok, len(rs), 100 * goal,
                      100 * np.mean([r["keep_flood"] for r in rs]),
                      100 * np.mean([r["breach_flood"] for r in rs]),
                      tvk, np.mean(tvb), np.mean([r["crease_keep"] for r in rs]) / ce,
                      np.mean([r["crease_breach"] for r in rs]) / ce, 100 * flat_e,
                      100 * np.mean([r["keep_flat"] for r in rs]),
                      100 * np.mean([r["breach_flat"] for r in rs]),
                      100 * np.mean([r["changed"] for r in rs]),
                      np.mean([r["mean_change"] for r in rs]),
                      np.mean([r.get("seconds", 0.0) for r in rs])))
    print("\ndepressions within goal: %d of %d runs; landforms within TV 0.06: %d of %d"
          % (met, total, tv_met, total))
    if "sketch" in a.methods.split(","):
        sketch_at_output_cells(rows, dems, sketch)
    return 0


def sketch_at_output_cells(rows, dems, sketch):
    """The sketch sets the output's grid (3 arcsec here), so its rows are also judged
    against the exemplar averaged to the output's cells: the landforms, pits and creases
    of the land at the scale the output has."""
    metres = ground_cell(sketch)
    print("\nSketch rows against the exemplar averaged to the output's cells (%.0f m):" % metres)
    print("| DEM | depressions: exemplar there / breached (goal) | landforms TV breached | "
          "creases breached |")
    print("|---|---|---|---|")
    met = total = tv_met = 0
    with tempfile.TemporaryDirectory() as tmp:
        for p in dems:
            rs = [r for r in rows if r["method"] == "sketch"
                  and r["dem"] == os.path.basename(p)[:-4]]
            if not rs or any("error" in r for r in rs):
                continue
            q = averaged_to(p, metres, tmp)
            se, fe = judge(q, tmp, metres)
            ce = crease(read(q))
            goal = 1.5 * se + 0.002
            ok = sum(r["breach_sink"] <= goal for r in rs)
            tvb = [0.5 * np.abs(np.array(r["breach_forms"]) - fe).sum() for r in rs]
            met += ok
            total += len(rs)
            tv_met += sum(t <= 0.06 for t in tvb)
            print("| %s | %.2f %% / %.2f %% (%d of %d <= %.2f %%) | %.3f | %.2f |" % (
                rs[0]["dem"], 100 * se, 100 * np.mean([r["breach_sink"] for r in rs]), ok,
                len(rs), 100 * goal, np.mean(tvb),
                np.mean([r["crease_breach"] for r in rs]) / ce))
    print("\nat the output's cells: depressions within goal %d of %d runs; landforms within "
          "TV 0.06: %d of %d" % (met, total, tv_met, total))


if __name__ == "__main__":
    sys.exit(main())
