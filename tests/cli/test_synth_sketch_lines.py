# SPDX-License-Identifier: GPL-2.0-or-later
"""Sketches drawn as lines (`terrasynth synth --sketch LINES.gpkg`), against oracles that use
none of our code: the cells a line becomes against GDAL's rasterisation of the same layer; a
layer in another CRS against PROJ (osr) on its points; kinds and heights read from fields;
the graph's junctions where lines meet; a drawing painted and digitised giving the same
terrain figures; drawn valleys free of closed depressions (a plain numpy priority-flood);
the round trip from `ppa --lines`; recipes; the errors of bad layers."""
import heapq
import os

import numpy as np
import pytest
from osgeo import gdal, ogr, osr
from scipy import ndimage

from tsutil import FLOOR_REACH, JACKSBORO, run  # noqa: E402

gdal.UseExceptions()
ogr.UseExceptions()

W, H, RES = 260, 220, 90.0
ORIGIN = (650000.0, 4030000.0)
EPSG = 32616


def utm():
    s = osr.SpatialReference()
    s.ImportFromEPSG(EPSG)
    s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return s


def grid(path):
    """A raster whose grid the output takes (--like)."""
    ds = gdal.GetDriverByName("GTiff").Create(str(path), W, H, 1, gdal.GDT_Byte)
    ds.SetGeoTransform((ORIGIN[0], RES, 0, ORIGIN[1], 0, -RES))
    ds.SetProjection(utm().ExportToWkt())
    ds = None
    return path


def xy(col, row):
    """Cell coordinates (continuous) to the grid's CRS."""
    return ORIGIN[0] + col * RES, ORIGIN[1] - row * RES


# A drawing on the grid, in cell coordinates: a ridge with a spur (a T), a valley that crosses
# another valley (an X), a valley touching the ridge's end, and a river.
LINES = [
    ("ridge", [(20.3, 40.2), (120.6, 35.7), (235.1, 50.4)], None),
    ("ridge", [(120.6, 35.7), (130.2, 100.9)], None),
    ("valley", [(15.5, 130.5), (130.5, 150.5), (250.2, 140.1)], None),
    ("valley", [(60.4, 190.8), (110.7, 90.3)], None),
    ("river", [(200.2, 210.5), (190.3, 150.0)], None),
]


def write_lines(path, lines, srs=None, field="kind", height_field=None, geom3d=False,
                transform=None, layer="strokes"):
    drv = ogr.GetDriverByName("GPKG")
    if os.path.exists(path):
        drv.DeleteDataSource(str(path))
    ds = drv.CreateDataSource(str(path))
    lyr = ds.CreateLayer(layer, srs or utm(), ogr.wkbLineString25D if geom3d else ogr.wkbLineString)
    lyr.CreateField(ogr.FieldDefn(field, ogr.OFTString))
    if height_field:
        lyr.CreateField(ogr.FieldDefn(height_field, ogr.OFTReal))
    for kind, pts, z in lines:
        f = ogr.Feature(lyr.GetLayerDefn())
        f.SetField(field, kind)
        if height_field and z is not None:
            f.SetField(height_field, z)
        g = ogr.Geometry(ogr.wkbLineString25D if geom3d else ogr.wkbLineString)
        for c, r in pts:
            x, y = xy(c, r)
            if transform:
                x, y, _ = transform.TransformPoint(x, y)
            if geom3d:
                g.AddPoint(x, y, float(z))
            else:
                g.AddPoint_2D(x, y)
        f.SetGeometry(g)
        lyr.CreateFeature(f)
    ds = None
    return path


