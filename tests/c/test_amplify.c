/*
 * test_amplify.c - dictionary amplification (algorithms/src/amplify/):
 * the tiled matching against a brute-force loop over every atom, the D8
 * drainage area against a walk down every flow path, exact reconstruction
 * when the input is the area-averaged exemplar itself, back-projection
 * (the output averages back to the input), orientation (no atom inverted),
 * nodata, determinism across thread counts, errors.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <string.h>

#include "amplify.h"
#include "harness.h"
#include "terrasynth.h"

/* A terrain: random sinusoids with amplitude falling as 1/frequency. */
static ts_raster make_terrain(ts_ctx *ctx, int w, int h, uint64_t seed)
{
    ts_raster r;
    double fx[24], fy[24], ph[24], amp[24];
    int k, x, y;
    uint64_t rng = seed;
    ts_raster_alloc(ctx, w, h, &r);
    for (k = 0; k < 24; k++) {
        double f = 0.01 * pow(1.25, k), a = 2 * 3.14159265 * th_uniform(&rng);
        fx[k] = f * cos(a);
        fy[k] = f * sin(a);
        ph[k] = 6.2831853 * th_uniform(&rng);
        amp[k] = 60.0 / pow(1.25, k);
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double z = 500;
            for (k = 0; k < 24; k++)
                z += amp[k] * sin(fx[k] * x + fy[k] * y + ph[k]);
            TS_PIX(&r, x, y) = (float)z;
        }
    return r;
}

static void test_matching_equals_brute_force(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 320, 256, 7), other = make_terrain(ctx, 160, 128, 9);
    ts_dictionary *D = NULL;
    size_t np = 150, i, k;
    int d, diff = 0;
    float *ph, *pu, *coef, *score;
    double *pa, *ps, w[4];
    int *best;
    uint64_t rng = 3;
    p.factor = 4;
    p.patch = 8;
    p.atoms = 700;
    CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_OK);
    CHECK(ts_dictionary_size(D) > 300 && ts_dictionary_size(D) <= 700);
    d = D->d;
    ph = malloc(np * d * sizeof *ph);
    pu = malloc(np * d * sizeof *pu);
    coef = malloc(np * sizeof *coef);
    score = malloc(np * sizeof *score);
    pa = malloc(np * sizeof *pa);
    ps = malloc(np * sizeof *ps);
    best = malloc(np * sizeof *best);
    /* patches: windows of another terrain, with random drainage vectors */
    for (i = 0; i < np; i++) {
        float win[64], uw[64];
        int x0 = (int)(th_uniform(&rng) * (160 - 8)), y0 = (int)(th_uniform(&rng) * (128 - 8)), j;
        double um, urms;
        for (j = 0; j < d; j++) {
            win[j] = TS_PIX(&other, x0 + j % 8, y0 + j / 8);
            uw[j] = (float)th_uniform(&rng);
        }
        ts__amp_normalise(win, d, ph + i * d, &pa[i], &ps[i]);
        ts__amp_normalise(uw, d, pu + i * d, &um, &urms);
    }
    ts__amp_weights(&p, w);
    ts_ctx_set_threads(ctx, 3);
    CHECK(ts__match_atoms(ctx, D, ph, pu, pa, ps, np, w, best, score, coef) == 0);
    for (i = 0; i < np; i++) {
        /* brute force: every atom, dot products in double, medians by sorting */
        size_t na = D->n;
        double *da = malloc(na * sizeof *da), *ds = malloc(na * sizeof *ds), sa, ss, bg = -1;
        int bk = -1;
        for (k = 0; k < na; k++) {
            da[k] = fabs(pa[i] - D->a[k]);
            ds[k] = fabs(ps[i] - D->s[k]);
        }
        for (k = 0; k < na; k++) /* insertion sorts: slow and plain */
            for (size_t m = k; m > 0 && da[m - 1] > da[m]; m--) {
                double t = da[m];
                da[m] = da[m - 1];
                da[m - 1] = t;
            }
        for (k = 0; k < na; k++)
            for (size_t m = k; m > 0 && ds[m - 1] > ds[m]; m--) {
                double t = ds[m];
                ds[m] = ds[m - 1];
                ds[m - 1] = t;
            }
        sa = da[na / 2] / sqrt(log(2.0));
        ss = ds[na / 2] / sqrt(log(2.0));
        for (k = 0; k < na; k++) {
            double dh = 0, du = 0, g;
            for (int j = 0; j < d; j++) {
                dh += (double)ph[i * d + j] * D->dh[k * d + j];
                du += (double)pu[i * d + j] * D->du[k * d + j];
            }
            g = ts__amp_score(w, dh, du, pa[i] - D->a[k], ps[i] - D->s[k], sa, ss);
            if (g > bg) {
                bg = g;
                bk = (int)k;
            }
        }
        /* the same atom, or one scoring the same within float rounding */
        if (best[i] != bk) {
            diff++;
            CHECK_NEAR(score[i], bg, 1e-5);
        }
        CHECK_NEAR(score[i], bg, 1e-5);
        free(da);
        free(ds);
    }
    CHECK(diff <= 2);
    free(ph);
    free(pu);
    free(coef);
    free(score);
    free(pa);
    free(ps);
    free(best);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
    ts_raster_free(&other);
    ts_ctx_free(ctx);
}

