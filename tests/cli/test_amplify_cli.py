# SPDX-License-Identifier: GPL-2.0-or-later
"""`terrasynth amplify` end to end (issue 13): the output grid (extent, CRS, resolution,
nodata) read back with GDAL; the output averages back to the input (numpy); recipes through
the TSYN driver; determinism; and the super-resolution check on real data against
`gdalwarp -r cubic`, judged by ../shared/eval/terrain_metrics.py (none of our code)."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import JACKSBORO, ROOT, SHARED, plugin_env, run  # noqa: E402

gdal.UseExceptions()
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
METRICS = os.path.join(os.path.dirname(os.path.dirname(SHARED)), "eval", "terrain_metrics.py")


def write(path, a, gt, wkt, nodata=None):
    ds = gdal.GetDriverByName("GTiff").Create(str(path), a.shape[1], a.shape[0], 1,
                                              gdal.GDT_Float32)
    ds.SetGeoTransform(gt)
    ds.SetProjection(wkt)
    if nodata is not None:
        ds.GetRasterBand(1).SetNoDataValue(nodata)
    ds.GetRasterBand(1).WriteArray(a)
    ds = None


def test_grid_nodata_and_averaging_back(tmp_path):
    src = gdal.Open(JACKSBORO)
    z = src.ReadAsArray().astype(np.float32)[:200, :240]
    z[50:60, 70:85] = -32768
    gt = src.GetGeoTransform()
    write(tmp_path / "in.tif", z, gt, src.GetProjection(), nodata=-32768)
    out = tmp_path / "out.tif"
    p = run("amplify", tmp_path / "in.tif", out, "--exemplar", JACKSBORO, "--factor", "3")
    assert "amplify: 240 x 200 -> 720 x 600 cells (x3)" in p.stdout
    ds = gdal.Open(str(out))
    assert (ds.RasterXSize, ds.RasterYSize) == (720, 600)
    assert ds.GetGeoTransform() == pytest.approx((gt[0], gt[1] / 3, 0, gt[3], 0, gt[5] / 3))
    assert ds.GetProjection() == src.GetProjection()
    band = ds.GetRasterBand(1)
    assert band.GetNoDataValue() == -9999
    a = band.ReadAsArray().astype(np.float64)
    nod = a == -9999
    want = np.zeros((600, 720), bool)
    want[150:180, 210:255] = True
    assert (nod == want).all()  # nodata exactly under the input's nodata
    av = a.reshape(200, 3, 240, 3).mean(axis=(1, 3))
    valid = z != -32768
    relief = z[valid].max() - z[valid].min()
    assert np.abs(av[valid] - z[valid]).max() < 0.01 * relief
    # detail the input has not: the output is rougher than its own smooth upsampling
    assert np.std(np.diff(a[~nod].reshape(-1))) > 0


def test_recipe_equals_cli_and_open_options(tmp_path):
    args = [JACKSBORO, "--exemplar", JACKSBORO, "--factor", "2", "--patch", "8"]
    run("amplify", *args[:1], tmp_path / "cli.tif", *args[1:], "-q")
    run("amplify", *args, "--recipe", tmp_path / "a.tsyn")
    assert "<Amplify>" in (tmp_path / "a.tsyn").read_text()
    env = plugin_env(PLUGINS)
    subprocess.run(["gdal_translate", "-q", str(tmp_path / "a.tsyn"), str(tmp_path / "r.tif")],
                   check=True, env=env)
    a = gdal.Open(str(tmp_path / "cli.tif")).ReadAsArray()
    b = gdal.Open(str(tmp_path / "r.tif")).ReadAsArray()
    assert a.tobytes() == b.tobytes()
    subprocess.run(["gdal_translate", "-q", "-oo", "FACTOR=3", str(tmp_path / "a.tsyn"),
                    str(tmp_path / "r3.tif")], check=True, env=env)
    r3 = gdal.Open(str(tmp_path / "r3.tif"))
    assert (r3.RasterXSize, r3.RasterYSize) == (403 * 3, 344 * 3)


def test_deterministic_across_threads(tmp_path):
    for t in ("1", "0"):
        run("amplify", JACKSBORO, tmp_path / ("t%s.tif" % t), "--exemplar", JACKSBORO,
            "--factor", "2", "--threads", t, "-q")
    a = gdal.Open(str(tmp_path / "t1.tif")).ReadAsArray()
    b = gdal.Open(str(tmp_path / "t0.tif")).ReadAsArray()
    assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("args,words", [
    (["--factor", "4"], "give at least one exemplar"),
    (["--exemplar", JACKSBORO, "--factor", "20"], "factor"),
    (["--exemplar", JACKSBORO, "--patch", "2"], "patch"),
])
def test_bad_options(tmp_path, args, words):
    p = run("amplify", JACKSBORO, tmp_path / "o.tif", *args, "-q", check=False)
    assert p.returncode == 2 and words in p.stderr, p.stderr
    assert not (tmp_path / "o.tif").exists()


@pytest.mark.skipif(not os.path.isdir(SHARED) or not os.path.exists(METRICS),
                    reason="../shared (DEMs, eval) not present")
@pytest.mark.parametrize("fine,exemplar,factor", [
    ("mountains_bigtujunga_ca_30m.tif", "mountains_mackay_id_30m.tif", 8),
    ("mountains_mackay_id_30m.tif", "mountains_bigtujunga_ca_30m.tif", 8),
])
def test_super_resolution_beats_cubic(tmp_path, fine, exemplar, factor):
    """A real DEM area-averaged by 8 and amplified with ANOTHER real DEM's dictionary: its
    slope distribution is at least twice as close to the real one as cubic's, its RMSE no
    worse than 1.2 x cubic's."""
    s = gdal.Open(os.path.join(SHARED, fine))
    z = s.ReadAsArray().astype(np.float64)
    h, w = (z.shape[0] // factor) * factor, (z.shape[1] // factor) * factor
    z = z[:h, :w]
    c = z.reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))
    gt = list(s.GetGeoTransform())
    write(tmp_path / "fine.tif", z.astype(np.float32), gt, s.GetProjection())
    write(tmp_path / "coarse.tif", c.astype(np.float32),
          [gt[0], gt[1] * factor, 0, gt[3], 0, gt[5] * factor], s.GetProjection())
    run("amplify", tmp_path / "coarse.tif", tmp_path / "amp.tif", "--exemplar",
        os.path.join(SHARED, exemplar), "--factor", str(factor), "-q")
    subprocess.run(["gdalwarp", "-q", "-r", "cubic", "-tr", str(abs(gt[1])), str(abs(gt[1])),
                    str(tmp_path / "coarse.tif"), str(tmp_path / "cubic.tif")], check=True)
    fig = {}
    for name in ("amp", "cubic"):
        m = json.loads(subprocess.run(
            [sys.executable, METRICS, "--out", str(tmp_path / (name + ".tif")), "--exemplar",
             str(tmp_path / "fine.tif")], capture_output=True, text=True, check=True).stdout)
        a = gdal.Open(str(tmp_path / (name + ".tif"))).ReadAsArray().astype(np.float64)
        fig[name] = (m["slope_w1_deg"], float(np.sqrt(np.mean((a - z) ** 2))))
    assert fig["amp"][0] <= 0.5 * fig["cubic"][0], fig
    assert fig["amp"][1] <= 1.2 * fig["cubic"][1], fig


