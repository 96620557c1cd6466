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

/* A dictionary from one exemplar and nothing else. */
static ts_status build1(ts_ctx *ctx, const ts_raster *dem, const ts_amplify_params *p,
                        ts_dictionary **D)
{
    ts_exemplar e;
    memset(&e, 0, sizeof e);
    e.dem = *dem;
    return ts_dictionary_build(ctx, &e, 1, NULL, 0, p, D);
}

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
    ts_raster lat, cls;
    ts_exemplar e;
    ts_dictionary *D = NULL;
    size_t np = 150, i, k;
    int d, K, diff = 0, x, y;
    float *ph, *pu, *pl, *pc, *px, *coef, *score;
    double *pa, *ps, w[AMP_NW];
    int *best;
    uint64_t rng = 3;
    amp_patches pt;
    p.factor = 4;
    p.patch = 8;
    p.atoms = 700;
    p.w_l = 0.15;
    p.w_c = 0.3;
    p.w_x = 0.25;
    /* an exemplar with its latitude (irradiance) and three classes in bands */
    ts_raster_alloc(ctx, 80, 64, &lat);
    ts_raster_alloc(ctx, 320, 256, &cls);
    for (y = 0; y < 64; y++)
        for (x = 0; x < 80; x++)
            TS_PIX(&lat, x, y) = 46.5f - 0.01f * y;
    for (y = 0; y < 256; y++)
        for (x = 0; x < 320; x++)
            TS_PIX(&cls, x, y) = x < 100 ? 1.0f : x < 200 ? (y < 128 ? 2.0f : NAN) : 3.0f;
    memset(&e, 0, sizeof e);
    e.dem = ex;
    e.dx = e.dy = 30;
    e.classes = &cls;
    e.lat = &lat;
    CHECK(ts_dictionary_build(ctx, &e, 1, NULL, 0, &p, &D) == TS_OK);
    CHECK(D->dl && D->n_classes == 3);
    d = D->d;
    K = D->n_classes;
    ph = malloc(np * d * sizeof *ph);
    pu = malloc(np * d * sizeof *pu);
    pl = malloc(np * d * sizeof *pl);
    pc = malloc(np * K * sizeof *pc);
    px = malloc(np * d * sizeof *px);
    coef = malloc(np * sizeof *coef);
    score = malloc(np * sizeof *score);
    pa = malloc(np * sizeof *pa);
    ps = malloc(np * sizeof *ps);
    best = malloc(np * sizeof *best);
    /* patches: windows of another terrain, with random drainage, irradiance and
     * class vectors */
    for (i = 0; i < np; i++) {
        float win[64], uw[64], lw[64], cw[3];
        int x0 = (int)(th_uniform(&rng) * (160 - 8)), y0 = (int)(th_uniform(&rng) * (128 - 8)), j;
        double um, urms, cn = 0;
        for (j = 0; j < d; j++) {
            win[j] = TS_PIX(&other, x0 + j % 8, y0 + j / 8);
            uw[j] = (float)th_uniform(&rng);
            lw[j] = (float)th_uniform(&rng);
        }
        for (j = 0; j < K; j++) {
            cw[j] = (float)th_uniform(&rng);
            cn += cw[j] * cw[j];
        }
        for (j = 0; j < K; j++)
            pc[i * K + j] = (float)(cw[j] / sqrt(cn));
        ts__amp_normalise(win, d, ph + i * d, &pa[i], &ps[i]);
        ts__amp_normalise(uw, d, pu + i * d, &um, &urms);
        ts__amp_normalise(lw, d, pl + i * d, &um, &urms);
        ts__amp_context(&other, x0, y0, 8, px + i * d); /* the real context there */
    }
    ts__amp_weights(&p, 1, 1, w);
    ts_ctx_set_threads(ctx, 3);
    pt.n = np;
    pt.ph = ph;
    pt.pu = pu;
    pt.pl = pl;
    pt.pc = pc;
    pt.px = px;
    pt.pa = pa;
    pt.ps = ps;
    CHECK(ts__match_atoms(ctx, D, &pt, w, best, score, coef) == 0);
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
            double dh = 0, du = 0, dl = 0, dc = 0, dx = 0, g;
            for (int j = 0; j < d; j++) {
                dh += (double)ph[i * d + j] * D->dh[k * d + j];
                du += (double)pu[i * d + j] * D->du[k * d + j];
                dl += (double)pl[i * d + j] * D->dl[k * d + j];
                dx += (double)px[i * d + j] * D->dx[k * d + j];
            }
            for (int j = 0; j < K; j++)
                dc += (double)pc[i * K + j] * D->dc[k * K + j];
            g = ts__amp_score(w, dh, du, dl, dc, dx, pa[i] - D->a[k], ps[i] - D->s[k], sa, ss);
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
    free(pl);
    free(pc);
    free(px);
    ts_raster_free(&lat);
    ts_raster_free(&cls);
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

