# SPDX-License-Identifier: GPL-2.0-or-later
"""The drainage stage after every method (--drainage keep|breach|fill): judged by a numpy
priority-flood written out here (how much water each cell would hold), on the outputs of
synth (free, tiled, a sketch), pixel and amplify; windows of a recipe equal the whole with
the stage on; water and pinned cells never change; bad values refused in one line."""
import heapq
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import DATA, JACKSBORO, ROOT, plugin_env, run  # noqa: E402

gdal.UseExceptions()
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
LAMBDA = os.path.join(DATA, "sketches", "lambda_ridges.tif")


def read(path):
    ds = gdal.Open(str(path))
    b = ds.GetRasterBand(1)
    a = b.ReadAsArray().astype(np.float64)
    if b.GetNoDataValue() is not None:
        a[a == b.GetNoDataValue()] = np.nan
    return a


def filled(a):
    """The water surface: a priority-flood from the grid's edge and from nodata (Barnes et
    al. 2014, here in plain Python): each cell at least as high as the lowest way out."""
    h, w = a.shape
    wat = np.where(np.isfinite(a), np.inf, np.nan)
    done = ~np.isfinite(a)
    heap = []
    for y in range(h):
        for x in range(w):
            if done[y, x]:
                continue
            near_nodata = any(0 <= y + dy < h and 0 <= x + dx < w and not np.isfinite(a[y + dy, x + dx])
                              for dy in (-1, 0, 1) for dx in (-1, 0, 1))
            if y in (0, h - 1) or x in (0, w - 1) or near_nodata:
                wat[y, x] = a[y, x]
                done[y, x] = True
                heapq.heappush(heap, (a[y, x], y, x))
    while heap:
        z, y, x = heapq.heappop(heap)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                v, u = y + dy, x + dx
                if 0 <= v < h and 0 <= u < w and not done[v, u]:
                    done[v, u] = True
                    wat[v, u] = max(z, a[v, u])
                    heapq.heappush(heap, (wat[v, u], v, u))
    return wat


def in_pits(a, tol=0.01):
    """Share of the cells a flood would raise by more than tol."""
    d = filled(a) - a
    return float((d[np.isfinite(d)] > tol).mean())


CASES = {
    "synth": ["synth", "--exemplar", JACKSBORO, "--size", "200x160", "--seed", 3],
    "tiled": ["synth", "--exemplar", JACKSBORO, "--size", "260x200", "--seed", 3, "--tiled", 128],
    "sketch": ["synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", 1],
    "sketch_valleys": ["synth", "--sketch", os.path.join(DATA, "sketches", "ridges_valleys.tif"),
                       "--exemplar", JACKSBORO, "--seed", 1],
    "pixel": ["pixel", "--exemplar", JACKSBORO, "--size", "200x160", "--seed", 3],
}


def flat_share(a, tol=0.01):
    """Share of the cells with data whose gradient (central differences) is under tol height
    units per cell: the flat lakes a fill leaves."""
    gy, gx = np.gradient(a)
    g = np.hypot(gx, gy)
    return float((g[np.isfinite(g)] < tol).mean())


def crease(a):
    lap = a[1:-1, 2:] + a[1:-1, :-2] + a[2:, 1:-1] + a[:-2, 1:-1] - 4 * a[1:-1, 1:-1]
    return float(np.percentile(np.abs(lap[np.isfinite(lap)]), 99.9))


