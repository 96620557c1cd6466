# SPDX-License-Identifier: GPL-2.0-or-later
"""What a job writes, as tsjob writes it for every front end (gdal_driver/tsjob.c): no
output is ever one of the inputs (compared by identity: a link, or another spelling of
the path, is refused too), a refused job writes nothing and leaves the input as it was,
and the debug folder holds every map, georeferenced like the output."""
import hashlib
import os
import shutil
import sys

import pytest
from osgeo import gdal

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tsutil import JACKSBORO, run  # noqa: E402

gdal.UseExceptions()


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


@pytest.fixture
def dem(tmp_path):
    p = tmp_path / "dem.tif"
    shutil.copy(JACKSBORO, p)
    return p


def spellings(tmp_path, dem):
    """The input itself, another spelling of its path, and a symbolic link to it."""
    link = tmp_path / "link.tif"
    os.symlink(dem, link)
    other = tmp_path / "sub" / ".." / dem.name
    (tmp_path / "sub").mkdir()
    return [str(dem), str(other), str(link)]


@pytest.mark.parametrize("which", [0, 1, 2], ids=["same", "spelled", "link"])
def test_ppa_never_writes_over_its_input(tmp_path, dem, which):
    before = digest(dem)
    target = spellings(tmp_path, dem)[which]
    for args in ([dem, target], [dem, tmp_path / "o.tif", "--lines", target],
                 [dem, tmp_path / "o.tif", "--preview", target]):
        p = run("ppa", *args, "-q", check=False)
        assert p.returncode != 0
        assert "an output never overwrites an input" in p.stderr, p.stderr
        assert digest(dem) == before
        assert not (tmp_path / "o.tif").exists()


@pytest.mark.parametrize("which", [0, 2], ids=["same", "link"])
def test_synth_never_writes_over_an_input(tmp_path, dem, which):
    before = digest(dem)
    target = spellings(tmp_path, dem)[which]
    for args in (["--exemplar", dem, "--size", "80x80", target],
                 ["--exemplar", JACKSBORO, "--like", dem, tmp_path / "o.tif", "--preview",
                  target]):
        p = run("synth", *args, "-q", check=False)
        assert p.returncode != 0
        assert "an output never overwrites an input" in p.stderr, p.stderr
        assert digest(dem) == before
        assert not (tmp_path / "o.tif").exists()


def test_debug_folder_is_an_input_map(tmp_path, dem):
    """An input named like a debug map in the debug folder is refused before the work."""
    dbg = tmp_path / "dbg"
    dbg.mkdir()
    shutil.copy(dem, dbg / "seams.tif")
    before = digest(dbg / "seams.tif")
    p = run("synth", "--exemplar", dbg / "seams.tif", "--size", "80x80", tmp_path / "o.tif",
            "--debug-dir", dbg, "-q", check=False)
    assert p.returncode != 0 and "an output never overwrites an input" in p.stderr
    assert digest(dbg / "seams.tif") == before
    assert not (tmp_path / "o.tif").exists()


def test_debug_maps_and_preview(tmp_path, dem):
    dbg = tmp_path / "dbg"  # created by the job
    out, png = tmp_path / "o.tif", tmp_path / "o.png"
    run("synth", "--exemplar", dem, "--size", "96x80", "--seed", "3", out, "--preview", png,
        "--debug-dir", dbg, "-q")
    o = gdal.Open(str(out))
    assert gdal.Open(str(png)).RasterCount == 3
    for name in ("seams", "source_exemplar", "source_x", "source_y", "order"):
        m = gdal.Open(str(dbg / (name + ".tif")))
        assert (m.RasterXSize, m.RasterYSize) == (96, 80)
        assert m.GetGeoTransform() == o.GetGeoTransform()
    ex = gdal.Open(str(dbg / "source_exemplar.tif")).ReadAsArray()
    sx = gdal.Open(str(dbg / "source_x.tif")).ReadAsArray()
    src = gdal.Open(str(dem))
    # independent check: every source column lies inside the exemplar, exemplar index 0
    assert set(ex[ex >= 0].astype(int).ravel()) == {0}
    assert sx[sx >= 0].max() < src.RasterXSize


def test_debug_dir_that_is_a_file(tmp_path, dem):
    f = tmp_path / "notadir"
    f.write_text("x")
    p = run("synth", "--exemplar", dem, "--size", "80x80", tmp_path / "o.tif", "--debug-dir", f,
            "-q", check=False)
    assert p.returncode != 0 and "exists and is not a folder" in p.stderr
    assert not (tmp_path / "o.tif").exists()
