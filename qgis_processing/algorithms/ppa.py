# SPDX-License-Identifier: GPL-2.0-or-later
"""terrasynth:ppa - ridge and valley axes of a DEM (`terrasynth ppa`)."""
import os

from qgis.core import (
    QgsProcessing,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterBand,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterVectorDestination,
    QgsProcessingUtils,
)

from .base import TerraSynthAlgorithm, gdal_source

# Condensed from algorithms/docs/ppa.md (the manual page).
HELP = """
<p>Maps the <b>ridge and valley axes</b> of a DEM with the Profile recognition and Polygon
breaking Algorithm (PPA; Chang, Song &amp; Hsu 1998, as summarised by Zhou et al. 2007,
section 3). Runs <code>terrasynth ppa</code>.</p>
<ol>
<li><b>Profile recognition</b>: through every cell run four profiles (E-W, N-S, two
diagonals), each <i>Profile length</i> cells long. A cell is a ridge target if along one
profile the terrain dips below it by more than the threshold on both sides within half the
profile; a valley target if it rises above it likewise. Profiles stop at the raster edge and at
nodata.</li>
<li><b>Target connection</b>: 8-adjacent targets are joined by segments; where two diagonals
cross, the less important one is cancelled.</li>
<li><b>Polygon breaking</b>: the least important segment of every closed polygon is removed
(a maximum spanning forest).</li>
<li><b>Branch reduction</b>: branches shorter than <i>Minimum branch length</i> are removed,
keeping the main axes whole.</li>
</ol>
<p><b>Valleys where the water runs</b> (the default): valley targets draining fewer than
<i>Minimum drainage</i> cells (200) are dropped (the hollows above the channel heads; the
drainage: depressions filled, flats crossed, each cell to its lowest neighbour), and valleys get
a lower dip and shorter branches than ridges, so they follow the channels a flow router finds
(GRASS <code>r.stream.extract</code>: recall 0.71-0.99 at precision 0.71-0.81 on nine real
DEMs). <i>Minimum drainage</i> 0 gives the paper's valleys, by their profiles alone.</p>
<h3>Parameters</h3>
<ul>
<li><b>Features</b>: ridges, valleys or both.</li>
<li><b>Profile length</b> (odd, 3..1001 cells, default 11): lengthen it for broad valleys on fine
grids.</li>
<li><b>Threshold</b> (metres) and <b>Threshold fraction</b> (of the DEM's elevation range, default
-1 = auto: 0.0025 for ridges, 0.0001 for valleys with the drainage test): the minimum dip. As on
the command line, the two exclude each other: changing one from its default replaces the other
(which is then 0); changing both is an error. A value given is every kind's.</li>
<li><b>Minimum branch length</b> with its <b>unit</b> (cells, or metres on the ground; default
-1 = auto: 40 cells for ridges, 10 for valleys with the drainage test): the main knob for detail
(20 cells: dense network, 80: only the main axes). Metres need a CRS, or <i>Cell size</i> for a
raster without one.</li>
<li><b>Minimum drainage</b> (cells, default 200): valleys where the water runs (above); 0: by
profile alone.</li>
<li><b>Band</b>: the input band. Heights are read in metres (scale/offset applied, feet
converted); lengths are measured on the ground (geodesic in a geographic CRS).</li>
</ul>
<h3>Outputs</h3>
<ul>
<li><b>Ridges and valleys</b>: a Byte raster on the input's grid: 1 ridge, 2 valley, 3 both,
0 none, 255 where the input is nodata.</li>
<li><b>Ridge and valley lines</b> (optional, GeoPackage): layer <code>paths</code> (LineStrings
with kind, length_m, length_cells, mean/min/max elevation, start/end node kind), returned as
LINES, and layer <code>nodes</code> (endpoints and branch points), returned as NODES; both are
loaded.</li>
<li><b>Preview</b> (optional PNG): hillshade with ridges in red and valleys in blue.</li>
</ul>
<p>Outputs are written to temporary names and renamed into place: a failed or canceled run
leaves no file. Same input and parameters give the same bytes.</p>
"""


