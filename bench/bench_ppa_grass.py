#!/usr/bin/python3
# bench_ppa_grass.py - `terrasynth ppa` against GRASS GIS, in the same run.
#
#  speed:  a SIZE x SIZE mosaic (mirror-tiled, no seams) of a projected DEM (Big Tujunga, UTM
#          30 m) and of a geographic one (Zion, 3 arc-seconds): `terrasynth ppa --both` against
#          `r.geomorphon search=10` on the same raster; wall time and peak memory of each, and
#          the ratio (goal: TerraSynth >= 8 x faster).
#  recall: every DEM of ../shared/data/dem (but the global ETOPO5 grid): the PPA's valley
#          cells against the channels of `r.stream.extract threshold=400`, within 3 cells:
#          recall (channel cells with a valley cell that near) and precision (valley cells with
#          a channel cell that near); goal recall >= 0.7 at precision >= 0.6 with the
#          defaults; then the valleys by profile alone (--min-drainage 0) beside them.
#  scaling: `terrasynth ppa --both` alone at 1024^2, 4096^2, 8192^2: bytes per cell, cells/s.
#
# GRASS (Debian package grass-core) is a benchmark's peer, not a build or test dependency:
# without it the script says so and stops.
#
#   /usr/bin/python3 bench/bench_ppa_grass.py [--size 4096] [--no-speed] [--no-recall] [--no-scaling]
#        [--ppa-args '--profile-length 11 ...'] [--terrasynth BIN]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

import numpy as np
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_amplify import DEM, ROOT, spawn  # noqa: E402

gdal.UseExceptions()

# the defaults are valleys where the water runs (ppa.md: drainage-area test, a low threshold,
# short branches kept); beside them, the valleys by profile alone (the paper's, as ridges)
PROFILE_ARGS = "--min-drainage 0"


