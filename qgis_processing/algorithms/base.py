# SPDX-License-Identifier: GPL-2.0-or-later
"""What every TerraSynth algorithm shares: the core's parameters built from its
descriptor tables, checks, and the hand-over to runner.py."""
from qgis.core import (
    QgsProcessing,
    QgsProcessingAlgorithm,
    QgsProcessingException,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterEnum,
    QgsProcessingParameterNumber,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorDestination,
    QgsProviderRegistry,
)
from qgis.PyQt.QtCore import QCoreApplication

from .. import descriptors, runner


def exception_text(e):
    return str(e.args[0]) if getattr(e, "args", None) else str(e)


def gdal_source(layer, key):
    """The GDAL dataset name of a raster layer, for the CLI."""
    if layer.providerType() != "gdal":
        raise QgsProcessingException(
            "%s: layer '%s' comes from the '%s' provider; terrasynth reads rasters GDAL opens "
            "(files)" % (key, layer.name(), layer.providerType()))
    src = layer.source()
    try:
        parts = QgsProviderRegistry.instance().decodeUri("gdal", src)
    except Exception:  # pragma: no cover - decodeUri is always there in 3.22
        parts = {}
    path = parts.get("path") if parts else None
    if path and not parts.get("layerName") and not parts.get("openOptions"):
        return path  # a plain file, without any "|option:..." suffix
    return src  # a GDAL connection string (NETCDF:..., GPKG:..., /vsizip/...)


def _decimals(d):
    """Decimals shown for a double: 5 for fractions, else enough for the default (>= 2)."""
    if float(d["max"]) <= 1.0:
        return 5
    default = float(d["default"])
    for k in range(2, 7):
        if round(default, k) == default:
            return k
    return 6


def is_set(parameters, key):
    """Was an optional parameter given (0 and 0.0 count as given)?"""
    v = parameters.get(key)
    return v is not None and not (isinstance(v, str) and v.strip() == "")


