# SPDX-License-Identifier: GPL-2.0-or-later
"""The one place that finds the `terrasynth` executable, builds its argv and runs it.

Algorithms hand over plain Python values (descriptor values by name, extra
options by name, positional file names); this module turns them into an argv
LIST (never a shell string), runs it in a subprocess, maps the CLI's
`PROGRESS <percent> <stage>` lines to the feedback, kills the child when the
user cancels, removes whatever the run left behind when it did not succeed, and
turns the CLI's one-line stderr message into a QgsProcessingException.

Everything above `run()` is pure Python and is unit-tested without QGIS and
without the binary.  If process overhead ever matters, a ctypes binding can
replace run() here without touching the algorithm classes.
"""
import json
import os
import queue
import re
import shlex
import shutil
import stat
import subprocess
import threading

try:
    from qgis.core import QgsProcessingException, QgsSettings
except ImportError:  # argv building stays usable (and testable) without QGIS

    class QgsProcessingException(Exception):
        pass

    QgsSettings = None

EXECUTABLE = "terrasynth"
ENV_VAR = "TERRASYNTH"
# Processing setting (Settings > Options > Processing > Providers > TerraSynth);
# ProcessingConfig stores it in QgsSettings under this key.
SETTING_NAME = "TERRASYNTH_CLI"
SETTINGS_KEY = "Processing/Configuration/" + SETTING_NAME
PLUGIN_DIR = os.path.dirname(os.path.abspath(__file__))
BUNDLED = os.path.join(PLUGIN_DIR, "bin", EXECUTABLE)


def exclusive_groups(stage):
    """Parameters of a job of which the CLI accepts only one (giving one sets the others to
    0): its "excludes" rules between core parameters, from `terrasynth describe`."""
    from . import descriptors
    params = {d["name"] for st in descriptors.job(stage).get("stages", [stage])
              for d in descriptors.stage(st)}
    groups = []
    for r in descriptors.job(stage).get("rules", []):
        names = [r["a"]] + list(r["b"])
        if r["kind"] == "excludes" and all(n in params for n in names):
            groups.append(tuple(names))
    return groups

# Options whose value is a pair, and the separator the CLI expects.
PAIR_SEPARATORS = {"size": "x", "origin": ","}

CANCELED_MESSAGE = "terrasynth: canceled; no output was kept"

_PROGRESS = re.compile(r"^PROGRESS\s+(\d+(?:\.\d+)?)\s*(.*)$")


# ---------------------------------------------------------------------------
# Finding the executable
# ---------------------------------------------------------------------------

def _setting_value():
    if QgsSettings is None:
        return ""
    value = QgsSettings().value(SETTINGS_KEY, "")
    return str(value).strip() if value else ""


def _is_executable(path):
    return os.path.isfile(path) and os.access(path, os.X_OK)


def _make_executable(path):
    """A plugin ZIP installed by QGIS loses the exec bit (zipfile does not keep modes)."""
    if os.path.isfile(path) and not os.access(path, os.X_OK):
        try:
            mode = os.stat(path).st_mode
            os.chmod(path, mode | ((mode & 0o444) >> 2) | stat.S_IXUSR)
        except OSError:
            pass
    return _is_executable(path)


def find_cli(setting=None, environ=None, bundled=BUNDLED, path_lookup=shutil.which):
    """Path of the terrasynth executable, looked for in this order:

    1. the Processing setting TERRASYNTH_CLI (QgsSettings key SETTINGS_KEY),
    2. the TERRASYNTH environment variable,
    3. bin/terrasynth inside the plugin folder (what the plugin ZIP ships),
    4. PATH.

    A location given explicitly (1 or 2) that is not an executable file is an
    error rather than silently skipped.
    """
    setting = _setting_value() if setting is None else setting
    environ = os.environ if environ is None else environ
    for origin, value in (("the Processing setting " + SETTING_NAME, setting),
                          ("the " + ENV_VAR + " environment variable", environ.get(ENV_VAR, ""))):
        if value:
            if _is_executable(value):
                return value
            raise QgsProcessingException(
                "terrasynth: %s points to %s, which is not an executable file" % (origin, value))
    if bundled and _make_executable(bundled):
        return bundled
    found = path_lookup(EXECUTABLE) if path_lookup else None
    if found:
        return found
    raise QgsProcessingException(
        "terrasynth: the terrasynth executable was not found. Set its location in "
        "Settings > Options > Processing > Providers > TerraSynth (%s), or in the %s "
        "environment variable, or put it on PATH (also looked for %s)"
        % (SETTING_NAME, ENV_VAR, bundled))


