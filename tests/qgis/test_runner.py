# SPDX-License-Identifier: GPL-2.0-or-later
"""runner.py on its own: argv building (pure Python, nothing is run), finding the
executable, and run() against a fake CLI (a Python script) for progress, error
messages, cancel and clean-up.  Needs neither QGIS nor the terrasynth binary."""
import os
import stat
import sys
import textwrap
import time

import pytest

from terrasynth_qgis import descriptors, runner

PPA = descriptors.FALLBACK["stages"]["ppa"]
SYNTH = descriptors.FALLBACK["stages"]["synth"]
PPA_DEFAULTS = {"features": 0, "profile_length": 11, "threshold": 0.0,
                "threshold_fraction": -1.0, "min_branch_length": (-1.0, "cells"),
                "min_drainage": 200.0}


def by_name(descs, name):
    return next(d for d in descs if d["name"] == name)


# --------------------------------------------------------------------------- argv

def test_flag_names():
    assert runner.flag("profile_length") == "--profile-length"
    assert runner.flag("debug_dir") == "--debug-dir"
    assert runner.flag("band") == "--band"


@pytest.mark.parametrize("value,text", [(40, "40"), (40.0, "40"), (0.0025, "0.0025"),
                                        (0.1, "0.1"), (1e6, "1000000"), (-84.41375, "-84.41375"),
                                        (2.5e-7, "2.5e-07")])
def test_format_number(value, text):
    assert runner.format_number(value) == text


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), True])
def test_format_number_rejects(bad):
    with pytest.raises(ValueError):
        runner.format_number(bad)


def test_format_value_by_type():
    assert runner.format_value(by_name(PPA, "profile_length"), 13) == "13"
    assert runner.format_value(by_name(PPA, "profile_length"), 13.0) == "13"
    with pytest.raises(ValueError):
        runner.format_value(by_name(PPA, "profile_length"), 12.5)
    assert runner.format_value(by_name(PPA, "threshold"), 2.5) == "2.5"
    feat = by_name(PPA, "features")
    assert [runner.format_value(feat, i) for i in range(3)] == ["ridges", "valleys", "both"]
    assert runner.format_value(feat, "valleys") == "valleys"
    with pytest.raises(ValueError):
        runner.format_value(feat, 3)
    mbl = by_name(PPA, "min_branch_length")
    assert runner.format_value(mbl, (40.0, "cells")) == "40"
    assert runner.format_value(mbl, (600.0, "metres")) == "600m"
    assert runner.format_value(mbl, (12.5, "m")) == "12.5m"
    assert runner.format_value(mbl, 40) == "40"          # the default unit
    assert runner.format_value(mbl, "600m") == "600m"     # already CLI text
    with pytest.raises(ValueError):
        runner.format_value(mbl, "600 feet")
    with pytest.raises(ValueError):
        runner.format_value(mbl, (5, "feet"))


def test_defaults_pass_all_but_the_exclusive_pair():
    args = runner.descriptor_args("ppa", PPA, PPA_DEFAULTS)
    assert args == ["--features", "ridges", "--profile-length", "11",
                    "--min-branch-length", "-1", "--min-drainage", "200"]


def test_threshold_replaces_fraction():
    args = runner.descriptor_args("ppa", PPA, dict(PPA_DEFAULTS, threshold=5.0))
    assert args[args.index("--threshold") + 1] == "5"
    assert "--threshold-fraction" not in args
    args = runner.descriptor_args("ppa", PPA, dict(PPA_DEFAULTS, threshold_fraction=0.01))
    assert args[args.index("--threshold-fraction") + 1] == "0.01"
    assert "--threshold" not in args
    # 0 is a change from the fraction's default: no threshold at all
    args = runner.descriptor_args("ppa", PPA, dict(PPA_DEFAULTS, threshold_fraction=0))
    assert args[args.index("--threshold-fraction") + 1] == "0"


def test_both_thresholds_go_to_the_program():
    """Two exclusive parameters both changed are passed on: the program refuses them with the
    job's message (the same on every front end); the groups come from describe's rules."""
    assert ("threshold", "threshold_fraction") in runner.exclusive_groups("ppa")
    values = dict(PPA_DEFAULTS, threshold=5.0, threshold_fraction=0.01)
    args = runner.descriptor_args("ppa", PPA, values)
    assert "--threshold" in args and "--threshold-fraction" in args


def test_unknown_parameter_is_refused():
    with pytest.raises(ValueError):
        runner.descriptor_args("ppa", PPA, {"sketch": "x.tif"})


def test_option_args():
    args = runner.option_args([
        ("exemplar", ["a.tif", "b c.tif"]), ("size", (128, 96)), ("origin", (-84.5, 36.25)),
        ("resolution", 0.000833), ("crs", "EPSG:4326"), ("seed", 0), ("threads", 0),
        ("preview", ""), ("debug_dir", None), ("cell_size", None), ("quiet", False),
        ("both", True)])
    assert args == ["--exemplar", "a.tif", "--exemplar", "b c.tif", "--size", "128x96",
                    "--origin", "-84.5,36.25", "--resolution", "0.000833", "--crs", "EPSG:4326",
                    "--seed", "0", "--threads", "0", "--both"]


