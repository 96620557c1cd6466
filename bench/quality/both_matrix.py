#!/usr/bin/python3
# both_matrix.py - the matrix of sketches that draw ridges AND valleys, painted and as lines:
# each synthesised with `terrasynth synth --sketch` and judged by the independent yardsticks
# of ../shared/eval: terrain_metrics.py --mode both (layout, recall of each kind, seams,
# slopes) and drainage_metrics.py (GRASS r.stream.extract: do drawn valleys carry water, does
# water cross drawn ridges).
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
#
#   /usr/bin/python3 bench/quality/both_matrix.py [--terrasynth BIN] [--shared DIR]
#        [--out DIR] [--seeds 1,2,3] [--only SUBSTRING] [--form painted,lines] [--no-montage]
#
# Sketches: the two both-kind drawings of ../shared/eval/make_sketches.py and the two of
# bench/quality/draw_sketches.py, each with three DEMs of ../shared/data/dem whose style suits
# it; painted (the raster, --mode auto) and digitised (the same drawing's GeoPackage on the
# raster's grid, --like).  Prints every figure of every run, whether it meets the goals
# (structure_r >= 0.6, recall of each kind >= 0.7, seam_lap and seam_grad <= 1.2, slope_w1
# <= 3 degrees, valley_flow_recall >= 0.9, ridge_flow_cross <= 0.05), the worst case of each
# figure, and writes hillshade montages (OUT/montage_*.png).  The drainage figures need GRASS
# (`apt-get install grass-core`, python3-skimage); without it they are left out.  Skips (exit
# 0) when ../shared is absent.
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

GOAL = {"structure_r": (">=", 0.6), "feature_recall_ridges": (">=", 0.7),
        "feature_recall_valleys": (">=", 0.7), "seam_lap": ("<=", 1.2), "seam_grad": ("<=", 1.2),
        "slope_w1_deg": ("<=", 3.0), "valley_flow_recall": (">=", 0.9),
        "ridge_flow_cross": ("<=", 0.05)}

BT, MK, AI = "mountains_bigtujunga_ca_30m.tif", "mountains_mackay_id_30m.tif", \
    "mountains_aiguestortes_pyrenees_20m_nocrs.tif"
SH10, SH30, SHC = "volcano_st_helens_10m_nocrs.tif", "volcano_st_helens_30m.tif", \
    "volcano_st_helens_crater_2007_10m.tif"
MATRIX = [
    ("valley_between_ridges_800.tif", "shared", [BT, MK, AI]),
    ("volcano_rim_gullies_700.tif", "shared", [SH10, SH30, SHC]),
    ("range_spurs_both_720.tif", "own", [BT, MK, AI]),
    ("caldera_both_geo1s_600.tif", "own", [SH30, SH10, BT]),
]
NOCRS_CELL = {AI: 20.0, SH10: 10.0}


def meets(name, v):
    op, lim = GOAL[name]
    return v is not None and (v >= lim if op == ">=" else v <= lim)


def with_crs(path, tmp):
    """GRASS needs a CRS: a copy of a raster without one, in a metric CRS."""
    from osgeo import gdal
    ds = gdal.Open(path)
    if ds.GetProjection():
        return path
    out = os.path.join(tmp, os.path.basename(path)[:-4] + "_crs.tif")
    if not os.path.exists(out):
        gdal.Translate(out, ds, outputSRS="EPSG:32611")
    return out


