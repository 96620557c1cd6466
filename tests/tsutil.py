# SPDX-License-Identifier: GPL-2.0-or-later
"""What the command-line tests share: where things are, and running terrasynth."""
import os
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
TERRASYNTH = os.environ.get("TERRASYNTH", os.path.join(ROOT, "build", "gdal_driver", "terrasynth"))
DATA = os.environ.get("TS_DATA_DIR", os.path.join(ROOT, "data"))
SHARED = os.environ.get("TS_SHARED_DEM_DIR", os.path.join(ROOT, "..", "shared", "data", "dem"))
JACKSBORO = os.path.join(DATA, "jacksboro_fault_dem.tif")
# A drawn valley's floor is the valley's own lowest line within a tenth of a patch of the drawn
# one: with the default 64-cell patch, within 6 cells of it.
FLOOR_REACH = 6


def run(*args, check=True):
    """terrasynth with args (str()-ed); raises on a non-zero exit unless check=False."""
    p = subprocess.run([TERRASYNTH, *map(str, args)], capture_output=True, text=True, timeout=900)
    if check and p.returncode != 0:
        raise AssertionError(f"terrasynth failed ({p.returncode}): {p.stderr}")
    return p


def plugin_env(plugins):
    """The environment for a plain program (python3, gdalinfo) that loads the TSYN plugin
    from `plugins`: under the sanitizers the instrumented plugin needs their runtimes
    preloaded (TS_TOOL_PRELOAD)."""
    env = dict(os.environ, GDAL_DRIVER_PATH=plugins)
    if os.environ.get("TS_TOOL_PRELOAD"):
        env.update(LD_PRELOAD=os.environ["TS_TOOL_PRELOAD"], ASAN_OPTIONS="detect_leaks=0")
    return env
