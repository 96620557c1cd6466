/*
 * test_relief_guide.c - the relief guide of sketch-guided synthesis: the
 * Euclidean distance transform against brute force, the exemplar's relief
 * profile on roofs with a known fall, and the guide built from it.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "relief_guide.h"
#include "terrasynth.h"

/* ---- distance transform == brute force ---- */
static void test_edt_brute_force(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t s = 5;
    int rep;
    for (rep = 0; rep < 40; rep++) {
        int w = 1 + (int)(th_uniform(&s) * 70), h = 1 + (int)(th_uniform(&s) * 50), x, y, bad = 0;
        double density = rep == 0 ? 0.0 : rep == 1 ? 1.0 : th_uniform(&s) * 0.1;
        unsigned char *m = malloc((size_t)w * h);
        float *d = malloc((size_t)w * h * sizeof(float));
        for (y = 0; y < w * h; y++)
            m[y] = th_uniform(&s) < density;
        ts_ctx_set_threads(ctx, 1 + rep % 3);
        CHECK(ts__distance_transform(ctx, m, w, h, d) == TS_OK);
        for (y = 0; y < h && !bad; y++)
            for (x = 0; x < w; x++) {
                double best = INFINITY;
                int u, v;
                for (v = 0; v < h; v++)
                    for (u = 0; u < w; u++)
                        if (m[v * w + u])
                            best = fmin(best, hypot(u - x, v - y));
                int ok = isinf(best) ? isinf(d[y * w + x])
                                     : fabs(d[y * w + x] - best) <= 1e-4 * (1 + best);
                if (!ok) {
                    CHECK_MSG(0, "rep %d (%d x %d) cell (%d, %d): %g, brute force %g", rep, w, h, x,
                              y, d[y * w + x], best);
                    bad = 1;
                    break;
                }
            }
        free(m);
        free(d);
    }
    ts_ctx_free(ctx);
}

/* ---- relief profile of a roof: drop(d) = slope * d ---- */
static void test_profile_of_a_roof(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 90, H = 81, crest = 40, x, y, d, kind;
    for (kind = TS_RIDGE; kind <= TS_VALLEY; kind <<= 1) {
        double sign = kind == TS_RIDGE ? 1.0 : -1.0;
        ts_raster dem;
        unsigned char *mask = calloc((size_t)W * H, 1);
        ts_relief_profile prof;
        ts_raster_alloc(ctx, W, H, &dem);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                TS_PIX(&dem, x, y) = (float)(1000.0 - sign * 7.5 * abs(y - crest));
                if (y == crest)
                    mask[y * W + x] = (unsigned char)kind;
            }
        /* a nodata hole is ignored */
        TS_PIX(&dem, 3, 10) = NAN;
        CHECK(ts__relief_profile_measure(ctx, &dem, mask, kind, 30, &prof) == TS_OK);
        CHECK(prof.valid && prof.max_d == 30);
        CHECK_NEAR(prof.level, 1000.0, 1e-9);
        for (d = 0; d <= 30; d++)
            CHECK_NEAR(prof.drop[d], 7.5 * d, 1e-6);
        ts__relief_profile_free(&prof);
        /* no such feature: not valid, not an error */
        CHECK(ts__relief_profile_measure(ctx, &dem, mask, kind == TS_RIDGE ? TS_VALLEY : TS_RIDGE,
                                         30, &prof) == TS_OK);
        CHECK(!prof.valid);
        ts__relief_profile_free(&prof);
        free(mask);
        ts_raster_free(&dem);
    }
    ts_ctx_free(ctx);
}

/* ---- the guide: level - drop(distance), NaN beyond max_d and on nodata ---- */
static void test_guide(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 60, H = 50, x, y, d;
    ts_relief_profile profs[2];
    unsigned char *sk = calloc((size_t)W * H, 1), *nodata = calloc((size_t)W * H, 1);
    int32_t *cell_ex = malloc((size_t)W * H * sizeof(int32_t));
    float *g = malloc((size_t)W * H * sizeof(float));
    for (d = 0; d < 2; d++) {
        profs[d].valid = 1;
        profs[d].max_d = 20;
        profs[d].level = d ? 2000.0 : 500.0;
        profs[d].drop = malloc(21 * sizeof(double));
    }
    for (d = 0; d <= 20; d++) {
        profs[0].drop[d] = 10.0 * d;
        profs[1].drop[d] = 3.0 * d;
    }
    for (x = 0; x < W; x++)
        sk[25 * W + x] = TS_RIDGE | TS_VALLEY;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            cell_ex[y * W + x] = x < 20 ? 0 : x < 40 ? 1 : -1;
    nodata[30 * W + 5] = 1;
    CHECK(ts__relief_guide(ctx, sk, TS_RIDGE, W, H, profs, 2, cell_ex, nodata, g) == TS_OK);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            double dist = abs(y - 25), want;
            float got = g[y * W + x];
            if (dist > 20 || (x == 5 && y == 30)) {
                CHECK_MSG(isnan(got), "(%d, %d) %g", x, y, got);
                continue;
            }
            want = x < 20 ? 500.0 - 10.0 * dist
                 : x < 40 ? 2000.0 - 3.0 * dist
                          : 0.5 * ((500.0 - 10.0 * dist) + (2000.0 - 3.0 * dist));
            CHECK_NEAR(got, want, 1e-3);
        }
    /* valleys: the land rises away from the strokes */
    CHECK(ts__relief_guide(ctx, sk, TS_VALLEY, W, H, profs, 2, NULL, NULL, g) == TS_OK);
    CHECK_NEAR(g[35 * W + 10], 0.5 * ((500.0 + 100.0) + (2000.0 + 30.0)), 1e-3);
    /* an invalid profile is left out; none valid: no guide */
    profs[1].valid = 0;
    CHECK(ts__relief_guide(ctx, sk, TS_RIDGE, W, H, profs, 2, NULL, NULL, g) == TS_OK);
    CHECK_NEAR(g[35 * W + 50], 500.0 - 100.0, 1e-3);
    profs[0].valid = 0;
    CHECK(ts__relief_guide(ctx, sk, TS_RIDGE, W, H, profs, 2, NULL, NULL, g) == TS_OK);
    CHECK(isnan(g[25 * W + 10]));
    for (d = 0; d < 2; d++)
        free(profs[d].drop);
    free(sk);
    free(nodata);
    free(cell_ex);
    free(g);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"edt_brute_force", test_edt_brute_force},
        {"profile_of_a_roof", test_profile_of_a_roof},
        {"guide", test_guide},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
