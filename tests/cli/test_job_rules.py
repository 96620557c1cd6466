# SPDX-License-Identifier: GPL-2.0-or-later
"""One declaration per job: the command line and recipes reject the same bad combinations with
the same message (the rules live in gdal_driver/jobspec.c alone; tests/qgis drives the QGIS
provider with the same cases, tests/job_cases.py).  Also: options that do not apply are refused, not
silently ignored (issue 11)."""
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