static void test_drainage_against_path_walks(void)
{
    static const int dx[8] = {1, 1, 0, -1, -1, -1, 0, 1}, dy[8] = {0, 1, 1, 1, 0, -1, -1, -1};
    ts_ctx *ctx = ts_ctx_new();
    ts_raster z = make_terrain(ctx, 60, 50, 11), a;
    int x, y, k, W = 60, H = 50;
    static double want[50][60];
    TS_PIX(&z, 10, 10) = NAN;
    ts_raster_alloc(ctx, W, H, &a);
    CHECK(ts_drainage_area(ctx, &z, &a) == TS_OK);
    memset(want, 0, sizeof want);
    /* every cell walks down its flow path, adding one to each cell it passes */
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int cx = x, cy = y, steps = 0;
            if (isnan(TS_PIX(&z, x, y)))
                continue;
            for (;;) {
                int to = -1;
                double best = 0;
                want[cy][cx] += 1;
                for (k = 0; k < 8; k++) {
                    int nx = cx + dx[k], ny = cy + dy[k];
                    double drop;
                    if (nx < 0 || ny < 0 || nx >= W || ny >= H || isnan(TS_PIX(&z, nx, ny)))
                        continue;
                    drop = (TS_PIX(&z, cx, cy) - TS_PIX(&z, nx, ny)) / ((k & 1) ? sqrt(2.0) : 1.0);
                    if (drop > best) {
                        best = drop;
                        to = k;
                    }
                }
                if (to < 0 || ++steps > W * H)
                    break;
                cx += dx[to];
                cy += dy[to];
            }
        }
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            if (isnan(TS_PIX(&z, x, y)))
                CHECK(isnan(TS_PIX(&a, x, y)));
            else
                CHECK_NEAR(TS_PIX(&a, x, y), want[y][x], 1e-3);
        }
    ts_raster_free(&z);
    ts_raster_free(&a);
    ts_ctx_free(ctx);
}

/* Amplify the area average of an exemplar with a dictionary holding every
 * window of it: every patch finds its own atom and the exemplar comes back. */
static void test_exemplar_comes_back(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 192, 160, 5), coarse, out;
    ts_dictionary *D = NULL;
    ts_amplify_info info;
    double err = 0;
    int x, y;
    p.factor = 4;
    p.patch = 8;
    p.atoms = 100000; /* lattice step 1: every window */
    p.refine = 0;
    CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_OK);
    ts_raster_alloc(ctx, 48, 40, &coarse);
    ts_raster_alloc(ctx, 192, 160, &out);
    CHECK(ts_area_average(ctx, &ex, 4, &coarse) == TS_OK);
    CHECK(ts_amplify(ctx, &coarse, D, &p, &out, &info) == TS_OK);
    for (y = 0; y < 160; y++)
        for (x = 0; x < 192; x++)
            err = fmax(err, fabs(TS_PIX(&out, x, y) - TS_PIX(&ex, x, y)));
    CHECK_MSG(err < 0.01, "max error %g m", err);
    CHECK(info.n_inverted == 0 && info.mean_score > 0.999);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
    ts_raster_free(&coarse);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

/* Another terrain amplified: the output, area-averaged, is the input within
 * 1 % of its relief after back-projection; nodata stays nodata; the bytes do
 * not depend on the thread count. */
