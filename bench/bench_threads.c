/*
 * bench_threads.c - thread scaling of every method, on a machine without GDAL.
 *
 * bench_threads DEM.f32 WIDTH HEIGHT [--threads 1,2,4,8,16] [--jobs LIST] [--size N]
 *
 * DEM.f32 is the raw little-endian float32 raster (row-major, NaN = nodata)
 * that `gdal_translate -of ENVI -ot Float32 DEM.tif DEM.f32` writes, so this
 * program links the core alone (libterrasynth, FFTW) and can be copied to a
 * many-core machine that has neither GDAL nor the shared data.  Each job runs
 * on each thread count (ts_ctx_set_threads) and prints its seconds, the
 * speed-up over the first count, Amdahl's parallel fraction from the first
 * and the last, and a hash of its output: the bytes must not depend on the
 * thread count (the line says "same bytes" or "DIFFERENT BYTES").
 *
 * Jobs (default all):
 *   ppa      ts_ppa_extract, ridges and valleys (default parameters: valleys
 *            where the water runs) on a SIZE^2 reflect-tiled mosaic (4096)
 *   ridges   the same, ridges alone (no ridge/valley split to help)
 *   profile  ts_ppa_profile_recognition alone (both kinds)
 *   synth    ts_synth_patches in one piece, SIZE/2 square from a SIZE/2 mosaic
 *   tiled    ts_synth_tiled, SIZE/2 square in tiles of SIZE/16 (64 tiles,
 *            16 a wave) from the SIZE/2 mosaic
 *   tilesched  the tiled job's tiles made one at a time through the public
 *            ts_synth_tiles (1 thread each, waves in order), each timed, the
 *            cores put together (their hash must be the tiled job's), then the
 *            core's schedule replayed for each thread count: within a wave,
 *            each free thread takes the next tile in row order, a wave starts
 *            when the last one ends.  Prints the schedule's speed-up (how far
 *            the tiles' costs and the waves' barriers let the threads go,
 *            before memory bandwidth and clocks), to set beside the tiled
 *            job's measured one where the machine has fewer cores than asked
 *   pixel    ts_pixel_synthesize 1024^2 from the 512^2 centre of the DEM
 *   amplify  ts_amplify x8 of a SIZE/16 area average of the mosaic (a
 *            dictionary of the mosaic's SIZE/2 centre)
 * For the PPA jobs the time at which each progress message was last seen
 * is printed too (the end of each stage: profile recognition, drainage,
 * polygon breaking, branch reduction, ridges/valleys), so a stage that does
 * not scale shows.
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#define _POSIX_C_SOURCE 200809L

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_common.h"
#include "terrasynth.h"

#define MAX_THREADS_LIST 16
#define MAX_MARKS 16

typedef struct marks {
    double t0;
    int n;
    char msg[MAX_MARKS][48];
    double last[MAX_MARKS];
    char extra[160]; /* a job's own stage figures */
} marks;

static int on_progress(double done, const char *msg, void *user)
{
    marks *m = user;
    int i;
    (void)done;
    if (!msg || !*msg)
        return 1;
    for (i = 0; i < m->n; i++)
        if (strcmp(m->msg[i], msg) == 0)
            break;
    if (i == m->n) {
        if (m->n == MAX_MARKS)
            return 1;
        snprintf(m->msg[m->n], sizeof m->msg[0], "%s", msg);
        m->n++;
    }
    m->last[i] = bench_now_s() - m->t0;
    return 1;
}

static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    size_t i;
    for (i = 0; i < n; i++) {
        h ^= b[i];
        h *= 1099511628211ull;
    }
    return h;
}

static uint64_t hash_raster(const ts_raster *r)
{
    uint64_t h = 1469598103934665603ull;
    int y;
    for (y = 0; y < r->height; y++)
        h = fnv(h, r->data + (ptrdiff_t)y * r->stride, (size_t)r->width * sizeof(float));
    return h;
}

/* A square n x n reflect-tiled mosaic of src, centred crop when n < src. */
static int mosaic(const ts_raster *src, int n, ts_raster *out)
{
    int x, y;
    out->data = malloc((size_t)n * (size_t)n * sizeof(float));
    if (!out->data)
        return 1;
    out->width = out->height = n;
    out->stride = n;
    for (y = 0; y < n; y++)
        for (x = 0; x < n; x++)
            out->data[(size_t)y * n + x] =
                TS_PIX(src, bench_reflect(x, src->width), bench_reflect(y, src->height));
    return 0;
}

typedef struct job_input {
    const ts_raster *dem;    /* the DEM as read */
    const ts_raster *big;    /* SIZE^2 mosaic */
    const ts_raster *half;   /* SIZE/2 mosaic */
    int size;
} job_input;

