# SPDX-License-Identifier: GPL-2.0-or-later
"""The TSYN GDAL plugin: recipes through the GDAL tools and osgeo.gdal, VRTs
over recipes, TerraSynth pixel functions, broken recipes."""
import os
import subprocess

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
TERRASYNTH = os.environ.get("TERRASYNTH", os.path.join(ROOT, "build", "gdal_driver", "terrasynth"))
DATA = os.environ.get("TS_DATA_DIR", os.path.join(ROOT, "data"))
JACKSBORO = os.path.join(DATA, "jacksboro_fault_dem.tif")

os.environ["GDAL_DRIVER_PATH"] = PLUGINS  # before osgeo is imported
from osgeo import gdal, osr  # noqa: E402

gdal.UseExceptions()
gdal.AllRegister()

ENV = dict(os.environ, GDAL_DRIVER_PATH=PLUGINS)


def tool(*args, check=True):
    p = subprocess.run([*map(str, args)], capture_output=True, text=True, env=ENV, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError(f"{args[0]} failed: {p.stderr}")
    return p


def ts(*args):
    return tool(TERRASYNTH, *args)


def arr(path):
    return gdal.Open(str(path)).ReadAsArray()


def write_tif(path, a, nodata=None, srs="EPSG:32611", gt=(400000, 30, 0, 3800000, 0, -30), unit=None):
    ds = gdal.GetDriverByName("GTiff").Create(str(path), a.shape[1], a.shape[0], 1, gdal.GDT_Float32)
    ds.SetGeoTransform(gt)
    s = osr.SpatialReference()
    s.SetFromUserInput(srs)
    ds.SetProjection(s.ExportToWkt())
    if nodata is not None:
        ds.GetRasterBand(1).SetNoDataValue(nodata)
    if unit:
        ds.GetRasterBand(1).SetUnitType(unit)
    ds.GetRasterBand(1).WriteArray(a)
    ds = None


# ---------------------------------------------------------------- the driver


def test_formats_lists_tsyn():
    assert gdal.GetDriverByName("TSYN") is not None
    out = tool("gdalinfo", "--formats").stdout
    assert "TSYN -raster- (rov)" in out


def test_open_option_list_declares_every_parameter():
    """The driver's option list comes from the declarations: every stage parameter with its
    type, default and range (choices as string-select values), every job option that names
    no file; none that names one."""
    import json
    import xml.etree.ElementTree as ET

    d = json.loads(ts("describe").stdout)
    opts = {o.get("name"): o for o in ET.fromstring(
        gdal.GetDriverByName("TSYN").GetMetadataItem("DMD_OPENOPTIONLIST"))}
    for job in d["jobs"].values():
        for st in job["stages"]:
            for p in d["stages"][st]:
                o = opts[p["name"].upper()]
                if p["type"] == "enum":
                    assert o.get("type") == "string-select"
                    assert [v.text for v in o] == p["choices"]
                    assert o.get("default") == p["choices"][int(p["default"])]
                elif p["type"] in ("int", "double"):
                    assert o.get("type") == ("int" if p["type"] == "int" else "float")
                    assert float(o.get("min")) == p["min"] and float(o.get("max")) == p["max"]
                    assert float(o.get("default")) == pytest.approx(p["default"])
        for op in job["options"]:
            named = op["name"].upper() in opts
            if op["recipe"] and op["kind"] not in ("file", "pin", "rule", "named", "pair"):
                assert named, op["name"]
            elif op["kind"] in ("file", "pin", "rule", "named", "pair", "output"):
                assert not named or op["name"] in ("band", "cell_size"), op["name"]


@pytest.fixture(scope="module")
def ppa_recipe(tmp_path_factory):
    d = tmp_path_factory.mktemp("ppa")
    ts("ppa", JACKSBORO, "--both", "--recipe", d / "axes.tsyn")
    ts("ppa", JACKSBORO, d / "cli.tif", "--both", "-q")
    return d


def test_gdalinfo_reports_driver_size_crs_nodata(ppa_recipe):
    info = tool("gdalinfo", ppa_recipe / "axes.tsyn").stdout
    assert "Driver: TSYN/" in info
    assert "Size is 403, 344" in info
    assert 'ID["EPSG",4326]' in info
    assert "NoData Value=255" in info
    ds = gdal.Open(str(ppa_recipe / "axes.tsyn"))
    assert ds.GetDriver().ShortName == "TSYN"
    assert ds.GetGeoTransform() == pytest.approx(gdal.Open(JACKSBORO).GetGeoTransform())


def test_translate_equals_cli_ppa(ppa_recipe):
    tool("gdal_translate", "-q", ppa_recipe / "axes.tsyn", ppa_recipe / "gdal.tif")
    a, b = arr(ppa_recipe / "gdal.tif"), arr(ppa_recipe / "cli.tif")
    assert a.dtype == np.uint8 and a.tobytes() == b.tobytes()
    assert (a == 1).sum() > 100


def test_python_reads_blocks_and_windows(ppa_recipe):
    ds = gdal.Open(str(ppa_recipe / "axes.tsyn"))
    band = ds.GetRasterBand(1)
    assert band.GetBlockSize() == [256, 256]
    whole = band.ReadAsArray()
    assert (band.ReadAsArray(300, 200, 50, 40) == whole[200:240, 300:350]).all()
    assert (band.ReadBlock(1, 1) is not None)


def test_schedule_metadata(tmp_path):
    """Metadata domain TSYN says how a recipe is made (what the Dask runner schedules by):
    the job, whether any window is made alone, the tile size, and the files it reads as
    GDAL opens them; reading it writes nothing beside the recipe."""
    ex = tmp_path / "sub" / "ex.tif"
    ex.parent.mkdir()
    gdal.Translate(str(ex), JACKSBORO)
    cases = {
        "ppa": (["ppa", ex, "--both"], "PPA", "whole", 0),
        "pixel": (["pixel", "--exemplar", ex, "--size", "64x64"], "Pixel", "any", 0),
        "tiled": (["synth", "--exemplar", ex, "--size", "600x500", "--tiled", "256"], "Synth",
                  "tiles", 256),
        "synth": (["synth", "--exemplar", ex, "--size", "100x90"], "Synth", "whole", 0),
    }
    for name, (args, job, windows, tile) in cases.items():
        recipe = tmp_path / (name + ".tsyn")
        ts(*args, "--recipe", recipe)
        before = sorted(os.listdir(tmp_path))
        ds = gdal.Open(str(recipe))
        md = ds.GetMetadata("TSYN")
        assert "TSYN" in ds.GetMetadataDomainList()
        assert md["JOB"] == job and md["WINDOWS"] == windows and md["TILE_SIZE"] == str(tile)
        assert [v for k, v in md.items() if k.startswith("INPUT_")] == [str(ex)], md
        ds = None
        assert sorted(os.listdir(tmp_path)) == before


def test_synth_recipe_equals_cli_and_warps(tmp_path):
    args = ["--exemplar", JACKSBORO, "--size", "160x150", "--seed", "5", "--patch-size", "32", "--overlap", "8"]
    ts("synth", *args, "--recipe", tmp_path / "s.tsyn")
    ts("synth", *args, tmp_path / "cli.tif", "-q")
    tool("gdal_translate", "-q", tmp_path / "s.tsyn", tmp_path / "gdal.tif")
    assert arr(tmp_path / "gdal.tif").tobytes() == arr(tmp_path / "cli.tif").tobytes()
    # a VRT around the recipe
    tool("gdal_translate", "-q", "-of", "VRT", tmp_path / "s.tsyn", tmp_path / "wrap.vrt")
    tool("gdal_translate", "-q", tmp_path / "wrap.vrt", tmp_path / "wrap.tif")
    assert arr(tmp_path / "wrap.tif").tobytes() == arr(tmp_path / "cli.tif").tobytes()
    # gdalwarp to another CRS
    tool("gdalwarp", "-q", "-t_srs", "EPSG:32616", "-tr", "100", "100", tmp_path / "s.tsyn", tmp_path / "utm.tif")
    w = gdal.Open(str(tmp_path / "utm.tif"))
    assert osr.SpatialReference(w.GetProjection()).GetAuthorityCode(None) == "32616"
    assert w.GetRasterBand(1).GetNoDataValue() == -9999


def test_open_options_override(tmp_path):
    args = ["--exemplar", JACKSBORO, "--size", "150x150", "--seed", "5", "--patch-size", "32", "--overlap", "8"]
    ts("synth", *args, "--recipe", tmp_path / "s.tsyn")
    base = gdal.Open(str(tmp_path / "s.tsyn")).ReadAsArray()
    other = gdal.OpenEx(str(tmp_path / "s.tsyn"), open_options=["SEED=6"]).ReadAsArray()
    assert base.tobytes() != other.tobytes()
    ts("synth", *args[:-5], "6", "--patch-size", "32", "--overlap", "8", tmp_path / "s6.tif", "-q")
    assert other.tobytes() == arr(tmp_path / "s6.tif").tobytes()
    with pytest.raises(RuntimeError, match="patch_size"):
        gdal.OpenEx(str(tmp_path / "s.tsyn"), open_options=["PATCH_SIZE=5000"])
    # a seed is taken as a 64-bit number without a word from GDAL's option check
    p = tool("gdalinfo", "-oo", "SEED=18446744073709551615", tmp_path / "s.tsyn")
    assert "not recognized" not in p.stderr and "Warning" not in p.stderr, p.stderr


def test_nodata_round_trips(tmp_path):
    z = gdal.Open(JACKSBORO).ReadAsArray().astype(np.float32)
    z[50:90, 100:180] = -32768
    write_tif(tmp_path / "holes.tif", z, nodata=-32768, srs="EPSG:4326",
              gt=gdal.Open(JACKSBORO).GetGeoTransform())
    (tmp_path / "h.tsyn").write_text(
        '<TerraSynth version="1"><PPA><Input>holes.tif</Input>'
        '<Param name="features">both</Param></PPA></TerraSynth>')
    a = gdal.Open(str(tmp_path / "h.tsyn")).ReadAsArray()
    assert (a[50:90, 100:180] == 255).all() and (a[z != -32768] != 255).all()


def test_relative_and_vsimem_recipes(tmp_path):
    import shutil
    shutil.copy(JACKSBORO, tmp_path / "dem.tif")
    (tmp_path / "rel.tsyn").write_text(
        '<TerraSynth version="1"><PPA><Input>dem.tif</Input></PPA></TerraSynth>')
    cwd = os.getcwd()
    try:
        os.chdir("/")
        a = gdal.Open(str(tmp_path / "rel.tsyn")).ReadAsArray()
    finally:
        os.chdir(cwd)
    gdal.FileFromMemBuffer("/vsimem/x.tsyn",
                           f'<TerraSynth version="1"><PPA><Input>{tmp_path / "dem.tif"}</Input></PPA></TerraSynth>')
    b = gdal.Open("/vsimem/x.tsyn").ReadAsArray()
    gdal.Unlink("/vsimem/x.tsyn")
    assert a.tobytes() == b.tobytes() and (a == 1).sum() > 100


# ---------------------------------------------------------------- broken recipes


@pytest.mark.parametrize(
    "text,words",
    [
        ("<TerraSynth version='1'><PPA><Input>dem.tif</Input>", "XML"),
        ("<Other/>", "root element"),
        ("<TerraSynth version='9'><PPA/></TerraSynth>", "version"),
        ("<TerraSynth version='1'/>", "<PPA>, a <Synth>, an <Amplify> or a <Pixel>"),
        ("<TerraSynth version='1'><PPA/></TerraSynth>", "input"),
        ("<TerraSynth version='1'><PPA><Input>missing.tif</Input></PPA></TerraSynth>", "no such file"),
        ("<TerraSynth version='1'><PPA><Input>dem.tif</Input><Param name='profile_length'>abc</Param></PPA></TerraSynth>",
         "profile_length"),
        ("<TerraSynth version='1'><PPA><Input>dem.tif</Input><Param name='profile_length'>4</Param></PPA></TerraSynth>",
         "odd"),
        ("<TerraSynth version='1'><PPA><Input>dem.tif</Input><Param name='nope'>1</Param></PPA></TerraSynth>",
         "unknown parameter"),
        ("<TerraSynth version='1'><PPA><Input>dem.tif</Input><Param>1</Param></PPA></TerraSynth>", "name"),
        ("<TerraSynth version='1'><PPA><Input band='x'>dem.tif</Input></PPA></TerraSynth>", "band"),
        ("<TerraSynth version='1'><Synth><Grid width='10' height='10'/></Synth></TerraSynth>", "exemplar"),
        ("<TerraSynth version='1'><Synth><Exemplar>dem.tif</Exemplar></Synth></TerraSynth>", "target grid"),
        ("<TerraSynth version='1'><Synth seed='-1'><Exemplar>dem.tif</Exemplar><Grid width='10' height='10'/></Synth></TerraSynth>",
         "seed"),
        ("<TerraSynth version='1'><Synth><Exemplar>dem.tif</Exemplar><Grid width='0' height='10'/></Synth></TerraSynth>",
         "size takes WxH"),
        ("<TerraSynth version='1'><Synth><Exemplar>dem.tif</Exemplar><Grid width='100' height='100' crs='EPSG:32611'/></Synth></TerraSynth>",
         "origin"),
        ("<TerraSynth version='1'><PPA><Input>self.tsyn</Input></PPA></TerraSynth>", "recursion"),
        ("", "1 byte"),
    ],
)
def test_broken_recipes_give_gdal_errors(tmp_path, text, words):
    import shutil
    shutil.copy(JACKSBORO, tmp_path / "dem.tif")
    (tmp_path / "self.tsyn").write_text(text)
    with pytest.raises(RuntimeError) as e:
        gdal.Open(str(tmp_path / "self.tsyn"))
    assert words.lower() in str(e.value).lower(), str(e.value)
    p = tool("gdalinfo", tmp_path / "self.tsyn", check=False)
    assert p.returncode != 0 and "self.tsyn" in p.stderr


def test_indirect_recursion(tmp_path):
    (tmp_path / "a.tsyn").write_text("<TerraSynth version='1'><PPA><Input>b.tsyn</Input></PPA></TerraSynth>")
    (tmp_path / "b.tsyn").write_text("<TerraSynth version='1'><PPA><Input>a.tsyn</Input></PPA></TerraSynth>")
    with pytest.raises(RuntimeError, match="recursion|nested"):
        gdal.Open(str(tmp_path / "a.tsyn"))


def test_compute_error_is_a_read_error(tmp_path):
    # an exemplar smaller than a patch fails when the cells are read, with a GDAL error
    write_tif(tmp_path / "tiny.tif", np.ones((20, 20), np.float32))
    (tmp_path / "t.tsyn").write_text(
        "<TerraSynth version='1'><Synth><Exemplar>tiny.tif</Exemplar>"
        "<Grid width='100' height='100'/></Synth></TerraSynth>")
    ds = gdal.Open(str(tmp_path / "t.tsyn"))
    with pytest.raises(RuntimeError, match="smaller than a patch"):
        ds.ReadAsArray()


# ---------------------------------------------------------------- pixel functions


def pixfun_vrt(path, func, sources, args="", nodata=None, size=(40, 30)):
    srcs = "".join(
        f"<SimpleSource><SourceFilename>{s}</SourceFilename><SourceBand>1</SourceBand></SimpleSource>"
        for s in sources)
    nd = f"<NoDataValue>{nodata}</NoDataValue>" if nodata is not None else ""
    path.write_text(
        f'<VRTDataset rasterXSize="{size[0]}" rasterYSize="{size[1]}">'
        '<SRS>EPSG:32611</SRS><GeoTransform>400000, 30, 0, 3800000, 0, -30</GeoTransform>'
        f'<VRTRasterBand dataType="Float32" band="1" subClass="VRTDerivedRasterBand">{nd}'
        f"<PixelFunctionType>{func}</PixelFunctionType><PixelFunctionArguments {args}/>{srcs}"
        "</VRTRasterBand></VRTDataset>")


@pytest.fixture()
def rasters(tmp_path):
    rng = np.random.default_rng(1)
    t1 = (1000 + 300 * rng.random((30, 40))).astype(np.float32)
    t2 = (500 + 100 * rng.random((30, 40))).astype(np.float32)
    w1 = rng.random((30, 40)).astype(np.float32)
    w2 = (1 - w1).astype(np.float32)
    t1[0, 0] = -9999
    for name, a in (("t1", t1), ("t2", t2), ("w1", w1), ("w2", w2)):
        write_tif(tmp_path / f"{name}.tif", a, nodata=-9999 if name[0] == "t" else None)
    return tmp_path, t1, t2, w1, w2


def test_pixfun_blend(rasters):
    d, t1, t2, w1, w2 = rasters
    pixfun_vrt(d / "b.vrt", "tsyn_blend", [d / "t1.tif", d / "t2.tif", d / "w1.tif", d / "w2.tif"],
               'nodata="-9999"', nodata=-9999)
    tool("gdal_translate", "-q", d / "b.vrt", d / "b.tif")
    got = arr(d / "b.tif")
    want = (w1 * t1 + w2 * t2) / (w1 + w2)
    want[0, 0] = t2[0, 0]  # the nodata terrain does not count
    assert np.allclose(got, want, rtol=1e-5)


def test_pixfun_rescale_units_water(rasters):
    d, t1, *_ = rasters
    pixfun_vrt(d / "r.vrt", "tsyn_rescale", [d / "t1.tif"],
               'from_min="1000" from_max="1300" to_min="0" to_max="1" nodata="-9999"', nodata=-9999)
    r = gdal.Open(str(d / "r.vrt")).ReadAsArray()
    assert r[0, 0] == -9999 and np.allclose(r.ravel()[1:], ((t1 - 1000) / 300).ravel()[1:], atol=1e-5)
    pixfun_vrt(d / "u.vrt", "tsyn_units", [d / "t1.tif"], 'from="ft" to="m" nodata="-9999"', nodata=-9999)
    u = gdal.Open(str(d / "u.vrt")).ReadAsArray()
    assert np.allclose(u.ravel()[1:], (t1 * 0.3048).ravel()[1:], rtol=1e-6)
    for mode, f in (("fill", lambda z: np.maximum(z, 1150)), ("depth", lambda z: np.maximum(1150 - z, 0)),
                    ("mask", lambda z: (z < 1150).astype(np.float32))):
        pixfun_vrt(d / "w.vrt", "tsyn_water", [d / "t1.tif"], f'level="1150" mode="{mode}" nodata="-9999"',
                   nodata=-9999)
        w = gdal.Open(str(d / "w.vrt")).ReadAsArray()
        assert np.allclose(w.ravel()[1:], f(t1).ravel()[1:], atol=1e-4), mode


@pytest.mark.parametrize(
    "func,args,nsrc,words",
    [
        ("tsyn_rescale", 'from_min="0" from_max="1" to_min="0"', 1, "to_max"),
        ("tsyn_rescale", 'from_min="0" from_max="0" to_min="0" to_max="1"', 1, "equals"),
        ("tsyn_rescale", 'from_min="a" from_max="1" to_min="0" to_max="1"', 1, "not a number"),
        ("tsyn_units", 'from="furlong" to="m"', 1, "ft"),
        ("tsyn_water", 'mode="fill"', 1, "level"),
        ("tsyn_water", 'level="1" mode="swim"', 1, "swim"),
        ("tsyn_blend", "", 3, "even"),
        ("tsyn_water", 'level="1"', 2, "1 source"),
    ],
)
def test_pixfun_bad_arguments(rasters, func, args, nsrc, words):
    d = rasters[0]
    pixfun_vrt(d / "bad.vrt", func, [d / "t1.tif"] * nsrc, args)
    with pytest.raises(RuntimeError, match=words):
        gdal.Open(str(d / "bad.vrt")).ReadAsArray()


def test_sketch_recipe_with_pin_and_water_equals_cli(tmp_path):
    sketch = os.path.join(DATA, "sketches", "lambda_ridges.tif")
    mask = np.zeros((512, 512), np.uint8)
    mask[400:450, 30:120] = 1
    sk = gdal.Open(sketch)
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "water.tif"), 512, 512, 1, gdal.GDT_Byte)
    ds.SetGeoTransform(sk.GetGeoTransform())
    ds.SetProjection(sk.GetProjection())
    ds.GetRasterBand(1).WriteArray(mask)
    ds = None
    args = ["--sketch", sketch, "--exemplar", JACKSBORO, "--seed", "3", "--patch-size", "32", "--overlap", "8",
            "--pin", f"{JACKSBORO}:200,150,60,40@300,20", "--water", tmp_path / "water.tif", "--water-level", "250"]
    ts("synth", *args, "--recipe", tmp_path / "s.tsyn")
    ts("synth", *args, tmp_path / "cli.tif", "-q")
    text = (tmp_path / "s.tsyn").read_text()
    assert "<Sketch>" in text and "<Pin " in text and "<Water level=" in text
    tool("gdal_translate", "-q", tmp_path / "s.tsyn", tmp_path / "gdal.tif")
    a = arr(tmp_path / "gdal.tif")
    assert a.tobytes() == arr(tmp_path / "cli.tif").tobytes()
    assert (a[400:450, 30:120] == 250).all()