def describe(cli, timeout=30):
    """The core's descriptor tables, from `terrasynth describe` (a dict)."""
    from .descriptors import validate

    p = subprocess.run([cli, "describe"], stdin=subprocess.DEVNULL, capture_output=True,
                       text=True, timeout=timeout)
    if p.returncode != 0:
        raise ValueError("%s describe failed (%d): %s" % (cli, p.returncode, p.stderr.strip()))
    return validate(json.loads(p.stdout))


def check(argv, timeout=30):
    """The program's own verdict on a command line (`--check`: its options and the rules
    between them, nothing read or run): None, or its one-line message without the
    "terrasynth JOB: " prefix and the "(see ...)" hint."""
    p = subprocess.run(list(argv) + ["--check"], stdin=subprocess.DEVNULL, capture_output=True,
                       text=True, timeout=timeout)
    if p.returncode == 0:
        return None
    msg = error_message(p.stderr.splitlines(), p.returncode)
    msg = re.sub(r"^terrasynth( [a-z]+)?: ", "", msg)
    return re.sub(r" \(see 'terrasynth [a-z]+ --help'\)$", "", msg)


# ---------------------------------------------------------------------------
# Building argv (pure Python)
# ---------------------------------------------------------------------------

def flag(name):
    """CLI flag of a parameter or option name: profile_length -> --profile-length."""
    return "--" + name.replace("_", "-")


def format_number(value):
    """40 -> '40', 40.0 -> '40', 0.0025 -> '0.0025' (shortest round-trip form)."""
    if isinstance(value, bool):
        raise ValueError("a number, not a boolean")
    v = float(value)
    if v != v or v in (float("inf"), float("-inf")):
        raise ValueError("not a finite number: %r" % (value,))
    if v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return repr(v)


def format_value(desc, value):
    """The CLI text of a descriptor's value."""
    t = desc["type"]
    if t == "int":
        v = float(value)
        if not v.is_integer():
            raise ValueError("%s must be an integer, not %r" % (desc["name"], value))
        return str(int(v))
    if t == "double":
        return format_number(value)
    if t == "enum":
        choices = desc["choices"]
        if isinstance(value, str) and value in choices:
            return value
        i = int(value)
        if not 0 <= i < len(choices):
            raise ValueError("%s: no choice number %r in %s" % (desc["name"], value, choices))
        return choices[i]
    if t == "length":
        if isinstance(value, str):  # already in CLI form: "40", "600m"
            text = value.strip()
            if not re.match(r"^\d+(\.\d*)?(e[+-]?\d+)?m?$", text, re.I):
                raise ValueError("%s: '%s' is not a length (N cells or Nm)" % (desc["name"], value))
            return text
        if isinstance(value, (int, float)):  # a bare number is in the default unit
            value = (value, desc.get("default_unit", "cells"))
        number, unit = value
        unit = str(unit).lower()
        if unit in ("m", "metres", "meters"):
            return format_number(number) + "m"
        if unit in ("cells", "cell"):
            return format_number(number)
        raise ValueError("%s: unknown unit '%s' (cells or metres)" % (desc["name"], unit))
    raise ValueError("%s: unknown descriptor type '%s'" % (desc["name"], t))


def is_default(desc, value):
    """Is `value` the descriptor's default?"""
    try:
        return format_value(desc, value) == format_value(desc, desc["default"])
    except (TypeError, ValueError):
        return False


