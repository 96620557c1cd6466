# SPDX-License-Identifier: GPL-2.0-or-later
"""No unbounded memory: a job's memory is estimated from the sizes of its
grids before anything is read or allocated, and refused past the machine's memory, or past
--max-memory / TSYN_MAX_MEMORY, with a message that says how much is needed.  The same in
the GDAL driver.  The estimate is checked against the peak the kernel measures."""
import os
import re
import subprocess
import sys
import time

import pytest
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import JACKSBORO, ROOT, TERRASYNTH, plugin_env, run  # noqa: E402

gdal.UseExceptions()
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
NEEDS = re.compile(r"needs about ([0-9.e+-]+) GB of memory, more than the ([0-9.e+-]+) GB")


def huge_vrt(tmp_path, size=100000, name="huge.vrt"):
    """A VRT that says it is size x size cells (over the small real DEM)."""
    src = gdal.Open(JACKSBORO)
    gt = src.GetGeoTransform()
    p = tmp_path / name
    p.write_text(
        '<VRTDataset rasterXSize="%d" rasterYSize="%d"><SRS>%s</SRS>'
        '<GeoTransform>%r, %r, 0, %r, 0, %r</GeoTransform>'
        '<VRTRasterBand dataType="Float32" band="1"><SimpleSource>'
        '<SourceFilename relativeToVRT="0">%s</SourceFilename><SourceBand>1</SourceBand>'
        '</SimpleSource></VRTRasterBand></VRTDataset>'
        % (size, size, src.GetProjection().replace('"', "&quot;"), gt[0], gt[1] / 100, gt[3],
           gt[5] / 100, JACKSBORO))
    return p


@pytest.mark.parametrize("args", [
    ["synth", "--exemplar", JACKSBORO, "--size", "65536x65536", "{out}"],
    ["synth", "--exemplar", JACKSBORO, "--like", "{huge}", "{out}"],
    ["synth", "--exemplar", "{huge}", "--size", "64x64", "{out}"],
    # the PPA maps a DEM too large for memory in tiles: refused only when even tiles do not
    # fit (the chains held are a byte a cell): 10^12 cells
    ["ppa", "{vast}", "{out}"],
])
def test_too_big_for_the_machine_is_refused_at_once(tmp_path, args):
    huge = huge_vrt(tmp_path)
    vast = huge_vrt(tmp_path, 1000000, "vast.vrt")
    argv = [a.format(out=tmp_path / "o.tif", huge=huge, vast=vast) for a in args]
    t0 = time.monotonic()
    p = run(*argv, "-q", check=False)
    took = time.monotonic() - t0
    assert p.returncode == 1, p.stderr
    m = NEEDS.search(p.stderr)
    assert m, p.stderr
    need, limit = float(m.group(1)), float(m.group(2))
    assert need > limit and "this machine has" in p.stderr
    assert took < 60  # refused from the sizes, nothing read or allocated
    assert not (tmp_path / "o.tif").exists()


def test_max_memory_option_and_config(tmp_path):
    out = tmp_path / "o.tif"
    args = ["synth", "--exemplar", JACKSBORO, "--size", "512x512", out, "-q"]
    p = run(*args, "--max-memory", "50M", check=False)
    assert p.returncode == 1 and "GB allowed (--max-memory" in p.stderr, p.stderr
    assert not out.exists()
    run(*args, "--max-memory", "8G")
    assert out.exists()
    out.unlink()
    # the configuration option, as GDAL reads it (an environment variable here)
    p = subprocess.run([TERRASYNTH, *map(str, args)], capture_output=True, text=True,
                       env=dict(os.environ, TSYN_MAX_MEMORY="50"))
    assert p.returncode == 1 and "allowed" in p.stderr
    for bad in ("lots", "-5G", "0", "150%"):
        p = run(*args, "--max-memory", bad, check=False)
        assert p.returncode == 2 and "--max-memory takes an amount of memory" in p.stderr