def test_build_argv_is_a_list_of_strings_without_shell():
    argv = runner.build_argv("/opt/ts/terrasynth", "ppa",
                             positional=["/data/my dem;rm -rf ~.tif", "-odd.tif"],
                             params=dict(PPA_DEFAULTS, features=2), descs=PPA,
                             options=[("band", 1), ("lines", "/o/l $HOME.gpkg")])
    assert isinstance(argv, list) and all(isinstance(a, str) for a in argv)
    assert argv[:2] == ["/opt/ts/terrasynth", "ppa"]
    # file names pass through as single items, untouched by any shell
    assert "/data/my dem;rm -rf ~.tif" in argv
    assert "/o/l $HOME.gpkg" in argv
    # a name that looks like an option is made unambiguous
    assert argv[-1] == "./-odd.tif"
    assert "--progress-lines" in argv
    assert argv[argv.index("--features") + 1] == "both"
    # the log shows a quoted command line; it is never executed
    assert "'/data/my dem;rm -rf ~.tif'" in runner.command_line(argv)


def test_build_argv_synth_layout():
    values = {d["name"]: d["default"] for d in SYNTH}
    values.update(patch_size=32, overlap=8, order=1)
    argv = runner.build_argv("terrasynth", "synth", positional=["out.tif"], params=values,
                             descs=SYNTH, options=[("exemplar", ["a.tif"]), ("size", (128, 128))])
    assert argv[1] == "synth" and argv[-1] == "out.tif"
    pairs = dict(zip(argv[2::2], argv[3::2]))
    assert pairs["--patch-size"] == "32" and pairs["--overlap"] == "8"
    assert pairs["--order"] == "raster" and pairs["--size"] == "128x128"
    assert pairs["--variety"] == "0.1" and pairs["--coarse-factor"] == "0"


def test_run_refuses_a_shell_string():
    with pytest.raises(TypeError):
        runner.run("terrasynth ppa a.tif b.tif")


# --------------------------------------------------------------------------- finding the CLI

def _exe(path):
    with open(path, "w") as f:
        f.write("#!/bin/sh\nexit 0\n")
    os.chmod(path, 0o755)
    return str(path)


def test_find_cli_order(tmp_path):
    setting, env = _exe(tmp_path / "from_setting"), _exe(tmp_path / "from_env")
    bundled, on_path = _exe(tmp_path / "bundled"), _exe(tmp_path / "on_path")
    look = lambda name: on_path  # noqa: E731
    environ = {runner.ENV_VAR: env}
    assert runner.find_cli(setting, environ, bundled, look) == setting
    assert runner.find_cli("", environ, bundled, look) == env
    assert runner.find_cli("", {}, bundled, look) == bundled
    assert runner.find_cli("", {}, str(tmp_path / "none"), look) == on_path


def test_find_cli_restores_the_exec_bit_of_the_bundled_binary(tmp_path):
    bundled = _exe(tmp_path / "terrasynth")
    os.chmod(bundled, 0o644)  # as after QGIS' "Install from ZIP" (zipfile drops modes)
    assert runner.find_cli("", {}, bundled, None) == bundled
    assert os.stat(bundled).st_mode & stat.S_IXUSR


def test_find_cli_errors(tmp_path):
    with pytest.raises(runner.QgsProcessingException, match="not found"):
        runner.find_cli("", {}, str(tmp_path / "none"), lambda name: None)
    with pytest.raises(runner.QgsProcessingException, match="TERRASYNTH environment"):
        runner.find_cli("", {runner.ENV_VAR: str(tmp_path / "missing")}, None, None)
    with pytest.raises(runner.QgsProcessingException, match="Processing setting"):
        runner.find_cli(str(tmp_path), {}, None, None)  # a folder is not an executable


# --------------------------------------------------------------------------- run() on a fake CLI

FAKE_CLI = textwrap.dedent(r'''
    import os, sys, time
    mode, out = sys.argv[1], sys.argv[2]
    d, base = os.path.split(out)
    stem, ext = os.path.splitext(base)
    tmp = os.path.join(d, ".%s.tmp%d%s" % (stem, os.getpid(), ext))
    open(os.path.join(d, "pid"), "w").write(str(os.getpid()))
    if mode == "fail":
        sys.stderr.write("terrasynth: warning: x.tif has no CRS: lengths are in cells\n")
        sys.stderr.write("terrasynth: x.tif: band 5 does not exist (the file has 1 band)\n")
        sys.exit(1)
    print("PROGRESS 0 profile recognition", flush=True)
    open(tmp, "w").write("partial")
    open(tmp + ".aux.xml", "w").write("partial")
    if mode == "slow":
        for i in range(1, 100):
            print("PROGRESS %d polygon breaking" % i, flush=True)
            time.sleep(0.2)
    print("PROGRESS 50 polygon breaking", flush=True)
    print("ppa: 3 ridge paths", flush=True)
    sys.stderr.write("terrasynth: warning: a warning\n")
    os.rename(tmp, out)
    os.remove(tmp + ".aux.xml")
    print("PROGRESS 100 done", flush=True)
''')


