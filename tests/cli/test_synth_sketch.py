# SPDX-License-Identifier: GPL-2.0-or-later
"""Sketch-guided synthesis (`terrasynth synth --sketch`): the output follows
the sketch (measured with PPA), keeps the exemplar's style, sits on the
sketch's grid with its nodata; errors; determinism."""
import math
import os

import numpy as np
import pytest
from osgeo import gdal, ogr, osr

import crest_profile  # noqa: E402
from tsutil import DATA, JACKSBORO, SHARED, run  # noqa: E402

gdal.UseExceptions()

LAMBDA = os.path.join(DATA, "sketches", "lambda_ridges.tif")
LAMBDA_V = os.path.join(DATA, "sketches", "lambda_valleys.tif")
PATCH = 64


def axes(src, out, kind, main):
    """PPA mask of `kind` ('ridges'/'valleys'), by profile (the paper's PPA: a drawing's
    valleys drain nothing); main=True keeps only the main axes."""
    extra = ["--profile-length", "31", "--threshold-fraction", "0.02", "--min-branch-length", "64"] if main \
        else ["--min-branch-length", "32"]
    extra += ["--min-drainage", "0"]
    run("ppa", src, out, f"--{kind}", "-q", *extra)
    return gdal.Open(str(out)).ReadAsArray()


def mean_distance(sketch, output, kind, tmp):
    """Mean distance (cells) from the sketch's axes to the output's main axes."""
    sk = axes(sketch, tmp / "sk.tif", kind, False)
    axes(output, tmp / "out_axes.tif", kind, True)
    src = gdal.Open(str(tmp / "out_axes.tif"))
    mem = gdal.GetDriverByName("MEM").Create("", src.RasterXSize, src.RasterYSize, 1, gdal.GDT_Float32)
    gdal.ComputeProximity(src.GetRasterBand(1), mem.GetRasterBand(1), ["VALUES=1,2,3", "DISTUNITS=PIXEL"])
    d = mem.ReadAsArray()
    sel = (sk > 0) & (sk < 255)
    return float(d[sel].mean())


@pytest.fixture(scope="module")
def lambda_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("lambda")
    for order in ("tree", "raster"):
        run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "1", "--order", order,
            d / f"{order}.tif", "-q")
    run("synth", "--like", LAMBDA, "--exemplar", JACKSBORO, "--seed", "1", d / "unguided.tif", "-q")
    for relief, name in (("0", "one_level.tif"), ("1", "full_relief.tif")):
        run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "1", "--crest-relief",
            relief, d / name, "-q")
    # the feature-patch constraints are measured on the patches alone (--layout 0
    # --slope-style 0 --drainage keep): the later stages would reshape the crest after them
    alone = ["--layout", "0", "--slope-style", "0", "--drainage", "keep"]
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "1", "--alpha-r", "0",
        *alone, d / "no_guide.tif", "-q")
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "1", *alone,
        d / "patches.tif", "-q")
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "1", "--alpha-s", "3",
        *alone, d / "smooth.tif", "-q")
    # the synthesis's seams, without the drainage stage's channels across them
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "1", d / "dbg.tif",
        "--debug-dir", d / "debug", "--preview", d / "lambda.png", "--drainage", "keep")
    return d


def crest(lambda_runs, name, valleys=False):
    return crest_profile.measure(lambda_runs / name, lambda_runs / "debug" / "sketch_features.gpkg",
                                 valleys)


