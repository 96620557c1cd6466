# SPDX-License-Identifier: GPL-2.0-or-later
"""The TerraSynth provider inside QGIS (Python API, no GUI): registration, parameters
against the core's descriptors (`terrasynth describe`), command lines (nothing run),
and processing.run() end to end on data/jacksboro_fault_dem.tif."""
import json
import os
import subprocess

import numpy as np
import pytest

pytest.importorskip("qgis.core", reason="qgis is not importable (python3-qgis)")

from osgeo import gdal, osr  # noqa: E402
from qgis.core import (  # noqa: E402
    QgsApplication,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingFeedback,
    QgsProcessingParameterEnum,
    QgsProcessingParameterNumber,
    QgsProject,
    QgsRasterLayer,
    QgsSettings,
    QgsVectorLayer,
    QgsWkbTypes,
)

gdal.UseExceptions()

pytestmark = pytest.mark.usefixtures("qgis_app")

ALGORITHMS = {"ppa": ("Extract ridges and valleys (PPA)", "Terrain analysis"),
              "synth": ("Synthesize terrain", "Terrain synthesis"),
              "amplify": ("Amplify a coarse DEM", "Terrain synthesis"),
              "pixel": ("Grow terrain cell by cell (pixel synthesis)", "Terrain synthesis")}
# the descriptor tables of `terrasynth describe` each algorithm shows
DESCRIPTOR_STAGES = {"ppa": ("ppa",), "synth": ("synth", "sketch", "drainage"),
                     "amplify": ("amplify", "drainage"), "pixel": ("pixel", "drainage")}
ALG_STAGES = [(alg, st) for alg in sorted(DESCRIPTOR_STAGES) for st in DESCRIPTOR_STAGES[alg]]
# parameters that are not the core's descriptors, and the CLI flag each maps to
# (None: a positional file or an output QGIS reports, not a CLI option)
OTHER_FLAGS = {
    "ppa": {"INPUT": None, "OUTPUT": None, "NODES": None, "BAND": "--band",
            "CELL_SIZE": "--cell-size", "THREADS": "--threads", "LINES": "--lines",
            "PREVIEW": "--preview"},
    "synth": {"EXEMPLARS": "--exemplar", "SKETCH": "--sketch", "LIKE": "--like",
              "SKETCH_LINES": "--sketch", "KIND_FIELD": "--kind-field",
              "HEIGHT_FIELD": "--height-field",
              "EXTENT": "--origin", "PIXEL_SIZE": "--resolution", "WIDTH": "--size",
              "HEIGHT": "--size", "ORIGIN_X": "--origin", "ORIGIN_Y": "--origin",
              "RESOLUTION": "--resolution", "CRS": "--crs", "SEED": "--seed", "BAND": "--band",
              "CELL_SIZE": "--cell-size", "THREADS": "--threads", "OUTPUT": None,
              "PREVIEW": "--preview", "DEBUG_DIR": "--debug-dir", "PINS": "--pin",
              "WATER_MASK": "--water", "WATER_LEVEL": "--water-level", "REGIONS": "--regions",
              "REGION_EXEMPLARS": "--region-exemplar", "HEIGHTS": "--heights",
              "ALPHA_H": "--alpha-h"},
    "amplify": {"INPUT": None, "EXEMPLARS": "--exemplar", "BAND": "--band",
                "CELL_SIZE": "--cell-size", "THREADS": "--threads", "OUTPUT": None,
                "PREVIEW": "--preview", "EXEMPLAR_CLASSES": "--exemplar-classes",
                "EXEMPLAR_LAYERS": "--exemplar-layer", "CLASSES": "--classes",
                "OUT_LAYER_NAME": "--out-layer", "OUT_LAYER": "--out-layer",
                "OUT_CLASSES": "--out-classes", "DICTIONARY": "--dictionary",
                "BIOMES": "--biome"},
    "pixel": {"EXEMPLARS": "--exemplar", "GUIDE": "--guide", "LIKE": "--like",
              "WIDTH": "--size", "HEIGHT": "--size", "SEED": "--seed", "BAND": "--band",
              "CELL_SIZE": "--cell-size", "THREADS": "--threads", "OUTPUT": None,
              "PREVIEW": "--preview"},
}
# the streams of every job's DEM (base.addFlowParameters)
for _flags in OTHER_FLAGS.values():
    _flags.update(FLOW_LINES="--flow-lines", FLOW_CELLS="--flow-cells", FLOW_KM2="--flow-km2")
# parameters whose flag is not --<name in kebab case>
IRREGULAR_FLAGS = ("--size", "--origin", "--resolution", "--exemplar", "--pin", "--water",
                   "--sketch",
                   "--region-exemplar", "--exemplar-layer", "--out-layer", "--biome")


def processing_run(alg_id, params, feedback=None):
    import processing

    return processing.run(alg_id, params, feedback=feedback or QgsProcessingFeedback())


def registry():
    return QgsApplication.processingRegistry()


@pytest.fixture(scope="module")
def describe(cli):
    p = subprocess.run([cli, "describe"], capture_output=True, text=True, check=True)
    return json.loads(p.stdout)


def raster_info(path):
    ds = gdal.Open(str(path))
    srs = osr.SpatialReference(wkt=ds.GetProjection()) if ds.GetProjection() else None
    return ds, srs


# --------------------------------------------------------------------------- registration

def test_provider_registered_with_every_algorithm():
    provider = registry().providerById("terrasynth")
    assert provider is not None
    assert provider.name() == "TerraSynth"
    assert sorted(a.id() for a in provider.algorithms()) == sorted(
        "terrasynth:" + name for name in ALGORITHMS)
    for name, (display, group) in ALGORITHMS.items():
        alg = registry().algorithmById("terrasynth:" + name)
        assert alg.displayName() == display
        assert alg.group() == group
        assert "terrasynth " + name in alg.shortHelpString()
        assert "\n" not in alg.shortHelpString()


def test_provider_read_the_descriptors_from_the_cli(cli):
    from terrasynth_qgis import descriptors

    assert descriptors.source().startswith("describe ")


# --------------------------------------------------------------------------- parameters vs the core

@pytest.mark.parametrize("alg_name,stage", ALG_STAGES)
def test_parameters_match_the_core_descriptors(alg_name, stage, describe):
    alg = registry().algorithmById("terrasynth:" + alg_name)
    assert describe["stages"][stage], "describe has no stage %s" % stage
    for d in describe["stages"][stage]:
        key = d["name"].upper()
        assert d["flag"] == "--" + d["name"].replace("_", "-")
        p = alg.parameterDefinition(key)
        assert p is not None, "%s has no parameter %s" % (stage, key)
        assert p.help() == d["help"]
        if d["type"] in ("int", "double", "length"):
            assert isinstance(p, QgsProcessingParameterNumber), key
            want = (QgsProcessingParameterNumber.Integer if d["type"] == "int"
                    else QgsProcessingParameterNumber.Double)
            assert p.dataType() == want, key
            assert p.defaultValue() == d["default"], key
            assert p.minimum() == d["min"], key
            # a length's range is in cells: the widget also takes metres beyond it
            assert p.maximum() == (max(d["max"], 1e9) if d["type"] == "length" else d["max"]), key
        if d["type"] == "enum":
            assert isinstance(p, QgsProcessingParameterEnum), key
            assert p.options() == d["choices"], key
            assert p.defaultValue() == d["default"], key
            assert not p.allowMultiple()
        if d["type"] == "length":
            u = alg.parameterDefinition(key + "_UNIT")
            assert isinstance(u, QgsProcessingParameterEnum)
            assert u.options() == ["cells", "metres"]
            assert u.options()[u.defaultValue()] == {"cells": "cells", "m": "metres"}[
                d["default_unit"]]


