# SPDX-License-Identifier: GPL-2.0-or-later
"""One declaration per job: the command line and recipes reject the same bad combinations with
the same message (the rules live in gdal_driver/jobs/declarations.c alone; tests/qgis drives the QGIS
provider with the same cases, tests/job_cases.py).  Also: options that do not apply are refused, not
silently ignored."""
import os
import subprocess
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import job_cases  # noqa: E402
from tsutil import JACKSBORO, TERRASYNTH, run  # noqa: E402

LAMBDA = os.path.join(os.path.dirname(JACKSBORO), "sketches", "lambda_ridges.tif")
PLUGINS = os.environ.get("TS_GDAL_PLUGINS",
                         os.path.join(os.path.dirname(os.path.dirname(TERRASYNTH)), "gdalplugins"))

CASES = [(c[0], c[1], c[2], c[4]) for c in job_cases.CASES]


def names(tmp):
    import shutil
    shutil.copy(JACKSBORO, tmp / "ex.tif")
    shutil.copy(LAMBDA, tmp / "sk.tif")
    return {"EX": str(tmp / "ex.tif"), "SK": str(tmp / "sk.tif")}


@pytest.mark.parametrize("cmd,args,xml,message", CASES, ids=[c[3][:40] for c in CASES])
def test_cli_and_recipe_say_the_same(tmp_path, cmd, args, xml, message):
    n = names(tmp_path)
    out = tmp_path / "out.tif"
    p = run(cmd, *[n.get(a, a) for a in args], *([] if cmd == "ppa" else []), out, "-q",
            check=False)
    assert p.returncode == 2, p.stderr
    assert message in p.stderr, p.stderr
    assert not out.exists()
    recipe = tmp_path / "r.tsyn"
    for k, v in n.items():
        xml = xml.replace(">" + k + "<", ">" + os.path.basename(v) + "<").replace(
            "'" + k + "'", "'" + os.path.basename(v) + "'")
    recipe.write_text("<TerraSynth version='1'>" + xml + "</TerraSynth>")
    env = dict(os.environ, GDAL_DRIVER_PATH=PLUGINS)
    if os.environ.get("TS_TOOL_PRELOAD"):  # an instrumented plugin in a plain tool
        env.update(LD_PRELOAD=os.environ["TS_TOOL_PRELOAD"], ASAN_OPTIONS="detect_leaks=0")
    g = subprocess.run(["gdalinfo", str(recipe)], capture_output=True, text=True, env=env)
    assert g.returncode != 0
    assert message in g.stderr, g.stderr


def test_options_are_listed_once_in_describe():
    import json
    d = json.loads(run("describe").stdout)
    for job in ("ppa", "synth"):
        opts = [o["name"] for o in d["jobs"][job]["options"]]
        assert len(opts) == len(set(opts))
        params = {p["name"] for s in d["jobs"][job]["stages"] for p in d["stages"][s]}
        assert not params & set(opts), params & set(opts)
        for r in d["jobs"][job]["rules"]:
            for name in [r["a"]] + r["b"]:
                assert name in opts or name in params or name.startswith("@"), name
    limits = {o["name"]: o["max_count"] for o in d["jobs"]["synth"]["options"]}
    assert limits["exemplar"] == 64 and limits["pin"] == 16


def test_help_lists_every_option_and_rule():
    h = run("synth", "--help").stdout
    for flag in ("--exemplar", "--cell-size", "--sketch", "--pin", "--water-level", "--alpha-h",
                 "--region-exemplar", "--seed", "--debug-dir", "--layout", "--alpha-p"):
        assert flag in h, flag
    assert "Rules:" in h and "water goes with water_level" in h


def test_cell_size_over_two_geotransforms(tmp_path):
    """--cell-size is the ground cell of every raster without a CRS: a guide, sketch or input
    whose geotransform gives other cells than the exemplar's is taken at that size too, and
    the command says so (one line, the job still runs); not when their cells agree, when
    they have a CRS, or without --cell-size."""
    import numpy as np
    from osgeo import gdal, osr

    yy, xx = np.mgrid[0:96, 0:96].astype(np.float32)
    relief = 300 + 40 * np.sin(xx / 7.0) * np.cos(yy / 9.0) + 3 * xx

    def write(path, cell, crs=False, a=relief):
        ds = gdal.GetDriverByName("GTiff").Create(str(path), a.shape[1], a.shape[0], 1,
                                                  gdal.GDT_Float32)
        ds.SetGeoTransform((0, cell, 0, cell * a.shape[0], 0, -cell))
        if crs:
            s = osr.SpatialReference()
            s.ImportFromEPSG(32631)
            ds.SetProjection(s.ExportToWkt())
        ds.GetRasterBand(1).WriteArray(a)
        ds = None
        return str(path)

    said = "give them a CRS"
    cases = [  # (grid cell, exemplar cell, CRS, --cell-size, warned)
        (80, 20, False, True, True),
        (20, 20, False, True, False),
        (80, 20, True, True, False),
        (80, 20, False, False, False),
    ]
    for k, (gc, ec, crs, cs, warned) in enumerate(cases):
        ex = write(tmp_path / ("ex%d.tif" % k), ec, crs)
        guide = write(tmp_path / ("g%d.tif" % k), gc, crs)
        extra = ["--cell-size", "20"] if cs else []
        p = run("pixel", "--exemplar", ex, "--guide", guide, *extra,
                tmp_path / ("p%d.tif" % k), "-q")
        assert (said in p.stderr) == warned, (k, p.stderr)
        if warned:
            line = [ln for ln in p.stderr.splitlines() if said in ln][0]
            assert guide in line and "80" in line and "20 m" in line, line
    # the same rule for a sketch (synth) and an input (amplify)
    ex = write(tmp_path / "ex.tif", 20)
    sk = write(tmp_path / "sk.tif", 80, a=(relief > 320).astype(np.float32))
    p = run("synth", "--exemplar", ex, "--sketch", sk, "--cell-size", "20",
            tmp_path / "s.tif", "-q", check=False)
    assert said in p.stderr, p.stderr
    coarse = write(tmp_path / "in.tif", 80, a=relief[::4, ::4].copy())
    p = run("amplify", coarse, "--exemplar", ex, "--cell-size", "20",
            tmp_path / "a.tif", "-q", check=False)
    assert said in p.stderr, p.stderr