def test_follows_the_lambda_sketch(lambda_runs, tmp_path):
    d = lambda_runs
    tree = mean_distance(LAMBDA, d / "tree.tif", "ridges", tmp_path)
    raster = mean_distance(LAMBDA, d / "raster.tif", "ridges", tmp_path)
    unguided = mean_distance(LAMBDA, d / "unguided.tif", "ridges", tmp_path)
    held_tree, held_raster = crest(d, "tree.tif")["held"], crest(d, "raster.tif")["held"]
    print(f"mean distance sketch ridges -> output ridges: tree {tree:.2f}, raster {raster:.2f}, "
          f"unguided {unguided:.2f} cells (patch/8 = {PATCH / 8}); sketch held as a ridge: "
          f"tree {held_tree:.2f}, raster {held_raster:.2f}")
    assert tree < PATCH / 8
    assert raster < PATCH / 8
    # the guide matters: without it the same exemplar gives ridges much farther away
    assert tree < 0.6 * unguided
    # both orders draw the sketch as a ridge nearly all along it (the layout stage holds the
    # crest in either; before it, tree order held 0.89 against raster order's 0.79 here, the
    # paper's Fig. 8; over the quality matrix the two orders now score alike: sketch.md)
    assert held_tree > 0.85 and held_raster > 0.85


def test_relief_guide_makes_the_sketched_ridges_stand_out(lambda_runs):
    guided, flat = crest(lambda_runs, "patches.tif"), crest(lambda_runs, "no_guide.tif")
    print(f"crest above the land 31 cells off: guided {guided['stand']:.0f} m, without the "
          f"guide {flat['stand']:.0f} m; held {guided['held']:.2f} / {flat['held']:.2f}")
    # measured 84 m against 55 m (held 0.89 against 0.85 then; with the prominence term and
    # the refused folding warps both hold about 0.91, so only the stand is asserted)
    assert guided["stand"] > 1.25 * flat["stand"]


def test_layout_makes_the_sketched_ridges_stand_out(lambda_runs):
    laid, patches = crest(lambda_runs, "tree.tif"), crest(lambda_runs, "patches.tif")
    print(f"crest above the land 31 cells off: layout {laid['stand']:.0f} m, patches alone "
          f"{patches['stand']:.0f} m; held {laid['held']:.2f} / {patches['held']:.2f}")
    assert laid["stand"] > 1.25 * patches["stand"]
    assert laid["held"] > patches["held"]


