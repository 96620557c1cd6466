#!/usr/bin/python3
# SPDX-License-Identifier: GPL-2.0-or-later
"""bench_scale: free patch synthesis past one run, every figure printed.

  /usr/bin/python3 bench/bench_scale.py [--terrasynth BIN] [--plugins DIR] [--tile 1024]
                                        [--exemplar DEM] [--quick] [--work DIR]

1. A window of a 65 536 x 65 536 tiled recipe through `gdal_translate -srcwin` (a fresh
   process each): time and peak memory (goal: a 256^2 window in <= 5 s and <= 1 GB), for a
   window inside one tile of the last wave (17 tiles made: the tile and its cone) and one
   across four tiles.
2. Time per cell: `terrasynth synth` in one piece and in tiles at 1024^2, 4096^2 and 8192^2
   (cells/s printed; the goal: flat from 1024^2 up); tiles on 1 thread and on all (the
   parallel fraction, and what Amdahl's law gives on 16 threads).
3. The Dask runner: 16 384^2 from a tiled recipe on a local cluster of 2 workers (threads of
   the runner) against the single-process tiled 8192^2 of step 2 (goal: <= 4 x its time, 4 x
   the cells), peak memory (goal <= 1.5 GB a worker).  Same bytes on 1 and 2 workers, as
   threads and as processes, and as the CLI: checked on 2048^2.

The exemplar is the Jacksboro DEM warped once to UTM 16N at 80 m (gdalwarp, in the work
folder), so that every size synthesises from the same exemplar: on the DEM's own geographic
grid a 16 384-cell side spans 13.6 degrees of latitude, the exemplar is resampled to the
ground resolution at the grid's centre row (33.0 vs 29.6 degrees N), and 8192^2 and 16 384^2
were different problems (the exemplar about 387 vs 374 cells wide, so other FFT sizes: the
FFTs' share of the CPU samples 19 vs 23 %, and 16 384^2 cost 4.2 x 8192^2 in one process).  `--exemplar` takes any other DEM as it is.
4. Seams across tile borders: ../shared/eval/terrain_metrics.py on the 4096^2 tiled output
   (seam_lap and seam_grad <= 1.2), and, ours, the 99.9th percentile of |Laplacian| on the
   cells next to a tile border against everywhere (1 = the borders are like any cell).

Timings are of this machine in this run; ratios are what the goals are about.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from osgeo import gdal

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
METRICS = os.path.normpath(os.path.join(ROOT, "..", "shared", "eval", "terrain_metrics.py"))


# the creation options of terrasynth-dask --no-overviews on a Float32 recipe (ZSTD where
# GDAL has it, as the runner)
_ZSTD = "ZSTD" in (gdal.GetDriverByName("GTiff").GetMetadataItem("DMD_CREATIONOPTIONLIST") or "")
DASK_CODEC = "ZSTD" if _ZSTD else "DEFLATE"
DASK_CO = (["-co", "TILED=YES", "-co", "BLOCKXSIZE=256", "-co", "BLOCKYSIZE=256",
            "-co", "COMPRESS=" + DASK_CODEC, "-co", "PREDICTOR=3", "-co", "BIGTIFF=IF_SAFER"]
           + (["-co", "ZSTD_LEVEL=1"] if _ZSTD else []))


def time_rss(cmd, env=None):
    """seconds and the peak resident MB of cmd alone (GNU time)."""
    t = time.monotonic()
    p = subprocess.run(["/usr/bin/time", "-f", "TSRSS %M"] + [str(c) for c in cmd],
                       capture_output=True, text=True, env=env)
    dt = time.monotonic() - t
    if p.returncode != 0:
        sys.exit("bench_scale: %s failed: %s" % (" ".join(map(str, cmd[:3])), p.stderr.strip()))
    kb = [int(line.split()[1]) for line in p.stderr.splitlines() if line.startswith("TSRSS")]
    return dt, p, (kb[-1] / 1024.0 if kb else float("nan"))


def border_ratio(path, T):
    z = gdal.Open(path).ReadAsArray().astype(np.float64)
    lap = np.abs(z[1:-1, :-2] + z[1:-1, 2:] + z[:-2, 1:-1] + z[2:, 1:-1] - 4 * z[1:-1, 1:-1])
    H, W = lap.shape
    near = np.zeros((H, W), bool)
    for b in range(T, W + 2, T):  # columns b-1, b of z are cells b-2, b-1 of lap
        near[:, max(b - 3, 0):min(b + 1, W)] = True
    for b in range(T, H + 2, T):
        near[max(b - 3, 0):min(b + 1, H), :] = True
    return np.percentile(lap[near], 99.9) / np.percentile(lap[~near], 99.9)


def wave_roughness(path, T):
    """Mean |gradient| (elevation units per cell) of the T x T cells of each wave (tile
    (i, j) is of wave (i & 1) + 2 (j & 1)): when each 2 x 2 block of tiles holds a copy of
    a small exemplar, the waves differ and the tile lattice shows (1 = the waves alike)."""
    ds = gdal.Open(path)
    a = ds.GetRasterBand(1).ReadAsArray().astype(np.float64)
    nd = ds.GetRasterBand(1).GetNoDataValue()
    if nd is not None:
        a[a == nd] = np.nan
    gy, gx = np.gradient(a)
    g = np.hypot(gx, gy)
    w = [[], [], [], []]
    for j in range(a.shape[0] // T):
        for i in range(a.shape[1] // T):
            w[(i & 1) + 2 * (j & 1)].append(np.nanmean(g[j * T:(j + 1) * T, i * T:(i + 1) * T]))
    return [float(np.mean(v)) for v in w], wave_anova(w)


def wave_anova(w):
    """One-way analysis of variance of the tiles' mean |gradient| across the four waves: F
    (between-wave over within-wave variance; about 1 when the waves are alike) and its p."""
    k, n = len(w), sum(len(v) for v in w)
    if k < 2 or n <= k:
        return float("nan"), float("nan")
    grand = np.mean(np.concatenate([np.asarray(v) for v in w]))
    between = sum(len(v) * (np.mean(v) - grand) ** 2 for v in w) / (k - 1)
    within = sum(((np.asarray(v) - np.mean(v)) ** 2).sum() for v in w) / (n - k)
    F = between / within if within > 0 else float("inf")
    try:
        from scipy.stats import f as fdist
        p = float(fdist.sf(F, k - 1, n - k))
    except ImportError:
        p = float("nan")
    return float(F), p


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--terrasynth", default=os.path.join(ROOT, "build", "gdal_driver",
                                                         "terrasynth"))
    ap.add_argument("--plugins", default=os.path.join(ROOT, "build", "gdalplugins"))
    ap.add_argument("--exemplar", default=None,
                    help="default: data/jacksboro_fault_dem.tif warped to UTM 16N at 80 m")
    ap.add_argument("--tile", type=int, default=1024,
                    help="tiles of steps 2-4 (default 1024, the issue's; step 1: 256 and 512)")
    ap.add_argument("--quick", action="store_true", help="skip 8192^2 and the Dask 16384^2")
    ap.add_argument("--full", action="store_true",
                    help="also 16384^2 in one process (CLI, tiles), compared with the Dask one")
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    B, T = a.terrasynth, a.tile
    work = a.work or tempfile.mkdtemp(prefix="bench_scale.")
    os.makedirs(work, exist_ok=True)
    env = dict(os.environ, GDAL_DRIVER_PATH=os.path.abspath(a.plugins))
    if a.exemplar is None:  # the same exemplar at every size: a projected grid
        a.exemplar = os.path.join(work, "jacksboro_utm16n_80m.tif")
        subprocess.run(["gdalwarp", "-q", "-overwrite", "-t_srs", "EPSG:32616", "-tr", "80",
                        "80", "-r", "bilinear",
                        os.path.join(ROOT, "data", "jacksboro_fault_dem.tif"), a.exemplar],
                       check=True)
    ex = ["--exemplar", a.exemplar, "--seed", 11]
    print("bench_scale: exemplar %s, tiles of %d cells, %d cores, work in %s" % (
        os.path.basename(a.exemplar), T, os.cpu_count(), work))

    # 1. windows of a 65536^2 recipe
    print("\n1. a window of a 65536 x 65536 tiled recipe, gdal_translate -srcwin (goal 256^2: "
          "<= 5 s, <= 1024 MB)")
    for t in (256, 512):  # small tiles: a window needs its tile and 16 more
        rec = os.path.join(work, "big%d.tsyn" % t)
        subprocess.run([B, "synth", *map(str, ex), "--size", "65536x65536", "--tiled", str(t),
                        "--recipe", rec], check=True)
        k = 65536 // t // 2 | 1  # an odd tile index near the middle: (k, k) is of wave 3
        for name, x0, y0 in [("inside a wave-3 tile", k * t + t // 4, k * t + t // 4),
                             ("across 4 tiles (same 17)", (k + 1) * t - 128, (k + 1) * t - 128)]:
            w = min(256, t)
            dt, _, mb = time_rss(["gdal_translate", "-q", "-srcwin", x0, y0, w, w, rec,
                                  os.path.join(work, "win.tif")], env)
            ok = dt <= 5.0 and mb <= 1024
            print("   tiles %4d, %dx%d %-31s %6.2f s %7.0f MB  %s" % (
                t, w, w, name, dt, mb, "ok" if ok else "MISS"))

    # 2. time per cell
    print("\n2. time per cell, terrasynth synth (2 threads here; goal: cells/s flat)")
    sizes = [1024, 4096] if a.quick else [1024, 4096, 8192]
    single = {}
    for n in sizes:
        for tiled in (0, T):
            if tiled == 0 and n > 4096:
                continue  # in one piece past 4096^2: minutes (the scans over all positions)
            out = os.path.join(work, "s%d_%d.tif" % (n, tiled))
            dt, _, mb = time_rss([B, "synth", *ex, "--size", "%dx%d" % (n, n), "--tiled",
                                  tiled, "-q", out])
            single[(n, tiled)] = dt
            print("   %5d^2 %-14s %7.1f s %9.0f cells/s %7.0f MB" % (
                n, "in one piece" if not tiled else "tiles of %d" % tiled, dt, n * n / dt, mb))
    if not a.quick:
        # the same tiles written as the Dask runner writes them (without overviews):
        # ZSTD (or DEFLATE) after the floating-point predictor, 256^2 blocks (the CLI's
        # default is uncompressed, so step 3 compares with both)
        out = os.path.join(work, "s8192_%d_deflate.tif" % T)
        dt, _, mb = time_rss([B, "synth", *ex, "--size", "8192x8192", "--tiled", T, "-q",
                              *DASK_CO, out])
        single["deflate"] = dt
        print("   %5d^2 %-14s %7.1f s %9.0f cells/s %7.0f MB  (written as the Dask runner "
              "does: %s, predictor 3)" % (8192, "tiles of %d" % T, dt, 8192 * 8192 / dt, mb,
                                          DASK_CODEC))

    # thread scaling of the tiles (a wave's tiles side by side)
    n_cpu = os.cpu_count() or 1
    t = {}
    for th in sorted({1, n_cpu}):
        out = os.path.join(work, "th%d.tif" % th)
        t[th], _, _ = time_rss([B, "synth", *ex, "--size", "2048x2048", "--tiled", 256,
                                "--threads", th, "-q", out])
    if n_cpu > 1:
        same = (gdal.Open(os.path.join(work, "th1.tif")).ReadAsArray().tobytes() ==
                gdal.Open(os.path.join(work, "th%d.tif" % n_cpu)).ReadAsArray().tobytes())
        pf = (1 - t[n_cpu] / t[1]) / (1 - 1.0 / n_cpu)
        print("   2048^2 in tiles of 256: %.2f s on 1 thread, %.2f s on %d (%s); parallel "
              "fraction %.2f, Amdahl on 16 threads: %.1f x (goal >= 8; Amdahl counts a wave's "
              "idle end as serial work: bench_threads --jobs tilesched replays the schedule, "
              "a 16-core Xeon measured 9.8 x)" % (
                  t[1], t[n_cpu], n_cpu, "same bytes" if same else "DIFFERENT BYTES", pf,
                  1 / ((1 - pf) + pf / 16)))

    # 3. Dask
    runner = os.path.join(ROOT, "gdal_driver", "dask", "terrasynth_dask.py")
    print("\n3. terrasynth-dask, a local cluster of 2 workers (threads of the runner; "
          "--processes: processes)")
    rec = os.path.join(work, "d2048.tsyn")
    subprocess.run([B, "synth", *map(str, ex), "--size", "2048x2048", "--tiled", str(T),
                    "--recipe", rec], check=True)
    cli = os.path.join(work, "d2048_cli.tif")
    subprocess.run([B, "synth", *map(str, ex), "--size", "2048x2048", "--tiled", str(T), "-q",
                    cli], check=True)
    got = {}
    for nw, kind in ((1, []), (2, []), (2, ["--processes"])):
        o = os.path.join(work, "d2048_%d%s.tif" % (nw, "p" if kind else ""))
        dt, _, _ = time_rss([sys.executable, runner, rec, o, "--workers", str(nw), *kind,
                             "--no-overviews", "-q"], env)
        got[(nw, bool(kind))] = gdal.Open(o).ReadAsArray().tobytes()
        print("   2048^2, %d worker%s as %s: %.1f s" % (nw, "s" if nw > 1 else "",
                                                      "processes" if kind else "threads", dt))
    ref = gdal.Open(cli).ReadAsArray().tobytes()
    same = all(g == ref for g in got.values())
    print("   2048^2: 1 worker, 2 workers (threads, processes) and the CLI give %s" % (
        "the same bytes" if same else "DIFFERENT BYTES"))
    if not a.quick:
        rec = os.path.join(work, "d16k.tsyn")
        subprocess.run([B, "synth", *map(str, ex), "--size", "16384x16384", "--tiled", str(T),
                        "--recipe", rec], check=True)
        dt, p, _ = time_rss([sys.executable, runner, rec, os.path.join(work, "d16k.tif"),
                             "--workers", "2", "--no-overviews", "--stats", "-q"], env)
        peaks = [float(line.split("peak memory ")[1].split()[0]) for line in
                 p.stdout.splitlines() if "peak memory" in line]
        cpus = [float(line.split(", ")[-1].split()[0]) for line in p.stdout.splitlines()
                if "peak memory" in line]
        ref = single[(8192, T)]
        print("   16384^2 in %.1f s = %.2f x the single-process 8192^2 (%.1f s; goal <= 4)  %s"
              % (dt, dt / ref, ref, "ok" if dt <= 4 * ref else "MISS"))
        print("   16384^2 in %.1f s = %.2f x the single-process 8192^2 written the same way "
              "(%.1f s, %s tiles; goal <= 4)  %s" % (
                  dt, dt / single["deflate"], single["deflate"], DASK_CODEC,
                  "ok" if dt <= 4 * single["deflate"] else "MISS"))
        print("   %.0f cells/s; peak of the process (both workers and the client) %s MB "
              "(goal <= 1536 per worker)  %s" % (
            16384 * 16384 / dt, ", ".join("%.0f" % m for m in peaks),
            "ok" if peaks and max(peaks) <= 1536 else "MISS"))
        print("   CPU s / wall s: %s (threads: all workers together, 200 %% = both cores)" %
              ", ".join("%.0f %%" % (100 * c / dt) for c in cpus))
        if a.full:
            one = os.path.join(work, "s16k_cli.tif")
            dt1, _, mb1 = time_rss([B, "synth", *ex, "--size", "16384x16384", "--tiled", T,
                                    "-q", one])
            print("   16384^2 in one process (CLI, tiles of %d): %.1f s, %.0f cells/s, %.0f MB"
                  % (T, dt1, 16384 * 16384 / dt1, mb1))
            dds, cds = gdal.Open(os.path.join(work, "d16k.tif")), gdal.Open(one)
            d, c = dds.GetRasterBand(1), cds.GetRasterBand(1)  # the datasets kept open
            same = all(d.ReadAsArray(0, y, 16384, 1024).tobytes() ==
                       c.ReadAsArray(0, y, 16384, 1024).tobytes() for y in range(0, 16384, 1024))
            print("   the Dask 16384^2 and the one-process 16384^2: %s" % (
                "the same bytes" if same else "DIFFERENT BYTES"))

    # 4. seams
    print("\n4. seams across tile borders (4096^2, tiles of %d)" % T)
    out = os.path.join(work, "s4096_%d.tif" % T)
    if os.path.exists(METRICS):
        p = subprocess.run([sys.executable, METRICS, "--out", out, "--exemplar", a.exemplar],
                           capture_output=True, text=True, check=True)
        m = json.loads(p.stdout)
        print("   terrain_metrics: seam_lap %.3f, seam_grad %.3f (goal <= 1.2)  %s" % (
            m["seam_lap"], m["seam_grad"],
            "ok" if m["seam_lap"] <= 1.2 and m["seam_grad"] <= 1.2 else "MISS"))
    else:
        print("   terrain_metrics: %s absent, skipped" % METRICS)
    print("   ours: P99.9 |Laplacian| next to tile borders / elsewhere: %.3f" %
          border_ratio(out, T))
    one = os.path.join(work, "s4096_0.tif")
    print("   the same measure on the run in one piece, at the same lines: %.3f" %
          border_ratio(one, T))
    # the waves alike? mean |gradient| of the tiles' cores, wave by wave
    for name, path in (("tiles", out), ("one piece, same grid", one)):
        m, (F, p) = wave_roughness(path, T)
        print("   mean |gradient| by wave (%s): %s, max / min %.2f (1 = the waves alike), "
              "F %.1f, p %.2g (tiles' means by wave, one-way ANOVA)" % (
                  name, " ".join("%.2f" % v for v in m), max(m) / min(m), F, p))


if __name__ == "__main__":
    main()