/* Run one job on `threads` threads; *seconds, *hash out; marks filled for PPA jobs. */
static int run_job(const char *job, const job_input *in, int threads, double *seconds,
                   uint64_t *hash, marks *mk)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_status st = TS_OK;
    double t0;
    ts_ctx_set_threads(ctx, threads);
    ts_ctx_set_seed(ctx, 7);
    memset(mk, 0, sizeof *mk);
    ts_ctx_set_progress(ctx, on_progress, mk);
    t0 = bench_now_s();
    mk->t0 = t0;
    *hash = 0;
    if (!strcmp(job, "ppa") || !strcmp(job, "ridges")) {
        ts_ppa_params p = ts_ppa_params_default();
        ts_features *f = NULL;
        p.features = !strcmp(job, "ppa") ? TS_PPA_BOTH : TS_PPA_RIDGES;
        st = ts_ppa_extract(ctx, in->big, NULL, &p, &f);
        *seconds = bench_now_s() - t0;
        if (st == TS_OK) {
            *hash = fnv(1469598103934665603ull, f->mask,
                        (size_t)in->big->width * (size_t)in->big->height);
            ts_features_free(f);
        }
    } else if (!strcmp(job, "profile")) {
        size_t n = (size_t)in->big->width * (size_t)in->big->height;
        unsigned char *t = malloc(n);
        if (!t) {
            ts_ctx_free(ctx);
            return 1;
        }
        st = ts_ppa_profile_recognition(ctx, in->big, ts_ppa_params_default().profile_length,
                                        20.0, TS_RIDGE | TS_VALLEY, t);
        *seconds = bench_now_s() - t0;
        if (st == TS_OK)
            *hash = fnv(1469598103934665603ull, t, n);
        free(t);
    } else if (!strcmp(job, "synth") || !strcmp(job, "tiled")) {
        ts_synth_params p = ts_synth_params_default();
        ts_synth_maps maps;
        ts_raster out;
        int n = in->half->width;
        memset(&maps, 0, sizeof maps);
        if ((st = ts_raster_alloc(ctx, n, n, &out)) == TS_OK) {
            if (!strcmp(job, "synth")) {
                st = ts_synth_patches(ctx, in->half, 1, &p, NULL, &out, &maps);
                snprintf(mk->extra, sizeof mk->extra,
                         "  [%d patches; summed: prepare %.2f match %.2f cut %.2f poisson %.2f]",
                         maps.n_patches, maps.seconds_prepare, maps.seconds_match,
                         maps.seconds_cut, maps.seconds_poisson);
            } else
                st = ts_synth_tiled(ctx, in->half, 1, &p, NULL, in->size / 16, &out);
            *seconds = bench_now_s() - t0;
            if (st == TS_OK)
                *hash = hash_raster(&out);
            ts_raster_free(&out);
        }
    } else if (!strcmp(job, "pixel")) {
        ts_pixel_params p = ts_pixel_params_default();
        ts_pixel_exemplars *ex = NULL;
        ts_raster crop = *in->dem, out;
        int c = in->dem->width < in->dem->height ? in->dem->width : in->dem->height;
        if (c > 512)
            c = 512;
        crop.data += (ptrdiff_t)((in->dem->height - c) / 2) * crop.stride +
                     (in->dem->width - c) / 2;
        crop.width = crop.height = c;
        if ((st = ts_raster_alloc(ctx, 1024, 1024, &out)) == TS_OK) {
            st = ts_pixel_prepare(ctx, &crop, 1, &p, &ex);
            if (st == TS_OK)
                st = ts_pixel_synthesize(ctx, ex, &p, 0, 0, &out);
            *seconds = bench_now_s() - t0;
            if (st == TS_OK)
                *hash = hash_raster(&out);
            ts_pixel_exemplars_free(ex);
            ts_raster_free(&out);
        }
    } else if (!strcmp(job, "amplify")) {
        ts_amplify_params p = ts_amplify_params_default();
        ts_dictionary *dict = NULL;
        ts_exemplar ex;
        ts_raster coarse, out;
        int f = 8, nc = in->size / 16;
        memset(&ex, 0, sizeof ex);
        ex.dem = *in->half;
        p.factor = f;
        coarse.data = NULL;
        out.data = NULL;
        if ((st = ts_raster_alloc(ctx, nc, nc, &coarse)) == TS_OK &&
            (st = ts_area_average(ctx, in->big, in->size / nc, &coarse)) == TS_OK &&
            (st = ts_raster_alloc(ctx, nc * f, nc * f, &out)) == TS_OK &&
            (st = ts_dictionary_build(ctx, &ex, 1, NULL, 0, &p, &dict)) == TS_OK)
            st = ts_amplify(ctx, &coarse, NULL, dict, &p, &out, NULL, NULL);
        *seconds = bench_now_s() - t0;
        if (st == TS_OK)
            *hash = hash_raster(&out);
        ts_dictionary_free(dict);
        ts_raster_free(&coarse);
        ts_raster_free(&out);
    } else {
        fprintf(stderr, "bench_threads: unknown job '%s'\n", job);
        ts_ctx_free(ctx);
        return 1;
    }
    if (st != TS_OK) {
        fprintf(stderr, "bench_threads: %s on %d threads: %s\n", job, threads,
                ts_ctx_message(ctx));
        ts_ctx_free(ctx);
        return 1;
    }
    ts_ctx_free(ctx);
    return 0;
}