def test_crests_rise_and_fall_with_the_exemplars_peaks_and_saddles(lambda_runs, tmp_path):
    """Along the drawn ridges, peaks and saddles about a patch apart, measured as along the
    exemplar's own main ridges: closer to the exemplar's with the crest relief than at one
    level, and the ridges still drawn as ridges."""
    d = lambda_runs
    run("ppa", JACKSBORO, tmp_path / "ppa.tif", "--ridges", "--lines", tmp_path / "ex.gpkg", "-q")
    z, gt = crest_profile.read(JACKSBORO)
    ex = crest_profile.figures(crest_profile.main_ridges(crest_profile.line_stands(
        z, crest_profile.polylines(tmp_path / "ex.gpkg", "paths", gt), PATCH, 3 * PATCH // 2)), PATCH)
    got = {}
    for name in ("full_relief.tif", "tree.tif", "one_level.tif"):
        z, gt = crest_profile.read(d / name)
        got[name] = crest_profile.figures(crest_profile.line_stands(
            z, crest_profile.polylines(d / "debug" / "sketch_features.gpkg", "paths", gt), PATCH,
            PATCH + 1), PATCH)
    on, dflt, off = got["full_relief.tif"], got["tree.tif"], got["one_level.tif"]
    print(f"bend {PATCH // 2}: exemplar {ex['bend']:.0f} m, crest relief 1 {on['bend']:.0f} m, "
          f"default {dflt['bend']:.0f} m, 0 {off['bend']:.0f} m; cross-section spread "
          f"{ex['cv']:.2f} / {on['cv']:.2f} / {dflt['cv']:.2f} / {off['cv']:.2f}")
    assert abs(math.log(on["bend"] / ex["bend"])) < abs(math.log(off["bend"] / ex["bend"]))
    assert off["bend"] < dflt["bend"] < on["bend"]
    assert crest(d, "full_relief.tif")["held"] > 0.9 * crest(d, "one_level.tif")["held"]


def test_path_smoothness_smooths_the_crest(lambda_runs):
    smooth, free = crest(lambda_runs, "smooth.tif"), crest(lambda_runs, "patches.tif")
    print(f"crest height bend over 16 cells: alpha_s 3 {smooth['bend']:.1f} m, alpha_s 0 "
          f"{free['bend']:.1f} m")
    # measured 67 m against 90 m
    assert smooth["bend"] < 0.85 * free["bend"]


def test_on_the_sketch_grid_and_in_the_exemplar_style(lambda_runs):
    d = lambda_runs
    out, sk = gdal.Open(str(d / "tree.tif")), gdal.Open(LAMBDA)
    assert (out.RasterXSize, out.RasterYSize) == (sk.RasterXSize, sk.RasterYSize)
    assert out.GetGeoTransform() == pytest.approx(sk.GetGeoTransform())
    assert osr.SpatialReference(out.GetProjection()).IsSame(
        osr.SpatialReference(sk.GetProjection()), ["IGNORE_DATA_AXIS_TO_SRS_AXIS_MAPPING=YES"])
    z = out.ReadAsArray().astype(float)
    ex = gdal.Open(JACKSBORO).ReadAsArray().astype(float)
    assert np.isfinite(z).all() and (z != -9999).all()
    # elevations come from the exemplar, not from the sketch's 0..255 (the layout may take
    # a corner a little past the exemplar's lowest land)
    lo, hi = np.percentile(z, [1, 99])
    assert lo > ex.min() - 0.3 * np.ptp(ex) and hi < ex.max() + 0.3 * np.ptp(ex)
    # slope distribution close to the exemplar's (KS distance)
    def slopes(a):
        gy, gx = np.gradient(a, 92.6, 74.6)
        return np.sort(np.degrees(np.arctan(np.hypot(gx, gy))).ravel())
    s_out, s_ex = slopes(z), slopes(ex)
    grid = np.linspace(0, 60, 601)
    ks = np.max(np.abs(np.searchsorted(s_ex, grid) / s_ex.size - np.searchsorted(s_out, grid) / s_out.size))
    assert ks < 0.25, ks


def test_no_seams(lambda_runs):
    """Height steps across the seams of feature patches and fill stay within the exemplar's."""
    z = gdal.Open(str(lambda_runs / "dbg.tif")).ReadAsArray().astype(float)
    ex = gdal.Open(JACKSBORO).ReadAsArray().astype(float)
    seams = gdal.Open(str(lambda_runs / "debug" / "seams.tif")).ReadAsArray().astype(bool)
    assert seams.sum() > 100

    def steps(a):
        return np.concatenate([np.abs(np.diff(a, axis=1)).ravel(), np.abs(np.diff(a, axis=0)).ravel()])

    sx = seams[:, 1:] | seams[:, :-1]
    sy = seams[1:, :] | seams[:-1, :]
    seam_steps = np.concatenate([np.abs(np.diff(z, axis=1))[sx], np.abs(np.diff(z, axis=0))[sy]])
    limit = np.percentile(steps(ex), 99.9)
    print(f"seam steps 99 % {np.percentile(seam_steps, 99):.1f} m, 99.9 % "
          f"{np.percentile(seam_steps, 99.9):.1f} m; exemplar 99.9 % {limit:.1f} m")
    assert np.percentile(seam_steps, 99) <= limit
    assert np.percentile(seam_steps, 99.9) <= 1.1 * limit
    assert np.percentile(seam_steps, 99) <= 1.1 * np.percentile(steps(z), 99)


def test_debug_outputs(lambda_runs):
    d = lambda_runs / "debug"
    for name in ("sketch_features.gpkg", "output_features.gpkg"):
        ds = ogr.Open(str(d / name))
        assert ds.GetLayerByName("paths").GetFeatureCount() > 0
    ds = ogr.Open(str(d / "sketch_features.gpkg"))  # keep the dataset alive while iterating
    nodes = ds.GetLayerByName("nodes")
    assert sum(1 for f in nodes if f.GetField("kind") == "branch") == 1  # the lambda's junction
    for name in ("seams.tif", "source_exemplar.tif", "order.tif"):
        assert gdal.Open(str(d / name)).RasterXSize == 512
    assert (lambda_runs / "lambda.png").exists()


def test_deterministic(tmp_path):
    args = ["synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "4", "-q"]
    run(*args, tmp_path / "a.tif")
    run(*args, tmp_path / "b.tif", "--threads", "1")
    assert (tmp_path / "a.tif").read_bytes() == (tmp_path / "b.tif").read_bytes()


def test_sketch_nodata_stays_nodata(tmp_path):
    sk = gdal.Open(LAMBDA)
    a = sk.ReadAsArray()
    a[:, :40] = -9999
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "sk.tif"), a.shape[1], a.shape[0], 1, gdal.GDT_Float32)
    ds.SetGeoTransform(sk.GetGeoTransform())
    ds.SetProjection(sk.GetProjection())
    ds.GetRasterBand(1).SetNoDataValue(-9999)
    ds.GetRasterBand(1).WriteArray(a)
    ds = None
    run("synth", "--sketch", tmp_path / "sk.tif", "--exemplar", JACKSBORO, tmp_path / "o.tif", "-q")
    z = gdal.Open(str(tmp_path / "o.tif")).ReadAsArray()
    assert (z[:, :40] == -9999).all() and (z[:, 40:] != -9999).all()


@pytest.mark.skipif(not os.path.exists(os.path.join(SHARED, "canyon_zion_ut_srtm90m.tif")),
                    reason="../shared/data/dem not present")
def test_valley_sketch_with_a_canyon(tmp_path):
    canyon = os.path.join(SHARED, "canyon_zion_ut_srtm90m.tif")
    run("synth", "--sketch", LAMBDA_V, "--exemplar", canyon, "--seed", "1", tmp_path / "v.tif", "-q",
        "--debug-dir", tmp_path / "debug")
    run("synth", "--like", LAMBDA_V, "--exemplar", canyon, "--seed", "1", tmp_path / "u.tif", "-q")
    guided = mean_distance(LAMBDA_V, tmp_path / "v.tif", "valleys", tmp_path)
    unguided = mean_distance(LAMBDA_V, tmp_path / "u.tif", "valleys", tmp_path)
    held = crest_profile.measure(tmp_path / "v.tif", tmp_path / "debug" / "sketch_features.gpkg",
                                 valleys=True)["held"]
    print(f"valleys: guided {guided:.2f}, unguided {unguided:.2f} cells; held as a valley {held:.2f}")
    assert guided < PATCH / 8 and guided < unguided
    assert held > 0.85  # measured 0.97


@pytest.mark.parametrize(
    "extra,words",
    [
        (["--size", "100x100"], "sketch sets the output grid"),
        (["--mode", "hills"], "hills"),
        (["--alpha-d", "-1"], "out of range"),
        (["--patch-size", "1024"], "smaller than a patch"),
        (["--patch-size", "200000m"], "2403 cells of 83.23 m: must be 8..1024 cells"),
        (["--patch-size", "5km"], "unit must be cells (no suffix) or m"),
        (["--patch-size", "3000m", "--overlap", "40"], "overlap 40 must be at most half of patch_size 36"),
    ],
)
def test_errors(tmp_path, extra, words):
    p = run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, *extra, tmp_path / "o.tif", "-q", check=False)
    assert p.returncode != 0
    assert p.stderr.strip().count("\n") == 0 and words in p.stderr, p.stderr
    assert not (tmp_path / "o.tif").exists()


def test_exemplar_without_ridges_warns(tmp_path):
    src = gdal.Open(JACKSBORO)
    plane = np.fromfunction(lambda y, x: 300 + 0.5 * x + 0.2 * y,
                            (src.RasterYSize, src.RasterXSize)).astype(np.float32)
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "plane.tif"), src.RasterXSize,
                                              src.RasterYSize, 1, gdal.GDT_Float32)
    ds.SetGeoTransform(src.GetGeoTransform())
    ds.SetProjection(src.GetProjection())
    ds.GetRasterBand(1).WriteArray(plane)
    ds = None
    p = run("synth", "--sketch", LAMBDA, "--exemplar", tmp_path / "plane.tif", tmp_path / "o.tif", "-q")
    assert "no main ridges to draw the sketch with" in p.stderr
    assert (tmp_path / "o.tif").exists()


