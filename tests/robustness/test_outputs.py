# SPDX-License-Identifier: GPL-2.0-or-later
"""What a job writes, as tsjob writes it for every front end (gdal_driver/jobs/): no
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


# ------------------------------------------------------------------ nothing lost

def listing(d):
    """Every file under d with its content's digest (the directory's state)."""
    out = {}
    for root, dirs, files in os.walk(d):
        for name in dirs + files:
            p = os.path.join(root, name)
            out[os.path.relpath(p, d)] = None if os.path.isdir(p) else digest(p)
    return out


def test_two_outputs_never_the_same_file(tmp_path, dem):
    """The DEM output replaced by its own PNG, a debug map over the output: refused."""
    before = listing(tmp_path)
    for cmd in (["ppa", dem, tmp_path / "p.tif", "--preview", tmp_path / "p.tif"],
                ["ppa", dem, tmp_path / "p.tif", "--lines", tmp_path / "sub" / ".." / "p.tif"],
                ["synth", "--exemplar", dem, "--size", "64x64", tmp_path / "seams.tif",
                 "--debug-dir", tmp_path],
                ["synth", "--exemplar", dem, "--size", "64x64", tmp_path / "o.tif", "--preview",
                 tmp_path / "o.tif"]):
        (tmp_path / "sub").mkdir(exist_ok=True)
        p = run(*cmd, "-q", check=False)
        assert p.returncode == 1, (cmd, p.stderr)
        assert "each output needs its own file" in p.stderr, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1
        (tmp_path / "sub").rmdir()
        assert listing(tmp_path) == before


@pytest.mark.parametrize("job", ["ppa", "synth"])
def test_recipe_never_over_an_input(tmp_path, dem, job):
    before = digest(dem)
    link = tmp_path / "link.tif"
    os.symlink(dem, link)
    args = [dem] if job == "ppa" else ["--exemplar", dem, "--size", "64x64"]
    for target in (dem, link):
        p = run(job, *args, "--recipe", target, check=False)
        assert p.returncode != 0 and "an output never overwrites an input" in p.stderr
        assert digest(dem) == before


def test_special_files_are_not_replaced(tmp_path, dem):
    """A FIFO (or /dev/null, as root) is no output: refused at once, left as it was."""
    import stat

    fifo = tmp_path / "fifo.tif"
    os.mkfifo(fifo)
    for cmd in (["ppa", dem, fifo], ["synth", "--exemplar", dem, "--size", "64x64", fifo],
                ["ppa", dem, tmp_path / "o.tif", "--preview", fifo],
                ["ppa", dem, "--recipe", fifo]):
        p = run(*cmd, "-q", check=False)
        assert p.returncode == 1, (cmd, p.stderr)
        assert "is not a regular file" in p.stderr, p.stderr
        assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert sorted(os.listdir(tmp_path)) == ["dem.tif", "fifo.tif"]
    p = run("ppa", dem, "/dev/null", "-q", check=False)
    assert p.returncode == 1 and "is not a regular file" in p.stderr
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def run_with_file_limit(limit, *args, ignore_xfsz=True):
    """terrasynth with files capped at `limit` bytes (`ulimit -f`): a write that fails half
    way through the job.  With ignore_xfsz the parent ignores SIGXFSZ; without, the signal
    has its default action (a shell's `ulimit -f`), which the program must not die of."""
    import resource
    import signal
    import subprocess
    from tsutil import TERRASYNTH

    def cap():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN if ignore_xfsz else signal.SIG_DFL)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return subprocess.run([TERRASYNTH, *map(str, args)], capture_output=True, text=True,
                          timeout=600, preexec_fn=cap)


def test_a_failed_write_leaves_nothing(tmp_path, dem):
    """The DEM is written (140 kB), the lines or the preview (250 kB) fail: none is left,
    nor any temporary file; an earlier output of the same name is kept as it was."""
    out, png = tmp_path / "p.tif", tmp_path / "p.png"
    out.write_bytes(b"an earlier result")
    before = listing(tmp_path)
    p = run_with_file_limit(200_000, "ppa", dem, out, "--preview", png, "--lines",
                            tmp_path / "p.gpkg", "-q")
    assert p.returncode == 1, p.stderr
    assert ("p.png" in p.stderr or "p.gpkg" in p.stderr) and p.stderr.count("\n") == 1
    assert listing(tmp_path) == before
    # the same run without the cap writes all three
    run("ppa", dem, out, "--preview", png, "--lines", tmp_path / "p.gpkg", "-q")
    assert out.stat().st_size > 100_000 and png.exists() and (tmp_path / "p.gpkg").exists()