def mosaic(src, size, out):
    """src mirror-tiled to size x size cells (tile i mirrored when i is odd), its CRS and cell
    size kept, its origin kept."""
    ds = gdal.Open(src)
    a = ds.GetRasterBand(1).ReadAsArray().astype(np.float32)
    nd = ds.GetRasterBand(1).GetNoDataValue()
    if nd is not None:
        a[a == nd] = np.nan
    h, w = a.shape
    ry = [np.flipud(a) if (i % 2) else a for i in range(size // h + 1)]
    col = np.concatenate(ry, axis=0)[:size]
    rx = [np.fliplr(col) if (i % 2) else col for i in range(size // w + 1)]
    m = np.concatenate(rx, axis=1)[:, :size]
    m = np.where(np.isnan(m), np.float32(-9999), m)
    o = gdal.GetDriverByName("GTiff").Create(out, size, size, 1, gdal.GDT_Float32,
                                             ["TILED=YES", "COMPRESS=NONE"])
    o.SetGeoTransform(ds.GetGeoTransform())
    o.SetProjection(ds.GetProjection())
    o.GetRasterBand(1).SetNoDataValue(-9999)
    o.GetRasterBand(1).WriteArray(m)
    o = None


def grass(dem, script, tmp):
    """Run the shell `script` in a temporary GRASS location of dem's CRS (XY without one);
    its stdout and stderr."""
    srs = gdal.Open(dem).GetProjection()
    loc = dem if srs else "XY"
    sh = os.path.join(tmp, "grass_job.sh")
    with open(sh, "w") as f:
        f.write("set -e\n" + script)
    p = subprocess.run(["grass", "--tmp-location", loc, "--exec", "sh", sh],
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError("GRASS failed: " + p.stderr[-2000:])
    return p.stdout + p.stderr


def speed(ts, size, tmp):
    for name, src in (("projected (Big Tujunga, UTM 30 m)", "mountains_bigtujunga_ca_30m.tif"),
                      ("geographic (Zion, 3 arc-seconds)", "canyon_zion_ut_srtm90m.tif")):
        dem = os.path.join(tmp, "mosaic.tif")
        mosaic(os.path.join(DEM, src), size, dem)
        t, mb, _ = spawn([ts, "ppa", dem, os.path.join(tmp, "ppa.tif"), "--both", "-q"])
        out = grass(dem, "r.external -o input=%s output=dem >/dev/null 2>&1\n"
                         "g.region raster=dem\n"
                         "/usr/bin/time -f 'GEOMORPHON %%e s %%M KB' r.geomorphon elevation=dem "
                         "forms=forms search=10 --quiet\n" % dem, tmp)
        m = re.search(r"GEOMORPHON ([0-9.]+) s ([0-9]+) KB", out)
        tg, mbg = float(m.group(1)), int(m.group(2)) / 1024.0
        print("%s %dx%d: terrasynth ppa --both %.2f s, %.0f MB; r.geomorphon search=10 %.2f s, "
              "%.0f MB; r.geomorphon / terrasynth = %.1f x (goal >= 8: %s)"
              % (name, size, size, t, mb, tg, mbg, tg / t, "PASS" if tg / t >= 8 else "FAIL"),
              flush=True)


def scaling(ts, tmp):
    """terrasynth ppa --both alone at 1024^2, 4096^2 and 8192^2 of the projected mosaic: bytes
    per cell (peak memory over cells) and cells per second (goal: both about constant, under
    64 bytes per cell)."""
    for size in (1024, 4096, 8192):
        dem = os.path.join(tmp, "mosaic.tif")
        mosaic(os.path.join(DEM, "mountains_bigtujunga_ca_30m.tif"), size, dem)
        t, mb, _ = spawn([ts, "ppa", dem, os.path.join(tmp, "ppa.tif"), "--both", "-q"])
        cells = size * size
        print("terrasynth ppa --both %dx%d: %.2f s, %.0f MB: %.1f bytes/cell, %.2f M cells/s"
              % (size, size, t, mb, mb * 1048576.0 / cells, cells / t / 1e6), flush=True)
        os.remove(dem)


def near(mask, other, r=3):
    """The share of mask's cells with an `other` cell within r cells (Euclidean)."""
    from scipy import ndimage
    if not mask.any():
        return float("nan")
    d = ndimage.distance_transform_edt(~other)
    return float((d[mask] <= r).mean())


def recall(ts, tmp, ppa_args):
    rows = []
    for f in sorted(os.listdir(DEM)):
        if not f.endswith(".tif") or "etopo5" in f:
            continue
        src = os.path.join(DEM, f)
        cs = re.search(r"_(\d+)m_nocrs", f)
        extra = ["--cell-size", cs.group(1)] if cs else []
        out = os.path.join(tmp, "v.tif")
        subprocess.run([ts, "ppa", src, out, "--valleys", "-q"] + extra + shlex.split(ppa_args),
                       check=True)
        streams = os.path.join(tmp, "streams.tif")
        grass(src, "r.external -o input=%s output=dem >/dev/null 2>&1\n"
                   "g.region raster=dem\n"
                   "r.stream.extract elevation=dem threshold=400 stream_raster=streams --quiet\n"
                   "r.out.gdal -c --overwrite input=streams output=%s format=GTiff type=Int32 --quiet "
                   ">/dev/null 2>&1\n" % (src, streams), tmp)
        v = gdal.Open(out).ReadAsArray()
        sds = gdal.Open(streams)  # kept open while its band is read
        s = sds.ReadAsArray()
        snd = sds.GetRasterBand(1).GetNoDataValue()
        valley = (v == 2) | (v == 3)
        chan = (s > 0) & ((s != snd) if snd is not None else True)
        rec, prec = near(chan, valley), near(valley, chan)
        rows.append((f[:-4], rec, prec))
        print("%-45s recall %.2f precision %.2f (%d channel cells, %d valley cells)"
              % (f[:-4], rec, prec, int(chan.sum()), int(valley.sum())), flush=True)
    rec = [r[1] for r in rows]
    prec = [r[2] for r in rows]
    print("valleys vs r.stream.extract (threshold 400, within 3 cells)%s: recall %.2f-%.2f "
          "(mean %.2f), precision %.2f-%.2f (mean %.2f); goal recall >= 0.7 at precision >= 0.6 "
          "on every DEM: %s"
          % (" with " + ppa_args if ppa_args else "", min(rec), max(rec), sum(rec) / len(rec),
             min(prec), max(prec), sum(prec) / len(prec),
             "PASS" if all(r >= 0.7 and p >= 0.6 for _, r, p in rows) else "FAIL"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build", "gdal_driver",
                                                         "terrasynth"))
    ap.add_argument("--size", type=int, default=4096)
    ap.add_argument("--no-speed", action="store_true")
    ap.add_argument("--no-recall", action="store_true")
    ap.add_argument("--no-scaling", action="store_true")
    ap.add_argument("--ppa-args", default="", help="extra `terrasynth ppa` options (recall)")
    a = ap.parse_args()
    if not os.path.isdir(DEM):
        print("bench_ppa_grass: skipped: ../shared/data/dem not present")
        return 0
    if not shutil.which("grass"):
        print("bench_ppa_grass: skipped: GRASS GIS is not installed (apt install grass-core)")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        if not a.no_speed:
            speed(a.terrasynth, a.size, tmp)
        if not a.no_scaling:
            scaling(a.terrasynth, tmp)
        if not a.no_recall:
            recall(a.terrasynth, tmp, a.ppa_args)
            if not a.ppa_args:  # and the valleys by profile alone, for comparison
                recall(a.terrasynth, tmp, PROFILE_ARGS)
    return 0


if __name__ == "__main__":
    sys.exit(main())
