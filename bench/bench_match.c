/*
 * bench_match.c - micro-benchmark of the FFT masked-SSD matcher
 * (algorithms/src/fill/match_ssd.c).
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 *
 * Usage: bench_match [THREADS]   (default 0 = all online processors)
 *
 * For exemplars of 512^2, 1024^2, 2048^2 and 4096^2 cells of random smooth
 * terrain (fractal value noise around 3000 m) and a 64 x 64 target cut from
 * the exemplar with its right half unknown, times ts_matcher_new, one
 * ts_matcher_ssd and one ts_matcher_best (k = 8, min_separation = 32), in
 * seconds per call, averaged over repeated calls (at least 0.3 s each;
 * queries after one untimed warm-up call).  Memory is the heap the matcher
 * holds (glibc mallinfo2, in use after minus before): after
 * ts_matcher_new, and after the first query (+ per-thread scratch).
 * No file I/O; exit status 0 unless a call fails.
 */
#define _POSIX_C_SOURCE 200809L

#include <malloc.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "terrasynth.h"

#define PATCH 64
#define K_BEST 8
#define SEPARATION 32
#define MIN_SECONDS 0.3 /* repeat a call until this much time has passed */

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double heap_mb(void)
{
    struct mallinfo2 mi = mallinfo2();
    return (double)(mi.uordblks + mi.hblkhd) / (1024.0 * 1024.0);
}

