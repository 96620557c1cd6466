# SPDX-License-Identifier: GPL-2.0-or-later
"""terrasynth:synth - a new terrain grown from real DEMs (`terrasynth synth`),
optionally following a sketch (`terrasynth synth --sketch`).

The core's parameters come from `terrasynth describe`: the "synth" table, and the
"sketch" table (MODE, ALPHA_D, ALPHA_F), which is passed only with a SKETCH.
The constraints (PINS, WATER_MASK/WATER_LEVEL, REGIONS/REGION_EXEMPLARS, HEIGHTS/ALPHA_H)
are `terrasynth synth`'s --pin, --water/--water-level, --regions/--region-exemplar and
--heights/--alpha-h. REGIONS is one map-layer parameter that takes an integer raster or a
polygon vector layer (with an integer field "region"); PINS and REGION_EXEMPLARS are strings
(one item per line or separated by ';').
"""
import math
import os
import re

from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsProcessing,
    QgsProcessingException,
    QgsProcessingParameterCrs,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterExtent,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterField,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterMapLayer,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
    QgsProviderRegistry,
    QgsRasterLayer,
    QgsVectorLayer,
    QgsWkbTypes,
)

from qgis.PyQt.QtCore import QVariant

from .. import descriptors, runner
from .base import TerraSynthAlgorithm, gdal_source, is_set

REGION_FIELD = "region"  # the integer field of a polygon REGIONS layer
_INT_TYPES = (QVariant.Int, QVariant.LongLong, QVariant.UInt, QVariant.ULongLong)

def _items(text):
    """Non-empty items of a string, one per line or separated by ';' (the program checks
    each: FILE:XOFF,YOFF,W,H@X,Y for a pin, ID=FILE for a region's exemplar)."""
    return [t.strip() for t in re.split(r"[;\r\n]+", text or "") if t.strip()]

