#!/usr/bin/python3
# terrasynth-dask - compute a TerraSynth recipe on a Dask cluster, block by block, into a
# tiled, compressed GeoTIFF (a COG when GDAL has the COG driver) with overviews.
#
# Copyright (C) 2026 The TerraSynth developers
# SPDX-License-Identifier: GPL-2.0-or-later
#
#   terrasynth-dask RECIPE.tsyn OUT.tif [--workers N [--processes] | --scheduler ADDRESS]
#                   [--chunk N] [--plugins DIR] [--no-overviews] [--stats] [-q]
#
# The workers open the recipe through the TSYN GDAL driver and each reads one chunk (a window
# of the raster); the client writes the chunks as they come.  Methods that compute any window
# alone (pixel, amplify, a sketch in tiles: read from the coarse pass its recipe keeps, or
# laid out once per worker when it keeps none, then amplified chunk by chunk) are spread over the workers chunk by chunk.  A tiled synth recipe without a sketch
# (<Param name="tiled">) is one Dask task per tile: a tile's task takes the windows of its
# earlier-wave neighbours (four waves, see algorithms/docs/synth.md) as its inputs, so Dask
# runs the waves in order, each tile once, and moves the neighbours' windows between workers;
# the task calls the plugin's tsyn_tile_make; with the drainage stage a second task per tile
# drains its core from the tiles within reach (tsyn_tile_drain).  The others (synth in one piece, ppa) compute
# the whole raster on first read, so their recipe is read by one task as one chunk (the same
# bytes, no gain in speed).  A chunk is a pure function of the recipe and its
# window, so Dask recomputes the chunks of a worker that dies.  The output appears whole or
# not at all (written under a temporary name, moved at the end; removed on error and on
# Ctrl-C); it never replaces the recipe or a file the recipe names.  A local cluster's workers
# are threads of this process by default: the tile and chunk calls run in C with Python's
# lock released, so threads compute side by side and share the windows without copying them
# (worker processes, --processes, pay for pickling and moving every window).  Debian
# packages only: python3-gdal, python3-numpy, python3-dask, python3-distributed.
import argparse
import os
import signal
import sys
import tempfile

PROG = "terrasynth-dask"


def fail(msg):
    sys.stderr.write("%s: %s\n" % (PROG, msg))
    sys.exit(1)


def same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def tsyn_driver(plugins):
    """GDAL (osgeo.gdal) and its TSYN driver on this worker, the plugin loaded from `plugins`
    when given."""
    if plugins:
        os.environ["GDAL_DRIVER_PATH"] = plugins
    from osgeo import gdal
    gdal.UseExceptions()
    if plugins:
        gdal.SetConfigOption("GDAL_DRIVER_PATH", plugins)
    if gdal.GetDriverByName("TSYN") is None:
        gdal.AllRegister()
    drv = gdal.GetDriverByName("TSYN")
    if drv is None:
        raise RuntimeError("the TSYN GDAL driver is not installed on this worker "
                           "(cmake --install, or GDAL_DRIVER_PATH)")
    return gdal, drv


def _chunk_dataset(recipe, plugins):
    """The recipe opened once per worker thread (a GDAL dataset is one thread's), kept on the
    Dask worker object like the tile handles (_tiles_handle says why not a global)."""
    import threading
    gdal, _ = tsyn_driver(plugins)
    try:
        from distributed import get_worker
        cache = get_worker().__dict__.setdefault("_terrasynth_chunks", {})
    except (ImportError, ValueError):  # not on a worker: no cache
        cache = {}
    st = os.stat(recipe)  # a recipe rewritten in place is opened anew
    key = (recipe, st.st_mtime_ns, st.st_size, threading.get_ident())
    if key not in cache:
        cache[key] = gdal.OpenEx(recipe, gdal.OF_RASTER | gdal.OF_READONLY,
                                 allowed_drivers=["TSYN"])
    return cache[key]


def read_chunk(recipe, plugins, x, y, w, h):
    """One window of the recipe, read through the TSYN driver (runs on a worker)."""
    a = _chunk_dataset(recipe, plugins).GetRasterBand(1).ReadAsArray(x, y, w, h)
    return x, y, a


