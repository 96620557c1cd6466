# SPDX-License-Identifier: GPL-2.0-or-later
"""The core's parameter descriptor tables, as `terrasynth describe` prints them.

The provider reads them from the executable when it loads (runner.describe) so
the QGIS parameters always carry the core's names, defaults and ranges; FALLBACK
is used when no executable is found.  tests/qgis compares FALLBACK with
`terrasynth describe`, so it cannot drift unnoticed.

A descriptor is a dict: name, flag, type (int | double | enum | length),
default, min, max, units, choices (list or None), help, and for a length
default_unit ("cells" or "m").  The QGIS parameter key is name.upper().
"""
import copy

FALLBACK = {
    "version": "0.1.0",
    "stages": {
        "ppa": [
            {"name": "features", "flag": "--features", "type": "enum", "default": 0,
             "min": 0, "max": 2, "units": "", "choices": ["ridges", "valleys", "both"],
             "help": "Which axes to extract."},
            {"name": "profile_length", "flag": "--profile-length", "type": "int",
             "default": 11, "min": 3, "max": 1001, "units": "cells", "choices": None,
             "help": "Length of the four profiles through each cell (odd); a target must "
                     "dip on both sides within half of it."},
            {"name": "threshold", "flag": "--threshold", "type": "double", "default": 0,
             "min": 0, "max": 1000000, "units": "elevation units", "choices": None,
             "help": "Minimum dip on both sides of a profile, in elevation units (metres "
                     "after unit conversion)."},
            {"name": "threshold_fraction", "flag": "--threshold-fraction", "type": "double",
             "default": 0.0025, "min": 0, "max": 1, "units": "fraction", "choices": None,
             "help": "Minimum dip as a fraction of the DEM's elevation range; the larger of "
                     "the two thresholds applies."},
            {"name": "min_branch_length", "flag": "--min-branch-length", "type": "length",
             "default": 40, "min": 0, "max": 10000000, "default_unit": "cells",
             "units": "cells or m", "choices": None,
             "help": "Branches shorter than this are removed (branch reduction); a plain "
                     "number is cells, a number with suffix m is metres."},
        ],
        "synth": [
            {"name": "patch_size", "flag": "--patch-size", "type": "length", "default": 64,
             "min": 8, "max": 1024, "default_unit": "cells", "units": "cells or m",
             "choices": None,
             "help": "Side of the square patches copied from the exemplars: a whole number of "
                     "cells, or a number with suffix m for metres (turned into cells at the "
                     "output grid's ground resolution; 8..1024 cells either way)."},
            {"name": "overlap", "flag": "--overlap", "type": "length", "default": 16, "min": 2,
             "max": 512, "default_unit": "cells", "units": "cells or m", "choices": None,
             "help": "Width shared by neighbouring patches, where seams are cut and smoothed: "
                     "cells, or metres with suffix m; smaller than the patch."},
            {"name": "candidates", "flag": "--candidates", "type": "int", "default": 6,
             "min": 1, "max": 256, "units": "", "choices": None,
             "help": "Best SSD matches examined per patch position (k)."},
            {"name": "order", "flag": "--order", "type": "enum", "default": 0, "min": 0,
             "max": 2, "units": "", "choices": ["grow", "raster", "tree"],
             "help": "Placement order: grow out from what is filled (with a sketch: its "
                     "feature tree breadth first), raster scan, or tree (= grow)."},
            {"name": "alpha_g", "flag": "--alpha-g", "type": "double", "default": 1, "min": 0,
             "max": 1000000, "units": "", "choices": None,
             "help": "Weight of the graph-cut seam cost against the SSD when choosing a "
                     "candidate."},
            {"name": "variety", "flag": "--variety", "type": "double", "default": 0.1,
             "min": 0, "max": 10, "units": "fraction", "choices": None,
             "help": "Pick at random (seeded) among candidates whose cost is within this "
                     "fraction of the best."},
            {"name": "coarse_factor", "flag": "--coarse-factor", "type": "int", "default": 0,
             "min": 0, "max": 16, "units": "", "choices": None,
             "help": "Search on exemplars downsampled by this factor, then refine at full "
                     "resolution (1 = exhaustive full-resolution search; 0 = automatic: "
                     "exemplars brought to at most 512 x 512 cells)."},
        ],
        "sketch": [
            {"name": "mode", "flag": "--mode", "type": "enum", "default": 2, "min": 0,
             "max": 2, "units": "", "choices": ["ridges", "valleys", "auto"],
             "help": "What the sketch draws: ridges (bright strokes), valleys (dark strokes), "
                     "or auto."},
            {"name": "alpha_d", "flag": "--alpha-d", "type": "double", "default": 1000,
             "min": 0, "max": 1000000000, "units": "", "choices": None,
             "help": "Weight of the warp deformation cost c_d of feature patches."},
            {"name": "alpha_f", "flag": "--alpha-f", "type": "double", "default": 3,
             "min": 0, "max": 1000000000, "units": "", "choices": None,
             "help": "Weight of the feature profile dissimilarity c_f of feature patches."},
            {"name": "alpha_s", "flag": "--alpha-s", "type": "double", "default": 0,
             "min": 0, "max": 1000000000, "units": "", "choices": None,
             "help": "Weight of the path smoothness constraint c_s: crest (valleys: thalweg) "
                     "heights along the sketch's strokes bend less, within a feature patch and "
                     "where it joins the placed ones; larger gives smoother, gentler crests "
                     "(0 = off)."},
            {"name": "alpha_p", "flag": "--alpha-p", "type": "double", "default": 1,
             "min": 0, "max": 1000000000, "units": "", "choices": None,
             "help": "Weight of the crest prominence c_p of feature patches: among the "
                     "candidates that fit, those whose crest (valleys: thalweg) stands out most "
                     "across the stroke, an eighth of a patch either side, so that sketched "
                     "strokes read as main features (0 = off)."},
            {"name": "alpha_r", "flag": "--alpha-r", "type": "double", "default": 0.5,
             "min": 0, "max": 1000000000, "units": "", "choices": None,
             "help": "Weight of the relief guide: sketched ridges stand high and sketched "
                     "valleys lie low, falling away from the strokes as the exemplars' land "
                     "falls away from their main features (0 = off: the exemplars alone decide "
                     "the heights)."},
            {"name": "layout", "flag": "--layout", "type": "double", "default": 1,
             "min": 0, "max": 1, "units": "fraction", "choices": None,
             "help": "How far the sketch sets the large-scale relief (scales above a third of "
                     "a patch): the land rises to sketched ridges and falls to sketched valleys "
                     "as steeply, at that scale, as the exemplars' land; smaller scales keep the "
                     "patches' detail (0 = off)."},
        ],
    },
}

