#!/usr/bin/python3
# quality.py - the sketch-fidelity matrix: sketches x real DEMs x seeds, each
# synthesised with `terrasynth synth --sketch` and judged by an independent
# yardstick (../shared/eval/terrain_metrics.py, which uses none of our code).
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
#
#   /usr/bin/python3 bench/quality/quality.py [--terrasynth BIN] [--shared DIR]
#        [--out DIR] [--seeds 1,2,3] [--only SUBSTRING] [--extra 'ARGS']
#
# Sketches: the five of ../shared/eval/make_sketches.py and the five of
# bench/quality/draw_sketches.py (our own hand), each with three DEMs of
# ../shared/data/dem whose style suits it.  For every case it prints the
# figures, whether they meet the goal (structure_r >= 0.6, feature_recall >=
# 0.7, seam_lap and seam_grad <= 1.2, slope_w1 <= 3 degrees), the seconds of
# the synthesis, then the worst case of every figure, and writes a hillshade
# montage per sketch (sketch | one output per DEM) into OUT/montage_*.png to
# be looked at.  Skips (exit 0) when ../shared is absent.
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

GOAL = {"structure_r": (">=", 0.6), "feature_recall": (">=", 0.7), "seam_lap": ("<=", 1.2),
        "seam_grad": ("<=", 1.2), "slope_w1_deg": ("<=", 3.0)}

BT, MK, AI = "mountains_bigtujunga_ca_30m.tif", "mountains_mackay_id_30m.tif", \
    "mountains_aiguestortes_pyrenees_20m_nocrs.tif"
JB, ZI, SH, SH10 = "hills_jacksboro_tn_3arcsec.tif", "canyon_zion_ut_srtm90m.tif", \
    "volcano_st_helens_30m.tif", "volcano_st_helens_10m_nocrs.tif"
# sketch -> (drawn by, exemplars, cell size of a sketch without CRS).  Exemplars whose style
# suits the sketch, at the sketch's resolution or finer (a 90 m DEM brought to 30 m cells has
# no detail below 90 m, and the yardstick compares curvature per square metre): ridge sketches
# on mountains; valley sketches on dissected mountains and a volcano's gullies.  Mackay (a range
# beside a flat basin: 57 % of its cells away from its main valleys are flatter than 5 degrees)
# is a ridge exemplar here: a valley network leaves no room for its basin, so its slope figure
# would measure the missing basin.
MATRIX = [
    ("fork_valleys_800.tif", "shared", [BT, AI, SH10], None),
    ("star_ridges_720.tif", "shared", [MK, BT, AI], None),
    ("meander_valley_900.tif", "shared", [BT, ZI, MK], 30.0),
    ("arcs_ridges_geo1s.tif", "shared", [MK, BT, AI], None),
    ("comb_valleys_640.tif", "shared", [AI, BT, SH10], None),
    ("dendritic_valleys_768.tif", "own", [BT, AI, SH10], None),
    ("junction4_ridges_640.tif", "own", [MK, BT, AI], None),
    ("spiral_ridge_geo3s_560.tif", "own", [JB, BT, MK], None),
    ("radial5_valleys_600.tif", "own", [SH10, BT, AI], None),
    ("fishbone_ridges_geo1s_640.tif", "own", [BT, MK, AI], None),
]
NOCRS_CELL = {AI: 20.0, SH10: 10.0}