class TerraSynthAlgorithm(QgsProcessingAlgorithm):
    """Subclasses set the class attributes and implement initAlgorithm,
    prepareJob (and optionally checkJob)."""

    STAGE = None          # the core's stage, `terrasynth <STAGE>`, descriptor table name
    NAME = None           # algorithm id inside the provider: terrasynth:<NAME>
    DISPLAY_NAME = None
    GROUP = None
    GROUP_ID = None
    HELP = ""             # HTML, condensed from algorithms/docs/<stage>.md
    LABELS = {}           # descriptor name -> dialog label (default: from the name)
    ADVANCED = ()         # descriptor names shown under "Advanced parameters"
    # descriptor tables whose parameters this algorithm shows (default: those `terrasynth
    # describe` gives the job, e.g. synth, sketch and drainage for `terrasynth synth`)
    DESCRIPTOR_STAGES = None

    def __init__(self):
        super().__init__()
        self._descs = []
        self._desc_stage = {}  # descriptor name -> the table it comes from
        for st in (self.DESCRIPTOR_STAGES or
                   descriptors.job(self.STAGE).get("stages", [self.STAGE])):
            for d in descriptors.stage(st):
                if d.get("type") in descriptors.KNOWN_TYPES:
                    self._descs.append(d)
                    self._desc_stage[d["name"]] = st

    # -- identity -----------------------------------------------------------
    def name(self):
        return self.NAME

    def displayName(self):  # noqa: N802
        return self.tr(self.DISPLAY_NAME)

    def group(self):
        return self.tr(self.GROUP)

    def groupId(self):  # noqa: N802
        return self.GROUP_ID

    def shortHelpString(self):  # noqa: N802
        # the dialog turns newlines into breaks: hand over one line of HTML
        return " ".join(self.HELP.split())

    def createInstance(self):  # noqa: N802
        return type(self)()

    def tr(self, text):
        return QCoreApplication.translate("TerraSynth", text)

    # -- the core's parameters ----------------------------------------------
    def descriptors(self):
        """The descriptors this instance was built from (copies)."""
        return [dict(d) for d in self._descs]

    def _label(self, d):
        text = self.LABELS.get(d["name"]) or d["name"].replace("_", " ").capitalize()
        units = d.get("units") or ""
        if d["type"] in ("int", "double") and units and units.lower() not in text.lower():
            text += " (%s)" % units
        return text

    def descriptorParameters(self, d):  # noqa: N802
        """QGIS parameters for one descriptor: key = name in UPPER_SNAKE_CASE."""
        key, label = descriptors.key(d), self._label(d)
        t = d["type"]
        if t in ("int", "double"):
            p = QgsProcessingParameterNumber(
                key, label,
                QgsProcessingParameterNumber.Integer if t == "int"
                else QgsProcessingParameterNumber.Double,
                defaultValue=int(d["default"]) if t == "int" else float(d["default"]),
                minValue=float(d["min"]), maxValue=float(d["max"]))
            if t == "double":
                p.setMetadata({"widget_wrapper": {"decimals": _decimals(d)}})
            params = [p]
        elif t == "enum":
            params = [QgsProcessingParameterEnum(key, label, options=list(d["choices"]),
                                                 defaultValue=int(d["default"]))]
        else:  # length: a number and its unit
            # the range is in cells; a length in metres is checked by the program once it
            # is turned into cells of the grid, so the widget only keeps it positive
            p = QgsProcessingParameterNumber(
                key, label, QgsProcessingParameterNumber.Double,
                defaultValue=float(d["default"]), minValue=float(d["min"]),
                maxValue=max(float(d["max"]), 1e9))
            p.setMetadata({"widget_wrapper": {"decimals": _decimals(d)}})
            unit_default = 1 if d.get("default_unit") in ("m", "metres") else 0
            u = QgsProcessingParameterEnum(descriptors.unit_key(d), label + " unit",
                                           options=list(descriptors.LENGTH_UNITS),
                                           defaultValue=unit_default)
            u.setHelp("Unit of %s: cells, or metres on the ground (needs a CRS or CELL_SIZE)."
                      % key)
            params = [p, u]
        params[0].setHelp(d.get("help", ""))
        if d["name"] in self.ADVANCED:
            for p in params:
                p.setFlags(p.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
        return params

    def addDescriptorParameters(self):  # noqa: N802
        for d in self._descs:
            for p in self.descriptorParameters(d):
                self.addParameter(p)

    def descriptorStages(self, parameters, context):  # noqa: N802
        """The descriptor tables passed to the program for these parameters (default:
        all of DESCRIPTOR_STAGES); e.g. synth leaves out "sketch" without a sketch."""
        return set(self._desc_stage.values())

    def descriptorValues(self, parameters, context):  # noqa: N802
        """{descriptor name: value} in the form runner.format_value takes, for the
        descriptors of descriptorStages()."""
        stages = self.descriptorStages(parameters, context)
        values = {}
        for d in self._descs:
            if self._desc_stage[d["name"]] not in stages:
                continue
            key = descriptors.key(d)
            if d["type"] == "int":
                values[d["name"]] = self.parameterAsInt(parameters, key, context)
            elif d["type"] == "double":
                values[d["name"]] = self.parameterAsDouble(parameters, key, context)
            elif d["type"] == "enum":
                values[d["name"]] = self.parameterAsEnum(parameters, key, context)
            else:
                unit = self.parameterAsEnum(parameters, descriptors.unit_key(d), context)
                values[d["name"]] = (self.parameterAsDouble(parameters, key, context),
                                     descriptors.LENGTH_UNITS[unit])
        return values

    # -- the job's own options (band, cell size, seed) and the common ones --------
    def optionParameter(self, key, name, label, advanced=True):  # noqa: N802
        """A QGIS parameter for option `name` of the job, or one every command takes
        (threads), with its kind, range and help as `terrasynth describe` declares them.
        A seed is text: it takes the whole 64-bit range the program takes."""
        o = descriptors.job_option(self.STAGE, name) or descriptors.common(name)
        kind = o.get("kind")
        if kind == "seed":
            p = QgsProcessingParameterString(key, self.tr(label), defaultValue="0")
        elif kind in ("int", "number"):
            optional = kind == "number"
            p = QgsProcessingParameterNumber(
                key, self.tr(label),
                QgsProcessingParameterNumber.Integer if kind == "int"
                else QgsProcessingParameterNumber.Double,
                defaultValue=None if optional else max(1 if name == "band" else 0,
                                                       int(o.get("min", 0))),
                optional=optional, minValue=float(o.get("min", 0)),
                maxValue=float(o.get("max", 1e9)))
        else:
            raise ValueError("%s: no option %s in `terrasynth describe`" % (self.STAGE, name))
        text = o.get("help", "")
        p.setHelp("%s%s (%s)." % (text[:1].upper(), text[1:],
                                   o.get("flag") or "--" + name.replace("_", "-")))
        if advanced:
            p.setFlags(p.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
        self.addParameter(p)
        return p

    def optionValue(self, parameters, key, name, context):  # noqa: N802
        """The value of an optionParameter for the command line (None when not given)."""
        o = descriptors.job_option(self.STAGE, name) or descriptors.common(name)
        if not is_set(parameters, key):
            return None
        if o.get("kind") == "seed":
            return self.parameterAsString(parameters, key, context).strip()
        if o.get("kind") == "int":
            return self.parameterAsInt(parameters, key, context)
        return self.parameterAsDouble(parameters, key, context)

    # -- the streams of the DEM a job writes (flow_lines, flow_cells, flow_km2) --
    FLOW_LINES = "FLOW_LINES"
    FLOW_CELLS = "FLOW_CELLS"
    FLOW_KM2 = "FLOW_KM2"

    def addFlowParameters(self):  # noqa: N802
        """The streams as lines (optional, GeoPackage) and their threshold."""
        o = descriptors.job_option(self.STAGE, "flow_lines") or {}
        p = QgsProcessingParameterVectorDestination(
            self.FLOW_LINES, self.tr("Streams (flow lines)"),
            QgsProcessing.TypeVectorLine, optional=True, createByDefault=False)
        text = o.get("help", "")
        p.setHelp("%s%s (--flow-lines)." % (text[:1].upper(), text[1:]))
        self.addParameter(p)
        self.optionParameter(self.FLOW_CELLS, "flow_cells", "Streams: least drainage area (cells)")
        self.optionParameter(self.FLOW_KM2, "flow_km2", "Streams: least drainage area (km²)")

    def addFlowJob(self, job, parameters, context):  # noqa: N802
        """The streams' options, output and result added to a prepared job."""
        path = self.parameterAsOutputLayer(parameters, self.FLOW_LINES, context) or ""
        if not path:
            return
        job["options"] = list(job["options"]) + [
            ("flow_lines", path),
            ("flow_cells", self.optionValue(parameters, self.FLOW_CELLS, "flow_cells", context)),
            ("flow_km2", self.optionValue(parameters, self.FLOW_KM2, "flow_km2", context))]
        job["outputs"] = list(job["outputs"]) + [path]
        job["results"][self.FLOW_LINES] = path

    # -- checks and running ---------------------------------------------------
    def checkJob(self, parameters, context):  # noqa: N802
        """Cross-parameter checks; raise QgsProcessingException."""

    def checkParameterValues(self, parameters, context):  # noqa: N802
        ok, msg = super().checkParameterValues(parameters, context)
        if not ok:
            return ok, msg
        try:
            self.checkJob(parameters, context)
            argv, _ = self.buildCommand(parameters, context)
        except QgsProcessingException as e:
            return False, exception_text(e)
        # the job's rules are the program's: it checks the command line it would be given
        # (--check: nothing read or run) and says what is wrong in its own words
        try:
            msg = runner.check(argv)
        except (OSError, ValueError) as e:
            return False, "terrasynth: %s" % e
        if msg:
            return False, msg
        return True, ""

    def prepareJob(self, parameters, context):  # noqa: N802
        """Return a dict: positional (list), options (list of (name, value)),
        outputs (files written), output_dirs (folders written into), results."""
        raise NotImplementedError

    def buildCommand(self, parameters, context, cli=None):  # noqa: N802
        """(argv, job) for these parameters; nothing is run."""
        self.checkJob(parameters, context)
        job = self.prepareJob(parameters, context)
        if self.parameterDefinition(self.FLOW_LINES) is not None:
            self.addFlowJob(job, parameters, context)
        argv = runner.build_argv(cli or runner.find_cli(), self.STAGE,
                                 positional=job["positional"],
                                 params=self.descriptorValues(parameters, context),
                                 descs=self._descs, options=job["options"])
        return argv, job

    def finishJob(self, job, context, feedback):  # noqa: N802
        """Hook after a successful run (e.g. which layers QGIS loads)."""

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        argv, job = self.buildCommand(parameters, context)
        runner.run(argv, feedback, outputs=job["outputs"], output_dirs=job.get("output_dirs", ()))
        self.finishJob(job, context, feedback)
        return job["results"]
