#!/usr/bin/python3
# make_sketches.py - draw the sketch maps of Zhou et al. 2007 ("Terrain
# synthesis from digital elevation models", IEEE TVCG 13(4)) as grey GeoTIFFs
# in data/sketches/: the half-life symbol (Fig. 10a), its inverse (Fig. 10e),
# the Chinese character for water (Fig. 12a) and a two-style sketch with a
# region map (section 6.1).
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
#
# This program is free software; you can redistribute it and/or modify it
# under the terms of the GNU General Public License as published by the Free
# Software Foundation; either version 2 of the License, or (at your option)
# any later version.  This program is distributed in the hope that it will be
# useful, but WITHOUT ANY WARRANTY; without even the implied warranty of
# MERCHANTABILITY or FITNESS FOR A PARTICULAR PURPOSE.  See the GNU General
# Public License for more details.
#
# Usage (Debian's interpreter: it has numpy and osgeo):
#   /usr/bin/python3 data/make_sketches.py [OUTPUT_DIR]
#
# Every sketch is a set of strokes (polylines, Bezier curves, a circle) drawn
# with a soft round brush: value = 255 * max over strokes of
# exp(-d^2 / (2 sigma^2)), d = distance from the cell centre to the stroke,
# bright = high.  Nothing is random.  Values are rounded to multiples of 1/16
# (exact in Float32; compresses well).  The output is byte-for-byte
# reproducible for a given numpy and GDAL (checked with numpy 1.24.2 and GDAL
# 3.6.2): no timestamps, files written under a temporary name and renamed into
# place, no .aux.xml side-car.  See README.md, section "sketches/".
#
# Georeferencing: EPSG:4326, 3" cells, origin at the top-left corner of
# data/jacksboro_fault_dem.tif, i.e. the same grid as that DEM, so a terrain
# synthesised on a sketch lands where the default exemplar is.

import argparse
import hashlib
import os
import sys

# Grid of data/jacksboro_fault_dem.tif (north-west corner, cell size).
ORIGIN_LON = -84.41375
ORIGIN_LAT = 36.44625
CELL = 1.0 / 1200.0          # 3 arc-seconds = 0.000833333 deg
NODATA = -9999.0             # declared for the Float32 sketches; never present
REGION_NODATA = 0            # declared for the Byte region map; never present
QUANTUM = 16.0               # values are multiples of 1/QUANTUM
CREDIT = ("drawn by the TerraSynth developers with data/make_sketches.py, "
          "GPL-2.0-or-later, no third-party data")


def die(msg):
    sys.stderr.write("make_sketches: %s\n" % msg)
    sys.exit(1)


try:
    import numpy as np
    from osgeo import gdal, osr
except ImportError as e:
    die("%s; run this script with /usr/bin/python3 (Debian's python3-numpy and "
        "python3-gdal)" % e)


# ---------------------------------------------------------------------------
# Stroke geometry.  Coordinates are in cells, x to the east (column), y to the
# south (row), (0, 0) the north-west corner of the raster; the centre of cell
# (col, row) is (col + 0.5, row + 0.5).

def bezier(points, n=64):
    """Polyline sampling a Bezier curve (any degree) at n+1 points."""
    p = np.asarray(points, dtype=np.float64)
    t = np.linspace(0.0, 1.0, n + 1)[:, None, None]
    q = np.broadcast_to(p, (n + 1,) + p.shape)
    while q.shape[1] > 1:                   # de Casteljau
        q = q[:, :-1] * (1.0 - t) + q[:, 1:] * t
    return q[:, 0, :]


def catmull_rom(points, n=32):
    """Polyline through the given points (uniform Catmull-Rom spline)."""
    p = np.asarray(points, dtype=np.float64)
    p = np.vstack([2 * p[0] - p[1], p, 2 * p[-1] - p[-2]])
    out = [p[1]]
    t = np.linspace(0.0, 1.0, n + 1)[1:, None]
    for i in range(1, len(p) - 2):
        p0, p1, p2, p3 = p[i - 1], p[i], p[i + 1], p[i + 2]
        seg = 0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t ** 2
                     + (-p0 + 3 * p1 - 3 * p2 + p3) * t ** 3)
        out.extend(seg)
    return np.asarray(out)