/* The drainage area of z against every cell walking down its flow path. */
static void drainage_against_path_walks(ts_ctx *ctx, ts_raster z)
{
    static const int dx[8] = {1, 1, 0, -1, -1, -1, 0, 1}, dy[8] = {0, 1, 1, 1, 0, -1, -1, -1};
    ts_raster a;
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
}

static void test_drainage_against_path_walks(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster z = make_terrain(ctx, 60, 50, 11);
    int x, y;
    drainage_against_path_walks(ctx, z);
    /* heights below and above 0, -0 and 0, in steps of 10: flats and ties everywhere
     * (the cells are sorted by their bits) */
    z = make_terrain(ctx, 60, 50, 12);
    for (y = 0; y < 50; y++)
        for (x = 0; x < 60; x++)
            TS_PIX(&z, x, y) =
                (x + y) % 7 == 0 ? -0.0f : 10.0f * roundf(TS_PIX(&z, x, y) / 10.0f) - 500.0f;
    drainage_against_path_walks(ctx, z);
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
    CHECK(build1(ctx, &ex, &p, &D) == TS_OK);
    ts_raster_alloc(ctx, 48, 40, &coarse);
    ts_raster_alloc(ctx, 192, 160, &out);
    CHECK(ts_area_average(ctx, &ex, 4, &coarse) == TS_OK);
    CHECK(ts_amplify(ctx, &coarse, NULL, D, &p, &out, NULL, &info) == TS_OK);
    for (y = 0; y < 160; y++)
        for (x = 0; x < 192; x++)
            err = fmax(err, fabs(TS_PIX(&out, x, y) - TS_PIX(&ex, x, y)));
    CHECK_MSG(err < 0.01, "max error %g m", err);
    CHECK(info.n_inverted == 0 && info.mean_score > 0.999);
    /* with the context term too: the atom's neighbourhood is the patch's */
    p.w_x = 0.3;
    CHECK(ts_amplify(ctx, &coarse, NULL, D, &p, &out, NULL, &info) == TS_OK);
    err = 0;
    for (y = 0; y < 160; y++)
        for (x = 0; x < 192; x++)
            err = fmax(err, fabs(TS_PIX(&out, x, y) - TS_PIX(&ex, x, y)));
    CHECK_MSG(err < 0.01, "with context: max error %g m", err);
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
    CHECK(build1(ctx, &ex, &p, &D) == TS_OK);
    ts_raster_alloc(ctx, 350, 300, &out);
    ts_raster_alloc(ctx, 350, 300, &out1);
    ts_raster_alloc(ctx, 70, 60, &avg);
    ts_ctx_set_threads(ctx, 4);
    CHECK(ts_amplify(ctx, &in, NULL, D, &p, &out, NULL, NULL) == TS_OK);
    ts_ctx_set_threads(ctx, 1);
    CHECK(ts_amplify(ctx, &in, NULL, D, &p, &out1, NULL, NULL) == TS_OK);
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
    CHECK(build1(ctx, &ex, &p, &D) == TS_OK);
    CHECK(ts_dictionary_size(D) == 1);
    ts_raster_alloc(ctx, 8, 8, &coarse);
    ts_raster_alloc(ctx, 32, 32, &out);
    CHECK(ts_area_average(ctx, &ex, 4, &coarse) == TS_OK);
    for (y = 0; y < 8; y++)
        for (x = 0; x < 8; x++) {
            TS_PIX(&coarse, x, y) = 1000.0f - TS_PIX(&coarse, x, y);
            m += TS_PIX(&coarse, x, y) / 64.0;
        }
    CHECK(ts_amplify(ctx, &coarse, NULL, D, &p, &out, NULL, &info) == TS_OK);
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
    ts_amplify_guide guide = {&drain, NULL, NULL};
    p.factor = 4;
    TS_PIX(&in, 20, 11) = NAN;
    TS_PIX(&in, 0, 46) = NAN;
    ts_raster_alloc(ctx, 53, 47, &drain);
    CHECK(ts_drainage_area(ctx, &in, &drain) == TS_OK);
    ts_raster_alloc(ctx, 212, 188, &whole);
    for (refine = 0; refine <= 4; refine += 2) {
        p.refine = refine;
        CHECK(build1(ctx, &ex, &p, &D) == TS_OK);
        CHECK(ts_amplify(ctx, &in, NULL, D, &p, &whole, NULL, NULL) == TS_OK);
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
            CHECK(ts_amplify_window(ctx, &in, &guide, D, &p, x0, y0, &win, NULL, NULL) == TS_OK);
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
    CHECK(ts_amplify_window(ctx, &in, &guide, D ? D : NULL, &p, 0, 0, &win, NULL, NULL) ==
          TS_ERR_ARG);
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
    CHECK(build1(ctx, &ex, &p, &D) == TS_OK);
    CHECK(ts_dictionary_to_bytes(ctx, D, &bytes, &len) == TS_OK);
    CHECK(memcmp(bytes, "TSDICT\r\n", 8) == 0 && bytes[8] == 3 && bytes[12] == 3);
    CHECK(ts_dictionary_from_bytes(ctx, bytes, len, &E) == TS_OK);
    ts_dictionary_shape(E, &f, &pa);
    CHECK(f == 3 && pa == p.patch && ts_dictionary_size(E) == ts_dictionary_size(D));
    ts_raster_alloc(ctx, 90, 78, &a);
    ts_raster_alloc(ctx, 90, 78, &b);
    CHECK(ts_amplify(ctx, &in, NULL, D, &p, &a, NULL, NULL) == TS_OK);
    CHECK(ts_amplify(ctx, &in, NULL, E, &p, &b, NULL, NULL) == TS_OK);
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
    bad[8] = 1;
    CHECK(ts_dictionary_from_bytes(ctx, bad, len, &E) == TS_ERR_ARG && !E);
    CHECK(strstr(ts_ctx_message(ctx), "version 1") != NULL);
    /* one bit flipped anywhere in the contents: the checksum refuses it */
    for (k = 0; k < 50; k++) {
        size_t at = 52 + (size_t)(th_uniform(&rng) * (double)(len - 52 - 8));
        memcpy(bad, bytes, len);
        bad[at] ^= (unsigned char)(1u << (int)(th_uniform(&rng) * 8));
        CHECK(ts_dictionary_from_bytes(ctx, bad, len, &E) == TS_ERR_ARG && !E);
        CHECK(strstr(ts_ctx_message(ctx), "checksum") != NULL);
    }
    /* version 2 (no checksum) is read; there a NaN or a huge fine height is refused by its
     * value (the fine heights follow 52 bytes of header, the two d-vectors) */
    {
        size_t hh_at = 52 + 2 * ts_dictionary_size(D) * (size_t)(p.patch * p.patch) * 4;
        float nan = NAN, huge = 1e30f;
        memcpy(bad, bytes, len - 8);
        bad[8] = 2;
        CHECK(ts_dictionary_from_bytes(ctx, bad, len - 8, &E) == TS_OK);
        ts_dictionary_free(E);
        E = NULL;
        memcpy(bad + hh_at + 40, &nan, 4);
        CHECK(ts_dictionary_from_bytes(ctx, bad, len - 8, &E) == TS_ERR_ARG && !E);
        CHECK(strstr(ts_ctx_message(ctx), "a value no dictionary holds") != NULL);
        memcpy(bad + hh_at + 40, &huge, 4);
        CHECK(ts_dictionary_from_bytes(ctx, bad, len - 8, &E) == TS_ERR_ARG && !E);
        /* the same value under a checksum made for it (FNV-1a here): refused by its value */
        {
            uint64_t h = 0xcbf29ce484222325ull;
            size_t i;
            bad[8] = 3;
            for (i = 0; i < len - 8; i++)
                h = (h ^ bad[i]) * 0x100000001b3ull;
            for (i = 0; i < 8; i++)
                bad[len - 8 + i] = (unsigned char)(h >> (8 * i));
            CHECK(ts_dictionary_from_bytes(ctx, bad, len, &E) == TS_ERR_ARG && !E);
            CHECK(strstr(ts_ctx_message(ctx), "a value no dictionary holds") != NULL);
        }
    }
    for (k = 0; k < 2000; k++) { /* random damage to the header: a clean refusal or a load */
        size_t at = (size_t)(th_uniform(&rng) * 52);
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
    CHECK(build1(ctx, &ex, &p, &D) == TS_ERR_SIZE && !D);
    CHECK(strstr(ts_ctx_message(ctx), "smaller than a patch") != NULL);
    p = ts_amplify_params_default();
    p.factor = 1;
    CHECK(build1(ctx, &ex, &p, &D) == TS_ERR_ARG);
    p = ts_amplify_params_default();
    p.factor = 2;
    CHECK(build1(ctx, &ex, &p, &D) == TS_OK);
    ts_raster_alloc(ctx, 4, 4, &small);
    ts_raster_alloc(ctx, 8, 8, &out);
    CHECK(ts_amplify(ctx, &small, NULL, D, &p, &out, NULL, NULL) == TS_ERR_SIZE);
    p.factor = 3;
    CHECK(ts_amplify(ctx, &small, NULL, D, &p, &out, NULL, NULL) == TS_ERR_ARG);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
    ts_raster_free(&small);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

/* ---- irradiance: against a slow integration written from the textbook ---- */

/* Mean annual clear-sky beam on a plane of slope beta facing (downhill) the
 * azimuth gamma (clockwise from north), at latitude phi, with the sun below
 * `horizon` (elevation angle, radians, in every direction) taken as hidden:
 * every day of the year, every 10 minutes, elevation and azimuth by the
 * spherical-astronomy formulas (asin, acos), no shortcuts. */
static double slow_irradiance(double phi_deg, double beta, double gamma, double horizon_south)
{
    const double pi = 3.14159265358979323846, phi = phi_deg * pi / 180;
    double sum = 0;
    long n = 0;
    for (int day = 1; day <= 365; day++) {
        double delta = 23.44 * pi / 180 * sin(2 * pi * (284.0 + day) / 365.0);
        for (int t = 0; t < 144; t++, n++) {
            double h = 2 * pi * ((t + 0.5) / 144 - 0.5);
            double alpha = asin(sin(phi) * sin(delta) + cos(phi) * cos(delta) * cos(h));
            double ca, az, inc;
            if (alpha <= 0)
                continue;
            ca = (sin(delta) - sin(alpha) * sin(phi)) / (cos(alpha) * cos(phi));
            az = acos(fmax(-1.0, fmin(1.0, ca))); /* from north, east positive */
            if (h > 0)
                az = 2 * pi - az; /* afternoon: west */
            /* a wall to the south: hides the sun when it is within 45 degrees of
             * south and below the wall's elevation angle */
            if (fabs(az - pi) < pi / 4 && alpha < horizon_south)
                continue;
            inc = cos(beta) * sin(alpha) + sin(beta) * cos(alpha) * cos(az - gamma);
            if (inc > 0)
                sum += 1361.0 * pow(0.7, pow(1.0 / sin(alpha), 0.678)) * inc;
        }
    }
    return sum / n;
}

/* A plane sloping down towards `down_az` (0 north, 90 east, ...), on a
 * north-up grid of 30 m cells; slope angle beta. */
static void plane(ts_raster *z, double beta, double down_az_deg)
{
    double a = down_az_deg * 3.14159265358979323846 / 180, t = tan(beta);
    for (int y = 0; y < z->height; y++)
        for (int x = 0; x < z->width; x++) {
            double east = (x - z->width / 2) * 30.0, north = -(y - z->height / 2) * 30.0;
            TS_PIX(z, x, y) = (float)(2000.0 - t * (east * sin(a) + north * cos(a)));
        }
}

static void test_irradiance_planes(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster z, lat, out;
    double dx[33], dy[33];
    ts_grid_metrics m = {dx, dy};
    static const struct {
        double lat, beta_deg, az;
    } cases[] = {{45, 0, 0},    {45, 30, 180}, {45, 30, 0},    {45, 25, 90},
                 {10, 20, 270}, {-35, 30, 0},  {-35, 30, 180}, {65, 15, 135}};
    ts_raster_alloc(ctx, 33, 33, &z);
    ts_raster_alloc(ctx, 33, 33, &lat);
    ts_raster_alloc(ctx, 33, 33, &out);
    for (int i = 0; i < 33; i++)
        dx[i] = dy[i] = 30.0;
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        double beta = cases[c].beta_deg * 3.14159265358979323846 / 180, want, got;
        plane(&z, beta, cases[c].az);
        for (int i = 0; i < 33 * 33; i++)
            lat.data[i] = (float)cases[c].lat;
        CHECK(ts_irradiance(ctx, &z, &m, &lat, NULL, &out) == TS_OK);
        want = slow_irradiance(cases[c].lat, beta, cases[c].az * 3.14159265358979323846 / 180, -1);
        got = TS_PIX(&out, 16, 16);
        CHECK_MSG(fabs(got - want) <= 0.03 * want + 1.0,
                  "lat %g slope %g facing %g: %g W/m2, the slow integration %g", cases[c].lat,
                  cases[c].beta_deg, cases[c].az, got, want);
    }
    /* the same plane with the grid turned: up at azimuth 90 (east) and the
     * terrain turned with it gives the same sunlight */
    {
        ts_raster north;
        double want;
        ts_raster_alloc(ctx, 33, 33, &north);
        for (int i = 0; i < 33 * 33; i++) {
            lat.data[i] = 45.0f;
            north.data[i] = 90.0f;
        }
        /* faces south in the world: in a grid whose up is east, south is the
         * grid's right; down-slope towards grid-right */
        plane(&z, 30 * 3.14159265358979323846 / 180, 90);
        CHECK(ts_irradiance(ctx, &z, &m, &lat, &north, &out) == TS_OK);
        want = slow_irradiance(45, 30 * 3.14159265358979323846 / 180, 3.14159265358979323846, -1);
        CHECK_MSG(fabs(TS_PIX(&out, 16, 16) - want) <= 0.03 * want, "turned grid: %g, want %g",
                  (double)TS_PIX(&out, 16, 16), want);
        ts_raster_free(&north);
    }
    ts_raster_free(&z);
    ts_raster_free(&lat);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

/* A long east-west wall south of a flat valley floor: the floor's sunlight
 * is that of a flat cell whose southern sky is hidden below the wall's angle
 * (the slow integration with that horizon), far less than in the open. */
static void test_irradiance_self_shadowing(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster z, lat, out;
    double dx[80], dy[80], open, want, got, wall_angle;
    ts_grid_metrics m = {dx, dy};
    ts_raster_alloc(ctx, 80, 80, &z);
    ts_raster_alloc(ctx, 80, 80, &lat);
    ts_raster_alloc(ctx, 80, 80, &out);
    for (int i = 0; i < 80; i++)
        dx[i] = dy[i] = 10.0;
    for (int y = 0; y < 80; y++)
        for (int x = 0; x < 80; x++) {
            TS_PIX(&z, x, y) = y >= 50 && y <= 52 ? 1100.0f : 1000.0f; /* 100 m high */
            TS_PIX(&lat, x, y) = 45.0f;
        }
    CHECK(ts_irradiance(ctx, &z, &m, &lat, NULL, &out) == TS_OK);
    open = slow_irradiance(45, 0, 0, -1);
    /* the cell 10 cells (100 m) north of the wall sees it at 45 degrees */
    wall_angle = atan2(100.0, 100.0);
    want = slow_irradiance(45, 0, 0, wall_angle);
    got = TS_PIX(&out, 40, 40);
    CHECK_MSG(fabs(got - want) <= 0.08 * want, "shadowed: %g W/m2, the slow integration %g", got,
              want);
    CHECK_MSG(got < 0.8 * open, "shadowed %g vs open %g", got, open);
    /* far from the wall: the open value */
    CHECK_MSG(fabs(TS_PIX(&out, 40, 5) - open) <= 0.03 * open, "open: %g, want %g",
              (double)TS_PIX(&out, 40, 5), open);
    ts_raster_free(&z);
    ts_raster_free(&lat);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

/* ---- layers and classes carried by the atoms ---- */

/* The area average of an exemplar amplified with every window of it: each
 * patch finds its own atom, so its layer and classes come back with it. */
static void test_layers_and_classes_come_back(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 192, 160, 5), veg, cls, coarse, out, vout, cout;
    ts_exemplar e;
    ts_dictionary *D = NULL, *E = NULL;
    const char *names[1] = {"vegetation"};
    ts_amplify_layers lay = {&vout, &cout};
    unsigned char *bytes = NULL;
    size_t len = 0;
    double err = 0;
    int x, y, wrong = 0;
    p.factor = 4;
    p.patch = 8;
    p.atoms = 100000;
    p.refine = 0;
    ts_raster_alloc(ctx, 192, 160, &veg);
    ts_raster_alloc(ctx, 192, 160, &cls);
    for (y = 0; y < 160; y++)
        for (x = 0; x < 192; x++) {
            TS_PIX(&veg, x, y) = (float)(0.5 + 0.5 * sin(0.21 * x) * cos(0.13 * y));
            TS_PIX(&cls, x, y) = (float)(1 + (x / 37 + y / 29) % 3);
        }
    memset(&e, 0, sizeof e);
    e.dem = ex;
    e.layers = &veg;
    e.classes = &cls;
    CHECK(ts_dictionary_build(ctx, &e, 1, names, 1, &p, &D) == TS_OK);
    CHECK(ts_dictionary_to_bytes(ctx, D, &bytes, &len) == TS_OK);
    CHECK(ts_dictionary_from_bytes(ctx, bytes, len, &E) == TS_OK);
    CHECK(strcmp(ts_dictionary_layer_name(E, 0), "vegetation") == 0);
    ts_raster_alloc(ctx, 48, 40, &coarse);
    ts_raster_alloc(ctx, 192, 160, &out);
    ts_raster_alloc(ctx, 192, 160, &vout);
    ts_raster_alloc(ctx, 192, 160, &cout);
    CHECK(ts_area_average(ctx, &ex, 4, &coarse) == TS_OK);
    CHECK(ts_amplify(ctx, &coarse, NULL, E, &p, &out, &lay, NULL) == TS_OK);
    for (y = 0; y < 160; y++)
        for (x = 0; x < 192; x++) {
            err = fmax(err, fabs(TS_PIX(&vout, x, y) - TS_PIX(&veg, x, y)));
            wrong += TS_PIX(&cout, x, y) != TS_PIX(&cls, x, y);
        }
    CHECK_MSG(err < 1e-5, "layer: max error %g", err);
    CHECK_MSG(wrong == 0, "%d cells of another class", wrong);
    free(bytes);
    ts_dictionary_free(D);
    ts_dictionary_free(E);
    ts_raster_free(&ex);
    ts_raster_free(&veg);
    ts_raster_free(&cls);
    ts_raster_free(&coarse);
    ts_raster_free(&out);
    ts_raster_free(&vout);
    ts_raster_free(&cout);
    ts_ctx_free(ctx);
}

/* Class control (section 5.4): an exemplar whose left half is labelled 1
 * and right half 2; the wanted classes choose where the atoms come from
 * (the atoms' source, counted independently of the class output), and
 * windows of the class output are the whole's. */
static void test_class_control(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 400, 200, 61), in = make_terrain(ctx, 40, 40, 62), cls, want,
              out, cout, drain, win, cwin;
    ts_exemplar e;
    ts_dictionary *D = NULL;
    ts_amplify_guide guide = {&drain, NULL, &want};
    ts_amplify_layers lay = {NULL, &cout}, wlay = {NULL, &cwin};
    int x, y, c, same = 1;
    p.factor = 4;
    p.patch = 8;
    ts_raster_alloc(ctx, 400, 200, &cls);
    for (y = 0; y < 200; y++)
        for (x = 0; x < 400; x++)
            TS_PIX(&cls, x, y) = x < 200 ? 1.0f : 2.0f;
    memset(&e, 0, sizeof e);
    e.dem = ex;
    e.classes = &cls;
    CHECK(ts_dictionary_build(ctx, &e, 1, NULL, 0, &p, &D) == TS_OK);
    ts_raster_alloc(ctx, 40, 40, &want);
    ts_raster_alloc(ctx, 40, 40, &drain);
    ts_raster_alloc(ctx, 160, 160, &out);
    ts_raster_alloc(ctx, 160, 160, &cout);
    CHECK(ts_drainage_area(ctx, &in, &drain) == TS_OK);
    for (c = 1; c <= 2; c++) {
        size_t n_c = 0, n = 0;
        for (y = 0; y < 40; y++)
            for (x = 0; x < 40; x++)
                TS_PIX(&want, x, y) = x < 20 ? (float)c : (float)(3 - c); /* left c, right not */
        CHECK(ts_amplify(ctx, &in, &guide, D, &p, &out, &lay, NULL) == TS_OK);
        for (y = 0; y < 160; y++)
            for (x = 0; x < 160; x++) {
                int wanted = x < 80 ? c : 3 - c;
                /* away from the boundary between the wanted halves */
                if (abs(x - 80) < 16)
                    continue;
                n++;
                n_c += TS_PIX(&cout, x, y) == (float)wanted;
            }
        CHECK_MSG(n_c >= 0.97 * n, "wanted classes %d|%d: %zu of %zu cells", c, 3 - c, n_c, n);
    }
    /* without wanted classes, both halves of the exemplar are used */
    {
        size_t ones = 0;
        CHECK(ts_amplify(ctx, &in, NULL, D, &p, &out, &lay, NULL) == TS_OK);
        for (y = 0; y < 160; y++)
            for (x = 0; x < 160; x++)
                ones += TS_PIX(&cout, x, y) == 1.0f;
        CHECK(ones > 160 * 160 / 10 && ones < 160 * 160 * 9 / 10);
    }
    CHECK(ts_amplify(ctx, &in, &guide, D, &p, &out, &lay, NULL) == TS_OK);
    ts_raster_alloc(ctx, 37, 51, &win);
    ts_raster_alloc(ctx, 37, 51, &cwin);
    CHECK(ts_amplify_window(ctx, &in, &guide, D, &p, 61, 70, &win, &wlay, NULL) == TS_OK);
    for (y = 0; y < 51; y++)
        for (x = 0; x < 37; x++)
            same &= TS_PIX(&cwin, x, y) == TS_PIX(&cout, 61 + x, 70 + y) &&
                    memcmp(&TS_PIX(&win, x, y), &TS_PIX(&out, 61 + x, 70 + y), 4) == 0;
    CHECK(same);
    /* a class that is no code */
    TS_PIX(&want, 3, 4) = 2.5f;
    CHECK(ts_amplify(ctx, &in, &guide, D, &p, &out, &lay, NULL) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "class 2.5 at input cell 3,4") != NULL);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
    ts_raster_free(&in);
    ts_raster_free(&cls);
    ts_raster_free(&want);
    ts_raster_free(&out);
    ts_raster_free(&cout);
    ts_raster_free(&drain);
    ts_raster_free(&win);
    ts_raster_free(&cwin);
    ts_ctx_free(ctx);
}

/* Biomes (section 5.5): two dictionaries painted left and right give, away
 * from their edge, byte for byte what each gives alone; one dictionary
 * twice at equal weights is that dictionary alone; windows are the whole's;
 * a negative weight is refused. */
static void test_biomes(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster exa = make_terrain(ctx, 300, 260, 71), exb = make_terrain(ctx, 280, 300, 72);
    ts_raster in = make_terrain(ctx, 60, 40, 73), drain, wts[2], outa, outb, both, win;
    ts_dictionary *D[2] = {NULL, NULL};
    ts_amplify_guide g = {&drain, NULL, NULL};
    const ts_dictionary *dd[2];
    int x, y, same_a = 1, same_b = 1, same = 1, margin;
    p.factor = 4;
    p.patch = 6;
    CHECK(build1(ctx, &exa, &p, &D[0]) == TS_OK);
    CHECK(build1(ctx, &exb, &p, &D[1]) == TS_OK);
    ts_raster_alloc(ctx, 60, 40, &drain);
    CHECK(ts_drainage_area(ctx, &in, &drain) == TS_OK);
    ts_raster_alloc(ctx, 60, 40, &wts[0]);
    ts_raster_alloc(ctx, 60, 40, &wts[1]);
    for (y = 0; y < 40; y++)
        for (x = 0; x < 60; x++) {
            TS_PIX(&wts[0], x, y) = x < 30 ? 1.0f : 0.0f;
            TS_PIX(&wts[1], x, y) = x < 30 ? 0.0f : 3.0f; /* any scale: shares */
        }
    ts_raster_alloc(ctx, 240, 160, &outa);
    ts_raster_alloc(ctx, 240, 160, &outb);
    ts_raster_alloc(ctx, 240, 160, &both);
    CHECK(ts_amplify(ctx, &in, &g, D[0], &p, &outa, NULL, NULL) == TS_OK);
    CHECK(ts_amplify(ctx, &in, &g, D[1], &p, &outb, NULL, NULL) == TS_OK);
    dd[0] = D[0];
    dd[1] = D[1];
    CHECK(ts_amplify_biomes(ctx, &in, &g, dd, wts, 2, &p, 0, 0, &both, NULL) == TS_OK);
    /* the edge reaches a patch, a cell of interpolation and two cells per pass */
    margin = (p.patch + 1 + 2 * p.refine + 1) * p.factor;
    for (y = 0; y < 160; y++)
        for (x = 0; x < 240; x++) {
            if (x < 120 - margin)
                same_a &= memcmp(&TS_PIX(&both, x, y), &TS_PIX(&outa, x, y), 4) == 0;
            if (x >= 120 + margin)
                same_b &= memcmp(&TS_PIX(&both, x, y), &TS_PIX(&outb, x, y), 4) == 0;
        }
    CHECK(same_a && same_b);
    /* near the edge, a blend of the two */
    CHECK(memcmp(&TS_PIX(&both, 120, 80), &TS_PIX(&outa, 120, 80), 4) != 0 &&
          memcmp(&TS_PIX(&both, 120, 80), &TS_PIX(&outb, 120, 80), 4) != 0);
    /* a window of the biomes is the whole's */
    ts_raster_alloc(ctx, 57, 43, &win);
    CHECK(ts_amplify_biomes(ctx, &in, &g, dd, wts, 2, &p, 93, 61, &win, NULL) == TS_OK);
    for (y = 0; y < 43; y++)
        for (x = 0; x < 57; x++)
            same &= memcmp(&TS_PIX(&win, x, y), &TS_PIX(&both, 93 + x, 61 + y), 4) == 0;
    CHECK(same);
    /* one dictionary twice, equal weights: that dictionary alone */
    dd[1] = D[0];
    for (y = 0; y < 40; y++)
        for (x = 0; x < 60; x++)
            TS_PIX(&wts[0], x, y) = TS_PIX(&wts[1], x, y) = 0.5f;
    CHECK(ts_amplify_biomes(ctx, &in, &g, dd, wts, 2, &p, 0, 0, &both, NULL) == TS_OK);
    CHECK(memcmp(both.data, outa.data, sizeof(float) * 240 * 160) == 0);
    TS_PIX(&wts[1], 7, 9) = -1.0f;
    CHECK(ts_amplify_biomes(ctx, &in, &g, dd, wts, 2, &p, 0, 0, &both, NULL) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "biome 2: weight -1 at cell 7,9") != NULL);
    ts_dictionary_free(D[0]);
    ts_dictionary_free(D[1]);
    ts_raster_free(&exa);
    ts_raster_free(&exb);
    ts_raster_free(&in);
    ts_raster_free(&drain);
    ts_raster_free(&wts[0]);
    ts_raster_free(&wts[1]);
    ts_raster_free(&outa);
    ts_raster_free(&outb);
    ts_raster_free(&both);
    ts_raster_free(&win);
    ts_ctx_free(ctx);
}