def _tiles_handle(recipe, plugins):
    """The recipe opened once per worker for tile tasks: the plugin's library (ctypes) and
    a handle with the exemplars read, kept on the Dask worker object.  (Not in a module
    global: this script runs as __main__, so Dask pickles its functions by value and every
    task would unpickle a fresh, empty global; a worker of a running cluster would open the
    recipe and read its exemplars again for every tile.)"""
    import threading
    from distributed import get_worker
    w = get_worker()
    cache = w.__dict__.setdefault("_terrasynth_tiles", {})
    if recipe not in cache:
        with w.__dict__.setdefault("_terrasynth_lock", threading.Lock()):
            if recipe not in cache:
                cache[recipe] = _tiles_open(recipe, plugins)
    return cache[recipe]


def _tiles_open(recipe, plugins):
    import ctypes
    _, drv = tsyn_driver(plugins)
    path = drv.GetMetadataItem("TSYN_LIBRARY")
    if not path:
        raise RuntimeError("this TSYN driver does not name its library (TSYN_LIBRARY)")
    lib = ctypes.CDLL(path)
    lib.tsyn_tiles_open.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_void_p),
                                    ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int),
                                    ctypes.POINTER(ctypes.c_int), ctypes.c_char_p, ctypes.c_int]
    lib.tsyn_tile_make.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int,
                                   ctypes.c_void_p * 9, ctypes.c_void_p, ctypes.c_char_p,
                                   ctypes.c_int]
    lib.tsyn_tile_rect.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int,
                                   ctypes.c_int * 4, ctypes.c_int * 4, ctypes.c_char_p,
                                   ctypes.c_int]
    lib.tsyn_tile_reach.argtypes = [ctypes.c_void_p]
    lib.tsyn_tile_reach.restype = ctypes.c_int
    lib.tsyn_tile_drain.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int,
                                    ctypes.POINTER(ctypes.c_void_p), ctypes.c_void_p,
                                    ctypes.c_char_p, ctypes.c_int]
    h, w, ht, t = ctypes.c_void_p(), ctypes.c_int(), ctypes.c_int(), ctypes.c_int()
    msg = ctypes.create_string_buffer(1024)
    if lib.tsyn_tiles_open(recipe.encode(), ctypes.byref(h), ctypes.byref(w), ctypes.byref(ht),
                           ctypes.byref(t), msg, 1024) != 0:
        raise RuntimeError(msg.value.decode(errors="replace"))
    return (lib, h, w.value, ht.value, t.value)


def make_tile(recipe, plugins, ti, tj, neighbours):
    """Tile (ti, tj)'s window (runs on a worker) from its earlier-wave neighbours' windows
    (neighbours[(dj + 1) * 3 + di + 1], None where not needed), and where its window and
    core lie ({x, y, w, h} each)."""
    import ctypes
    import numpy as np
    lib, h, W, H, T = _tiles_handle(recipe, plugins)
    win, core = (ctypes.c_int * 4)(), (ctypes.c_int * 4)()
    msg = ctypes.create_string_buffer(1024)
    if lib.tsyn_tile_rect(h, ti, tj, win, core, msg, 1024) != 0:
        raise RuntimeError(msg.value.decode(errors="replace"))
    window = np.empty((win[3], win[2]), dtype=np.float32)
    keep = [None if n is None else np.ascontiguousarray(n[2], dtype=np.float32)
            for n in neighbours]
    ptrs = (ctypes.c_void_p * 9)(*[None if n is None else n.ctypes.data for n in keep])
    if lib.tsyn_tile_make(h, ti, tj, ptrs, window.ctypes.data, msg, 1024) != 0:
        raise RuntimeError(msg.value.decode(errors="replace"))
    return tuple(win), tuple(core), window