def descriptor_args(stage, descs, values):
    """argv items for the core's parameters, in descriptor-table order.

    Every value is passed explicitly, except inside an exclusive group, where only
    the members changed from their defaults are passed (the CLI then zeroes the others,
    or refuses two with the job's message)."""
    by_name = {d["name"]: d for d in descs}
    skip = set()
    for group in exclusive_groups(stage):
        for n in group:
            if n in values and n in by_name and is_default(by_name[n], values[n]):
                skip.add(n)
    unknown = set(values) - set(by_name)
    if unknown:
        raise ValueError("terrasynth %s has no parameter %s" % (stage, ", ".join(sorted(unknown))))
    args = []
    for d in descs:
        if d["name"] in values and d["name"] not in skip and values[d["name"]] is not None:
            args += [d["flag"], format_value(d, values[d["name"]])]
    return args


def _safe_path(path):
    """A file name the CLI cannot mistake for an option."""
    path = str(path)
    return "./" + path if path.startswith("-") else path


def option_args(options):
    """argv items for (name, value) options: None/''/False are left out, True is a
    bare flag, a list repeats the flag, a pair is joined with PAIR_SEPARATORS."""
    args = []
    for name, value in options:
        if value is None or value is False or (isinstance(value, str) and value == ""):
            continue
        f = flag(name)
        if value is True:
            args.append(f)
        elif isinstance(value, list):
            for v in value:
                args += [f, str(v)]
        elif isinstance(value, tuple):
            args += [f, PAIR_SEPARATORS[name].join(format_number(v) for v in value)]
        elif isinstance(value, (int, float)):
            args += [f, format_number(value)]
        else:
            args += [f, str(value)]
    return args


def build_argv(cli, stage, positional=(), params=None, descs=(), options=()):
    """[cli, stage, <core parameters>, <options>, --progress-lines, <positional>...]."""
    argv = [str(cli), stage]
    argv += descriptor_args(stage, list(descs), dict(params or {}))
    argv += option_args(list(options))
    argv.append("--progress-lines")
    argv += [_safe_path(p) for p in positional]
    assert all(isinstance(a, str) for a in argv)
    return argv


def command_line(argv):
    """The argv as a shell-quoted string, for the log only (never executed)."""
    return " ".join(shlex.quote(a) for a in argv)


# ---------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------

class _NullFeedback:
    def isCanceled(self):  # noqa: N802
        return False

    def __getattr__(self, name):
        return lambda *a, **k: None


def _snapshot(path):
    try:
        s = os.stat(path)
    except OSError:
        return None
    return (s.st_dev, s.st_ino, s.st_mtime_ns, s.st_size)


def _listing(directory):
    try:
        return {n: _snapshot(os.path.join(directory, n)) for n in os.listdir(directory)}
    except OSError:
        return None


def _remove(path):
    try:
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path, ignore_errors=True)
        else:
            os.remove(path)
    except OSError:
        pass


def temp_name_pattern(pid):
    """The CLI's temporary names: '<dir>/.<stem>.tmp<pid>[-k]<suffix>'."""
    return re.compile(r"^\..+\.tmp%d(?:-\d+)?(?:[.\-].*)?$" % pid)


def _cleanup(pid, outputs, output_dirs):
    """Remove what a failed or canceled run created, and nothing else: the child's temporary
    files (their names carry its pid), an output file that did not exist before the run (a
    run cut short while it moved its outputs into place), and a folder the run created once
    it is empty.  A file another program wrote meanwhile, or one that existed before (even
    if replaced), is left alone."""
    pattern = temp_name_pattern(pid) if pid else None
    dirs = {os.path.dirname(os.path.abspath(p)) for p in outputs}
    dirs |= {os.path.abspath(d) for d in output_dirs}
    for d in dirs:
        if pattern is None or not os.path.isdir(d):
            continue
        for name in os.listdir(d):
            if pattern.match(name):
                _remove(os.path.join(d, name))
    for path, before in outputs.items():
        if before is None and os.path.isfile(path) and not os.path.islink(path):
            _remove(path)
    for d, before in output_dirs.items():
        if before is None and os.path.isdir(d):  # the run created the folder
            try:
                os.rmdir(d)  # only when nothing else is in it
            except OSError:
                pass