def graph_cells(gpkg, kind):
    """The cells of the sketch's feature graph of one kind (the debug GeoPackage: vertices at
    cell centres)."""
    ds = ogr.Open(str(gpkg))
    lyr = ds.GetLayerByName("paths")
    cells = np.zeros((H, W), bool)
    for f in lyr:
        if f.GetField("kind") != kind:
            continue
        g = f.GetGeometryRef()
        for i in range(g.GetPointCount()):
            x, y = g.GetX(i), g.GetY(i)
            cells[int((ORIGIN[1] - y) // RES), int((x - ORIGIN[0]) // RES)] = True
    return cells


def graph_nodes(gpkg):
    ds = ogr.Open(str(gpkg))
    out = []
    for f in ds.GetLayerByName("nodes"):
        g = f.GetGeometryRef()
        out.append((f.GetField("feature"), f.GetField("degree"), (g.GetX(), g.GetY())))
    return out


def rasterised(path, where, all_touched):
    ds = gdal.GetDriverByName("MEM").Create("", W, H, 1, gdal.GDT_Byte)
    ds.SetGeoTransform((ORIGIN[0], RES, 0, ORIGIN[1], 0, -RES))
    ds.SetProjection(utm().ExportToWkt())
    opts = ["ALL_TOUCHED=TRUE"] if all_touched else []
    src = ogr.Open(str(path))
    lyr = src.GetLayer(0)
    lyr.SetAttributeFilter(where)
    gdal.RasterizeLayer(ds, [1], lyr, burn_values=[1], options=opts)
    return ds.ReadAsArray() > 0


def dilate(m, r=1):
    out = m.copy()
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out |= np.roll(np.roll(m, dy, 0), dx, 1)
    return out


@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    d = tmp_path_factory.mktemp("lines")
    grid(d / "grid.tif")
    write_lines(d / "lines.gpkg", LINES)
    run("synth", "--sketch", d / "lines.gpkg", "--like", d / "grid.tif", "--exemplar", JACKSBORO,
        "--seed", "3", d / "out.tif", "--debug-dir", d / "debug", "-q")
    return d


def test_cells_against_gdal_rasterize(drawn):
    """Every cell of the graph lies on GDAL's all-touched rasterisation of its kind's lines
    (or within the 2 cells of snapping of it); every cell GDAL burns is next to a graph cell."""
    for kind, where in (("ridge", "kind = 'ridge'"), ("valley", "kind IN ('valley', 'river')")):
        cells = graph_cells(drawn / "debug" / "sketch_features.gpkg", kind)
        touched = rasterised(drawn / "lines.gpkg", where, True)
        burnt = rasterised(drawn / "lines.gpkg", where, False)
        assert cells.sum() > 100
        assert (cells & touched).sum() >= 0.97 * cells.sum(), kind
        assert not (cells & ~dilate(touched, 2)).any(), kind
        assert not (burnt & ~dilate(cells, 1)).any(), kind


def test_junctions_where_lines_meet(drawn):
    """The spur meets the ridge (a degree-3 ridge node); the two valleys cross (degree 4); the
    river is a valley of its own; a ridge never joins a valley."""
    nodes = graph_nodes(drawn / "debug" / "sketch_features.gpkg")
    ridge_deg = sorted(d for k, d, _ in nodes if k == "ridge")
    valley_deg = sorted(d for k, d, _ in nodes if k == "valley")
    assert ridge_deg == [1, 1, 1, 3], ridge_deg
    assert valley_deg.count(4) == 1 and valley_deg.count(1) == 6, valley_deg


def test_crs_transformed_with_proj(tmp_path, drawn):
    """The same lines stored in EPSG:4326: the graph's end nodes land within a cell of the
    ends transformed by PROJ (osr), which the test itself does."""
    geo = osr.SpatialReference()
    geo.ImportFromEPSG(4326)
    geo.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ct = osr.CoordinateTransformation(utm(), geo)
    write_lines(tmp_path / "geo.gpkg", LINES, srs=geo, transform=ct)
    run("synth", "--sketch", tmp_path / "geo.gpkg", "--like", drawn / "grid.tif", "--exemplar",
        JACKSBORO, "--seed", "3", tmp_path / "o.tif", "--debug-dir", tmp_path / "dbg", "-q")
    ends = [xy(*pts[i]) for _, pts, _ in LINES for i in (0, -1)]
    nodes = [p for _, deg, p in graph_nodes(tmp_path / "dbg" / "sketch_features.gpkg")]
    for e in ends:
        if not (0 <= e[0] - ORIGIN[0] < W * RES and 0 <= ORIGIN[1] - e[1] < H * RES):
            continue
        near = min(np.hypot(e[0] - n[0], e[1] - n[1]) for n in nodes)
        assert near <= 1.5 * RES, (e, near)
    for kind in ("ridge", "valley"):  # the same cells as the lines drawn in the grid's CRS
        a = graph_cells(tmp_path / "dbg" / "sketch_features.gpkg", kind)
        b = graph_cells(drawn / "debug" / "sketch_features.gpkg", kind)
        assert (a & b).sum() >= 0.98 * max(a.sum(), b.sum()), kind


def test_kind_field_and_heights(tmp_path, drawn):
    """--kind-field names the field; --height-field gives a ridge its height: the output
    along it comes within a tenth of the exemplar's range of the wanted height."""
    e = gdal.Open(JACKSBORO).ReadAsArray().astype(float)
    want = float(np.percentile(e, 90))
    lines = [(k, p, want if k == "ridge" else None) for k, p, _ in LINES]
    write_lines(tmp_path / "h.gpkg", lines, field="what", height_field="alt")
    run("synth", "--sketch", tmp_path / "h.gpkg", "--kind-field", "what", "--height-field", "alt",
        "--like", drawn / "grid.tif", "--exemplar", JACKSBORO, "--seed", "3", tmp_path / "o.tif",
        "--debug-dir", tmp_path / "dbg", "-q")
    z = gdal.Open(str(tmp_path / "o.tif")).ReadAsArray().astype(float)
    ridge = graph_cells(tmp_path / "dbg" / "sketch_features.gpkg", "ridge")
    base = gdal.Open(str(drawn / "out.tif")).ReadAsArray().astype(float)
    rng = np.percentile(e, 95) - np.percentile(e, 5)
    assert abs(z[ridge].mean() - want) <= 0.1 * rng, (z[ridge].mean(), want)
    assert abs(z[ridge].mean() - want) < abs(base[ridge].mean() - want)
    # Z values do the same when no field is named (the valleys drawn at the 20th percentile)
    low = float(np.percentile(e, 20))
    write_lines(tmp_path / "z.gpkg", [(k, p, want if k == "ridge" else low) for k, p, _ in LINES],
                geom3d=True)
    run("synth", "--sketch", tmp_path / "z.gpkg", "--like", drawn / "grid.tif", "--exemplar",
        JACKSBORO, "--seed", "3", tmp_path / "oz.tif", "-q")
    zz = gdal.Open(str(tmp_path / "oz.tif")).ReadAsArray().astype(float)
    assert abs(zz[ridge].mean() - want) <= 0.1 * rng


def priority_flood(z):
    """Filled heights: each cell raised to the lowest level at which water leaves the grid
    (plain priority-flood from the edge)."""
    h, w = z.shape
    f = z.copy()
    seen = np.zeros(z.shape, bool)
    q = []
    for y in range(h):
        for x in range(w):
            if y in (0, h - 1) or x in (0, w - 1):
                heapq.heappush(q, (f[y, x], y, x))
                seen[y, x] = True
    while q:
        v, y, x = heapq.heappop(q)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                ny, nx = y + dy, x + dx
                if 0 <= ny < h and 0 <= nx < w and not seen[ny, nx]:
                    seen[ny, nx] = True
                    f[ny, nx] = max(f[ny, nx], v)
                    heapq.heappush(q, (f[ny, nx], ny, nx))
    return f


def test_drawn_valleys_hold_no_closed_depression(drawn):
    """Water on a drawn valley's floor runs off the grid: beside every valley cell of the graph
    (within the floor's reach) a cell lies in no closed depression (filled minus output > 0),
    on any of three seeds; on the first, every cell of the floor --debug-dir marks drains."""
    z = gdal.Open(str(drawn / "out.tif")).ReadAsArray().astype(float)
    valley = graph_cells(drawn / "debug" / "sketch_features.gpkg", "valley")
    held = priority_flood(z) - z
    dep = ndimage.minimum_filter(held, size=2 * FLOOR_REACH + 1)
    assert (dep[valley] > 0.01).mean() <= 0.01, (dep[valley] > 0.01).mean()
    # the floor itself (--debug-dir valley_floor.tif): every cell of it drains, it lies within
    # its reach of the drawn valleys and runs along all of them
    floor = gdal.Open(str(drawn / "debug" / "valley_floor.tif")).ReadAsArray() == 1
    assert floor.sum() > 0.5 * valley.sum(), (floor.sum(), valley.sum())
    assert (held[floor] > 0.01).sum() == 0, np.argwhere(floor & (held > 0.01))[:5]
    off = ndimage.distance_transform_edt(~valley)
    assert off[floor].max() <= FLOOR_REACH + 1, off[floor].max()
    near = ndimage.distance_transform_edt(~floor)
    assert (near[valley] <= FLOOR_REACH + 1).mean() >= 0.95, (near[valley] <= FLOOR_REACH + 1).mean()
    for seed in (4, 5):
        run("synth", "--sketch", drawn / "lines.gpkg", "--like", drawn / "grid.tif", "--exemplar",
            JACKSBORO, "--seed", str(seed), drawn / f"s{seed}.tif", "-q")
        z = gdal.Open(str(drawn / f"s{seed}.tif")).ReadAsArray().astype(float)
        dep = ndimage.minimum_filter(priority_flood(z) - z, size=2 * FLOOR_REACH + 1)
        assert (dep[valley] > 0.01).mean() <= 0.01, (seed, (dep[valley] > 0.01).mean())


def test_ridges_stand_valleys_sink(drawn):
    """Along the drawn ridges the land is higher than a few cells beside them, along the drawn
    valleys lower (the layout of both kinds at once)."""
    z = gdal.Open(str(drawn / "out.tif")).ReadAsArray().astype(float)
    g = drawn / "debug" / "sketch_features.gpkg"
    for kind, sign in (("ridge", 1), ("valley", -1)):
        c = graph_cells(g, kind)
        ring = dilate(c, 6) & ~dilate(c, 3)
        assert sign * (z[c].mean() - z[ring].mean()) > 0, kind


def test_painted_and_digitised_alike(tmp_path, drawn):
    """The same drawing painted (the lines burnt brighter and darker than a grey ground, soft
    brush) gives the terrain the same figures: ridges higher and valleys lower than beside
    them by similar amounts."""
    ridges = rasterised(drawn / "lines.gpkg", "kind = 'ridge'", False)
    valleys = rasterised(drawn / "lines.gpkg", "kind IN ('valley', 'river')", False)
    from scipy import ndimage
    img = 128 + 127 * np.clip(1 - ndimage.distance_transform_edt(~ridges) / 4, 0, 1) \
        - 128 * np.clip(1 - ndimage.distance_transform_edt(~valleys) / 4, 0, 1)
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "painted.tif"), W, H, 1, gdal.GDT_Byte)
    ds.SetGeoTransform((ORIGIN[0], RES, 0, ORIGIN[1], 0, -RES))
    ds.SetProjection(utm().ExportToWkt())
    ds.GetRasterBand(1).WriteArray(np.clip(img, 0, 255).astype(np.uint8))
    ds = None
    p = run("synth", "--sketch", tmp_path / "painted.tif", "--exemplar", JACKSBORO, "--seed", "3",
            tmp_path / "p.tif")
    assert "ridges and valleys" in p.stdout
    zp = gdal.Open(str(tmp_path / "p.tif")).ReadAsArray().astype(float)
    zl = gdal.Open(str(drawn / "out.tif")).ReadAsArray().astype(float)
    for m, sign in ((ridges, 1), (valleys, -1)):
        ring = dilate(m, 6) & ~dilate(m, 3)
        sp, sl = sign * (zp[m].mean() - zp[ring].mean()), sign * (zl[m].mean() - zl[ring].mean())
        assert sp > 0 and sl > 0 and 0.5 < sp / sl < 2.0, (sp, sl)


