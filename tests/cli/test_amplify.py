# SPDX-License-Identifier: GPL-2.0-or-later
"""`terrasynth amplify` end to end: the output grid (extent, CRS, resolution,
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
    # the amplification alone averages back to the input (the drainage stage's channels
    # would lower a few cells)
    p = run("amplify", tmp_path / "in.tif", out, "--exemplar", JACKSBORO, "--factor", "3",
            "--drainage", "keep")
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


def test_weights_in_one_option(tmp_path):
    """--weights h=..,u=.. is --w-h and --w-u: the same bytes, and a recipe keeps them."""
    base = [JACKSBORO, "--exemplar", JACKSBORO, "--factor", "2", "-q"]
    run("amplify", base[0], tmp_path / "a.tif", *base[1:], "--weights", "h=1,a=0,s=0.5,u=0")
    run("amplify", base[0], tmp_path / "b.tif", *base[1:], "--w-h", "1", "--w-a", "0", "--w-s",
        "0.5", "--w-u", "0")
    run("amplify", base[0], tmp_path / "c.tif", *base[1:])
    a, b, c = (gdal.Open(str(tmp_path / n)).ReadAsArray().tobytes() for n in ("a.tif", "b.tif",
                                                                              "c.tif"))
    assert a == b and a != c
    run("amplify", *base[:-1], "--weights", "h=1,a=0,s=0.5,u=0", "--recipe", tmp_path / "r.tsyn")
    assert '<Param name="w_s">0.5</Param>' in (tmp_path / "r.tsyn").read_text()


def test_deterministic_across_threads(tmp_path):
    for t in ("1", "0"):
        run("amplify", JACKSBORO, tmp_path / ("t%s.tif" % t), "--exemplar", JACKSBORO,
            "--factor", "2", "--threads", t, "-q")
    a = gdal.Open(str(tmp_path / "t1.tif")).ReadAsArray()
    b = gdal.Open(str(tmp_path / "t0.tif")).ReadAsArray()
    assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("args,words", [
    (["--factor", "4"], "give at least one exemplar"),
    (["--exemplar", JACKSBORO, "--weights", "h=1,q=2"], "weights takes h=W"),
    (["--exemplar", JACKSBORO, "--weights", "h=1", "--w-h", "2"], "give weights or w_h, not both"),
    (["--exemplar", JACKSBORO, "--weights", "a=-1"], "w_a = -1 is out of range"),
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
    # the amplification alone (what the drainage stage changes: bench/README.md, "Drainage")
    run("amplify", tmp_path / "coarse.tif", tmp_path / "amp.tif", "--exemplar",
        os.path.join(SHARED, exemplar), "--factor", str(factor), "-q", "--drainage", "keep")
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
    # damage a reader would take for data: one bit of a fine height (the output would be off
    # by a metre), a NaN, the header's factor made 65535, the file cut inside its header;
    # `info` verifies as amplify does
    import struct
    meta = js.loads(run("dictionary", "info", d).stdout)
    # past the file's header, the core's, and the atoms' dh and du (patch x patch floats each)
    hh = 16 + 52 + 2 * meta["atoms"] * meta["patch"] ** 2 * 4 + 100
    cases = {"bit": bytearray(raw), "nan": bytearray(raw), "factor": bytearray(raw),
             "cut": bytearray(raw[:40])}
    cases["bit"][hh] ^= 0x10
    cases["nan"][hh:hh + 4] = struct.pack("<f", float("nan"))
    cases["factor"][16 + 12:16 + 14] = b"\xff\xff"
    says = {"bit": "checksum does not match", "nan": "checksum does not match",
            "factor": "its header says factor 65535", "cut": "damaged: cut to"}
    for name, data in cases.items():
        (tmp_path / (name + ".tsd")).write_bytes(bytes(data))
        for cmd in (["dictionary", "info", tmp_path / (name + ".tsd")],
                    ["amplify", tmp_path / "coarse.tif", tmp_path / "c.tif", "--dictionary",
                     tmp_path / (name + ".tsd")]):
            p = run(*cmd, check=False)
            assert p.returncode == 1 and "damaged" in p.stderr, (name, p.stderr)
            assert cmd[0] == "dictionary" or says[name] in p.stderr, (name, p.stderr)
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


def jacksboro_pair(tmp_path, factor):
    """Jacksboro cut to whole blocks and its block means on cells `factor` times larger: an
    exemplar at exactly the output's resolution and a coarse input."""
    s = gdal.Open(JACKSBORO)
    z = s.ReadAsArray().astype(np.float64)
    h, w = (z.shape[0] // factor) * factor, (z.shape[1] // factor) * factor
    z = z[:h, :w]
    gt = list(s.GetGeoTransform())
    c = z.reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))
    write(tmp_path / "ex.tif", z.astype(np.float32), gt, s.GetProjection())
    cgt = [gt[0], gt[1] * factor, 0, gt[3], 0, gt[5] * factor]
    write(tmp_path / "coarse.tif", c.astype(np.float32), cgt, s.GetProjection())
    return z, c, gt, cgt, s.GetProjection()


