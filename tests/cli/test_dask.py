# SPDX-License-Identifier: GPL-2.0-or-later
"""terrasynth-dask (gdal_driver/dask/terrasynth_dask.py): a recipe computed on a local
Dask cluster of two workers (threads of the runner, or processes on loopback) gives the same cells, geotransform, CRS
and nodata as `gdal_translate RECIPE OUT.tif` of the same recipe, whatever the chunk size; a
pixel and an amplify recipe chunk by chunk, a tiled synth recipe tile by tile, a synth recipe
in one piece in one task; a worker killed mid-run on a running cluster loses nothing; refusals leave
nothing behind.  Skips when python3-distributed is absent; not under the sanitizers (the
runner is plain Python and its workers would each load the instrumented plugin: the plugin is
checked under them by tests/gdal)."""
import os
import re
import stat
import subprocess
import sys

import numpy as np
import pytest
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import JACKSBORO, ROOT, plugin_env, run  # noqa: E402

gdal.UseExceptions()
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
RUNNER = os.path.join(ROOT, "gdal_driver", "dask", "terrasynth_dask.py")
# the runner's default compression: ZSTD where GDAL's GeoTIFF driver has it
HAS_ZSTD = "ZSTD" in (gdal.GetDriverByName("GTiff").GetMetadataItem("DMD_CREATIONOPTIONLIST")
                      or "")

try:
    import distributed  # noqa: F401
    HAVE_DASK = True
except ImportError:
    HAVE_DASK = False

pytestmark = [
    pytest.mark.skipif(not HAVE_DASK, reason="python3-distributed not installed"),
    pytest.mark.skipif(bool(os.environ.get("TS_TOOL_PRELOAD")),
                       reason="the runner's workers would load the instrumented plugin"),
]


def runner(*args, check=True, env=None):
    p = subprocess.run([sys.executable, RUNNER, *map(str, args)], capture_output=True,
                       text=True, env=dict(plugin_env(PLUGINS), **(env or {})), timeout=600)
    if check:
        assert p.returncode == 0, p.stderr
    return p


def translate(recipe, out):
    subprocess.run(["gdal_translate", "-q", str(recipe), str(out)], check=True,
                   env=plugin_env(PLUGINS))


def same_raster(a_path, b_path):
    a, b = gdal.Open(str(a_path)), gdal.Open(str(b_path))
    assert (a.RasterXSize, a.RasterYSize) == (b.RasterXSize, b.RasterYSize)
    assert a.GetGeoTransform() == b.GetGeoTransform()
    assert a.GetSpatialRef().IsSame(b.GetSpatialRef())
    assert a.GetRasterBand(1).GetNoDataValue() == b.GetRasterBand(1).GetNoDataValue()
    assert a.GetRasterBand(1).DataType == b.GetRasterBand(1).DataType
    assert a.ReadAsArray().tobytes() == b.ReadAsArray().tobytes()


