# SPDX-License-Identifier: GPL-2.0-or-later
"""terrasynth:pixel - a terrain grown cell by cell, coarse to fine, in the style of real DEMs
(`terrasynth pixel`, Lefebvre and Hoppe 2005; Cruz et al.). The core's parameters come from
the "pixel" descriptor table of `terrasynth describe`."""
import os

from qgis.core import (
    QgsProcessing,
    QgsProcessingException,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
)

from .. import descriptors
from .base import TerraSynthAlgorithm, gdal_source, is_set

# Condensed from algorithms/docs/pixel.md (the manual page).
HELP = """
<p>Grows a <b>terrain cell by cell</b>, coarse to fine, in the style of real DEMs
(multiresolution pixel synthesis: Lefebvre and Hoppe 2005, with the guide of Cruz et al.).
Runs <code>terrasynth pixel</code>.</p>
<ol>
<li><b>Gaussian stacks</b> of the exemplars (and their turned and mirrored copies).</li>
<li><b>Coordinates</b>, coarse to fine: upsampled, jittered, corrected against the
neighbours' heights (k-coherence, in sub-passes), with a roughness term (ours) so that a
neighbourhood pieced from several places is not answered by the smoothest one.</li>
<li><b>Guide</b> (optional): a DEM in the exemplars' units on the output grid that the
terrain follows at its coarser levels (down to the guide spacing).</li>
</ol>
<p>Every cell is a function of the seed and its position: the same inputs and seed give the
same bytes, and any window equals the same window of a larger run.</p>
<h3>Outputs</h3>
<ul><li><b>Terrain</b>: Float32 on the target grid, nodata -9999.</li>
<li><b>Preview</b> (optional PNG): hillshade of the result.</li></ul>
"""


class PixelAlgorithm(TerraSynthAlgorithm):
    STAGE = "pixel"
    NAME = "pixel"
    DISPLAY_NAME = "Grow terrain cell by cell (pixel synthesis)"
    GROUP = "Terrain synthesis"
    GROUP_ID = "terrainsynthesis"
    HELP = HELP
    LABELS = {"levels": "Levels (0 = as many as fit)", "passes": "Correction passes",
              "window": "Neighbourhood (cells)", "jitter": "Jitter (spacings)",
              "guide_weight": "Guide weight",
              "guide_heights": "Guide's values (as heights, stretched, or by rank: a drawing)",
              "rotations": "Rotations (0, 4 or 8)",
              "pca_energy": "Share of the neighbourhoods' variance compared (PCA)",
              "coherence": "k-coherence candidates per neighbour (1 = coherent only)",
              "roughness_weight": "Roughness term's weight (0 = off)"}
    ADVANCED = ("levels", "passes", "window", "jitter", "pca_energy", "coherence",
                "roughness_weight", "guide_spacing", "start", "relief_scale", "guide_mode")

    EXEMPLARS = "EXEMPLARS"
    GUIDE = "GUIDE"
    LIKE = "LIKE"
    WIDTH = "WIDTH"
    HEIGHT = "HEIGHT"
    SEED = "SEED"
    BAND = "BAND"
    CELL_SIZE = "CELL_SIZE"
    THREADS = "THREADS"
    OUTPUT = "OUTPUT"
    PREVIEW = "PREVIEW"

    def initAlgorithm(self, config=None):  # noqa: N802
        ex = QgsProcessingParameterMultipleLayers(self.EXEMPLARS, self.tr("Exemplar DEMs"),
                                                  QgsProcessing.TypeRaster)
        ex.setMinimumNumberInputs(1)
        ex.setHelp("Real DEMs whose style the terrain takes (--exemplar).")
        self.addParameter(ex)
        guide = QgsProcessingParameterRasterLayer(self.GUIDE, self.tr("Guide DEM"), optional=True)
        guide.setHelp("A DEM in the exemplars' units that the terrain follows; its grid is the "
                      "output's (--guide).")
        self.addParameter(guide)
        like = QgsProcessingParameterRasterLayer(self.LIKE, self.tr("Grid like"), optional=True)
        like.setHelp("Size, geotransform and CRS of a raster (--like), without a guide.")
        self.addParameter(like)
        Number = QgsProcessingParameterNumber
        for key, label in ((self.WIDTH, "Width (cells)"), (self.HEIGHT, "Height (cells)")):
            lo, hi = descriptors.option_range("pixel", "size", (1, 1048576))
            p = Number(key, self.tr(label), Number.Integer, optional=True, minValue=int(lo),
                       maxValue=int(hi))
            p.setHelp("Size of the output in cells, on the first exemplar's grid (--size), "
                      "without a guide or a grid.")
            self.addParameter(p)
        self.addDescriptorParameters()
        self.optionParameter(self.SEED, "seed", "Random seed", advanced=False)
        self.optionParameter(self.BAND, "band", "Band of every input")
        self.optionParameter(self.CELL_SIZE, "cell_size",
                             "Cell size for rasters without CRS (metres)")
        self.optionParameter(self.THREADS, "threads", "Threads (0 = all cores)")
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT,
                                                                  self.tr("Terrain")))
        self.addParameter(QgsProcessingParameterFileDestination(
            self.PREVIEW, self.tr("Preview"), fileFilter="PNG files (*.png)", optional=True,
            createByDefault=False))
        self.addFlowParameters()

    def checkJob(self, parameters, context):  # noqa: N802
        grids = [is_set(parameters, self.GUIDE), is_set(parameters, self.LIKE),
                 is_set(parameters, self.WIDTH) or is_set(parameters, self.HEIGHT)]
        if sum(grids) != 1:
            raise QgsProcessingException("give the target grid: a guide, a grid, or a width "
                                         "and a height (one of them)")
        if grids[2] and not (is_set(parameters, self.WIDTH) and is_set(parameters, self.HEIGHT)):
            raise QgsProcessingException("WIDTH and HEIGHT go together")

    def prepareJob(self, parameters, context):  # noqa: N802
        layers = self.parameterAsLayerList(parameters, self.EXEMPLARS, context)
        exemplars = [gdal_source(layer, self.EXEMPLARS) for layer in layers]
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        preview = self.parameterAsFileOutput(parameters, self.PREVIEW, context) or ""
        if preview and os.path.splitext(preview)[1].lower() != ".png":
            raise QgsProcessingException("PREVIEW must be a .png file, not %s" % preview)
        guide = (gdal_source(self.parameterAsRasterLayer(parameters, self.GUIDE, context),
                             self.GUIDE) if is_set(parameters, self.GUIDE) else None)
        like = (gdal_source(self.parameterAsRasterLayer(parameters, self.LIKE, context),
                            self.LIKE) if is_set(parameters, self.LIKE) else None)
        size = None
        if is_set(parameters, self.WIDTH):
            size = "%dx%d" % (self.parameterAsInt(parameters, self.WIDTH, context),
                              self.parameterAsInt(parameters, self.HEIGHT, context))
        options = [("exemplar", exemplars), ("guide", guide), ("like", like), ("size", size)]
        options += [(n, self.optionValue(parameters, k, n, context)) for k, n in (
                    (self.SEED, "seed"), (self.BAND, "band"), (self.CELL_SIZE, "cell_size"),
                    (self.THREADS, "threads"))]
        options += [("preview", preview)]
        results = {self.OUTPUT: output}
        if preview:
            results[self.PREVIEW] = preview
        return {"positional": [output], "options": options, "outputs": [output, preview],
                "results": results}