@pytest.mark.parametrize("case", sorted(CASES))
def test_breach_drains_every_method(case, tmp_path):
    """The output as synthesised holds water in pits.  Breached, with one-cell channels
    (--drainage-banks 0) or with banks (the default, at the slope the summary gives), no
    cell is raised and no cell is left in a pit (within 1 cm), save in a basin whose way out
    is farther than the radius; no flat is made; the banks soften the slots' creases.  Synth
    in one piece may raise the basins the breach keeps beside a drawn valley to plains: none
    above the kept output's water surface by more than 3/4 of the banks' slope; free synth in
    one piece lifts its basins wider than the radius first."""
    args = CASES[case]
    run(*args, tmp_path / "keep.tif", "-q", "--drainage", "keep")
    run(*args, tmp_path / "slot.tif", "-q", "--drainage-banks", 0)
    p = run(*args, tmp_path / "breach.tif")
    m = re.search(r"drainage: breach, banks ([\d.e+]+) per cell", p.stdout)
    assert m, p.stdout
    banks = float(m.group(1))
    keep, slot, breach = (read(tmp_path / (n + ".tif")) for n in ("keep", "slot", "breach"))
    assert (np.isnan(keep) == np.isnan(breach)).all()
    ok = np.isfinite(keep)
    assert (slot[ok] <= keep[ok]).all()  # never raised without banks (no automatic depth)
    up = breach[ok] > keep[ok]
    m = re.search(r"(\d+) dammed basins raised to plains \((\d+) cells", p.stdout)
    lifted = re.search(r"basins wider than the radius lifted \((\d+) cells", p.stdout)
    if case in ("sketch", "sketch_valleys") and m:
        water = filled(keep)[ok]
        assert up.sum() <= int(m.group(2))
        assert (breach[ok][up] <= water[up] + 0.75 * banks + 1e-3).all()
    elif case == "synth" and lifted:
        # free synthesis in one piece lifts the basins the breach leaves: no cell raised by
        # more than the kept output's deepest depression and the grade (a twentieth of the
        # banks' slope a block of 8 cells) along a way across the grid
        assert up.sum() <= int(lifted.group(1)), p.stdout
        h, w = keep.shape
        deepest = float(np.nanmax(filled(keep) - keep))
        assert (breach[ok] - keep[ok]).max() <= deepest + 0.05 * banks * (w + h) / 8 + 1e-3
    else:
        assert not up.any() and not lifted
    before, after_slot, after = in_pits(keep), in_pits(slot), in_pits(breach)
    print(case, "in pits: %.4f -> %.4f (slots), %.4f (banks %g); flats %.4f -> %.4f; "
          "creases %.2f -> %.2f (slots), %.2f (banks); changed %.3f" % (
              before, after_slot, after, banks, flat_share(keep), flat_share(breach),
              crease(keep), crease(slot), crease(breach), float((breach[ok] != keep[ok]).mean())))
    assert before > 0.01
    # the lambda's closed ring holds a basin wider than the radius; with a sketch, a channel
    # beside a drawn valley running lower than its floor is cut at most the banks' slope deep
    # by default, and deeper basins there are kept (the rest drain as after any method);
    # drawn valleys' floors follow the synthesis's thalweg and side gullies run down to them,
    # so few cells stay in pits there
    sketch = case.startswith("sketch")
    assert after_slot <= (0.15 if sketch else 0.001), after_slot
    assert after <= (0.8 * before if case == "sketch" else 0.025 if sketch else 0.001), after
    assert flat_share(breach) <= flat_share(keep) + 0.002
    assert crease(breach) <= crease(slot) + 1e-6
    assert float((breach[ok] != keep[ok]).mean()) < 0.2


def test_wide_basins_lifted(tmp_path):
    """Free synthesis in one piece with the automatic depth lifts the basins wider than the
    radius that the breach leaves, and breaches again: with a radius of 16 cells the breach
    alone (--drainage-depth 0: any depth, no lift) leaves some; lifted and breached, none."""
    args = ["synth", "--exemplar", JACKSBORO, "--size", "200x160", "--seed", 3,
            "--drainage-radius", 16]
    run(*args, tmp_path / "keep.tif", "-q", "--drainage", "keep")
    run(*args, tmp_path / "alone.tif", "-q", "--drainage-depth", 0)
    p = run(*args, tmp_path / "lifted.tif")
    m = re.search(r"banks ([\d.e+]+) per cell.*basins wider than the radius lifted \((\d+) cells",
                  p.stdout)
    assert m, p.stdout
    keep, alone, lifted = (read(tmp_path / n) for n in ("keep.tif", "alone.tif", "lifted.tif"))
    print("in pits: kept %.4f, breached alone %.4f, lifted and breached %.4f" % (
        in_pits(keep), in_pits(alone), in_pits(lifted)))
    assert in_pits(alone) > 0.02 and in_pits(lifted) <= 0.001
    # no more cells raised than the summary says, none by more than the kept output's deepest
    # depression and the grade (a twentieth of the banks' slope a block of 2 cells) along a
    # way across the grid
    up = lifted > keep
    assert 0 < up.sum() <= int(m.group(2))
    h, w = keep.shape
    bound = float(np.max(filled(keep) - keep)) + 0.05 * float(m.group(1)) * (w + h) / 2
    assert float(np.max(lifted - keep)) <= bound + 1e-3


def test_amplify_drains(tmp_path):
    ds = gdal.Open(JACKSBORO)
    z = ds.ReadAsArray().astype(np.float32)[:60, :80]
    coarse = z.reshape(30, 2, 40, 2).mean(axis=(1, 3))
    gt = list(ds.GetGeoTransform())
    gt[1] *= 2
    gt[5] *= 2
    out = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "c.tif"), 40, 30, 1,
                                               gdal.GDT_Float32)
    out.SetGeoTransform(gt)
    out.SetProjection(ds.GetProjection())
    out.GetRasterBand(1).WriteArray(coarse)
    out = None
    args = ["amplify", tmp_path / "c.tif", "--exemplar", JACKSBORO, "--factor", 4, "-q"]
    run(*args[:2], tmp_path / "keep.tif", *args[2:], "--drainage", "keep")
    run(*args[:2], tmp_path / "breach.tif", *args[2:])
    keep, breach = read(tmp_path / "keep.tif"), read(tmp_path / "breach.tif")
    assert in_pits(keep) > 0.01 and in_pits(breach) <= 0.001
    assert (breach <= keep).all()


