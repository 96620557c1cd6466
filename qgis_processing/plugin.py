# SPDX-License-Identifier: GPL-2.0-or-later
"""The plugin object: registers the TerraSynth Processing provider."""
from qgis.core import QgsApplication

from .provider import TerraSynthProvider


class TerraSynthPlugin:
    def __init__(self, iface):
        self.iface = iface
        self.provider = None

    def initProcessing(self):  # noqa: N802
        """Called by QGIS (also by qgis_process, without a GUI) to add the provider."""
        if self.provider is None:
            self.provider = TerraSynthProvider()
            QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802
        self.initProcessing()

    def unload(self):
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
