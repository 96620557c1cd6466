#!/usr/bin/python3
# draw_sketches.py - the TerraSynth developers' own test sketches for the quality
# matrix (bench/quality), drawn unlike ../shared/eval/make_sketches.py's so
# that the synthesis is not tuned to one drawer's hand: other brushes, other
# grids, other shapes.
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
#
#   /usr/bin/python3 bench/quality/draw_sketches.py OUTDIR
#
# Writes, with a line each in OUTDIR/sketches.csv (file, mode):
#   dendritic_valleys_768.tif  a trunk valley with five tributaries, two of them
#                              forked again (degree-3 junctions), UTM 11N 30 m
#   junction4_ridges_640.tif   three straight ridges and an arc meeting in one
#                              degree-4 junction, UTM 12N 30 m
#   spiral_ridge_geo3s_560.tif one long spiral ridge on a geographic grid
#                              (EPSG:4326, 3 arc-seconds)
#   radial5_valleys_600.tif    five valleys leaving one point (a degree-5
#                              junction), UTM 10N 30 m
#   fishbone_ridges_geo1s_640.tif a winding main ridge with six side spurs,
#                              EPSG:4326 1 arc-second
#   range_spurs_both_720.tif   both kinds on a grey ground: a winding crest with
#                              side spurs and the valleys between them coming
#                              down from it, UTM 13N 30 m
#   caldera_both_geo1s_600.tif both kinds: a closed ring ridge (a caldera rim)
#                              with eight valleys radiating from it and one
#                              cutting into the ring, EPSG:4326 1 arc-second
# The both-kind drawings are also written as lines, NAME.gpkg (layer
# "strokes", field "kind"), the way a GIS user would digitise them.
# Strokes are painted with a brush whose value falls linearly to zero at
# `width` cells from the stroke and is then blurred a little (a felt pen, not
# a Gaussian airbrush); ridges are bright on dark, valleys dark on bright.
# Nothing is random.
import math
import os
import sys

import numpy as np
from osgeo import gdal, osr
from scipy import ndimage

gdal.UseExceptions()


class Canvas:
    def __init__(self, n):
        self.n = n
        self.lines = np.zeros((n, n), bool)
        self.polylines = []

    def stroke(self, pts):
        """Rasterise a polyline (x, y in cells) at sub-cell steps."""
        self.polylines.append([(x + 0.5, y + 0.5) for x, y in pts])
        for (x0, y0), (x1, y1) in zip(pts[:-1], pts[1:]):
            steps = max(2, int(4 * math.hypot(x1 - x0, y1 - y0)))
            t = np.linspace(0.0, 1.0, steps)
            xs = np.rint(x0 + t * (x1 - x0)).astype(int)
            ys = np.rint(y0 + t * (y1 - y0)).astype(int)
            ok = (xs >= 0) & (ys >= 0) & (xs < self.n) & (ys < self.n)
            self.lines[ys[ok], xs[ok]] = True

    def paint(self, width, blur):
        d = ndimage.distance_transform_edt(~self.lines)
        return ndimage.gaussian_filter(np.clip(1.0 - d / width, 0.0, 1.0), blur)


def wiggle(p0, p1, amp, waves, n=60):
    """A line from p0 to p1 bent sideways by a sine of `amp` cells."""
    (x0, y0), (x1, y1) = p0, p1
    L = math.hypot(x1 - x0, y1 - y0)
    nx, ny = -(y1 - y0) / L, (x1 - x0) / L
    out = []
    for t in np.linspace(0.0, 1.0, n):
        s = amp * math.sin(math.pi * waves * t)
        out.append((x0 + t * (x1 - x0) + s * nx, y0 + t * (y1 - y0) + s * ny))
    return out


def write(path, grey, gt, epsg):
    n = grey.shape[0]
    ds = gdal.GetDriverByName("GTiff").Create(path, n, n, 1, gdal.GDT_Byte,
                                              ["COMPRESS=DEFLATE"])
    ds.SetGeoTransform(gt)
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(epsg)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).WriteArray(grey)
    ds = None