def test_grid_from_resolution_and_recipe(tmp_path, drawn):
    """--resolution: the lines' box grown by a patch, on the resolution's lattice, in the
    layer's CRS; the recipe gives the same cells through GDAL."""
    out = tmp_path / "r.tif"
    run("synth", "--sketch", drawn / "lines.gpkg", "--resolution", "90", "--exemplar", JACKSBORO,
        "--seed", "3", out, "-q")
    ds = gdal.Open(str(out))
    gt = ds.GetGeoTransform()
    assert gt[1] == 90 and gt[0] % 90 == 0 and gt[3] % 90 == 0
    xs = [xy(*p)[0] for _, pts, _ in LINES for p in pts]
    assert gt[0] <= min(xs) - 64 * 90 + 90 and gt[0] + ds.RasterXSize * 90 >= max(xs) + 64 * 90 - 90
    assert osr.SpatialReference(wkt=ds.GetProjection()).GetAuthorityCode(None) == str(EPSG)
    run("synth", "--sketch", drawn / "lines.gpkg", "--resolution", "90", "--exemplar", JACKSBORO,
        "--seed", "3", "--recipe", tmp_path / "r.tsyn")
    from tsutil import plugin_env
    import subprocess
    plugins = os.environ.get("TS_GDAL_PLUGINS",
                             os.path.join(os.path.dirname(__file__), "..", "..", "build",
                                          "gdalplugins"))
    subprocess.run(["gdal_translate", "-q", str(tmp_path / "r.tsyn"), str(tmp_path / "rr.tif")],
                   check=True, env=plugin_env(plugins), timeout=600)
    assert np.array_equal(gdal.Open(str(tmp_path / "rr.tif")).ReadAsArray(), ds.ReadAsArray())