def test_recipe_is_lazy_window_equals_whole(tmp_path):
    """gdal_translate -srcwin and ReadAsArray windows of an amplify recipe are the same bytes
    as the same windows of the command line's whole output (the driver computes only the
    blocks asked for, with the margin they need)."""
    args = ["--exemplar", JACKSBORO, "--factor", "5"]
    run("amplify", JACKSBORO, tmp_path / "cli.tif", *args, "-q")
    run("amplify", JACKSBORO, *args, "--recipe", tmp_path / "a.tsyn")
    whole = gdal.Open(str(tmp_path / "cli.tif")).ReadAsArray()
    code = ("import sys; from osgeo import gdal; import numpy as np; gdal.UseExceptions()\n"
            "ds = gdal.Open(sys.argv[1]); b = ds.GetRasterBand(1)\n"
            "for x, y, w, h in ((0, 0, 300, 200), (1700, 1500, 315, 220), (777, 333, 1, 1)):\n"
            "    sys.stdout.buffer.write(b.ReadAsArray(x, y, w, h).astype('<f4').tobytes())\n")
    p = subprocess.run([sys.executable, "-c", code, str(tmp_path / "a.tsyn")],
                       capture_output=True, env=plugin_env(PLUGINS), check=True)
    got = np.frombuffer(p.stdout, "<f4")
    want = np.concatenate([whole[0:200, 0:300].ravel(), whole[1500:1720, 1700:2015].ravel(),
                           whole[333:334, 777:778].ravel()]).astype("<f4")
    assert got.tobytes() == want.tobytes()