def test_open_options_take_the_sketch_parameters(tmp_path):
    """-oo ALPHA_R=... and the other sketch parameters on a synth recipe with a sketch give
    what the command line gives with the same flags."""
    sketch = os.path.join(DATA, "sketches", "lambda_ridges.tif")
    args = ["--sketch", sketch, "--exemplar", JACKSBORO, "--seed", "3", "--patch-size", "32",
            "--overlap", "8"]
    ts("synth", *args, "--recipe", tmp_path / "s.tsyn")
    ts("synth", *args, "--alpha-r", "0", "--layout", "0.5", tmp_path / "cli.tif", "-q")
    ds = gdal.OpenEx(str(tmp_path / "s.tsyn"), open_options=["ALPHA_R=0", "LAYOUT=0.5"])
    assert ds.ReadAsArray().tobytes() == arr(tmp_path / "cli.tif").tobytes()
    ds = None
    base = gdal.Open(str(tmp_path / "s.tsyn")).ReadAsArray()
    assert base.tobytes() != arr(tmp_path / "cli.tif").tobytes()
    with pytest.raises(RuntimeError, match="layout"):
        gdal.OpenEx(str(tmp_path / "s.tsyn"), open_options=["LAYOUT=3"])


def test_multistyle_recipe_equals_cli(tmp_path):
    regions = os.path.join(DATA, "sketches", "multistyle_regions.tif")
    sketch = os.path.join(DATA, "sketches", "multistyle_sketch.tif")
    args = ["--sketch", sketch, "--regions", regions, "--region-exemplar", f"1={JACKSBORO}",
            "--region-exemplar", f"2={JACKSBORO}", "--seed", "2", "--patch-size", "32", "--overlap", "8"]
    ts("synth", *args, "--recipe", tmp_path / "m.tsyn")
    ts("synth", *args, tmp_path / "cli.tif", "-q")
    assert "<RegionExemplar" in (tmp_path / "m.tsyn").read_text()
    tool("gdal_translate", "-q", tmp_path / "m.tsyn", tmp_path / "gdal.tif")
    assert arr(tmp_path / "gdal.tif").tobytes() == arr(tmp_path / "cli.tif").tobytes()


