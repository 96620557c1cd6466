# SPDX-License-Identifier: GPL-2.0-or-later
"""QGIS test set-up: an offscreen QgsApplication with the Processing framework and the
TerraSynth provider (pytest-qgis is not packaged in Debian, so this is done by hand).

The plugin folder qgis_processing/ is copied into a temporary directory under the
name it has inside the plugin ZIP, `terrasynth_qgis`, so the tests import exactly
what QGIS loads (and no __pycache__ lands in the source tree).

Environment (set by ctest, with defaults for a plain `pytest tests/qgis`):
  TERRASYNTH              the CLI (default build/gdal_driver/terrasynth)
  TS_DATA_DIR             data/ (jacksboro_fault_dem.tif, sketches/lambda_ridges.tif)
  TS_QGIS_SCREENSHOT_DIR  where the dialog screenshot goes (default: pytest's tmp dir)
  TS_QGIS_ZIP             the plugin ZIP built by CMake (tests skip without it)
"""
import atexit
import importlib
import os
import shutil
import sys
import tempfile

import pytest

# Before anything imports qgis: no display, and a throw-away QGIS profile.
os.environ["QT_QPA_PLATFORM"] = "offscreen"
_CONFIG_DIR = tempfile.mkdtemp(prefix="ts-qgis-config-")
os.environ["QGIS_CUSTOM_CONFIG_PATH"] = _CONFIG_DIR
os.environ.setdefault("XDG_RUNTIME_DIR", _CONFIG_DIR)  # silences a Qt warning
sys.dont_write_bytecode = True

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
PLUGIN_SOURCE = os.path.join(ROOT, "qgis_processing")
PLUGIN_NAME = "terrasynth_qgis"
DATA = os.environ.get("TS_DATA_DIR", os.path.join(ROOT, "data"))
JACKSBORO = os.path.join(DATA, "jacksboro_fault_dem.tif")
LAMBDA_RIDGES = os.path.join(DATA, "sketches", "lambda_ridges.tif")
DEFAULT_CLI = os.path.join(ROOT, "build", "gdal_driver", "terrasynth")
if not os.environ.get("TERRASYNTH") and os.path.isfile(DEFAULT_CLI):
    os.environ["TERRASYNTH"] = DEFAULT_CLI
CLI = os.environ.get("TERRASYNTH", "")
PROCESSING_PLUGINS = "/usr/share/qgis/python/plugins"


def stage_plugin(parent):
    """Copy qgis_processing/ to <parent>/terrasynth_qgis; return the plugin folder."""
    dest = os.path.join(parent, PLUGIN_NAME)
    shutil.copytree(PLUGIN_SOURCE, dest,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "CMakeLists.txt",
                                                  "metadata.txt.in"))
    # metadata.txt is made by the build (the version comes from CMakeLists.txt)
    meta = os.environ.get("TS_QGIS_METADATA") or os.path.join(
        ROOT, "build", "qgis_processing", "metadata.txt")
    if os.path.isfile(meta):
        shutil.copy(meta, os.path.join(dest, "metadata.txt"))
    return dest


PLUGIN_PARENT = tempfile.mkdtemp(prefix="ts-qgis-plugins-")
PLUGIN_DIR = stage_plugin(PLUGIN_PARENT)
sys.path.insert(0, PLUGIN_PARENT)
atexit.register(shutil.rmtree, PLUGIN_PARENT, True)
atexit.register(shutil.rmtree, _CONFIG_DIR, True)

try:
    importlib.import_module("qgis.core")
    HAVE_QGIS = True
except ImportError:
    HAVE_QGIS = False


def require_cli():
    if not (CLI and os.access(CLI, os.X_OK)):
        pytest.skip("terrasynth CLI not built (set TERRASYNTH)")
    return CLI


@pytest.fixture(scope="session")
def qgis_app():
    """QgsApplication (no GUI), Processing initialised, TerraSynth provider registered."""
    if not HAVE_QGIS:
        pytest.skip("qgis is not importable (python3-qgis)")
    from qgis.core import QgsApplication

    QgsApplication.setPrefixPath("/usr", True)
    app = QgsApplication([], False)
    app.initQgis()
    for p in (PROCESSING_PLUGINS, PLUGIN_PARENT):
        if p not in sys.path:
            sys.path.append(p)
    from processing.core.Processing import Processing

    Processing.initialize()
    from terrasynth_qgis.plugin import TerraSynthPlugin

    plugin = TerraSynthPlugin(None)
    plugin.initProcessing()
    yield app
    plugin.unload()
    # no app.exitQgis(): tearing QGIS down at interpreter exit is not what is tested
    # here, and a crash there would turn a green run red


@pytest.fixture(scope="session")
def plugin_parent():
    """The folder holding the staged plugin folder terrasynth_qgis/."""
    return PLUGIN_PARENT


@pytest.fixture(scope="session")
def cli():
    return require_cli()


@pytest.fixture(scope="session")
def jacksboro(tmp_path_factory):
    """A copy of the DEM: QGIS writes .aux.xml statistics next to the rasters it loads, and
    data/ must stay as committed."""
    if not os.path.isfile(JACKSBORO):
        pytest.skip("data/jacksboro_fault_dem.tif missing")
    import shutil
    copy = tmp_path_factory.mktemp("data") / "jacksboro_fault_dem.tif"
    shutil.copy(JACKSBORO, copy)
    return str(copy)


@pytest.fixture(scope="session")
def lambda_ridges(tmp_path_factory):
    """A copy of the ridge sketch data/sketches/lambda_ridges.tif (same reason as jacksboro)."""
    if not os.path.isfile(LAMBDA_RIDGES):
        pytest.skip("data/sketches/lambda_ridges.tif missing")
    copy = tmp_path_factory.mktemp("sketches") / "lambda_ridges.tif"
    shutil.copy(LAMBDA_RIDGES, copy)
    return str(copy)
