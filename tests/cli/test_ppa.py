# SPDX-License-Identifier: GPL-2.0-or-later
"""End-to-end tests of `terrasynth ppa`: outputs read back with GDAL/OGR,
errors, determinism, and real DEMs from ../shared/data/dem when present."""
import os

import numpy as np
import pytest
from osgeo import gdal, ogr, osr

from tsutil import DATA, JACKSBORO, SHARED, run  # noqa: E402

gdal.UseExceptions()


def read(path):
    ds = gdal.Open(str(path))
    return ds, ds.GetRasterBand(1).ReadAsArray()


def write_tif(path, arr, nodata=None, srs="EPSG:32611", gt=(400000, 30, 0, 3800000, 0, -30), unit=None):
    drv = gdal.GetDriverByName("GTiff")
    dt = gdal.GDT_Float32 if arr.dtype.kind == "f" else gdal.GDT_Int16
    ds = drv.Create(str(path), arr.shape[1], arr.shape[0], 1, dt)
    if gt is not None:
        ds.SetGeoTransform(gt)
    if srs:
        s = osr.SpatialReference()
        s.SetFromUserInput(srs)
        ds.SetProjection(s.ExportToWkt())
    b = ds.GetRasterBand(1)
    if nodata is not None:
        b.SetNoDataValue(nodata)
    if unit:
        b.SetUnitType(unit)
    b.WriteArray(arr)
    ds = None