def test_patch_size_in_metres(tmp_path):
    # the lambda's grid is 3" at 36 N: 83.23 m per cell (geometric mean of 74.9 x 92.5 m on
    # its middle row), so 5000 m is 60 cells and 1200 m is 14
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "2", "--patch-size", "5000m",
        "--overlap", "1200m", tmp_path / "m.tif", "-q")
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "2", "--patch-size", "60",
        "--overlap", "14", tmp_path / "c.tif", "-q")
    assert (tmp_path / "m.tif").read_bytes() == (tmp_path / "c.tif").read_bytes()
    # without a CRS there is no ground size to turn metres into cells
    nocrs = tmp_path / "nocrs.tif"
    z = gdal.Open(JACKSBORO).ReadAsArray()
    ds = gdal.GetDriverByName("GTiff").Create(str(nocrs), z.shape[1], z.shape[0], 1, gdal.GDT_Float32)
    ds.GetRasterBand(1).WriteArray(z)
    ds = None
    p = run("synth", "--exemplar", nocrs, "--size", "100x100", "--patch-size", "3000m",
            tmp_path / "n.tif", "-q", check=False)
    assert p.returncode != 0 and "no ground size" in p.stderr and str(nocrs) in p.stderr, p.stderr
    assert not (tmp_path / "n.tif").exists()


