# SPDX-License-Identifier: GPL-2.0-or-later
"""The provider through `qgis_process` (headless, as in scripts and CI), from the
plugin folder and from the plugin ZIP built by CMake (target terrasynth_qgis_zip).

/usr/bin/qgis_process is a Debian wrapper that passes --noversioncheck first and
then fails for every command, so qgis_process.bin is called directly."""
import configparser
import json
import os
import shutil
import stat
import sys
import subprocess
import zipfile

import pytest

pytest.importorskip("qgis.core", reason="qgis is not importable (python3-qgis)")

from osgeo import gdal, osr  # noqa: E402

gdal.UseExceptions()

PLUGIN_NAME = "terrasynth_qgis"

QGIS_PROCESS = shutil.which("qgis_process.bin") or "/usr/bin/qgis_process.bin"
if not os.access(QGIS_PROCESS, os.X_OK):
    pytest.skip("qgis_process.bin not installed (Debian package qgis)", allow_module_level=True)

ZIP = os.environ.get("TS_QGIS_ZIP") or os.path.join(
    os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
    "build", "qgis_processing", "terrasynth_qgis.zip")


def qgis_process(env, *args, timeout=300):
    return subprocess.run([QGIS_PROCESS, *map(str, args)], env=env, capture_output=True,
                          text=True, timeout=timeout)


def make_env(tmp, plugin_parent, base=None):
    """Environment for qgis_process with the plugin enabled in a throw-away profile."""
    env = dict(os.environ if base is None else base, QT_QPA_PLATFORM="offscreen",
               QGIS_PLUGINPATH=str(plugin_parent), QGIS_CUSTOM_CONFIG_PATH=str(tmp / "config"),
               PYTHONDONTWRITEBYTECODE="1", XDG_RUNTIME_DIR=str(tmp))
    p = qgis_process(env, "plugins", "enable", PLUGIN_NAME)
    assert p.returncode == 0, p.stdout + p.stderr
    return env


@pytest.fixture(scope="module")
def env(tmp_path_factory, cli, plugin_parent):
    """plugin_parent holds only the staged copy of qgis_processing/ as terrasynth_qgis/."""
    tmp = tmp_path_factory.mktemp("qgis_process")
    return make_env(tmp, plugin_parent, dict(os.environ, TERRASYNTH=cli))


def test_list(env):
    p = qgis_process(env, "list")
    assert p.returncode == 0, p.stderr
    assert "TerraSynth" in p.stdout
    assert "terrasynth:ppa\tExtract ridges and valleys (PPA)" in p.stdout
    assert "terrasynth:synth\tSynthesize terrain" in p.stdout


def test_help_lists_the_parameters(env):
    p = qgis_process(env, "help", "terrasynth:ppa")
    assert p.returncode == 0, p.stderr
    for key in ("INPUT", "FEATURES", "PROFILE_LENGTH", "THRESHOLD_FRACTION",
                "MIN_BRANCH_LENGTH_UNIT", "LINES", "NODES", "PREVIEW"):
        assert key in p.stdout


def test_run_ppa(env, jacksboro, tmp_path):
    out, lines = tmp_path / "axes.tif", tmp_path / "axes.gpkg"
    p = qgis_process(env, "run", "terrasynth:ppa", "--json", "--", "INPUT=%s" % jacksboro,
                     "FEATURES=2", "OUTPUT=%s" % out, "LINES=%s" % lines)
    assert p.returncode == 0, p.stdout + p.stderr
    results = json.loads(p.stdout)["results"]
    assert results["OUTPUT"] == str(out)
    assert results["LINES"] == "%s|layername=paths" % lines
    assert results["NODES"] == "%s|layername=nodes" % lines
    ds, ds_in = gdal.Open(str(out)), gdal.Open(jacksboro)
    assert osr.SpatialReference(wkt=ds.GetProjection()).IsSame(
        osr.SpatialReference(wkt=ds_in.GetProjection()))
    v = gdal.OpenEx(str(lines), gdal.OF_VECTOR)
    assert {v.GetLayer(i).GetName() for i in range(v.GetLayerCount())} == {"paths", "nodes"}


def test_run_synth_over_an_extent(env, jacksboro, tmp_path):
    """EXTENT as qgis_process takes it ("xmin,xmax,ymin,ymax [CRS]") and PIXEL_SIZE."""
    out = tmp_path / "new.tif"
    p = qgis_process(env, "run", "terrasynth:synth", "--json", "--",
                     "EXEMPLARS=%s" % jacksboro,
                     "EXTENT=400000,402990,3900000,3902000 [EPSG:32616]", "PIXEL_SIZE=40",
                     "PATCH_SIZE=24", "OVERLAP=6", "OUTPUT=%s" % out)
    assert p.returncode == 0, p.stdout + p.stderr
    ds = gdal.Open(str(out))
    assert (ds.RasterXSize, ds.RasterYSize) == (75, 50)  # 2990/40 = 74.75 -> 75; 2000/40
    assert ds.GetGeoTransform() == pytest.approx((400000, 40, 0, 3902000, 0, -40))
    srs = osr.SpatialReference(wkt=ds.GetProjection())
    srs.AutoIdentifyEPSG()
    assert srs.GetAuthorityCode(None) == "32616"  # the extent's CRS, not the exemplar's 4326