def test_fill_is_the_flood(tmp_path):
    """--drainage fill raises every depression to its spill: the flood's surface (within a
    millimetre) where the radius reaches every way out; nothing is lowered."""
    args = ["pixel", "--exemplar", JACKSBORO, "--size", "120x100", "--seed", 5, "-q"]
    run(*args, tmp_path / "keep.tif", "--drainage", "keep")
    run(*args, tmp_path / "fill.tif", "--drainage", "fill")
    keep, fill = read(tmp_path / "keep.tif"), read(tmp_path / "fill.tif")
    assert np.abs(fill - filled(keep)).max() <= 1e-3
    assert (fill >= keep).all() and (fill > keep).any()


def test_deepest_cut(tmp_path):
    """--drainage-depth D: no cell cut deeper than D (and the channel's millimetre a cell),
    none raised; the depressions that need more are kept."""
    args = ["pixel", "--exemplar", JACKSBORO, "--size", "160x120", "--seed", 6, "-q"]
    run(*args, tmp_path / "keep.tif", "--drainage", "keep")
    run(*args, tmp_path / "d.tif", "--drainage-depth", 2)
    run(*args, tmp_path / "all.tif")
    keep, d, a = (read(tmp_path / n) for n in ("keep.tif", "d.tif", "all.tif"))
    assert (d <= keep).all() and (d >= keep - 2.2).all()
    assert in_pits(keep) > in_pits(d) > in_pits(a)


def test_windows_equal_the_whole(tmp_path):
    """A recipe's windows, each computed alone with the stage's margin (pixel: blocks of 512;
    here windows read in a fresh process), equal the CLI's whole output."""
    args = ["pixel", "--exemplar", JACKSBORO, "--size", "300x260", "--seed", 2]
    run(*args, tmp_path / "whole.tif", "-q")
    run(*args, "--recipe", tmp_path / "p.tsyn")
    whole = gdal.Open(str(tmp_path / "whole.tif")).ReadAsArray()
    for x0, y0, w, h in ((0, 0, 300, 260), (137, 91, 60, 70), (250, 200, 50, 60)):
        out = tmp_path / ("w%d_%d.tif" % (x0, y0))
        subprocess.run(["gdal_translate", "-q", "-srcwin", str(x0), str(y0), str(w), str(h),
                        str(tmp_path / "p.tsyn"), str(out)], check=True, env=plugin_env(PLUGINS))
        got = gdal.Open(str(out)).ReadAsArray()
        assert got.tobytes() == whole[y0:y0 + h, x0:x0 + w].tobytes(), (x0, y0)


def test_water_and_pins_stay(tmp_path):
    """Water cells keep their level and pinned cells the pinned DEM's heights."""
    mask = np.zeros((160, 200), np.uint8)
    mask[60:90, 40:100] = 1
    ds = gdal.Open(JACKSBORO)
    m = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "w.tif"), 200, 160, 1, gdal.GDT_Byte)
    gt = ds.GetGeoTransform()
    m.SetGeoTransform(gt)
    m.SetProjection(ds.GetProjection())
    m.GetRasterBand(1).WriteArray(mask)
    m = None
    level = 350.0
    run("synth", "--exemplar", JACKSBORO, "--size", "200x160", "--origin",
        "%r,%r" % (gt[0], gt[3]), "--resolution", repr(gt[1]), "--crs", "EPSG:4326",
        "--seed", 3, "--water", tmp_path / "w.tif", "--water-level", level,
        "--pin", "%s:10,10,40,30@140,110" % JACKSBORO, tmp_path / "o.tif", "-q")
    o = read(tmp_path / "o.tif")
    assert (o[mask == 1] == np.float32(level)).all()
    pin = ds.ReadAsArray()[10:40, 10:50].astype(np.float32)
    assert (o[110:140, 140:180] == pin).all()


@pytest.mark.parametrize("bad, says", [(["--drainage", "sometimes"], "drainage"),
                                       (["--drainage-radius", "0"], "drainage_radius"),
                                       (["--drainage-depth", "-2"], "drainage_depth"),
                                       (["--drainage-banks", "-2"], "drainage_banks")])
def test_bad_values_refused(bad, says, tmp_path):
    p = run("pixel", "--exemplar", JACKSBORO, "--size", "64x64", tmp_path / "o.tif", *bad,
            check=False)
    assert p.returncode != 0
    assert len(p.stderr.strip().splitlines()) == 1 and says in p.stderr, p.stderr
    assert not (tmp_path / "o.tif").exists()
