#!/usr/bin/python3
# amplify_superres.py - the super-resolution check of `terrasynth amplify` on real data
# a real fine DEM is area-averaged by the factor, amplified back with a
# dictionary built from a DIFFERENT real DEM of the same style, and compared with the real
# fine DEM, side by side with `gdalwarp -r cubic` of the same coarse input.  The figures
# come from ../shared/eval/terrain_metrics.py (slope W1, power-spectrum slope; none of our
# code) and plain numpy (RMSE, how far the output averages back to the input).
#
#   /usr/bin/python3 bench/quality/amplify_superres.py [TERRASYNTH] [-- extra amplify args]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from osgeo import gdal

gdal.UseExceptions()
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SHARED = os.path.join(ROOT, "..", "shared")
DEM = os.path.join(SHARED, "data", "dem")
METRICS = os.path.join(SHARED, "eval", "terrain_metrics.py")
# (real fine DEM, exemplar of the same style, factor)
PAIRS = [
    ("mountains_bigtujunga_ca_30m.tif", "mountains_mackay_id_30m.tif", 8),
    ("mountains_mackay_id_30m.tif", "mountains_bigtujunga_ca_30m.tif", 8),
    ("mountains_bigtujunga_ca_30m.tif", "mountains_mackay_id_30m.tif", 4),
    ("volcano_st_helens_30m.tif", "mountains_mackay_id_30m.tif", 6),
    # beyond the four the patch size was chosen on
    ("canyon_zion_ut_srtm90m.tif", "mountains_bigtujunga_ca_30m.tif", 4),
    ("hills_jacksboro_tn_3arcsec.tif", "canyon_zion_ut_srtm90m.tif", 4),
    ("mountains_mackay_id_30m.tif", "volcano_st_helens_30m.tif", 6),
]


def coarse_of(fine, factor, d):
    s = gdal.Open(os.path.join(DEM, fine))
    z = s.ReadAsArray().astype(np.float64)
    nd = s.GetRasterBand(1).GetNoDataValue()
    if nd is not None:
        z[z == nd] = np.nan
    h, w = (z.shape[0] // factor) * factor, (z.shape[1] // factor) * factor
    z = z[:h, :w]
    c = z.reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))
    gt = list(s.GetGeoTransform())
    out = []
    for name, a, g in (("fine.tif", z, gt),
                       ("coarse.tif", c, [gt[0], gt[1] * factor, 0, gt[3], 0, gt[5] * factor])):
        p = os.path.join(d, name)
        ds = gdal.GetDriverByName("GTiff").Create(p, a.shape[1], a.shape[0], 1, gdal.GDT_Float32)
        ds.SetGeoTransform(g)
        ds.SetProjection(s.GetProjection())
        b = ds.GetRasterBand(1)
        b.SetNoDataValue(-9999)
        b.WriteArray(np.where(np.isnan(a), -9999, a))
        ds = None
        out.append(p)
    return out + [abs(gt[1])]


def figures(out, fine, coarse, factor):
    m = json.loads(subprocess.run([sys.executable, METRICS, "--out", out, "--exemplar", fine],
                                  capture_output=True, text=True, check=True).stdout)
    a = gdal.Open(out).ReadAsArray().astype(np.float64)
    f = gdal.Open(fine).ReadAsArray().astype(np.float64)
    c = gdal.Open(coarse).ReadAsArray().astype(np.float64)
    ok = (a > -9000) & (f > -9000)
    rmse = float(np.sqrt(np.mean((a[ok] - f[ok]) ** 2)))
    h, w = c.shape
    av = a[:h * factor, :w * factor].reshape(h, factor, w, factor).mean(axis=(1, 3))
    cv = c > -9000
    back = float(np.nanmax(np.abs(av[cv] - c[cv])) / (c[cv].max() - c[cv].min()))
    return {"slope_w1": m["slope_w1_deg"], "psd_beta_diff": m["psd_beta_diff"],
            "seam_lap": m["seam_lap"], "rmse": rmse, "averages_back": back}


def main():
    args = sys.argv[1:]
    extra = args[args.index("--") + 1:] if "--" in args else []
    ts = args[0] if args and args[0] != "--" else os.path.join(ROOT, "build", "gdal_driver",
                                                               "terrasynth")
    rows = []
    for fine_name, ex_name, factor in PAIRS:
        with tempfile.TemporaryDirectory() as d:
            fine, coarse, res = coarse_of(fine_name, factor, d)
            amp, cub = os.path.join(d, "amp.tif"), os.path.join(d, "cubic.tif")
            subprocess.run([ts, "amplify", coarse, amp, "--exemplar",
                            os.path.join(DEM, ex_name), "--factor", str(factor), "-q", *extra],
                           check=True)
            subprocess.run(["gdalwarp", "-q", "-r", "cubic", "-tr", str(res), str(res),
                            "-dstnodata", "-9999", coarse, cub], check=True)
            fa, fc = figures(amp, fine, coarse, factor), figures(cub, fine, coarse, factor)
            rows.append((fine_name, ex_name, factor, fa, fc))
    print("%-34s %-30s %3s | %-22s | %-13s | %-22s | %s" % (
        "real fine DEM", "exemplar", "x", "slope W1 amp / cubic", "PSD dbeta a/c",
        "RMSE amp / cubic", "averages back"))
    ok = True
    for fine_name, ex_name, factor, fa, fc in rows:
        r1, r2 = fa["slope_w1"] / fc["slope_w1"], fa["rmse"] / fc["rmse"]
        pa, pc = fa["psd_beta_diff"], fc["psd_beta_diff"]
        print("%-34s %-30s %3d | %5.2f / %5.2f (%.2f) | %5s / %5s | %6.2f / %6.2f (%.2f) | %.4f"
              % (fine_name, ex_name, factor, fa["slope_w1"], fc["slope_w1"], r1,
                 "-" if pa is None else "%.2f" % pa, "-" if pc is None else "%.2f" % pc,
                 fa["rmse"], fc["rmse"], r2, fa["averages_back"]))
        ok &= r1 <= 0.5 and r2 <= 1.2 and fa["averages_back"] <= 0.01
    print("goals (W1 <= 0.5 x cubic, RMSE <= 1.2 x cubic, averages back within 1 %%): %s"
          % ("met" if ok else "NOT met"))


if __name__ == "__main__":
    main()