/* The context descriptor (section 5.3) against block means written out:
 * inside, and at a corner where the neighbourhood is clamped to the edge. */
static void test_context_descriptor(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster r = make_terrain(ctx, 40, 30, 81);
    float got[36];
    int cases[2][2] = {{12, 9}, {0, 0}}, c, i, j, a, b;
    TS_PIX(&r, 14, 10) = NAN; /* left out of its block */
    for (c = 0; c < 2; c++) {
        double want[36], m = 0, ss = 0;
        int x = cases[c][0], y = cases[c][1];
        for (j = 0; j < 6; j++)
            for (i = 0; i < 6; i++) {
                double s = 0;
                int n = 0;
                for (b = 0; b < 3; b++)
                    for (a = 0; a < 3; a++) {
                        int cx = x - 6 + 3 * i + a, cy = y - 6 + 3 * j + b;
                        float v;
                        if (cx < 0)
                            cx = 0;
                        if (cy < 0)
                            cy = 0;
                        v = TS_PIX(&r, cx, cy);
                        if (v == v) {
                            s += v;
                            n++;
                        }
                    }
                want[j * 6 + i] = s / n;
            }
        for (i = 0; i < 36; i++)
            m += want[i] / 36;
        for (i = 0; i < 36; i++)
            ss += (want[i] - m) * (want[i] - m);
        ts__amp_context(&r, x, y, 6, got);
        for (i = 0; i < 36; i++)
            CHECK_NEAR(got[i], (want[i] - m) / sqrt(ss), 1e-5);
    }
    ts_raster_free(&r);
    ts_ctx_free(ctx);
}

