/*
 * test_pixel.c - multiresolution pixel synthesis (algorithms/src/pixel/):
 * the stack's blur against a 2D convolution written out, the neighbourhood
 * distance against a plain sum, and the property the method is built for:
 * any window, anywhere (negative and huge coordinates too), alone equals
 * the same window of a larger run, whatever the threads; the heights within the
 * exemplar's range; seeds differ.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "pixel.h"
#include "terrasynth.h"

static ts_raster make_terrain(ts_ctx *ctx, int w, int h, uint64_t seed)
{
    ts_raster r;
    double fx[16], fy[16], ph[16], amp[16];
    int k, x, y;
    uint64_t rng = seed;
    ts_raster_alloc(ctx, w, h, &r);
    for (k = 0; k < 16; k++) {
        double f = 0.03 * pow(1.3, k), a = 6.2831853 * th_uniform(&rng);
        fx[k] = f * cos(a);
        fy[k] = f * sin(a);
        ph[k] = 6.2831853 * th_uniform(&rng);
        amp[k] = 40.0 / pow(1.3, k);
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double z = 800;
            for (k = 0; k < 16; k++)
                z += amp[k] * sin(fx[k] * x + fy[k] * y + ph[k]);
            TS_PIX(&r, x, y) = (float)z;
        }
    return r;
}

static void test_blur_against_convolution(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster r = make_terrain(ctx, 37, 29, 3);
    float *out = malloc(37 * 29 * sizeof *out);
    double sigma = 2.0;
    int x, y, bad = 0;
    TS_PIX(&r, 10, 10) = NAN;
    TS_PIX(&r, 11, 10) = NAN;
    CHECK(ts__pix_blur(r.data, 37, 29, sigma, out) == 0);
    for (y = 0; y < 29; y++)
        for (x = 0; x < 37; x++) {
            double s = 0, sw = 0;
            int i, j, rad = (int)ceil(3 * sigma);
            if (isnan(TS_PIX(&r, x, y))) {
                bad += !isnan(out[y * 37 + x]);
                continue;
            }
            for (j = -rad; j <= rad; j++)
                for (i = -rad; i <= rad; i++) {
                    int xx = x + i, yy = y + j;
                    double wgt;
                    if (xx < 0 || yy < 0 || xx >= 37 || yy >= 29 || isnan(TS_PIX(&r, xx, yy)))
                        continue;
                    wgt = exp(-0.5 * (i * i + j * j) / (sigma * sigma));
                    s += wgt * TS_PIX(&r, xx, yy);
                    sw += wgt;
                }
            bad += fabs(out[y * 37 + x] - s / sw) > 1e-3;
        }
    CHECK_MSG(bad == 0, "%d cells differ", bad);
    free(out);
    ts_raster_free(&r);
    ts_ctx_free(ctx);
}

static void test_ssd_plain(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster r = make_terrain(ctx, 60, 50, 4);
    float t[25];
    uint64_t rng = 1;
    int i, a, b;
    for (i = 0; i < 25; i++)
        t[i] = (float)(800 + 50 * th_uniform(&rng));
    for (int h = 1; h <= 4; h *= 2) {
        double want = 0;
        for (b = -2; b <= 2; b++)
            for (a = -2; a <= 2; a++) {
                double d = t[(b + 2) * 5 + a + 2] - TS_PIX(&r, 30 + a * h, 25 + b * h);
                want += d * d;
            }
        CHECK_NEAR(ts__pix_ssd(r.data, 60, 30, 25, 5, h, t), want, 1e-6 * want);
    }
    ts_raster_free(&r);
    ts_ctx_free(ctx);
}

/* Windows alone equal the windows of a larger run. */
static void test_windows_anywhere(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 96, 80, 5), big, win;
    ts_pixel_exemplars *E = NULL;
    static const int64_t origins[][2] = {{0, 0},
                                         {-70, -33},
                                         {((int64_t)1 << 39) - 17, 12345},
                                         {-((int64_t)1 << 39), ((int64_t)1 << 38) + 5}};
    size_t o;
    TS_PIX(&ex, 40, 40) = NAN; /* nodata: never matched */
    p.levels = 3;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    CHECK(ts_pixel_levels(E) == 3);
    ts_ctx_set_seed(ctx, 42);
    ts_raster_alloc(ctx, 90, 70, &big);
    for (o = 0; o < sizeof origins / sizeof origins[0]; o++) {
        int64_t bx = origins[o][0], by = origins[o][1];
        int k, x, y;
        uint64_t rng = 7 + o;
        ts_ctx_set_threads(ctx, 3);
        CHECK(ts_pixel_synthesize(ctx, E, &p, bx, by, &big) == TS_OK);
        for (k = 0; k < 4; k++) {
            int w = 1 + (int)(th_uniform(&rng) * 40), h = 1 + (int)(th_uniform(&rng) * 40);
            int wx = (int)(th_uniform(&rng) * (90 - w)), wy = (int)(th_uniform(&rng) * (70 - h));
            int same = 1;
            ts_raster_alloc(ctx, w, h, &win);
            ts_ctx_set_threads(ctx, 1 + k % 2);
            CHECK(ts_pixel_synthesize(ctx, E, &p, bx + wx, by + wy, &win) == TS_OK);
            for (y = 0; y < h; y++)
                for (x = 0; x < w; x++)
                    same &= memcmp(&TS_PIX(&win, x, y), &TS_PIX(&big, wx + x, wy + y), 4) == 0;
            CHECK_MSG(same, "origin %lld,%lld window %d,%d %dx%d differs", (long long)bx,
                      (long long)by, wx, wy, w, h);
            ts_raster_free(&win);
        }
        /* the heights are sums of the exemplar's bands: within its range and a tenth of
         * its relief, never nodata */
        {
            float lo = 1e30f, hi = -1e30f;
            int bad = 0;
            for (y = 0; y < 80; y++)
                for (x = 0; x < 96; x++)
                    if (!isnan(TS_PIX(&ex, x, y))) {
                        lo = fminf(lo, TS_PIX(&ex, x, y));
                        hi = fmaxf(hi, TS_PIX(&ex, x, y));
                    }
            for (y = 0; y < 70; y++)
                for (x = 0; x < 90; x++) {
                    float v = TS_PIX(&big, x, y);
                    bad += isnan(v) || v < lo - 0.1f * (hi - lo) || v > hi + 0.1f * (hi - lo);
                }
            CHECK_MSG(bad == 0, "%d heights out of the exemplar's range", bad);
        }
    }
    /* another seed, another terrain */
    {
        ts_raster other;
        ts_raster_alloc(ctx, 90, 70, &other);
        CHECK(ts_pixel_synthesize(ctx, E, &p, 0, 0, &big) == TS_OK);
        ts_ctx_set_seed(ctx, 43);
        CHECK(ts_pixel_synthesize(ctx, E, &p, 0, 0, &other) == TS_OK);
        CHECK(memcmp(big.data, other.data, sizeof(float) * 90 * 70) != 0);
        ts_raster_free(&other);
    }
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex);
    ts_raster_free(&big);
    ts_ctx_free(ctx);
}