def test_several_styles_from_a_region_map(tmp_path):
    # style 2: the same DEM made smooth (down- then up-sampled), so the two regions differ
    smooth = tmp_path / "smooth.tif"
    src = gdal.Open(JACKSBORO)
    gdal.Warp(str(tmp_path / "coarse.tif"), JACKSBORO, width=src.RasterXSize // 6, height=src.RasterYSize // 6,
              resampleAlg="average")
    gdal.Warp(str(smooth), str(tmp_path / "coarse.tif"), width=src.RasterXSize, height=src.RasterYSize,
              resampleAlg="cubicspline")
    regions = os.path.join(DATA, "sketches", "multistyle_regions.tif")
    sketch = os.path.join(DATA, "sketches", "multistyle_sketch.tif")
    run("synth", "--sketch", sketch, "--regions", regions, "--region-exemplar", f"1={JACKSBORO}",
        "--region-exemplar", f"2={smooth}", "--seed", "1", tmp_path / "o.tif", "--debug-dir",
        tmp_path / "dbg", "-q", "--drainage", "keep")  # each region's style as synthesised
    r = gdal.Open(regions).ReadAsArray()
    z = gdal.Open(str(tmp_path / "o.tif")).ReadAsArray().astype(float)
    se = gdal.Open(str(tmp_path / "dbg" / "source_exemplar.tif")).ReadAsArray()
    assert np.isfinite(z).all()
    assert (se[r == 1] == 0).mean() > 0.85 and (se[r == 2] == 1).mean() > 0.85
    gy, gx = np.gradient(z)
    steep = np.hypot(gx, gy)
    assert steep[r == 1].mean() > 1.5 * steep[r == 2].mean()  # rugged west, smooth east
    # each region's slopes (per cell) take its own exemplar's distribution, not the other's
    # (the slope style maps each region onto its exemplar)
    def w1(a, b):
        q = np.linspace(0.5, 99.5, 199)
        return np.mean(np.abs(np.percentile(a, q) - np.percentile(b, q)))

    def cell_slopes(a):
        gy, gx = np.gradient(a.astype(float))
        return np.hypot(gx, gy)[1:-1, 1:-1].ravel()

    e1 = cell_slopes(gdal.Open(JACKSBORO).ReadAsArray())
    e2 = cell_slopes(gdal.Open(str(smooth)).ReadAsArray())
    inner = np.zeros_like(r, dtype=bool)
    inner[1:-1, 1:-1] = True
    s1, s2 = steep[(r == 1) & inner], steep[(r == 2) & inner]
    assert w1(s1, e1) < w1(s1, e2) and w1(s2, e2) < w1(s2, e1)
    # measured 0.20 and 0.30 m per cell (2.60 and 0.87 with --slope-style 0)
    assert w1(s1, e1) < 1.0 and w1(s2, e2) < 0.6, (w1(s1, e1), w1(s2, e2))