class Recorder:
    def __init__(self, cancel_after=None):
        self.progress, self.texts, self.info, self.warnings, self.console = [], [], [], [], []
        self.commands, self.cancel_after = [], cancel_after

    def isCanceled(self):  # noqa: N802
        return self.cancel_after is not None and len(self.progress) >= self.cancel_after

    def setProgress(self, p):  # noqa: N802
        self.progress.append(p)

    def setProgressText(self, t):  # noqa: N802
        self.texts.append(t)

    def pushInfo(self, t):  # noqa: N802
        self.info.append(t)

    def pushWarning(self, t):  # noqa: N802
        self.warnings.append(t)

    def pushConsoleInfo(self, t):  # noqa: N802
        self.console.append(t)

    def pushCommandInfo(self, t):  # noqa: N802
        self.commands.append(t)


@pytest.fixture
def fake(tmp_path):
    script = tmp_path / "fake_terrasynth.py"
    script.write_text(FAKE_CLI)
    work = tmp_path / "work"
    work.mkdir()
    return [sys.executable, str(script)], work


def test_run_maps_progress_and_output(fake):
    cmd, work = fake
    out = str(work / "out.tif")
    fb = Recorder()
    res = runner.run(cmd + ["ok", out], fb, outputs=[out])
    assert res["returncode"] == 0
    assert fb.progress == [0.0, 50.0, 100.0]
    assert fb.texts == ["profile recognition", "polygon breaking", "done"]
    assert fb.info == ["ppa: 3 ridge paths"]
    assert fb.warnings == ["terrasynth: warning: a warning"]
    assert fb.commands and "fake_terrasynth.py" in fb.commands[0]
    assert os.path.exists(out)


def test_run_failure_raises_the_cli_message(fake):
    cmd, work = fake
    out = str(work / "out.tif")
    with pytest.raises(runner.QgsProcessingException) as e:
        runner.run(cmd + ["fail", out], Recorder(), outputs=[out])
    assert e.value.args[0] == "terrasynth: x.tif: band 5 does not exist (the file has 1 band)"


def test_run_cancel_kills_the_child_and_removes_everything(fake):
    cmd, work = fake
    out, dbg = str(work / "out.tif"), str(work / "debug")
    fb = Recorder(cancel_after=2)
    t0 = time.monotonic()
    with pytest.raises(runner.QgsProcessingException, match="canceled"):
        runner.run(cmd + ["slow", out], fb, outputs=[out], output_dirs=[dbg])
    assert time.monotonic() - t0 < 10  # the slow fake alone would take 20 s
    pid = int((work / "pid").read_text())
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # the child is gone (and reaped)
    assert sorted(os.listdir(work)) == ["pid"]  # temporary files removed, no output


def test_run_cancel_keeps_what_others_wrote(fake):
    """A failed or canceled run removes only what it created: a file another program writes
    into the output folders meanwhile stays, and so does a folder that is not empty."""
    cmd, work = fake
    out, dbg = str(work / "out.tif"), work / "debug"
    dbg.mkdir()
    (dbg / "mine.txt").write_text("before")

    class Neighbour(Recorder):
        def setProgress(self, p):  # noqa: N802
            super().setProgress(p)
            (work / "theirs.tif").write_text("written meanwhile")
            (dbg / "mine.txt").write_text("changed meanwhile")
            (dbg / "new.txt").write_text("new meanwhile")

    with pytest.raises(runner.QgsProcessingException, match="canceled"):
        runner.run(cmd + ["slow", out], Neighbour(cancel_after=2), outputs=[out],
                   output_dirs=[str(dbg), str(work / "created")])
    assert sorted(os.listdir(work)) == ["debug", "pid", "theirs.tif"]
    assert sorted(os.listdir(dbg)) == ["mine.txt", "new.txt"]
    assert (dbg / "mine.txt").read_text() == "changed meanwhile"


def test_run_leaves_an_untouched_existing_output_alone(fake):
    cmd, work = fake
    out = work / "out.tif"
    out.write_text("from an earlier run")
    with pytest.raises(runner.QgsProcessingException):
        runner.run(cmd + ["fail", str(out)], Recorder(), outputs=[str(out)])
    assert out.read_text() == "from an earlier run"


def test_run_missing_executable():
    with pytest.raises(runner.QgsProcessingException, match="cannot run"):
        runner.run(["/nonexistent/terrasynth", "ppa"], Recorder())


def test_temp_name_pattern():
    p = runner.temp_name_pattern(12)
    assert p.match(".axes.tmp12.tif") and p.match(".axes.tmp12-3.gpkg")
    assert p.match(".axes.tmp12.tif.aux.xml") and p.match(".axes.tmp12.gpkg-journal")
    assert not p.match(".axes.tmp123.tif") and not p.match("axes.tif")
    assert not p.match(".axes.tmp1.tif")
