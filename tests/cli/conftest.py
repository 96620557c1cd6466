# SPDX-License-Identifier: GPL-2.0-or-later
"""tests/tsutil.py (where things are, running terrasynth) importable by these tests; the
`matrix` marker."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "matrix: one behaviour over many cases; under the sanitizers "
        "(TS_SANITIZED=1) only the first case runs")


def pytest_collection_modifyitems(config, items):
    """Under the sanitizers each matrix test keeps its first case (the others run the
    same code on other data, in the normal build)."""
    if os.environ.get("TS_SANITIZED", "0") != "1":
        return
    seen, keep, drop = set(), [], []
    for item in items:
        if item.get_closest_marker("matrix") is None:
            keep.append(item)
            continue
        key = (item.fspath, item.originalname)
        (drop if key in seen else keep).append(item)
        seen.add(key)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep
