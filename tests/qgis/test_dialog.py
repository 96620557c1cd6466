# SPDX-License-Identifier: GPL-2.0-or-later
"""The algorithm dialogs in QGIS' GUI, offscreen: they open, show the parameters and
the help, and a screenshot is saved (TS_QGIS_SCREENSHOT_DIR, else pytest's tmp dir)."""
import json
import os
import subprocess
import sys

import pytest

pytest.importorskip("qgis.core", reason="qgis is not importable (python3-qgis)")

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "dialog_screenshot.py")


@pytest.mark.parametrize("alg_id,labels,values,expect", [
    ("terrasynth:ppa", ["Input DEM", "Features", "Profile length (cells)",
                        "Minimum branch length unit", "Ridges and valleys"],
     {"INPUT": "DEM", "FEATURES": 2, "MIN_BRANCH_LENGTH": 600, "MIN_BRANCH_LENGTH_UNIT": 1},
     {"--features": "both", "--min-branch-length": "600m", "--band": "1"}),
    ("terrasynth:synth", ["Exemplar DEMs", "Sketch [optional]", "Target grid like [optional]",
                          "Patch size", "Patch size unit", "Overlap", "Placement order",
                          "Sketch mode"],
     {"EXEMPLARS": ["DEM"], "WIDTH": 96, "HEIGHT": 80, "PATCH_SIZE": 32, "OVERLAP": 8},
     {"--size": "96x80", "--patch-size": "32", "--overlap": "8", "--exemplar": "DEM"}),
])
def test_dialog_screenshot(alg_id, labels, values, expect, tmp_path, plugin_parent, jacksboro):
    shots = os.environ.get("TS_QGIS_SCREENSHOT_DIR") or str(tmp_path)
    png = os.path.join(shots, alg_id.replace(":", "_") + "_dialog.png")
    if os.path.exists(png):
        os.remove(png)
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen",
               QGIS_CUSTOM_CONFIG_PATH=str(tmp_path / "config"), PYTHONDONTWRITEBYTECODE="1",
               TMPDIR=str(tmp_path))  # QGIS puts its processing_* temp folders there
    values = {k: ([jacksboro] if v == ["DEM"] else jacksboro if v == "DEM" else v)
              for k, v in values.items()}
    params = tmp_path / "parameters.json"
    params.write_text(json.dumps(values))
    p = subprocess.run([sys.executable, SCRIPT, plugin_parent, alg_id, png, str(params)],
                       env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    info = json.loads(p.stdout.strip().splitlines()[-1])
    print("dialog screenshot:", info["png"])
    assert info["png"] == os.path.abspath(png) and os.path.getsize(png) > 10000
    assert (info["width"], info["height"]) == (1000, 760)
    assert info["colours"] > 20, "the screenshot looks blank"
    assert info["help"], "the help panel does not show the algorithm's help"
    for label in labels:
        assert any(text.startswith(label) for text in info["labels"]), (label, info["labels"])
    # what the dialog's widgets produce (optional outputs, unset CRS, temporary files...)
    # passes the checks and makes a valid command line
    assert info["check"] == [True, ""], info["check"]
    argv = info["argv"]
    assert argv[:2] == ["terrasynth", alg_id.split(":")[1]] and "--progress-lines" in argv
    for flag, value in expect.items():
        assert argv[argv.index(flag) + 1] == (jacksboro if value == "DEM" else value), flag
    assert "--crs" not in argv and "--origin" not in argv and "--like" not in argv
    assert "--preview" not in argv and "--debug-dir" not in argv  # off by default
    assert "--sketch" not in argv and "--mode" not in argv  # no sketch: no sketch options