def test_region_polygons(tmp_path):
    # the same split as polygons with a 'region' field
    regions = os.path.join(DATA, "sketches", "multistyle_regions.tif")
    src = gdal.Open(regions)
    vec = tmp_path / "regions.gpkg"
    drv = ogr.GetDriverByName("GPKG")
    ds = drv.CreateDataSource(str(vec))
    srs = osr.SpatialReference(src.GetProjection())
    lyr = ds.CreateLayer("regions", srs, ogr.wkbPolygon)
    lyr.CreateField(ogr.FieldDefn("region", ogr.OFTInteger))
    gdal.Polygonize(src.GetRasterBand(1), None, lyr, 0)
    ds = None
    sketch = os.path.join(DATA, "sketches", "multistyle_sketch.tif")
    run("synth", "--sketch", sketch, "--regions", vec, "--region-exemplar", f"1={JACKSBORO}",
        "--region-exemplar", f"2={JACKSBORO}", "--seed", "1", tmp_path / "o.tif", "-q")
    assert np.isfinite(gdal.Open(str(tmp_path / "o.tif")).ReadAsArray()).all()
    p = run("synth", "--sketch", sketch, "--regions", JACKSBORO, "--region-exemplar", f"1={JACKSBORO}",
            tmp_path / "x.tif", "-q", check=False)
    assert p.returncode == 1 and "region map" in p.stderr