def test_open_option_map_serves_the_synthesis_maps(tmp_path):
    """-oo MAP= serves where the cells came from, as --debug-dir writes them; checked against
    what they mean: a copied patch keeps its exemplar's layout, seams lie between patches."""
    args = ["--exemplar", JACKSBORO, "--size", "150x140", "--seed", "3", "--patch-size", "32",
            "--overlap", "8"]
    ts("synth", *args, "--recipe", tmp_path / "s.tsyn")
    ts("synth", *args, tmp_path / "cli.tif", "--debug-dir", tmp_path / "dbg", "-q")
    maps = {}
    for name in ("seams", "source_exemplar", "source_x", "source_y", "order"):
        ds = gdal.OpenEx(str(tmp_path / "s.tsyn"), open_options=["MAP=" + name])
        band = ds.GetRasterBand(1)
        want_type = gdal.GDT_Byte if name == "seams" else gdal.GDT_Int32
        assert band.DataType == want_type, name
        assert band.GetNoDataValue() == (255 if name == "seams" else -1)
        assert ds.GetGeoTransform() == gdal.Open(str(tmp_path / "cli.tif")).GetGeoTransform()
        maps[name] = band.ReadAsArray()
        cli = arr(tmp_path / "dbg" / (name + ".tif"))
        assert (maps[name].astype(np.float64) == np.nan_to_num(cli, nan=-1)).all(), name
    # the terrain is the default, and MAP=dem says so
    dem = gdal.OpenEx(str(tmp_path / "s.tsyn"), open_options=["MAP=dem"]).ReadAsArray()
    assert dem.tobytes() == arr(tmp_path / "cli.tif").tobytes()
    # meaning: one exemplar; every cell placed; inside a patch, the source advances with x, y
    order, sx, sy, seams = maps["order"], maps["source_x"], maps["source_y"], maps["seams"]
    assert (maps["source_exemplar"] == 0).all() and (order >= 0).all()
    same = order[:, 1:] == order[:, :-1]
    assert same.mean() > 0.8
    assert (sx[:, 1:][same] == sx[:, :-1][same] + 1).all()
    assert (sy[:, 1:][same] == sy[:, :-1][same]).all()
    # a seam cell borders a cell of another patch
    diff = np.zeros(order.shape, bool)
    diff[:, 1:] |= order[:, 1:] != order[:, :-1]
    diff[:, :-1] |= order[:, 1:] != order[:, :-1]
    diff[1:, :] |= order[1:, :] != order[:-1, :]
    diff[:-1, :] |= order[1:, :] != order[:-1, :]
    assert seams.sum() > 0 and (diff[seams == 1]).all()
    with pytest.raises(RuntimeError, match="MAP=nope: not one of dem, seams"):
        gdal.OpenEx(str(tmp_path / "s.tsyn"), open_options=["MAP=nope"])
    ts("ppa", JACKSBORO, "--recipe", tmp_path / "p.tsyn")
    with pytest.raises(RuntimeError, match="not an option of ppa recipes"):
        gdal.OpenEx(str(tmp_path / "p.tsyn"), open_options=["MAP=seams"])


