/*
 * bench_sketch.c - benchmark of sketch-guided synthesis (the lambda sketch).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 *
 * Usage: bench_sketch [DEM.tif]
 *   A. the lambda sketch (data/sketches/lambda_ridges.tif) scaled to
 *      1000 x 1000, from the 1500 x 1500 exemplar;
 *   B. scaled to 2000 x 2000, from a 4096 x 4096 exemplar (the DEM
 *      reflect-tiled).
 * Prints seconds (features, fill stages) and peak RSS; for B the goal line
 * "goal: < 15 s and < 2048 MB: PASS/FAIL".  Each case then runs free
 * synthesis of the same grid from the same exemplar in the same process,
 * its peer, and prints both times and their ratio (goal: <= 1.5, MET or
 * MISS).  Skipped (exit 0) when the default DEM is absent.
 */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>

#include "bench_common.h"
#include "terrasynth.h"
#include "tsio.h"

#ifndef TS_SHARED_DEM_DIR
#define TS_SHARED_DEM_DIR "../shared/data/dem"
#endif
#ifndef TS_DATA_DIR
#define TS_DATA_DIR "data"
#endif
#define DEFAULT_DEM "mountains_aiguestortes_pyrenees_20m_nocrs.tif"

/* Bilinear resize of the sketch to n x n. */
static ts_raster scaled(const ts_raster *s, int n)
{
    ts_raster r;
    int x, y;
    r.width = r.height = n;
    r.stride = n;
    r.data = malloc((size_t)n * (size_t)n * sizeof(float));
    for (y = 0; y < n && r.data; y++)
        for (x = 0; x < n; x++) {
            double fx = (x + 0.5) * s->width / n - 0.5, fy = (y + 0.5) * s->height / n - 0.5;
            int x0 = (int)floor(fx), y0 = (int)floor(fy);
            double ax = fx - x0, ay = fy - y0;
            int x1 = x0 + 1, y1 = y0 + 1;
            if (x0 < 0)
                x0 = 0;
            if (y0 < 0)
                y0 = 0;
            if (x1 >= s->width)
                x1 = s->width - 1;
            if (y1 >= s->height)
                y1 = s->height - 1;
            r.data[(size_t)y * n + x] =
                (float)((1 - ay) * ((1 - ax) * TS_PIX(s, x0, y0) + ax * TS_PIX(s, x1, y0)) +
                        ay * ((1 - ax) * TS_PIX(s, x0, y1) + ax * TS_PIX(s, x1, y1)));
        }
    return r;
}

/* Free synthesis of a w x h grid from ex, the sketch's peer: its seconds, or
 * a negative number on failure. */
static double free_peer(int w, int h, const ts_raster *ex, int tiled)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_synth_params p = ts_synth_params_default();
    ts_raster out;
    double t0, t = -1.0;
    ts_ctx_set_seed(ctx, 1);
    p.tiled = tiled;
    if (ts_raster_alloc(ctx, w, h, &out) == TS_OK) {
        t0 = bench_now_s();
        if (ts_synth_patches(ctx, ex, 1, &p, NULL, &out, NULL) == TS_OK)
            t = bench_now_s() - t0;
        else
            fprintf(stderr, "bench_sketch: free synthesis: %s\n", ts_ctx_message(ctx));
        ts_raster_free(&out);
    }
    ts_ctx_free(ctx);
    return t;
}

