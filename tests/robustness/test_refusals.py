# SPDX-License-Identifier: GPL-2.0-or-later
"""One rule each, said once: seeds past 2^64-1 refused everywhere, a
grid past a pole refused by every job, no message prefixed twice."""
import os
import subprocess
import sys

import numpy as np
import pytest
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import JACKSBORO, ROOT, plugin_env, run  # noqa: E402

gdal.UseExceptions()
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
TOO_BIG = "18446744073709551616"  # 2^64


def test_seed_past_2_64_refused_on_the_command_line(tmp_path):
    p = run("synth", "--exemplar", JACKSBORO, "--size", "64x64", "--seed", TOO_BIG,
            tmp_path / "o.tif", "-q", check=False)
    assert p.returncode == 2
    assert "seed must be a whole number in 0..18446744073709551615, not '%s'" % TOO_BIG \
        in p.stderr
    assert not (tmp_path / "o.tif").exists()
    run("synth", "--exemplar", JACKSBORO, "--size", "64x64", "--seed", "18446744073709551615",
        tmp_path / "o.tif", "-q")


@pytest.mark.parametrize("how", ["recipe", "open_option"])
def test_seed_past_2_64_refused_by_recipes(tmp_path, how):
    r = tmp_path / "r.tsyn"
    run("synth", "--exemplar", JACKSBORO, "--size", "64x64", "--recipe", r)
    if how == "recipe":
        r.write_text(r.read_text().replace("<Synth>", "<Synth seed=\"%s\">" % TOO_BIG))
    code = ("import sys; from osgeo import gdal; gdal.UseExceptions()\n"
            "try:\n  gdal.OpenEx(sys.argv[1], open_options=sys.argv[2:])\n"
            "except RuntimeError as e:\n  print(e); sys.exit(1)\n")
    oo = ["SEED=" + TOO_BIG] if how == "open_option" else []
    p = subprocess.run([sys.executable, "-c", code, str(r), *oo], capture_output=True,
                       text=True, env=plugin_env(PLUGINS))
    assert p.returncode == 1, p.stdout + p.stderr
    assert "seed must be a whole number in 0..18446744073709551615" in p.stdout


def past_the_pole(tmp_path):
    src = gdal.Open(JACKSBORO)
    z = src.ReadAsArray().astype(np.float32)
    p = tmp_path / "pole.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(p), z.shape[1], z.shape[0], 1,
                                              gdal.GDT_Float32)
    ds.SetGeoTransform((0, 0.01, 0, 92, 0, -0.01))
    ds.SetProjection(src.GetProjection())  # geographic (EPSG:4326)
    ds.GetRasterBand(1).WriteArray(z)
    ds = None
    return p


@pytest.mark.parametrize("cmd", [
    ["ppa", "{pole}", "{out}", "--min-branch-length", "500m"],
    ["ppa", "{pole}", "{out}"],
    ["synth", "--exemplar", "{pole}", "--size", "64x64", "{out}"],
    ["synth", "--exemplar", JACKSBORO, "--like", "{pole}", "{out}"],
])
def test_a_grid_past_the_pole_is_one_rule(tmp_path, cmd):
    pole = past_the_pole(tmp_path)
    args = [a.format(pole=pole, out=tmp_path / "o.tif") for a in cmd]
    p = run(*args, "-q", check=False)
    assert p.returncode == 1
    assert "the grid reaches latitude 92, past the pole" in p.stderr, p.stderr
    assert not (tmp_path / "o.tif").exists()


def test_no_prefix_said_twice(tmp_path):
    for args in (["synth", "--exemplar", JACKSBORO, "--size", "64x64", "--patch-size", "4",
                  tmp_path / "o.tif"],
                 ["synth", "--exemplar", JACKSBORO, "--size", "64x64", "--overlap", "64",
                  tmp_path / "o.tif"]):
        p = run(*args, "-q", check=False)
        assert p.returncode != 0
        line = p.stderr.strip()
        assert "synth: synth:" not in line and "synth: synth" not in line, line
        assert line.count("\n") == 0


def test_a_very_long_name_leaves_room_for_the_problem(tmp_path):
    """A 5000-character input name is shortened in the message (its two ends), so the one
    line still says what is wrong."""
    name = tmp_path / ("a" * 5000 + ".tif")
    p = run("ppa", name, tmp_path / "o.tif", check=False)
    assert p.returncode == 1
    line = p.stderr.strip()
    assert len(line.splitlines()) == 1 and line.endswith(".tif: no such file"), line[-200:]
    assert "..." in line and len(line) < 1024
