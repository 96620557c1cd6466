#!/usr/bin/python3
# bench_pixel.py - benchmark of `terrasynth pixel`: a 1024 x 1024 terrain from a
# 512 x 512 real exemplar (Big Tujunga, 30 m, ../shared/data/dem), and an 8192 x 8192 recipe
# streamed through the TSYN driver by gdal_translate (block by block).  Prints the wall time
# and peak memory (the kernel's count for the spawned process) of each, and the same for the
# peer `gdalwarp -r cubic` to the same grids from the same exemplar, run alongside, with the
# ratios.  Goals: 1024^2 <= 2 s on 2 cores; the streamed 8192^2 <= 512 MB.
#
#   /usr/bin/python3 bench/bench_pixel.py [TERRASYNTH [GDAL_DRIVER_PATH]]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_amplify import DEM, ROOT, spawn  # noqa: E402

SOURCE = os.path.join(DEM, "mountains_bigtujunga_ca_30m.tif")


def main():
    ts = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "gdal_driver",
                                                            "terrasynth")
    plugins = sys.argv[2] if len(sys.argv) > 2 else os.path.join(os.path.dirname(
        os.path.dirname(os.path.abspath(ts))), "gdalplugins")
    if not os.path.exists(SOURCE):
        print("bench_pixel: skipped: ../shared/data/dem not present")
        return
    with tempfile.TemporaryDirectory() as d:
        ex = os.path.join(d, "ex.tif")
        subprocess.run(["gdal_translate", "-q", "-srcwin", "300", "60", "512", "512", SOURCE, ex],
                       check=True)
        out = os.path.join(d, "p.tif")
        t, mb, text = spawn([ts, "pixel", "--exemplar", ex, "--size", "1024x1024", "--seed", "1",
                             out])
        line = [ln for ln in text.splitlines() if ln.startswith("pixel:")][-1]
        tc, mbc, _ = spawn(["/usr/bin/gdalwarp", "-q", "-r", "cubic", "-ts", "1024", "1024", ex,
                            os.path.join(d, "c.tif")])
        print(line)
        print("pixel 1024x1024 from 512x512: %.2f s wall, %.0f MB peak (%d threads); peer "
              "gdalwarp -r cubic to 1024x1024: %.2f s, %.0f MB; pixel / cubic = %.1f x"
              % (t, mb, os.cpu_count(), tc, mbc, t / tc))
        recipe = os.path.join(d, "big.tsyn")
        subprocess.run([ts, "pixel", "--exemplar", ex, "--size", "8192x8192", "--seed", "1",
                        "--recipe", recipe], check=True)
        os.environ["GDAL_DRIVER_PATH"] = plugins
        t8, mb8, _ = spawn(["/usr/bin/gdal_translate", "-q", "--config", "GDAL_CACHEMAX", "64",
                            "-co", "TILED=YES", recipe,
                            os.path.join(d, "big.tif")])
        tc8, mbc8, _ = spawn(["/usr/bin/gdalwarp", "-q", "-r", "cubic", "-ts", "8192", "8192",
                              "-co", "TILED=YES", ex, os.path.join(d, "c8.tif")])
        print("pixel 8192x8192 streamed by gdal_translate: %.1f s, %.0f MB peak; peer gdalwarp "
              "-r cubic to 8192x8192: %.1f s, %.0f MB" % (t8, mb8, tc8, mbc8))
        print("goals: 1024^2 <= 2 s: %s; streamed 8192^2 <= 512 MB: %s"
              % ("PASS" if t <= 2 else "FAIL", "PASS" if mb8 <= 512 else "FAIL"))


if __name__ == "__main__":
    main()
