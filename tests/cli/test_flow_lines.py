# SPDX-License-Identifier: GPL-2.0-or-later
"""--flow-lines: the streams of a job's DEM as vector lines, judged by a numpy D8 written out
here (each cell to its lowest neighbour on a DEM made free of pits and flats, the areas
summed downhill, the Strahler order counted up the tree) cell by cell and link by link; every
job that writes a DEM writes them from its output; bad values refused before the work."""
import heapq
import os
import sys

import numpy as np
import pytest
from osgeo import gdal, ogr

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import JACKSBORO, run  # noqa: E402

gdal.UseExceptions()
ogr.UseExceptions()
# E, SE, S, SW, W, NW, N, NE (x right, y down)
DIRS = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)]


def pit_free(a, eps=0.01):
    """A priority-flood from the edge with a small rise (Barnes et al. 2014): every inner
    cell ends higher than a neighbour that leads out, so the D8 flow is plain."""
    h, w = a.shape
    out = a.copy()
    done = np.zeros(a.shape, bool)
    heap = []
    for y in range(h):
        for x in range(w):
            if y in (0, h - 1) or x in (0, w - 1):
                done[y, x] = True
                heapq.heappush(heap, (out[y, x], y, x))
    while heap:
        z, y, x = heapq.heappop(heap)
        for dx, dy in DIRS:
            v, u = y + dy, x + dx
            if 0 <= v < h and 0 <= u < w and not done[v, u]:
                done[v, u] = True
                out[v, u] = max(out[v, u], z + eps)
                heapq.heappush(heap, (out[v, u], v, u))
    return out


def d8(a):
    """to[y, x] = (y', x') of the lowest neighbour ((-1, -1): off the grid, the edge's
    cells), the drainage area in cells, and each cell's inflows."""
    h, w = a.shape
    to = {}
    for y in range(h):
        for x in range(w):
            if y in (0, h - 1) or x in (0, w - 1):
                to[y, x] = None
                continue
            best = None
            for dx, dy in DIRS:
                if a[y + dy, x + dx] < a[y, x] and (best is None or
                                                    a[y + dy, x + dx] < a[best]):
                    best = (y + dy, x + dx)
            assert best is not None, "not pit-free"
            to[y, x] = best
    area = np.ones(a.shape)
    for i in np.argsort(-a, axis=None, kind="stable"):
        y, x = divmod(int(i), w)
        if to[y, x] is not None:
            area[to[y, x]] += area[y, x]
    return to, area


def strahler(to, stream):
    order = {}
    inflows = {}
    for c in stream:
        if to[c] is not None and to[c] in stream:
            inflows.setdefault(to[c], []).append(c)

    def of(c):
        if c not in order:
            o = [of(k) for k in inflows.get(c, [])]
            m = max(o, default=0)
            order[c] = 1 if not o else m + (o.count(m) >= 2)
        return order[c]
    sys.setrecursionlimit(100000)
    for c in stream:
        of(c)
    return order, inflows


def read_links(path, gt):
    """Each stream's fields and its cells (row, col) from its vertices (cell centres)."""
    ds = ogr.Open(str(path))
    lyr = ds.GetLayerByName("streams")
    links = []
    for f in lyr:
        g = f.GetGeometryRef()
        cells = []
        for i in range(g.GetPointCount()):
            px, py = g.GetX(i), g.GetY(i)
            cells.append((int(round((py - gt[3]) / gt[5] - 0.5)),
                          int(round((px - gt[0]) / gt[1] - 0.5))))
        links.append(dict(f.items(), cells=cells))
    return links


def write_like(path, a, ds):
    out = gdal.GetDriverByName("GTiff").Create(str(path), a.shape[1], a.shape[0], 1,
                                               gdal.GDT_Float32)
    out.SetGeoTransform(ds.GetGeoTransform())
    out.SetProjection(ds.GetProjection())
    out.GetRasterBand(1).WriteArray(a)
    out = None


@pytest.mark.parametrize("thr", [30, 150])
def test_streams_are_numpy_d8(thr, tmp_path):
    """A real DEM made free of pits and flats: the streams drain exactly the cells numpy's D8
    gives at least thr, each link follows the flow from a head or a confluence to the next
    confluence or the edge, with the Strahler order, the area and the link below that numpy
    counts."""
    src = gdal.Open(JACKSBORO)
    z = src.ReadAsArray().astype(np.float64)[40:130, 30:150]
    rng = np.random.default_rng(5)
    z = pit_free(z + rng.uniform(0, 0.001, z.shape)).astype(np.float32)
    dem = tmp_path / "dem.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(dem), z.shape[1], z.shape[0], 1,
                                              gdal.GDT_Float32)
    gt = list(src.GetGeoTransform())
    ds.SetGeoTransform(gt)
    ds.SetProjection(src.GetProjection())
    ds.GetRasterBand(1).WriteArray(z)
    ds = None
    run("ppa", dem, tmp_path / "axes.tif", "--flow-lines", tmp_path / "s.gpkg",
        "--flow-cells", thr, "-q")
    to, area = d8(z.astype(np.float64))
    stream = {c for c in to if area[c] >= thr}
    order, inflows = strahler(to, stream)
    starts = {c for c in stream if len(inflows.get(c, [])) != 1 and to[c] is not None}
    links = read_links(tmp_path / "s.gpkg", gt)
    assert len(links) == len(starts) > 5
    covered = set()
    first_of = {tuple(L["cells"][0]): L["link"] for L in links}
    for L in links:
        cells = [tuple(c) for c in L["cells"]]
        assert cells[0] in starts
        for a, b in zip(cells, cells[1:]):
            assert to[a] == b
        for c in cells[1:-1]:
            assert len(inflows.get(c, [])) == 1
        last = cells[-1]
        assert len(inflows.get(last, [])) >= 2 or to[last] is None
        assert L["strahler"] == order[cells[0]]
        own = cells[-2] if len(inflows.get(last, [])) >= 2 else last
        assert L["area_cells"] == area[own]
        if L["down"] is None:
            assert to[last] is None
        else:
            assert first_of[last] == L["down"]
        assert L["elev_top"] == pytest.approx(float(z[cells[0]]))
        assert L["elev_bottom"] == pytest.approx(float(z[last]))
        assert L["length_m"] > 0 and L["area_km2"] > 0
        covered.update(cells)
    # every stream cell that flows on, and every outlet something flows into
    assert covered == {c for c in stream if to[c] is not None or c in inflows}
    assert max(L["strahler"] for L in links) >= 2