def drainage(metrics, out, sketch, exemplar, tmp, cache):
    """drainage_metrics.py on the output (the exemplar's sink share computed once)."""
    cmd = [sys.executable, metrics, "--out", with_crs(out, tmp), "--sketch", sketch]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:  # said once: valley flow and ridge cross then print as '-'
        if "said" not in cache:
            cache["said"] = True
            print("both_matrix: drainage_metrics.py failed (%s)" % (
                p.stderr.strip().splitlines() or ["no message"])[-1], file=sys.stderr)
        return {}
    d = json.loads(p.stdout)
    if exemplar not in cache:
        q = subprocess.run([sys.executable, metrics, "--out", with_crs(exemplar, tmp)],
                           capture_output=True, text=True)
        cache[exemplar] = json.loads(q.stdout)["sink_frac"] if q.returncode == 0 else None
    d["sink_frac_exemplar"] = cache[exemplar]
    return d


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build/gdal_driver/terrasynth"))
    ap.add_argument("--shared", default=os.path.join(os.path.dirname(ROOT), "shared"))
    ap.add_argument("--out", default=os.path.join(ROOT, "build/quality_both"))
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--only", default="")
    ap.add_argument("--form", default="painted,lines")
    ap.add_argument("--patch", type=int, default=64)
    ap.add_argument("--tiled", type=int, default=0,
                    help="a sketch in tiles of this many cells (laid out coarser, amplified)")
    ap.add_argument("--no-montage", action="store_true")
    a = ap.parse_args()
    dem_dir = os.path.join(a.shared, "data/dem")
    tm = os.path.join(a.shared, "eval/terrain_metrics.py")
    dm = os.path.join(a.shared, "eval/drainage_metrics.py")
    if not os.path.isdir(dem_dir) or not os.path.exists(tm):
        print("both_matrix: skipped: %s not found" % a.shared)
        return 0
    grass = shutil.which("grass") is not None
    sk_dir = os.path.join(a.out, "sketches")
    os.makedirs(sk_dir, exist_ok=True)
    subprocess.run([sys.executable, os.path.join(a.shared, "eval/make_sketches.py"), sk_dir],
                   check=True, capture_output=True)
    subprocess.run([sys.executable, os.path.join(HERE, "draw_sketches.py"), sk_dir], check=True)
    tmp = tempfile.mkdtemp(prefix="both-")
    seeds = [int(s) for s in a.seeds.split(",")]
    forms = a.form.split(",")
    rows, cache = [], {}
    print("%-30s %-8s %-40s %4s %5s %5s %5s %5s %5s %5s %5s %6s %5s  %s" % (
        "sketch", "form", "exemplar", "seed", "r", "recR", "recV", "s_lap", "s_grd", "slope",
        "vflow", "rcross", "sec", "goal"))
    for sk, _, exs in MATRIX:
        if a.only and a.only not in sk:
            continue
        raster = os.path.join(sk_dir, sk)
        for form in forms:
            src = raster if form == "painted" else raster[:-4] + ".gpkg"
            for ex in exs:
                for seed in seeds:
                    tag = "%s__%s__%s__%d" % (sk[:-4], form, ex[:-4], seed)
                    out = os.path.join(a.out, tag + ".tif")
                    cmd = [a.terrasynth, "synth", "-q", "--sketch", src, "--exemplar",
                           os.path.join(dem_dir, ex), "--seed", str(seed), "--patch-size",
                           str(a.patch), out]
                    if form == "lines":
                        cmd += ["--like", raster]
                    if a.tiled:
                        cmd += ["--tiled", str(a.tiled)]
                    if NOCRS_CELL.get(ex):
                        cmd += ["--cell-size", str(NOCRS_CELL[ex])]
                    t0 = time.time()
                    r = subprocess.run(cmd, capture_output=True, text=True)
                    sec = time.time() - t0
                    if r.returncode != 0:
                        print("%s: terrasynth failed: %s" % (tag, r.stderr.strip()))
                        rows.append({"tag": tag, "failed": True})
                        continue
                    mcmd = [sys.executable, tm, "--out", out, "--exemplar",
                            os.path.join(dem_dir, ex), "--sketch", raster, "--patch",
                            str(a.patch), "--mode", "both"]
                    if NOCRS_CELL.get(ex):
                        mcmd += ["--cell-size", str(NOCRS_CELL[ex])]
                    m = json.loads(subprocess.run(mcmd, capture_output=True, text=True,
                                                  check=True).stdout)
                    if grass:
                        m.update(drainage(dm, out, raster, os.path.join(dem_dir, ex), tmp, cache))
                    goals = [k for k in GOAL if k in m or not k.startswith(("valley_flow",
                                                                              "ridge_flow"))]
                    ok = all(meets(k, m.get(k)) for k in goals)
                    m.update({"tag": tag, "sketch": sk, "form": form, "exemplar": ex,
                              "seed": seed, "sec": sec, "ok": ok})
                    rows.append(m)
                    print("%-30s %-8s %-40s %4d %5.2f %5.2f %5.2f %5.2f %5.2f %5.2f %5s %6s %5.1f"
                          "  %s" % (sk[:-4], form, ex[:-4], seed, m["structure_r"],
                                    m["feature_recall_ridges"], m["feature_recall_valleys"],
                                    m["seam_lap"], m["seam_grad"], m["slope_w1_deg"],
                                    "%.2f" % m["valley_flow_recall"] if "valley_flow_recall" in m
                                    else "-",
                                    "%.3f" % m["ridge_flow_cross"] if "ridge_flow_cross" in m
                                    else "-", sec,
                                    "ok" if ok else "MISS " + ",".join(
                                        k for k in goals if not meets(k, m.get(k)))),
                          flush=True)
    shutil.rmtree(tmp, ignore_errors=True)
    good = [r for r in rows if not r.get("failed")]
    if not good:
        return 1
    print("\nworst case of each figure over %d runs (%d failed):" % (len(good),
                                                                     len(rows) - len(good)))
    for k, (op, lim) in GOAL.items():
        have = [r for r in good if r.get(k) is not None]
        if not have:
            print("  %-22s (not measured: GRASS missing)" % k)
            continue
        w = min(have, key=lambda r: r[k]) if op == ">=" else max(have, key=lambda r: r[k])
        print("  %-22s %7.3f  goal %s %g  %s  (%s)" % (k, w[k], op, lim,
                                                       "ok" if meets(k, w[k]) else "MISS",
                                                       w["tag"]))
    for form in forms:
        fr = [r for r in good if r["form"] == form]
        print("  %s: %d of %d runs meet every goal; mean structure_r %.3f, recall %.3f / %.3f"
              % (form, sum(r["ok"] for r in fr), len(fr),
                 sum(r["structure_r"] for r in fr) / max(1, len(fr)),
                 sum(r["feature_recall_ridges"] for r in fr) / max(1, len(fr)),
                 sum(r["feature_recall_valleys"] for r in fr) / max(1, len(fr))))
    with open(os.path.join(a.out, "both.json"), "w") as f:
        json.dump(rows, f, indent=1)
    if not a.no_montage:
        try:
            sys.path.insert(0, HERE)
            import montage
            for form in forms:
                sub = [dict(r, sketch=r["sketch"]) for r in good if r["form"] == form]
                montage.write_all(a.out, sk_dir, sub, prefix="montage_%s_" % form)
        except ImportError as e:
            print("both_matrix: no montage (%s)" % e)
    return 0


if __name__ == "__main__":
    sys.exit(main())