# ---------------------------------------------------------------- untrusted recipes

class Listener:
    """A local TCP port that records whether anything connected to it."""

    def __init__(self):
        import socket
        import threading

        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(4)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.hits = 0
        self.stop = False
        self.t = threading.Thread(target=self._serve, daemon=True)
        self.t.start()

    def _serve(self):
        import socket

        while not self.stop:
            try:
                c, _ = self.sock.accept()
            except socket.timeout:
                continue
            except OSError:
                return
            self.hits += 1
            c.close()

    def close(self):
        self.stop = True
        self.t.join()
        self.sock.close()


@pytest.mark.parametrize("where", ["crs", "exemplar", "vsicurl"])
def test_a_recipe_never_reaches_out(tmp_path, where):
    import shutil

    shutil.copy(JACKSBORO, tmp_path / "dem.tif")
    srv = Listener()
    url = "http://127.0.0.1:%d/x" % srv.port
    grid = "<Grid width='64' height='64' originX='0' originY='0' resolution='30' crs='%s'/>"
    ex, crs = "dem.tif", "EPSG:32611"
    if where == "crs":
        crs = url
    else:
        ex = (url if where == "exemplar" else "/vsicurl/" + url) + ".tif"
    (tmp_path / "r.tsyn").write_text("<TerraSynth version='1'><Synth><Exemplar>%s</Exemplar>%s"
                                     "</Synth></TerraSynth>" % (ex, grid % crs))
    try:
        p = tool("gdalinfo", tmp_path / "r.tsyn", check=False)
        assert p.returncode != 0 and "r.tsyn" in p.stderr
        want = "never a file or an address" if where == "crs" else "names a network resource"
        assert want in p.stderr, p.stderr
        import time
        time.sleep(0.3)
        assert srv.hits == 0
        if where == "vsicurl":
            # the user may allow it: then GDAL does go there
            p = tool("gdalinfo", "-checksum", "--config", "TSYN_ALLOW_NETWORK", "YES",
                     tmp_path / "r.tsyn",
                     check=False)
            assert "names a network resource" not in p.stderr
            time.sleep(0.3)
            assert srv.hits > 0
    finally:
        srv.close()