class Canvas:
    """Minimum squared distance to the strokes drawn so far."""

    def __init__(self, width, height, sigma):
        self.w, self.h, self.sigma = width, height, float(sigma)
        self.d2 = np.full((height, width), np.inf)
        self.reach = 6.0 * self.sigma       # exp(-18) * 255 < 1/32: rounds to 0

    def polyline(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        for a, b in zip(pts[:-1], pts[1:]):
            self._segment(a, b)

    def _segment(self, a, b):
        r = self.reach
        c0 = max(int(np.floor(min(a[0], b[0]) - r)), 0)
        c1 = min(int(np.ceil(max(a[0], b[0]) + r)), self.w)
        r0 = max(int(np.floor(min(a[1], b[1]) - r)), 0)
        r1 = min(int(np.ceil(max(a[1], b[1]) + r)), self.h)
        if c0 >= c1 or r0 >= r1:
            return
        x = np.arange(c0, c1, dtype=np.float64)[None, :] + 0.5
        y = np.arange(r0, r1, dtype=np.float64)[:, None] + 0.5
        ab = b - a
        L2 = float(ab @ ab)
        if L2 > 0.0:
            t = ((x - a[0]) * ab[0] + (y - a[1]) * ab[1]) / L2
            t = np.clip(t, 0.0, 1.0)
        else:
            t = np.zeros((r1 - r0, c1 - c0))
        dx = x - (a[0] + t * ab[0])
        dy = y - (a[1] + t * ab[1])
        win = self.d2[r0:r1, c0:c1]
        np.minimum(win, dx * dx + dy * dy, out=win)

    def circle(self, cx, cy, radius):
        """A ring, exact distance | |p - c| - radius |."""
        x = np.arange(self.w, dtype=np.float64)[None, :] + 0.5
        y = np.arange(self.h, dtype=np.float64)[:, None] + 0.5
        d = np.abs(np.hypot(x - cx, y - cy) - radius)
        np.minimum(self.d2, d * d, out=self.d2)

    def grey(self):
        """0..255 grey, bright on the strokes, rounded to multiples of 1/QUANTUM."""
        v = 255.0 * np.exp(-self.d2 / (2.0 * self.sigma ** 2))
        v = np.round(v * QUANTUM) / QUANTUM
        return v.astype(np.float32)


# ---------------------------------------------------------------------------
# The sketches.

def lambda_ridges():
    """Fig. 10a: the half-life symbol, a ring around a lowercase lambda.

    The lambda is a long stroke from upper left to lower right (with the
    small leftward curl of the glyph at its top) and a short stroke from the
    middle of the long one down to the lower left: one branch point (degree 3)
    at J.  Gaps between lambda and ring are >= 5 sigma so the ring stays a
    separate ridge.  sigma = 6: with 7 or more the round brush ends and the
    bend of the curl grow ridge spurs longer than 20 cells in PPA.
    """
    c = Canvas(512, 512, sigma=6.0)
    c.circle(256.0, 256.0, 218.0)
    a = np.array([198.0, 132.0])                     # top of the straight part
    b = np.array([366.0, 402.0])                     # foot, lower right
    u = (b - a) / np.hypot(*(b - a))
    top = bezier([(150.0, 104.0), tuple(a - 30.0 * u), tuple(a)], n=24)  # curl, G1 at a
    c.polyline(np.vstack([top, b]))
    j = a + 0.5 * (b - a)                            # branch point, middle of the stroke
    c.polyline([j, (158.0, 402.0)])
    return c.grey()


def water_character():
    """Fig. 12a: the Chinese character for water (shui, U+6C34).

    Strokes: the central vertical with a hook to the left at its foot; on the
    left a short horizontal then a long diagonal down to the left (one
    stroke, hengpie); on the right a short diagonal up to the right and a long
    one down to the right, both leaving one point J just right of the
    vertical.  J is 12 cells (2 sigma) from the vertical's axis: the brushes
    touch, as the strokes do in the glyph, but PPA maps the pair as a ridge
    of its own (three ridges in all, no branch point).
    """
    c = Canvas(512, 512, sigma=6.0)
    # Central vertical with a rounded hook up to the left at its foot.
    foot = bezier([(258.0, 400.0), (258.0, 452.0), (214.0, 418.0)], n=24)
    c.polyline(np.vstack([[(256.0, 52.0)], foot]))
    # Left: horizontal to the corner, then the long falling-left diagonal.
    c.polyline(np.vstack([[(102.0, 196.0), (206.0, 188.0)],
                          bezier([(206.0, 188.0), (170.0, 320.0), (74.0, 404.0)], n=32)]))
    # Right: short rising diagonal and long falling diagonal from one point
    # beside the vertical (they touch its flank, not its axis).
    j = (268.0, 246.0)
    c.polyline(bezier([j, (330.0, 216.0), (388.0, 142.0)], n=24))
    c.polyline(bezier([j, (330.0, 330.0), (452.0, 420.0)], n=32))
    return c.grey()


def multistyle():
    """Section 6.1: one long winding ridge across the map plus side branches,
    and a region map splitting it into two styles along a curved border."""
    w, h = 512, 384
    c = Canvas(w, h, sigma=6.0)
    main = catmull_rom([(18.0, 250.0), (80.0, 200.0), (150.0, 228.0), (220.0, 150.0),
                        (290.0, 132.0), (350.0, 196.0), (420.0, 214.0), (494.0, 150.0)], n=40)
    c.polyline(main)

    def from_main(i):
        return tuple(main[i])
    # Side branches: two in the western (mountain) style, one in the eastern.
    c.polyline(catmull_rom([from_main(2 * 40 - 6), (130.0, 290.0), (104.0, 350.0)], n=40))
    c.polyline(catmull_rom([from_main(3 * 40 + 4), (240.0, 80.0), (200.0, 30.0)], n=40))
    c.polyline(catmull_rom([from_main(5 * 40 + 10), (370.0, 270.0), (400.0, 340.0)], n=40))
    sketch = c.grey()

    # Region 1 (west, e.g. mountains) | region 2 (east, e.g. hills); border
    # x = 270 + 45 sin(...) : a smooth S-curve from north to south.
    y = np.arange(h, dtype=np.float64)[:, None] + 0.5
    x = np.arange(w, dtype=np.float64)[None, :] + 0.5
    border = 270.0 + 45.0 * np.sin(2.0 * np.pi * (y / h) * 1.1 + 0.4)
    regions = np.where(x < border, 1, 2).astype(np.uint8)
    return sketch, regions


def ridges_valleys():
    """A drawing of both kinds (ours, not the paper's): a crest across the map
    with two spurs to either side, the valleys between the spurs running down
    to the map's edges, and a river along the south.  Returns the painted
    sketch (a grey ground, 128, with ridges brighter and valleys darker) and
    the strokes as lines [(kind, [(col, row), ...])], in cell coordinates."""
    crest = catmull_rom([(20.0, 250.0), (150.0, 226.0), (280.0, 244.0), (400.0, 214.0),
                         (492.0, 230.0)], n=24)
    lines = [("ridge", [tuple(p) for p in crest])]
    for x0, y0, x1, y1 in ((150.0, 228.0, 128.0, 84.0), (360.0, 226.0, 392.0, 70.0),
                           (220.0, 236.0, 200.0, 360.0), (420.0, 218.0, 450.0, 340.0)):
        lines.append(("ridge", [(x0, y0), (0.5 * (x0 + x1) + 8.0, 0.5 * (y0 + y1)), (x1, y1)]))
    for x0, y0, x1, y1 in ((60.0, 200.0, 40.0, 8.0), (262.0, 212.0, 250.0, 8.0),
                           (470.0, 186.0, 500.0, 40.0), (110.0, 272.0, 96.0, 430.0),
                           (320.0, 268.0, 330.0, 430.0)):
        lines.append(("valley", [(x0, y0), (0.5 * (x0 + x1) - 6.0, 0.5 * (y0 + y1)), (x1, y1)]))
    river = catmull_rom([(4.0, 440.0), (120.0, 432.0), (250.0, 452.0), (380.0, 430.0),
                         (508.0, 446.0)], n=24)
    lines.append(("river", [tuple(p) for p in river]))
    ridge, valley = Canvas(512, 512, sigma=5.0), Canvas(512, 512, sigma=4.0)
    for kind, pts in lines:
        (ridge if kind == "ridge" else valley).polyline(pts)
    grey = 128.0 + 0.5 * ridge.grey() - 0.5 * valley.grey()
    grey = np.round(grey * QUANTUM) / QUANTUM
    return grey.astype(np.float32), lines


def write_lines(path, lines, description):
    """The strokes as GeoJSON lines (EPSG:4326, the grid's CRS) with a field kind."""
    feats = []
    for kind, pts in lines:
        coords = ",".join("[%.7f,%.7f]" % (ORIGIN_LON + c * CELL, ORIGIN_LAT - r * CELL)
                          for c, r in pts)
        feats.append('{"type":"Feature","properties":{"kind":"%s"},'
                     '"geometry":{"type":"LineString","coordinates":[%s]}}' % (kind, coords))
    text = ('{"type":"FeatureCollection","name":"strokes","description":"%s",\n'
            '"features":[\n%s\n]}\n' % (description, ",\n".join(feats)))
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)
    print("%s: %d lines, %d bytes" % (os.path.basename(path), len(lines), len(text)))