@pytest.mark.parametrize("chunk,kind", [(64, "--processes"), (200, None)])
def test_pixel_recipe_chunk_by_chunk(tmp_path, chunk, kind):
    """Workers as processes (chunks of 64) and as threads (200): the same cells."""
    recipe = tmp_path / "p.tsyn"
    run("pixel", "--exemplar", JACKSBORO, "--size", "300x260", "--seed", 5, "--recipe", recipe)
    translate(recipe, tmp_path / "gt.tif")
    p = runner(recipe, tmp_path / "dask.tif", "--workers", 2, "--chunk", chunk, "--stats",
               *([kind] if kind else []))
    assert "chunk by chunk" in p.stdout
    n = -(-300 // chunk) * -(-260 // chunk)
    assert f"in {n} chunks" in p.stdout
    # the recipe is opened once per worker thread, not once per chunk
    m = re.search(r"the recipe opened (\d+) times on 2 workers for (\d+) chunks", p.stdout)
    assert m and int(m.group(2)) == n and 1 <= int(m.group(1)) <= 2 * (os.cpu_count() or 1)
    if n > 4 * (os.cpu_count() or 1):
        assert int(m.group(1)) < n
    same_raster(tmp_path / "dask.tif", tmp_path / "gt.tif")
    ds = gdal.Open(str(tmp_path / "dask.tif"))
    st = ds.GetMetadata("IMAGE_STRUCTURE")
    assert st.get("COMPRESSION") == ("ZSTD" if HAS_ZSTD else "DEFLATE")
    assert st.get("PREDICTOR") == "3"  # floating point: smaller files, same CPU time
    if gdal.GetDriverByName("COG") is not None:
        assert st.get("LAYOUT") == "COG"
    assert sorted(os.listdir(tmp_path)) == ["dask.tif", "gt.tif", "p.tsyn"]  # no temp file


def test_overviews_of_a_larger_raster(tmp_path):
    recipe = tmp_path / "p.tsyn"
    run("pixel", "--exemplar", JACKSBORO, "--size", "700x600", "--seed", 2, "--recipe", recipe)
    translate(recipe, tmp_path / "gt.tif")
    runner(recipe, tmp_path / "dask.tif", "--chunk", 256, "-q")
    same_raster(tmp_path / "dask.tif", tmp_path / "gt.tif")
    assert gdal.Open(str(tmp_path / "dask.tif")).GetRasterBand(1).GetOverviewCount() >= 1


def test_amplify_recipe(tmp_path):
    recipe = tmp_path / "a.tsyn"
    run("amplify", JACKSBORO, "--exemplar", JACKSBORO, "--factor", 2, "--patch", 8, "--recipe",
        recipe)
    translate(recipe, tmp_path / "gt.tif")
    runner(recipe, tmp_path / "dask.tif", "--chunk", 256, "-q")
    same_raster(tmp_path / "dask.tif", tmp_path / "gt.tif")


def test_synth_recipe_in_one_task(tmp_path):
    recipe = tmp_path / "s.tsyn"
    run("synth", "--exemplar", JACKSBORO, "--size", "200x150", "--seed", 7, "--recipe", recipe)
    translate(recipe, tmp_path / "gt.tif")
    p = runner(recipe, tmp_path / "dask.tif", "--chunk", 64)
    assert "whole raster, one task" in p.stdout and "in 1 chunks" in p.stdout
    same_raster(tmp_path / "dask.tif", tmp_path / "gt.tif")


def test_sketch_recipe_in_tiles_chunk_by_chunk(tmp_path):
    """A sketch in tiles (laid out coarser and amplified): chunk by chunk on two worker
    processes, each laying the sketch out once; the same cells as the command line's run."""
    sketch = os.path.join(os.path.dirname(JACKSBORO), "sketches", "ridges_valleys.tif")
    args = ["--exemplar", JACKSBORO, "--sketch", sketch, "--seed", 3, "--tiled", 256]
    run("synth", *args, tmp_path / "cli.tif", "-q")
    run("synth", *args, "--recipe", tmp_path / "s.tsyn")
    p = runner(tmp_path / "s.tsyn", tmp_path / "dask.tif", "--workers", 2, "--processes",
               "--chunk", 128)
    assert "chunk by chunk" in p.stdout and "in 16 chunks" in p.stdout, p.stdout
    assert gdal.Open(str(tmp_path / "dask.tif")).ReadAsArray().tobytes() == \
        gdal.Open(str(tmp_path / "cli.tif")).ReadAsArray().tobytes()


def test_tiled_synth_recipe_tile_by_tile(tmp_path):
    """A tiled synth recipe: one task per tile, the waves as dependencies, the neighbours'
    windows shared by two workers (threads) or moved between them (processes): the same
    cells as the CLI's whole run and as gdal_translate, on 2 workers of each kind and on 1."""
    args = ["--exemplar", JACKSBORO, "--size", "530x400", "--seed", 8, "--tiled", 128]
    recipe = tmp_path / "t.tsyn"
    run("synth", *args, "--recipe", recipe)
    run("synth", *args, tmp_path / "cli.tif", "-q")
    translate(recipe, tmp_path / "gt.tif")
    p = runner(recipe, tmp_path / "d2.tif", "--no-overviews")
    assert "tile by tile, four waves" in p.stdout and "in 20 tiles" in p.stdout, p.stdout
    same_raster(tmp_path / "d2.tif", tmp_path / "gt.tif")
    st = gdal.Open(str(tmp_path / "d2.tif")).GetMetadata("IMAGE_STRUCTURE")
    assert (st.get("COMPRESSION"), st.get("PREDICTOR")) == (
        "ZSTD" if HAS_ZSTD else "DEFLATE", "3")  # no overviews
    # the mode every new file gets under the umask, as with overviews (not mkstemp's 0600)
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(os.stat(tmp_path / "d2.tif").st_mode) == 0o666 & ~mask
    # another compression asked for: the same cells
    runner(recipe, tmp_path / "dd.tif", "--no-overviews", "--compress", "DEFLATE", "-q")
    st = gdal.Open(str(tmp_path / "dd.tif")).GetMetadata("IMAGE_STRUCTURE")
    assert (st.get("COMPRESSION"), st.get("PREDICTOR")) == ("DEFLATE", "3")
    same_raster(tmp_path / "dd.tif", tmp_path / "gt.tif")
    runner(recipe, tmp_path / "d1.tif", "--workers", 1, "--no-overviews", "-q")
    same_raster(tmp_path / "d1.tif", tmp_path / "gt.tif")
    p = runner(recipe, tmp_path / "dp.tif", "--processes", "--no-overviews", "--stats", "-q")
    assert p.stdout.count("peak memory") == 2, p.stdout  # one line per worker process
    same_raster(tmp_path / "dp.tif", tmp_path / "gt.tif")
    cli = gdal.Open(str(tmp_path / "cli.tif")).ReadAsArray()
    assert gdal.Open(str(tmp_path / "d2.tif")).ReadAsArray().tobytes() == cli.tobytes()


@pytest.mark.parametrize("sketch", [False, True])
def test_tiled_recipe_with_pins_and_water(tmp_path, sketch):
    """A tiled recipe with a pin and a water mask, free or with a sketch: each tile or chunk
    task reads its window's part of them, and the result is the CLI's with the whole
    grid's."""
    base = ["--exemplar", JACKSBORO, "--seed", 3, "--tiled", 128]
    if sketch:  # the sketch's grid: 512 x 512
        sk = os.path.join(ROOT, "data", "sketches", "ridges_valleys.tif")
        base += ["--sketch", sk]
        g = gdal.Open(sk)
    else:
        base += ["--size", "300x260"]
        run("synth", *base, tmp_path / "grid.tif", "-q")
        g = gdal.Open(str(tmp_path / "grid.tif"))
    water = np.zeros((g.RasterYSize, g.RasterXSize), np.uint8)
    water[30:90, 100:220] = 1  # across tile borders
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "water.tif"), g.RasterXSize,
                                              g.RasterYSize, 1, gdal.GDT_Byte)
    ds.SetGeoTransform(g.GetGeoTransform())
    ds.SetProjection(g.GetProjection())
    ds.GetRasterBand(1).WriteArray(water)
    ds = None
    args = base + ["--pin", f"{JACKSBORO}:0,0,40,40@120,120", "--water", tmp_path / "water.tif",
                   "--water-level", 300]
    run("synth", *args, tmp_path / "cli.tif", "-q")
    run("synth", *args, "--recipe", tmp_path / "t.tsyn")
    runner(tmp_path / "t.tsyn", tmp_path / "d.tif", "--no-overviews", "-q")
    cli = gdal.Open(str(tmp_path / "cli.tif")).ReadAsArray()
    assert gdal.Open(str(tmp_path / "d.tif")).ReadAsArray().tobytes() == cli.tobytes()
    assert (cli[30:90, 100:220] == 300).all()