# Condensed from algorithms/docs/synth.md (the manual page).
HELP = """
<p>Grows a <b>new terrain</b> of any size from one or more real DEMs (the exemplars), without
visible seams: non-feature patch synthesis of Zhou et al. (2007, sections 4.2 and 5). The new
terrain has the exemplars' style (slopes, valley spacing, roughness) but a layout of its own.
Runs <code>terrasynth synth</code>.</p>
<ol>
<li><b>Exemplars at the target's scale</b>: each is read in metres and resampled to the target's
ground resolution when it differs (cubic when finer, averaging when coarser).</li>
<li><b>Placement</b>: patch positions on a grid of step <i>Patch size - Overlap</i>, visited
growing out from the centre (<i>grow</i>; <i>tree</i> is the same without a sketch; with a
sketch, both follow its feature tree breadth first) or in scan order (<i>raster</i>).</li>
<li><b>Matching</b>: masked SSD by FFT against every exemplar window, on a pyramid (<i>Coarse
factor</i>; 0 = automatic). Windows with nodata are never candidates.</li>
<li><b>Seams</b>: each of the <i>Candidates</i> best matches is cut in with a minimum-cost graph
cut; the winner has the lowest RMS SSD + <i>alpha_g</i> x seam mismatch; <i>Variety</i> picks at
random (seeded) among candidates within that fraction of the best.</li>
<li><b>Seam removal</b>: Poisson re-solve of the heights around each new patch.</li>
</ol>
<h3>Target grid</h3>
<p>One of: a <b>Sketch</b> (the output is on the sketch's grid, see below); an <b>Extent</b>
and a <b>Pixel size</b>, as in QGIS's own <i>Create constant raster layer</i> (the grid starts
at the extent's top-left corner and covers it, the last row and column rounded up; the CRS is
<b>CRS</b> when given, the extent's own CRS otherwise, else the first exemplar's); <b>Target
grid like</b> (size, geotransform and CRS of a raster); or, under <i>Advanced parameters</i>,
<b>Width</b> and <b>Height</b> in cells, on the first exemplar's CRS, resolution and origin
unless <b>Origin X/Y</b> (top-left corner, CRS units), <b>Resolution</b> (CRS units) and
<b>CRS</b> are given. A CRS needs the origin and the resolution.</p>
<h3>Sketch-guided synthesis</h3>
<p>A <b>Sketch</b> is a grey drawing (any single-band GDAL raster): <b>bright strokes are
ridges, dark strokes valleys</b>; on a grey ground, strokes brighter than it are ridges and
darker valleys, both in one sketch (Zhou et al. 2007, sections 3-4). <b>Sketch as lines</b>
takes a line layer instead, digitised on the map: its <b>Kind field</b> says <i>ridge</i>,
<i>valley</i> or <i>river</i> of each line, lines meet at junctions, an optional <b>Height
field</b> (or the lines' Z values) gives the height wanted along each line; the output grid is
<b>Target grid like</b>'s, or the <b>Target extent</b> at the <b>Pixel size</b>, or the lines'
extent grown by a patch at the <b>Pixel size</b>. Drawn valleys are carved to drain to the
grid's edge or into another valley. The lines of <i>terrasynth:ppa</i> (its <i>Lines</i> output)
are a sketch too: a new terrain with a real landscape's ridges and valleys. The ridge or valley axes
of the sketch and of the exemplars are extracted (PPA); along the sketch's feature tree, the
exemplar feature patches that fit best are warped onto it (thin-plate spline / similarity
warps) and cut in, then the rest is filled as above. The output is <b>on the sketch's grid</b>
(size, geotransform, CRS), <b>nodata where the sketch is nodata</b>; Target grid like, Width,
Height, Origin X/Y, Resolution and CRS must then be left empty.</p>
{SKETCH_PARAMETERS}
<h3>Parameters</h3>
<ul>
<li><b>Patch size</b> ({PATCH_SIZE}) and <b>Overlap</b> ({OVERLAP}, at most half the patch), in target cells, or in metres on the ground with their <b>unit</b> set to metres
(turned into cells at the target grid's resolution). A patch should hold a few ridge and valley
spacings.</li>
<li><b>Seed</b>: same inputs and seed give identical bytes.</li>
<li><b>Band</b>: the band read from every exemplar.</li>
</ul>
<h3>Constraints</h3>
<p>Optional, under <i>Advanced parameters</i>; the rasters are on the output grid.</p>
<ul>
<li><b>Pinned windows</b> (<code>--pin</code>, at most 16): one per line or separated by
<code>;</code>, each <code>FILE:XOFF,YOFF,W,H@X,Y</code>: the window XOFF,YOFF,W,H of the DEM
FILE (in its own cells, resampled like an exemplar) is copied unchanged with its top-left at
output cell X,Y; the synthesis grows around it.</li>
<li><b>Water mask</b> and <b>Water level</b> (<code>--water</code>,
<code>--water-level</code>, both or neither): cells where the mask is non-zero keep the
level (metres).</li>
<li><b>Regions</b> and <b>Region exemplars</b> (<code>--regions</code>,
<code>--region-exemplar</code>, both or neither): several styles. Regions is an integer raster
or a polygon layer (a file; its first layer) with an integer field <code>region</code>;
Region exemplars lists <code>ID=FILE</code> rules, one per line or separated by
<code>;</code> (e.g. <code>1=a.tif;2=b.tif</code>): region ID takes exemplar FILE (added to
the exemplars if needed); regions without a rule take any exemplar.</li>
<li><b>Wanted heights</b> (<code>--heights</code>, nodata = free) and <b>alpha_h</b>
(<code>--alpha-h</code>, default 1): each candidate patch pays alpha_h x its RMS difference
to the wanted heights.</li>
</ul>
<h3>Outputs</h3>
<ul>
<li><b>Synthesized DEM</b>: Float32 on the target grid with its CRS, nodata -9999 (and
wherever the sketch is nodata).</li>
<li><b>Preview</b> (optional PNG): hillshade of the result.</li>
<li><b>Debug folder</b> (optional): seams.tif, source_exemplar.tif, source_x.tif, source_y.tif,
order.tif on the target grid (where every cell came from); with a sketch also its features and
the output's (GeoPackage) and valley_floor.tif (1 on the drawn valleys' floors).</li>
</ul>
<p>An exemplar smaller than a patch (after resampling), all nodata or unreadable gives a
one-line error naming the file, and nothing is written.</p>
"""


