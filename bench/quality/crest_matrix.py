#!/usr/bin/python3
# crest_matrix.py - do sketched crests have the exemplar's peaks and saddles
# along them and its varied cross-sections, or are they even embankments?
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
#
#   /usr/bin/python3 bench/quality/crest_matrix.py [--terrasynth BIN]
#        [--baseline BIN] [--shared DIR] [--out DIR] [--seeds 1,2] [--only S]
#        [--extra 'ARGS']
#
# Every sketch of ../shared/eval/make_sketches.py and draw_sketches.py that
# draws ridges x three
# DEMs x seeds.  Along the drawn ridge strokes (the sketch's GeoPackage: the
# drawing's own lines, not ours) and along the exemplar's own main ridges, every
# cell of arc length, the crest height (the highest cell within 3 cells
# across) and the land P/4 and P/2 cells off on both sides (P the patch):
#
#   bend   RMS of z(s - P/2) - 2 z(s) + z(s + P/2), metres: peaks and
#          saddles about a patch apart (0 on an even embankment)
#   cv     spread over mean of the crest's stand at P/4 (how much the
#          cross-section varies along the crest: 0 for one profile)
#
# The exemplar's main ridges: the exemplar averaged to the output's cell
# size, its ridge axes by `terrasynth ppa --lines` (Chang et al. 1998) at
# least 1.5 P long, the upper half by stand at P/2.
# Printed per case: the two figures of the output over the exemplar's (goal
# 0.6 .. 1.67 each), with --baseline the same for another build in the same
# run.  Skips (exit 0) when ../shared is absent.
import argparse
import math
import os
import subprocess
import sys
import tempfile

from osgeo import gdal

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "tests/cli"))
import crest_profile as cp  # noqa: E402

gdal.UseExceptions()
BT, MK, AI = "mountains_bigtujunga_ca_30m.tif", "mountains_mackay_id_30m.tif", \
    "mountains_aiguestortes_pyrenees_20m_nocrs.tif"
SH10, SH30 = "volcano_st_helens_10m_nocrs.tif", "volcano_st_helens_30m.tif"
MATRIX = [
    ("star_ridges_720", [MK, BT, AI]),
    ("arcs_ridges_geo1s", [BT, AI, MK]),
    ("valley_between_ridges_800", [BT, MK, AI]),
    ("range_spurs_both_720", [BT, MK, AI]),
    ("volcano_rim_gullies_700", [SH10, SH30, BT]),
    ("caldera_both_geo1s_600", [SH30, BT, MK]),
]
NOCRS_CELL = {AI: 20.0, SH10: 10.0}
GOAL = (0.6, 1.0 / 0.6)


def cell_metres(path):
    ds = gdal.Open(path)
    gt = ds.GetGeoTransform()
    if NOCRS_CELL.get(os.path.basename(path)):
        return NOCRS_CELL[os.path.basename(path)]
    srs = ds.GetSpatialRef()
    if srs is not None and srs.IsGeographic():
        lat = gt[3] + gt[5] * ds.RasterYSize / 2
        return abs(gt[1]) * 111320.0 * math.cos(math.radians(lat))
    return abs(gt[1])


def exemplar_figures(ts, dem, cell, P, tmp):
    """The exemplar at the output's cell size (cell metres), its main ridges' figures."""
    name = "%s_%g" % (os.path.basename(dem)[:-4], cell)
    f = cell_metres(dem) / cell
    src = gdal.Open(dem)
    ex = os.path.join(tmp, name + ".tif")
    gdal.Translate(ex, src, width=max(2, round(src.RasterXSize * f)),
                   height=max(2, round(src.RasterYSize * f)), resampleAlg="average")
    gp = os.path.join(tmp, name + "_ridges.gpkg")
    subprocess.run([ts, "ppa", "-q", ex, os.path.join(tmp, name + "_ppa.tif"), "--ridges",
                    "--lines", gp], check=True)
    z, gt = cp.read(ex)
    return cp.figures(cp.main_ridges(cp.line_stands(z, cp.polylines(gp, "paths", gt), P,
                                               int(1.5 * P))), P)