static void test_back_projection_nodata_threads(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 400, 400, 21), in = make_terrain(ctx, 70, 60, 22), out, out1,
              avg;
    ts_dictionary *D = NULL;
    double lo = 1e30, hi = -1e30, worst = 0;
    int x, y;
    p.factor = 5;
    p.patch = 8;
    TS_PIX(&in, 30, 30) = NAN;
    CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_OK);
    ts_raster_alloc(ctx, 350, 300, &out);
    ts_raster_alloc(ctx, 350, 300, &out1);
    ts_raster_alloc(ctx, 70, 60, &avg);
    ts_ctx_set_threads(ctx, 4);
    CHECK(ts_amplify(ctx, &in, D, &p, &out, NULL) == TS_OK);
    ts_ctx_set_threads(ctx, 1);
    CHECK(ts_amplify(ctx, &in, D, &p, &out1, NULL) == TS_OK);
    CHECK(memcmp(out.data, out1.data, sizeof(float) * 350 * 300) == 0);
    CHECK(isnan(TS_PIX(&out, 152, 153)) && !isnan(TS_PIX(&out, 160, 153)));
    CHECK(ts_area_average(ctx, &out, 5, &avg) == TS_OK);
    for (y = 0; y < 60; y++)
        for (x = 0; x < 70; x++) {
            float v = TS_PIX(&in, x, y);
            if (isnan(v))
                continue;
            lo = fmin(lo, v);
            hi = fmax(hi, v);
        }
    for (y = 0; y < 60; y++)
        for (x = 0; x < 70; x++)
            if (!isnan(TS_PIX(&in, x, y)))
                worst = fmax(worst, fabs(TS_PIX(&avg, x, y) - TS_PIX(&in, x, y)));
    CHECK_MSG(worst < 0.01 * (hi - lo), "worst %g m of a %g m relief", worst, hi - lo);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
    ts_raster_free(&in);
    ts_raster_free(&out);
    ts_raster_free(&out1);
    ts_raster_free(&avg);
    ts_ctx_free(ctx);
}

/* The only atom is the input upside down: the shape term alone would take it
 * inverted; it is refused (the patch stays flat) and counted. */
static void test_no_atom_inverted(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 32, 32, 31), coarse, out;
    ts_dictionary *D = NULL;
    ts_amplify_info info;
    double m = 0;
    int x, y;
    p.factor = 4;
    p.patch = 8;
    p.refine = 0;
    p.w_a = p.w_s = p.w_u = 0;
    p.w_h = 1;
    CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_OK);
    CHECK(ts_dictionary_size(D) == 1);
    ts_raster_alloc(ctx, 8, 8, &coarse);
    ts_raster_alloc(ctx, 32, 32, &out);
    CHECK(ts_area_average(ctx, &ex, 4, &coarse) == TS_OK);
    for (y = 0; y < 8; y++)
        for (x = 0; x < 8; x++) {
            TS_PIX(&coarse, x, y) = 1000.0f - TS_PIX(&coarse, x, y);
            m += TS_PIX(&coarse, x, y) / 64.0;
        }
    CHECK(ts_amplify(ctx, &coarse, D, &p, &out, &info) == TS_OK);
    CHECK(info.n_inverted == 1);
    for (y = 0; y < 32; y++)
        for (x = 0; x < 32; x++)
            CHECK_NEAR(TS_PIX(&out, x, y), m, 1e-2);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
    ts_raster_free(&coarse);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

/* Windows of every size and place, at the edges too, with nodata and any
 * number of back-projection passes: byte for byte the window of the whole. */
static void test_windows_equal_the_whole(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 300, 260, 41), in = make_terrain(ctx, 53, 47, 42), drain,
              whole, win;
    ts_dictionary *D = NULL;
    uint64_t rng = 5;
    int refine, k, x, y;
    p.factor = 4;
    TS_PIX(&in, 20, 11) = NAN;
    TS_PIX(&in, 0, 46) = NAN;
    ts_raster_alloc(ctx, 53, 47, &drain);
    CHECK(ts_drainage_area(ctx, &in, &drain) == TS_OK);
    ts_raster_alloc(ctx, 212, 188, &whole);
    for (refine = 0; refine <= 4; refine += 2) {
        p.refine = refine;
        CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_OK);
        CHECK(ts_amplify(ctx, &in, D, &p, &whole, NULL) == TS_OK);
        for (k = 0; k < 12; k++) {
            int w = 1 + (int)(th_uniform(&rng) * 90), h = 1 + (int)(th_uniform(&rng) * 90);
            int x0 = (int)(th_uniform(&rng) * (212 - w)), y0 = (int)(th_uniform(&rng) * (188 - h));
            int same = 1;
            if (k == 0)
                x0 = y0 = 0; /* the corners */
            if (k == 1)
                x0 = 212 - w, y0 = 188 - h;
            ts_raster_alloc(ctx, w, h, &win);
            ts_ctx_set_threads(ctx, 1 + k % 3);
            CHECK(ts_amplify_window(ctx, &in, &drain, D, &p, x0, y0, &win, NULL) == TS_OK);
            for (y = 0; y < h; y++)
                for (x = 0; x < w; x++)
                    same &= memcmp(&TS_PIX(&win, x, y), &TS_PIX(&whole, x0 + x, y0 + y),
                                   sizeof(float)) == 0;
            CHECK_MSG(same, "refine %d window %d,%d %dx%d differs", refine, x0, y0, w, h);
            ts_raster_free(&win);
        }
        ts_dictionary_free(D);
        D = NULL;
    }
    ts_raster_alloc(ctx, 10, 10, &win);
    CHECK(ts_amplify_window(ctx, &in, &drain, D ? D : NULL, &p, 0, 0, &win, NULL) == TS_ERR_ARG);
    ts_raster_free(&win);
    ts_raster_free(&ex);
    ts_raster_free(&in);
    ts_raster_free(&drain);
    ts_raster_free(&whole);
    ts_ctx_free(ctx);
}

