# SPDX-License-Identifier: GPL-2.0-or-later
"""The bad-input suite: every line of cases.txt is a command that must fail with
its exit status and message, in one line, leaving its folder exactly as it was (every file
hashed before and after).  Runs the CLI, the GDAL tools over recipes (the TSYN plugin) and
VRT pixel functions."""
import hashlib
import os
import shlex
import shutil
import stat
import subprocess
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
TERRASYNTH = os.environ.get("TERRASYNTH", os.path.join(ROOT, "build", "gdal_driver", "terrasynth"))
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
DATA = os.environ.get("TS_DATA_DIR", os.path.join(ROOT, "data"))
DEM = os.path.join(DATA, "jacksboro_fault_dem.tif")
SKETCH = os.path.join(DATA, "sketches", "lambda_ridges.tif")

from osgeo import gdal, ogr, osr  # noqa: E402

gdal.UseExceptions()


def read_cases():
    cases = []
    with open(os.path.join(HERE, "cases.txt")) as f:
        for n, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            status, fragment, command = (p.strip() for p in line.split("|", 2))
            cases.append(pytest.param(status, fragment, command, id="%d:%s" % (n, command[:60])))
    return cases


def write_dem(path, z, gt, wkt):
    ds = gdal.GetDriverByName("GTiff").Create(str(path), z.shape[1], z.shape[0], 1,
                                              gdal.GDT_Float32)
    ds.SetGeoTransform(gt)
    ds.SetProjection(wkt)
    ds.GetRasterBand(1).WriteArray(z)
    ds = None


GRID = "<Grid width='64' height='64' originX='0' originY='0' resolution='30' crs='%s'/>"
RECIPES = {
    "self.tsyn": "<PPA><Input>self.tsyn</Input></PPA>",
    "a.tsyn": "<Synth><Exemplar>b.tsyn</Exemplar>" + GRID % "EPSG:32616" + "</Synth>",
    "b.tsyn": "<Synth><Exemplar>dem.tif</Exemplar>" + GRID % "EPSG:32616" +
              "<Heights>a.tsyn</Heights></Synth>",
    "crs_file.tsyn": "<Synth><Exemplar>dem.tif</Exemplar>" + GRID % "/etc/hostname" + "</Synth>",
    "crs_url.tsyn": "<Synth><Exemplar>dem.tif</Exemplar>" + GRID % "http://127.0.0.1:9/x" +
                    "</Synth>",
    "vsicurl.tsyn": "<Synth><Exemplar>/vsicurl/http://127.0.0.1:9/x.tif</Exemplar>" +
                    GRID % "EPSG:32616" + "</Synth>",
    "huge.tsyn": "<Synth><Exemplar>dem.tif</Exemplar><Grid width='65536' height='65536'/>"
                 "</Synth>",
    "seed.tsyn": "<Synth seed='18446744073709551616'><Exemplar>dem.tif</Exemplar>" +
                 GRID % "EPSG:32616" + "</Synth>",
    "ok.tsyn": "<Synth><Exemplar>dem.tif</Exemplar>" + GRID % "EPSG:32616" + "</Synth>",
    "pin_far.tsyn": "<Synth><Exemplar>dem.tif</Exemplar>" + GRID % "EPSG:32616" +
                    "<Pin xoff='2147483600' yoff='0' width='100' height='20' x='0' y='0'>"
                    "dem.tif</Pin></Synth>",
    # a recipe's typos are refused, not ignored
    "watter.tsyn": "<Synth><Exemplar>dem.tif</Exemplar>" + GRID % "EPSG:32616" +
                   "<Watter level='300'>mask.tif</Watter></Synth>",
    "sed.tsyn": "<Synth sed='5'><Exemplar>dem.tif</Exemplar>" + GRID % "EPSG:32616" + "</Synth>",
    "bnd.tsyn": "<PPA><Input bnd='2'>dem.tif</Input></PPA>",
    "two_jobs.tsyn": "<Synth><Exemplar>dem.tif</Exemplar>" + GRID % "EPSG:32616" +
                     "</Synth><PPA><Input>dem.tif</Input></PPA>",
    "pin_off.tsyn": "<Synth><Exemplar>dem.tif</Exemplar>" + GRID % "EPSG:32616" +
                    "<Pin xoff='0' yoff='0' width='20' height='20' x='2147483640' y='0'>"
                    "dem.tif</Pin></Synth>",
}