@pytest.mark.parametrize("stage", sorted(ALGORITHMS))
def test_every_other_parameter_is_a_cli_option(stage, cli, describe):
    """One name per parameter: KEY <-> --key for everything that is not a descriptor."""
    alg = registry().algorithmById("terrasynth:" + stage)
    help_text = subprocess.run([cli, stage, "--help"], capture_output=True, text=True,
                               check=True).stdout
    core = {d["name"].upper() for st in DESCRIPTOR_STAGES[stage]
            for d in describe["stages"][st]}
    core |= {k + "_UNIT" for k in core}
    names = {p.name() for p in alg.parameterDefinitions()} | \
        {o.name() for o in alg.outputDefinitions()}
    for name in sorted(names - core):
        assert name in OTHER_FLAGS[stage], "%s: %s is not documented here" % (stage, name)
        flag = OTHER_FLAGS[stage][name]
        if flag is None:
            continue
        assert flag in help_text, "%s: %s not in 'terrasynth %s --help'" % (name, flag, stage)
        if flag not in IRREGULAR_FLAGS:
            assert flag == "--" + name.lower().replace("_", "-")


@pytest.mark.parametrize("stage", sorted({st for _, st in ALG_STAGES}))
def test_fallback_tables_match_describe(stage, describe):
    """The built-in tables (used when no terrasynth is found) equal `describe` for every
    stage an algorithm exposes; the core may have stages QGIS does not show yet."""
    from terrasynth_qgis import descriptors

    fallback = descriptors.FALLBACK
    assert fallback["version"] == describe["version"]
    descs = describe["stages"][stage]
    assert [d["name"] for d in fallback["stages"][stage]] == [d["name"] for d in descs]
    for want, got in zip(descs, fallback["stages"][stage]):
        assert got == want, ("qgis_processing/describe.json is stale (%s.%s): cmake --build build "
                             "--target qgis_describe_json" % (stage, want["name"]))


def test_fallback_jobs_match_describe(describe):
    """The jobs' options and rules in describe.json are the executable's too."""
    from terrasynth_qgis import descriptors

    assert descriptors.FALLBACK["jobs"] == describe["jobs"], (
        "qgis_processing/describe.json is stale: cmake --build build --target qgis_describe_json")


def test_fallback_is_used_without_a_cli(monkeypatch, tmp_path):
    from terrasynth_qgis import descriptors, runner
    from terrasynth_qgis.provider import TerraSynthProvider

    monkeypatch.setattr(runner, "find_cli", lambda: (_ for _ in ()).throw(
        runner.QgsProcessingException("terrasynth: not found")))
    try:
        TerraSynthProvider().loadDescriptors()
        assert descriptors.source() == "fallback"
        assert descriptors.stage("ppa") == descriptors.FALLBACK["stages"]["ppa"]
        synth = registry().algorithmById("terrasynth:synth").create()  # fallback tables
        for key in ("PATCH_SIZE", "MODE", "ALPHA_D", "ALPHA_F"):
            assert synth.parameterDefinition(key) is not None, key
    finally:
        monkeypatch.undo()
        TerraSynthProvider().loadDescriptors()
    assert descriptors.source().startswith("describe ")


def test_metadata(cli):
    from terrasynth_qgis import runner

    import configparser

    meta = configparser.ConfigParser()
    meta.read(os.path.join(runner.PLUGIN_DIR, "metadata.txt"))
    g = meta["general"]
    assert g["hasProcessingProvider"] == "yes"
    assert g["qgisMinimumVersion"] == "3.22"
    assert g["licence"] == "GPL-2.0-or-later"
    version = subprocess.run([cli, "--version"], capture_output=True, text=True).stdout.split()[1]
    assert g["version"] == version


# --------------------------------------------------------------------------- command lines (not run)

def build(alg_id, params):
    alg = registry().createAlgorithmById(alg_id)
    context = QgsProcessingContext()
    ok, msg = alg.checkParameterValues(params, context)
    assert ok, msg
    argv, job = alg.buildCommand(params, context, cli="/x/terrasynth")
    assert isinstance(argv, list) and all(isinstance(a, str) for a in argv)
    return argv, job


def pairs(argv):
    out = {}
    for i, a in enumerate(argv):
        if a.startswith("--") and i + 1 < len(argv) and not argv[i + 1].startswith("--"):
            out.setdefault(a, argv[i + 1])
    return out


def test_ppa_command_line(jacksboro, tmp_path):
    out, lines = str(tmp_path / "axes.tif"), str(tmp_path / "axes.gpkg")
    argv, job = build("terrasynth:ppa", {
        "INPUT": jacksboro, "FEATURES": 1, "PROFILE_LENGTH": 15, "THRESHOLD": 5,
        "MIN_BRANCH_LENGTH": 600, "MIN_BRANCH_LENGTH_UNIT": 1, "BAND": 1,
        "OUTPUT": out, "LINES": lines})
    assert argv[:2] == ["/x/terrasynth", "ppa"]
    assert argv[-2:] == [jacksboro, out]
    kv = pairs(argv)
    assert kv["--features"] == "valleys" and kv["--profile-length"] == "15"
    assert kv["--threshold"] == "5" and "--threshold-fraction" not in argv
    assert kv["--min-branch-length"] == "600m" and kv["--lines"] == lines
    assert "--progress-lines" in argv and "--preview" not in argv
    assert job["results"]["LINES"] == lines + "|layername=paths"
    assert job["results"]["NODES"] == lines + "|layername=nodes"
    assert os.listdir(tmp_path) == []  # nothing was run


def test_synth_command_line_with_crs_origin_resolution(jacksboro, tmp_path):
    out = str(tmp_path / "new.tif")
    argv, _ = build("terrasynth:synth", {
        "EXEMPLARS": [jacksboro, jacksboro], "WIDTH": 200, "HEIGHT": 100,
        "CRS": "EPSG:32616", "ORIGIN_X": 500000, "ORIGIN_Y": 4000000.5, "RESOLUTION": 90,
        "PATCH_SIZE": 48, "OVERLAP": 12, "ORDER": 1, "SEED": 7, "OUTPUT": out,
        "DEBUG_DIR": str(tmp_path / "dbg")})
    assert argv[:2] == ["/x/terrasynth", "synth"] and argv[-1] == out
    assert argv.count("--exemplar") == 2
    kv = pairs(argv)
    assert kv["--size"] == "200x100" and kv["--crs"] == "EPSG:32616"
    assert kv["--origin"] == "500000,4000000.5" and kv["--resolution"] == "90"
    assert kv["--order"] == "raster" and kv["--seed"] == "7"
    assert kv["--debug-dir"] == str(tmp_path / "dbg")
    assert "--like" not in argv


