# SPDX-License-Identifier: GPL-2.0-or-later
"""Elevations no terrain has: never quiet garbage.  A float's extreme
value (+-3.4e38, a nodata nobody declared) is read as nodata with a warning; any other
value outside the Earth's -12000..9000 m is refused, naming the file and the first cell."""
import os
import sys

import numpy as np
import pytest
from osgeo import gdal, osr

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import JACKSBORO, run  # noqa: E402

gdal.UseExceptions()
F32_MIN = float(np.finfo(np.float32).min)


def dem_with(tmp_path, name, fill, unit=None):
    src = gdal.Open(JACKSBORO)
    z = src.ReadAsArray().astype(np.float32)
    fill(z)
    p = tmp_path / name
    ds = gdal.GetDriverByName("GTiff").Create(str(p), z.shape[1], z.shape[0], 1,
                                              gdal.GDT_Float32)
    ds.SetGeoTransform(src.GetGeoTransform())
    ds.SetProjection(src.GetProjection())
    if unit:
        ds.GetRasterBand(1).SetUnitType(unit)
    ds.GetRasterBand(1).WriteArray(z)
    ds = None
    return p


def block_1e30(z):
    z[100:104, 200:204] = 1e30


def corner_fmin(z):
    z[:30, :40] = F32_MIN


@pytest.mark.parametrize("job", ["ppa", "synth"])
def test_implausible_block_refused(tmp_path, job):
    dem = dem_with(tmp_path, "bad.tif", block_1e30)
    args = [dem, tmp_path / "o.tif"] if job == "ppa" else \
        ["--exemplar", dem, "--size", "64x64", tmp_path / "o.tif"]
    p = run(job, *args, "-q", check=False)
    assert p.returncode == 1
    assert "bad.tif: 16 cells hold elevations no terrain has (1e+30 m at column 200, row 100" \
        in p.stderr, p.stderr
    assert not (tmp_path / "o.tif").exists()


def test_undeclared_float_minimum_is_nodata_with_a_warning(tmp_path):
    dem = dem_with(tmp_path, "corner.tif", corner_fmin)
    p = run("ppa", dem, tmp_path / "p.tif", "--both", "-q")
    assert "warning: " in p.stderr and "1200 cells of +-3.4e38" in p.stderr, p.stderr
    codes = gdal.Open(str(tmp_path / "p.tif")).ReadAsArray()
    assert (codes[:30, :40] == 255).all()          # nodata where the sentinel was
    assert ((codes == 1) | (codes == 2)).sum() > 100  # the rest mapped as usual
    # a baseline threshold, not one of 1e27 m
    out = run("ppa", dem, tmp_path / "p2.tif").stdout
    thr = float(out.split("threshold ")[1].split(" m")[0])
    assert 0 < thr < 100, out


def test_undeclared_float_minimum_in_an_exemplar(tmp_path):
    """The issue's case: 8,737 output cells of exactly 0, a value absent from the input."""
    dem = dem_with(tmp_path, "corner.tif", corner_fmin)
    p = run("synth", "--exemplar", dem, "--size", "160x160", "--seed", "2", tmp_path / "s.tif",
            "-q")
    assert "1200 cells of +-3.4e38" in p.stderr
    z = gdal.Open(str(tmp_path / "s.tif")).ReadAsArray()
    valid = z[z != -9999]
    assert valid.size == z.size
    # within the real DEM's 236..1076 m, with a margin for Poisson seam removal
    assert 100 < valid.min() and valid.max() < 1300


def test_feet_are_checked_after_units(tmp_path):
    """29 000 ft (8 839 m, about Everest) is plausible once in metres."""
    def feet(z):
        z *= 3.28084
        z[5, 5] = 29000
    dem = dem_with(tmp_path, "ft.tif", feet, unit="ft")
    out = run("ppa", dem, tmp_path / "p.tif").stdout
    # read in metres: the automatic threshold is 0.25 % of the range in metres (feet would
    # give 3.3 times more)
    z = gdal.Open(str(dem)).ReadAsArray().astype(np.float64) * 0.3048
    want = 0.0025 * (np.nanmax(z) - np.nanmin(z))
    thr = float(out.split("threshold ")[1].split(" m")[0])
    assert abs(thr - want) < 0.01 * want, (thr, want, out)