def pixfun_vrt(path, func, args):
    path.write_text(
        '<VRTDataset rasterXSize="40" rasterYSize="30"><SRS>EPSG:32611</SRS>'
        '<GeoTransform>400000, 30, 0, 3800000, 0, -30</GeoTransform>'
        '<VRTRasterBand dataType="Float32" band="1" subClass="VRTDerivedRasterBand">'
        '<PixelFunctionType>%s</PixelFunctionType><PixelFunctionArguments %s/>'
        '<SimpleSource><SourceFilename relativeToVRT="1">dem.tif</SourceFilename>'
        '<SourceBand>1</SourceBand></SimpleSource></VRTRasterBand></VRTDataset>' % (func, args))


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    """The work folder every case starts from."""
    w = tmp_path_factory.mktemp("bad_inputs")
    shutil.copy(DEM, w / "dem.tif")
    shutil.copy(SKETCH, w / "sketch.tif")
    src = gdal.Open(DEM)
    z = src.ReadAsArray().astype(np.float32)
    gt, wkt = src.GetGeoTransform(), src.GetProjection()
    m = (z < np.percentile(z, 20)).astype(np.float32)
    write_dem(w / "mask.tif", m, gt, wkt)
    e = z.copy()
    e[100:104, 200:204] = 1e30
    write_dem(w / "e30.tif", e, gt, wkt)
    write_dem(w / "pole.tif", z, (0, 0.01, 0, 92, 0, -0.01), wkt)
    # a grid without meaning (cell size 0), complex numbers as elevations
    (w / "zerocell.vrt").write_text(
        '<VRTDataset rasterXSize="%d" rasterYSize="%d"><GeoTransform>%r, 0, 0, %r, 0, %r'
        '</GeoTransform><VRTRasterBand dataType="Float32" band="1"><SimpleSource>'
        '<SourceFilename relativeToVRT="1">dem.tif</SourceFilename><SourceBand>1</SourceBand>'
        '</SimpleSource></VRTRasterBand></VRTDataset>'
        % (z.shape[1], z.shape[0], gt[0], gt[3], gt[5]))
    c = gdal.GetDriverByName("GTiff").Create(str(w / "complex.tif"), z.shape[1], z.shape[0], 1,
                                             gdal.GDT_CFloat32)
    c.SetGeoTransform(gt)
    c.SetProjection(wkt)
    c.GetRasterBand(1).WriteArray(z.astype(np.complex64))
    c = None
    # rasters of the same size on another grid: shifted 100 cells, in another CRS
    write_dem(w / "mask_far.tif", m, (gt[0] + 100 * gt[1],) + tuple(gt[1:]), wkt)
    utm = osr.SpatialReference()
    utm.ImportFromEPSG(32616)
    write_dem(w / "mask_crs.tif", m, gt, utm.ExportToWkt())
    write_dem(w / "flat.tif", np.full(z.shape, 300, np.float32), gt, wkt)
    # region maps that say nothing usable: a fractional id, ids as text, points, far away
    r = np.ones(z.shape, np.float32)
    r[10:20, 10:20] = 1.6
    write_dem(w / "regfloat.tif", r, gt, wkt)
    cx, cy = gt[0] + gt[1] * z.shape[1] / 2, gt[3] + gt[5] * z.shape[0] / 2
    far = gt[1] * z.shape[1] * 100
    for name, geom, ftype, value, dx in (
            ("regstr", ogr.wkbPolygon, ogr.OFTString, "2abc", 0),
            ("regpts", ogr.wkbPoint, ogr.OFTInteger, 2, 0),
            ("regfar", ogr.wkbPolygon, ogr.OFTInteger, 2, far)):
        ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(w / (name + ".gpkg")))
        srs = osr.SpatialReference(wkt=wkt)
        lyr = ds.CreateLayer("regions", srs, geom)
        lyr.CreateField(ogr.FieldDefn("region", ftype))
        f = ogr.Feature(lyr.GetLayerDefn())
        f.SetField("region", value)
        s_ = abs(gt[1]) * 20
        wkt_g = ("POINT (%r %r)" % (cx + dx, cy) if geom == ogr.wkbPoint else
                 "POLYGON ((%r %r, %r %r, %r %r, %r %r, %r %r))" % (
                     cx + dx - s_, cy - s_, cx + dx + s_, cy - s_, cx + dx + s_, cy + s_,
                     cx + dx - s_, cy + s_, cx + dx - s_, cy - s_))
        f.SetGeometry(ogr.CreateGeometryFromWkt(wkt_g))
        lyr.CreateFeature(f)
        ds = None
    (w / "text.tif").write_text("this is not a raster\n")
    (w / "empty.tif").write_bytes(b"")
    (w / "broken.tsyn").write_text("<TerraSynth version='1'><Synth><Exemplar>")
    for name, body in RECIPES.items():
        (w / name).write_text("<TerraSynth version='1'>%s</TerraSynth>" % body)
    pixfun_vrt(w / "pix_rescale.vrt", "tsyn_rescale", 'from_min="0" from_max="1" to_min="0"')
    pixfun_vrt(w / "pix_water.vrt", "tsyn_water", 'level="1" mode="swim"')
    return w


def state(d):
    """Every entry under d: its kind and, for files, a digest of the bytes."""
    out = {}
    for root, dirs, files in os.walk(d):
        for name in dirs + files:
            p = os.path.join(root, name)
            st = os.lstat(p)
            if stat.S_ISREG(st.st_mode):
                with open(p, "rb") as f:
                    out[os.path.relpath(p, d)] = hashlib.sha256(f.read()).hexdigest()
            else:
                out[os.path.relpath(p, d)] = stat.S_IFMT(st.st_mode)
    return out


def tool_env():
    env = dict(os.environ, GDAL_DRIVER_PATH=PLUGINS)
    if os.environ.get("TS_TOOL_PRELOAD"):  # an instrumented plugin in a plain tool
        env.update(LD_PRELOAD=os.environ["TS_TOOL_PRELOAD"], ASAN_OPTIONS="detect_leaks=0")
    return env


@pytest.mark.parametrize("status,fragment,command", read_cases())
def test_bad_input(template, tmp_path, status, fragment, command):
    w = tmp_path / "w"
    shutil.copytree(template, w, symlinks=True)
    os.symlink(w / "dem.tif", w / "link.tif")
    os.mkfifo(w / "fifo.tif")
    subst = {k: str(w / v) for k, v in (("dem", "dem.tif"), ("link", "link.tif"),
                                        ("sketch", "sketch.tif"), ("mask", "mask.tif"),
                                        ("text", "text.tif"), ("empty", "empty.tif"),
                                        ("fifo", "fifo.tif"), ("pole", "pole.tif"),
                                        ("e30", "e30.tif"))}
    subst["w"] = str(w)
    argv = [a.format(**subst) for a in shlex.split(command)]
    fragment = fragment.format(**subst)
    env = dict(os.environ)
    if argv[0] == "terrasynth":
        argv[0] = TERRASYNTH
    elif argv[0] == "python-update":
        argv = [sys.executable, "-c", "import sys; from osgeo import gdal; gdal.UseExceptions(); "
                "gdal.Open(sys.argv[1], gdal.GA_Update)", argv[1]]
        env = tool_env()
    else:
        env = tool_env()
    before = state(w)
    p = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=300, cwd=w)
    err = p.stderr + p.stdout
    if status == "!0":
        assert p.returncode > 0, err
    else:
        assert p.returncode == int(status), err
    assert fragment in err, err
    if argv[0] == TERRASYNTH:
        lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
        assert len(lines) == 1, p.stderr
    assert state(w) == before, "the folder changed"
