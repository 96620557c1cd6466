# SPDX-License-Identifier: GPL-2.0-or-later
"""The manuals' parameter tables against the declarations (`terrasynth describe`): every
option of a job and every parameter of its stages has a row in its manual (a line of the
PARAMETERS table starting with its flag), and every parameter's row gives the declared
default.  A parameter added to the core or an option to a job fails here until the manual
says it."""
import json
import os
import re
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import ROOT, run  # noqa: E402

DOCS = os.path.join(ROOT, "algorithms", "docs")
# manual -> (job, stages whose parameters it documents)
MANUALS = {"ppa.md": ("ppa", ["ppa"]), "synth.md": ("synth", ["synth"]),
           "sketch.md": (None, ["sketch"])}
# options documented in another manual (with the reason)
ELSEWHERE = {("synth", o): "sketch.md" for o in ("sketch", "sketch_layer", "kind_field",
                                                "height_field", "snap", "extent")}


@pytest.fixture(scope="module")
def describe():
    return json.loads(run("describe").stdout)


def rows(manual):
    """{flag: the row's cells} for the table rows that start with a flag."""
    out = {}
    with open(os.path.join(DOCS, manual), encoding="utf-8") as f:
        for line in f:
            if not line.startswith("| `-"):
                continue
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            for flag in re.findall(r"(--[a-z][a-z-]*)", cells[0]):
                out.setdefault(flag, cells)
    return out


def default_text(d):
    if d["type"] == "enum":
        return d["choices"][int(d["default"])]
    return "%g" % d["default"]


@pytest.mark.parametrize("manual", sorted(MANUALS))
def test_every_option_and_parameter_has_a_row(describe, manual):
    job, stages = MANUALS[manual]
    table = rows(manual)
    missing = []
    if job:
        for o in describe["jobs"][job]["options"]:
            if o["positional"]:
                continue
            where = ELSEWHERE.get((job, o["name"]), manual)
            if o["flag"] not in rows(where):
                missing.append(o["flag"])
    for st in stages:
        for d in describe["stages"][st]:
            if d["flag"] not in table:
                missing.append(d["flag"])
                continue
            shown = table[d["flag"]][1].split()[0] if table[d["flag"]][1] else ""
            assert shown == default_text(d), "%s: %s says %r, the core %r" % (
                manual, d["flag"], shown, default_text(d))
    assert not missing, "%s has no row for %s" % (manual, ", ".join(missing))