def test_driver_refuses_at_open(tmp_path):
    r = tmp_path / "big.tsyn"
    run("synth", "--exemplar", JACKSBORO, "--size", "65536x65536", "--recipe", r)
    code = ("import sys; from osgeo import gdal; gdal.UseExceptions()\n"
            "for k, v in [a.split('=', 1) for a in sys.argv[2:]]: gdal.SetConfigOption(k, v)\n"
            "try:\n  gdal.Open(sys.argv[1])\nexcept RuntimeError as e:\n  print(e); sys.exit(1)\n")
    env = plugin_env(PLUGINS)
    p = subprocess.run([sys.executable, "-c", code, str(r)], capture_output=True, text=True,
                       env=env, timeout=120)
    assert p.returncode == 1 and NEEDS.search(p.stdout), p.stdout + p.stderr
    small = tmp_path / "small.tsyn"
    run("synth", "--exemplar", JACKSBORO, "--size", "512x512", "--recipe", small)
    p = subprocess.run([sys.executable, "-c", code, str(small), "TSYN_MAX_MEMORY=50M"],
                       capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 1 and "allowed" in p.stdout, p.stdout + p.stderr


TIME = "/usr/bin/time"  # Debian package time (tools/install-deps.sh)


def peak_rss(argv, tmp_path):
    """Run argv; its peak resident memory in bytes, as the kernel counts it, through
    /usr/bin/time: a child of this Python (forked or spawned) would count this Python's own
    pages from before its exec."""
    out = tmp_path / "rss.txt"
    p = subprocess.run([TIME, "-o", str(out), "-f", "%M", *map(str, argv)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return int(out.read_text().split()[-1]) * 1024


@pytest.mark.skipif(bool(os.environ.get("TS_TOOL_PRELOAD")),
                    reason="sanitizers multiply the memory a run takes")
@pytest.mark.skipif(not os.access(TIME, os.X_OK), reason="/usr/bin/time not installed")
@pytest.mark.parametrize("args", [
    ["synth", "--exemplar", JACKSBORO, "--size", "1024x1024"],
    ["synth", "--exemplar", JACKSBORO, "--exemplar", JACKSBORO, "--size", "700x500",
     "--debug-dir", "{dbg}"],
    ["synth", "--sketch", os.path.join(os.path.dirname(JACKSBORO), "sketches",
                                       "lambda_ridges.tif"), "--exemplar", JACKSBORO],
    ["ppa", JACKSBORO],
    # many exemplars matched at full resolution: the FFT spectra of every exemplar
    ["synth", *["--exemplar", "{fine}"] * 16, "--size", "512x512", "--coarse-factor", "1",
     "--candidates", "32"],
    ["synth", "--exemplar", JACKSBORO, "--size", "1536x1024", "--tiled", "256"],
    ["pixel", "--exemplar", JACKSBORO, "--size", "512x512", "--window", "7", "--coherence", "4"],
    ["amplify", "{coarse}", "--exemplar", JACKSBORO, "--factor", "4"],
    # a dictionary's atoms, held twice while the file is written: a lattice of phase 0
    # (more windows than atoms), every phase (fewer)
    ["dictionary", "build", "{dict}", "--exemplar", JACKSBORO, "--resolution", "30",
     "--factor", "2", "--atoms", "100000"],
    ["dictionary", "build", "{dict}", "--exemplar", JACKSBORO, "--exemplar", JACKSBORO,
     "--resolution", "45", "--factor", "4", "--atoms", "50000"],
])
def test_the_estimate_covers_the_measured_peak(tmp_path, args):
    if "{coarse}" in args:
        gdal.Warp(str(tmp_path / "coarse.tif"), JACKSBORO, xRes=0.0025, yRes=0.0025,
                  resampleAlg="average")
    if "{fine}" in args:  # 806 x 688 cells
        gdal.Warp(str(tmp_path / "fine.tif"), JACKSBORO, xRes=0.000416666666667,
                  yRes=0.000416666666667, resampleAlg="cubic")
    argv = [a.format(dbg=tmp_path / "dbg", coarse=tmp_path / "coarse.tif",
                     fine=tmp_path / "fine.tif", dict=tmp_path / "d.tsd") for a in args]
    if args[0] != "dictionary":
        argv += [tmp_path / "o.tif"]
    argv += ["-q"]
    p = run(*argv, "--max-memory", "1K", check=False)
    m = NEEDS.search(p.stderr)
    assert m, p.stderr
    estimate = float(m.group(1)) * 2**30
    peak = peak_rss([TERRASYNTH, *argv], tmp_path)
    assert peak <= estimate, (peak, estimate)
    assert estimate < 6 * peak + 200e6  # and not absurdly above it