@pytest.mark.parametrize("crs", ["/etc/hostname", "../secret.prj", "+init=epsg:4326"])
def test_a_recipe_crs_reads_no_file(tmp_path, crs):
    import shutil

    shutil.copy(JACKSBORO, tmp_path / "dem.tif")
    (tmp_path / "r.tsyn").write_text(
        "<TerraSynth version='1'><Synth><Exemplar>dem.tif</Exemplar><Grid width='64' "
        "height='64' originX='0' originY='0' resolution='30' crs='%s'/></Synth></TerraSynth>"
        % crs)
    with pytest.raises(RuntimeError, match="never a file or an address"):
        gdal.Open(str(tmp_path / "r.tsyn"))
    # the forms a recipe does take
    for ok, res in (("EPSG:32611", 30), (osr.SRS_WKT_WGS84_LAT_LONG.replace("'", '"'), 0.001)):
        (tmp_path / "ok.tsyn").write_text(
            "<TerraSynth version='1'><Synth><Exemplar>dem.tif</Exemplar><Grid width='64' "
            "height='64' originX='0' originY='0' resolution='%g' crs='%s'/></Synth></TerraSynth>"
            % (res, ok))
        assert gdal.Open(str(tmp_path / "ok.tsyn")).RasterXSize == 64


SYNTH_GRID = "<Grid width='64' height='64' originX='0' originY='0' resolution='30' crs='EPSG:32611'/>"


