# SPDX-License-Identifier: GPL-2.0-or-later
"""The TerraSynth Processing provider (id `terrasynth`)."""
import os
import subprocess

from qgis.core import Qgis, QgsMessageLog, QgsProcessingException, QgsProcessingProvider
from qgis.PyQt.QtGui import QIcon

from . import descriptors, runner
from .algorithms.amplify import AmplifyAlgorithm
from .algorithms.pixel import PixelAlgorithm
from .algorithms.ppa import PpaAlgorithm
from .algorithms.synth import SynthAlgorithm

try:  # the Processing plugin's settings (absent in a bare QgsApplication)
    from processing.core.ProcessingConfig import ProcessingConfig, Setting
except ImportError:  # pragma: no cover
    ProcessingConfig = Setting = None

# The explicit list of algorithms; a new `terrasynth` stage adds its class here.
ALGORITHMS = (PpaAlgorithm, SynthAlgorithm, AmplifyAlgorithm, PixelAlgorithm)

ICON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "icon.svg")


class TerraSynthProvider(QgsProcessingProvider):
    def id(self):
        return "terrasynth"

    def name(self):
        return "TerraSynth"

    def longName(self):  # noqa: N802
        version = descriptors.current_version()
        return "TerraSynth %s" % version if version else "TerraSynth"

    def versionInfo(self):  # noqa: N802
        return descriptors.current_version() or ""

    def icon(self):
        return QIcon(ICON)

    def svgIconPath(self):  # noqa: N802
        return ICON

    def load(self):
        if ProcessingConfig is not None:
            ProcessingConfig.settingIcons[self.name()] = self.icon()
            ProcessingConfig.addSetting(Setting(
                self.name(), runner.SETTING_NAME,
                "Location of the terrasynth executable (empty: the TERRASYNTH environment "
                "variable, then the plugin's bin/terrasynth, then PATH)",
                "", valuetype=Setting.FILE))
            ProcessingConfig.readSettings()
        self.refreshAlgorithms()
        return True

    def unload(self):
        if ProcessingConfig is not None:
            ProcessingConfig.removeSetting(runner.SETTING_NAME)

    def loadDescriptors(self):  # noqa: N802
        """The core's descriptor tables from `terrasynth describe`, else the fallback."""
        try:
            cli = runner.find_cli()
            descriptors.set_tables(runner.describe(cli), "describe " + cli)
        except (QgsProcessingException, ValueError, OSError, subprocess.SubprocessError) as e:
            descriptors.set_tables(descriptors.FALLBACK, "fallback")
            QgsMessageLog.logMessage(
                "TerraSynth: using the built-in parameter tables (%s)"
                % (e.args[0] if e.args else e), "Processing", Qgis.Warning)

    def loadAlgorithms(self):  # noqa: N802
        self.loadDescriptors()
        for cls in ALGORITHMS:
            self.addAlgorithm(cls())

    # outputs: files only (the CLI writes them); lines in GeoPackage (two layers)
    def supportsNonFileBasedOutput(self):  # noqa: N802
        return False

    def supportedOutputVectorLayerExtensions(self):  # noqa: N802
        return ["gpkg"]

    def defaultVectorFileExtension(self, hasGeometry=True):  # noqa: N802,N803
        return "gpkg"

    def defaultRasterFileExtension(self):  # noqa: N802
        return "tif"
