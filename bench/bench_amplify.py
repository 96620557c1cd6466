#!/usr/bin/python3
# bench_amplify.py - benchmark of `terrasynth amplify`: a 500 x 500 real coarse
# DEM (the Alps at 200 m, ../shared/data/dem) amplified x10 to 5000 x 5000 with two real
# exemplars (about 4000 atoms).  Prints the dictionary, matching and synthesis seconds the
# program reports, the wall time and peak memory (the kernel's count for the spawned
# process), and the same for the peer `gdalwarp -r cubic` to the same grid, run alongside,
# with the ratio.  Goal: <= 3 s in all on 2 cores, <= 1 GB.
#
#   /usr/bin/python3 bench/bench_amplify.py [TERRASYNTH]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import os
import re
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DEM = os.path.join(ROOT, "..", "shared", "data", "dem")
COARSE = os.path.join(DEM, "coarse_grenoble_alps_copdem200m.tif")
EXEMPLAR = os.path.join(DEM, "mountains_mackay_id_30m.tif")
EXEMPLAR2 = os.path.join(DEM, "mountains_bigtujunga_ca_30m.tif")  # with it, ~4000 atoms


def spawn(argv):
    """Wall seconds, peak resident MB and standard output of argv (spawned, not forked;
    the peak may include this small Python's pages from before the exec)."""
    r, w = os.pipe()
    t0 = time.monotonic()
    pid = os.posix_spawn(argv[0], argv, dict(os.environ),
                         file_actions=[(os.POSIX_SPAWN_DUP2, w, 1),
                                       (os.POSIX_SPAWN_CLOSE, r)])
    os.close(w)
    out = b""
    while True:
        chunk = os.read(r, 65536)
        if not chunk:
            break
        out += chunk
    os.close(r)
    _, status, usage = os.wait4(pid, 0)
    t = time.monotonic() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit("bench_amplify: %s failed" % argv[0])
    return t, usage.ru_maxrss / 1024.0, out.decode()


def main():
    ts = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "gdal_driver",
                                                            "terrasynth")
    if not os.path.exists(COARSE) or not os.path.exists(EXEMPLAR):
        print("bench_amplify: skipped: ../shared/data/dem not present")
        return
    gdalwarp = "/usr/bin/gdalwarp"
    with tempfile.TemporaryDirectory() as d:
        out, cub = os.path.join(d, "amp.tif"), os.path.join(d, "cubic.tif")
        t, mb, text = spawn([ts, "amplify", COARSE, out, "--exemplar", EXEMPLAR, "--exemplar",
                             EXEMPLAR2, "--factor", "10", "--atoms", "4000"])
        line = [ln for ln in text.splitlines() if ln.startswith("amplify:")][-1]
        tc, mbc, _ = spawn([gdalwarp, "-q", "-r", "cubic", "-ts", "5000", "5000", COARSE, cub])
    secs = dict(re.findall(r"(dictionary|matching|synthesis) ([0-9.]+) s", line))
    print(line)
    print("amplify x10, 500x500 -> 5000x5000: %.2f s wall, %.0f MB peak (dictionary %s s, "
          "matching %s s, synthesis %s s; %d threads)" % (
              t, mb, secs.get("dictionary"), secs.get("matching"), secs.get("synthesis"),
              os.cpu_count()))
    print("peer gdalwarp -r cubic to the same grid: %.2f s, %.0f MB; amplify / cubic = %.1f x"
          % (tc, mbc, t / tc))
    print("goal: <= 3 s and <= 1024 MB: %s" % ("PASS" if t <= 3 and mb <= 1024 else "FAIL"))


if __name__ == "__main__":
    main()