def log_recall(z, drawn, kind, patch):
    """Share of the drawn cells within patch/8 of the strongest 8 % of the output's
    curvature of that kind (Laplacian of Gaussian at patch/8): the yardstick's feature
    recall, without the skeleton."""
    from scipy import ndimage
    log = ndimage.gaussian_laplace(z, max(2.0, patch / 8.0))
    feat = -log if kind == 1 else log
    strong = feat > np.percentile(feat, 92)
    return float((ndimage.distance_transform_edt(~strong)[drawn] <= patch / 8.0).mean())


def test_round_trip_from_ppa_lines(tmp_path):
    """`ppa --lines` of a real DEM (its main axes), then those lines as the sketch of a new
    terrain on the DEM's grid: the new terrain's strongest ridges and valleys lie on the
    mapped ones far more often than a free synthesis's do."""
    run("ppa", JACKSBORO, tmp_path / "axes.tif", "--both", "--lines", tmp_path / "axes.gpkg",
        "--min-branch-length", "5000m", "--profile-length", "15", "--threshold-fraction", "0.03",
        "-q")
    run("synth", "--sketch", tmp_path / "axes.gpkg", "--like", JACKSBORO, "--exemplar", JACKSBORO,
        "--patch-size", "32", "--seed", "5", tmp_path / "new.tif", "-q")
    run("synth", "--like", JACKSBORO, "--exemplar", JACKSBORO, "--patch-size", "32", "--seed", "5",
        tmp_path / "free.tif", "-q")
    a = gdal.Open(str(tmp_path / "axes.tif")).ReadAsArray()
    new = gdal.Open(str(tmp_path / "new.tif")).ReadAsArray().astype(float)
    free = gdal.Open(str(tmp_path / "free.tif")).ReadAsArray().astype(float)
    for bit in (1, 2):
        drawn = (a != 255) & ((a & bit) > 0)
        assert drawn.sum() > 200
        got, base = log_recall(new, drawn, bit, 32), log_recall(free, drawn, bit, 32)
        assert got >= base + 0.12, (bit, got, base)