# Descriptor types the plugin knows how to show; others are skipped (and logged).
KNOWN_TYPES = ("int", "double", "enum", "length")

_current = {"source": "fallback", "tables": FALLBACK}


def set_tables(tables, source):
    """Install the tables (from `describe`, or FALLBACK) used by new algorithm instances."""
    _current["tables"] = tables
    _current["source"] = source


def source():
    """'describe <path>' or 'fallback': where the current tables came from."""
    return _current["source"]


def stage(name):
    """The descriptors of one stage (a deep copy), [] if the core has no such stage."""
    return copy.deepcopy(_current["tables"].get("stages", {}).get(name, []))


def key(descriptor_or_name):
    """QGIS parameter key of a descriptor: profile_length -> PROFILE_LENGTH."""
    name = descriptor_or_name if isinstance(descriptor_or_name, str) else descriptor_or_name["name"]
    return name.upper()


def unit_key(descriptor):
    """Companion unit parameter of a length descriptor: MIN_BRANCH_LENGTH_UNIT."""
    return key(descriptor) + "_UNIT"


LENGTH_UNITS = ["cells", "metres"]  # enum options of a *_UNIT parameter; "metres" -> suffix m


def validate(tables):
    """Raise ValueError unless `tables` looks like `terrasynth describe` output."""
    if not isinstance(tables, dict) or not isinstance(tables.get("stages"), dict):
        raise ValueError("no 'stages' object")
    for st, descs in tables["stages"].items():
        if not isinstance(descs, list):
            raise ValueError("stage %s: not a list" % st)
        for d in descs:
            for field in ("name", "flag", "type", "default", "min", "max", "help"):
                if field not in d:
                    raise ValueError("stage %s: a descriptor has no '%s'" % (st, field))
            if d["type"] == "enum" and not d.get("choices"):
                raise ValueError("stage %s: enum %s has no choices" % (st, d["name"]))
    return tables


def current_version():
    """Version of the core the current tables describe."""
    return _current["tables"].get("version", "")