def write_lines(path, kinds, gt, epsg):
    """kinds: [(kind, Canvas)]: every polyline of each canvas, in the grid's CRS."""
    from osgeo import ogr
    drv = ogr.GetDriverByName("GPKG")
    if os.path.exists(path):
        drv.DeleteDataSource(path)
    ds = drv.CreateDataSource(path)
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(epsg)
    lyr = ds.CreateLayer("strokes", srs, ogr.wkbLineString)
    lyr.CreateField(ogr.FieldDefn("kind", ogr.OFTString))
    for kind, canvas in kinds:
        for pts in canvas.polylines:
            f = ogr.Feature(lyr.GetLayerDefn())
            f.SetField("kind", kind)
            g = ogr.Geometry(ogr.wkbLineString)
            for x, y in pts:
                g.AddPoint_2D(gt[0] + x * gt[1], gt[3] + y * gt[5])
            f.SetGeometry(g)
            lyr.CreateFeature(f)
    ds = None


def both(r, v):
    """Ridges brighter and valleys darker than a grey ground."""
    return np.rint(np.clip(120 + 125 * r - 110 * v, 0, 255)).astype(np.uint8)


def ridges(v):
    return np.rint(20 + 220 * v).astype(np.uint8)


def valleys(v):
    return np.rint(235 - 215 * v).astype(np.uint8)


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    rows = []

    n = 768
    c = Canvas(n)
    trunk = wiggle((0.45 * n, 0.99 * n), (0.55 * n, 0.08 * n), 0.04 * n, 2)
    c.stroke(trunk)
    for i, (t, side, length, fork) in enumerate([(0.25, 1, 0.30, False), (0.40, -1, 0.36, True),
                                                 (0.55, 1, 0.33, True), (0.70, -1, 0.26, False),
                                                 (0.82, 1, 0.22, False)]):
        x0, y0 = trunk[int(t * (len(trunk) - 1))]
        ang = -math.pi / 2 + side * (0.95 - 0.25 * t)
        end = (x0 + length * n * math.cos(ang), y0 + length * n * math.sin(ang))
        trib = wiggle((x0, y0), end, 0.02 * n * side, 1.5, 40)
        c.stroke(trib)
        if fork:
            xm, ym = trib[len(trib) // 2]
            a2 = ang - side * 0.8
            c.stroke(wiggle((xm, ym), (xm + 0.16 * n * math.cos(a2), ym + 0.16 * n * math.sin(a2)),
                            0.01 * n, 1, 20))
    write(os.path.join(out, "dendritic_valleys_768.tif"), valleys(c.paint(14, 3)),
          (380000.0, 30.0, 0.0, 3800000.0, 0.0, -30.0), 32611)
    rows.append("dendritic_valleys_768.tif,valleys")

    n = 640
    c = Canvas(n)
    jx, jy = 0.52 * n, 0.47 * n
    for ang, length in ((0.1, 0.42), (1.9, 0.40), (3.6, 0.45)):
        c.stroke([(jx, jy), (jx + length * n * math.cos(ang), jy + length * n * math.sin(ang))])
    c.stroke([(jx + 0.3 * n * math.cos(a) - 0.3 * n * math.cos(4.9),
               jy + 0.3 * n * math.sin(a) - 0.3 * n * math.sin(4.9))
              for a in np.linspace(4.9, 6.0, 40)])
    write(os.path.join(out, "junction4_ridges_640.tif"), ridges(c.paint(12, 2.5)),
          (500000.0, 30.0, 0.0, 4900000.0, 0.0, -30.0), 32612)
    rows.append("junction4_ridges_640.tif,ridges")

    n = 560
    c = Canvas(n)
    c.stroke([(0.5 * n + (0.05 + 0.40 * t) * n * math.cos(5.2 * math.pi * t),
               0.5 * n + (0.05 + 0.40 * t) * n * math.sin(5.2 * math.pi * t))
              for t in np.linspace(0.08, 1.0, 700)])
    write(os.path.join(out, "spiral_ridge_geo3s_560.tif"), ridges(c.paint(9, 2)),
          (-112.9, 1.0 / 1200, 0.0, 37.45, 0.0, -1.0 / 1200), 4326)
    rows.append("spiral_ridge_geo3s_560.tif,ridges")

    n = 600
    c = Canvas(n)
    for k in range(5):
        a = 0.4 + 2 * math.pi * k / 5
        r = (0.36 + 0.07 * (k % 2)) * n
        c.stroke(wiggle((0.5 * n, 0.5 * n), (0.5 * n + r * math.cos(a), 0.5 * n + r * math.sin(a)),
                        0.03 * n, 1, 30))
    write(os.path.join(out, "radial5_valleys_600.tif"), valleys(c.paint(13, 3)),
          (560000.0, 30.0, 0.0, 5120000.0, 0.0, -30.0), 32610)
    rows.append("radial5_valleys_600.tif,valleys")

    n = 640
    c = Canvas(n)
    main_ridge = wiggle((0.06 * n, 0.55 * n), (0.94 * n, 0.45 * n), 0.08 * n, 1.2, 80)
    c.stroke(main_ridge)
    for i, t in enumerate((0.18, 0.32, 0.46, 0.60, 0.74, 0.88)):
        x0, y0 = main_ridge[int(t * (len(main_ridge) - 1))]
        side = 1 if i % 2 == 0 else -1
        c.stroke([(x0, y0), (x0 + 0.07 * n, y0 + side * 0.26 * n)])
    write(os.path.join(out, "fishbone_ridges_geo1s_640.tif"), ridges(c.paint(10, 2)),
          (-114.0, 1.0 / 3600, 0.0, 44.15, 0.0, -1.0 / 3600), 4326)
    rows.append("fishbone_ridges_geo1s_640.tif,ridges")

    # both kinds: a crest with spurs and the valleys between them
    n = 720
    r, v = Canvas(n), Canvas(n)
    crest = wiggle((0.04 * n, 0.40 * n), (0.96 * n, 0.30 * n), 0.05 * n, 1.5, 90)
    r.stroke(crest)
    for i, t in enumerate((0.15, 0.30, 0.45, 0.60, 0.75, 0.90)):
        x0, y0 = crest[int(t * (len(crest) - 1))]
        side = 1 if i % 2 == 0 else -1
        r.stroke(wiggle((x0, y0), (x0 + 0.05 * n, y0 + side * 0.28 * n), 0.015 * n, 1, 20))
    for i, t in enumerate((0.075, 0.225, 0.375, 0.525, 0.675, 0.825)):
        x0, y0 = crest[int(t * (len(crest) - 1))]
        side = 1 if i % 2 == 0 else -1
        v.stroke(wiggle((x0 + 0.01 * n, y0 + side * 0.06 * n),
                        (x0 + 0.04 * n, y0 + side * 0.42 * n), 0.02 * n, 1, 24))
    gt = (420000.0, 30.0, 0.0, 4400000.0, 0.0, -30.0)
    write(os.path.join(out, "range_spurs_both_720.tif"), both(r.paint(12, 2.5), v.paint(10, 2.5)),
          gt, 32613)
    write_lines(os.path.join(out, "range_spurs_both_720.gpkg"), [("ridge", r), ("valley", v)], gt,
                32613)
    rows.append("range_spurs_both_720.tif,both")

    # both kinds: a closed caldera rim, valleys radiating from it, one cutting into it
    n = 600
    r, v = Canvas(n), Canvas(n)
    cx, cy, rad = 0.47 * n, 0.52 * n, 0.20 * n
    r.stroke([(cx + rad * math.cos(a) * (1 + 0.08 * math.sin(3 * a)),
               cy + rad * math.sin(a) * (1 + 0.08 * math.sin(3 * a)))
              for a in np.linspace(0.0, 2 * math.pi, 240)])
    for k in range(8):
        a = 0.3 + 2 * math.pi * k / 8
        r0, r1 = rad * 1.25, (0.42 + 0.05 * (k % 3)) * n
        v.stroke(wiggle((cx + r0 * math.cos(a), cy + r0 * math.sin(a)),
                        (cx + r1 * math.cos(a + 0.15), cy + r1 * math.sin(a + 0.15)),
                        0.015 * n, 1, 24))
    v.stroke([(cx - 0.45 * rad, cy + 0.1 * rad), (cx - 1.6 * rad, cy + 0.9 * rad),
              (cx - 2.2 * rad, cy + 1.9 * rad)])
    gt = (7.60, 1.0 / 3600, 0.0, 46.50, 0.0, -1.0 / 3600)
    write(os.path.join(out, "caldera_both_geo1s_600.tif"), both(r.paint(11, 2), v.paint(9, 2)),
          gt, 4326)
    write_lines(os.path.join(out, "caldera_both_geo1s_600.gpkg"), [("ridge", r), ("valley", v)],
                gt, 4326)
    rows.append("caldera_both_geo1s_600.tif,both")

    with open(os.path.join(out, "sketches.csv"), "w") as f:
        f.write("file,mode\n" + "\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
