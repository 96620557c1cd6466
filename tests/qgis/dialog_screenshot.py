# SPDX-License-Identifier: GPL-2.0-or-later
"""Open a TerraSynth algorithm's dialog in QGIS' GUI (offscreen platform) and save a
screenshot.  Run by test_dialog.py in its own process, because the GUI needs a
QgsApplication with the GUI enabled while the other tests use one without.

    python3 dialog_screenshot.py PLUGIN_PARENT ALGORITHM_ID OUT.png [PARAMETERS.json]

Prints one JSON line: png, width, height, colours (distinct colours in the image),
labels (texts of the dialog's QLabels), help (whether the help panel has text).
With PARAMETERS.json (a dict), the dialog is then filled with those values, and the
parameters its widgets produce are checked and turned into a command line (not run):
check (ok, message) and argv are added to the JSON.
"""
import json
import os
import sys

os.environ["QT_QPA_PLATFORM"] = "offscreen"
if "QGIS_CUSTOM_CONFIG_PATH" not in os.environ:
    sys.exit("set QGIS_CUSTOM_CONFIG_PATH to a temporary folder")


def main(plugin_parent, alg_id, png, parameters_json=None):
    from qgis.core import QgsApplication

    QgsApplication.setPrefixPath("/usr", True)
    app = QgsApplication([], True)
    app.initQgis()
    sys.path += ["/usr/share/qgis/python/plugins", plugin_parent]
    from processing.core.Processing import Processing

    Processing.initialize()
    from terrasynth_qgis.plugin import TerraSynthPlugin

    plugin = TerraSynthPlugin(None)  # keep a reference: the provider lives in it
    plugin.initProcessing()
    from processing.gui.AlgorithmDialog import AlgorithmDialog
    from qgis.PyQt.QtWidgets import QLabel, QTextBrowser

    alg = QgsApplication.processingRegistry().createAlgorithmById(alg_id)
    if alg is None:
        sys.exit("algorithm %s not found" % alg_id)
    dlg = AlgorithmDialog(alg)
    dlg.resize(1000, 760)
    dlg.show()
    for _ in range(30):
        app.processEvents()
    image = dlg.grab().toImage()
    os.makedirs(os.path.dirname(os.path.abspath(png)), exist_ok=True)
    if not image.save(png):
        sys.exit("cannot save %s" % png)
    colours = set()
    for y in range(0, image.height(), 4):
        for x in range(0, image.width(), 4):
            colours.add(image.pixel(x, y))
    labels = [w.text() for w in dlg.findChildren(QLabel) if w.text()]
    helps = [w.toPlainText() for w in dlg.findChildren(QTextBrowser)]
    info = {"png": os.path.abspath(png), "width": image.width(), "height": image.height(),
            "colours": len(colours), "labels": labels,
            "help": any(alg.displayName() in h for h in helps), "title": dlg.windowTitle()}
    if parameters_json:
        with open(parameters_json) as f:
            dlg.setParameters(json.load(f))
        for _ in range(5):
            app.processEvents()
        parameters = dlg.createProcessingParameters()
        from processing.tools import dataobjects

        context = dataobjects.createContext()  # as AlgorithmDialog.runAlgorithm does
        info["check"] = list(alg.checkParameterValues(parameters, context))
        if info["check"][0]:
            info["argv"] = alg.buildCommand(parameters, context, cli="terrasynth")[0]
    print(json.dumps(info))
    dlg.close()
    sys.stdout.flush()
    os._exit(0)  # skip QGIS' teardown: not under test, and noisy offscreen


if __name__ == "__main__":
    main(*sys.argv[1:5])