static void test_errors(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 20, 20, 6);
    ts_pixel_exemplars *E = NULL;
    p.levels = 5; /* a 5 x 5 neighbourhood at spacing 32 does not fit in 20 cells */
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_ERR_SIZE && !E);
    CHECK(strstr(ts_ctx_message(ctx), "no valid 5 x 5 neighbourhood") != NULL);
    p = ts_pixel_params_default();
    p.window = 4;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_ERR_ARG && !E);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* The Jacobi eigenvalues keep the matrix's invariants (trace, Frobenius
 * norm) and give a 2 x 2 matrix's by the formula; the window choice takes 3
 * for white noise (every direction carries variance) and 9 for a smooth
 * wave (a few components hold it all). */
static void test_window_choice(void)
{
    ts_ctx *ctx = ts_ctx_new();
    double a[25 * 25], b[25 * 25], ev[25], tr = 0, fro = 0, s1 = 0, s2 = 0;
    double m2[4] = {2, 1, 1, 3}, e2[2];
    uint64_t rng = 11;
    ts_raster noise, wave;
    int i, j;
    for (i = 0; i < 25; i++)
        for (j = 0; j <= i; j++)
            a[i * 25 + j] = a[j * 25 + i] = th_uniform(&rng) - 0.5;
    memcpy(b, a, sizeof a);
    for (i = 0; i < 25; i++) {
        tr += a[i * 25 + i];
        for (j = 0; j < 25; j++)
            fro += a[i * 25 + j] * a[i * 25 + j];
    }
    CHECK(ts__pix_eigenvalues(b, 25, ev) == 0);
    for (i = 0; i < 25; i++) {
        s1 += ev[i];
        s2 += ev[i] * ev[i];
    }
    CHECK_NEAR(s1, tr, 1e-9);
    CHECK_NEAR(s2, fro, 1e-9);
    CHECK(ts__pix_eigenvalues(m2, 2, e2) == 0);
    CHECK_NEAR(fmin(e2[0], e2[1]), 2.5 - sqrt(1.25), 1e-12);
    CHECK_NEAR(fmax(e2[0], e2[1]), 2.5 + sqrt(1.25), 1e-12);
    ts_raster_alloc(ctx, 120, 100, &noise);
    ts_raster_alloc(ctx, 120, 100, &wave);
    for (j = 0; j < 100; j++)
        for (i = 0; i < 120; i++) {
            TS_PIX(&noise, i, j) = (float)th_uniform(&rng);
            TS_PIX(&wave, i, j) = (float)(100 * sin(0.05 * i + 0.03 * j));
        }
    CHECK(ts__pix_choose_window(&noise, 1) == 3);
    CHECK(ts__pix_choose_window(&wave, 1) == 9);
    ts_raster_free(&noise);
    ts_raster_free(&wave);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"blur_against_convolution", test_blur_against_convolution},
        {"ssd_plain", test_ssd_plain},
        {"windows_anywhere", test_windows_anywhere},
        {"errors", test_errors},
        {"window_choice", test_window_choice},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