def stripe_power(a):
    """The rows' spectral line at a period of 4 cells: the power there over the median power
    of the frequencies around it (about 1 without ripples)."""
    a = a[:, :(a.shape[1] // 4) * 4]
    p = (np.abs(np.fft.rfft(a - a.mean(axis=1, keepdims=True), axis=1)) ** 2).sum(axis=0)
    k = a.shape[1] // 4
    return p[k] / np.median(np.r_[p[k - 24:k - 2], p[k + 3:k + 25]])


def test_class_control_chooses_the_exemplar(tmp_path):
    """Section 5.4: two exemplars whose area averages are the same (the second has ripples of
    a 4-cell period, which averaging by 4 removes) labelled 1 and 2; wanted classes on the
    input's left and right halves choose which one each half's detail comes from, judged by
    the ripples' share of the output's spectrum (numpy), then with the halves swapped."""
    f = 4
    z, c, gt, cgt, wkt = jacksboro_pair(tmp_path, f)
    x = np.arange(z.shape[1])
    write(tmp_path / "ripples.tif", (z + 10.0 * np.sin(2 * np.pi * x / 4 + 0.3)).astype(np.float32),
          gt, wkt)
    for name, v in (("c1.tif", 1), ("c2.tif", 2)):
        write(tmp_path / name, np.full(z.shape, v, np.float32), gt, wkt)
    half = c.shape[1] // 2
    for left in (1, 2):
        want = np.full(c.shape, 3 - left, np.float32)
        want[:, :half] = left
        write(tmp_path / "want.tif", want, cgt, wkt)
        run("amplify", tmp_path / "coarse.tif", tmp_path / "o.tif", "--exemplar",
            tmp_path / "ex.tif", "--exemplar", tmp_path / "ripples.tif", "--exemplar-classes",
            tmp_path / "c1.tif", "--exemplar-classes", tmp_path / "c2.tif", "--classes",
            tmp_path / "want.tif", "--factor", str(f), "--out-classes", tmp_path / "oc.tif", "-q")
        a = gdal.Open(str(tmp_path / "o.tif")).ReadAsArray().astype(np.float64)
        oc = gdal.Open(str(tmp_path / "oc.tif")).ReadAsArray()
        m = half * f
        lpow, rpow = stripe_power(a[:, :m - 24]), stripe_power(a[:, m + 24:])
        rip, plain = (lpow, rpow) if left == 2 else (rpow, lpow)
        assert rip > 4 and plain < 2, (left, lpow, rpow)
        assert np.mean(oc[:, :m - 24] == left) > 0.97 and np.mean(oc[:, m + 24:] == 3 - left) > 0.97
    # a wanted code no atom holds: its cells are matched as unlabelled, with a warning
    want = np.full(c.shape, 1, np.float32)
    want[:, :half] = 3
    write(tmp_path / "want3.tif", want, cgt, wkt)
    p = run("amplify", tmp_path / "coarse.tif", tmp_path / "o3.tif", "--exemplar",
            tmp_path / "ex.tif", "--exemplar", tmp_path / "ripples.tif", "--exemplar-classes",
            tmp_path / "c1.tif", "--exemplar-classes", tmp_path / "c2.tif", "--classes",
            tmp_path / "want3.tif", "--factor", str(f), "-q")
    assert "no atom holds class 3" in p.stderr, p.stderr
    p = run("amplify", tmp_path / "coarse.tif", tmp_path / "o4.tif", "--exemplar",
            tmp_path / "ex.tif", "--exemplar", tmp_path / "ripples.tif", "--exemplar-classes",
            tmp_path / "c1.tif", "--exemplar-classes", tmp_path / "c2.tif", "--classes",
            tmp_path / "want.tif", "--factor", str(f), "-q")
    assert "no atom holds" not in p.stderr, p.stderr
    # without wanted classes both exemplars are used (ties go to the first: exemplar 1)
    run("amplify", tmp_path / "coarse.tif", tmp_path / "n.tif", "--exemplar", tmp_path / "ex.tif",
        "--exemplar", tmp_path / "ripples.tif", "--exemplar-classes", tmp_path / "c1.tif",
        "--exemplar-classes", tmp_path / "c2.tif", "--factor", str(f), "--out-classes",
        tmp_path / "nc.tif", "-q")
    assert set(np.unique(gdal.Open(str(tmp_path / "nc.tif")).ReadAsArray())) <= {1, 2}


def laplacian(z, d):
    """The Laplacian (curvature) by plain central differences, edges repeated."""
    p = np.pad(z, 1, mode="edge")
    return (p[:-2, 1:-1] + p[2:, 1:-1] + p[1:-1, :-2] + p[1:-1, 2:] - 4 * z) / d ** 2


@pytest.mark.skipif(not os.path.isdir(SHARED), reason="../shared DEMs not present")
@pytest.mark.parametrize("fine,win,exemplar", [
    ("mountains_bigtujunga_ca_30m.tif", (300, 60, 512, 512), "mountains_mackay_id_30m.tif"),
    ("mountains_mackay_id_30m.tif", (100, 200, 512, 512), "mountains_bigtujunga_ca_30m.tif"),
    ("volcano_st_helens_30m.tif", None, "mountains_mackay_id_30m.tif"),
])
def test_carried_layer_is_coherent(tmp_path, fine, win, exemplar):
    """A layer that is a known function of the terrain (its curvature, numpy) carried by the
    atoms agrees with the same function recomputed on the amplified DEM better than the
    function of the coarse input resampled by gdalwarp -r cubic does (Pearson correlation)."""
    f = 4

    def read(path):
        ds = gdal.Open(path)
        a = ds.ReadAsArray().astype(np.float64)
        nd = ds.GetRasterBand(1).GetNoDataValue()
        if nd is not None:
            a[a == nd] = np.nan
        a[a == -9999] = np.nan
        return ds, a

    s, z = read(os.path.join(SHARED, fine))
    if win:
        x0, y0, w, h = win
        z = z[y0:y0 + h, x0:x0 + w]
    h, w = (z.shape[0] // f) * f, (z.shape[1] // f) * f
    z = z[:h, :w]
    gt = list(s.GetGeoTransform())
    if win:
        gt[0] += win[0] * gt[1]
        gt[3] += win[1] * gt[5]
    c = z.reshape(h // f, f, w // f, f).mean(axis=(1, 3))  # NaN where any cell is nodata
    cgt = [gt[0], gt[1] * f, 0, gt[3], 0, gt[5] * f]
    write(tmp_path / "coarse.tif", np.nan_to_num(c, nan=-9999).astype(np.float32), cgt,
          s.GetProjection(), nodata=-9999)
    e, ez = read(os.path.join(SHARED, exemplar))
    write(tmp_path / "ex_curv.tif", np.nan_to_num(laplacian(ez, 30.0), nan=-9999).astype(
        np.float32), e.GetGeoTransform(), e.GetProjection(), nodata=-9999)
    run("amplify", tmp_path / "coarse.tif", tmp_path / "amp.tif", "--exemplar",
        os.path.join(SHARED, exemplar), "--exemplar-layer", "curv=%s" % (tmp_path / "ex_curv.tif"),
        "--out-layer", "curv=%s" % (tmp_path / "o_curv.tif"), "--factor", str(f), "-q")
    amp = read(str(tmp_path / "amp.tif"))[1]
    carried = read(str(tmp_path / "o_curv.tif"))[1]
    write(tmp_path / "c_curv.tif", np.nan_to_num(laplacian(c, 30.0 * f), nan=-9999).astype(
        np.float32), cgt, s.GetProjection(), nodata=-9999)
    subprocess.run(["gdalwarp", "-q", "-r", "cubic", "-tr", "30", "30",
                    str(tmp_path / "c_curv.tif"), str(tmp_path / "cubic.tif")], check=True)
    cubic = read(str(tmp_path / "cubic.tif"))[1]
    truth = laplacian(amp, 30.0)
    inner = (slice(4, -4), slice(4, -4))
    t, a, b = truth[inner].ravel(), carried[inner].ravel(), cubic[inner].ravel()
    ok = np.isfinite(t) & np.isfinite(a) & np.isfinite(b)
    assert ok.mean() > 0.5
    r_carried = np.corrcoef(t[ok], a[ok])[0, 1]
    r_cubic = np.corrcoef(t[ok], b[ok])[0, 1]
    print("curvature: carried r=%.3f, cubic r=%.3f" % (r_carried, r_cubic))
    assert r_carried > r_cubic, (r_carried, r_cubic)


def test_layers_and_classes_through_a_dictionary_file(tmp_path):
    """A dictionary built with layers and classes holds them (info), and amplify with it
    gives the same bytes for the DEM, the layer and the classes as with the exemplars; the
    mistakes a user makes with layers are refused with one line."""
    import json as js
    f = 4
    # a projected exemplar of 90 m cells and a coarse input of 360 m cells: exact resolutions
    subprocess.run(["gdalwarp", "-q", "-t_srs", "EPSG:32616", "-tr", "90", "90", "-r", "cubic",
                    "-dstnodata", "-9999", JACKSBORO, str(tmp_path / "utm.tif")], check=True)
    u = gdal.Open(str(tmp_path / "utm.tif"))
    gt, wkt = list(u.GetGeoTransform()), u.GetProjection()
    z = u.ReadAsArray().astype(np.float64)
    h, w = (z.shape[0] // f) * f, (z.shape[1] // f) * f
    z = z[:h, :w]
    z[z == -9999] = np.nan
    write(tmp_path / "ex.tif", np.nan_to_num(z, nan=-9999).astype(np.float32), gt, wkt,
          nodata=-9999)
    c = z.reshape(h // f, f, w // f, f).mean(axis=(1, 3))
    write(tmp_path / "coarse.tif", np.nan_to_num(c, nan=-9999).astype(np.float32),
          [gt[0], 360, 0, gt[3], 0, -360], wkt, nodata=-9999)
    med = np.nanmedian(z)
    write(tmp_path / "veg.tif", (z > med).astype(np.float32) * 0.8, gt, wkt)
    write(tmp_path / "cl.tif", np.where(z > med, 2, 1).astype(np.float32), gt, wkt)
    d = tmp_path / "d.tsd"
    res = 90
    lay = ["--exemplar-layer", "veg=%s" % (tmp_path / "veg.tif"), "--exemplar-classes",
           tmp_path / "cl.tif"]
    run("dictionary", "build", d, "--exemplar", tmp_path / "ex.tif", *lay, "--factor", str(f),
        "--resolution", "%.6f" % res, "-q")
    info = js.loads(run("dictionary", "info", d).stdout)
    assert info["layers"] == ["veg"] and info["classes"] == 2 and info["version"] == 3
    assert info["checksum"] == "verified"
    outs = lambda p: ["--out-layer", "veg=%s" % (tmp_path / (p + "v.tif")), "--out-classes",  # noqa
                      tmp_path / (p + "c.tif")]
    run("amplify", tmp_path / "coarse.tif", tmp_path / "a.tif", "--exemplar", tmp_path / "ex.tif",
        *lay, "--factor", str(f), *outs("a"), "-q")
    run("amplify", tmp_path / "coarse.tif", tmp_path / "b.tif", "--dictionary", d, *outs("b"),
        "-q")
    for suffix in (".tif", "v.tif", "c.tif"):
        a = gdal.Open(str(tmp_path / ("a" + suffix))).ReadAsArray()
        b = gdal.Open(str(tmp_path / ("b" + suffix))).ReadAsArray()
        assert a.tobytes() == b.tobytes(), suffix
    v = gdal.Open(str(tmp_path / "av.tif"))
    assert v.GetGeoTransform() == gdal.Open(str(tmp_path / "a.tif")).GetGeoTransform()
    assert v.GetRasterBand(1).GetNoDataValue() == -9999
    # the carried classes follow the terrain they came with: class 2 (the upper half of the
    # exemplar's elevations) mostly where the output is high
    a = gdal.Open(str(tmp_path / "a.tif")).ReadAsArray()
    cls = gdal.Open(str(tmp_path / "ac.tif")).ReadAsArray()
    valid = a != -9999
    assert np.mean(cls[valid & (a > med)] == 2) > 0.8
    assert np.mean(cls[valid & (a < med)] == 1) > 0.8
    # mistakes
    bad = [
        (["--exemplar", tmp_path / "ex.tif", "--out-layer", "soil=%s" % (tmp_path / "s.tif")],
         1, "out_layer soil: the atoms carry no layer soil (they carry: none)"),
        (["--exemplar", tmp_path / "ex.tif", "--exemplar", tmp_path / "ex.tif", "--exemplar-layer",
          "veg=%s" % (tmp_path / "veg.tif")], 2, "exemplar_layer veg: one file for each of the 2"),
        (["--exemplar", JACKSBORO, "--exemplar-layer", "veg=%s" % (tmp_path / "veg.tif")], 1,
         "is not on the grid of its exemplar"),
        (["--exemplar", tmp_path / "ex.tif", "--exemplar-layer", "a b=x.tif"], 2,
         "exemplar_layer takes NAME=FILE"),
        (["--dictionary", d, "--classes", tmp_path / "veg.tif"], 1, "the class raster is"),
        (["--dictionary", d, "--w-l", "0.3"], 1, "built without the irradiance"),
        (["--dictionary", d, "--exemplar-layer", "veg=%s" % (tmp_path / "veg.tif")], 2,
         "the dictionary holds the exemplars' layers and classes"),
        (["--exemplar", tmp_path / "ex.tif", "--out-classes", tmp_path / "x.tif"], 1,
         "out_classes: the atoms have no classes"),
    ]
    for args, code, words in bad:
        p = run("amplify", tmp_path / "coarse.tif", tmp_path / "o.tif", *args, "--factor", str(f),
                check=False)
        assert p.returncode == code and words in p.stderr, (args, p.stderr)
        assert len(p.stderr.strip().splitlines()) == 1, p.stderr
        assert not (tmp_path / "o.tif").exists()


def test_irradiance_term(tmp_path):
    """With w_l the atoms and the input are matched on their mean annual irradiance too (each
    cell's latitude from the CRS); an input without a CRS is refused; the weight changes the
    choice of atoms but not the averaging back."""
    f = 4
    z, c, gt, cgt, wkt = jacksboro_pair(tmp_path, f)
    run("amplify", tmp_path / "coarse.tif", tmp_path / "a.tif", "--exemplar", tmp_path / "ex.tif",
        "--factor", str(f), "-q", "--drainage", "keep")
    run("amplify", tmp_path / "coarse.tif", tmp_path / "l.tif", "--exemplar", tmp_path / "ex.tif",
        "--factor", str(f), "--w-l", "1", "-q", "--drainage", "keep")
    a = gdal.Open(str(tmp_path / "a.tif")).ReadAsArray().astype(np.float64)
    b = gdal.Open(str(tmp_path / "l.tif")).ReadAsArray().astype(np.float64)
    assert a.tobytes() != b.tobytes()
    av = b.reshape(c.shape[0], f, c.shape[1], f).mean(axis=(1, 3))
    assert np.abs(av - c).max() < 0.01 * (c.max() - c.min())
    write(tmp_path / "nocrs.tif", c.astype(np.float32), [0, 1, 0, 0, 0, -1], "")
    p = run("amplify", tmp_path / "nocrs.tif", tmp_path / "n.tif", "--exemplar",
            tmp_path / "ex.tif", "--factor", str(f), "--w-l", "1", check=False)
    assert p.returncode == 1 and "needs each cell's latitude" in p.stderr, p.stderr


def test_recipe_serves_layers_and_classes(tmp_path):
    """An amplify recipe with exemplar layers and classes serves, with -oo LAYER=NAME or
    LAYER=classes, the same values as --out-layer and --out-classes, window by window."""
    f = 3
    z, c, gt, cgt, wkt = jacksboro_pair(tmp_path, f)
    med = np.median(z)
    write(tmp_path / "veg.tif", np.where(z > med, 0.2, 0.9).astype(np.float32), gt, wkt)
    write(tmp_path / "cl.tif", np.where(z > med, 2, 1).astype(np.float32), gt, wkt)
    args = ["--exemplar", tmp_path / "ex.tif", "--exemplar-layer", "veg=%s" % (tmp_path / "veg.tif"),
            "--exemplar-classes", tmp_path / "cl.tif", "--factor", str(f)]
    run("amplify", tmp_path / "coarse.tif", tmp_path / "a.tif", *args, "--out-layer",
        "veg=%s" % (tmp_path / "av.tif"), "--out-classes", tmp_path / "ac.tif", "-q")
    run("amplify", tmp_path / "coarse.tif", *args, "--recipe", tmp_path / "r.tsyn")
    text = (tmp_path / "r.tsyn").read_text()
    assert '<ExemplarLayer name="veg">' in text and "<ExemplarClasses>" in text
    env = plugin_env(PLUGINS)
    for layer, ref in (("veg", "av.tif"), ("classes", "ac.tif"), ("dem", "a.tif")):
        subprocess.run(["gdal_translate", "-q", "-oo", "LAYER=" + layer, "-srcwin", "37", "51",
                        "300", "211", str(tmp_path / "r.tsyn"), str(tmp_path / "w.tif")],
                       check=True, env=env)
        got = gdal.Open(str(tmp_path / "w.tif")).ReadAsArray().astype(np.float64)
        want = gdal.Open(str(tmp_path / ref)).ReadAsArray()[51:262, 37:337].astype(np.float64)
        assert np.array_equal(got, want), layer
    p = subprocess.run(["gdal_translate", "-q", "-oo", "LAYER=soil", str(tmp_path / "r.tsyn"),
                        str(tmp_path / "s.tif")], env=env, capture_output=True, text=True)
    assert p.returncode != 0 and "the atoms carry no layer soil" in p.stderr, p.stderr


def utm_pair(tmp_path, f):
    """Jacksboro in UTM at 90 m (an exemplar at the output's resolution) and its block means
    on cells of 90 f m (the coarse input)."""
    subprocess.run(["gdalwarp", "-q", "-t_srs", "EPSG:32616", "-tr", "90", "90", "-r", "cubic",
                    "-dstnodata", "-9999", JACKSBORO, str(tmp_path / "utm.tif")], check=True)
    u = gdal.Open(str(tmp_path / "utm.tif"))
    gt, wkt = list(u.GetGeoTransform()), u.GetProjection()
    z = u.ReadAsArray().astype(np.float64)
    h, w = (z.shape[0] // f) * f, (z.shape[1] // f) * f
    z = z[:h, :w]
    z[z == -9999] = np.nan
    write(tmp_path / "ex.tif", np.nan_to_num(z, nan=-9999).astype(np.float32), gt, wkt,
          nodata=-9999)
    c = z.reshape(h // f, f, w // f, f).mean(axis=(1, 3))
    cgt = [gt[0], 90.0 * f, 0, gt[3], 0, -90.0 * f]
    write(tmp_path / "coarse.tif", np.nan_to_num(c, nan=-9999).astype(np.float32), cgt, wkt,
          nodata=-9999)
    return z, c, gt, cgt, wkt


def test_biomes_paint_where_each_dictionary_goes(tmp_path):
    """Section 5.5: two dictionaries (one of them with 4-cell ripples that area-averaging
    removes) and painted weights, left and right: each half of the output has the detail of
    its biome, judged by the ripples' spectral line (numpy); the recipe serves the same
    bytes; mistakes are refused."""
    f = 4
    z, c, gt, cgt, wkt = utm_pair(tmp_path, f)
    x = np.arange(z.shape[1])
    rip = np.where(np.isnan(z), -9999, z + 10.0 * np.sin(2 * np.pi * x / 4 + 0.3))
    write(tmp_path / "ripples.tif", rip.astype(np.float32), gt, wkt, nodata=-9999)
    for name, ex in (("a.tsd", "ex.tif"), ("b.tsd", "ripples.tif")):
        run("dictionary", "build", tmp_path / name, "--exemplar", tmp_path / ex, "--resolution",
            "90", "--factor", str(f), "-q")
    half = c.shape[1] // 2
    wa = np.zeros(c.shape, np.float32)
    wa[:, :half] = 1
    write(tmp_path / "wa.tif", wa, cgt, wkt)
    write(tmp_path / "wb.tif", 1 - wa, cgt, wkt)
    bio = ["--biome", "%s=%s" % (tmp_path / "wa.tif", tmp_path / "a.tsd"), "--biome",
           "%s=%s" % (tmp_path / "wb.tif", tmp_path / "b.tsd")]
    run("amplify", tmp_path / "coarse.tif", tmp_path / "o.tif", *bio, "-q")
    a = gdal.Open(str(tmp_path / "o.tif")).ReadAsArray().astype(np.float64)
    m = half * f
    rows = slice(a.shape[0] // 4, 3 * a.shape[0] // 4)  # away from the warped edges' nodata
    left, right = a[rows, 24:m - 24], a[rows, m + 24:-24]
    assert (left != -9999).all() and (right != -9999).all()
    lp, rp = stripe_power(left), stripe_power(right)
    assert rp > 4 and lp < 2, (lp, rp)
    run("amplify", tmp_path / "coarse.tif", *bio, "--recipe", tmp_path / "b.tsyn")
    assert '<Biome weights="wa.tif">a.tsd</Biome>' in (tmp_path / "b.tsyn").read_text()
    subprocess.run(["gdal_translate", "-q", str(tmp_path / "b.tsyn"), str(tmp_path / "r.tif")],
                   check=True, env=plugin_env(PLUGINS))
    assert gdal.Open(str(tmp_path / "r.tif")).ReadAsArray().tobytes() == \
        gdal.Open(str(tmp_path / "o.tif")).ReadAsArray().tobytes()
    run("dictionary", "build", tmp_path / "a2.tsd", "--exemplar", tmp_path / "ex.tif",
        "--resolution", "45", "--factor", "8", "-q")
    bad = [
        (["--biome", "%s=%s" % (tmp_path / "ex.tif", tmp_path / "a.tsd")], 1,
         "the weights are"),
        (bio + ["--biome", "%s=%s" % (tmp_path / "wa.tif", tmp_path / "a2.tsd")], 1,
         "was built for factor 8 and patch 6, not 4 and 6"),
        (bio + ["--exemplar", tmp_path / "ex.tif"], 2, "give at least one exemplar"),
        (bio + ["--out-classes", tmp_path / "x.tif"], 2, "biomes blend dictionaries"),
        (["--biome", "=%s" % (tmp_path / "a.tsd")], 2, "biome takes FILE=FILE"),
    ]
    for args, code, words in bad:
        p = run("amplify", tmp_path / "coarse.tif", tmp_path / "n.tif", *args, check=False)
        assert p.returncode == code and words in p.stderr, (args, p.stderr)
        assert not (tmp_path / "n.tif").exists()
