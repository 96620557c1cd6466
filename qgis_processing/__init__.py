# SPDX-License-Identifier: GPL-2.0-or-later
"""TerraSynth QGIS plugin: a Processing provider around the `terrasynth` CLI."""


def classFactory(iface):  # noqa: N802 (QGIS' name)
    """Entry point QGIS calls when it loads the plugin."""
    from .plugin import TerraSynthPlugin

    return TerraSynthPlugin(iface)