@pytest.mark.skipif(bool(os.environ.get("TS_TOOL_PRELOAD")),
                    reason="sanitizers multiply the memory a run takes")
@pytest.mark.skipif(not os.access("/usr/bin/time", os.X_OK), reason="/usr/bin/time missing")
def test_a_huge_recipe_reads_a_window_in_little_memory(tmp_path):
    """A 2048 x 2048 input amplified x16 is 32768 x 32768 cells (4 GB of Float32): the
    driver opens it and serves a window in a small fraction of that.  The input's cells are
    16 times the exemplar's, so the exemplar is at the output's resolution."""
    src = gdal.Open(JACKSBORO)
    z = src.ReadAsArray().astype(np.float32)
    tiled = np.tile(np.concatenate([z, z[::-1]], axis=0), (4, 6))[:2048, :2048]
    big = tmp_path / "big.tif"
    res = src.GetGeoTransform()[1] * 16
    write(big, np.ascontiguousarray(tiled), (-100, res, 0, 40, 0, -res), src.GetProjection())
    run("amplify", big, "--exemplar", JACKSBORO, "--factor", "16", "--recipe",
        tmp_path / "huge.tsyn")
    code = ("import sys; from osgeo import gdal; gdal.UseExceptions()\n"
            "ds = gdal.Open(sys.argv[1]); assert ds.RasterXSize == 32768\n"
            "a = ds.GetRasterBand(1).ReadAsArray(16000, 16000, 512, 512)\n"
            "assert a.shape == (512, 512) and (a > -9999).all()\n")
    rss = tmp_path / "rss.txt"
    p = subprocess.run(["/usr/bin/time", "-o", str(rss), "-f", "%M", sys.executable, "-c", code,
                        str(tmp_path / "huge.tsyn")], env=plugin_env(PLUGINS),
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    peak_mb = int(rss.read_text().split()[-1]) / 1024
    assert peak_mb < 600, peak_mb  # the whole output alone would be 4096 MB


def test_dictionary_built_once_and_reused(tmp_path):
    """`terrasynth dictionary build` then `amplify --dictionary`: the same bytes as amplify
    with the exemplar (the dictionary is the same atoms); its info; the checks that keep a
    dictionary to the grids it was built for; a damaged file is refused."""
    import json as js

    # a projected exemplar at 90 m, and a coarse input of 360 m cells: exact resolutions
    ex = tmp_path / "utm90.tif"
    subprocess.run(["gdalwarp", "-q", "-t_srs", "EPSG:32616", "-tr", "90", "90", "-r", "cubic",
                    JACKSBORO, str(ex)], check=True)
    e = gdal.Open(str(ex))
    z = e.ReadAsArray().astype(np.float64)
    nd = e.GetRasterBand(1).GetNoDataValue()
    h, w = (z.shape[0] // 4) * 4, (z.shape[1] // 4) * 4
    zc = z[:h, :w].copy()
    if nd is not None:
        zc[zc == nd] = np.nan
    c = zc.reshape(h // 4, 4, w // 4, 4).mean(axis=(1, 3))
    gt = list(e.GetGeoTransform())
    write(tmp_path / "coarse.tif", np.where(np.isnan(c), -9999, c).astype(np.float32),
          [gt[0], 360, 0, gt[3], 0, -360], e.GetProjection(), nodata=-9999)
    JEX = str(ex)
    res = 90
    d = tmp_path / "j.tsd"
    out = run("dictionary", "build", d, "--exemplar", JEX, "--resolution", str(res),
              "--factor", "4").stdout
    assert "atoms (factor 4, patch 6" in out
    info = js.loads(run("dictionary", "info", d).stdout)
    assert info["factor"] == 4 and info["patch"] == 6 and info["atoms"] > 256
    run("amplify", tmp_path / "coarse.tif", tmp_path / "a.tif", "--dictionary", d, "-q")
    run("amplify", tmp_path / "coarse.tif", tmp_path / "b.tif", "--exemplar", JEX,
        "--factor", "4", "-q")
    a = gdal.Open(str(tmp_path / "a.tif")).ReadAsArray()
    b = gdal.Open(str(tmp_path / "b.tif")).ReadAsArray()
    assert a.shape == (h, w) and a.tobytes() == b.tobytes()  # the same atoms, the same bytes
    p = run("amplify", tmp_path / "coarse.tif", tmp_path / "c.tif", "--dictionary", d,
            "--factor", "2", check=False)
    assert p.returncode == 1 and "was built for factor 4 and patch 6" in p.stderr
    p = run("amplify", JACKSBORO, tmp_path / "c.tif", "--dictionary", d, check=False)
    assert p.returncode == 1 and "was built for cells of" in p.stderr
    p = run("amplify", tmp_path / "coarse.tif", tmp_path / "c.tif", "--dictionary", d,
            "--exemplar", JEX, check=False)
    assert p.returncode == 2 and "give at least one exemplar, or a dictionary" in p.stderr
    raw = d.read_bytes()
    (tmp_path / "cut.tsd").write_bytes(raw[:-10])
    p = run("amplify", tmp_path / "coarse.tif", tmp_path / "c.tif", "--dictionary",
            tmp_path / "cut.tsd", check=False)
    assert p.returncode == 1 and "damaged" in p.stderr
    (tmp_path / "not.tsd").write_bytes(b"hello world, not a dictionary at all")
    p = run("dictionary", "info", tmp_path / "not.tsd", check=False)
    assert p.returncode == 1 and "not a TerraSynth dictionary" in p.stderr
    assert not (tmp_path / "c.tif").exists()


def test_multi_step_by_chaining(tmp_path):
    """Section 6.1's multi-step synthesis: an amplify recipe whose input is another amplify
    recipe gives the same bytes as running the command line twice."""
    run("amplify", JACKSBORO, "--exemplar", JACKSBORO, "--factor", "2", "--recipe",
        tmp_path / "s1.tsyn")
    run("amplify", tmp_path / "s1.tsyn", "--exemplar", JACKSBORO, "--factor", "2", "--recipe",
        tmp_path / "s2.tsyn")
    subprocess.run(["gdal_translate", "-q", str(tmp_path / "s2.tsyn"), str(tmp_path / "r.tif")],
                   check=True, env=plugin_env(PLUGINS))
    run("amplify", JACKSBORO, tmp_path / "c1.tif", "--exemplar", JACKSBORO, "--factor", "2", "-q")
    run("amplify", tmp_path / "c1.tif", tmp_path / "c2.tif", "--exemplar", JACKSBORO,
        "--factor", "2", "-q")
    a = gdal.Open(str(tmp_path / "r.tif")).ReadAsArray()
    b = gdal.Open(str(tmp_path / "c2.tif")).ReadAsArray()
    assert a.shape == (344 * 4, 403 * 4) and a.tobytes() == b.tobytes()