@pytest.mark.parametrize("case,fragment", [
    ("nokind", "has no field \"kind\""),
    ("badkind", "not ridge, valley or river"),
    ("empty", "holds no lines"),
    ("outside", "no line crosses the output grid"),
    ("points", "no layer of lines"),
    ("polygons", "no layer of lines"),
    ("selfcross", "crosses itself"),
    ("badlayer", "has no layer \"nope\""),
    ("engineering", "cannot be transformed to the output's"),
])
def test_bad_layers(tmp_path, drawn, case, fragment):
    """A bad layer: a one-line error naming the file, nothing written."""
    p = tmp_path / f"{case}.gpkg"
    extra = []
    if case == "nokind":
        write_lines(p, LINES, field="type")
    elif case == "badkind":
        write_lines(p, [("crest", LINES[0][1], None)])
    elif case == "empty":
        write_lines(p, [])
    elif case == "outside":
        write_lines(p, [("ridge", [(-500.0, -500.0), (-400.0, -450.0)], None)])
    elif case in ("points", "polygons"):
        ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(p))
        gt = ogr.wkbPoint if case == "points" else ogr.wkbPolygon
        lyr = ds.CreateLayer("x", utm(), gt)
        lyr.CreateField(ogr.FieldDefn("kind", ogr.OFTString))
        f = ogr.Feature(lyr.GetLayerDefn())
        f.SetField("kind", "ridge")
        f.SetGeometry(ogr.CreateGeometryFromWkt(
            "POINT (655000 4020000)" if case == "points" else
            "POLYGON ((655000 4020000,656000 4020000,656000 4021000,655000 4020000))"))
        lyr.CreateFeature(f)
        ds = None
    elif case == "selfcross":
        write_lines(p, [("valley", [(10, 10), (100, 100), (100, 10), (10, 100)], None)])
    elif case == "badlayer":
        write_lines(p, LINES)
        extra = ["--sketch-layer", "nope"]
    elif case == "engineering":
        eng = osr.SpatialReference()
        eng.SetFromUserInput('ENGCRS["site",EDATUM["site"],CS[Cartesian,2],'
                             'AXIS["x",east,ORDER[1],LENGTHUNIT["metre",1]],'
                             'AXIS["y",north,ORDER[2],LENGTHUNIT["metre",1]]]')
        write_lines(p, LINES, srs=eng)
    r = run("synth", "--sketch", p, "--like", drawn / "grid.tif", "--exemplar", JACKSBORO,
            tmp_path / "o.tif", *extra, check=False)
    assert r.returncode == 1, r.stderr
    assert fragment in r.stderr and str(p) in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o.tif").exists()