@pytest.mark.parametrize("element", [
    "<Exemplar>{}</Exemplar>" + SYNTH_GRID,
    "<Exemplar>dem.tif</Exemplar><Sketch>{}</Sketch>",
    "<Exemplar>dem.tif</Exemplar><Grid like='{}'/>",
    "<Exemplar>dem.tif</Exemplar>" + SYNTH_GRID + "<Water level='3'>{}</Water>",
    "<Exemplar>dem.tif</Exemplar>" + SYNTH_GRID + "<Heights>{}</Heights>",
    "<Exemplar>dem.tif</Exemplar>" + SYNTH_GRID +
    "<Pin xoff='0' yoff='0' width='8' height='8' x='1' y='1'>{}</Pin>",
    "<Exemplar>dem.tif</Exemplar>" + SYNTH_GRID + "<Regions>{}</Regions>"
    "<RegionExemplar id='1'>dem.tif</RegionExemplar>",
    "<Exemplar>dem.tif</Exemplar>" + SYNTH_GRID + "<Regions>reg.tif</Regions>"
    "<RegionExemplar id='1'>{}</RegionExemplar>",
], ids=["exemplar", "sketch", "like", "water", "heights", "pin", "regions", "region_exemplar"])
def test_recipe_loops_refused_at_open(tmp_path, element):
    """A loop through any input, direct or through another recipe, is refused when the
    recipe is opened, in one line naming the chain (not 8 levels deep, and not as "not a
    raster")."""
    import shutil

    shutil.copy(JACKSBORO, tmp_path / "dem.tif")
    write_tif(tmp_path / "reg.tif", np.ones((64, 64), np.float32), srs="EPSG:32611",
              gt=(0, 30, 0, 0, 0, -30))
    body = "<TerraSynth version='1'><Synth>%s</Synth></TerraSynth>"
    (tmp_path / "self.tsyn").write_text(body % element.format("self.tsyn"))
    (tmp_path / "a.tsyn").write_text(body % element.format("b.tsyn"))
    (tmp_path / "b.tsyn").write_text(body % element.format("a.tsyn"))
    for name, chain in (("self.tsyn", "self.tsyn -> self.tsyn"),
                        ("a.tsyn", "a.tsyn -> b.tsyn -> a.tsyn")):
        p = tool("gdalinfo", "-checksum", tmp_path / name, check=False)
        assert p.returncode != 0
        errors = [l for l in p.stderr.splitlines() if l.startswith("ERROR")]
        assert len(errors) == 1, p.stderr
        assert "in a loop (recursion): " + chain in errors[0], p.stderr