def test_synth_command_line_extent(jacksboro, tmp_path):
    """EXTENT + PIXEL_SIZE as QGIS's own raster creators lay a grid: from the top-left corner,
    rounded up to cover the extent; the CRS is the extent's unless CRS is given."""
    out = str(tmp_path / "n.tif")
    argv, _ = build("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "EXTENT": "500000,506010,4000000,4003000 [EPSG:32616]",
        "PIXEL_SIZE": 30, "OUTPUT": out})
    kv = pairs(argv)
    # 6010 / 30 = 200.33 -> 201 columns; 3000 / 30 = exactly 100 rows
    assert kv["--size"] == "201x100" and kv["--origin"] == "500000,4003000"
    assert kv["--resolution"] == "30" and kv["--crs"] == "EPSG:32616"
    assert "--like" not in argv
    # with CRS, the extent is taken into it (a lon/lat box into UTM 16N)
    argv, _ = build("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "EXTENT": "-87.01,-86.99,36.99,37.01 [EPSG:4326]",
        "CRS": "EPSG:32616", "PIXEL_SIZE": 100, "OUTPUT": out})
    kv = pairs(argv)
    w, h = (int(v) for v in kv["--size"].split("x"))
    x0, y0 = (float(v) for v in kv["--origin"].split(","))
    assert kv["--crs"] == "EPSG:32616" and kv["--resolution"] == "100"
    assert 17 <= w <= 20 and 22 <= h <= 25  # about 1.8 km x 2.2 km
    assert 497000 < x0 < 499500 and 4095000 < y0 < 4097500
    # an extent with no CRS of its own: the first exemplar's CRS
    argv, _ = build("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "EXTENT": "0,640,0,480", "PIXEL_SIZE": 10, "OUTPUT": out})
    kv = pairs(argv)
    assert kv["--size"] == "64x48" and kv["--origin"] == "0,480" and "--crs" not in argv
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("params,want", [
    ({"EXTENT": "0,640,0,480"}, "EXTENT needs PIXEL_SIZE"),
    ({"PIXEL_SIZE": 10, "WIDTH": 64, "HEIGHT": 64}, "PIXEL_SIZE goes with EXTENT"),
    ({"EXTENT": "0,640,0,480", "PIXEL_SIZE": 10, "WIDTH": 64, "HEIGHT": 64},
     "EXTENT sets the output grid: give no WIDTH/HEIGHT with it"),
    ({"EXTENT": "0,640,0,480", "PIXEL_SIZE": 10, "LIKE": "JACKSBORO"},
     "EXTENT sets the output grid: give no LIKE with it"),
    ({"EXTENT": "0,640,0,480", "PIXEL_SIZE": 10, "RESOLUTION": 10},
     "EXTENT sets the output grid: give no RESOLUTION with it"),
    ({"EXTENT": "0,640000000,0,480", "PIXEL_SIZE": 1}, "more than 65536 on a side"),
    ({"EXTENT": "5,5,0,480", "PIXEL_SIZE": 1}, "EXTENT: the area is empty"),
])
def test_synth_extent_form_errors(jacksboro, tmp_path, params, want):
    params = {k: (jacksboro if v == "JACKSBORO" else v) for k, v in params.items()}
    params.update(EXEMPLARS=[jacksboro], OUTPUT=str(tmp_path / "n.tif"))
    alg = registry().createAlgorithmById("terrasynth:synth")
    ok, msg = alg.checkParameterValues(params, QgsProcessingContext())
    assert not ok and want in msg
    with pytest.raises(QgsProcessingException, match=want):
        processing_run("terrasynth:synth", params)
    assert os.listdir(tmp_path) == []


def test_synth_command_line_like(jacksboro, tmp_path):
    argv, _ = build("terrasynth:synth", {"EXEMPLARS": [jacksboro], "LIKE": jacksboro,
                                         "OUTPUT": str(tmp_path / "n.tif")})
    assert pairs(argv)["--like"] == jacksboro
    assert "--size" not in argv and "--origin" not in argv
    # the sketch table's parameters go to the program only with a sketch
    assert not {"--sketch", "--mode", "--alpha-d", "--alpha-f"} & set(argv)


def test_synth_command_line_with_sketch(jacksboro, lambda_ridges, tmp_path):
    out = str(tmp_path / "new.tif")
    argv, job = build("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "SKETCH": lambda_ridges, "MODE": 1, "ALPHA_D": 250.5,
        "ALPHA_F": 0, "ALPHA_S": 2, "ALPHA_R": 0, "ORDER": 2, "PATCH_SIZE": 32, "OVERLAP": 8, "SEED": 5, "OUTPUT": out})
    assert argv[:2] == ["/x/terrasynth", "synth"] and argv[-1] == out
    kv = pairs(argv)
    assert kv["--sketch"] == lambda_ridges and argv.count("--sketch") == 1
    assert kv["--exemplar"] == jacksboro
    assert kv["--mode"] == "valleys" and kv["--alpha-d"] == "250.5" and kv["--alpha-f"] == "0"
    assert kv["--alpha-s"] == "2" and kv["--alpha-r"] == "0"
    assert kv["--order"] == "tree" and kv["--patch-size"] == "32" and kv["--seed"] == "5"
    for grid_flag in ("--like", "--size", "--origin", "--resolution", "--crs"):
        assert grid_flag not in argv
    assert job["results"] == {"OUTPUT": out}
    # defaults are passed explicitly too
    argv, _ = build("terrasynth:synth", {"EXEMPLARS": [jacksboro], "SKETCH": lambda_ridges,
                                         "OUTPUT": out})
    kv = pairs(argv)
    assert (kv["--mode"], kv["--alpha-d"], kv["--alpha-f"]) == ("auto", "1000", "3")
    assert (kv["--alpha-s"], kv["--alpha-r"]) == ("0", "0.5")
    # patch size and overlap in metres on the ground
    argv, _ = build("terrasynth:synth", {"EXEMPLARS": [jacksboro], "SKETCH": lambda_ridges,
                                         "PATCH_SIZE": 5000, "PATCH_SIZE_UNIT": 1,
                                         "OVERLAP": 1200, "OVERLAP_UNIT": 1, "OUTPUT": out})
    kv = pairs(argv)
    assert (kv["--patch-size"], kv["--overlap"]) == ("5000m", "1200m")
    assert "--size" not in argv and "--like" not in argv
    assert os.listdir(tmp_path) == []  # nothing was run


def line_sketch(path):
    """A GeoPackage of lines on the Jacksboro grid (EPSG:4326): a ridge and a valley, with a
    field "what" for the kinds and "alt" for heights."""
    from osgeo import ogr, osr
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    lyr = ds.CreateLayer("strokes", srs, ogr.wkbLineString)
    lyr.CreateField(ogr.FieldDefn("what", ogr.OFTString))
    lyr.CreateField(ogr.FieldDefn("alt", ogr.OFTReal))
    for kind, wkt, alt in (("ridge", "LINESTRING (-84.40 36.30, -84.25 36.33, -84.10 36.30)", 900),
                           ("valley", "LINESTRING (-84.35 36.20, -84.20 36.25, -84.09 36.19)",
                            None)):
        f = ogr.Feature(lyr.GetLayerDefn())
        f.SetField("what", kind)
        if alt is not None:
            f.SetField("alt", alt)
        f.SetGeometry(ogr.CreateGeometryFromWkt(wkt))
        lyr.CreateFeature(f)
    ds = None
    return str(path)