static uint64_t rng_next(uint64_t *s)
{
    uint64_t z = (*s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static double rng_uniform(uint64_t *s)
{
    return (double)(rng_next(s) >> 11) / 9007199254740992.0;
}

/* Fractal value noise: lattices every 512, 256, ..., 4 cells, smoothstep
 * interpolation, amplitude halving with the spacing; 3000 m +- ~600 m. */
static float *make_terrain(int n, uint64_t *seed)
{
    float *z = malloc((size_t)n * (size_t)n * sizeof *z);
    int spacing;
    double amp = 400.0;
    if (!z)
        return NULL;
    for (size_t i = 0; i < (size_t)n * (size_t)n; i++)
        z[i] = 3000.0f;
    for (spacing = 512; spacing >= 4; spacing /= 2, amp *= 0.5) {
        const int g = n / spacing + 2;
        float *lat = malloc((size_t)g * (size_t)g * sizeof *lat);
        if (!lat) {
            free(z);
            return NULL;
        }
        for (int i = 0; i < g * g; i++)
            lat[i] = (float)(amp * (2.0 * rng_uniform(seed) - 1.0));
        for (int y = 0; y < n; y++) {
            const int gy = y / spacing;
            double fy = (double)(y % spacing) / spacing;
            fy = fy * fy * (3.0 - 2.0 * fy);
            for (int x = 0; x < n; x++) {
                const int gx = x / spacing;
                double fx = (double)(x % spacing) / spacing;
                fx = fx * fx * (3.0 - 2.0 * fx);
                const float *l0 = lat + (size_t)gy * g + gx, *l1 = l0 + g;
                double top = l0[0] + fx * (l0[1] - l0[0]);
                double bot = l1[0] + fx * (l1[1] - l1[0]);
                z[(size_t)y * n + x] += (float)(top + fy * (bot - top));
            }
        }
        free(lat);
    }
    return z;
}

static int fail(ts_ctx *ctx, const char *what)
{
    fprintf(stderr, "bench_match: %s: %s\n", what, ts_ctx_message(ctx));
    return 1;
}

int main(int argc, char **argv)
{
    static const int sizes[] = {512, 1024, 2048, 4096};
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 42;
    int threads = argc > 1 ? atoi(argv[1]) : 0;
    int rc = 0;
    if (!ctx) {
        fprintf(stderr, "bench_match: out of memory\n");
        return 1;
    }
    ts_ctx_set_threads(ctx, threads);
    printf("bench_match: %dx%d patch (right half unknown), best k=%d sep=%d, threads %d%s\n", PATCH,
           PATCH, K_BEST, SEPARATION, threads, threads == 0 ? " (= all online)" : "");
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0] && rc == 0; s++) {
        const int n = sizes[s], x0 = n / 3, y0 = n / 4;
        float *z = make_terrain(n, &seed);
        float target_data[PATCH * PATCH];
        ts_raster ex, target;
        ts_matcher *m = NULL;
        ts_candidate best[K_BEST];
        float *map = NULL;
        int nx, ny, n_found = 0, reps;
        double t0, t_new, t_ssd, t_best, mb_before, mb_new, mb_query;
        if (!z) {
            fprintf(stderr, "bench_match: out of memory for %d^2\n", n);
            rc = 1;
            break;
        }
        ex = ts_raster_wrap(z, n, n, n);
        for (int j = 0; j < PATCH; j++)
            for (int i = 0; i < PATCH; i++)
                target_data[j * PATCH + i] =
                    i < PATCH / 2 ? TS_PIX(&ex, x0 + i, y0 + j) + (float)rng_uniform(&seed) : NAN;
        target = ts_raster_wrap(target_data, PATCH, PATCH, PATCH);

        /* ts_matcher_new */
        reps = 0;
        t0 = now_s();
        do {
            ts_matcher_free(m);
            m = NULL;
            mb_before = heap_mb();
            if (ts_matcher_new(ctx, &ex, PATCH, PATCH, &m) != TS_OK) {
                rc = fail(ctx, "ts_matcher_new");
                break;
            }
            mb_new = heap_mb() - mb_before;
            reps++;
        } while (now_s() - t0 < MIN_SECONDS);
        t_new = (now_s() - t0) / reps;
        if (rc) {
            free(z);
            break;
        }

        /* ts_matcher_ssd: one untimed call (first touch of the map, worker
         * scratch), then timed calls */
        ts_matcher_positions(m, &nx, &ny);
        map = malloc((size_t)nx * (size_t)ny * sizeof *map);
        if (!map || ts_matcher_ssd(ctx, m, &target, map) != TS_OK) {
            rc = map ? fail(ctx, "ts_matcher_ssd") : 1;
            free(map);
            ts_matcher_free(m);
            free(z);
            break;
        }
        mb_query = heap_mb() - mb_before - (double)nx * ny * sizeof *map / 1048576.0;
        reps = 0;
        t0 = now_s();
        do {
            if (ts_matcher_ssd(ctx, m, &target, map) != TS_OK) {
                rc = fail(ctx, "ts_matcher_ssd");
                break;
            }
            reps++;
        } while (now_s() - t0 < MIN_SECONDS);
        t_ssd = (now_s() - t0) / reps;

        /* ts_matcher_best: the same, one untimed call first */
        reps = 0;
        t0 = 0.0;
        while (rc == 0) {
            if (ts_matcher_best(ctx, m, &target, K_BEST, SEPARATION, best, &n_found) != TS_OK) {
                rc = fail(ctx, "ts_matcher_best");
                break;
            }
            if (t0 == 0.0) {
                t0 = now_s();
                continue;
            }
            reps++;
            if (now_s() - t0 >= MIN_SECONDS)
                break;
        }
        t_best = (now_s() - t0) / (reps ? reps : 1);

        if (rc == 0) {
            printf("%4d^2: new %.4f s, ssd %.4f s, best %.4f s; memory %.1f MB after new, "
                   "%.1f MB after a query; best (%d,%d) ssd %.3g (target cut at (%d,%d)), "
                   "%d found\n",
                   n, t_new, t_ssd, t_best, mb_new, mb_query, best[0].x, best[0].y, best[0].ssd, x0,
                   y0, n_found);
            fflush(stdout);
        }
        free(map);
        ts_matcher_free(m);
        free(z);
    }
    ts_ctx_free(ctx);
    return rc;
}