def test_same_file_bytes_on_every_run(tmp_path):
    """The pieces come back in any order, but the file is written in one order: the same
    bytes (not only the same cells) on every run, with a GDAL block cache far smaller than
    the raster (1 MB: blocks leave the cache while the run goes on; before the ordered
    writes, three runs gave three different files)."""
    import hashlib
    recipe = tmp_path / "t.tsyn"
    run("synth", "--exemplar", JACKSBORO, "--size", "768x640", "--seed", 3, "--tiled", 128,
        "--recipe", recipe)
    chunks = tmp_path / "p.tsyn"
    run("pixel", "--exemplar", JACKSBORO, "--size", "700x600", "--seed", 4, "--recipe", chunks)
    for rec, extra in ((recipe, []), (chunks, ["--chunk", "128"])):
        digests = set()
        for k in range(3):
            out = tmp_path / ("o%d.tif" % k)
            runner(rec, out, "--no-overviews", "-q", *extra, env={"GDAL_CACHEMAX": "1"})
            digests.add(hashlib.sha256(out.read_bytes()).hexdigest())
            out.unlink()
        assert len(digests) == 1, rec


def test_refusals_leave_nothing(tmp_path):
    recipe = tmp_path / "p.tsyn"
    run("pixel", "--exemplar", JACKSBORO, "--size", "64x64", "--recipe", recipe)
    before = sorted(os.listdir(tmp_path))
    p = runner(recipe, recipe, check=False)  # over the recipe
    assert p.returncode == 1 and "would replace" in p.stderr and len(p.stderr.splitlines()) == 1
    link = tmp_path / "alias.tsyn"
    os.symlink(recipe, link)
    p = runner(recipe, link, check=False)  # the same file by another name
    assert p.returncode == 1 and "would replace" in p.stderr
    os.unlink(link)
    p = runner(tmp_path / "none.tsyn", tmp_path / "o.tif", check=False)
    assert p.returncode == 1 and "no such recipe" in p.stderr
    bad = tmp_path / "bad.tsyn"
    bad.write_text('<TerraSynth version="1"><Pixel><Exemplar>/no/such/dem.tif</Exemplar>'
                   '<Grid width="10" height="10"/></Pixel></TerraSynth>')
    p = runner(bad, tmp_path / "o.tif", check=False)
    assert p.returncode == 1 and str(bad.name) in p.stderr and len(p.stderr.splitlines()) == 1
    p = runner(recipe, tmp_path / "o.tif", "--chunk", 3, check=False)
    assert p.returncode == 1 and "--chunk" in p.stderr
    p = runner(recipe, tmp_path / "o.tif", "--scheduler", "tcp://127.0.0.1:9", "--processes",
               check=False)
    assert p.returncode == 1 and "--processes" in p.stderr and len(p.stderr.splitlines()) == 1
    assert sorted(os.listdir(tmp_path)) == sorted(before + ["bad.tsyn"])