static int run_case(const char *name, const ts_raster *sketch, const ts_raster *ex, int tiled,
                    double goal_s, double goal_mb)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_synth_params p = ts_synth_params_default();
    ts_sketch_params sp = ts_sketch_params_default();
    ts_synth_maps maps;
    ts_sketch_info info;
    ts_raster out;
    double t0, t;
    int rc = 0, x;
    memset(&maps, 0, sizeof maps);
    ts_ctx_set_seed(ctx, 1);
    p.tiled = tiled;
    if (ts_raster_alloc(ctx, sketch->width, sketch->height, &out) != TS_OK) {
        ts_ctx_free(ctx);
        return 1;
    }
    for (x = 0; x < sketch->width * sketch->height; x++)
        out.data[x] = NAN;
    t0 = bench_now_s();
    if (ts_synth_sketch(ctx, sketch, ex, 1, &sp, &p, NULL, &out, tiled ? NULL : &maps, NULL,
                        &info) != TS_OK) {
        fprintf(stderr, "bench_sketch: %s\n", ts_ctx_message(ctx));
        rc = 1;
    }
    t = bench_now_s() - t0;
    if (!rc) {
        printf("sketch %s: lambda at %dx%d from %dx%d%s: %.2f s total, %zu feature sites, %zu "
               "feature patches (%zu exemplar sites), %d patches, peak RSS %.0f MB\n",
               name, sketch->width, sketch->height, ex->width, ex->height,
               tiled ? ", in tiles (laid out coarser, amplified)" : "", t, info.n_sites,
               info.n_feature_patches, info.n_exemplar_sites, maps.n_patches, bench_peak_rss_mb());
        printf("  stages: sketch PPA %.2f s, exemplar PPA and relief profiles %.2f s, feature "
               "patches (guide, matching, warps, cuts) %.2f s, fill %.2f s, layout %.2f s, slope "
               "style %.2f s, heights, banks and valley floors %.2f s\n",
               info.seconds_sketch_ppa, info.seconds_exemplar_ppa, info.seconds_features,
               info.seconds_fill, info.seconds_layout, info.seconds_slope_style,
               info.seconds_finish);
        if (!tiled)
            printf("  fill stages: prepare %.2f s, match %.2f s, graph cut %.2f s, Poisson %.2f "
                   "s\n",
                   maps.seconds_prepare, maps.seconds_match, maps.seconds_cut,
                   maps.seconds_poisson);
        if (goal_s > 0)
            bench_goal_line(t, goal_s, goal_mb);
    }
    if (!rc) {
        double tf = free_peer(sketch->width, sketch->height, ex, tiled);
        if (tf > 0)
            printf("  against free synthesis of the same grid%s: sketch %.2f s, free %.2f s, "
                   "ratio %.2f (goal <= 1.5: %s)\n",
                   tiled ? " in the same tiles" : "", t, tf, t / tf,
                   t / tf <= 1.5 ? "MET" : "MISS");
        else
            rc = 1;
    }
    ts_raster_free(&out);
    ts_ctx_free(ctx);
    return rc;
}

int main(int argc, char **argv)
{
    const char *path =
        argc > 1 && strcmp(argv[1], "--tiled") ? argv[1] : TS_SHARED_DEM_DIR "/" DEFAULT_DEM;
    int tiled = argc > 1 && !strcmp(argv[argc - 1], "--tiled");
    struct stat st;
    tsio_raster in, sk;
    tsio_err err;
    ts_raster big, s1, s2;
    int n = 4096, x, y, rc;
    if (argc == 1 + tiled && stat(path, &st) != 0) {
        printf("bench_sketch: skipped: %s not found\n", path);
        return 0;
    }
    if (tsio_read_raster(path, 1, &in, &err) != 0 ||
        tsio_read_raster(TS_DATA_DIR "/sketches/lambda_ridges.tif", 1, &sk, &err) != 0) {
        fprintf(stderr, "bench_sketch: %s\n", err.msg);
        return 1;
    }
    s1 = scaled(&sk.r, tiled ? 2000 : 1000);
    s2 = scaled(&sk.r, tiled ? 4096 : 2000);
    big.data = malloc((size_t)n * (size_t)n * sizeof(float));
    if (!s1.data || !s2.data || !big.data) {
        fprintf(stderr, "bench_sketch: out of memory\n");
        return 1;
    }
    rc = tiled ? 0 : run_case("A", &s1, &in.r, 0, 0, 0);
    big.width = big.height = n;
    big.stride = n;
    for (y = 0; y < n; y++)
        for (x = 0; x < n; x++)
            big.data[(size_t)y * n + x] =
                TS_PIX(&in.r, bench_reflect(x, in.r.width), bench_reflect(y, in.r.height));
    if (tiled) { /* the larger first: the peak RSS printed is the process's so far */
        rc = run_case("D", &s2, &big, 512, 0, 0);
        rc |= run_case("C", &s1, &big, 512, 0, 0);
    } else
        rc |= run_case("B", &s2, &big, 0, 15.0, 2048.0);
    free(big.data);
    free(s1.data);
    free(s2.data);
    tsio_raster_free(&in);
    tsio_raster_free(&sk);
    return rc;
}