class PpaAlgorithm(TerraSynthAlgorithm):
    STAGE = "ppa"
    NAME = "ppa"
    DISPLAY_NAME = "Extract ridges and valleys (PPA)"
    GROUP = "Terrain analysis"
    GROUP_ID = "terrainanalysis"
    HELP = HELP
    LABELS = {"features": "Features", "min_branch_length": "Minimum branch length"}

    INPUT = "INPUT"
    BAND = "BAND"
    CELL_SIZE = "CELL_SIZE"
    THREADS = "THREADS"
    OUTPUT = "OUTPUT"
    LINES = "LINES"
    NODES = "NODES"
    PREVIEW = "PREVIEW"

    def initAlgorithm(self, config=None):  # noqa: N802
        self.addParameter(QgsProcessingParameterRasterLayer(self.INPUT, self.tr("Input DEM")))
        # optional: QGIS 3.22 rejects an omitted band parameter even with a default
        band = QgsProcessingParameterBand(self.BAND, self.tr("Band"), defaultValue=1,
                                          parentLayerParameterName=self.INPUT, optional=True)
        band.setHelp("Input band (--band); default 1.")
        self.addParameter(band)
        self.addDescriptorParameters()
        self.optionParameter(self.CELL_SIZE, "cell_size",
                             "Cell size for a raster without CRS (metres)")
        self.optionParameter(self.THREADS, "threads", "Threads (0 = all cores)")
        self.addParameter(QgsProcessingParameterRasterDestination(
            self.OUTPUT, self.tr("Ridges and valleys")))
        self.addParameter(QgsProcessingParameterVectorDestination(
            self.LINES, self.tr("Ridge and valley lines (GeoPackage)"),
            QgsProcessing.TypeVectorLine, optional=True, createByDefault=True))
        self.addOutput(QgsProcessingOutputVectorLayer(
            self.NODES, self.tr("Ridge and valley nodes"), QgsProcessing.TypeVectorPoint))
        self.addParameter(QgsProcessingParameterFileDestination(
            self.PREVIEW, self.tr("Preview"), fileFilter="PNG files (*.png)", optional=True,
            createByDefault=False))
        self.addFlowParameters()

    def prepareJob(self, parameters, context):  # noqa: N802
        layer = self.parameterAsRasterLayer(parameters, self.INPUT, context)
        if layer is None:
            raise QgsProcessingException(self.invalidRasterError(parameters, self.INPUT))
        source = gdal_source(layer, self.INPUT)
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        lines = self.parameterAsOutputLayer(parameters, self.LINES, context) or ""
        preview = self.parameterAsFileOutput(parameters, self.PREVIEW, context) or ""
        if lines and os.path.splitext(lines)[1].lower() != ".gpkg":
            raise QgsProcessingException(
                "LINES must be a GeoPackage (.gpkg), which holds both layers 'paths' and "
                "'nodes', not %s" % lines)
        if preview and os.path.splitext(preview)[1].lower() != ".png":
            raise QgsProcessingException("PREVIEW must be a .png file, not %s" % preview)
        options = [("band", self.parameterAsInt(parameters, self.BAND, context) or 1),
                   ("cell_size", self.optionValue(parameters, self.CELL_SIZE, "cell_size", context)),
                   ("threads", self.optionValue(parameters, self.THREADS, "threads", context)),
                   ("lines", lines),
                   ("preview", preview)]
        results = {self.OUTPUT: output}
        if lines:
            results[self.LINES] = lines + "|layername=paths"
            results[self.NODES] = lines + "|layername=nodes"
        if preview:
            results[self.PREVIEW] = preview
        return {"positional": [source, output], "options": options,
                "outputs": [output, lines, preview], "results": results, "lines": lines}

    def finishJob(self, job, context, feedback):  # noqa: N802
        """QGIS would load LINES' .gpkg as one layer: load 'paths' and 'nodes' instead."""
        lines = job["lines"]
        if not lines or not context.willLoadLayerOnCompletion(lines):
            return
        details = context.layerToLoadOnCompletionDetails(lines)
        layers = context.layersToLoadOnCompletion()
        layers.pop(lines, None)
        hint = QgsProcessingUtils.LayerHint.Vector
        layers[job["results"][self.LINES]] = QgsProcessingContext.LayerDetails(
            details.name or self.tr("Ridge and valley lines"), details.project, self.LINES, hint)
        layers[job["results"][self.NODES]] = QgsProcessingContext.LayerDetails(
            self.tr("Ridge and valley nodes"), details.project, self.NODES, hint)
        context.setLayersToLoadOnCompletion(layers)
