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


@pytest.mark.parametrize("alg_id,labels", [
    ("terrasynth:ppa", ["Input DEM", "Features", "Profile length (cells)",
                        "Minimum branch length unit", "Ridges and valleys"]),
    ("terrasynth:synth", ["Exemplar DEMs", "Target grid like [optional]", "Patch size (cells)",
                          "Overlap (cells)", "Placement order"]),
])
def test_dialog_screenshot(alg_id, labels, tmp_path, plugin_parent):
    shots = os.environ.get("TS_QGIS_SCREENSHOT_DIR") or str(tmp_path)
    png = os.path.join(shots, alg_id.replace(":", "_") + "_dialog.png")
    if os.path.exists(png):
        os.remove(png)
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen",
               QGIS_CUSTOM_CONFIG_PATH=str(tmp_path / "config"), PYTHONDONTWRITEBYTECODE="1")
    p = subprocess.run([sys.executable, SCRIPT, plugin_parent, alg_id, png], env=env,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    info = json.loads(p.stdout.strip().splitlines()[-1])
    print("dialog screenshot:", info["png"])
    assert info["png"] == os.path.abspath(png) and os.path.getsize(png) > 10000
    assert (info["width"], info["height"]) == (1000, 760)
    assert info["colours"] > 20, "the screenshot looks blank"
    assert info["help"], "the help panel does not show the algorithm's help"
    for label in labels:
        assert any(text.startswith(label) for text in info["labels"]), (label, info["labels"])