def drain_tile(recipe, plugins, ti, tj, reach, tiles):
    """Tile (ti, tj)'s core after the drainage stage (runs on a worker), from the windows of
    the tiles within `reach` rings (tiles[(dj + reach) * (2 reach + 1) + di + reach], None off
    the grid); returned as make_tile returns a window whose window is its core."""
    import ctypes
    import numpy as np
    lib, h, W, H, T = _tiles_handle(recipe, plugins)
    win, core = (ctypes.c_int * 4)(), (ctypes.c_int * 4)()
    msg = ctypes.create_string_buffer(1024)
    if lib.tsyn_tile_rect(h, ti, tj, win, core, msg, 1024) != 0:
        raise RuntimeError(msg.value.decode(errors="replace"))
    out = np.empty((core[3], core[2]), dtype=np.float32)
    keep = [None if t is None else np.ascontiguousarray(t[2], dtype=np.float32) for t in tiles]
    ptrs = (ctypes.c_void_p * len(keep))(*[None if t is None else t.ctypes.data for t in keep])
    if lib.tsyn_tile_drain(h, ti, tj, ptrs, out.ctypes.data, msg, 1024) != 0:
        raise RuntimeError(msg.value.decode(errors="replace"))
    return tuple(core), tuple(core), out


def worker_stats():
    """This process's peak resident set in MB and CPU seconds (runs on a worker)."""
    import resource
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_maxrss / 1024.0, u.ru_utime + u.ru_stime


def recipe_opens(dask_worker):
    """How many times this worker opened the recipe for chunks (once per thread)."""
    return len(dask_worker.__dict__.get("_terrasynth_chunks", {}))


def wave(ti, tj):
    return (ti & 1) + 2 * (tj & 1)


def tile_tasks(client, recipe, plugins, W, H, T, reach=0):
    """Submit a task per tile, each after the earlier-wave neighbours it takes (tiles in row
    order, a tile's needs first: Dask runs them in about that order, so the windows it holds
    are a few tile rows); with the drainage stage (reach > 0 rings of tiles) a task per tile
    after them that drains its core."""
    nti, ntj = (W + T - 1) // T, (H + T - 1) // T
    futs = {}

    def submit(ti, tj):
        stack = [(ti, tj)]
        while stack:
            i, j = stack[-1]
            if (i, j) in futs:
                stack.pop()
                continue
            needs = [(i + di, j + dj) for dj in (-1, 0, 1) for di in (-1, 0, 1)
                     if (di or dj) and 0 <= i + di < nti and 0 <= j + dj < ntj
                     and wave(i + di, j + dj) < wave(i, j)]
            missing = [n for n in needs if n not in futs]
            if missing:
                stack.extend(missing)
                continue
            stack.pop()
            nb = [futs.get((i + di, j + dj)) if (i + di, j + dj) in needs else None
                  for dj in (-1, 0, 1) for di in (-1, 0, 1)]
            # the tile rows in order (Dask would otherwise go wave by wave over the whole
            # grid): the windows the workers keep for later tiles, and the tiles the client
            # holds until their turn to be written, stay a few tile rows
            futs[(i, j)] = client.submit(make_tile, recipe, plugins, i, j, nb, pure=True,
                                         retries=2, priority=-j, key="tile-%d-%d-%s" % (
                                             i, j, abs(hash((recipe, plugins)))))
    for tj in range(ntj):
        for ti in range(nti):
            submit(ti, tj)
    if not reach:
        return futs
    # the drainage stage: each core from the tiles within reach rings of it
    drained = {}
    for tj in range(ntj):
        for ti in range(nti):
            near = [futs.get((ti + di, tj + dj)) for dj in range(-reach, reach + 1)
                    for di in range(-reach, reach + 1)]
            drained[(ti, tj)] = client.submit(drain_tile, recipe, plugins, ti, tj, reach, near,
                                              pure=True, retries=2, priority=-tj,
                                              key="drain-%d-%d-%s" % (
                                                  ti, tj, abs(hash((recipe, plugins)))))
    return drained


