# SPDX-License-Identifier: GPL-2.0-or-later
"""The soak: many mixed runs, 8 at a time, in one folder: ppa, synth, recipe reads
through gdal_translate, valid and invalid inputs picked at random (seeded).  No crash, no
sanitizer report, no temporary file left, and every valid output byte-identical to the same
command run alone.  TS_SOAK_RUNS sets the number of runs (default 200)."""
import hashlib
import os
import random
import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
TERRASYNTH = os.environ.get("TERRASYNTH", os.path.join(ROOT, "build", "gdal_driver", "terrasynth"))
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
DATA = os.environ.get("TS_DATA_DIR", os.path.join(ROOT, "data"))
RUNS = int(os.environ.get("TS_SOAK_RUNS", "200"))


def env():
    e = dict(os.environ, GDAL_DRIVER_PATH=PLUGINS)
    if os.environ.get("TS_TOOL_PRELOAD"):  # an instrumented plugin in a plain tool
        e.update(LD_PRELOAD=os.environ["TS_TOOL_PRELOAD"], ASAN_OPTIONS="detect_leaks=0")
    return e


# (kind, argv with {out}); "ok" ones write {out}, "bad" ones must fail and write nothing
VALID = [
    ["{ts}", "ppa", "dem.tif", "{out}", "-q"],
    ["{ts}", "ppa", "dem.tif", "{out}", "--both", "--profile-length", "9", "-q"],
    ["{ts}", "synth", "--exemplar", "dem.tif", "--size", "96x80", "--seed", "1", "{out}", "-q"],
    ["{ts}", "synth", "--exemplar", "dem.tif", "--size", "80x96", "--seed", "2",
     "--patch-size", "32", "--overlap", "8", "{out}", "-q"],
    ["{ts}", "synth", "--exemplar", "dem.tif", "--exemplar", "dem.tif", "--size", "96x96",
     "--seed", "3", "--threads", "1", "{out}", "-q"],
    ["{ts}", "synth", "--sketch", "small_sketch.tif", "--exemplar", "dem.tif", "--seed", "4",
     "--patch-size", "32", "--overlap", "8", "{out}", "-q"],
    ["gdal_translate", "-q", "synth.tsyn", "{out}"],
    ["gdal_translate", "-q", "-oo", "SEED=9", "synth.tsyn", "{out}"],
    ["gdal_translate", "-q", "ppa.tsyn", "{out}"],
]
INVALID = [
    ["{ts}", "ppa", "missing.tif", "{out}", "-q"],
    ["{ts}", "ppa", "dem.tif", "dem.tif", "-q"],
    ["{ts}", "synth", "--exemplar", "dem.tif", "--size", "64x64", "--seed", "-3", "{out}"],
    ["{ts}", "synth", "--exemplar", "dem.tif", "--size", "65536x65536", "{out}", "-q"],
    ["{ts}", "synth", "--exemplar", "text.tif", "--size", "64x64", "{out}", "-q"],
    ["{ts}", "synth", "--exemplar", "dem.tif", "--size", "128x128", "--patch-size", "32",
     "--overlap", "30", "{out}", "-q"],
    ["gdal_translate", "-q", "loop.tsyn", "{out}"],
    ["gdal_translate", "-q", "-oo", "PATCH_SIZE=5000", "synth.tsyn", "{out}"],
]


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def run(argv, out, cwd):
    argv = [a.format(ts=TERRASYNTH, out=out) for a in argv]
    return subprocess.run(argv, capture_output=True, text=True, env=env(), cwd=cwd, timeout=600)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("soak")
    shutil.copy(os.path.join(DATA, "jacksboro_fault_dem.tif"), d / "dem.tif")
    subprocess.run(["gdal_translate", "-q", "-srcwin", "100", "100", "160", "160",
                    os.path.join(DATA, "sketches", "lambda_ridges.tif"), str(d / "small_sketch.tif")],
                   check=True, env=env())
    (d / "text.tif").write_text("not a raster")
    grid = "<Grid width='96' height='96' originX='0' originY='0' resolution='90' crs='EPSG:32616'/>"
    (d / "synth.tsyn").write_text("<TerraSynth version='1'><Synth seed='5'><Exemplar>dem.tif"
                                  "</Exemplar>%s</Synth></TerraSynth>" % grid)
    (d / "ppa.tsyn").write_text("<TerraSynth version='1'><PPA><Input>dem.tif</Input></PPA>"
                                "</TerraSynth>")
    (d / "loop.tsyn").write_text("<TerraSynth version='1'><Synth><Exemplar>dem.tif</Exemplar>"
                                 "%s<Heights>loop.tsyn</Heights></Synth></TerraSynth>" % grid)
    return d


def test_soak(folder):
    # the reference: each valid command alone
    ref = {}
    for i, argv in enumerate(VALID):
        out = folder / ("ref_%d.tif" % i)
        p = run(argv, out, folder)
        assert p.returncode == 0, (argv, p.stderr)
        ref[i] = digest(out)
    rng = random.Random(12)
    jobs = []
    for k in range(RUNS):
        if rng.random() < 0.7:
            i = rng.randrange(len(VALID))
            jobs.append(("ok", i, VALID[i], folder / ("run_%03d.tif" % k)))
        else:
            i = rng.randrange(len(INVALID))
            jobs.append(("bad", i, INVALID[i], folder / ("bad_%03d.tif" % k)))

    def one(job):
        kind, i, argv, out = job
        return job, run(argv, out, folder)

    with ThreadPoolExecutor(max_workers=8) as pool:
        results = list(pool.map(one, jobs))
    for (kind, i, argv, out), p in results:
        assert p.returncode >= 0, (argv, "killed by signal %d" % -p.returncode, p.stderr)
        assert "Sanitizer" not in p.stderr and "runtime error" not in p.stderr, p.stderr
        if kind == "ok":
            assert p.returncode == 0, (argv, p.stderr)
            assert digest(out) == ref[i], (argv, "differs from the same command run alone")
        else:
            assert p.returncode != 0, argv
            assert not out.exists(), argv
    left = [n for n in os.listdir(folder) if ".tmp" in n or n.endswith(".aux.xml")]
    assert not left, left
    assert digest(folder / "dem.tif") == digest(os.path.join(DATA, "jacksboro_fault_dem.tif"))