def test_synth_sketch_of_lines(jacksboro, tmp_path):
    """SKETCH_LINES with its fields and the grid of LIKE, or of PIXEL_SIZE alone, or EXTENT at
    PIXEL_SIZE; the run follows the lines (the ridge higher than beside it)."""
    lines = line_sketch(tmp_path / "lines.gpkg")
    out = str(tmp_path / "o.tif")
    argv, _ = build("terrasynth:synth", {"EXEMPLARS": [jacksboro], "SKETCH_LINES": lines,
                                         "KIND_FIELD": "what", "HEIGHT_FIELD": "alt",
                                         "LIKE": jacksboro, "OUTPUT": out})
    kv = pairs(argv)
    assert kv["--sketch"] == lines and kv["--kind-field"] == "what"
    assert kv["--height-field"] == "alt" and kv["--like"] == jacksboro
    argv, _ = build("terrasynth:synth", {"EXEMPLARS": [jacksboro], "SKETCH_LINES": lines,
                                         "KIND_FIELD": "what", "PIXEL_SIZE": 0.001,
                                         "OUTPUT": out})
    kv = pairs(argv)
    assert kv["--resolution"] == "0.001" and "--extent" not in kv and "--size" not in kv
    argv, _ = build("terrasynth:synth", {"EXEMPLARS": [jacksboro], "SKETCH_LINES": lines,
                                         "KIND_FIELD": "what", "PIXEL_SIZE": 0.001,
                                         "EXTENT": "-84.45,-84.05,36.15,36.40 [EPSG:4326]",
                                         "OUTPUT": out})
    kv = pairs(argv)
    assert [float(v) for v in kv["--extent"].split(",")] == [-84.45, 36.15, -84.05, 36.40]
    assert kv["--crs"] == "EPSG:4326"
    alg = registry().createAlgorithmById("terrasynth:synth")
    ok, msg = alg.checkParameterValues({"EXEMPLARS": [jacksboro], "SKETCH_LINES": lines,
                                        "KIND_FIELD": "what", "OUTPUT": out},
                                       QgsProcessingContext())
    assert not ok and "needs the output grid" in msg
    res = processing_run("terrasynth:synth", {"EXEMPLARS": [jacksboro], "SKETCH_LINES": lines,
                                              "KIND_FIELD": "what", "LIKE": jacksboro,
                                              "SEED": 2, "OUTPUT": out})
    import numpy as np
    from osgeo import gdal
    z = gdal.Open(res["OUTPUT"]).ReadAsArray().astype(float)
    ds = gdal.Open(jacksboro)
    gt = ds.GetGeoTransform()
    col = lambda lon: int((lon - gt[0]) / gt[1])  # noqa: E731
    row = lambda lat: int((lat - gt[3]) / gt[5])  # noqa: E731
    ridge = z[row(36.33), col(-84.25)]
    beside = np.mean([z[row(36.33) + 25, col(-84.25)], z[row(36.33) - 25, col(-84.25)]])
    assert ridge > beside


@pytest.mark.parametrize("params,want", [
    ({"LIKE": "JACKSBORO"}, "a painted sketch sets the output grid: give no like"),
    ({"WIDTH": 64, "HEIGHT": 64}, "a sketch sets the output grid: give no size"),
    ({"WIDTH": 64}, "give both WIDTH and HEIGHT, or neither"),
    ({"ORIGIN_X": 0, "ORIGIN_Y": 0}, "a sketch sets the output grid: give no origin"),
    ({"RESOLUTION": 30}, "a painted sketch sets the output grid: give no resolution"),
    ({"CRS": "EPSG:32616"}, "a painted sketch sets the output grid: give no crs"),
    ({"LIKE": "JACKSBORO", "WIDTH": 64, "HEIGHT": 64, "ORIGIN_X": 0, "ORIGIN_Y": 0,
      "RESOLUTION": 30, "CRS": "EPSG:32616"}, "a painted sketch sets the output grid: give no like"),
])
def test_synth_sketch_excludes_other_grids(jacksboro, lambda_ridges, tmp_path, params, want):
    """The dialog checks the job's rules (from describe) with the program's own messages."""
    params = {k: (jacksboro if v == "JACKSBORO" else v) for k, v in params.items()}
    params.update(EXEMPLARS=[jacksboro], SKETCH=lambda_ridges, OUTPUT=str(tmp_path / "n.tif"))
    alg = registry().createAlgorithmById("terrasynth:synth")
    ok, msg = alg.checkParameterValues(params, QgsProcessingContext())  # the dialog's check
    assert (ok, msg) == (False, want)
    with pytest.raises(QgsProcessingException) as e:
        processing_run("terrasynth:synth", params)
    assert want in str(e.value.args[0])
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("params,message", [
    ({}, "give the target grid: a sketch, like or size"),
    ({"WIDTH": 64}, "WIDTH and HEIGHT"),
    ({"LIKE": "JACKSBORO", "WIDTH": 64, "HEIGHT": 64}, "like sets the output grid: give no size"),
    ({"WIDTH": 64, "HEIGHT": 64, "ORIGIN_X": 0}, "ORIGIN_Y"),
    ({"WIDTH": 64, "HEIGHT": 64, "CRS": "EPSG:32616"}, "a CRS needs an origin and a resolution"),
    ({"WIDTH": 64, "HEIGHT": 64, "PATCH_SIZE": 32, "OVERLAP": 32}, "overlap"),
])
def test_synth_bad_parameter_combinations(jacksboro, tmp_path, params, message):
    params = {k: (jacksboro if v == "JACKSBORO" else v) for k, v in params.items()}
    params.update(EXEMPLARS=[jacksboro], OUTPUT=str(tmp_path / "n.tif"))
    with pytest.raises(QgsProcessingException, match=message):
        processing_run("terrasynth:synth", params)
    assert os.listdir(tmp_path) == []


def test_ppa_both_thresholds_refused(jacksboro, tmp_path):
    with pytest.raises(QgsProcessingException,
                       match="give threshold or threshold_fraction, not both"):
        processing_run("terrasynth:ppa", {"INPUT": jacksboro, "THRESHOLD": 5,
                                          "THRESHOLD_FRACTION": 0.01,
                                          "OUTPUT": str(tmp_path / "a.tif")})


# --------------------------------------------------------------------------- constraints

def values_of(argv, flag):
    return [argv[i + 1] for i, a in enumerate(argv) if a == flag]


def test_synth_constraint_parameters_are_advanced():
    from qgis.core import QgsProcessingParameterDefinition as Def

    alg = registry().algorithmById("terrasynth:synth")
    for key in ("PINS", "WATER_MASK", "WATER_LEVEL", "REGIONS", "REGION_EXEMPLARS", "HEIGHTS",
                "ALPHA_H"):
        p = alg.parameterDefinition(key)
        assert p is not None, key
        assert p.flags() & Def.FlagAdvanced, key
        assert key == "ALPHA_H" or p.flags() & Def.FlagOptional, key  # ALPHA_H has a default
    assert alg.parameterDefinition("ALPHA_H").defaultValue() == 1
    assert alg.parameterDefinition("ALPHA_H").minimum() == 0
    assert "<h3>Constraints</h3>" in alg.shortHelpString()
    for flag in ("--pin", "--water", "--regions", "--region-exemplar", "--heights", "--alpha-h"):
        assert flag in alg.shortHelpString(), flag


def test_synth_command_line_pins(jacksboro, tmp_path):
    out = str(tmp_path / "n.tif")
    base = {"EXEMPLARS": [jacksboro], "WIDTH": 64, "HEIGHT": 64, "OUTPUT": out}
    argv, _ = build("terrasynth:synth", dict(base, PINS="%s:1,2,30,40@5,6\n"
                                             " C:/dem b.tif:0,0,8,8@0,0 ;; /x/y.tif:3,4,5,6@7,8"
                                             % jacksboro))
    # one pin a line or between ';', passed as typed: the program reads and checks them
    assert values_of(argv, "--pin") == ["%s:1,2,30,40@5,6" % jacksboro,
                                        "C:/dem b.tif:0,0,8,8@0,0", "/x/y.tif:3,4,5,6@7,8"]
    assert argv[-1] == out
    argv, _ = build("terrasynth:synth", dict(base, PINS="  "))
    assert "--pin" not in argv
    assert not {"--water", "--water-level", "--regions", "--region-exemplar", "--heights",
                "--alpha-h"} & set(argv)