# ---------------------------------------------------------------------------
# Output.

def write(path, array, gdal_type, nodata, description, predictor):
    h, w = array.shape
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    mem = gdal.GetDriverByName("MEM").Create("", w, h, 1, gdal_type)
    mem.SetGeoTransform((ORIGIN_LON, CELL, 0.0, ORIGIN_LAT, 0.0, -CELL))
    mem.SetSpatialRef(srs)
    mem.SetMetadataItem("AREA_OR_POINT", "Area")
    mem.SetMetadataItem("TIFFTAG_IMAGEDESCRIPTION", description)
    band = mem.GetRasterBand(1)
    band.SetNoDataValue(nodata)
    band.WriteArray(array)
    tmp = path + ".tmp.tif"
    opts = ["COMPRESS=DEFLATE", "PREDICTOR=%d" % predictor, "ZLEVEL=9", "TILED=YES",
            "BLOCKXSIZE=256", "BLOCKYSIZE=256"]
    try:
        ds = gdal.GetDriverByName("GTiff").CreateCopy(tmp, mem, strict=1, options=opts)
        ds.FlushCache()
        ds = None
        os.replace(tmp, path)
    except Exception as e:  # noqa: BLE001 - report any GDAL/OS failure plainly
        if os.path.exists(tmp):
            os.remove(tmp)
        die("cannot write %s: %s" % (path, e))
    with open(path, "rb") as f:
        sha = hashlib.sha256(f.read()).hexdigest()
    print("%s: %d x %d %s, %d bytes, values %g..%g\n  sha256 %s"
          % (os.path.basename(path), w, h, gdal.GetDataTypeName(gdal_type),
             os.path.getsize(path), float(array.min()), float(array.max()), sha))


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description="Draw the Zhou et al. 2007 sketch maps "
                                 "as GeoTIFFs on the grid of jacksboro_fault_dem.tif.")
    ap.add_argument("outdir", nargs="?", default=os.path.join(here, "sketches"),
                    help="output folder (default: data/sketches)")
    args = ap.parse_args()
    gdal.UseExceptions()
    gdal.SetConfigOption("GDAL_PAM_ENABLED", "NO")
    os.makedirs(args.outdir, exist_ok=True)
    out = lambda name: os.path.join(args.outdir, name)  # noqa: E731

    lam = lambda_ridges()
    write(out("lambda_ridges.tif"), lam, gdal.GDT_Float32, NODATA,
          "Sketch map (ridges): half-life symbol, a ring around a lowercase lambda, "
          "after Zhou et al. 2007 Fig. 10a; grey 0..255, bright = high; " + CREDIT, 3)
    write(out("lambda_valleys.tif"), (np.float32(255.0) - lam).astype(np.float32),
          gdal.GDT_Float32, NODATA,
          "Sketch map (valleys): inverse of lambda_ridges.tif (255 - value), after "
          "Zhou et al. 2007 Fig. 10e; grey 0..255, bright = high; " + CREDIT, 3)
    write(out("water_character.tif"), water_character(), gdal.GDT_Float32, NODATA,
          "Sketch map (ridges): the Chinese character for water (U+6C34), after "
          "Zhou et al. 2007 Fig. 12a; grey 0..255, bright = high; " + CREDIT, 3)
    sketch, regions = multistyle()
    write(out("multistyle_sketch.tif"), sketch, gdal.GDT_Float32, NODATA,
          "Sketch map (ridges): a winding ridge across the map with three side "
          "branches, for two-style synthesis (Zhou et al. 2007 sec. 6.1); "
          "grey 0..255, bright = high; regions in multistyle_regions.tif; " + CREDIT, 3)
    write(out("multistyle_regions.tif"), regions, gdal.GDT_Byte, REGION_NODATA,
          "Style region map for multistyle_sketch.tif: 1 = west (e.g. mountains), "
          "2 = east (e.g. hills), curved border; nodata 0 declared, not present; "
          + CREDIT, 2)
    both, lines = ridges_valleys()
    write(out("ridges_valleys.tif"), both, gdal.GDT_Float32, NODATA,
          "Sketch map (ridges and valleys): a crest with spurs, the valleys between them "
          "and a river, on a grey ground (128): brighter = ridges, darker = valleys; the "
          "same drawing as lines in ridges_valleys.geojson; " + CREDIT, 3)
    write_lines(out("ridges_valleys.geojson"), lines,
                "Sketch (ridges and valleys) as lines, field kind; the same drawing painted in "
                "ridges_valleys.tif; " + CREDIT)
    return 0


if __name__ == "__main__":
    sys.exit(main())