def local_relief(z, r=7):
    """z minus the mean of the valid cells of its (2r+1)^2 neighbourhood; NaN = nodata."""
    valid = ~np.isnan(z)

    def box(a):
        p = np.pad(a, r)
        c = np.pad(np.cumsum(np.cumsum(p, 0), 1), ((1, 0), (1, 0)))
        k = 2 * r + 1
        return c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]

    n = box(valid.astype(np.float64))
    s = box(np.where(valid, z, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return z - s / n


def same_crs(a, b):
    return a.IsSame(b, ["IGNORE_DATA_AXIS_TO_SRS_AXIS_MAPPING=YES"])


def leftovers(d):
    return [f for f in os.listdir(d) if ".tmp" in f]


# ---------------------------------------------------------------- help


def test_help_lists_parameters_with_defaults():
    p = run("ppa", "--help")
    for flag in ("--profile-length", "--threshold", "--threshold-fraction", "--min-branch-length",
                 "--lines", "--preview", "-of", "-co", "--ridges", "--valleys", "--both", "-q"):
        assert flag in p.stdout
    assert "default 11" in p.stdout
    assert "--pin" not in p.stdout and "--sketch" not in p.stdout  # synth's options only
    top = run("--help")
    assert "ppa" in top.stdout


# ---------------------------------------------------------------- main run


@pytest.fixture(scope="module")
def jacksboro_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("jb")
    out, lines, png = d / "axes.tif", d / "axes.gpkg", d / "axes.png"
    p = run("ppa", JACKSBORO, out, "--both", "--lines", lines, "--preview", png)
    return d, out, lines, png, p


def test_raster_output_keeps_grid_and_codes(jacksboro_run):
    d, out, _, _, p = jacksboro_run
    src, z = read(JACKSBORO)
    ds, a = read(out)
    assert ds.RasterXSize == src.RasterXSize and ds.RasterYSize == src.RasterYSize
    assert ds.GetGeoTransform() == pytest.approx(src.GetGeoTransform())
    assert same_crs(osr.SpatialReference(ds.GetProjection()), osr.SpatialReference(src.GetProjection()))
    assert ds.GetRasterBand(1).DataType == gdal.GDT_Byte
    assert ds.GetRasterBand(1).GetNoDataValue() == 255
    assert set(np.unique(a)) <= {0, 1, 2, 3}
    ridge, valley = (a & 1) > 0, (a & 2) > 0
    assert ridge.sum() > 500 and valley.sum() > 500
    # ridges sit above their surroundings, valleys below: the axes follow the terrain
    rel = local_relief(z.astype(np.float64))
    assert rel[ridge].mean() > 5.0
    assert rel[valley].mean() < -5.0
    assert "ridge paths" in p.stdout
    assert not leftovers(d)


def test_vector_output(jacksboro_run):
    _, out, lines, _, _ = jacksboro_run
    ds = ogr.Open(str(lines))
    paths, nodes = ds.GetLayerByName("paths"), ds.GetLayerByName("nodes")
    assert paths is not None and nodes is not None
    assert paths.GetFeatureCount() > 10 and nodes.GetFeatureCount() > 10
    assert same_crs(paths.GetSpatialRef(), osr.SpatialReference(gdal.Open(JACKSBORO).GetProjection()))
    kinds = set()
    a = gdal.Open(str(out)).ReadAsArray()
    gt = gdal.Open(str(out)).GetGeoTransform()
    for f in paths:
        kinds.add(f.GetField("kind"))
        assert f.GetField("length_m") > 0
        assert f.GetField("min_elev") <= f.GetField("mean_elev") <= f.GetField("max_elev")
        assert f.GetField("start_kind") in ("endpoint", "branch")
        g = f.GetGeometryRef()
        assert g.GetPointCount() >= 2
        # every vertex lies on a feature cell of the raster
        for i in range(g.GetPointCount()):
            col = int((g.GetX(i) - gt[0]) / gt[1])
            row = int((g.GetY(i) - gt[3]) / gt[5])
            bit = 1 if f.GetField("kind") == "ridge" else 2
            assert a[row, col] & bit
    assert kinds == {"ridge", "valley"}
    for f in nodes:
        assert f.GetField("kind") in ("endpoint", "branch")
        assert (f.GetField("degree") == 1) == (f.GetField("kind") == "endpoint")


def test_preview_png(jacksboro_run):
    _, _, _, png, _ = jacksboro_run
    ds = gdal.Open(str(png))
    assert ds.GetDriver().ShortName == "PNG"
    assert ds.RasterCount == 3
    rgb = ds.ReadAsArray()
    red = (rgb[0] == 230) & (rgb[1] == 30) & (rgb[2] == 30)
    blue = (rgb[0] == 20) & (rgb[1] == 80) & (rgb[2] == 240)
    assert red.sum() > 100 and blue.sum() > 100
    assert rgb.std() > 20  # a shaded relief, not a flat image


def test_deterministic_bytes(tmp_path):
    a, b = tmp_path / "a.tif", tmp_path / "b.tif"
    run("ppa", JACKSBORO, a, "--both", "-q", "--threads", "1")
    run("ppa", JACKSBORO, b, "--both", "-q", "--threads", "2")
    assert gdal.Open(str(a)).ReadAsArray().tobytes() == gdal.Open(str(b)).ReadAsArray().tobytes()


def test_metres_and_cells_branch_length(tmp_path):
    short, long_ = tmp_path / "s.tif", tmp_path / "l.tif"
    run("ppa", JACKSBORO, short, "-q", "--min-branch-length", "300m")
    run("ppa", JACKSBORO, long_, "-q", "--min-branch-length", "3000m")
    assert (read(short)[1] == 1).sum() > (read(long_)[1] == 1).sum() > 0


def test_other_formats_and_creation_options(tmp_path):
    run("ppa", JACKSBORO, tmp_path / "a.img", "-q", "-of", "HFA")
    assert gdal.Open(str(tmp_path / "a.img")).GetDriver().ShortName == "HFA"
    run("ppa", JACKSBORO, tmp_path / "c.tif", "-q", "-co", "COMPRESS=DEFLATE")
    md = gdal.Open(str(tmp_path / "c.tif")).GetMetadata("IMAGE_STRUCTURE")
    assert md.get("COMPRESSION") == "DEFLATE"
    run("ppa", JACKSBORO, tmp_path / "x.tif", "-q", "--lines", tmp_path / "x.geojson")
    assert ogr.Open(str(tmp_path / "x.geojson")).GetLayer(0).GetFeatureCount() > 0


def test_progress_lines(tmp_path):
    p = run("ppa", JACKSBORO, tmp_path / "o.tif", "--progress-lines", "--both")
    pcts = [int(l.split()[1]) for l in p.stdout.splitlines() if l.startswith("PROGRESS ")]
    assert pcts and pcts == sorted(pcts) and pcts[-1] == 100


def test_nodata_round_trip(tmp_path):
    src = gdal.Open(JACKSBORO).ReadAsArray().astype(np.float32)
    src[100:150, 100:200] = -9999
    src[10, 10] = np.nan
    inp = tmp_path / "holes.tif"
    write_tif(inp, src, nodata=-9999, srs="EPSG:4326", gt=gdal.Open(JACKSBORO).GetGeoTransform())
    run("ppa", inp, tmp_path / "o.tif", "--both", "-q")
    a = read(tmp_path / "o.tif")[1]
    assert (a[100:150, 100:200] == 255).all() and a[10, 10] == 255
    assert ((a != 255) | (src == -9999) | np.isnan(src)).all()


def test_no_crs_works_in_cells_and_says_so(tmp_path):
    z = gdal.Open(JACKSBORO).ReadAsArray().astype(np.float32)
    inp = tmp_path / "nocrs.tif"
    write_tif(inp, z, srs=None, gt=None)
    p = run("ppa", inp, tmp_path / "o.tif")
    assert p.stderr.count("no CRS") == 1
    assert (read(tmp_path / "o.tif")[1] == 1).sum() > 100
    p = run("ppa", inp, tmp_path / "m.tif", "--min-branch-length", "500m", check=False)
    assert p.returncode != 0 and "no CRS" in p.stderr
    run("ppa", inp, tmp_path / "m.tif", "-q", "--min-branch-length", "500m", "--cell-size", "90")


# ---------------------------------------------------------------- errors


def make_bad_inputs(d):
    (d / "notaraster.tif").write_text("this is not a raster\n")
    write_tif(d / "allnodata.tif", np.full((20, 20), -9999, np.float32), nodata=-9999)
    write_tif(d / "allnan.tif", np.full((20, 20), np.nan, np.float32))
    write_tif(d / "rotated.tif", np.ones((20, 20), np.float32), gt=(0, 30, 5, 0, 5, -30))
    write_tif(d / "tiny.tif", np.ones((1, 1), np.float32))


@pytest.mark.parametrize(
    "inp,args,words",
    [
        ("missing.tif", [], "no such file"),
        ("notaraster.tif", [], "not"),
        ("allnodata.tif", [], "nodata"),
        ("allnan.tif", [], "nodata"),
        ("rotated.tif", [], "rotated"),
        ("tiny.tif", [], "2 x 2"),
        ("JB", ["--profile-length", "4"], "odd"),
        ("JB", ["--profile-length", "100000"], "out of range"),
        ("JB", ["--threshold", "-5"], "out of range"),
        ("JB", ["--threshold-fraction", "7"], "out of range"),
        ("JB", ["--threshold", "1", "--threshold-fraction", "0.1"], "not both"),
        ("JB", ["--min-branch-length", "12furlongs"], "unit"),
        ("JB", ["--threads", "abc"], "--threads"),
        ("JB", ["--bogus"], "unknown option"),
        ("JB", ["-of", "NoSuchFormat"], "NoSuchFormat"),
        ("JB", ["-co", "BOGUS=1"], "BOGUS"),
        ("JB", ["--lines", "x.unknownext"], "extension"),
    ],
)
def test_errors_are_one_line_and_leave_nothing(tmp_path, inp, args, words):
    make_bad_inputs(tmp_path)
    src = JACKSBORO if inp == "JB" else tmp_path / inp
    out = tmp_path / "out.tif"
    before = set(os.listdir(tmp_path))
    p = run("ppa", src, out, *[tmp_path / a if a.startswith("x.") else a for a in args], "-q",
            check=False)
    assert p.returncode != 0
    err = p.stderr.strip()
    assert err.count("\n") == 0, err
    assert words.lower() in err.lower(), err
    assert set(os.listdir(tmp_path)) == before, "an output was left behind"


def test_missing_output_directory(tmp_path):
    p = run("ppa", JACKSBORO, tmp_path / "nodir" / "o.tif", check=False)
    assert p.returncode != 0 and "does not exist" in p.stderr
    assert p.stderr.strip().count("\n") == 0


def test_usage_errors_exit_2():
    assert run("ppa", check=False).returncode == 2
    assert run("nosuchcommand", check=False).returncode == 2


# ---------------------------------------------------------------- real DEMs

SHARED_DEMS = sorted(f for f in os.listdir(SHARED) if f.endswith(".tif")) if os.path.isdir(SHARED) else []


@pytest.mark.matrix
@pytest.mark.skipif(not SHARED_DEMS, reason="../shared/data/dem not present")
@pytest.mark.parametrize("name", [n for n in SHARED_DEMS if "etopo5" not in n] or ["none"])
def test_real_dem_axes_follow_terrain(tmp_path, name):
    src = os.path.join(SHARED, name)
    out, lines, png = tmp_path / "o.tif", tmp_path / "o.gpkg", tmp_path / "o.png"
    run("ppa", src, out, "--both", "--lines", lines, "--preview", png, "-q")
    ds = gdal.Open(src)
    z = ds.GetRasterBand(1).ReadAsArray().astype(np.float64)
    nd = ds.GetRasterBand(1).GetNoDataValue()
    a = read(out)[1]
    if nd is not None:
        assert (a[z == nd] == 255).all()
        z[z == nd] = np.nan
    ridge, valley = (a != 255) & ((a & 1) > 0), (a != 255) & ((a & 2) > 0)
    assert ridge.sum() > 200 and valley.sum() > 200
    rel = local_relief(z)
    assert np.nanmean(rel[ridge]) > 0 and np.nanmean(rel[valley]) < 0
    assert ogr.Open(str(lines)).GetLayerByName("paths").GetFeatureCount() > 10
    assert gdal.Open(str(png)).RasterCount == 3


def test_describe_json_matches_help():
    import json
    d = json.loads(run("describe").stdout)
    assert set(d["stages"]) >= {"ppa", "synth"}
    for stage, params in d["stages"].items():
        helptext = run("synth" if stage in ("sketch", "drainage") else stage, "--help").stdout
        for p in params:
            assert p["flag"] == "--" + p["name"].replace("_", "-")
            assert p["min"] <= p["default"] <= p["max"]
            if stage != "ppa" or p["name"] != "features":  # ppa spells features as --ridges etc.
                assert p["flag"] in helptext, (stage, p["flag"])
                # the help's default and range are the declaration's
                lines = helptext.splitlines()
                at = next(i for i, ln in enumerate(lines)
                          if ln.strip().startswith(p["flag"] + " "))
                said = next(ln.strip() for ln in lines[at + 1:] if ln.strip().startswith("default"))
                if p["type"] == "enum":
                    assert said == "default " + p["choices"][int(p["default"])], (p, said)
                else:
                    assert said.startswith("default %g" % p["default"]), (p, said)
                    assert ", range %g..%g" % (p["min"], p["max"]) in said, (p, said)
    one = json.loads(run("describe", "ppa").stdout)
    assert list(one["stages"]) == ["ppa"]
    assert run("describe", "nosuchstage", check=False).returncode == 2


# ---------------------------------------------------------------- in tiles


def test_tiles_give_the_raster_of_one_piece(tmp_path):
    """--tile-size: the same cells as the run in one piece (the oracle), with nodata across
    tile borders, a geographic grid (metres per row) and a branch length in metres."""
    z = gdal.Open(JACKSBORO).ReadAsArray().astype(np.float32)
    z[120:170, 90:260] = -9999
    inp = tmp_path / "holes.tif"
    write_tif(inp, z, nodata=-9999, srs="EPSG:4326", gt=gdal.Open(JACKSBORO).GetGeoTransform())
    whole = tmp_path / "whole.tif"
    run("ppa", inp, whole, "--both", "-q", "--min-branch-length", "600m")
    ref = read(whole)[1]
    assert (ref == 1).sum() > 500 and (ref == 2).sum() > 500 and (ref == 255).sum() == 50 * 170
    for tile in ("100", "64", "37"):  # 4 x 4 tiles and more, uneven last tiles
        out = tmp_path / ("t%s.tif" % tile)
        p = run("ppa", inp, out, "--both", "--min-branch-length", "600m", "--tile-size", tile)
        assert "tiles of %s cells" % tile in p.stdout
        ds, a = read(out)
        assert np.array_equal(a, ref), "tile %s: %d cells differ" % (tile, (a != ref).sum())
        assert ds.GetGeoTransform() == gdal.Open(str(whole)).GetGeoTransform()
        assert ds.GetRasterBand(1).GetNoDataValue() == 255
    assert not leftovers(tmp_path)


def test_tiles_give_the_channels_of_one_piece(tmp_path):
    """The defaults (valleys where the water runs: the drainage routed over the whole DEM before
    the tiles) in tiles: the cells of the run in one piece."""
    whole = tmp_path / "whole.tif"
    run("ppa", JACKSBORO, whole, "--both", "-q")
    ref = read(whole)[1]
    assert (ref & 2).sum() > 300
    for tile in ("100", "41"):
        out = tmp_path / ("t%s.tif" % tile)
        run("ppa", JACKSBORO, out, "--both", "-q", "--tile-size", tile)
        a = read(out)[1]
        assert np.array_equal(a, ref), "tile %s: %d cells differ" % (tile, (a != ref).sum())


@pytest.mark.skipif((os.cpu_count() or 1) > 16, reason="the drainage's tiles take a tile a core")
def test_tiles_chosen_from_memory(tmp_path):
    """No --tile-size, a DEM too large for memory in one piece: the largest tiles that fit,
    said so, the raster of the run in one piece; lines need one piece: refused; too little
    memory even for tiles: refused with the amount."""
    one, auto = tmp_path / "one.tif", tmp_path / "auto.tif"
    run("ppa", JACKSBORO, one, "--both", "-q")
    # in one piece it needs 96 MB and 24 bytes a cell (99.3 MB): just under that
    p = run("ppa", JACKSBORO, auto, "--both", "--max-memory", "99M")
    assert "too large for memory in one piece" in p.stdout and "tiles of" in p.stdout
    assert np.array_equal(read(auto)[1], read(one)[1])
    for extra, words in ((["--max-memory", "99M", "--lines", tmp_path / "l.gpkg"],
                          "lines, preview and flow_lines"),
                         (["--max-memory", "90M"], "allow more memory")):
        out = tmp_path / "o.tif"
        p = run("ppa", JACKSBORO, out, "--both", *extra, check=False)
        assert p.returncode != 0 and words in p.stderr, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1
        assert not out.exists() and not leftovers(tmp_path)


def test_tiles_progress_goes_one_way(tmp_path):
    p = run("ppa", JACKSBORO, tmp_path / "o.tif", "--progress-lines", "--both", "--tile-size", "64")
    pcts = [int(l.split()[1]) for l in p.stdout.splitlines() if l.startswith("PROGRESS ")]
    assert pcts and pcts == sorted(pcts) and pcts[-1] == 100


def test_tiles_refuse_what_needs_the_whole(tmp_path):
    out = tmp_path / "o.tif"
    for extra, words in ((["--lines", tmp_path / "l.gpkg"], "lines, preview and flow_lines"),
                         (["--preview", tmp_path / "p.png"], "lines, preview and flow_lines"),
                         (["--flow-lines", tmp_path / "f.gpkg"], "lines, preview and flow_lines"),
                         ([], "16..16384")):
        tile = "8" if not extra else "64"
        p = run("ppa", JACKSBORO, out, "--tile-size", tile, *extra, check=False)
        assert p.returncode != 0 and words in p.stderr, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1
        assert not out.exists() and not leftovers(tmp_path)


# ---------------------------------------------------------------- valleys where the water runs


def drainage_oracle(z):
    """Drainage area in cells by the definition in ppa.md, written here another way: F (the
    least, over paths to the boundary, of the highest cell) by one Dijkstra-like search over
    the whole DEM, D (steps to a way out on flats of F) by breadth-first search, each cell's
    flow to its neighbour of least (F, D), areas summed in falling (F, D) order."""
    import heapq
    from collections import deque
    h, w = z.shape
    nb = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)]
    valid = ~np.isnan(z)
    pv = np.pad(valid, 1, constant_values=False)
    allv = np.ones(z.shape, bool)
    for dx, dy in nb:
        allv &= pv[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
    bnd = valid & ~allv
    F = np.full(z.shape, np.inf)
    done = ~valid
    heap = [(float(z[y, x]), y, x) for y, x in zip(*np.nonzero(bnd))]
    heapq.heapify(heap)
    while heap:
        f, y, x = heapq.heappop(heap)
        if done[y, x]:
            continue
        done[y, x] = True
        F[y, x] = f
        for dx, dy in nb:
            nx, ny = x + dx, y + dy
            if 0 <= nx < w and 0 <= ny < h and not done[ny, nx]:
                nf = max(float(z[ny, nx]), f)
                if nf < F[ny, nx]:
                    F[ny, nx] = nf
                    heapq.heappush(heap, (nf, ny, nx))
    F = np.where(valid, F, np.nan).astype(np.float32)  # the core's heights are floats
    D = np.full(z.shape, -1, np.int64)
    q = deque()
    for y in range(h):
        for x in range(w):
            if not valid[y, x]:
                continue
            low = bnd[y, x] or any(0 <= x + dx < w and 0 <= y + dy < h and valid[y + dy, x + dx]
                                   and F[y + dy, x + dx] < F[y, x] for dx, dy in nb)
            if low:
                D[y, x] = 0
                q.append((y, x))
    while q:
        y, x = q.popleft()
        for dx, dy in nb:
            nx, ny = x + dx, y + dy
            if 0 <= nx < w and 0 <= ny < h and valid[ny, nx] and D[ny, nx] < 0 \
                    and F[ny, nx] == F[y, x]:
                D[ny, nx] = D[y, x] + 1
                q.append((ny, nx))
    area = np.where(valid, 1.0, np.nan)
    cells = [(y, x) for y, x in zip(*np.nonzero(valid))]
    cells.sort(key=lambda c: (float(F[c]), int(D[c])), reverse=True)
    for y, x in cells:
        if bnd[y, x]:
            continue
        best, bk = None, (float(F[y, x]), int(D[y, x]))
        for dx, dy in nb:
            nx, ny = x + dx, y + dy
            if 0 <= nx < w and 0 <= ny < h and valid[ny, nx]:
                k = (float(F[ny, nx]), int(D[ny, nx]))
                if k < bk:
                    best, bk = (ny, nx), k
        area[best] += area[y, x]
    return area


def test_valleys_where_the_water_runs(tmp_path):
    """By default valleys are channels: every valley cell drains at least 200 cells (the
    oracle above; the core's areas are compared cell for cell in test_ppa.c), the dip threshold is lower than the ridges' and the ridges are those of
    --min-drainage 0; with --min-drainage 0 valleys are by profile alone and reach hollows
    that drain a few cells."""
    z = gdal.Open(JACKSBORO).ReadAsArray().astype(np.float64)
    area = drainage_oracle(z)
    out, prof = tmp_path / "v.tif", tmp_path / "p.tif"
    p = run("ppa", JACKSBORO, out, "--both")
    assert "thresholds: ridges" in p.stdout
    run("ppa", JACKSBORO, prof, "--both", "--min-drainage", "0", "-q")
    a, b = read(out)[1], read(prof)[1]
    va, vb = (a & 2) > 0, (b & 2) > 0
    assert va.sum() > 300
    assert area[va].min() >= 200, area[va].min()
    assert (area[vb] < 200).mean() > 0.2  # profile valleys: hollows above the channel heads
    assert np.array_equal(a & 1, b & 1)  # ridges untouched
    # an explicit threshold is every kind's; -1 is auto, other negatives are refused
    p = run("ppa", JACKSBORO, tmp_path / "e.tif", "--both", "--threshold-fraction", "0.01")
    assert "ridges" in p.stdout
    words = p.stdout.split("thresholds: ridges ")[1]
    r, v = words.split(" m, valleys ")
    assert float(r) == float(v.split()[0])
    p = run("ppa", JACKSBORO, tmp_path / "n.tif", "--threshold-fraction", "-0.5", check=False)
    assert p.returncode != 0 and "auto" in p.stderr