def test_synth_command_line_water_regions_heights(jacksboro, tmp_path):
    regions = tmp_path / "regions.tif"
    gdal.Translate(str(regions), jacksboro, outputType=gdal.GDT_Int16)
    argv, _ = build("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "WIDTH": 64, "HEIGHT": 64, "OUTPUT": str(tmp_path / "n.tif"),
        "WATER_MASK": jacksboro, "WATER_LEVEL": 250.5, "REGIONS": str(regions),
        "REGION_EXEMPLARS": "1=/d/a.tif; 2=/d/b c.tif\n-3=/d/a.tif", "HEIGHTS": jacksboro,
        "ALPHA_H": 0.25})
    kv = pairs(argv)
    assert kv["--water"] == jacksboro and kv["--water-level"] == "250.5"
    assert kv["--regions"] == str(regions)
    assert values_of(argv, "--region-exemplar") == ["1=/d/a.tif", "2=/d/b c.tif", "-3=/d/a.tif"]
    assert kv["--heights"] == jacksboro and kv["--alpha-h"] == "0.25"
    # ALPHA_H defaults to 1 and goes only with HEIGHTS; a water level of 0 counts
    argv, _ = build("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "WIDTH": 64, "HEIGHT": 64, "OUTPUT": str(tmp_path / "n.tif"),
        "HEIGHTS": jacksboro, "WATER_MASK": jacksboro, "WATER_LEVEL": 0})
    kv = pairs(argv)
    assert kv["--alpha-h"] == "1" and kv["--water-level"] == "0"
    # ALPHA_H at its default without HEIGHTS is not passed; changed, it is refused as on
    # the command line (a weight that weighs nothing)
    argv, _ = build("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "WIDTH": 64, "HEIGHT": 64, "OUTPUT": str(tmp_path / "n.tif"),
        "ALPHA_H": 1})
    assert "--alpha-h" not in argv and "--heights" not in argv
    alg = registry().createAlgorithmById("terrasynth:synth")
    ok, msg = alg.checkParameterValues({
        "EXEMPLARS": [jacksboro], "WIDTH": 64, "HEIGHT": 64, "OUTPUT": str(tmp_path / "n.tif"),
        "ALPHA_H": 3}, QgsProcessingContext())
    assert not ok and msg == "alpha_h weighs heights: give heights"


def polygon_regions(path, field_type):
    from osgeo import ogr

    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    lyr = ds.CreateLayer("zones", srs, ogr.wkbPolygon)
    lyr.CreateField(ogr.FieldDefn("region", field_type))
    f = ogr.Feature(lyr.GetLayerDefn())
    f.SetField("region", 1 if field_type != ogr.OFTString else "one")
    f.SetGeometry(ogr.CreateGeometryFromWkt(
        "POLYGON((-84.4 36.4,-84.3 36.4,-84.3 36.3,-84.4 36.3,-84.4 36.4))"))
    lyr.CreateFeature(f)
    ds = None
    return str(path)


def test_synth_command_line_polygon_regions(jacksboro, tmp_path):
    from osgeo import ogr

    gpkg = polygon_regions(tmp_path / "zones.gpkg", ogr.OFTInteger)
    params = {"EXEMPLARS": [jacksboro], "WIDTH": 64, "HEIGHT": 64,
              "OUTPUT": str(tmp_path / "n.tif"), "REGION_EXEMPLARS": "1=%s" % jacksboro}
    argv, _ = build("terrasynth:synth", dict(params, REGIONS=gpkg))
    assert pairs(argv)["--regions"] == gpkg
    layer = QgsVectorLayer(gpkg + "|layername=zones", "zones", "ogr")
    assert layer.isValid()
    argv, _ = build("terrasynth:synth", dict(params, REGIONS=layer))  # a loaded layer
    assert pairs(argv)["--regions"] == gpkg
    bad = polygon_regions(tmp_path / "text.gpkg", ogr.OFTString)
    alg = registry().createAlgorithmById("terrasynth:synth")
    ok, msg = alg.checkParameterValues(dict(params, REGIONS=bad), QgsProcessingContext())
    assert not ok and "integer field 'region'" in msg


@pytest.mark.parametrize("params,message", [
    ({"WATER_MASK": "JACKSBORO"}, "water and water_level go together"),
    ({"WATER_LEVEL": 100}, "water and water_level go together"),
    ({"REGIONS": "JACKSBORO"}, "regions and region_exemplar go together"),
    ({"REGION_EXEMPLARS": "1=a.tif"}, "regions and region_exemplar go together"),
    # the program's own messages (the dialog asks it: terrasynth synth ... --check)
    ({"REGIONS": "JACKSBORO", "REGION_EXEMPLARS": "one=a.tif"},
     "region_exemplar takes ID=FILE, not 'one=a.tif'"),
    ({"REGIONS": "JACKSBORO", "REGION_EXEMPLARS": "1=a.tif;1=b.tif"},
     "region_exemplar: region 1 is given twice"),
    ({"PINS": "JACKSBORO:1,2,3@4,5"}, "pin takes FILE:XOFF,YOFF,W,H@X,Y"),
    ({"PINS": "JACKSBORO:1,2,3,4"}, "pin takes FILE:XOFF,YOFF,W,H@X,Y"),
    ({"PINS": "1,2,3,4@5,6"}, "pin takes FILE:XOFF,YOFF,W,H@X,Y"),
    ({"PINS": "JACKSBORO:-1,2,3,4@5,6"}, "pin takes FILE:XOFF,YOFF,W,H@X,Y"),
    ({"PINS": "JACKSBORO:1,2,0,4@5,6"}, "pin takes FILE:XOFF,YOFF,W,H@X,Y"),
    ({"PINS": ";".join(["JACKSBORO:0,0,4,4@0,0"] * 17)}, "pin: at most 16"),
])
def test_synth_constraint_errors(jacksboro, tmp_path, params, message):
    params = {k: (v.replace("JACKSBORO", jacksboro) if isinstance(v, str) else v)
              for k, v in params.items()}
    params.update(EXEMPLARS=[jacksboro], WIDTH=64, HEIGHT=64, OUTPUT=str(tmp_path / "n.tif"))
    alg = registry().createAlgorithmById("terrasynth:synth")
    ok, msg = alg.checkParameterValues(params, QgsProcessingContext())  # the dialog's check
    assert not ok and message in msg
    with pytest.raises(QgsProcessingException, match=message.replace("(", r"\(")):
        processing_run("terrasynth:synth", params)
    assert os.listdir(tmp_path) == []


