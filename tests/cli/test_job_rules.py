# SPDX-License-Identifier: GPL-2.0-or-later
"""One declaration per job: the command line and recipes reject the same bad combinations with
the same message (the rules live in gdal_driver/jobspec.c alone; tests/qgis drives the QGIS
provider with the cases it can express).  Also: options that do not apply are refused, not
silently ignored (issue 11)."""
import os
import subprocess
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import JACKSBORO, TERRASYNTH, run  # noqa: E402

LAMBDA = os.path.join(os.path.dirname(JACKSBORO), "sketches", "lambda_ridges.tif")
PLUGINS = os.environ.get("TS_GDAL_PLUGINS",
                         os.path.join(os.path.dirname(os.path.dirname(TERRASYNTH)), "gdalplugins"))

# (CLI arguments after "synth" / "ppa", the same job as a recipe's element, the message)
CASES = [
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--alpha-r", "1"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/>"
     "<Param name='alpha_r'>1</Param></Synth>",
     "alpha_r applies to a sketch: give sketch"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--layout", "0.5"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/>"
     "<Param name='layout'>0.5</Param></Synth>",
     "layout applies to a sketch: give sketch"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--mode", "valleys"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/>"
     "<Param name='mode'>valleys</Param></Synth>",
     "mode applies to a sketch: give sketch"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--alpha-h", "2"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/><Heights alpha='2'/></Synth>",
     "alpha_h weighs heights: give heights"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--water", "EX"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/><Water>EX</Water></Synth>",
     "water and water_level go together"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--regions", "EX"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/><Regions>EX</Regions></Synth>",
     "regions and region_exemplar go together"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--crs", "EPSG:32616"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100' crs='EPSG:32616'/></Synth>",
     "a CRS needs an origin and a resolution"),
    ("synth", ["--exemplar", "EX", "--sketch", "SK", "--size", "100x100"],
     "<Synth><Exemplar>EX</Exemplar><Sketch>SK</Sketch><Grid width='100' height='100'/></Synth>",
     "a sketch sets the output grid: give no size"),
    ("synth", ["--exemplar", "EX", "--like", "EX", "--resolution", "30"],
     "<Synth><Exemplar>EX</Exemplar><Grid like='EX' resolution='30'/></Synth>",
     "like sets the output grid: give no resolution"),
    ("synth", ["--exemplar", "EX"],
     "<Synth><Exemplar>EX</Exemplar></Synth>",
     "give the target grid: a sketch, like or size"),
    ("synth", ["--size", "100x100"],
     "<Synth><Grid width='100' height='100'/></Synth>",
     "needs at least one exemplar"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--seed", "-1"],
     "<Synth seed='-1'><Exemplar>EX</Exemplar><Grid width='100' height='100'/></Synth>",
     "seed must be a non-negative integer, not '-1'"),
    ("synth", ["--exemplar", "EX", "--size", "0x100"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='0' height='100'/></Synth>",
     "size takes WxH in cells (1..65536), not '0x100'"),
    ("ppa", ["EX", "--threshold", "5", "--threshold-fraction", "0.01"],
     "<PPA><Input>EX</Input><Param name='threshold'>5</Param>"
     "<Param name='threshold_fraction'>0.01</Param></PPA>",
     "give threshold or threshold_fraction, not both"),
    ("ppa", ["EX", "--band", "0"],
     "<PPA><Input band='0'>EX</Input></PPA>",
     "band must be a whole number in 1..65535, not '0'"),
]


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