def test_recipe_nesting_limit_names_the_chain(tmp_path):
    import shutil

    shutil.copy(JACKSBORO, tmp_path / "dem.tif")
    body = "<TerraSynth version='1'><Synth><Exemplar>%s</Exemplar>" + SYNTH_GRID + \
        "</Synth></TerraSynth>"
    for i in range(10):
        (tmp_path / ("r%d.tsyn" % i)).write_text(body % ("r%d.tsyn" % (i + 1) if i < 9
                                                         else "dem.tif"))
    with pytest.raises(RuntimeError, match=r"nested more than 8 deep: r0.tsyn -> r1.tsyn"):
        gdal.Open(str(tmp_path / "r0.tsyn"))
    # 8 deep is fine
    assert gdal.Open(str(tmp_path / "r3.tsyn")).RasterXSize == 64


def test_pixel_recipe_overviews(tmp_path):
    """A pixel recipe has overviews of 2^k (while 128 cells or more a side), on the grid GDAL
    expects (ceil of the size over the factor, the cell size times the factor); each
    follows the full-resolution terrain averaged over its blocks (the oracle: numpy's
    block means of the whole read at full resolution); a 100 000^2 recipe gives a 100 x 100
    thumbnail at once (it made every cell before: hours)."""
    recipe = tmp_path / "p.tsyn"
    ts("pixel", "--exemplar", JACKSBORO, "--size", "1000x600", "--seed", 4, "--recipe", recipe)
    ds = gdal.Open(str(recipe))
    band = ds.GetRasterBand(1)
    assert band.GetOverviewCount() == 2  # 500, 250 (125 < 128: no more)
    gt = ds.GetGeoTransform()
    full = band.ReadAsArray().astype(np.float64)
    for i, (w, h) in enumerate([(500, 300), (250, 150)]):
        ov = band.GetOverview(i)
        b = 2 ** (i + 1)
        assert (ov.XSize, ov.YSize) == (w, h)
        ogt = ov.GetDataset().GetGeoTransform()
        assert ogt[0] == gt[0] and ogt[3] == gt[3] and abs(ogt[1] - gt[1] * b) < 1e-12
        got = ov.ReadAsArray().astype(np.float64)
        means = full[:h * b, :w * b].reshape(h, b, w, b).mean(axis=(1, 3))
        corr = np.corrcoef(got.ravel(), means.ravel())[0, 1]
        assert corr > 0.95, (b, corr)
        assert np.sqrt(((got - means) ** 2).mean()) < 0.35 * means.std(), b
        # a window alone is the same cells as the whole overview's
        assert np.array_equal(ov.ReadAsArray(37, 11, 40, 30), got[11:41, 37:77])
    ds = None
    big = tmp_path / "big.tsyn"
    ts("pixel", "--exemplar", JACKSBORO, "--size", "100000x100000", "--seed", 4,
       "--recipe", big)
    tool("gdal_translate", "-q", "-outsize", "100", "100", big, tmp_path / "thumb.tif")
    t = arr(tmp_path / "thumb.tif")
    assert t.shape == (100, 100) and np.isfinite(t).all() and t.std() > 1