def test_synth_run_with_water_and_pin(jacksboro, cli, tmp_path):
    """The water cells keep the level; the pinned window is the exemplar's, unchanged."""
    import numpy as np

    # A copy of the DEM with square 30 m cells in UTM 16N: on the geographic original the
    # CLI resamples the pinned window like an exemplar (ground cells are not square there),
    # so it would not be bit-identical.
    exemplar = str(tmp_path / "jacksboro_utm.tif")
    gdal.Translate(exemplar, jacksboro, outputSRS="EPSG:32616",
                   outputBounds=[500000, 4000000, 500000 + 403 * 30, 4000000 - 344 * 30])
    # the output grid of --size: the exemplar's CRS, origin and resolution
    ex = gdal.Open(exemplar)
    mask_path = tmp_path / "water.tif"
    mask = gdal.GetDriverByName("GTiff").Create(str(mask_path), 128, 128, 1, gdal.GDT_Byte)
    mask.SetGeoTransform(ex.GetGeoTransform())
    mask.SetProjection(ex.GetProjection())
    water = np.zeros((128, 128), np.uint8)
    water[100:, :] = 1
    water[:20, 90:] = 1
    mask.GetRasterBand(1).WriteArray(water)
    mask = None
    level = 300.0
    xoff, yoff, w, h, x, y = 150, 120, 40, 30, 10, 40
    out = tmp_path / "constrained.tif"
    res = processing_run("terrasynth:synth", {
        "EXEMPLARS": [exemplar], "WIDTH": 128, "HEIGHT": 128, "PATCH_SIZE": 32,
        "OVERLAP": 8, "SEED": 2, "WATER_MASK": str(mask_path), "WATER_LEVEL": level,
        "PINS": "%s:%d,%d,%d,%d@%d,%d" % (exemplar, xoff, yoff, w, h, x, y),
        "OUTPUT": str(out)})
    assert res["OUTPUT"] == str(out)
    ds = gdal.Open(str(out))
    assert (ds.RasterXSize, ds.RasterYSize) == (128, 128)
    assert ds.GetGeoTransform() == pytest.approx(ex.GetGeoTransform())
    z = ds.GetRasterBand(1).ReadAsArray()
    assert (z != -9999).all()
    assert (z[water != 0] == level).all()
    window = ex.GetRasterBand(1).ReadAsArray(xoff, yoff, w, h).astype(np.float32)
    assert np.array_equal(z[y:y + h, x:x + w], window)
    assert z[water == 0].std() > 10  # the rest was synthesized


# --------------------------------------------------------------------------- finding the CLI

def test_processing_setting_wins(cli, tmp_path, monkeypatch):
    from terrasynth_qgis import runner

    fake = tmp_path / "my_terrasynth"
    fake.write_text("#!/bin/sh\nexit 0\n")
    fake.chmod(0o755)
    monkeypatch.setenv("TERRASYNTH", cli)
    s = QgsSettings()
    s.setValue(runner.SETTINGS_KEY, str(fake))
    try:
        assert runner.find_cli() == str(fake)
    finally:
        s.remove(runner.SETTINGS_KEY)
    assert runner.find_cli() == cli


def test_processing_setting_is_registered():
    from processing.core.ProcessingConfig import ProcessingConfig

    from terrasynth_qgis import runner

    assert runner.SETTING_NAME in ProcessingConfig.settings
    assert ProcessingConfig.settings[runner.SETTING_NAME].group == "TerraSynth"


def test_missing_cli_is_a_clear_error(jacksboro, tmp_path, monkeypatch):
    monkeypatch.setenv("TERRASYNTH", str(tmp_path / "no_such_terrasynth"))
    with pytest.raises(QgsProcessingException, match="not an executable file"):
        processing_run("terrasynth:ppa", {"INPUT": jacksboro, "OUTPUT": str(tmp_path / "a.tif")})


# --------------------------------------------------------------------------- end to end

def test_ppa_run(jacksboro, cli, tmp_path):
    out, lines, preview = tmp_path / "axes.tif", tmp_path / "axes.gpkg", tmp_path / "axes.png"
    res = processing_run("terrasynth:ppa", {
        "INPUT": jacksboro, "FEATURES": 2, "OUTPUT": str(out), "LINES": str(lines),
        "PREVIEW": str(preview)})
    assert res["OUTPUT"] == str(out)
    ds, srs = raster_info(out)
    ds_in, srs_in = raster_info(jacksboro)
    assert srs is not None and srs.IsSame(srs_in)
    assert (ds.RasterXSize, ds.RasterYSize) == (ds_in.RasterXSize, ds_in.RasterYSize)
    assert ds.GetGeoTransform() == pytest.approx(ds_in.GetGeoTransform())
    values = set(ds.GetRasterBand(1).ReadAsArray().ravel().tolist())
    assert {1, 2} <= values <= {0, 1, 2, 3, 255}
    assert res["LINES"] == str(lines) + "|layername=paths"
    assert res["NODES"] == str(lines) + "|layername=nodes"
    paths = QgsVectorLayer(res["LINES"], "paths", "ogr")
    nodes = QgsVectorLayer(res["NODES"], "nodes", "ogr")
    assert paths.isValid() and nodes.isValid()
    assert paths.geometryType() == QgsWkbTypes.LineGeometry and paths.featureCount() > 50
    assert nodes.geometryType() == QgsWkbTypes.PointGeometry and nodes.featureCount() > 50
    assert paths.crs() == QgsRasterLayer(jacksboro, "in").crs()
    assert {f["kind"] for f in paths.getFeatures()} == {"ridge", "valley"}
    assert preview.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".")]  # no temporary files


def test_ppa_loads_paths_and_nodes_layers(jacksboro, cli, tmp_path):
    """The GUI route: LINES loads as two layers, 'paths' and 'nodes'."""
    import processing

    project = QgsProject.instance()
    project.removeAllMapLayers()
    lines = str(tmp_path / "l.gpkg")
    processing.runAndLoadResults("terrasynth:ppa", {
        "INPUT": jacksboro, "OUTPUT": str(tmp_path / "a.tif"), "LINES": lines})
    sources = sorted(layer.source() for layer in project.mapLayers().values())
    project.removeAllMapLayers()
    assert any(s.endswith("a.tif") for s in sources)
    assert any(s.startswith(lines) and "layername=paths" in s for s in sources)
    assert any(s.startswith(lines) and "layername=nodes" in s for s in sources)
    assert len(sources) == 3


def test_streams_of_any_job(jacksboro, cli, tmp_path):
    """FLOW_LINES on a job: the command line carries the threshold, the streams load as a
    line layer with their Strahler order, on the DEM's CRS."""
    flow = str(tmp_path / "streams.gpkg")
    params = {"INPUT": jacksboro, "FEATURES": 1, "OUTPUT": str(tmp_path / "a.tif"),
              "FLOW_LINES": flow, "FLOW_KM2": 0.5}
    argv, job = build("terrasynth:ppa", params)
    kv = pairs(argv)
    assert kv["--flow-lines"] == flow and kv["--flow-km2"] == "0.5"
    assert "--flow-cells" not in argv and job["results"]["FLOW_LINES"] == flow
    res = processing_run("terrasynth:ppa", params)
    streams = QgsVectorLayer(res["FLOW_LINES"], "streams", "ogr")
    assert streams.isValid() and streams.geometryType() == QgsWkbTypes.LineGeometry
    assert streams.featureCount() > 10
    assert streams.crs() == QgsRasterLayer(jacksboro, "in").crs()
    orders = {f["strahler"] for f in streams.getFeatures()}
    assert 1 in orders and max(orders) >= 3
    assert min(f["area_km2"] for f in streams.getFeatures()) >= 0.49


def test_synth_run(jacksboro, cli, tmp_path):
    out, preview, dbg = tmp_path / "new.tif", tmp_path / "new.png", tmp_path / "dbg"
    res = processing_run("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "WIDTH": 128, "HEIGHT": 128, "PATCH_SIZE": 32,
        "OVERLAP": 8, "SEED": 3, "OUTPUT": str(out), "PREVIEW": str(preview),
        "DEBUG_DIR": str(dbg)})
    assert res["OUTPUT"] == str(out) and res["DEBUG_DIR"] == str(dbg)
    ds, srs = raster_info(out)
    _, srs_in = raster_info(jacksboro)
    assert srs is not None and srs.IsSame(srs_in)
    assert (ds.RasterXSize, ds.RasterYSize) == (128, 128)
    band = ds.GetRasterBand(1)
    assert band.DataType == gdal.GDT_Float32 and band.GetNoDataValue() == -9999
    z = band.ReadAsArray()
    assert (z != -9999).all()
    assert 150 < z.min() < z.max() < 1200 and z.std() > 10  # heights in the exemplar's range
    assert preview.exists()
    assert {"seams.tif", "source_exemplar.tif", "source_x.tif", "source_y.tif",
            "order.tif"} <= set(os.listdir(dbg))