JOBS = {
    "synth": ["synth", "--exemplar", JACKSBORO, "--size", "160x128", "--seed", 2],
    "pixel": ["pixel", "--exemplar", JACKSBORO, "--size", "128x96", "--seed", 2],
}


@pytest.mark.parametrize("job", sorted(JOBS))
def test_every_job_writes_its_streams(job, tmp_path):
    """The streams are the output's: every vertex on a cell with data, its height that
    cell's, the network the same as ppa maps on the output itself."""
    out = tmp_path / "out.tif"
    run(*JOBS[job], out, "--flow-lines", tmp_path / "f.gpkg", "--flow-cells", 50, "-q")
    run("ppa", out, tmp_path / "axes.tif", "--flow-lines", tmp_path / "again.gpkg",
        "--flow-cells", 50, "-q")
    ds = gdal.Open(str(out))
    a = ds.ReadAsArray()
    gt = ds.GetGeoTransform()
    mine, again = read_links(tmp_path / "f.gpkg", gt), read_links(tmp_path / "again.gpkg", gt)
    assert len(mine) > 3 and mine == again
    for L in mine:
        for c in L["cells"]:
            assert np.isfinite(a[c])
        assert L["elev_top"] == pytest.approx(float(a[L["cells"][0]]))
        assert L["elev_top"] >= L["elev_bottom"] - 1e-3  # the output drains (breach)


def test_amplify_writes_its_streams(tmp_path):
    src = gdal.Open(JACKSBORO)
    z = src.ReadAsArray().astype(np.float32)[:60, :80]
    coarse = z.reshape(30, 2, 40, 2).mean(axis=(1, 3))
    out = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "c.tif"), 40, 30, 1,
                                               gdal.GDT_Float32)
    gt = list(src.GetGeoTransform())
    gt[1] *= 2
    gt[5] *= 2
    out.SetGeoTransform(gt)
    out.SetProjection(src.GetProjection())
    out.GetRasterBand(1).WriteArray(coarse)
    out = None
    run("amplify", tmp_path / "c.tif", tmp_path / "a.tif", "--exemplar", JACKSBORO,
        "--factor", 4, "--flow-lines", tmp_path / "f.geojson", "--flow-km2", 0.5, "-q")
    ds = ogr.Open(str(tmp_path / "f.geojson"))
    lyr = ds.GetLayer(0)
    assert lyr.GetFeatureCount() > 3
    # the threshold in km2: no link's own area is below it
    assert min(f["area_km2"] for f in lyr) >= 0.5 * 0.98


@pytest.mark.parametrize("args, says", [
    (["--flow-cells", 100], "flow_cells goes with flow_lines"),
    (["--flow-lines", "{t}/f.gpkg", "--flow-cells", 1], "flow_cells must be a number in 2.."),
    (["--flow-lines", "{t}/f.gpkg", "--flow-cells", 10, "--flow-km2", 1], "not both"),
    (["--flow-lines", "{t}/f.txt"], "cannot tell the vector format"),
    (["--flow-lines", "{t}/out.tif"], "each output needs its own file"),
    (["--flow-lines", "{t}/f.gpkg", "--flow-km2", 1e-7], "a stream drains at least 2"),
])
def test_refused_before_the_work(args, says, tmp_path):
    args = [str(a).replace("{t}", str(tmp_path)) for a in args]
    p = run("synth", "--exemplar", JACKSBORO, "--size", "64x64", tmp_path / "out.tif", *args,
            check=False)
    assert p.returncode != 0 and says in p.stderr, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
    assert not os.listdir(tmp_path)


def test_km2_needs_ground_sizes(tmp_path):
    a = np.add.outer(np.arange(40.0), np.arange(50.0)).astype(np.float32)
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "n.tif"), 50, 40, 1,
                                              gdal.GDT_Float32)
    ds.GetRasterBand(1).WriteArray(a)
    ds = None
    p = run("ppa", tmp_path / "n.tif", tmp_path / "o.tif", "--flow-lines", tmp_path / "f.gpkg",
            "--flow-km2", 1, check=False)
    assert p.returncode != 0 and "no CRS" in p.stderr
    assert not (tmp_path / "o.tif").exists()
    run("ppa", tmp_path / "n.tif", tmp_path / "o.tif", "--flow-lines", tmp_path / "f.gpkg",
        "--flow-km2", 0.01, "--cell-size", 30, "-q")
    assert (tmp_path / "f.gpkg").exists()
