# SPDX-License-Identifier: GPL-2.0-or-later
"""terrasynth:amplify - a coarse DEM made finer with the detail of real terrain
(`terrasynth amplify`, Argudo et al. 2017).  The core's parameters come from the
"amplify" descriptor table of `terrasynth describe`."""
import os

from qgis.core import (
    QgsProcessing,
    QgsProcessingException,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
)

from .base import TerraSynthAlgorithm, gdal_source, is_set

# Condensed from algorithms/docs/amplify.md (the manual page).
HELP = """
<p>Makes a <b>coarse DEM finer</b> with the detail of real terrain (Argudo et al. 2017,
<i>Coherent multi-layer landscape synthesis</i>). Runs <code>terrasynth amplify</code>.
Where <i>Warp (reproject)</i> with cubic resampling gives smooth slopes, this gives the
gullies and crests of the exemplars' terrain; averaged back by the factor, the output is the
input.</p>
<ol>
<li><b>Dictionary</b>: the exemplars (resampled to the output's ground resolution) are
area-averaged by the factor; atoms are their windows of <i>Patch</i> cells with the fine
windows above them (and of the exemplars' extra layers and classes), described by shape, mean
altitude, slope (mean deviation), drainage area, mean annual solar irradiance with
self-shadowing (with an irradiance weight) and classes.</li>
<li><b>Matching</b>: the input is cut into patches overlapping by half; each takes the atom
that scores best on g = w_h g_h + w_a g_a + w_s g_s + w_u g_u + w_l g_l + w_c g_c, keeping
orientation (a ridge is never matched by an inverted valley). <i>Wanted classes</i> (a raster
on the input's grid, codes of the exemplars' classes) steer each patch to atoms of its
classes.</li>
<li><b>Replacement and blending</b>: each patch is replaced by its atom's fine window, scaled
to the patch's relief, and patches are blended with a falloff; the atom's extra layers and
classes come with it.</li>
<li><b>Back-projection</b> (our addition, <i>refine</i> passes): what the atoms do not
explain is added back smoothly, so the output averages back to the input.</li>
</ol>
<h3>Outputs</h3>
<ul>
<li><b>Amplified DEM</b>: Float32 on the input's extent and CRS, <i>Factor</i> times finer,
nodata -9999 where the input is nodata.</li>
<li><b>Carried layer</b> (optional): one of the exemplars' extra layers (given as NAME=FILE
lines, one per exemplar in order), as the atoms carry it onto the output's grid.</li>
<li><b>Classes</b> (optional Byte raster): the atoms' classes on the output's grid.</li>
<li><b>Preview</b> (optional PNG): hillshade of the result.</li>
</ul>
<p>Outputs are written to temporary names and moved into place together: a failed or canceled
run leaves no file. Same inputs give the same bytes.</p>
"""