def test_grid_rules(tmp_path, drawn):
    """A painted sketch sets the grid; lines need one."""
    r = run("synth", "--sketch", drawn / "grid.tif", "--resolution", "30", "--exemplar",
            JACKSBORO, tmp_path / "o.tif", check=False)
    assert r.returncode == 1 and "a painted sketch sets the output grid: give no resolution" \
        in r.stderr
    r = run("synth", "--sketch", drawn / "lines.gpkg", "--exemplar", JACKSBORO,
            tmp_path / "o.tif", check=False)
    assert r.returncode == 1 and "needs the output grid" in r.stderr
    r = run("synth", "--sketch", drawn / "lines.gpkg", "--size", "64x64", "--exemplar", JACKSBORO,
            tmp_path / "o.tif", check=False)
    assert r.returncode == 2 and "give no size" in r.stderr


def test_valleys_drain_into_a_lake(tmp_path):
    """A lake (--water) is an outlet as the grid's edge is: valleys drawn down to a lake in
    the middle of the map end in it and hold no closed depression when water leaves by the
    edge or the lake (numpy priority-flood seeded from both), and the land beside the lake
    stays at or above its level."""
    grid(tmp_path / "grid.tif")
    cx, cy, r = 130, 110, 18
    yy, xx = np.mgrid[0:H, 0:W]
    lake = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "lake.tif"), W, H, 1, gdal.GDT_Byte)
    ds.SetGeoTransform((ORIGIN[0], RES, 0, ORIGIN[1], 0, -RES))
    ds.SetProjection(utm().ExportToWkt())
    ds.GetRasterBand(1).WriteArray(lake.astype(np.uint8))
    ds = None
    valleys = [[(130.4, 25.6), (128.2, 70.3), (130.5, 93.0)],
               [(40.3, 60.2), (85.5, 90.7), (113.2, 104.6)],
               [(215.7, 170.4), (170.3, 140.2), (145.1, 121.5)]]
    lines = [("valley", v, None) for v in valleys]
    lines += [("ridge", [(60.2, 20.5), (100.7, 45.3), (95.2, 80.1)], None),
              ("ridge", [(200.6, 30.3), (170.4, 70.8), (165.3, 95.6)], None),
              ("ridge", [(60.5, 190.2), (110.3, 165.5)], None)]
    write_lines(tmp_path / "lines.gpkg", lines)
    level = 260.0  # below the land around the lake, as a lake is
    for seed in (1, 2):
        out = tmp_path / ("o%d.tif" % seed)
        run("synth", "--sketch", tmp_path / "lines.gpkg", "--like", tmp_path / "grid.tif",
            "--exemplar", JACKSBORO, "--water", tmp_path / "lake.tif", "--water-level", level,
            "--seed", seed, out, "--debug-dir", tmp_path / ("d%d" % seed), "-q")
        z = gdal.Open(str(out)).ReadAsArray().astype(float)
        assert np.all(z[lake] == level)
        # the banks: every land cell beside the lake at or above its level
        beside = dilate(lake) & ~lake
        assert z[beside].min() >= level - 1e-3, z[beside].min()
        # water leaves by the edge or into the lake: the flood starts from both
        f = z.copy()
        seen = lake.copy()
        q = [(z[y, x], y, x) for y, x in zip(*np.nonzero(lake))]
        for y in range(H):
            for x in range(W):
                if (y in (0, H - 1) or x in (0, W - 1)) and not seen[y, x]:
                    q.append((z[y, x], y, x))
                    seen[y, x] = True
        heapq.heapify(q)
        while q:
            v, y, x = heapq.heappop(q)
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    ny, nx = y + dy, x + dx
                    if 0 <= ny < H and 0 <= nx < W and not seen[ny, nx]:
                        seen[ny, nx] = True
                        f[ny, nx] = max(f[ny, nx], v)
                        heapq.heappush(q, (f[ny, nx], ny, nx))
        valley = graph_cells(tmp_path / ("d%d" % seed) / "sketch_features.gpkg", "valley")
        dep = ndimage.minimum_filter(f - z, size=2 * FLOOR_REACH + 1)
        assert (dep[valley & ~lake] > 0.01).mean() <= 0.01, (seed, (dep[valley] > 0.01).mean())
        # each valley's floor (the lowest land within its reach of the line) comes down to
        # the lake: where the line meets the lake it is within 6 m of its lowest (a valley
        # whose floor the lake's arm keeps at its level runs flat, a few metres either way:
        # the third valley's over seeds 1-12 up to 5.2 m)
        zf = ndimage.minimum_filter(np.where(lake, np.inf, z), size=2 * FLOOR_REACH + 1)
        ring = np.hypot(*np.mgrid[0:H, 0:W][::-1] - np.array([cx, cy])[:, None, None]) <= r + 5
        for v in valleys:
            path = rasterised_line(v) & ~lake
            at_lake = zf[path & ring].min()
            assert at_lake <= zf[path].min() + 6.0, (seed, v[0], at_lake, zf[path].min())


def rasterised_line(pts):
    """The cells a polyline (cell coordinates) passes, densely sampled."""
    m = np.zeros((H, W), bool)
    for (c0, r0), (c1, r1) in zip(pts[:-1], pts[1:]):
        n = int(max(abs(c1 - c0), abs(r1 - r0)) * 4) + 1
        for t in np.linspace(0, 1, n):
            m[int(r0 + t * (r1 - r0)), int(c0 + t * (c1 - c0))] = True
    return m