def test_wanted_heights_with_a_sketch(tmp_path):
    """--heights with a sketch: the layout and the slope style, which know nothing of them,
    must not give a block wanted at the exemplar's 95th percentile a mean near the land's
    median: each block's mean comes within a tenth of the exemplar's range of its wanted
    height."""
    sk = gdal.Open(LAMBDA)
    w, h = sk.RasterXSize, sk.RasterYSize
    e = gdal.Open(JACKSBORO).ReadAsArray().astype(np.float64)
    lo, hi = np.percentile(e, 5), np.percentile(e, 95)
    want = np.full((h, w), np.nan, np.float32)
    want[: h // 4, -w // 4:] = hi  # north-east corner high
    want[-h // 4:, : w // 4] = lo  # south-west corner low
    path = tmp_path / "heights.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(path), w, h, 1, gdal.GDT_Float32)
    ds.SetGeoTransform(sk.GetGeoTransform())
    ds.SetProjection(sk.GetProjection())
    ds.GetRasterBand(1).WriteArray(want)
    ds = None
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--heights", path, "--seed", "2",
        tmp_path / "o.tif", "-q")
    z = gdal.Open(str(tmp_path / "o.tif")).ReadAsArray().astype(np.float64)
    for v in (hi, lo):
        m = want == v
        assert abs(z[m].mean() - v) <= 0.1 * (hi - lo), (v, z[m].mean(), lo, hi)


def _drawing(path, bands, ds_like, palette=None):
    """A Byte drawing on ds_like's grid: bands is a list of arrays (1: grey or indices, 3: RGB)."""
    out = gdal.GetDriverByName("GTiff").Create(str(path), ds_like.RasterXSize,
                                               ds_like.RasterYSize, len(bands), gdal.GDT_Byte,
                                               ["PHOTOMETRIC=RGB"] if len(bands) == 3 else [])
    out.SetGeoTransform(ds_like.GetGeoTransform())
    out.SetProjection(ds_like.GetProjection())
    for i, a in enumerate(bands):
        out.GetRasterBand(i + 1).WriteArray(a)
    if palette is not None:
        ct = gdal.ColorTable()
        for i, rgb in enumerate(palette):
            ct.SetColorEntry(i, tuple(int(c) for c in rgb) + (255,))
        out.GetRasterBand(1).SetRasterColorTable(ct)
        out.GetRasterBand(1).SetRasterColorInterpretation(gdal.GCI_PaletteIndex)
    out = None


def test_drawings_are_read_as_colours(tmp_path):
    """A paletted drawing is read by its colours and an RGB one by its luminance: the same
    terrain as the grey drawing numpy makes of them (a white stroke at index 0 is a ridge)."""
    ds = gdal.Open(LAMBDA)
    grey = np.clip(ds.ReadAsArray(), 0, 255).astype(np.uint8)
    # the palette reversed: index i is the grey 255 - i
    _drawing(tmp_path / "pal.tif", [255 - grey], ds, [(255 - i,) * 3 for i in range(256)])
    _drawing(tmp_path / "rgb.tif", [grey, grey, grey], ds)
    _drawing(tmp_path / "grey.tif", [grey], ds)
    outs = {}
    for name in ("grey", "pal", "rgb"):
        run("synth", "--sketch", tmp_path / (name + ".tif"), "--exemplar", JACKSBORO, "--seed", 1,
            "--drainage", "keep", tmp_path / (name + "_out.tif"), "-q")
        outs[name] = gdal.Open(str(tmp_path / (name + "_out.tif"))).ReadAsArray()
    assert np.array_equal(outs["pal"], outs["grey"])
    assert np.array_equal(outs["rgb"], outs["grey"])
    # an index with no colour in the palette is refused, naming it (a VRT's palette of 16)
    vrt = gdal.Translate(str(tmp_path / "short.vrt"), str(tmp_path / "grey.tif"), format="VRT")
    vrt = None
    text = (tmp_path / "short.vrt").read_text()
    entries = "".join('<Entry c1="0" c2="0" c3="0" c4="255"/>' for _ in range(16))
    text = text.replace("<ColorInterp>Gray</ColorInterp>",
                        "<ColorInterp>Palette</ColorInterp><ColorTable>%s</ColorTable>" % entries)
    (tmp_path / "short.vrt").write_text(text)
    p = run("synth", "--sketch", tmp_path / "short.vrt", "--exemplar", JACKSBORO,
            tmp_path / "x.tif", check=False)
    assert p.returncode != 0 and "has no colour (the palette has 16)" in p.stderr


def test_debug_maps_leave_the_terrain_as_it_is(tmp_path):
    """--debug-dir only records where cells came from: the terrain is the same cell for cell
    (each fill patch draws from the stream of its place in the fill, whatever the maps count
    before it; a build keying it on the maps' count fails here)."""
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "2", tmp_path / "a.tif",
        "-q")
    run("synth", "--sketch", LAMBDA, "--exemplar", JACKSBORO, "--seed", "2", tmp_path / "b.tif",
        "-q", "--debug-dir", tmp_path / "debug")
    a = gdal.Open(str(tmp_path / "a.tif")).ReadAsArray()
    b = gdal.Open(str(tmp_path / "b.tif")).ReadAsArray()
    assert np.array_equal(a, b)