/* A dictionary through bytes gives the same output; damaged bytes are
 * refused with a message, never read past their end. */
static void test_dictionary_bytes(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 200, 180, 51), in = make_terrain(ctx, 30, 26, 52), a, b;
    ts_dictionary *D = NULL, *E = NULL;
    unsigned char *bytes = NULL, *bad;
    size_t len = 0, k;
    int f, pa;
    uint64_t rng = 9;
    p.factor = 3;
    CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_OK);
    CHECK(ts_dictionary_to_bytes(ctx, D, &bytes, &len) == TS_OK);
    CHECK(memcmp(bytes, "TSDICT\r\n", 8) == 0 && bytes[8] == 1 && bytes[12] == 3);
    CHECK(ts_dictionary_from_bytes(ctx, bytes, len, &E) == TS_OK);
    ts_dictionary_shape(E, &f, &pa);
    CHECK(f == 3 && pa == p.patch && ts_dictionary_size(E) == ts_dictionary_size(D));
    ts_raster_alloc(ctx, 90, 78, &a);
    ts_raster_alloc(ctx, 90, 78, &b);
    CHECK(ts_amplify(ctx, &in, D, &p, &a, NULL) == TS_OK);
    CHECK(ts_amplify(ctx, &in, E, &p, &b, NULL) == TS_OK);
    CHECK(memcmp(a.data, b.data, sizeof(float) * 90 * 78) == 0);
    ts_dictionary_free(E);
    E = NULL;
    /* truncated, wrong magic, another version, a header that lies */
    CHECK(ts_dictionary_from_bytes(ctx, bytes, len - 1, &E) == TS_ERR_ARG && !E);
    CHECK(strstr(ts_ctx_message(ctx), "damaged") != NULL);
    bad = malloc(len);
    memcpy(bad, bytes, len);
    bad[0] = 'X';
    CHECK(ts_dictionary_from_bytes(ctx, bad, len, &E) == TS_ERR_ARG && !E);
    CHECK(strstr(ts_ctx_message(ctx), "not a TerraSynth dictionary") != NULL);
    memcpy(bad, bytes, len);
    bad[8] = 2;
    CHECK(ts_dictionary_from_bytes(ctx, bad, len, &E) == TS_ERR_ARG && !E);
    CHECK(strstr(ts_ctx_message(ctx), "version 2") != NULL);
    for (k = 0; k < 2000; k++) { /* random damage to the header: a clean refusal or a load */
        size_t at = (size_t)(th_uniform(&rng) * 40);
        memcpy(bad, bytes, len);
        bad[at] = (unsigned char)(th_uniform(&rng) * 256);
        if (ts_dictionary_from_bytes(ctx, bad, len, &E) == TS_OK) {
            ts_dictionary_free(E);
            E = NULL;
        }
    }
    free(bad);
    free(bytes);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
    ts_raster_free(&in);
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_ctx_free(ctx);
}

static void test_errors(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 40, 40, 1), small, out;
    ts_dictionary *D = NULL;
    p.factor = 8; /* 40 / 8 = 5 low-resolution cells < a patch of 8 */
    CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_ERR_SIZE && !D);
    CHECK(strstr(ts_ctx_message(ctx), "smaller than a patch") != NULL);
    p = ts_amplify_params_default();
    p.factor = 1;
    CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_ERR_ARG);
    p = ts_amplify_params_default();
    p.factor = 2;
    CHECK(ts_dictionary_build(ctx, &ex, 1, &p, &D) == TS_OK);
    ts_raster_alloc(ctx, 4, 4, &small);
    ts_raster_alloc(ctx, 8, 8, &out);
    CHECK(ts_amplify(ctx, &small, D, &p, &out, NULL) == TS_ERR_SIZE);
    p.factor = 3;
    CHECK(ts_amplify(ctx, &small, D, &p, &out, NULL) == TS_ERR_ARG);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
    ts_raster_free(&small);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"matching_equals_brute_force", test_matching_equals_brute_force},
        {"drainage_against_path_walks", test_drainage_against_path_walks},
        {"exemplar_comes_back", test_exemplar_comes_back},
        {"back_projection_nodata_threads", test_back_projection_nodata_threads},
        {"no_atom_inverted", test_no_atom_inverted},
        {"windows_equal_the_whole", test_windows_equal_the_whole},
        {"dictionary_bytes", test_dictionary_bytes},
        {"errors", test_errors},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