def test_synth_sketch_run(jacksboro, lambda_ridges, cli, tmp_path):
    """Sketch-guided: the output is on the sketch's grid (size, CRS, geotransform)."""
    out = tmp_path / "sk.tif"
    res = processing_run("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "SKETCH": lambda_ridges, "MODE": 0, "PATCH_SIZE": 32,
        "OVERLAP": 8, "SEED": 1, "OUTPUT": str(out)})
    assert res["OUTPUT"] == str(out)
    ds, srs = raster_info(out)
    sk, srs_sk = raster_info(lambda_ridges)
    assert srs is not None and srs.IsSame(srs_sk)
    assert (ds.RasterXSize, ds.RasterYSize) == (sk.RasterXSize, sk.RasterYSize)
    assert ds.GetGeoTransform() == pytest.approx(sk.GetGeoTransform(), rel=1e-12, abs=1e-12)
    band = ds.GetRasterBand(1)
    assert band.DataType == gdal.GDT_Float32 and band.GetNoDataValue() == -9999
    z = band.ReadAsArray()
    valid = z[z != -9999]
    assert valid.size > 0.9 * z.size  # the sketch has no nodata
    # heights near the exemplar's 236..1076 m (Poisson seam removal may overshoot a little)
    assert 0 < valid.min() < valid.max() < 2000 and valid.std() > 10
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".")]  # no temporary files


def test_synth_like_grid(jacksboro, cli, tmp_path):
    like = tmp_path / "grid.tif"
    ds_in = gdal.Open(jacksboro)
    gt = list(ds_in.GetGeoTransform())
    gt[0] += 0.01
    drv = gdal.GetDriverByName("GTiff")
    t = drv.Create(str(like), 72, 56, 1, gdal.GDT_Byte)
    t.SetGeoTransform(gt)
    t.SetProjection(ds_in.GetProjection())
    t = None
    out = tmp_path / "new.tif"
    processing_run("terrasynth:synth", {"EXEMPLARS": [jacksboro], "LIKE": str(like),
                                        "PATCH_SIZE": 24, "OVERLAP": 6, "OUTPUT": str(out)})
    ds, _ = raster_info(out)
    assert (ds.RasterXSize, ds.RasterYSize) == (72, 56)
    assert ds.GetGeoTransform() == pytest.approx(tuple(gt))


def test_synth_extent_grid(jacksboro, cli, tmp_path):
    """The output covers the extent, from its top-left corner, in its CRS (read back with GDAL,
    not with our code)."""
    out = tmp_path / "new.tif"
    processing_run("terrasynth:synth", {
        "EXEMPLARS": [jacksboro], "EXTENT": "600000,603610,4100000,4102400 [EPSG:32616]",
        "PIXEL_SIZE": 50, "PATCH_SIZE": 24, "OVERLAP": 6, "OUTPUT": str(out)})
    ds, _ = raster_info(out)
    assert (ds.RasterXSize, ds.RasterYSize) == (73, 48)  # 3610/50 = 72.2 -> 73; 2400/50 = 48
    assert ds.GetGeoTransform() == pytest.approx((600000, 50, 0, 4102400, 0, -50))
    srs = osr.SpatialReference(wkt=ds.GetProjection())
    srs.AutoIdentifyEPSG()
    assert srs.GetAuthorityCode(None) == "32616"


def test_amplify_command_line_and_run(jacksboro, cli, tmp_path):
    out, png = tmp_path / "fine.tif", tmp_path / "fine.png"
    params = {"INPUT": jacksboro, "EXEMPLARS": [jacksboro], "FACTOR": 2, "PATCH": 8,
              "W_U": 0, "OUTPUT": str(out), "PREVIEW": str(png)}
    argv, _ = build("terrasynth:amplify", params)
    assert argv[:2] == ["/x/terrasynth", "amplify"] and argv[-2:] == [jacksboro, str(out)]
    kv = pairs(argv)
    assert kv["--exemplar"] == jacksboro and kv["--factor"] == "2" and kv["--patch"] == "8"
    assert kv["--w-u"] == "0" and kv["--preview"] == str(png)
    res = processing_run("terrasynth:amplify", params)
    assert res["OUTPUT"] == str(out) and res["PREVIEW"] == str(png)
    ds, src = gdal.Open(str(out)), gdal.Open(jacksboro)
    assert (ds.RasterXSize, ds.RasterYSize) == (2 * src.RasterXSize, 2 * src.RasterYSize)
    gt, sg = ds.GetGeoTransform(), src.GetGeoTransform()
    assert gt == pytest.approx((sg[0], sg[1] / 2, 0, sg[3], 0, sg[5] / 2))


def test_amplify_layers_and_classes(jacksboro, cli, tmp_path):
    """The exemplars' classes and a layer, wanted classes, the carried layer and the classes
    out: the same flags as the command line, and the files written."""
    src = gdal.Open(jacksboro)
    z = src.ReadAsArray().astype(np.float64)
    for name, a in (("cl.tif", np.where(z > np.median(z), 2, 1)), ("veg.tif", z / z.max()),
                    ("want.tif", np.full(z.shape, 2))):
        d = gdal.GetDriverByName("GTiff").Create(str(tmp_path / name), z.shape[1], z.shape[0],
                                                 1, gdal.GDT_Float32)
        d.SetGeoTransform(src.GetGeoTransform())
        d.SetProjection(src.GetProjection())
        d.GetRasterBand(1).WriteArray(a.astype(np.float32))
        d = None
    out, lay, cls = tmp_path / "o.tif", tmp_path / "veg_out.tif", tmp_path / "cls_out.tif"
    params = {"INPUT": jacksboro, "EXEMPLARS": [jacksboro], "FACTOR": 2,
              "EXEMPLAR_CLASSES": [str(tmp_path / "cl.tif")],
              "EXEMPLAR_LAYERS": "veg=%s\n" % (tmp_path / "veg.tif"),
              "CLASSES": str(tmp_path / "want.tif"), "W_C": 2.0,
              "OUT_LAYER_NAME": "veg", "OUT_LAYER": str(lay), "OUT_CLASSES": str(cls),
              "OUTPUT": str(out)}
    argv, _ = build("terrasynth:amplify", params)
    kv = pairs(argv)
    assert kv["--exemplar-classes"] == str(tmp_path / "cl.tif")
    assert kv["--exemplar-layer"] == "veg=%s" % (tmp_path / "veg.tif")
    assert kv["--out-layer"] == "veg=%s" % lay and kv["--out-classes"] == str(cls)
    assert kv["--classes"] == str(tmp_path / "want.tif") and kv["--w-c"] == "2"
    res = processing_run("terrasynth:amplify", params)
    assert res["OUT_LAYER"] == str(lay) and res["OUT_CLASSES"] == str(cls)
    c = gdal.Open(str(cls)).ReadAsArray()
    assert c.shape == (2 * z.shape[0], 2 * z.shape[1]) and np.mean(c == 2) > 0.9


# --------------------------------------------------------------------------- cancel

class CancelAfterFirstProgress(QgsProcessingFeedback):
    """Says it is canceled once the first progress report has arrived."""

    def __init__(self):
        super().__init__()
        self.reports = []

    def setProgress(self, progress):  # noqa: N802
        self.reports.append(progress)
        super().setProgress(progress)

    def isCanceled(self):  # noqa: N802
        return bool(self.reports) or super().isCanceled()