@pytest.mark.parametrize("job", ["synth", "dictionary"])
def test_a_file_size_limit_is_a_failed_write(tmp_path, dem, job):
    """Under `ulimit -f` (SIGXFSZ at its default, which kills a process that writes past
    the limit) the job fails in one line naming the file, exit 1, and leaves nothing."""
    if job == "synth":
        args = ["synth", "--exemplar", dem, "--size", "160x160", tmp_path / "o.tif", "-q"]
    else:
        args = ["dictionary", "build", tmp_path / "d.tsd", "--exemplar", dem, "--factor", 2,
                "--resolution", 60]
    p = run_with_file_limit(4_000, *args, ignore_xfsz=False)
    assert p.returncode == 1, (p.returncode, p.stderr)
    assert p.stderr.count("\n") == 1 and ("o.tif" in p.stderr or "d.tsd" in p.stderr), p.stderr
    assert sorted(os.listdir(tmp_path)) == ["dem.tif"]


def test_a_failed_synth_removes_the_debug_folder_it_made(tmp_path, dem):
    dbg = tmp_path / "dbg"
    p = run_with_file_limit(20_000, "synth", "--exemplar", dem, "--size", "96x96",
                            tmp_path / "o.tif", "--debug-dir", dbg, "-q")
    assert p.returncode == 1, p.stderr
    assert sorted(os.listdir(tmp_path)) == ["dem.tif"]


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_leaves_nothing(tmp_path, dem, sig):
    """Interrupted while it works: the folder it made is gone, no temporary file, it says
    so, and it dies by the signal (as a shell expects)."""
    import signal
    import subprocess
    import time
    from tsutil import TERRASYNTH

    dbg = tmp_path / "dbg"
    proc = subprocess.Popen([TERRASYNTH, "synth", "--exemplar", dem, "--size", "1500x1500",
                             tmp_path / "o.tif", "--debug-dir", dbg, "--preview",
                             tmp_path / "o.png", "--progress-lines"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # wait for the work to start (the folder exists once the outputs are checked)
    line = proc.stdout.readline()
    assert line.startswith("PROGRESS"), line + proc.stderr.read()
    assert dbg.is_dir()
    time.sleep(0.3)
    proc.send_signal(getattr(signal, sig))
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == -getattr(signal, sig), err
    assert "interrupted" in err and "nothing was written" in err, err
    assert sorted(os.listdir(tmp_path)) == ["dem.tif"]


def test_a_signal_while_writing_leaves_nothing(tmp_path, dem):
    """Interrupted while the output is being written (its temporary file exists): the
    handler removes it and the folder is as before."""
    import signal
    import subprocess
    import time
    from tsutil import TERRASYNTH

    before = listing(tmp_path)
    proc = subprocess.Popen([TERRASYNTH, "synth", "--exemplar", dem, "--size", "2500x2500",
                             tmp_path / "o.tif", "-co", "COMPRESS=DEFLATE", "-co", "ZLEVEL=9",
                             "-co", "PREDICTOR=3", "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = False
    deadline = time.monotonic() + 600
    while proc.poll() is None and time.monotonic() < deadline:
        if any(n.startswith(".o.tmp") for n in os.listdir(tmp_path)):
            seen = True
            proc.send_signal(signal.SIGINT)
            break
        time.sleep(0.002)
    _, err = proc.communicate(timeout=120)
    if not seen:
        pytest.skip("the write was over before it could be interrupted")
    assert proc.returncode == -signal.SIGINT, err
    import re
    assert re.search(r"interrupted: removed [1-9]\d* unfinished output file", err), err
    assert listing(tmp_path) == before


@pytest.mark.parametrize("length", [200, 250])
def test_long_names_are_written(tmp_path, dem, length):
    """A name of up to 255 bytes is a valid output: its temporary twin (.NAME.tmpPID.tif and
    GDAL's sidecars) must fit too, so a long stem is cut there, not refused after the work."""
    stem = "x" * (length - 4 - 100) + "é" * 50  # é is two bytes: cuts keep whole characters
    out = tmp_path / (stem + ".tif")
    assert len(os.fsencode(out.name)) == length
    run("synth", "--exemplar", dem, "--size", "64x64", "--seed", 1, out, "-q")
    assert gdal.Open(str(out)).RasterXSize == 64
    assert sorted(os.listdir(tmp_path)) == sorted(["dem.tif", out.name])  # nothing left