def test_run_amplify(env, jacksboro, tmp_path):
    out = tmp_path / "fine.tif"
    p = qgis_process(env, "run", "terrasynth:amplify", "--json", "--", "INPUT=%s" % jacksboro,
                     "EXEMPLARS=%s" % jacksboro, "FACTOR=2", "OUTPUT=%s" % out)
    assert p.returncode == 0, p.stdout + p.stderr
    ds, src = gdal.Open(str(out)), gdal.Open(jacksboro)
    assert (ds.RasterXSize, ds.RasterYSize) == (2 * src.RasterXSize, 2 * src.RasterYSize)


def test_run_error_exit_status(env, jacksboro, tmp_path):
    p = qgis_process(env, "run", "terrasynth:ppa", "--", "INPUT=%s" % jacksboro, "BAND=7",
                     "OUTPUT=%s" % (tmp_path / "a.tif"))
    assert p.returncode != 0
    assert "band 7 does not exist" in p.stdout + p.stderr
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------- the plugin ZIP

@pytest.fixture(scope="module")
def plugin_zip():
    if not os.path.isfile(ZIP):
        pytest.skip("plugin ZIP not built (cmake --build build --target terrasynth_qgis_zip)")
    return ZIP


def test_zip_layout(plugin_zip):
    with zipfile.ZipFile(plugin_zip) as z:
        names = set(z.namelist())
        meta = configparser.ConfigParser()
        meta.read_string(z.read(PLUGIN_NAME + "/metadata.txt").decode())
    files = {n for n in names if not n.endswith("/")}
    assert all(n.startswith(PLUGIN_NAME + "/") for n in names)
    for f in ("__init__.py", "plugin.py", "provider.py", "runner.py", "descriptors.py",
              "algorithms/__init__.py", "algorithms/base.py", "algorithms/ppa.py",
              "algorithms/synth.py", "metadata.txt", "icon.svg", "README.md", "LICENSE",
              "bin/terrasynth"):
        assert PLUGIN_NAME + "/" + f in files, f
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
    assert meta["general"]["hasProcessingProvider"] == "yes"
    assert meta["general"]["qgisMinimumVersion"] == "3.22"


def test_zip_installed_like_qgis_runs_its_own_binary(plugin_zip, jacksboro, tmp_path):
    """Unpacked the way QGIS' "Install from ZIP" does (zipfile: modes are lost), with no
    TERRASYNTH and no terrasynth on PATH: the plugin finds and uses bin/terrasynth."""
    plugins = tmp_path / "profile_plugins"
    with zipfile.ZipFile(plugin_zip) as z:
        z.extractall(plugins)
    exe = plugins / PLUGIN_NAME / "bin" / "terrasynth"
    os.chmod(exe, 0o644)
    base = {k: v for k, v in os.environ.items() if k != "TERRASYNTH"}
    base["PATH"] = "/usr/bin:/bin"
    assert shutil.which("terrasynth", path=base["PATH"]) is None
    env = make_env(tmp_path, plugins, base)
    out = tmp_path / "axes.tif"
    p = qgis_process(env, "run", "terrasynth:ppa", "--", "INPUT=%s" % jacksboro,
                     "OUTPUT=%s" % out)
    assert p.returncode == 0, p.stdout + p.stderr
    assert str(exe) in p.stdout  # the command line echoed in the log
    assert os.stat(exe).st_mode & stat.S_IXUSR
    assert gdal.Open(str(out)).RasterXSize == gdal.Open(jacksboro).RasterXSize


# --------------------------------------------------------------------------- the job's rules

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import job_cases  # noqa: E402

QGIS_CASES = [(c[0], c[3], c[4]) for c in job_cases.CASES if c[3] is not None]


@pytest.mark.parametrize("alg,params,message", QGIS_CASES, ids=[c[2][:40] for c in QGIS_CASES])
def test_rules_say_what_the_cli_says(env, jacksboro, lambda_ridges, tmp_path, alg, params,
                                     message):
    """The bad combinations of tests/job_cases.py through qgis_process: refused before
    anything runs, with the command line's message."""
    names = {"EX": jacksboro, "SK": lambda_ridges}
    args = ["%s=%s" % (k, names.get(v, v) if isinstance(v, str) else v)
            for k, v in params.items()]
    out = tmp_path / "out.tif"
    p = qgis_process(env, "run", "terrasynth:" + alg, "--", *args, "OUTPUT=%s" % out)
    assert p.returncode != 0
    assert message in p.stdout + p.stderr, p.stdout + p.stderr
    assert os.listdir(tmp_path) == []