def test_a_dead_worker_loses_nothing(tmp_path):
    """A running cluster (a scheduler and two workers on loopback, started here as a user
    would); one worker is killed once some tiles are written: Dask makes its tiles again on
    the other (a tile is a pure function of the recipe and its neighbours), and the output
    is the same bytes as gdal_translate."""
    import re
    import signal
    import socket
    import time
    args = ["--exemplar", JACKSBORO, "--size", "1024x768", "--seed", 12, "--tiled", 128]
    recipe = tmp_path / "t.tsyn"
    run("synth", *args, "--recipe", recipe)
    translate(recipe, tmp_path / "gt.tif")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = plugin_env(PLUGINS)
    py = sys.executable
    procs = [subprocess.Popen([py, "-m", "distributed.cli.dask_scheduler", "--host",
                               "127.0.0.1", "--port", str(port), "--dashboard-address", ":0"],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    addr = "tcp://127.0.0.1:%d" % port
    try:
        for _ in range(2):
            procs.append(subprocess.Popen([py, "-m", "distributed.cli.dask_worker", addr,
                                           "--nthreads", "1", "--no-nanny", "--host",
                                           "127.0.0.1", "--dashboard-address", ":0",
                                           "--local-directory", str(tmp_path / "w")],
                                          env=env, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL))
        from distributed import Client
        with Client(addr, timeout=60) as c:
            c.wait_for_workers(2, timeout=60)
        runner_p = subprocess.Popen([py, RUNNER, str(recipe), str(tmp_path / "d.tif"),
                                     "--scheduler", addr, "--no-overviews"], env=env,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        buf, killed = b"", 0
        deadline = time.monotonic() + 300
        while runner_p.poll() is None and time.monotonic() < deadline:
            ch = runner_p.stderr.read1(4096) if hasattr(runner_p.stderr, "read1") else b""
            buf += ch
            m = re.findall(rb"(\d+) of (\d+) tiles", buf)
            if not killed and m and int(m[-1][0]) >= 6:
                procs[1].send_signal(signal.SIGKILL)
                killed = int(m[-1][0])
            if not ch:
                time.sleep(0.05)
        out, err = runner_p.communicate(timeout=300)
        assert runner_p.returncode == 0, (buf + err).decode(errors="replace")
        done = re.findall(rb"(\d+) of (\d+) tiles", buf + err)
        assert 0 < killed < 48 and int(done[-1][0]) == 48, (killed, done[-1])
        same_raster(tmp_path / "d.tif", tmp_path / "gt.tif")
    finally:
        for p in procs:
            p.kill()
            p.wait()


def test_runner_declares_the_tile_interface_as_its_header():
    """The runner loads the plugin's tile functions with ctypes, which cannot read a C
    header: each function it declares has as many arguments, in the same order of kinds
    (pointer, int, array), as gdal_driver/recipe/tsyn_tiles.h gives it."""
    import re

    with open(os.path.join(ROOT, "gdal_driver", "recipe", "tsyn_tiles.h")) as f:
        header = f.read()
    with open(RUNNER) as f:
        runner = f.read()

    def kind_c(param):
        if "[" in param:
            return "array"
        return "int" if re.match(r"^\s*int\s+\w+\s*$", param) else "pointer"

    def kind_py(arg):
        if re.search(r"c_int \* \d|c_void_p \* \d", arg):
            return "array"
        return "int" if arg.strip() == "ctypes.c_int" else "pointer"

    declared = re.findall(r"lib\.(tsyn_\w+)\.argtypes = \[(.*?)\]", runner, re.S)
    assert {n for n, _ in declared} == {"tsyn_tiles_open", "tsyn_tile_make", "tsyn_tile_rect",
                                        "tsyn_tile_reach", "tsyn_tile_drain"}
    for name, args in declared:
        m = re.search(r"\b%s\((.*?)\);" % name, header, re.S)
        assert m, "%s is not in tsyn_tiles.h" % name
        c = [kind_c(p) for p in m.group(1).split(",")]
        py = [kind_py(a) for a in re.split(r",\s*(?![^()]*\))", " ".join(args.split()))]
        assert c == py, "%s: header %s, runner %s" % (name, c, py)


@pytest.mark.parametrize("kind", ["--processes", None])
def test_a_failing_task_is_one_line(tmp_path, kind):
    """A recipe that opens but fails in the workers (an exemplar smaller than a patch): one
    line naming the file, exit 1, no output, with or without -q (Dask's own dumps of each
    failed task stay quiet)."""
    src = gdal.Open(JACKSBORO)
    small = gdal.Translate(str(tmp_path / "tiny.tif"), src, srcWin=[0, 0, 20, 20])
    small = None
    recipe = tmp_path / "t.tsyn"
    run("synth", "--exemplar", tmp_path / "tiny.tif", "--size", "300x260", "--tiled", 128,
        "--recipe", recipe)
    for quiet in (["-q"], []):
        p = runner(recipe, tmp_path / "o.tif", "--workers", 2, *([kind] if kind else []),
                   *quiet, check=False)
        lines = [ln for ln in p.stderr.splitlines() if ln.strip() and not ln.startswith("\r[")]
        assert p.returncode == 1 and len(lines) == 1, p.stderr
        assert "tiny.tif" in lines[0] and "smaller than a patch" in lines[0]
        assert not (tmp_path / "o.tif").exists()


def test_a_full_disk_is_one_line(tmp_path):
    """The output's file cannot grow (a file size limit: writes fail as on a full disk):
    one line naming the output, exit 1, no Python traceback (closing the half-written file
    raised again from its destructor), nothing left in the folder; and no warning about the
    dashboard's port when another cluster holds it."""
    import resource
    import socket
    recipe = tmp_path / "p.tsyn"
    run("pixel", "--exemplar", JACKSBORO, "--size", "600x600", "--seed", 5, "--recipe", recipe)
    out_dir = tmp_path / "out"
    out_dir.mkdir()

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (64 << 10, 64 << 10))

    held = socket.socket()
    try:
        held.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        held.bind(("127.0.0.1", 8787))
        held.listen(1)
    except OSError:
        pass  # taken already: the same test
    try:
        p = subprocess.run([sys.executable, RUNNER, str(recipe), str(out_dir / "o.tif"),
                            "--workers", "2", "-q"],
                           capture_output=True, text=True, env=plugin_env(PLUGINS),
                           timeout=600, preexec_fn=small_files)
    finally:
        held.close()
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode == 1 and len(lines) == 1, p.stderr
    assert lines[0].startswith("terrasynth-dask: ") and "o.tif" in lines[0], lines[0]
    assert os.listdir(out_dir) == []
