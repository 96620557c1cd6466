# SPDX-License-Identifier: GPL-2.0-or-later
"""Crest (or thalweg) height profile along a sketch's feature lines.

    crest_profile.py OUTPUT.tif SKETCH_FEATURES.gpkg [--valleys] [--spacing S]

For every path of the sketch's feature lines (the `paths` layer written by
`terrasynth synth --sketch ... --debug-dir`), the output is sampled every cell
along the line; at each sample the crest height is the highest (valleys: the
lowest) cell within 3 cells across the line.  Printed figures:

  bend S   RMS of z(i-S) - 2 z(i) + z(i+S) along the lines (m): how much the
           crest's height trend bends at the scale of S cells
  step     RMS of z(i+1) - z(i) (m): cell-to-cell roughness
  relief   range of the crest heights (m)
  stand    mean height of the crest above the land --flank cells off the
           line on both sides (m; valleys: below): how much the sketched
           feature stands out
  held     fraction of the line where the crest is higher than the land
           --flank/2 cells off on both sides (valleys: lower): how much of the
           sketch is drawn as a ridge (valley) at that scale

polylines, line_stands, figures and main_ridges give the crest figures of
bench/quality/crest_matrix.py (bend and cross-section spread along drawn
ridges and along a DEM's main ridges).  Used by the sketch tests
(tests/cli/test_synth_sketch.py) and the bench.
"""
import argparse
import math

import numpy as np
from osgeo import gdal, ogr

gdal.UseExceptions()


def resample(pts, step=1.0):
    d = np.hypot(np.diff(pts[:, 0]), np.diff(pts[:, 1]))
    s = np.concatenate([[0.0], np.cumsum(d)])
    if s[-1] < 2 * step:
        return None
    t = np.arange(0.0, s[-1], step)
    return np.stack([np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])], axis=1)


def crest_heights(z, line, valleys, half=3):
    h, w = z.shape
    tang = np.gradient(line, axis=0)
    n = np.linalg.norm(tang, axis=1, keepdims=True)
    n[n == 0] = 1
    tang /= n
    normal = np.stack([-tang[:, 1], tang[:, 0]], axis=1)
    vals = []
    for (x, y), (nx, ny) in zip(line, normal):
        best = math.nan
        for j in range(-half, half + 1):
            cx, cy = int(math.floor(x + j * nx)), int(math.floor(y + j * ny))
            if 0 <= cx < w and 0 <= cy < h and math.isfinite(z[cy, cx]):
                v = z[cy, cx]
                if math.isnan(best) or (v < best if valleys else v > best):
                    best = v
        vals.append(best)
    return np.array(vals)


def flank_heights(z, line, off, both=False):
    h, w = z.shape
    tang = np.gradient(line, axis=0)
    n = np.linalg.norm(tang, axis=1, keepdims=True)
    n[n == 0] = 1
    tang /= n
    vals = []
    for (x, y), (tx, ty) in zip(line, tang):
        s = []
        for side in (-1, 1):
            cx, cy = int(math.floor(x - side * off * ty)), int(math.floor(y + side * off * tx))
            if 0 <= cx < w and 0 <= cy < h and math.isfinite(z[cy, cx]):
                s.append(z[cy, cx])
        if both:
            vals.append(max(s) if len(s) == 2 else math.nan)
        else:
            vals.append(np.mean(s) if s else math.nan)
    return np.array(vals)


