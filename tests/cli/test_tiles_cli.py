# SPDX-License-Identifier: GPL-2.0-or-later
"""terrasynth synth --tiled (tiled_synthesis.c, issue 16): the same bytes on 1 and 2
threads and through a recipe; no seam along the tile borders by the independent yardstick
(../shared/eval/terrain_metrics.py, when present); refusals in one line."""
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
METRICS = os.path.normpath(os.path.join(SHARED, "..", "..", "eval", "terrain_metrics.py"))
ARGS = ["--exemplar", JACKSBORO, "--size", "420x300", "--seed", 9, "--tiled", 128]


def test_threads_recipe_and_seams(tmp_path):
    run("synth", *ARGS, "--threads", 1, tmp_path / "t1.tif", "-q")
    run("synth", *ARGS, "--threads", 2, tmp_path / "t2.tif", "-q")
    a = gdal.Open(str(tmp_path / "t1.tif")).ReadAsArray()
    b = gdal.Open(str(tmp_path / "t2.tif")).ReadAsArray()
    assert a.tobytes() == b.tobytes()
    assert np.isfinite(a).all() and (a != -9999).all()
    run("synth", *ARGS, "--recipe", tmp_path / "t.tsyn")
    subprocess.run(["gdal_translate", "-q", str(tmp_path / "t.tsyn"), str(tmp_path / "r.tif")],
                   check=True, env=plugin_env(PLUGINS))
    assert gdal.Open(str(tmp_path / "r.tif")).ReadAsArray().tobytes() == a.tobytes()
    # a tiled terrain is its own: not the run in one piece
    run("synth", *ARGS[:-2], tmp_path / "one.tif", "-q")
    assert gdal.Open(str(tmp_path / "one.tif")).ReadAsArray().tobytes() != a.tobytes()
    if os.path.exists(METRICS):
        p = subprocess.run([sys.executable, METRICS, "--out", str(tmp_path / "t1.tif"),
                            "--exemplar", JACKSBORO], capture_output=True, text=True, check=True)
        m = json.loads(p.stdout)
        assert m["seam_lap"] <= 1.2 and m["seam_grad"] <= 1.2, m


@pytest.mark.parametrize("extra,words", [
    (["--tiled", 20], "tiles of 20 cells"),
    (["--tiled", 128, "--sketch", os.path.join(os.path.dirname(JACKSBORO), "sketches",
                                                    "lambda_ridges.tif")], "not with a sketch"),
])
def test_refusals(tmp_path, extra, words):
    args = ["--exemplar", JACKSBORO, *extra]
    if "--sketch" not in extra:
        args += ["--size", "200x200"]
    p = run("synth", *args, tmp_path / "o.tif", "-q", check=False)
    assert p.returncode != 0 and words in p.stderr and len(p.stderr.strip().splitlines()) == 1, \
        p.stderr
    assert not os.listdir(tmp_path)