def meets(name, v):
    op, lim = GOAL[name]
    return v is not None and (v >= lim if op == ">=" else v <= lim)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build/gdal_driver/terrasynth"))
    ap.add_argument("--shared", default=os.path.join(os.path.dirname(ROOT), "shared"))
    ap.add_argument("--out", default=os.path.join(ROOT, "build/quality"))
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--only", default="")
    ap.add_argument("--extra", default="", help="more terrasynth synth arguments")
    ap.add_argument("--patch", type=int, default=64)
    ap.add_argument("--no-montage", action="store_true")
    a = ap.parse_args()
    dem_dir = os.path.join(a.shared, "data/dem")
    metrics = os.path.join(a.shared, "eval/terrain_metrics.py")
    if not os.path.isdir(dem_dir) or not os.path.exists(metrics):
        print("quality: skipped: %s not found" % a.shared)
        return 0
    sk_dir = os.path.join(a.out, "sketches")
    os.makedirs(sk_dir, exist_ok=True)
    subprocess.run([sys.executable, os.path.join(a.shared, "eval/make_sketches.py"), sk_dir],
                   check=True)
    subprocess.run([sys.executable, os.path.join(HERE, "draw_sketches.py"), sk_dir], check=True)
    seeds = [int(s) for s in a.seeds.split(",")]
    rows = []
    print("%-30s %-46s %4s %6s %6s %6s %6s %6s %6s  %s" % (
        "sketch", "exemplar", "seed", "r", "recall", "s_lap", "s_grad", "slope", "sec", "goal"))
    for sk, _, exs, cell in MATRIX:
        if a.only and a.only not in sk:
            continue
        for ex in exs:
            for seed in seeds:
                tag = "%s__%s__%d" % (sk[:-4], ex[:-4], seed)
                out = os.path.join(a.out, tag + ".tif")
                cmd = [a.terrasynth, "synth", "-q", "--sketch", os.path.join(sk_dir, sk),
                       "--exemplar", os.path.join(dem_dir, ex), "--seed", str(seed),
                       "--patch-size", str(a.patch), out] + a.extra.split()
                cs = cell or NOCRS_CELL.get(ex)
                if cs:
                    cmd += ["--cell-size", str(cs)]
                t0 = time.time()
                r = subprocess.run(cmd, capture_output=True, text=True)
                sec = time.time() - t0
                if r.returncode != 0:
                    print("%s: terrasynth failed: %s" % (tag, r.stderr.strip()))
                    rows.append({"tag": tag, "failed": True})
                    continue
                mcmd = [sys.executable, metrics, "--out", out, "--exemplar",
                        os.path.join(dem_dir, ex), "--sketch", os.path.join(sk_dir, sk),
                        "--patch", str(a.patch)]
                if cs:
                    mcmd += ["--cell-size", str(cs)]
                m = json.loads(subprocess.run(mcmd, capture_output=True, text=True,
                                              check=True).stdout)
                ok = all(meets(k, m.get(k)) for k in GOAL)
                m.update({"tag": tag, "sketch": sk, "exemplar": ex, "seed": seed, "sec": sec,
                          "ok": ok})
                rows.append(m)
                print("%-30s %-46s %4d %6.2f %6.2f %6.2f %6.2f %6.2f %6.1f  %s" % (
                    sk[:-4], ex[:-4], seed, m["structure_r"], m["feature_recall"],
                    m["seam_lap"], m["seam_grad"], m["slope_w1_deg"], sec,
                    "ok" if ok else "MISS " + ",".join(k for k in GOAL if not meets(k, m[k]))),
                    flush=True)
    good = [r for r in rows if not r.get("failed")]
    if not good:
        return 1
    print("\nworst case of each figure over %d runs (%d failed):" % (len(good), len(rows) - len(good)))
    for k, (op, lim) in GOAL.items():
        w = min(good, key=lambda r: r[k]) if op == ">=" else max(good, key=lambda r: r[k])
        print("  %-15s %7.3f  goal %s %g  %s  (%s)" % (k, w[k], op, lim,
                                                       "ok" if meets(k, w[k]) else "MISS", w["tag"]))
    for k in GOAL:
        vals = [r[k] for r in good]
        print("  mean %-10s %7.3f" % (k, sum(vals) / len(vals)))
    n_ok = sum(1 for r in good if r["ok"])
    print("cases meeting every goal: %d of %d; synthesis seconds: total %.1f, max %.1f" % (
        n_ok, len(rows), sum(r["sec"] for r in good), max(r["sec"] for r in good)))
    with open(os.path.join(a.out, "quality.json"), "w") as f:
        json.dump(rows, f, indent=1)
    if not a.no_montage:
        try:
            import montage
            montage.write_all(a.out, sk_dir, good)
        except ImportError as e:
            print("quality: no montage (%s)" % e)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, HERE)
    sys.exit(main())