def measure(output, gpkg, valleys=False, spacing=16, flank=31):
    z, gt = read(output)
    bends, steps, allz, stands, helds = [], [], [], [], []
    for pts in polylines(gpkg, "paths", gt):
        line = resample(pts)
        if line is None:
            continue
        c = crest_heights(z, line, valleys)
        f = flank_heights(z, line, flank)
        sgn = -1 if valleys else 1
        hi = flank_heights(sgn * z, line, flank // 2, both=True)
        okh = np.isfinite(c) & np.isfinite(hi)
        helds.append(sgn * c[okh] > hi[okh])
        both = np.isfinite(c) & np.isfinite(f)
        stands.append((c[both] - f[both]) * (-1 if valleys else 1))
        ok = np.isfinite(c)
        c = c[ok]
        allz.append(c)
        if c.size > 2 * spacing:
            bends.append(c[:-2 * spacing] - 2 * c[spacing:-spacing] + c[2 * spacing:])
        if c.size > 1:
            steps.append(np.diff(c))
    b = np.concatenate(bends) if bends else np.array([np.nan])
    s = np.concatenate(steps) if steps else np.array([np.nan])
    a = np.concatenate(allz) if allz else np.array([np.nan])
    return {
        "bend": float(np.sqrt(np.mean(b * b))),
        "step": float(np.sqrt(np.mean(s * s))),
        "relief": float(np.ptp(a)),
        "stand": float(np.mean(np.concatenate(stands))) if stands else math.nan,
        "held": float(np.mean(np.concatenate(helds))) if helds else math.nan,
    }


def polylines(gpkg, layer, gt, kind=None):
    """The lines of `layer` (only those whose field kind is `kind`, when given) in cells."""
    ds = ogr.Open(str(gpkg))
    lay = ds.GetLayerByName(layer)
    inv = gdal.InvGeoTransform(gt)
    out = []
    for f in lay:
        if kind and f.GetField("kind") != kind:
            continue
        g = f.GetGeometryRef()
        pts = [(inv[0] + inv[1] * g.GetX(i) + inv[2] * g.GetY(i),
                inv[3] + inv[4] * g.GetX(i) + inv[5] * g.GetY(i)) for i in range(g.GetPointCount())]
        if len(pts) >= 2:
            out.append(np.array(pts))
    return out


def line_stands(z, lines, patch, min_len):
    """Per line at least min_len cells long: its crest heights and how far they stand above
    the land patch/4 and patch/2 cells off on both sides (the ends' patch/8 left out)."""
    out, k = [], max(1, patch // 8)
    for pts in lines:
        line = resample(pts)
        if line is None or len(line) < min_len:
            continue
        c = crest_heights(z, line, False)[k:-k]
        line = line[k:-k]
        out.append((c, c - flank_heights(z, line, patch // 4),
                    c - flank_heights(z, line, patch // 2)))
    return out


def figures(profs, patch):
    """bend: RMS of z(s - P/2) - 2 z(s) + z(s + P/2) (peaks and saddles about a patch apart);
    cv: spread over mean of the stand at P/4 (how much the cross-section varies along the
    crest); stand: mean stand at P/2.  None without a line longer than a patch."""
    S = patch // 2
    b = [c[:-2 * S] - 2 * c[S:-S] + c[2 * S:] for c, _, _ in profs if len(c) > 2 * S]
    if not b:
        return None
    b = np.concatenate(b)
    s4 = np.concatenate([p[1] for p in profs])
    s2 = np.concatenate([p[2] for p in profs])
    b, s4, s2 = b[np.isfinite(b)], s4[np.isfinite(s4)], s2[np.isfinite(s2)]
    return {"bend": float(np.sqrt(np.mean(b * b))),
            "cv": float(np.std(s4) / max(np.mean(s4), 1e-9)), "stand": float(np.mean(s2))}


def main_ridges(profs):
    """The upper half of the lines by their mean stand at P/2 (a DEM's main ridges)."""
    st = [np.nanmean(p[2]) for p in profs]
    med = float(np.median(st))
    return [p for p, s in zip(profs, st) if s >= med]


def read(path):
    ds = gdal.Open(str(path))
    band = ds.GetRasterBand(1)
    z = band.ReadAsArray().astype(float)
    nd = band.GetNoDataValue()
    if nd is not None:
        z[z == nd] = np.nan
    return z, ds.GetGeoTransform()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("output")
    ap.add_argument("features")
    ap.add_argument("--valleys", action="store_true")
    ap.add_argument("--spacing", type=int, default=16)
    ap.add_argument("--flank", type=int, default=31)
    a = ap.parse_args()
    m = measure(a.output, a.features, a.valleys, a.spacing, a.flank)
    print(f"bend {a.spacing} {m['bend']:.1f} m  step {m['step']:.2f} m  relief {m['relief']:.0f} m  "
          f"stand {a.flank} {m['stand']:.0f} m  held {m['held']:.2f}")


if __name__ == "__main__":
    main()