/* The tilesched job (see the top): returns 0, or 1 on failure. */
static int tile_schedule(const job_input *in, const int *threads, int n_threads)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_synth_params p = ts_synth_params_default();
    int n = in->half->width, T = in->size / 16, nti = (n + T - 1) / T, ntj = nti;
    int ti, tj, w, k, di, dj, y, rc = 1;
    size_t nt = (size_t)nti * (size_t)ntj;
    ts_raster *win = calloc(nt, sizeof *win), out;
    double *sec = calloc(nt, sizeof *sec), total = 0;
    out.data = NULL;
    if (!ctx || !win || !sec || ts_raster_alloc(ctx, n, n, &out) != TS_OK)
        goto done;
    ts_ctx_set_threads(ctx, 1);
    ts_ctx_set_seed(ctx, 7);
    for (w = 0; w < 4; w++)
        for (tj = 0; tj < ntj; tj++)
            for (ti = 0; ti < nti; ti++) {
                ts_synth_tile t;
                int wr[4], cr[4];
                size_t at = (size_t)tj * (size_t)nti + (size_t)ti;
                double t0;
                if ((ti & 1) + 2 * (tj & 1) != w)
                    continue;
                memset(&t, 0, sizeof t);
                t.ti = ti;
                t.tj = tj;
                if (ts_synth_tile_window(ctx, &p, T, n, n, ti, tj, wr, cr) != TS_OK ||
                    ts_raster_alloc(ctx, wr[2], wr[3], &win[at]) != TS_OK)
                    goto done;
                t.window = win[at];
                for (dj = -1; dj <= 1; dj++)
                    for (di = -1; di <= 1; di++) {
                        int ni = ti + di, nj = tj + dj;
                        if ((di || dj) && ni >= 0 && nj >= 0 && ni < nti && nj < ntj &&
                            (ni & 1) + 2 * (nj & 1) < w)
                            t.neighbours[(dj + 1) * 3 + di + 1] =
                                &win[(size_t)nj * (size_t)nti + (size_t)ni];
                    }
                t0 = bench_now_s();
                if (ts_synth_tiles(ctx, in->half, 1, &p, T, n, n, &t, 1) != TS_OK)
                    goto done;
                sec[at] = bench_now_s() - t0;
                total += sec[at];
                for (y = 0; y < cr[3]; y++)
                    memcpy(&TS_PIX(&out, cr[0], cr[1] + y),
                           &TS_PIX(&win[at], cr[0] - wr[0], cr[1] - wr[1] + y),
                           (size_t)cr[2] * sizeof(float));
            }
    printf("tilesched %d tiles of %d, made one by one: %.2f s in all (hash %016llx: the "
           "tiled job's)\n",
           (int)nt, T, total, (unsigned long long)hash_raster(&out));
    for (k = 0; k < n_threads; k++) {
        double clock = 0, freeat[64];
        int P = threads[k] < 1 ? 1 : threads[k] > 64 ? 64 : threads[k], q;
        for (w = 0; w < 4; w++) {
            double end = clock;
            for (q = 0; q < P; q++)
                freeat[q] = clock;
            for (tj = 0; tj < ntj; tj++)
                for (ti = 0; ti < nti; ti++) {
                    int first = 0;
                    if ((ti & 1) + 2 * (tj & 1) != w)
                        continue;
                    for (q = 1; q < P; q++) /* the first thread free takes it */
                        if (freeat[q] < freeat[first])
                            first = q;
                    freeat[first] += sec[(size_t)tj * (size_t)nti + (size_t)ti];
                    if (freeat[first] > end)
                        end = freeat[first];
                }
            clock = end; /* the wave's barrier */
        }
        printf("tilesched %2d threads: %7.2f s by the schedule, x%5.2f (ideal x%d)\n", P, clock,
               total / clock, P);
    }
    rc = 0;
