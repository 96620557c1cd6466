#!/usr/bin/python3
# table.py - the quality matrix as a Markdown table (worst figure over the seeds per sketch x
# exemplar), from quality.json written by quality.py; with a second file (e.g. a run with
# --extra "--order raster"), the mean of each figure in both.
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
#
#   /usr/bin/python3 bench/quality/table.py build/quality/quality.json [OTHER.json]
import json
import sys

KEYS = [("structure_r", max), ("feature_recall", max), ("seam_lap", min), ("seam_grad", min),
        ("slope_w1_deg", min)]


def main():
    rows = [r for r in json.load(open(sys.argv[1])) if not r.get("failed")]
    groups = {}
    for r in rows:
        groups.setdefault((r["sketch"], r["exemplar"]), []).append(r)
    print("| sketch | exemplar | seeds ok | structure_r | feature_recall | seam_lap | seam_grad "
          "| slope_w1 (deg) |")
    print("|---|---|---|---|---|---|---|---|")
    for (sk, ex), rs in groups.items():
        cells = []
        for k, better in KEYS:
            worst = min(r[k] for r in rs) if better is max else max(r[k] for r in rs)
            cells.append("%.2f" % worst)
        print("| %s | %s | %d/%d | %s |" % (sk[:-4], ex[:-4], sum(r["ok"] for r in rs), len(rs),
                                            " | ".join(cells)))
    print("\nworst over the seeds; %d of %d runs meet every goal" % (
        sum(r["ok"] for r in rows), len(rows)))
    if len(sys.argv) > 2:
        other = {r["tag"]: r for r in json.load(open(sys.argv[2])) if not r.get("failed")}
        both = [r for r in rows if r["tag"] in other]
        for k, better in KEYS:
            a = sum(r[k] for r in both) / len(both)
            b = sum(other[r["tag"]][k] for r in both) / len(both)
            wins = sum(1 for r in both if (r[k] > other[r["tag"]][k]) == (better is max)
                       and r[k] != other[r["tag"]][k])
            print("%-15s mean %.3f here, %.3f there; better here in %d of %d runs" % (
                k, a, b, wins, len(both)))


if __name__ == "__main__":
    main()