class AmplifyAlgorithm(TerraSynthAlgorithm):
    STAGE = "amplify"
    NAME = "amplify"
    DISPLAY_NAME = "Amplify a coarse DEM"
    GROUP = "Terrain synthesis"
    GROUP_ID = "terrainsynthesis"
    HELP = HELP
    LABELS = {"factor": "Factor (output cells per input cell)", "patch": "Patch (input cells)",
              "atoms": "Atoms per exemplar", "w_h": "Shape weight (w_h)",
              "w_a": "Altitude weight (w_a)", "w_s": "Slope weight (w_s)",
              "w_u": "Drainage weight (w_u)", "refine": "Back-projection passes",
              "w_l": "Irradiance weight (w_l)", "w_c": "Class weight (w_c)"}
    ADVANCED = ("atoms", "w_h", "w_a", "w_s", "w_u", "refine", "w_l", "w_c")

    INPUT = "INPUT"
    EXEMPLARS = "EXEMPLARS"
    BAND = "BAND"
    CELL_SIZE = "CELL_SIZE"
    THREADS = "THREADS"
    OUTPUT = "OUTPUT"
    PREVIEW = "PREVIEW"
    DICTIONARY = "DICTIONARY"
    BIOMES = "BIOMES"
    EXEMPLAR_CLASSES = "EXEMPLAR_CLASSES"
    EXEMPLAR_LAYERS = "EXEMPLAR_LAYERS"
    CLASSES = "CLASSES"
    OUT_LAYER_NAME = "OUT_LAYER_NAME"
    OUT_LAYER = "OUT_LAYER"
    OUT_CLASSES = "OUT_CLASSES"

    def initAlgorithm(self, config=None):  # noqa: N802
        self.addParameter(QgsProcessingParameterRasterLayer(self.INPUT,
                                                            self.tr("Coarse DEM")))
        ex = QgsProcessingParameterMultipleLayers(self.EXEMPLARS, self.tr("Exemplar DEMs"),
                                                  QgsProcessing.TypeRaster, optional=True)
        ex.setHelp("Real DEMs whose detail the output takes (--exemplar), best at the "
                   "output's resolution or finer. Give exemplars, a dictionary, or biomes.")
        self.addParameter(ex)
        dic = QgsProcessingParameterFile(self.DICTIONARY, self.tr("Dictionary (instead of "
                                                                  "exemplars)"),
                                         extension="tsd", optional=True)
        dic.setHelp("A dictionary built once by terrasynth dictionary build (--dictionary).")
        self.addParameter(dic)
        bio = QgsProcessingParameterString(self.BIOMES,
                                           self.tr("Biomes (WEIGHTS=DICTIONARY per line)"),
                                           multiLine=True, optional=True)
        bio.setHelp("Several dictionaries, each with a weight raster on the input's grid "
                    "painted where it should go (--biome W.tif=D.tsd), one per line.")
        self.addParameter(bio)
        exc = QgsProcessingParameterMultipleLayers(self.EXEMPLAR_CLASSES,
                                                   self.tr("Exemplar classes"),
                                                   QgsProcessing.TypeRaster, optional=True)
        exc.setHelp("Class codes 1..64 of each exemplar, one raster per exemplar in the same "
                    "order, on its grid (--exemplar-classes; 0 or nodata: unlabelled).")
        self.addParameter(exc)
        exl = QgsProcessingParameterString(self.EXEMPLAR_LAYERS,
                                           self.tr("Exemplar layers (NAME=FILE per line)"),
                                           multiLine=True, optional=True)
        exl.setHelp("Extra layers of the exemplars that the atoms carry to the output "
                    "(--exemplar-layer): one NAME=FILE line per exemplar and name, the k-th "
                    "file of a name belonging to the k-th exemplar.")
        self.addParameter(exl)
        cls = QgsProcessingParameterRasterLayer(self.CLASSES, self.tr("Wanted classes"),
                                                optional=True)
        cls.setHelp("Wanted classes on the input's grid (--classes; 0 or nodata: any).")
        self.addParameter(cls)
        self.addDescriptorParameters()
        self.optionParameter(self.BAND, "band", "Band of every input")
        self.optionParameter(self.CELL_SIZE, "cell_size",
                             "Cell size for rasters without CRS (metres)")
        self.optionParameter(self.THREADS, "threads", "Threads (0 = all cores)")
        self.addParameter(QgsProcessingParameterRasterDestination(
            self.OUTPUT, self.tr("Amplified DEM")))
        name = QgsProcessingParameterString(self.OUT_LAYER_NAME, self.tr("Carried layer name"),
                                            optional=True)
        name.setHelp("The name (of the exemplar layers) written as the carried layer.")
        self.addParameter(name)
        self.addParameter(QgsProcessingParameterRasterDestination(
            self.OUT_LAYER, self.tr("Carried layer"), optional=True, createByDefault=False))
        self.addParameter(QgsProcessingParameterRasterDestination(
            self.OUT_CLASSES, self.tr("Classes"), optional=True, createByDefault=False))
        self.addParameter(QgsProcessingParameterFileDestination(
            self.PREVIEW, self.tr("Preview"), fileFilter="PNG files (*.png)", optional=True,
            createByDefault=False))
        self.addFlowParameters()

    def checkJob(self, parameters, context):  # noqa: N802
        # the dialog's pair of parameters for --out-layer NAME=FILE
        out_layer = self.parameterAsOutputLayer(parameters, self.OUT_LAYER, context)
        name = self.parameterAsString(parameters, self.OUT_LAYER_NAME, context).strip()
        if bool(out_layer) != bool(name):
            raise QgsProcessingException("OUT_LAYER and OUT_LAYER_NAME go together")

    def prepareJob(self, parameters, context):  # noqa: N802
        layer = self.parameterAsRasterLayer(parameters, self.INPUT, context)
        if layer is None:
            raise QgsProcessingException(self.invalidRasterError(parameters, self.INPUT))
        layers = self.parameterAsLayerList(parameters, self.EXEMPLARS, context)
        exemplars = [gdal_source(lyr, self.EXEMPLARS) for lyr in layers]
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        preview = self.parameterAsFileOutput(parameters, self.PREVIEW, context) or ""
        if preview and os.path.splitext(preview)[1].lower() != ".png":
            raise QgsProcessingException("PREVIEW must be a .png file, not %s" % preview)
        ex_classes = [gdal_source(lyr, self.EXEMPLAR_CLASSES) for lyr in
                      self.parameterAsLayerList(parameters, self.EXEMPLAR_CLASSES, context)]
        ex_layers = [line.strip() for line in
                     self.parameterAsString(parameters, self.EXEMPLAR_LAYERS, context).splitlines()
                     if line.strip()]
        wanted = self.parameterAsRasterLayer(parameters, self.CLASSES, context) \
            if is_set(parameters, self.CLASSES) else None
        out_layer = self.parameterAsOutputLayer(parameters, self.OUT_LAYER, context) or ""
        out_name = self.parameterAsString(parameters, self.OUT_LAYER_NAME, context).strip()
        out_classes = self.parameterAsOutputLayer(parameters, self.OUT_CLASSES, context) or ""
        biomes = [line.strip() for line in
                  self.parameterAsString(parameters, self.BIOMES, context).splitlines()
                  if line.strip()]
        options = [("exemplar", exemplars or None),
                   ("dictionary", self.parameterAsFile(parameters, self.DICTIONARY, context)
                    or None),
                   ("biome", biomes or None),
                   ("exemplar_classes", ex_classes or None),
                   ("exemplar_layer", ex_layers or None),
                   ("classes", gdal_source(wanted, self.CLASSES) if wanted else None),
                   ("out_layer", "%s=%s" % (out_name, out_layer) if out_layer else None),
                   ("out_classes", out_classes or None),
                   ("preview", preview)]
        options += [(n, self.optionValue(parameters, k, n, context)) for k, n in (
                    (self.BAND, "band"), (self.CELL_SIZE, "cell_size"), (self.THREADS, "threads"))]
        results = {self.OUTPUT: output}
        if preview:
            results[self.PREVIEW] = preview
        if out_layer:
            results[self.OUT_LAYER] = out_layer
        if out_classes:
            results[self.OUT_CLASSES] = out_classes
        return {"positional": [gdal_source(layer, self.INPUT), output], "options": options,
                "outputs": [output, preview, out_layer, out_classes], "results": results}
