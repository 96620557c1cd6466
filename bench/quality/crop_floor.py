#!/usr/bin/python3
# crop_floor.py - what the yardstick gives real terrain: windows cut at random from each DEM
# of ../shared/data/dem, judged against the whole DEM by ../shared/eval/terrain_metrics.py's
# own figures (slope_w1, seam_lap, seam_grad), as a synthesis of that size is judged.  A
# heterogeneous exemplar (plains beside a range, one volcano) fails the goals with its own
# windows: this prints how often, so a synthesis's figures can be read against it.
#
#   /usr/bin/python3 bench/quality/crop_floor.py [--sizes 256,384,512] [--crops 30]
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SHARED = os.path.join(os.path.dirname(ROOT), "shared")
DEM = os.path.join(SHARED, "data", "dem")
EVAL = os.path.join(SHARED, "eval")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="384,512")
    ap.add_argument("--crops", type=int, default=30)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    if not os.path.exists(os.path.join(EVAL, "terrain_metrics.py")):
        print("crop_floor: skipped: ../shared is not present")
        return 0
    sys.path.insert(0, EVAL)
    import terrain_metrics as tm  # the yardstick's own figures, none of our code

    print("real windows of each DEM against the whole DEM (%d per size, those 90 %% valid); "
          "goals: slope_w1 <= 3, seam_lap and seam_grad <= 1.2" % a.crops)
    print("%-44s %5s  %-27s %-27s %-27s" % ("DEM", "size", "slope_w1 median (<=3)",
                                              "seam_lap median (<=1.2)",
                                              "seam_grad median (<=1.2)"))
    for name in sorted(os.listdir(DEM)):
        if not name.endswith(".tif") or "etopo5" in name:
            continue
        e, em, epx, _ = tm.read(os.path.join(DEM, name))
        ef = tm.fill_invalid(e, em)
        se = tm.slopes_deg(ef, em, epx)
        le = tm.tail(tm.lap(ef)[em] / (epx[0] * epx[1]))
        ge = tm.tail(tm.grad(ef, epx)[em])
        H, W = e.shape
        for n in [int(s) for s in a.sizes.split(",")]:
            if min(H, W) < n:
                continue
            rng = np.random.default_rng(a.seed)
            w1, sl, sg = [], [], []
            for _ in range(a.crops):
                y, x = rng.integers(0, H - n + 1), rng.integers(0, W - n + 1)
                c, cm = ef[y:y + n, x:x + n], em[y:y + n, x:x + n]
                if cm.mean() < 0.9:
                    continue
                w1.append(tm.w1(tm.slopes_deg(c, cm, epx), se))
                sl.append(tm.tail(tm.lap(c)[cm] / (epx[0] * epx[1])) / le)
                sg.append(tm.tail(tm.grad(c, epx)[cm]) / ge)
            if not w1:
                continue
            w1, sl, sg = np.array(w1), np.array(sl), np.array(sg)
            print("%-44s %5d  %5.2f (%3.0f %% of windows)     %5.2f (%3.0f %%)              "
                  "%5.2f (%3.0f %%)" % (name[:44], n, np.median(w1), 100 * (w1 <= 3).mean(),
                                        np.median(sl), 100 * (sl <= 1.2).mean(),
                                        np.median(sg), 100 * (sg <= 1.2).mean()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