def _pump(stream, kind, q):
    try:
        for line in stream:
            q.put((kind, line.rstrip("\r\n")))
    finally:
        q.put((kind, None))


def _terminate(proc):
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
    proc.wait()


def error_message(stderr_lines, returncode):
    """The CLI's one-line message: its last stderr line that is not a warning."""
    for line in reversed(stderr_lines):
        text = line.strip()
        if text and "warning:" not in text:
            return text
    if returncode < 0:
        return "terrasynth: killed by signal %d" % -returncode
    return "terrasynth: failed with exit status %d" % returncode


def _warn(feedback, text):
    if hasattr(feedback, "pushWarning"):
        feedback.pushWarning(text)
    else:
        feedback.reportError(text, False)


def run(argv, feedback=None, outputs=(), output_dirs=(), poll_seconds=0.05):
    """Run argv (a list) and report to `feedback`.

    outputs: files the run writes; output_dirs: folders it writes into.  On
    failure or cancel, anything the run created or replaced there is removed.
    Returns {'returncode', 'stdout', 'stderr'} (lists of lines); raises
    QgsProcessingException with the CLI's message on failure, CANCELED_MESSAGE
    on cancel.
    """
    if isinstance(argv, (str, bytes)) or not all(isinstance(a, str) for a in argv):
        raise TypeError("argv must be a list of strings")
    feedback = feedback if feedback is not None else _NullFeedback()
    outputs = {os.path.abspath(p): _snapshot(p) for p in outputs if p}
    output_dirs = {os.path.abspath(d): _listing(d) for d in output_dirs if d}
    feedback.pushCommandInfo(command_line(argv))
    if feedback.isCanceled():
        raise QgsProcessingException(CANCELED_MESSAGE)
    try:
        proc = subprocess.Popen(list(argv), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, errors="replace", bufsize=1,
                                close_fds=True)
    except OSError as e:
        raise QgsProcessingException("terrasynth: cannot run %s: %s" % (argv[0], e.strerror))
    q = queue.Queue()
    pumps = [threading.Thread(target=_pump, args=(proc.stdout, "out", q), daemon=True),
             threading.Thread(target=_pump, args=(proc.stderr, "err", q), daemon=True)]
    for t in pumps:
        t.start()
    out_lines, err_lines = [], []
    open_streams, canceled, last_stage = 2, False, None
    while open_streams:
        if feedback.isCanceled():
            canceled = True
            break
        try:
            kind, line = q.get(timeout=poll_seconds)
        except queue.Empty:
            continue
        if line is None:
            open_streams -= 1
            continue
        if kind == "out":
            m = _PROGRESS.match(line)
            if m:
                feedback.setProgress(min(100.0, float(m.group(1))))
                if m.group(2) and m.group(2) != last_stage:
                    last_stage = m.group(2)
                    feedback.setProgressText(last_stage)
                continue
            out_lines.append(line)
            feedback.pushInfo(line)
        else:
            err_lines.append(line)
            if "warning:" in line:
                _warn(feedback, line)
            else:
                feedback.pushConsoleInfo(line)
    if canceled:
        _terminate(proc)
    returncode = proc.wait()
    for t in pumps:
        t.join(timeout=5)
    for stream in (proc.stdout, proc.stderr):
        try:
            stream.close()
        except OSError:
            pass
    canceled = canceled or feedback.isCanceled()
    if canceled or returncode != 0:
        _cleanup(proc.pid, outputs, output_dirs)
        if canceled:
            raise QgsProcessingException(CANCELED_MESSAGE)
        raise QgsProcessingException(error_message(err_lines, returncode))
    return {"returncode": returncode, "stdout": out_lines, "stderr": err_lines}