def run_case(ts, sk_dir, sk, dem, seed, P, out, extra):
    cmd = [ts, "synth", "-q", "--sketch", os.path.join(sk_dir, sk + ".tif"), "--exemplar", dem,
           "--seed", str(seed), "--patch-size", str(P), out] + extra.split()
    if NOCRS_CELL.get(os.path.basename(dem)):
        cmd += ["--cell-size", str(NOCRS_CELL[os.path.basename(dem)])]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        print("%s: terrasynth failed: %s" % (out, r.stderr.strip()))
        return None
    z, gt = cp.read(out)
    drawn = cp.polylines(os.path.join(sk_dir, sk + ".gpkg"), "strokes", gt, "ridge")
    return cp.figures(cp.line_stands(z, drawn, P, P + 1), P)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build/gdal_driver/terrasynth"))
    ap.add_argument("--baseline", default="")
    ap.add_argument("--shared", default=os.path.join(os.path.dirname(ROOT), "shared"))
    ap.add_argument("--out", default=os.path.join(ROOT, "build/crest"))
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--only", default="")
    ap.add_argument("--patch", type=int, default=64)
    ap.add_argument("--extra", default="", help="more terrasynth synth arguments")
    a = ap.parse_args()
    dem_dir = os.path.join(a.shared, "data/dem")
    if not os.path.isdir(dem_dir):
        print("crest_matrix: skipped: %s not found" % a.shared)
        return 0
    P = a.patch
    sk_dir = os.path.join(a.out, "sketches")
    os.makedirs(sk_dir, exist_ok=True)
    subprocess.run([sys.executable, os.path.join(a.shared, "eval/make_sketches.py"), sk_dir],
                   check=True, capture_output=True)
    subprocess.run([sys.executable, os.path.join(HERE, "draw_sketches.py"), sk_dir], check=True,
                   capture_output=True)
    tmp = tempfile.mkdtemp(prefix="crest-")
    builds = [("new", a.terrasynth)] + ([("base", a.baseline)] if a.baseline else [])
    ex_cache, n_ok, n = {}, {b: 0 for b, _ in builds}, 0
    print("%-26s %-40s %4s %8s %8s %7s" % ("sketch", "exemplar", "seed", "ex bend", "ex cv",
                                           "build")
          + "  %6s %6s %6s %6s  %s" % ("bend", "cv", "bend/x", "cv/x", "goal"))
    for sk, exs in MATRIX:
        if a.only and a.only not in sk:
            continue
        for ex in exs:
            dem = os.path.join(dem_dir, ex)
            cell = cell_metres(os.path.join(sk_dir, sk + ".tif"))
            key = (ex, round(cell, 1))
            if key not in ex_cache:
                ex_cache[key] = exemplar_figures(a.terrasynth, dem, cell, P, tmp)
            xf = ex_cache[key]
            for seed in [int(s) for s in a.seeds.split(",")]:
                n += 1
                for b, ts in builds:
                    f = run_case(ts, sk_dir, sk, dem, seed, P,
                                 os.path.join(a.out, "%s__%s__%d__%s.tif" % (sk, ex[:-4], seed, b)),
                                 a.extra)
                    if not f or not xf:
                        continue
                    rb, rc = f["bend"] / xf["bend"], f["cv"] / xf["cv"]
                    ok = all(GOAL[0] <= v <= GOAL[1] for v in (rb, rc))
                    n_ok[b] += ok
                    print("%-26s %-40s %4d %8.0f %8.2f %7s  %6.0f %6.2f %6.2f %6.2f  %s" % (
                        sk, ex[:-4], seed, xf["bend"], xf["cv"], b, f["bend"], f["cv"], rb, rc,
                        "ok" if ok else "MISS"), flush=True)
    for b, _ in builds:
        print("%s: %d of %d cases within %.2f..%.2f x the exemplar's bend and cv" % (
            b, n_ok[b], n, GOAL[0], GOAL[1]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