def test_amplify_recipe_overview_is_its_input(tmp_path):
    """An amplify recipe's first overview (the factor) is its input, cell for cell; the
    next ones the input averaged; the terrain averaged by the factor is close to it."""
    coarse = tmp_path / "coarse.tif"
    gdal.Warp(str(coarse), JACKSBORO, xRes=0.0025, yRes=0.0025, resampleAlg="average")
    recipe = tmp_path / "a.tsyn"
    ts("amplify", coarse, "--recipe", recipe, "--exemplar", JACKSBORO, "--factor", 4)
    ds = gdal.Open(str(recipe))
    band = ds.GetRasterBand(1)
    c = arr(coarse).astype(np.float32)
    assert band.GetOverviewCount() >= 1
    assert np.array_equal(band.GetOverview(0).ReadAsArray(), c)
    full = band.ReadAsArray().astype(np.float64)
    H, W = c.shape
    m = full[:H * 4, :W * 4].reshape(H, 4, W, 4).mean(axis=(1, 3))
    assert np.median(np.abs(m - c)) < 2.0


@pytest.mark.parametrize("job", ["amplify", "pixel", "sketch"])
def test_large_reads_equal_blocks_and_the_cli(tmp_path, job):
    """A read of a drained lazy recipe over many blocks is made in windows drained once each
    (not block by block, each with the whole margin again): the same bytes as the command
    line's whole run and as the same cells read one block at a time, in Float32 and
    converted (Float64), into a buffer with a gap between rows."""
    if job == "amplify":
        coarse = tmp_path / "coarse.tif"
        gdal.Warp(str(coarse), JACKSBORO, xRes=0.0025, yRes=0.0025, resampleAlg="average")
        args = ["amplify", coarse, "--exemplar", JACKSBORO, "--factor", 4]
    elif job == "pixel":
        args = ["pixel", "--exemplar", JACKSBORO, "--size", "700x600", "--seed", 3]
    else:
        args = ["synth", "--exemplar", JACKSBORO, "--sketch",
                os.path.join(DATA, "sketches", "ridges_valleys.tif"), "--tiled", 256]
    ts(*args, tmp_path / "cli.tif")
    ts(*args, "--recipe", tmp_path / "r.tsyn")
    cli = arr(tmp_path / "cli.tif")
    ds = gdal.Open(str(tmp_path / "r.tsyn"))
    band = ds.GetRasterBand(1)
    bx, by = band.GetBlockSize()
    H, W = cli.shape
    x0, y0, w, h = 37, 41, W - 60, H - 80  # many blocks, not on their corners
    got = band.ReadAsArray(x0, y0, w, h)
    assert got.dtype == np.float32 and got.tobytes() == cli[y0:y0 + h, x0:x0 + w].tobytes()
    f64 = band.ReadAsArray(x0, y0, w, h, buf_type=gdal.GDT_Float64)
    assert np.array_equal(f64, cli[y0:y0 + h, x0:x0 + w].astype(np.float64))
    raw = band.ReadRaster(x0, y0, w, h, buf_type=gdal.GDT_Float32, buf_pixel_space=8,
                          buf_line_space=8 * w + 16)
    gapped = np.frombuffer(raw, np.float32, count=(2 * w + 4) * (h - 1) + 2 * (w - 1) + 1)
    assert np.array_equal(np.lib.stride_tricks.as_strided(gapped, (h, w), (8 * w + 16, 8)),
                          cli[y0:y0 + h, x0:x0 + w])
    ds = None
    ds = gdal.Open(str(tmp_path / "r.tsyn"))  # a fresh dataset: one block at a time
    band = ds.GetRasterBand(1)
    for yb in range(0, H, by):
        for xb in range(0, W, bx):
            b = band.ReadBlock(xb // bx, yb // by)
            a = np.frombuffer(b, np.float32).reshape(by, bx)
            hh, ww = min(by, H - yb), min(bx, W - xb)
            assert a[:hh, :ww].tobytes() == cli[yb:yb + hh, xb:xb + ww].tobytes(), (xb, yb)


def test_a_huge_synth_recipe_zoomed_out_is_refused_with_why(tmp_path):
    """A tiled synth recipe has no overviews: reading 65536^2 cells for a thumbnail is
    refused at once in one line that says why and what to do (it would make every cell);
    a small one zoomed out is read as before."""
    big = tmp_path / "s.tsyn"
    ts("synth", "--exemplar", JACKSBORO, "--size", "65536x65536", "--tiled", 256, "--seed", 3,
       "--recipe", big)
    p = tool("gdal_translate", "-q", "-outsize", "100", "100", big, tmp_path / "t.tif",
             check=False)
    assert p.returncode != 0 and "has no overviews" in p.stderr and "terrasynth-dask" in p.stderr
    small = tmp_path / "m.tsyn"
    ts("synth", "--exemplar", JACKSBORO, "--size", "600x400", "--tiled", 256, "--seed", 3,
       "--recipe", small)
    tool("gdal_translate", "-q", "-outsize", "60", "40", small, tmp_path / "m.tif")
    assert arr(tmp_path / "m.tif").shape == (40, 60)
