# SPDX-License-Identifier: GPL-2.0-or-later
"""The core's parameter descriptor tables, as `terrasynth describe` prints them.

The provider reads them from the executable when it loads (runner.describe) so
the QGIS parameters always carry the core's names, defaults and ranges; FALLBACK
(describe.json, written by the build) is used when no executable is found.
tests/qgis compares it with `terrasynth describe`, so it cannot drift unnoticed.
The "jobs" member gives each job's options (their limits) and rules, "common" the options
every command takes; the rules are checked by the program itself (runner.check).

A descriptor is a dict: name, flag, type (int | double | enum | length),
default, min, max, units, choices (list or None), help, and for a length
default_unit ("cells" or "m").  The QGIS parameter key is name.upper().
"""
import copy
import json
import os

# `terrasynth describe` as the build wrote it (describe.json, next to this file): used when no
# executable is found.  Never edited by hand: `cmake --build build --target qgis_describe_json`
# writes it, and tests/qgis checks that it equals what the executable prints.
DESCRIBE_JSON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "describe.json")


def _load_fallback():
    try:
        with open(DESCRIBE_JSON, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return {"version": "", "stages": {}, "jobs": {}}


FALLBACK = _load_fallback()

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


def job(name):
    """A job's options and rules ({} when the tables have none)."""
    return copy.deepcopy(_current["tables"].get("jobs", {}).get(name, {}))


def max_count(job_name, option, default):
    """How often an option of a job may be given (e.g. 64 exemplars)."""
    for o in job(job_name).get("options", []):
        if o.get("name") == option:
            return int(o.get("max_count", default))
    return default


def option_range(job_name, option, default):
    """(min, max) of a numeric option of a job (e.g. size: 1..65536 cells)."""
    for o in job(job_name).get("options", []):
        if o.get("name") == option and "max" in o:
            return o.get("min", 1), o["max"]
    return default


def param(stage_name, name):
    """One descriptor of a stage by name, or None."""
    for d in stage(stage_name):
        if d["name"] == name:
            return d
    return None


def job_option(job_name, name):
    """An option of a job as `terrasynth describe` declares it (kind, min, max, max_count,
    help, ...), or {}."""
    for o in job(job_name).get("options", []):
        if o.get("name") == name:
            return o
    return {}


def common(name):
    """An option every command takes (threads, ...), as `terrasynth describe` declares it,
    or {}."""
    for o in _current["tables"].get("common", []):
        if o.get("name") == name:
            return o
    return {}