class SynthAlgorithm(TerraSynthAlgorithm):
    STAGE = "synth"
    NAME = "synth"
    DISPLAY_NAME = "Synthesize terrain"
    GROUP = "Terrain synthesis"
    GROUP_ID = "terrainsynthesis"
    HELP = HELP
    LABELS = {"alpha_g": "Seam cost weight (alpha_g)", "coarse_factor": "Coarse search factor",
              "candidates": "Candidates per patch", "order": "Placement order",
              "mode": "Sketch mode", "alpha_d": "Deformation cost weight (alpha_d)",
              "alpha_f": "Feature profile cost weight (alpha_f)"}
    ADVANCED = ("candidates", "alpha_g", "coarse_factor", "alpha_d", "alpha_f")
    SKETCH_STAGE = "sketch"  # its parameters are passed only with a SKETCH

    EXEMPLARS = "EXEMPLARS"
    SKETCH = "SKETCH"
    SKETCH_LINES = "SKETCH_LINES"
    KIND_FIELD = "KIND_FIELD"
    HEIGHT_FIELD = "HEIGHT_FIELD"
    EXTENT = "EXTENT"
    PIXEL_SIZE = "PIXEL_SIZE"
    LIKE = "LIKE"
    WIDTH = "WIDTH"
    HEIGHT = "HEIGHT"
    ORIGIN_X = "ORIGIN_X"
    ORIGIN_Y = "ORIGIN_Y"
    RESOLUTION = "RESOLUTION"
    CRS = "CRS"
    SEED = "SEED"
    BAND = "BAND"
    CELL_SIZE = "CELL_SIZE"
    THREADS = "THREADS"
    OUTPUT = "OUTPUT"
    PREVIEW = "PREVIEW"
    DEBUG_DIR = "DEBUG_DIR"
    PINS = "PINS"
    WATER_MASK = "WATER_MASK"
    WATER_LEVEL = "WATER_LEVEL"
    REGIONS = "REGIONS"
    REGION_EXEMPLARS = "REGION_EXEMPLARS"
    HEIGHTS = "HEIGHTS"
    ALPHA_H = "ALPHA_H"

    def initAlgorithm(self, config=None):  # noqa: N802
        Number = QgsProcessingParameterNumber
        ex = QgsProcessingParameterMultipleLayers(self.EXEMPLARS, self.tr("Exemplar DEMs"),
                                                  QgsProcessing.TypeRaster)
        ex.setMinimumNumberInputs(1)
        ex.setHelp("Real DEMs (any GDAL raster) whose style the new terrain takes "
                   "(--exemplar, 1..64).")
        self.addParameter(ex)
        sketch = QgsProcessingParameterRasterLayer(self.SKETCH, self.tr("Sketch"),
                                                   optional=True)
        sketch.setHelp("A grey drawing (single-band raster): bright strokes = ridges, dark "
                       "strokes = valleys (--sketch). The output is on the sketch's grid (its "
                       "size, geotransform and CRS), nodata where the sketch is nodata; give "
                       "no LIKE, WIDTH/HEIGHT, ORIGIN_X/ORIGIN_Y, RESOLUTION or CRS with it.")
        self.addParameter(sketch)
        lines = QgsProcessingParameterFeatureSource(
            self.SKETCH_LINES, self.tr("Sketch as lines"), [QgsProcessing.TypeVectorLine],
            optional=True)
        lines.setHelp("Ridges and valleys drawn as lines (--sketch): a field (KIND_FIELD) says "
                      "ridge, valley or river of each line; junctions are where lines meet. "
                      "The output grid is LIKE's, or EXTENT at PIXEL_SIZE, or PIXEL_SIZE alone "
                      "(the lines' extent grown by a patch on each side); in CRS, else the "
                      "layer's.")
        self.addParameter(lines)
        kind = QgsProcessingParameterField(
            self.KIND_FIELD, self.tr("Kind field (ridge, valley or river)"), defaultValue="kind",
            parentLayerParameterName=self.SKETCH_LINES,
            type=QgsProcessingParameterField.String, optional=True)
        kind.setHelp("The field of SKETCH_LINES that says ridge, valley or river (--kind-field).")
        self.addParameter(kind)
        height = QgsProcessingParameterField(
            self.HEIGHT_FIELD, self.tr("Height field (wanted height along each line)"),
            parentLayerParameterName=self.SKETCH_LINES,
            type=QgsProcessingParameterField.Numeric, optional=True)
        height.setHelp("A numeric field of SKETCH_LINES: the height wanted along each line "
                       "(--height-field); without it the lines' Z values, if any.")
        self.addParameter(height)
        extent = QgsProcessingParameterExtent(self.EXTENT, self.tr("Target extent"),
                                              optional=True)
        extent.setHelp("The area to cover, with PIXEL_SIZE: the grid starts at its top-left "
                       "corner (--origin), covers it (--size, rounded up) and is in CRS, or "
                       "the extent's own CRS (--crs).")
        self.addParameter(extent)
        pixel = QgsProcessingParameterNumber(
            self.PIXEL_SIZE, self.tr("Pixel size (target CRS units)"),
            QgsProcessingParameterNumber.Double, optional=True, minValue=0.0)
        pixel.setHelp("Cell size of the grid over EXTENT, in its CRS's units (--resolution).")
        self.addParameter(pixel)
        like = QgsProcessingParameterRasterLayer(self.LIKE, self.tr("Target grid like"),
                                                 optional=True)
        like.setHelp("Size, geotransform and CRS of this raster (--like); or give EXTENT "
                     "and PIXEL_SIZE, WIDTH and HEIGHT, or a SKETCH.")
        self.addParameter(like)
        lo, hi = (int(v) for v in descriptors.option_range("synth", "size", (1, 65536)))
        grid = [
            (Number(self.WIDTH, self.tr("Width (cells)"), Number.Integer, optional=True,
                    minValue=lo, maxValue=hi), "Target width in cells (--size WxH)."),
            (Number(self.HEIGHT, self.tr("Height (cells)"), Number.Integer, optional=True,
                    minValue=lo, maxValue=hi), "Target height in cells (--size WxH)."),
            (Number(self.ORIGIN_X, self.tr("Origin X (top-left corner, CRS units)"),
                    Number.Double, optional=True),
             "Top-left corner X (--origin X,Y); default the first exemplar's."),
            (Number(self.ORIGIN_Y, self.tr("Origin Y (top-left corner, CRS units)"),
                    Number.Double, optional=True),
             "Top-left corner Y (--origin X,Y); default the first exemplar's."),
            (Number(self.RESOLUTION, self.tr("Resolution (cell size, CRS units)"),
                    Number.Double, optional=True, minValue=0.0),
             "Cell size in CRS units (--resolution); default the first exemplar's."),
            (QgsProcessingParameterCrs(self.CRS, self.tr("CRS"), optional=True),
             "Target CRS (--crs); with EXTENT, the CRS it is given in (default the "
             "extent's own); otherwise needs ORIGIN_X/ORIGIN_Y and RESOLUTION."),
        ]
        for p, text in grid:
            p.setHelp(text)
            if p.name() != self.CRS:  # cells and CRS units: the extent's long form
                p.setFlags(p.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
            self.addParameter(p)
        self.addDescriptorParameters()
        self.optionParameter(self.SEED, "seed", "Random seed", advanced=False)
        self.optionParameter(self.BAND, "band", "Band of the exemplars")
        self.optionParameter(self.CELL_SIZE, "cell_size",
                             "Cell size for rasters without CRS (metres)")
        self.optionParameter(self.THREADS, "threads", "Threads (0 = all cores)")
        # constraints (advanced)
        pins = QgsProcessingParameterString(self.PINS, self.tr("Pinned windows"),
                                            multiLine=True, optional=True)
        pins.setHelp("Windows of DEMs kept unchanged (--pin, at most 16): one per line or "
                     "separated by ';', each FILE:XOFF,YOFF,W,H@X,Y - the window XOFF,YOFF,W,H "
                     "in the file's own cells, its top-left at output cell X,Y.")
        water = QgsProcessingParameterRasterLayer(self.WATER_MASK, self.tr("Water mask"),
                                                  optional=True)
        water.setHelp("A raster on the output grid (--water): where it is non-zero the output "
                      "keeps WATER_LEVEL. Give WATER_LEVEL with it.")
        level = Number(self.WATER_LEVEL, self.tr("Water level (metres)"), Number.Double,
                       optional=True)
        level.setHelp("Height of the water cells (--water-level); needs WATER_MASK.")
        regions = QgsProcessingParameterMapLayer(
            self.REGIONS, self.tr("Regions (raster or polygon layer)"), optional=True,
            types=[QgsProcessing.TypeRaster, QgsProcessing.TypeVectorPolygon])
        regions.setHelp("Several styles (--regions): an integer raster on the output grid, or "
                        "a polygon layer (file, first layer) with an integer field 'region'. "
                        "Give REGION_EXEMPLARS with it.")
        rules = QgsProcessingParameterString(
            self.REGION_EXEMPLARS, self.tr("Region exemplars (ID=FILE; ...)"), multiLine=True,
            optional=True)
        rules.setHelp("Which exemplar each region takes (--region-exemplar): one rule per line "
                      "or separated by ';', each ID=FILE, e.g. 1=a.tif;2=b.tif. Regions without "
                      "a rule take any exemplar. Needs REGIONS.")
        heights = QgsProcessingParameterRasterLayer(self.HEIGHTS, self.tr("Wanted heights"),
                                                    optional=True)
        heights.setHelp("Wanted elevations, a raster on the output grid, nodata = free "
                        "(--heights).")
        alpha_h = Number(self.ALPHA_H, self.tr("Height cost weight (alpha_h)"), Number.Double,
                         defaultValue=1.0, minValue=0.0)
        alpha_h.setHelp("Each candidate pays alpha_h x the RMS difference to HEIGHTS "
                        "(--alpha-h); used only with HEIGHTS.")
        for p in (pins, water, level, regions, rules, heights, alpha_h):
            p.setFlags(p.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
            self.addParameter(p)
        self.addParameter(QgsProcessingParameterRasterDestination(
            self.OUTPUT, self.tr("Synthesized DEM")))
        self.addParameter(QgsProcessingParameterFileDestination(
            self.PREVIEW, self.tr("Preview"), fileFilter="PNG files (*.png)", optional=True,
            createByDefault=False))
        self.addFlowParameters()
        self.addParameter(QgsProcessingParameterFolderDestination(
            self.DEBUG_DIR, self.tr("Debug maps folder"), optional=True,
            createByDefault=False))

    def shortHelpString(self):  # noqa: N802
        """The manual's summary, with the sketch parameters listed from the descriptor
        tables (every one of them, with its default: never out of date)."""
        help_text = HELP
        items = "".join("<li><b>%s</b> (default %s): %s</li>" % (
            d["name"].upper(), d["choices"][int(d["default"])] if d.get("choices")
            else ("%g" % d["default"]), d["help"]) for d in descriptors.stage(self.SKETCH_STAGE))
        for name in ("patch_size", "overlap"):  # ranges and defaults from the core
            d = descriptors.param("synth", name)
            text_range = "%g..%g cells, default %g" % (d["min"], d["max"], d["default"]) \
                if d else "cells"
            help_text = help_text.replace("{%s}" % name.upper(), text_range)
        text = help_text.replace("{SKETCH_PARAMETERS}",
                            "<ul>%s</ul><p>They are passed only with a sketch (the program "
                            "refuses them without one).</p>" % items)
        return " ".join(text.split())

    # -- the target grid --------------------------------------------------------
    def targetOptions(self, parameters, context):  # noqa: N802
        """[(option, value)] for the target grid; raises on an incomplete grid."""
        sketch = self.parameterAsRasterLayer(parameters, self.SKETCH, context) \
            if is_set(parameters, self.SKETCH) else None
        if is_set(parameters, self.SKETCH) and sketch is None:
            raise QgsProcessingException(self.invalidRasterError(parameters, self.SKETCH))
        like = self.parameterAsRasterLayer(parameters, self.LIKE, context) \
            if is_set(parameters, self.LIKE) else None
        if is_set(parameters, self.LIKE) and like is None:
            raise QgsProcessingException(self.invalidRasterError(parameters, self.LIKE))
        width = self.parameterAsInt(parameters, self.WIDTH, context) \
            if is_set(parameters, self.WIDTH) else 0
        height = self.parameterAsInt(parameters, self.HEIGHT, context) \
            if is_set(parameters, self.HEIGHT) else 0
        has_x, has_y = is_set(parameters, self.ORIGIN_X), is_set(parameters, self.ORIGIN_Y)
        has_res = is_set(parameters, self.RESOLUTION)
        crs = self.parameterAsCrs(parameters, self.CRS, context) \
            if is_set(parameters, self.CRS) else QgsCoordinateReferenceSystem()
        raw_crs = parameters.get(self.CRS)
        # which of these go together is the job's rule (the program checks it, with the
        # same message as on the command line); here only what QGIS splits in two
        if (width > 0) != (height > 0):
            raise QgsProcessingException("give both WIDTH and HEIGHT, or neither")
        if has_x != has_y:
            raise QgsProcessingException("give both ORIGIN_X and ORIGIN_Y, or neither")
        if isinstance(raw_crs, str) and raw_crs.strip() and not crs.isValid():
            raise QgsProcessingException("CRS: '%s' is not a valid coordinate reference "
                                         "system" % raw_crs)
        res = self.parameterAsDouble(parameters, self.RESOLUTION, context) if has_res else None
        origin = (self.parameterAsDouble(parameters, self.ORIGIN_X, context),
                  self.parameterAsDouble(parameters, self.ORIGIN_Y, context)) if has_x else None
        size = (width, height) if width else None
        if sketch is not None:
            # a painted sketch is the grid (the program says the same of a raster --sketch)
            for given, name in ((like is not None, "like"), (has_res, "resolution"),
                                (crs.isValid(), "crs")):
                if given:
                    raise QgsProcessingException(
                        "a painted sketch sets the output grid: give no %s" % name)
        if is_set(parameters, self.SKETCH_LINES):
            if sketch is not None:
                raise QgsProcessingException("give SKETCH (painted) or SKETCH_LINES, not both")
            return self._lines_options(parameters, context, crs, like, size, has_x, has_res)
        if is_set(parameters, self.EXTENT) or is_set(parameters, self.PIXEL_SIZE):
            size, origin, res, crs = self._extent_grid(
                parameters, context, crs, (width > 0, has_x, has_res, sketch, like))
        crs_text = None
        if crs.isValid():
            crs_text = crs.authid() or crs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED)
        return [("sketch", gdal_source(sketch, self.SKETCH) if sketch is not None else None),
                ("like", gdal_source(like, self.LIKE) if like is not None else None),
                ("size", size), ("origin", origin),
                ("resolution", res), ("crs", crs_text)]

    def _lines_options(self, parameters, context, crs, like, size, has_origin, has_res):
        """[(option, value)] for a sketch drawn as lines: the layer (a file OGR reads, written
        to a temporary GeoPackage when it is not one), its fields, and the grid: LIKE, or
        EXTENT at PIXEL_SIZE, or PIXEL_SIZE (or RESOLUTION) alone."""
        path, layer_name = self.parameterAsCompatibleSourceLayerPathAndLayerName(
            parameters, self.SKETCH_LINES, context, ["gpkg", "shp", "geojson", "fgb", "kml"],
            "gpkg")
        if not path:
            raise QgsProcessingException("SKETCH_LINES: '%s' is not a line layer"
                                         % parameters.get(self.SKETCH_LINES))
        kind = self.parameterAsString(parameters, self.KIND_FIELD, context) \
            if is_set(parameters, self.KIND_FIELD) else ""
        height = self.parameterAsString(parameters, self.HEIGHT_FIELD, context) \
            if is_set(parameters, self.HEIGHT_FIELD) else ""
        res, extent = None, None
        if size is not None or has_origin:
            raise QgsProcessingException("a sketch sets the output grid: give no WIDTH/HEIGHT "
                                         "or ORIGIN_X/ORIGIN_Y with SKETCH_LINES")
        if is_set(parameters, self.PIXEL_SIZE):
            res = self.parameterAsDouble(parameters, self.PIXEL_SIZE, context)
        elif has_res:
            res = self.parameterAsDouble(parameters, self.RESOLUTION, context)
        if is_set(parameters, self.EXTENT):
            if res is None:
                raise QgsProcessingException("EXTENT needs PIXEL_SIZE, the cell size of the grid")
            if not crs.isValid():
                crs = self.parameterAsExtentCrs(parameters, self.EXTENT, context)
            rect = self.parameterAsExtent(parameters, self.EXTENT, context,
                                          crs if crs.isValid() else QgsCoordinateReferenceSystem())
            if rect.isNull() or not rect.width() > 0 or not rect.height() > 0:
                raise QgsProcessingException("EXTENT: the area is empty (%s)" % rect.toString())
            extent = "%.17g,%.17g,%.17g,%.17g" % (rect.xMinimum(), rect.yMinimum(),
                                                  rect.xMaximum(), rect.yMaximum())
        if like is None and res is None:
            raise QgsProcessingException("a sketch of lines needs the output grid: give LIKE, "
                                         "or PIXEL_SIZE (with EXTENT or without)")
        crs_text = None
        if crs.isValid() and like is None:
            crs_text = crs.authid() or crs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED)
        return [("sketch", path), ("sketch_layer", layer_name or None),
                ("kind_field", kind or None), ("height_field", height or None),
                ("like", gdal_source(like, self.LIKE) if like is not None else None),
                ("resolution", res), ("extent", extent), ("crs", crs_text)]

    def _extent_grid(self, parameters, context, crs, others):
        """(size, origin, resolution, crs) of the grid over EXTENT at PIXEL_SIZE, as QGIS's
        native "Create constant raster layer" lays it: from the top-left corner, rounded up
        to cover the extent."""
        has_size, has_origin, has_res, sketch, like = others
        if not is_set(parameters, self.EXTENT):
            raise QgsProcessingException("PIXEL_SIZE goes with EXTENT: give both, or use "
                                         "RESOLUTION with WIDTH and HEIGHT")
        if not is_set(parameters, self.PIXEL_SIZE):
            raise QgsProcessingException("EXTENT needs PIXEL_SIZE, the cell size of the grid")
        for given, name in ((sketch is not None, "SKETCH"), (like is not None, "LIKE"),
                            (has_size, "WIDTH/HEIGHT"), (has_origin, "ORIGIN_X/ORIGIN_Y"),
                            (has_res, "RESOLUTION")):
            if given:
                raise QgsProcessingException("EXTENT sets the output grid: give no %s with "
                                             "it" % name)
        if not crs.isValid():
            crs = self.parameterAsExtentCrs(parameters, self.EXTENT, context)
        rect = self.parameterAsExtent(parameters, self.EXTENT, context,
                                      crs if crs.isValid() else QgsCoordinateReferenceSystem())
        px = self.parameterAsDouble(parameters, self.PIXEL_SIZE, context)
        if not px > 0:
            raise QgsProcessingException("PIXEL_SIZE must be more than 0")
        if rect.isNull() or not rect.width() > 0 or not rect.height() > 0:
            raise QgsProcessingException("EXTENT: the area is empty (%s)" % rect.toString())
        cols = max(1, int(math.ceil(rect.width() / px - 1e-9)))
        rows = max(1, int(math.ceil(rect.height() / px - 1e-9)))
        most = int(descriptors.option_range("synth", "size", (1, 65536))[1])
        if cols > most or rows > most:
            raise QgsProcessingException("EXTENT at PIXEL_SIZE %g is %d x %d cells: more than "
                                         "%d on a side" % (px, cols, rows, most))
        return (cols, rows), (rect.xMinimum(), rect.yMaximum()), px, crs

    # -- the constraints ----------------------------------------------------------
    def _raster(self, parameters, key, context):
        if not is_set(parameters, key):
            return None
        layer = self.parameterAsRasterLayer(parameters, key, context)
        if layer is None:
            raise QgsProcessingException(self.invalidRasterError(parameters, key))
        return gdal_source(layer, key)

    def _regions_source(self, parameters, context):
        layer = self.parameterAsLayer(parameters, self.REGIONS, context)
        if layer is None:
            raise QgsProcessingException(
                "REGIONS: '%s' is not a raster or polygon layer" % parameters.get(self.REGIONS))
        if isinstance(layer, QgsRasterLayer):
            return gdal_source(layer, self.REGIONS)
        if not isinstance(layer, QgsVectorLayer) or \
                layer.geometryType() != QgsWkbTypes.PolygonGeometry:
            raise QgsProcessingException("REGIONS: layer '%s' is neither a raster nor a polygon "
                                         "layer" % layer.name())
        if layer.providerType() != "ogr":
            raise QgsProcessingException(
                "REGIONS: layer '%s' comes from the '%s' provider; terrasynth reads polygon "
                "files GDAL/OGR opens" % (layer.name(), layer.providerType()))
        idx = layer.fields().indexFromName(REGION_FIELD)
        if idx < 0 or not layer.fields().at(idx).isNumeric() or \
                layer.fields().at(idx).type() not in _INT_TYPES:
            raise QgsProcessingException("REGIONS: layer '%s' has no integer field '%s'"
                                         % (layer.name(), REGION_FIELD))
        parts = QgsProviderRegistry.instance().decodeUri("ogr", layer.source())
        if layer.subsetString():
            raise QgsProcessingException("REGIONS: layer '%s' has a filter; terrasynth reads the "
                                         "whole file" % layer.name())
        path = parts.get("path") or layer.source().split("|")[0]
        sub = parts.get("layerName") or parts.get("layerId")
        if sub not in (None, "", 0):
            from osgeo import ogr
            ds = ogr.Open(path)
            first = ds.GetLayer(0) if ds is not None and ds.GetLayerCount() else None
            if first is None or (parts.get("layerName") and
                                 first.GetName() != parts.get("layerName")) or \
                    (parts.get("layerId") not in (None, "") and int(parts["layerId"]) != 0):
                raise QgsProcessingException(
                    "REGIONS: terrasynth reads the first layer of %s; save layer '%s' to a "
                    "file of its own" % (path, layer.name()))
        return path

    def constraintOptions(self, parameters, context):  # noqa: N802
        """[(option, value)] for --pin, --water, --regions, --heights; raises on errors."""
        options = []
        pins = _items(self.parameterAsString(parameters, self.PINS, context)
                      if is_set(parameters, self.PINS) else "")
        options.append(("pin", pins or None))
        # WATER_MASK with WATER_LEVEL, REGIONS with REGION_EXEMPLARS: the job's rules
        options += [("water", self._raster(parameters, self.WATER_MASK, context)),
                    ("water_level", self.parameterAsDouble(parameters, self.WATER_LEVEL, context)
                     if is_set(parameters, self.WATER_LEVEL) else None)]
        rules = _items(self.parameterAsString(parameters, self.REGION_EXEMPLARS, context)
                       if is_set(parameters, self.REGION_EXEMPLARS) else "")
        options += [("regions", self._regions_source(parameters, context)
                     if is_set(parameters, self.REGIONS) else None),
                    ("region_exemplar", rules or None)]
        # ALPHA_H changed from its default without HEIGHTS is passed: the job's rule refuses it
        alpha_h = self.parameterAsDouble(parameters, self.ALPHA_H, context) \
            if is_set(parameters, self.ALPHA_H) else 1.0
        if is_set(parameters, self.HEIGHTS) or alpha_h != 1.0:
            options += [("heights", self._raster(parameters, self.HEIGHTS, context)
                         if is_set(parameters, self.HEIGHTS) else None),
                        ("alpha_h", alpha_h)]
        return options

    def descriptorValues(self, parameters, context):  # noqa: N802
        values = super().descriptorValues(parameters, context)
        if not is_set(parameters, self.SKETCH) and not is_set(parameters, self.SKETCH_LINES):
            # a dialog always holds the sketch parameters: without a sketch only those
            # changed from their defaults are passed, and the job's rule refuses them
            # ("alpha_r applies to a sketch: give sketch"), as on the command line
            for d in self._descs:
                if self._desc_stage[d["name"]] == self.SKETCH_STAGE and \
                        runner.is_default(d, values.get(d["name"])):
                    values.pop(d["name"], None)
        return values

    def checkJob(self, parameters, context):  # noqa: N802
        # the job's rules (exemplar count, overlap under the patch, cell size, which options
        # go together) are the program's: it checks them with the command line's messages;
        # here only what the dialog's form adds
        self.targetOptions(parameters, context)
        self.constraintOptions(parameters, context)

    def prepareJob(self, parameters, context):  # noqa: N802
        layers = self.parameterAsLayerList(parameters, self.EXEMPLARS, context)
        exemplars = [gdal_source(layer, self.EXEMPLARS) for layer in layers]
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        preview = self.parameterAsFileOutput(parameters, self.PREVIEW, context) or ""
        debug_dir = self.parameterAsFileOutput(parameters, self.DEBUG_DIR, context) or ""
        if preview and os.path.splitext(preview)[1].lower() != ".png":
            raise QgsProcessingException("PREVIEW must be a .png file, not %s" % preview)
        options = [("exemplar", exemplars)]
        options += self.targetOptions(parameters, context)
        options += self.constraintOptions(parameters, context)
        options += [(n, self.optionValue(parameters, k, n, context)) for k, n in (
                        (self.SEED, "seed"), (self.BAND, "band"), (self.CELL_SIZE, "cell_size"),
                        (self.THREADS, "threads"))]
        options += [
                    ("preview", preview),
                    ("debug_dir", debug_dir)]
        results = {self.OUTPUT: output}
        if preview:
            results[self.PREVIEW] = preview
        if debug_dir:
            results[self.DEBUG_DIR] = debug_dir
        return {"positional": [output], "options": options, "outputs": [output, preview],
                "output_dirs": [debug_dir] if debug_dir else [], "results": results}