/* An exemplar with fewer windows than the atoms asked for gives atoms from
 * several phases of its area average (fractions of a low-resolution cell
 * apart): as many as the phases allow, each atom's fine window the exemplar's
 * at its recorded origin, its mean altitude the block means there (written
 * out here). */
static void test_atoms_from_phases(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_amplify_params p = ts_amplify_params_default();
    ts_raster ex = make_terrain(ctx, 48, 40, 91);
    ts_dictionary *D = NULL;
    size_t k;
    int phases = 0;
    p.factor = 4;
    p.patch = 6;
    p.atoms = 100;
    /* phase 0: 12 x 10 low cells, 7 x 5 = 35 windows < 100: more phases */
    CHECK(build1(ctx, &ex, &p, &D) == TS_OK);
    for (k = 0; k < D->n; k++) {
        int fx = D->x[k], fy = D->y[k], i, j, P = 24, bad = 0;
        double m = 0;
        phases |= 1 << ((fx % 4) * 4 + fy % 4);
        for (j = 0; j < 6; j++)
            for (i = 0; i < 6; i++) {
                double b = 0;
                for (int bj = 0; bj < 4; bj++)
                    for (int bi = 0; bi < 4; bi++)
                        b += TS_PIX(&ex, fx + 4 * i + bi, fy + 4 * j + bj);
                m += b / 16 / 36;
            }
        CHECK_NEAR(D->a[k], m, 1e-3);
        for (j = 0; j < P; j++)
            for (i = 0; i < P; i++) {
                double v = D->hh[k * D->hd + j * P + i] * D->s[k] * 6 + D->a[k];
                bad += fabs(v - TS_PIX(&ex, fx + i, fy + j)) > 1e-2;
            }
        CHECK(bad == 0);
    }
    /* phases (0,0), (2,2), (2,0) whole (35 + 24 + 30 windows), then others thinned to the
     * budget of 100 */
    CHECK((phases & ((1 << 0) | (1 << 10) | (1 << 8))) == ((1 << 0) | (1 << 10) | (1 << 8)));
    CHECK_MSG(D->n >= 90 && D->n <= 100, "%zu atoms", D->n);
    ts_dictionary_free(D);
    ts_raster_free(&ex);
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
        {"irradiance_planes", test_irradiance_planes},
        {"irradiance_self_shadowing", test_irradiance_self_shadowing},
        {"layers_and_classes_come_back", test_layers_and_classes_come_back},
        {"class_control", test_class_control},
        {"biomes", test_biomes},
        {"context_descriptor", test_context_descriptor},
        {"atoms_from_phases", test_atoms_from_phases},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