def test_cancel_ppa_leaves_no_file(jacksboro, cli, tmp_path):
    fb = CancelAfterFirstProgress()
    with pytest.raises(QgsProcessingException, match="canceled"):
        processing_run("terrasynth:ppa", {
            "INPUT": jacksboro, "FEATURES": 2, "OUTPUT": str(tmp_path / "a.tif"),
            "LINES": str(tmp_path / "a.gpkg"), "PREVIEW": str(tmp_path / "a.png")}, fb)
    assert len(fb.reports) == 1
    assert os.listdir(tmp_path) == []


def test_cancel_synth_leaves_no_file(jacksboro, cli, tmp_path):
    fb = CancelAfterFirstProgress()
    with pytest.raises(QgsProcessingException, match="canceled"):
        processing_run("terrasynth:synth", {
            "EXEMPLARS": [jacksboro], "WIDTH": 384, "HEIGHT": 384, "PATCH_SIZE": 32,
            "OVERLAP": 8, "OUTPUT": str(tmp_path / "n.tif"), "PREVIEW": str(tmp_path / "n.png"),
            "DEBUG_DIR": str(tmp_path / "dbg")}, fb)
    assert len(fb.reports) == 1 and fb.reports[0] < 100
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------- errors

def cli_message(cli, *args):
    p = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
    assert p.returncode != 0
    return p.stderr.strip().splitlines()[-1]


def test_cli_error_message_reaches_qgis(jacksboro, cli, tmp_path):
    out = tmp_path / "a.tif"
    with pytest.raises(QgsProcessingException) as e:
        processing_run("terrasynth:ppa", {"INPUT": jacksboro, "BAND": 5, "OUTPUT": str(out)})
    want = cli_message(cli, "ppa", jacksboro, out, "--band", "5", "-q")
    assert want == "terrasynth: %s: band 5 does not exist (the file has 1 band)" % jacksboro
    assert str(e.value.args[0]) == want
    assert os.listdir(tmp_path) == []


def test_synth_small_exemplar_message(jacksboro, cli, tmp_path):
    small = tmp_path / "small.tif"
    gdal.Translate(str(small), jacksboro, srcWin=[0, 0, 20, 20])
    with pytest.raises(QgsProcessingException, match="smaller than a patch") as e:
        processing_run("terrasynth:synth", {"EXEMPLARS": [str(small)], "WIDTH": 64,
                                            "HEIGHT": 64, "PATCH_SIZE": 32, "OVERLAP": 8,
                                            "OUTPUT": str(tmp_path / "n.tif")})
    assert str(e.value.args[0]).startswith("terrasynth: %s: " % small)
    assert sorted(os.listdir(tmp_path)) == ["small.tif"]


def test_text_file_as_input(cli, tmp_path):
    """QGIS itself refuses a text file as a raster layer; the CLI says why if reached."""
    txt = tmp_path / "notes.txt"
    txt.write_text("this is not a DEM\n")
    with pytest.raises(QgsProcessingException, match="INPUT"):
        processing_run("terrasynth:ppa", {"INPUT": str(txt), "OUTPUT": str(tmp_path / "a.tif")})
    from terrasynth_qgis import runner

    with pytest.raises(QgsProcessingException) as e:
        runner.run([cli, "ppa", str(txt), str(tmp_path / "a.tif"), "--progress-lines"])
    assert e.value.args[0] == "terrasynth: %s: not a raster GDAL can open" % txt
    assert sorted(os.listdir(tmp_path)) == ["notes.txt"]


def test_missing_input_file(cli, tmp_path):
    with pytest.raises(QgsProcessingException, match="INPUT"):
        processing_run("terrasynth:ppa", {"INPUT": str(tmp_path / "missing.tif"),
                                          "OUTPUT": str(tmp_path / "a.tif")})
    assert os.listdir(tmp_path) == []


def test_synth_help_lists_every_sketch_parameter():
    """The help names every sketch parameter the core declares."""
    from terrasynth_qgis import descriptors

    text = registry().algorithmById("terrasynth:synth").shortHelpString()
    for d in descriptors.stage("sketch"):
        assert "<b>%s</b>" % d["name"].upper() in text, d["name"]
    # the patch ranges come from the core's declarations, not from the help's own text
    for name in ("patch_size", "overlap"):
        d = descriptors.param("synth", name)
        assert "%g..%g cells, default %g" % (d["min"], d["max"], d["default"]) in text
    assert "{" not in text
    lo, hi = descriptors.option_range("synth", "size", None)
    alg = registry().algorithmById("terrasynth:synth")
    assert alg.parameterDefinition("WIDTH").maximum() == hi
    assert alg.parameterDefinition("HEIGHT").minimum() == lo


def test_amplify_dictionary_and_biomes(jacksboro, cli, tmp_path):
    """A dictionary file, or biomes (WEIGHTS=DICTIONARY lines): the same flags as the
    command line; exemplars and a dictionary together are refused before anything runs."""
    d = tmp_path / "j.tsd"
    res = 45.0
    subprocess.run([cli, "dictionary", "build", str(d), "--exemplar", jacksboro,
                    "--resolution", str(res), "--factor", "2", "-q"], check=True)
    w = tmp_path / "w.tif"
    gdal.Translate(str(w), jacksboro, outputType=gdal.GDT_Float32)
    params = {"INPUT": jacksboro, "BIOMES": "%s=%s\n%s=%s" % (w, d, w, d),
              "OUTPUT": str(tmp_path / "o.tif")}
    argv, _ = build("terrasynth:amplify", params)
    assert argv.count("--biome") == 2 and "%s=%s" % (w, d) in argv
    argv, _ = build("terrasynth:amplify", {"INPUT": jacksboro, "DICTIONARY": str(d),
                                           "OUTPUT": str(tmp_path / "o.tif")})
    assert pairs(argv)["--dictionary"] == str(d)
    with pytest.raises(Exception, match="give at least one exemplar, or a dictionary, or biomes"):
        build("terrasynth:amplify", {"INPUT": jacksboro, "DICTIONARY": str(d),
                                     "EXEMPLARS": [jacksboro], "OUTPUT": str(tmp_path / "o.tif")})


def test_pixel_command_line_and_run(jacksboro, cli, tmp_path):
    """terrasynth:pixel: the same flags as the command line; a run writes the terrain on the
    guide's grid; a grid must be given once."""
    out = tmp_path / "p.tif"
    guide = tmp_path / "g.tif"
    gdal.Translate(str(guide), jacksboro, srcWin=[0, 0, 120, 100], outputType=gdal.GDT_Float32)
    params = {"EXEMPLARS": [jacksboro], "GUIDE": str(guide), "SEED": 4, "PASSES": 1,
              "OUTPUT": str(out)}
    argv, _ = build("terrasynth:pixel", params)
    kv = pairs(argv)
    assert argv[:2] == ["/x/terrasynth", "pixel"] and argv[-1] == str(out)
    assert kv["--guide"] == str(guide) and kv["--seed"] == "4" and kv["--passes"] == "1"
    res = processing_run("terrasynth:pixel", params)
    assert res["OUTPUT"] == str(out)
    ds = gdal.Open(str(out))
    assert (ds.RasterXSize, ds.RasterYSize) == (120, 100)
    with pytest.raises(Exception, match="give the target grid"):
        build("terrasynth:pixel", {"EXEMPLARS": [jacksboro], "OUTPUT": str(out)})