done:
    if (rc)
        fprintf(stderr, "bench_threads: tilesched: %s\n",
                ctx ? ts_ctx_message(ctx) : "out of memory");
    if (win)
        for (k = 0; k < (int)nt; k++)
            ts_raster_free(&win[k]);
    free(win);
    free(sec);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
    return rc;
}

int main(int argc, char **argv)
{
    const char *jobs = "ppa,ridges,profile,synth,tiled,tilesched,pixel,amplify";
    int threads[MAX_THREADS_LIST] = {1, 2, 4, 8, 16}, n_threads = 5, size = 4096;
    int w, h, i, rc = 0;
    ts_raster dem, big, half;
    job_input in;
    char *list, *job, *save = NULL;
    FILE *fp;
    size_t n;
    if (argc < 4) {
        fprintf(stderr, "usage: bench_threads DEM.f32 WIDTH HEIGHT [--threads 1,2,4,8,16] "
                        "[--jobs ppa,ridges,profile,synth,tiled,tilesched,pixel,amplify] "
                        "[--size 4096]\n");
        return 2;
    }
    w = atoi(argv[2]);
    h = atoi(argv[3]);
    for (i = 4; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--threads")) {
            char *s = argv[i + 1], *end;
            n_threads = 0;
            while (*s && n_threads < MAX_THREADS_LIST) {
                threads[n_threads++] = (int)strtol(s, &end, 10);
                s = *end ? end + 1 : end;
            }
        } else if (!strcmp(argv[i], "--jobs")) {
            jobs = argv[i + 1];
        } else if (!strcmp(argv[i], "--size")) {
            size = atoi(argv[i + 1]);
        } else {
            fprintf(stderr, "bench_threads: unknown option %s\n", argv[i]);
            return 2;
        }
    }
    if (w < 16 || h < 16 || size < 256 || size > 32768 || n_threads < 1) {
        fprintf(stderr, "bench_threads: bad size (%dx%d, --size %d)\n", w, h, size);
        return 2;
    }
    n = (size_t)w * (size_t)h;
    dem.data = malloc(n * sizeof(float));
    dem.width = w;
    dem.height = h;
    dem.stride = w;
    fp = fopen(argv[1], "rb");
    if (!dem.data || !fp || fread(dem.data, sizeof(float), n, fp) != n) {
        fprintf(stderr, "bench_threads: %s: cannot read %dx%d float32\n", argv[1], w, h);
        return 1;
    }
    fclose(fp);
    if (mosaic(&dem, size, &big) || mosaic(&dem, size / 2, &half)) {
        fprintf(stderr, "bench_threads: out of memory\n");
        return 1;
    }
    in.dem = &dem;
    in.big = &big;
    in.half = &half;
    in.size = size;
    printf("dem %s %dx%d, mosaic %d^2 (half %d^2)\n", argv[1], w, h, size, size / 2);
    list = strdup(jobs);
    for (job = strtok_r(list, ",", &save); job; job = strtok_r(NULL, ",", &save)) {
        double sec[MAX_THREADS_LIST];
        uint64_t hash[MAX_THREADS_LIST];
        int same = 1, k;
        if (!strcmp(job, "tilesched")) {
            rc |= tile_schedule(&in, threads, n_threads);
            continue;
        }
        for (i = 0; i < n_threads; i++) {
            marks mk;
            if (run_job(job, &in, threads[i], &sec[i], &hash[i], &mk)) {
                rc = 1;
                break;
            }
            same &= hash[i] == hash[0];
            printf("%-8s %2d threads: %7.2f s  x%5.2f  hash %016llx", job, threads[i], sec[i],
                   sec[0] / sec[i], (unsigned long long)hash[i]);
            if (!strcmp(job, "ppa") || !strcmp(job, "ridges"))
                for (k = 0; k < mk.n; k++)
                    printf("  [%s %.2f]", mk.msg[k], mk.last[k]);
            printf("%s\n", mk.extra);
            fflush(stdout);
        }
        if (i == n_threads && n_threads > 1) {
            double s = sec[0] / sec[n_threads - 1], nn = (double)threads[n_threads - 1] /
                                                          threads[0];
            double p = (1.0 - 1.0 / s) / (1.0 - 1.0 / nn);
            printf("%-8s %d -> %d threads: x%.2f, parallel fraction p = %.2f, %s\n", job,
                   threads[0], threads[n_threads - 1], s, p,
                   same ? "same bytes" : "DIFFERENT BYTES");
        }
    }
    printf("peak RSS %.0f MB\n", bench_peak_rss_mb());
    free(list);
    free(dem.data);
    free(big.data);
    free(half.data);
    return rc;
}