def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__)
    ap.add_argument("recipe")
    ap.add_argument("output")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, default=None,
                   help="workers of a local cluster (default 2), one thread each")
    g.add_argument("--scheduler", help="address of a running Dask scheduler (tcp://host:8786)")
    ap.add_argument("--processes", action="store_true",
                    help="a local cluster's workers as processes (default: threads of this "
                         "process, which share the windows without copying them)")
    ap.add_argument("--chunk", type=int, default=None,
                    help="chunk side in cells (default 2048, or 4 times the drainage stage's "
                         "margin when larger)")
    ap.add_argument("--plugins", default=os.environ.get("GDAL_DRIVER_PATH", ""),
                    help="folder of the TSYN plugin for the workers (default: GDAL_DRIVER_PATH)")
    ap.add_argument("--no-overviews", action="store_true")
    ap.add_argument("--compress", choices=("ZSTD", "DEFLATE", "LZW", "NONE"), default=None,
                    help="compression of the tiles (default ZSTD where GDAL has it, else "
                         "DEFLATE; ZSTD and DEFLATE after the predictor)")
    ap.add_argument("-q", "--quiet", action="store_true")
    ap.add_argument("--stats", action="store_true",
                    help="print each worker's peak memory (resident set) and CPU time at the end")
    a = ap.parse_args(argv)
    if a.chunk is not None and (a.chunk < 64 or a.chunk > 65536):
        fail("--chunk %d: give 64..65536 cells" % a.chunk)
    if a.workers is not None and a.workers < 1:
        fail("--workers %d: give at least 1" % a.workers)
    if a.processes and a.scheduler:
        fail("--processes: only for a local cluster (a running one has its own workers)")
    if not a.scheduler and a.workers is None:
        a.workers = 2
    if not os.path.isfile(a.recipe):
        fail("%s: no such recipe" % a.recipe)
    if a.plugins:
        os.environ["GDAL_DRIVER_PATH"] = a.plugins
    import numpy as np
    from osgeo import gdal
    gdal.UseExceptions()
    # the recipe read by the TSYN driver (the library's parser and checks): its grid, and
    # how it is made (metadata domain TSYN: JOB, WINDOWS any|tiles|whole, TILE_SIZE,
    # DRAINAGE_MARGIN, the files it reads as INPUT_n)
    try:
        src = gdal.OpenEx(a.recipe, gdal.OF_RASTER | gdal.OF_READONLY, allowed_drivers=["TSYN"])
    except RuntimeError as e:
        fail("%s: %s" % (a.recipe, str(e).strip().splitlines()[-1]))
    how = src.GetMetadata("TSYN") or {}
    method, windows_alone = how.get("JOB", "?"), how.get("WINDOWS") == "any"
    tile = int(how.get("TILE_SIZE", "0"))
    # the cells round a window its drainage stage reads: chunks of "any" windows are by
    # default at least 4 times as large, so the margin costs at most 2.25 x their cells
    margin = int(how.get("DRAINAGE_MARGIN", "0"))
    named = [v for k, v in sorted(how.items()) if k.startswith("INPUT_")]
    for p in [a.recipe] + named:
        if same_file(p, a.output):
            src = None
            fail("%s: the output would replace %s, which the job reads" % (a.output, p))
    if os.path.exists(a.output) and not os.path.isfile(a.output):
        fail("%s: not a regular file" % a.output)
    out_dir = os.path.dirname(os.path.abspath(a.output))
    if not os.path.isdir(out_dir) or not os.access(out_dir, os.W_OK):
        fail("%s: the folder is not writable" % a.output)
    W, H = src.RasterXSize, src.RasterYSize
    band = src.GetRasterBand(1)
    nodata = band.GetNoDataValue()
    gt, wkt, dtype = src.GetGeoTransform(), src.GetProjection(), band.DataType
    src = None
    try:
        import dask  # noqa: F401
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        fail("needs python3-dask and python3-distributed (apt-get install python3-distributed)")

    chunk = (a.chunk or max(2048, 4 * margin)) if windows_alone else max(W, H)
    windows = [(x, y, min(chunk, W - x), min(chunk, H - y))
               for y in range(0, H, chunk) for x in range(0, W, chunk)]
    fd, tmp = tempfile.mkstemp(prefix=".%s." % os.path.basename(a.output), suffix=".tif",
                               dir=out_dir)
    os.close(fd)
    tmps = [tmp, tmp + ".cog.tif"]

    def cleanup(*_):
        for p in tmps:
            for q in (p, p + ".aux.xml", p + ".ovr"):
                try:
                    os.unlink(q)
                except OSError:
                    pass

    def on_signal(signum, _frame):
        cleanup()
        sys.stderr.write("%s: interrupted; nothing written\n" % PROG)
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)

    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, on_signal)

    cluster = client = None
    where = a.recipe  # what a failure is named after
    try:
        if a.scheduler:
            client = Client(a.scheduler)
        else:
            # the workers' own logs stay quiet: a failed task is reported once, in one line,
            # by this process (Dask's "Compute Failed" dumps were 19 lines a failure)
            import logging
            # (its HTTP server on a free loopback port: with None it takes 8787, or warns
            # in three lines when another cluster has it)
            cluster = LocalCluster(n_workers=a.workers, threads_per_worker=1,
                                   processes=a.processes, dashboard_address="127.0.0.1:0",
                                   silence_logs=logging.CRITICAL)
            for name in ("distributed", "distributed.worker", "distributed.core",
                         "distributed.nanny", "distributed.scheduler"):
                logging.getLogger(name).setLevel(logging.CRITICAL)
            client = Client(cluster)
        drv = gdal.GetDriverByName("GTiff")
        if not os.environ.get("GDAL_CACHEMAX"):
            # a small block cache: the blocks written are compressed and leave while the
            # workers compute (with GDAL's default, 5 % of RAM, a 16 384^2 raster stayed in
            # the cache and took 13 s on one core to compress at the end)
            gdal.SetCacheMax(128 << 20)
        # a COG follows: the chunks go uncompressed into the intermediate (compressing them
        # twice cost the client CPU the workers need), the COG compresses on every core
        cog = not a.no_overviews and gdal.GetDriverByName("COG") is not None
        # after the predictor (floating point: 3, integers: 2): DEFLATE on a 8192^2 synth
        # output 18 % smaller than alone for the same CPU time (190 vs 233 MB); ZSTD at
        # level 1 the same size within 2 % in a third of DEFLATE's CPU time (186 vs 182 MB,
        # 1.2 vs 3.7 s), which the workers then have
        floating = dtype in (gdal.GDT_Float32, gdal.GDT_Float64)
        codec = a.compress or ("ZSTD" if "ZSTD" in (drv.GetMetadataItem(
            "DMD_CREATIONOPTIONLIST") or "") else "DEFLATE")
        level = {"ZSTD": ["ZSTD_LEVEL=1"], "DEFLATE": []}.get(codec, [])
        predictor = (["PREDICTOR=%d" % (3 if floating else 2)]
                     if codec in ("ZSTD", "DEFLATE", "LZW") else [])
        compress = (["COMPRESS=NONE"] if cog else
                    ["COMPRESS=" + codec] + predictor + level)
        dst = drv.Create(tmp, W, H, 1, dtype,
                         ["TILED=YES", "BLOCKXSIZE=256", "BLOCKYSIZE=256", "BIGTIFF=IF_SAFER"]
                         + compress)
        dst.SetGeoTransform(gt)
        if wkt:
            dst.SetProjection(wkt)
        ob = dst.GetRasterBand(1)
        if nodata is not None:
            ob.SetNoDataValue(nodata)
        recipe = os.path.abspath(a.recipe)
        plugins = os.path.abspath(a.plugins) if a.plugins else a.plugins
        # at most a few chunks in flight per worker: the client holds what has come back
        n_workers = max(1, len(client.scheduler_info().get("workers", {})) or a.workers or 1)
        pending = [] if tile else list(windows)
        futures = as_completed()
        if tile:  # one task per tile, the waves as dependencies
            futs = tile_tasks(client, recipe, plugins, W, H, tile,
                              -(-margin // tile) if margin else 0)
            windows = list(futs)
            futures = as_completed(list(futs.values()))
            futs = None  # the client keeps only what as_completed holds
        for _ in range(min(len(pending), 2 * n_workers)):
            w = pending.pop(0)
            futures.add(client.submit(read_chunk, recipe, a.plugins, *w, pure=True, retries=2))
        # pieces are written in row-major order, each flushed at once, whatever order they
        # come back in: the file's bytes (where each compressed block lies) are then the
        # same on every run; the client holds the pieces that came early
        order = (sorted((tj * tile, ti * tile) for ti, tj in windows) if tile else
                 sorted((w[1], w[0]) for w in windows))
        held, nxt = {}, 0
        done = 0
        for fut in futures:
            where = a.recipe  # a task's failure is the recipe's
            if tile:  # the tile's core out of its window
                win, core, window = fut.result()
                x, y = core[0], core[1]
                # a view of the core (GDAL writes it by its strides: no copy)
                arr = window[y - win[1]:y - win[1] + core[3], x - win[0]:x - win[0] + core[2]]
                if nodata is not None:
                    nan = np.isnan(arr)
                    if nan.any():  # (a synthesis fills every cell: a copy only if not)
                        arr = np.where(nan, np.float32(nodata), arr)
            else:
                x, y, arr = fut.result()
            held[(y, x)] = arr
            where = a.output  # a write's failure is the output's
            while nxt < len(order) and order[nxt] in held:
                y, x = order[nxt]
                ob.WriteArray(held.pop((y, x)), x, y)
                ob.FlushCache()
                nxt += 1
            fut.release()
            done += 1
            if pending:
                w = pending.pop(0)
                futures.add(client.submit(read_chunk, recipe, a.plugins, *w, pure=True,
                                          retries=2))
            if not a.quiet:
                k = 40 * done // len(windows)
                sys.stderr.write("\r[%s%s] %d of %d %s" % ("#" * k, " " * (40 - k), done,
                                                           len(windows),
                                                           "tiles" if tile else "chunks"))
                sys.stderr.flush()
        if not a.quiet:
            sys.stderr.write("\n")
        where = a.output
        if held or nxt != len(order):
            raise RuntimeError("internal error: %d pieces left unwritten" % (len(order) - nxt))
        if a.stats and cluster is not None and not a.processes:
            mb, cpu = worker_stats()  # the workers are threads of this process
            print("%s: %d workers as threads of this process: peak memory %.0f MB (all "
                  "workers and the client), %.1f CPU s" % (PROG, a.workers, mb, cpu))
        elif a.stats:
            for w, (mb, cpu) in sorted(client.run(worker_stats).items()):
                print("%s: worker %s peak memory %.0f MB, %.1f CPU s" % (PROG, w, mb, cpu))
        if a.stats and windows_alone and not tile:
            opens = client.run(recipe_opens)
            print("%s: the recipe opened %d times on %d workers for %d chunks" % (
                PROG, sum(opens.values()), len(opens), len(windows)))
        ob = None
        final = tmp
        if not a.no_overviews:
            levels, f = [], 2
            while max(W, H) // f >= 256:
                levels.append(f)
                f *= 2
            if cog:
                dst = None
                gdal.Translate(tmps[1], tmp, format="COG",
                               creationOptions=["COMPRESS=" + codec]
                                               + (["PREDICTOR=YES"] if predictor else [])
                                               + (["LEVEL=1"] if codec == "ZSTD" else [])
                                               + ["BIGTIFF=IF_SAFER",
                                                "OVERVIEW_RESAMPLING=AVERAGE",
                                                "NUM_THREADS=ALL_CPUS"])
                final = tmps[1]
            elif levels:
                dst.BuildOverviews("AVERAGE", levels)
        dst = None
        # the mode any new file gets under the umask (mkstemp made the temporary 0600)
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(final, 0o666 & ~mask)
        os.replace(final, a.output)
    except Exception as e:  # one line, nothing left behind
        # the output closed quietly first: closing it flushes what is left, and a full
        # disk then raised again from the dataset's destructor (a Python traceback)
        gdal.PushErrorHandler("CPLQuietErrorHandler")
        gdal.DontUseExceptions()
        try:
            ob = dst = None
        except Exception:
            pass
        gdal.UseExceptions()
        gdal.PopErrorHandler()
        msg = str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__
        try:  # (before the cleanup frees what the output took)
            st = os.statvfs(out_dir)
            if where == a.output and st.f_bavail * st.f_frsize < (1 << 20):
                msg = "no space left on its disk (%s)" % msg
        except OSError:
            pass
        cleanup()
        fail("%s: %s" % (where, msg))
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    cleanup()
    if not a.quiet:
        print("%s: %d x %d from %s (%s, %s) in %d %s" % (
            a.output, W, H, os.path.basename(a.recipe), method,
            "tile by tile, four waves" if tile else
            "chunk by chunk" if windows_alone else "whole raster, one task",
            len(windows), "tiles" if tile else "chunks"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
