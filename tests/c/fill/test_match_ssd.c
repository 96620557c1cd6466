/*
 * test_match_ssd.c - the FFT masked-SSD matcher against a naive quadruple
 * loop in double: SSD maps, nodata windows, k best with separation, the
 * empty target, errors, determinism and cancellation.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <pthread.h>

#include "harness.h"
#include "internal.h"
#include "terrasynth.h"

/* ---- data ------------------------------------------------------------ */

/* w x h raster with row stride `stride`; cells 3000 +/- 500 (a large
 * offset exposes cancellation), a fraction nan_frac of them NaN.  The
 * margin beyond the width is NaN so that reading it would show. */
static ts_raster make_random(uint64_t *seed, int w, int h, ptrdiff_t stride, double nan_frac)
{
    float *d = malloc((size_t)stride * (size_t)h * sizeof *d);
    ptrdiff_t i;
    int x, y;
    for (i = 0; i < stride * h; i++)
        d[i] = NAN;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            d[(ptrdiff_t)y * stride + x] =
                th_uniform(seed) < nan_frac ? NAN : (float)(2500.0 + 1000.0 * th_uniform(seed));
    return ts_raster_wrap(d, w, h, stride);
}

/* Smooth terrain: a few random sines around 3000 m, so the SSD landscape
 * has wide basins and near-ties between neighbours. */
static ts_raster make_smooth(uint64_t *seed, int w, int h)
{
    float *d = malloc((size_t)w * (size_t)h * sizeof *d);
    double fx[4], fy[4], ph[4], amp[4];
    int x, y, q;
    for (q = 0; q < 4; q++) {
        fx[q] = 0.02 + 0.15 * th_uniform(seed);
        fy[q] = 0.02 + 0.15 * th_uniform(seed);
        ph[q] = 6.28 * th_uniform(seed);
        amp[q] = 100.0 + 200.0 * th_uniform(seed);
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double v = 3000.0;
            for (q = 0; q < 4; q++)
                v += amp[q] * sin(fx[q] * x + fy[q] * y + ph[q]);
            d[(size_t)y * (size_t)w + (size_t)x] = (float)v;
        }
    return ts_raster_wrap(d, w, h, w);
}

/* Copy of a window of `src` as a target; cells unknown (NaN) with
 * probability 1 - known_frac; noise of +-noise added to known cells. */
static ts_raster make_target(uint64_t *seed, const ts_raster *src, int x0, int y0, int w, int h,
                             double known_frac, double noise)
{
    float *d = malloc((size_t)w * (size_t)h * sizeof *d);
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            float v = TS_PIX(src, x0 + x, y0 + y);
            if (th_uniform(seed) >= known_frac)
                v = NAN;
            else if (noise > 0.0)
                v += (float)(noise * (2.0 * th_uniform(seed) - 1.0));
            d[(size_t)y * (size_t)w + (size_t)x] = v;
        }
    return ts_raster_wrap(d, w, h, w);
}

/* ---- the oracle --------------------------------------------------------- */

static int window_has_nodata(const ts_raster *e, int x, int y, int w, int h)
{
    int i, j;
    for (j = 0; j < h; j++)
        for (i = 0; i < w; i++)
            if (!isfinite(TS_PIX(e, x + i, y + j)))
                return 1;
    return 0;
}

/* Masked SSD at (x, y), directly in double; +INFINITY on nodata. */
static double naive_ssd(const ts_raster *e, const ts_raster *t, int x, int y)
{
    double s = 0.0;
    int i, j;
    if (window_has_nodata(e, x, y, t->width, t->height))
        return INFINITY;
    for (j = 0; j < t->height; j++)
        for (i = 0; i < t->width; i++) {
            double d;
            if (!isfinite(TS_PIX(t, i, j)))
                continue;
            d = (double)TS_PIX(t, i, j) - TS_PIX(e, x + i, y + j);
            s += d * d;
        }
    return s;
}

static double valid_mean(const ts_raster *e)
{
    double s = 0.0;
    size_t n = 0;
    int x, y;
    for (y = 0; y < e->height; y++)
        for (x = 0; x < e->width; x++)
            if (isfinite(TS_PIX(e, x, y))) {
                s += TS_PIX(e, x, y);
                n++;
            }
    return n ? s / (double)n : 0.0;
}

/* Sum over known target cells of (E(x+i, y+j) - mean)^2. */
static double window_e2(const ts_raster *e, const ts_raster *t, double mean, int x, int y)
{
    double s = 0.0;
    int i, j;
    for (j = 0; j < t->height; j++)
        for (i = 0; i < t->width; i++)
            if (isfinite(TS_PIX(t, i, j))) {
                double d = TS_PIX(e, x + i, y + j) - mean;
                s += d * d;
            }
    return s;
}

static double worst_rel_err; /* largest |fft - naive| / scale seen */

/*
 * Compare ts_matcher_ssd with the oracle at every position, or at
 * `samples` random positions when samples > 0.  Tolerance: 1e-4 of the
 * SSD scale sum M T'^2 + max over valid windows of sum M E'^2 (' = minus
 * the exemplar mean), + 1e-3.  With samples the max runs over the sampled
 * windows only, which can only tighten the tolerance.
 */
static void check_map(ts_ctx *ctx, const ts_raster *e, const ts_raster *t, uint64_t *seed,
                      int samples)
{
    ts_matcher *m = NULL;
    float *map;
    int nx, ny, s, n, bad = 0, i, j;
    int *px, *py;
    double *ref, st = 0.0, max_e2 = 0.0, scale, tol;
    const double mean = valid_mean(e);
    if (ts_matcher_new(ctx, e, t->width, t->height, &m) != TS_OK) {
        CHECK_MSG(0, "ts_matcher_new: %s", ts_ctx_message(ctx));
        return;
    }
    ts_matcher_positions(m, &nx, &ny);
    CHECK(nx == e->width - t->width + 1 && ny == e->height - t->height + 1);
    map = malloc((size_t)nx * (size_t)ny * sizeof *map);
    CHECK(ts_matcher_ssd(ctx, m, t, map) == TS_OK);

    n = samples > 0 ? samples : nx * ny;
    px = malloc((size_t)n * sizeof *px);
    py = malloc((size_t)n * sizeof *py);
    ref = malloc((size_t)n * sizeof *ref);
    for (s = 0; s < n; s++) {
        px[s] = samples > 0 ? (int)(th_uniform(seed) * nx) : s % nx;
        py[s] = samples > 0 ? (int)(th_uniform(seed) * ny) : s / nx;
        ref[s] = naive_ssd(e, t, px[s], py[s]);
        if (!isinf(ref[s])) {
            double w = window_e2(e, t, mean, px[s], py[s]);
            if (w > max_e2)
                max_e2 = w;
        }
    }
    for (j = 0; j < t->height; j++)
        for (i = 0; i < t->width; i++)
            if (isfinite(TS_PIX(t, i, j)))
                st += (TS_PIX(t, i, j) - mean) * (TS_PIX(t, i, j) - mean);
    scale = st + max_e2;
    tol = 1e-4 * scale + 1e-3;
    for (s = 0; s < n; s++) {
        double got = map[(size_t)py[s] * (size_t)nx + (size_t)px[s]], err;
        if (isinf(ref[s])) {
            if (!(isinf(got) && got > 0) && bad++ < 5)
                CHECK_MSG(0, "%dx%d patch %dx%d at (%d,%d): %g, want +inf", e->width, e->height,
                          t->width, t->height, px[s], py[s], got);
            continue;
        }
        err = fabs(got - ref[s]);
        if (scale > 0.0 && err / scale > worst_rel_err)
            worst_rel_err = err / scale;
        if (!(err <= tol) && bad++ < 5)
            CHECK_MSG(0, "%dx%d patch %dx%d at (%d,%d): fft %.9g naive %.9g tol %g", e->width,
                      e->height, t->width, t->height, px[s], py[s], got, ref[s], tol);
    }
    free(px);
    free(py);
    free(ref);
    free(map);
    ts_matcher_free(m);
}

/* Greedy k best on the oracle: all valid positions by (ssd, y, x), taken
 * when at least sep (Chebyshev) from every taken one. */
typedef struct ref_pos {
    double ssd;
    int idx;
} ref_pos;

static int ref_cmp(const void *pa, const void *pb)
{
    const ref_pos *a = pa, *b = pb;
    if (a->ssd != b->ssd)
        return a->ssd < b->ssd ? -1 : 1;
    return (a->idx > b->idx) - (a->idx < b->idx);
}

/* (cost: NULL, or w x cost[position] added to every SSD) */
static const float *naive_cost;
static double naive_cost_w;

static int naive_best(const ts_raster *e, const ts_raster *t, int k, int sep, ts_candidate *out)
{
    const int nx = e->width - t->width + 1, ny = e->height - t->height + 1;
    ref_pos *all = malloc((size_t)nx * (size_t)ny * sizeof *all);
    int n = 0, nt = 0, i, q;
    for (i = 0; i < nx * ny; i++) {
        double s = naive_ssd(e, t, i % nx, i / nx);
        if (isinf(s))
            continue;
        all[n].ssd = s + (naive_cost ? naive_cost_w * naive_cost[i] : 0.0);
        all[n].idx = i;
        n++;
    }
    qsort(all, (size_t)n, sizeof *all, ref_cmp);
    for (i = 0; i < n && nt < k; i++) {
        int x = all[i].idx % nx, y = all[i].idx / nx, ok = 1;
        for (q = 0; q < nt && ok; q++)
            if (abs(out[q].x - x) < sep && abs(out[q].y - y) < sep)
                ok = 0;
        if (!ok)
            continue;
        out[nt].x = x;
        out[nt].y = y;
        out[nt].ssd = all[i].ssd;
        nt++;
    }
    free(all);
    return nt;
}

static void check_best(ts_ctx *ctx, const ts_raster *e, const ts_raster *t, int k, int sep)
{
    ts_matcher *m = NULL;
    ts_candidate *got = malloc((size_t)k * sizeof *got), *want = malloc((size_t)k * sizeof *want);
    int n_got = -1, n_want, i, j;
    if (ts_matcher_new(ctx, e, t->width, t->height, &m) != TS_OK) {
        CHECK_MSG(0, "ts_matcher_new: %s", ts_ctx_message(ctx));
        free(got);
        free(want);
        return;
    }
    CHECK(ts_matcher_best(ctx, m, t, k, sep, got, &n_got) == TS_OK);
    n_want = naive_best(e, t, k, sep, want);
    CHECK_MSG(n_got == n_want, "%dx%d patch %dx%d k %d sep %d: found %d, want %d", e->width,
              e->height, t->width, t->height, k, sep, n_got, n_want);
    for (i = 0; i < n_got && i < n_want; i++) {
        CHECK_MSG(got[i].x == want[i].x && got[i].y == want[i].y,
                  "%dx%d patch %dx%d k %d sep %d: #%d at (%d,%d) ssd %.17g, want (%d,%d) %.17g",
                  e->width, e->height, t->width, t->height, k, sep, i, got[i].x, got[i].y,
                  got[i].ssd, want[i].x, want[i].y, want[i].ssd);
        CHECK_NEAR(got[i].ssd, want[i].ssd, 1e-9 * fabs(want[i].ssd) + 1e-12);
        if (i > 0)
            CHECK(got[i].ssd >= got[i - 1].ssd);
        for (j = 0; j < i; j++)
            CHECK(sep <= 1 || abs(got[i].x - got[j].x) >= sep || abs(got[i].y - got[j].y) >= sep);
    }
    ts_matcher_free(m);
    free(got);
    free(want);
}

/* ---- cases ------------------------------------------------------------- */

static const int sizes[][4] = {
    /* exemplar w, h, patch w, h */
    {37, 29, 7, 5},     {16, 16, 16, 16}, {1, 1, 1, 1},     {64, 48, 8, 8},
    {101, 67, 13, 11},  {97, 89, 31, 1},  {53, 41, 1, 41},  {128, 128, 32, 32},
    {211, 149, 40, 30}, {2, 300, 1, 5},   {331, 17, 3, 17},
};

static void test_ssd_vs_naive(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 1;
    size_t c;
    int mask;
    static const double known[4] = {0.0, 1.0, 0.5, 0.1};
    for (c = 0; c < sizeof sizes / sizeof sizes[0]; c++)
        for (mask = 0; mask < 4; mask++) {
            ts_raster e = make_random(&seed, sizes[c][0], sizes[c][1], sizes[c][0], 0.0);
            ts_raster src = make_random(&seed, sizes[c][2], sizes[c][3], sizes[c][2], 0.0);
            ts_raster t =
                make_target(&seed, &src, 0, 0, sizes[c][2], sizes[c][3], known[mask], 0.0);
            check_map(ctx, &e, &t, &seed, 0);
            free(e.data);
            free(src.data);
            free(t.data);
        }
    ts_ctx_free(ctx);
}

static void test_ssd_nodata(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 2;
    int x, y, rep;
    for (rep = 0; rep < 3; rep++) {
        ts_raster e = make_random(&seed, 80 + rep, 60 + 2 * rep, 83, 0.01);
        ts_raster t = make_target(&seed, &e, 0, 0, 9, 7, rep == 0 ? 1.0 : 0.6, 5.0);
        for (y = 30; y < 36; y++) /* a nodata hole */
            for (x = 40; x < 45; x++)
                TS_PIX(&e, x, y) = NAN;
        TS_PIX(&e, 3, 50) = INFINITY;  /* non-finite counts as nodata */
        for (y = 0; y < t.height; y++) /* the target must not carry NaN from e */
            for (x = 0; x < t.width; x++)
                if (isnan(TS_PIX(&t, x, y)) && th_uniform(&seed) < 0.5)
                    TS_PIX(&t, x, y) = 2900.0f;
        check_map(ctx, &e, &t, &seed, 0);
        check_best(ctx, &e, &t, 5, 4);
        free(e.data);
        free(t.data);
    }
    ts_ctx_free(ctx);
}

static void test_ssd_large(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 3;
    ts_raster e = make_random(&seed, 1024, 1000, 1024, 0.0);
    ts_raster t = make_target(&seed, &e, 500, 300, 16, 16, 0.5, 0.0);
    ts_raster s = make_smooth(&seed, 700, 1023);
    ts_raster ts_ = make_target(&seed, &s, 17, 900, 48, 40, 0.5, 1.0);
    check_map(ctx, &e, &t, &seed, 3000);
    check_map(ctx, &s, &ts_, &seed, 3000);
    printf("     worst |fft - naive| / scale = %.3g\n", worst_rel_err);
    free(e.data);
    free(t.data);
    free(s.data);
    free(ts_.data);
    ts_ctx_free(ctx);
}

/* Views with stride > width give bit-identical results to packed copies. */
static void test_stride(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 4;
    ts_raster wide = make_random(&seed, 45, 33, 61, 0.02);
    ts_raster packed = make_random(&seed, 45, 33, 45, 0.0);
    ts_raster tw = make_random(&seed, 6, 5, 9, 0.3), tp = make_random(&seed, 6, 5, 6, 0.0);
    ts_matcher *m1 = NULL, *m2 = NULL;
    float *a = malloc(40 * 29 * sizeof *a), *b = malloc(40 * 29 * sizeof *b);
    int x, y;
    for (y = 0; y < 33; y++)
        for (x = 0; x < 45; x++)
            TS_PIX(&packed, x, y) = TS_PIX(&wide, x, y);
    for (y = 0; y < 5; y++)
        for (x = 0; x < 6; x++)
            TS_PIX(&tp, x, y) = TS_PIX(&tw, x, y);
    CHECK(ts_matcher_new(ctx, &wide, 6, 5, &m1) == TS_OK);
    CHECK(ts_matcher_new(ctx, &packed, 6, 5, &m2) == TS_OK);
    if (m1 && m2) {
        CHECK(ts_matcher_ssd(ctx, m1, &tw, a) == TS_OK);
        CHECK(ts_matcher_ssd(ctx, m2, &tp, b) == TS_OK);
        CHECK(memcmp(a, b, 40 * 29 * sizeof *a) == 0);
    }
    check_map(ctx, &wide, &tw, &seed, 0);
    check_best(ctx, &wide, &tw, 4, 3);
    ts_matcher_free(m1);
    ts_matcher_free(m2);
    free(a);
    free(b);
    free(wide.data);
    free(packed.data);
    free(tw.data);
    free(tp.data);
    ts_ctx_free(ctx);
}

static void test_best_vs_naive(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 5;
    size_t c;
    for (c = 0; c < sizeof sizes / sizeof sizes[0]; c++) {
        ts_raster e = make_random(&seed, sizes[c][0], sizes[c][1], sizes[c][0], 0.0);
        ts_raster src = make_random(&seed, sizes[c][2], sizes[c][3], sizes[c][2], 0.0);
        ts_raster t = make_target(&seed, &src, 0, 0, sizes[c][2], sizes[c][3], 0.7, 0.0);
        check_best(ctx, &e, &t, 1, 0);
        check_best(ctx, &e, &t, 6, 5);
        check_best(ctx, &e, &t, 3, 1);
        free(e.data);
        free(src.data);
        free(t.data);
    }
    ts_ctx_free(ctx);
}

/* A cost per position added to the SSD (the fill's usage cost): the k best
 * of SSD + w x cost, against the oracle adding it to every naive SSD; the
 * cost cleared, the plain k best again. */
static void test_best_cost(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 21;
    size_t c;
    for (c = 0; c < sizeof sizes / sizeof sizes[0]; c++) {
        ts_raster e = make_random(&seed, sizes[c][0], sizes[c][1], sizes[c][0], 0.0);
        ts_raster src = make_random(&seed, sizes[c][2], sizes[c][3], sizes[c][2], 0.0);
        ts_raster t = make_target(&seed, &src, 0, 0, sizes[c][2], sizes[c][3], 0.7, 0.0);
        int nx = sizes[c][0] - sizes[c][2] + 1, ny = sizes[c][1] - sizes[c][3] + 1, i, n = -1, n0;
        float *cost = malloc((size_t)nx * (size_t)ny * sizeof *cost);
        ts_candidate got[8], plain[8], want[8];
        ts_matcher *m = NULL;
        double w;
        for (i = 0; i < nx * ny; i++) /* a few positions cost much, most a little */
            cost[i] =
                (float)(th_uniform(&seed) < 0.2 ? 50.0 * th_uniform(&seed) : th_uniform(&seed));
        /* weights from negligible to dominant against the SSD */
        for (w = 0.01; w < 2e4; w *= 30.0) {
            CHECK(ts_matcher_new(ctx, &e, t.width, t.height, &m) == TS_OK);
            ts__matcher_cost(m, cost, w);
            CHECK(ts_matcher_best(ctx, m, &t, 8, 2, got, &n) == TS_OK);
            naive_cost = cost;
            naive_cost_w = w;
            n0 = naive_best(&e, &t, 8, 2, want);
            naive_cost = NULL;
            CHECK_MSG(n == n0, "case %zu w %g: %d found, want %d", c, w, n, n0);
            for (i = 0; i < n && i < n0; i++) {
                CHECK_MSG(got[i].x == want[i].x && got[i].y == want[i].y,
                          "case %zu w %g #%d at (%d,%d), want (%d,%d)", c, w, i, got[i].x, got[i].y,
                          want[i].x, want[i].y);
                CHECK_NEAR(got[i].ssd, want[i].ssd, 1e-9 * fabs(want[i].ssd) + 1e-9);
            }
            /* cleared: the plain k best */
            ts__matcher_cost(m, NULL, 0);
            CHECK(ts_matcher_best(ctx, m, &t, 8, 2, plain, &n) == TS_OK);
            n0 = naive_best(&e, &t, 8, 2, want);
            CHECK(n == n0);
            for (i = 0; i < n && i < n0; i++)
                CHECK(plain[i].x == want[i].x && plain[i].y == want[i].y);
            ts_matcher_free(m);
        }
        free(cost);
        free(e.data);
        free(src.data);
        free(t.data);
    }
    ts_ctx_free(ctx);
}

/* Smooth terrain: wide basins, so the pool and the threshold must grow. */
static void test_best_smooth(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 6;
    int rep;
    for (rep = 0; rep < 3; rep++) {
        ts_raster e = make_smooth(&seed, 160 + 7 * rep, 120 + 5 * rep);
        ts_raster t = make_target(&seed, &e, 50 + rep, 40, 16, 14, 0.5, 2.0);
        check_best(ctx, &e, &t, 1, 0);
        check_best(ctx, &e, &t, 8, 10);
        check_best(ctx, &e, &t, 20, 3);
        check_best(ctx, &e, &t, 40, 0);
        free(e.data);
        free(t.data);
    }
    ts_ctx_free(ctx);
}

/* A map large enough for the candidate stream to be read by several
 * workers (and several threads in every FFT phase). */
static void test_best_large(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 14;
    ts_raster e = make_smooth(&seed, 640, 480);
    ts_raster r = make_random(&seed, 700, 420, 700, 0.0);
    ts_raster t = make_target(&seed, &e, 200, 100, 12, 10, 0.6, 3.0);
    ts_raster tr = make_target(&seed, &r, 5, 400, 10, 12, 0.6, 30.0);
    ts_ctx_set_threads(ctx, 3);
    check_best(ctx, &e, &t, 10, 16);
    check_best(ctx, &e, &t, 3, 0);
    check_best(ctx, &r, &tr, 10, 16);
    check_best(ctx, &r, &tr, 50, 0);
    free(e.data);
    free(r.data);
    free(t.data);
    free(tr.data);
    ts_ctx_free(ctx);
}

/* Near-ties below the float map's resolution: a flat region (3000 m +-
 * 0.05) next to a rough one that sets the FFT's error scale.  The float
 * map cannot order the flat windows; the exact search still must. */
static void test_best_near_ties(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 13;
    int rep, x, y;
    for (rep = 0; rep < 4; rep++) {
        ts_raster e = make_random(&seed, 120 + rep, 100, 120 + rep, 0.0);
        ts_raster t;
        for (y = 0; y < 100; y++)
            for (x = 0; x < 80; x++)
                TS_PIX(&e, x, y) = (float)(3000.0 + 0.1 * (th_uniform(&seed) - 0.5));
        t = make_target(&seed, &e, 0, 0, 10, 10, rep < 2 ? 1.0 : 0.6, 0.0);
        for (y = 0; y < 10; y++)
            for (x = 0; x < 10; x++)
                if (isfinite(TS_PIX(&t, x, y)))
                    TS_PIX(&t, x, y) = (float)(3000.0 + 0.1 * (th_uniform(&seed) - 0.5));
        check_best(ctx, &e, &t, 1, 0);
        check_best(ctx, &e, &t, 5, 4);
        check_best(ctx, &e, &t, 30, 0);
        free(e.data);
        free(t.data);
    }
    ts_ctx_free(ctx);
}

/* A window of the exemplar itself, half masked, is found with SSD 0. */
static void test_best_self(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 7;
    ts_raster e = make_random(&seed, 200, 160, 200, 0.0);
    ts_raster t = make_target(&seed, &e, 123, 77, 24, 20, 0.5, 0.0);
    ts_matcher *m = NULL;
    ts_candidate c[3];
    int n = 0;
    CHECK(ts_matcher_new(ctx, &e, 24, 20, &m) == TS_OK);
    CHECK(ts_matcher_best(ctx, m, &t, 3, 8, c, &n) == TS_OK);
    CHECK(n == 3);
    CHECK(c[0].x == 123 && c[0].y == 77 && c[0].ssd == 0.0);
    CHECK(c[1].ssd > 0.0);
    ts_matcher_free(m);
    free(e.data);
    free(t.data);
    ts_ctx_free(ctx);
}

/* No known target cell: SSD 0 everywhere valid, first valid windows in
 * row-major order respecting the separation. */
static void test_best_empty(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 8;
    ts_raster e = make_random(&seed, 50, 40, 50, 0.0);
    ts_raster t = make_target(&seed, &e, 0, 0, 5, 4, 0.0, 0.0);
    ts_matcher *m = NULL;
    ts_candidate c[10];
    float *map = malloc(46 * 37 * sizeof *map);
    int n = 0, i;
    TS_PIX(&e, 2, 0) = NAN; /* windows x 0..2, y 0 invalid */
    CHECK(ts_matcher_new(ctx, &e, 5, 4, &m) == TS_OK);
    CHECK(ts_matcher_best(ctx, m, &t, 10, 20, c, &n) == TS_OK);
    CHECK(n == 6); /* x 3, 23, 43 on row 0; 0, 20, 40 on row 20; ny is 37 */
    CHECK(c[0].x == 3 && c[0].y == 0 && c[1].x == 23 && c[2].x == 43 && c[3].x == 0 &&
          c[3].y == 20 && c[5].x == 40 && c[5].y == 20);
    for (i = 0; i < n; i++)
        CHECK(c[i].ssd == 0.0);
    CHECK(ts_matcher_ssd(ctx, m, &t, map) == TS_OK);
    CHECK(isinf(map[0]) && isinf(map[2]) && map[3] == 0.0f && map[46 * 37 - 1] == 0.0f);
    check_best(ctx, &e, &t, 10, 20);
    check_best(ctx, &e, &t, 7, 0);
    ts_matcher_free(m);
    free(map);
    free(e.data);
    free(t.data);
    ts_ctx_free(ctx);
}

/* More candidates asked than exist. */
static void test_best_few(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 9;
    ts_raster e = make_random(&seed, 12, 9, 12, 0.0);
    ts_raster t = make_target(&seed, &e, 1, 1, 4, 3, 0.8, 3.0);
    ts_matcher *m = NULL;
    ts_candidate c[200];
    int n = 0;
    CHECK(ts_matcher_new(ctx, &e, 4, 3, &m) == TS_OK);
    CHECK(ts_matcher_best(ctx, m, &t, 200, 0, c, &n) == TS_OK);
    CHECK(n == 9 * 7);
    CHECK(ts_matcher_best(ctx, m, &t, 200, 1000, c, &n) == TS_OK);
    CHECK(n == 1);
    check_best(ctx, &e, &t, 200, 0);
    check_best(ctx, &e, &t, 200, 2);
    ts_matcher_free(m);
    free(e.data);
    free(t.data);
    ts_ctx_free(ctx);
}

static void test_errors(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 10;
    ts_raster e = make_random(&seed, 20, 10, 20, 0.0);
    ts_raster t = make_random(&seed, 5, 5, 5, 0.0), t2 = make_random(&seed, 6, 5, 6, 0.0);
    ts_matcher *m = (ts_matcher *)&seed;
    ts_candidate c[2];
    float map[16 * 6];
    int n = 7, x, y;

    CHECK(ts_matcher_new(ctx, &e, 21, 5, &m) == TS_ERR_SIZE);
    CHECK(m == NULL);
    CHECK_MSG(strcmp(ts_ctx_message(ctx),
                     "matcher: the exemplar (20 x 10) is smaller than a patch (21 x 5)") == 0,
              "%s", ts_ctx_message(ctx));
    CHECK(ts_matcher_new(ctx, &e, 5, 11, &m) == TS_ERR_SIZE);
    CHECK(ts_matcher_new(ctx, &e, 0, 5, &m) == TS_ERR_ARG);
    CHECK(ts_matcher_new(ctx, NULL, 5, 5, &m) == TS_ERR_ARG);
    CHECK(ts_matcher_new(ctx, &e, 5, 5, NULL) == TS_ERR_ARG);

    /* nodata everywhere, then in every 5 x 5 window */
    for (y = 0; y < 10; y++)
        for (x = 0; x < 20; x++)
            TS_PIX(&e, x, y) = NAN;
    CHECK(ts_matcher_new(ctx, &e, 5, 5, &m) == TS_ERR_NUMERIC);
    CHECK(m == NULL);
    for (y = 0; y < 10; y++)
        for (x = 0; x < 20; x++)
            TS_PIX(&e, x, y) = (x % 4 == 3 || y % 5 == 4) ? NAN : 100.0f;
    CHECK(ts_matcher_new(ctx, &e, 5, 5, &m) == TS_ERR_NUMERIC);
    CHECK(ts_ctx_status(ctx) == TS_ERR_NUMERIC && strlen(ts_ctx_message(ctx)) > 0);
    CHECK(ts_matcher_new(ctx, &e, 3, 4, &m) == TS_OK); /* 3 x 4 windows do fit */
    CHECK(ts_ctx_status(ctx) == TS_OK && ts_ctx_message(ctx)[0] == '\0');
    ts_matcher_free(m);

    for (y = 0; y < 10; y++)
        for (x = 0; x < 20; x++)
            TS_PIX(&e, x, y) = (float)(x + y);
    CHECK(ts_matcher_new(ctx, &e, 5, 5, &m) == TS_OK);
    CHECK(ts_matcher_best(ctx, m, &t, 0, 0, c, &n) == TS_ERR_ARG);
    CHECK(n == 0);
    CHECK(ts_matcher_best(ctx, m, &t, -3, 0, c, &n) == TS_ERR_ARG);
    CHECK(ts_matcher_best(ctx, m, &t, 2, -1, c, &n) == TS_ERR_ARG);
    CHECK(ts_matcher_best(ctx, m, &t2, 2, 0, c, &n) == TS_ERR_ARG);
    CHECK(ts_matcher_best(ctx, m, &t, 2, 0, NULL, &n) == TS_ERR_ARG);
    CHECK(ts_matcher_ssd(ctx, m, &t2, map) == TS_ERR_ARG);
    CHECK(ts_matcher_ssd(ctx, m, NULL, map) == TS_ERR_ARG);
    CHECK(ts_matcher_ssd(ctx, m, &t, NULL) == TS_ERR_ARG);
    CHECK(ts_matcher_ssd(ctx, NULL, &t, map) == TS_ERR_ARG);
    CHECK(ts_matcher_ssd(ctx, m, &t, map) == TS_OK);
    CHECK(ts_matcher_best(ctx, m, &t, 2, 0, c, &n) == TS_OK && n == 2);
    ts_matcher_free(m);
    ts_matcher_free(NULL);
    free(e.data);
    free(t.data);
    free(t2.data);
    ts_ctx_free(ctx);
}

/* Same inputs, same bits: twice, and with 1 or 3 threads. */
static void test_determinism(void)
{
    ts_ctx *c1 = ts_ctx_new(), *c3 = ts_ctx_new();
    uint64_t seed = 11;
    /* big enough for every phase to use several workers */
    ts_raster e = make_random(&seed, 1024, 600, 1024, 0.001);
    ts_raster t = make_target(&seed, &e, 30, 40, 33, 21, 0.5, 4.0);
    ts_matcher *m1 = NULL, *m3 = NULL;
    const size_t n = (size_t)(1024 - 33 + 1) * (600 - 21 + 1);
    float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b), *c = malloc(n * sizeof *c);
    ts_candidate k1[12], k2[12], k3[12];
    int n1 = 0, n2 = 0, n3 = 0;
    ts_ctx_set_threads(c1, 1);
    ts_ctx_set_threads(c3, 3);
    CHECK(ts_matcher_new(c1, &e, 33, 21, &m1) == TS_OK);
    CHECK(ts_matcher_new(c3, &e, 33, 21, &m3) == TS_OK);
    if (m1 && m3) {
        CHECK(ts_matcher_ssd(c1, m1, &t, a) == TS_OK);
        CHECK(ts_matcher_ssd(c1, m1, &t, b) == TS_OK);
        CHECK(ts_matcher_ssd(c3, m3, &t, c) == TS_OK);
        CHECK(memcmp(a, b, n * sizeof *a) == 0);
        CHECK(memcmp(a, c, n * sizeof *a) == 0);
        CHECK(ts_matcher_ssd(c3, m1, &t, b) == TS_OK); /* planned with 1 thread, run with 3 */
        CHECK(memcmp(a, b, n * sizeof *a) == 0);
        CHECK(ts_matcher_best(c1, m1, &t, 12, 6, k1, &n1) == TS_OK);
        CHECK(ts_matcher_best(c1, m1, &t, 12, 6, k2, &n2) == TS_OK);
        CHECK(ts_matcher_best(c3, m3, &t, 12, 6, k3, &n3) == TS_OK);
        CHECK(n1 == 12 && n2 == n1 && n3 == n1);
        CHECK(memcmp(k1, k2, sizeof k1) == 0 && memcmp(k1, k3, sizeof k1) == 0);
    }
    ts_matcher_free(m1);
    ts_matcher_free(m3);
    free(a);
    free(b);
    free(c);
    free(e.data);
    free(t.data);
    ts_ctx_free(c1);
    ts_ctx_free(c3);
}

/* Matchers planned, queried and freed concurrently from several threads
 * (the FFTW planner is serialised inside the library) give the same bits
 * as the same work done sequentially. */
typedef struct thread_work {
    ts_raster e, t;
    float *map;
    ts_candidate best[4];
    int n_best, ok;
} thread_work;

static void *thread_run(void *arg)
{
    thread_work *w = arg;
    ts_ctx *ctx = ts_ctx_new();
    int rep;
    w->ok = ctx != NULL;
    for (rep = 0; rep < 4 && w->ok; rep++) {
        ts_matcher *m = NULL;
        ts_ctx_set_threads(ctx, 1 + rep % 2);
        w->ok = ts_matcher_new(ctx, &w->e, w->t.width, w->t.height, &m) == TS_OK &&
                ts_matcher_ssd(ctx, m, &w->t, w->map) == TS_OK &&
                ts_matcher_best(ctx, m, &w->t, 4, 3, w->best, &w->n_best) == TS_OK;
        ts_matcher_free(m);
    }
    ts_ctx_free(ctx);
    return NULL;
}

static void test_threads(void)
{
    enum { NT = 4 };
    uint64_t seed = 15;
    thread_work par[NT], seq[NT];
    pthread_t tid[NT];
    int i;
    for (i = 0; i < NT; i++) {
        const int w = 90 + 17 * i, h = 70 + 9 * i;
        const size_t n = (size_t)(w - 11 + 1) * (size_t)(h - 9 + 1);
        par[i].e = make_random(&seed, w, h, w, 0.002);
        par[i].t = make_target(&seed, &par[i].e, 5, 6, 11, 9, 0.6, 2.0);
        par[i].map = malloc(n * sizeof *par[i].map);
        seq[i] = par[i];
        seq[i].map = malloc(n * sizeof *seq[i].map);
        thread_run(&seq[i]);
    }
    for (i = 0; i < NT; i++)
        CHECK(pthread_create(&tid[i], NULL, thread_run, &par[i]) == 0);
    for (i = 0; i < NT; i++) {
        const size_t n = (size_t)(par[i].e.width - 10) * (size_t)(par[i].e.height - 8);
        pthread_join(tid[i], NULL);
        CHECK(par[i].ok && seq[i].ok);
        CHECK(memcmp(par[i].map, seq[i].map, n * sizeof *par[i].map) == 0);
        CHECK(par[i].n_best == 4 && seq[i].n_best == 4);
        CHECK(memcmp(par[i].best, seq[i].best, sizeof par[i].best) == 0);
        free(par[i].e.data);
        free(par[i].t.data);
        free(par[i].map);
        free(seq[i].map);
    }
}

static int cancel_after;
static int progress_calls;

static int cancel_progress(double done, const char *msg, void *user)
{
    (void)msg;
    (void)user;
    CHECK(done >= 0.0 && done <= 1.0);
    return ++progress_calls < cancel_after;
}

static void test_cancel(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 12;
    ts_raster e = make_random(&seed, 90, 70, 90, 0.0);
    ts_raster t = make_target(&seed, &e, 3, 3, 10, 10, 0.5, 0.0);
    ts_matcher *m = NULL;
    float *map = malloc(81 * 61 * sizeof *map);
    ts_candidate c[4];
    int n = 0, calls;
    ts_ctx_set_progress(ctx, cancel_progress, NULL);
    cancel_after = 1000000;
    progress_calls = 0;
    CHECK(ts_matcher_new(ctx, &e, 10, 10, &m) == TS_OK);
    calls = progress_calls;
    CHECK(calls > 1);
    ts_matcher_free(m);
    m = NULL;
    for (cancel_after = 1; cancel_after <= calls; cancel_after++) {
        progress_calls = 0;
        CHECK(ts_matcher_new(ctx, &e, 10, 10, &m) == TS_ERR_CANCELLED);
        CHECK(m == NULL);
    }
    cancel_after = 1000000;
    CHECK(ts_matcher_new(ctx, &e, 10, 10, &m) == TS_OK);
    cancel_after = 1;
    progress_calls = 0;
    CHECK(ts_matcher_ssd(ctx, m, &t, map) == TS_ERR_CANCELLED);
    progress_calls = 0;
    CHECK(ts_matcher_best(ctx, m, &t, 4, 0, c, &n) == TS_ERR_CANCELLED);
    CHECK(n == 0);
    cancel_after = 1000000;
    CHECK(ts_matcher_best(ctx, m, &t, 4, 0, c, &n) == TS_OK && n == 4);
    ts_matcher_free(m);
    free(map);
    free(e.data);
    free(t.data);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"ssd_vs_naive", test_ssd_vs_naive},
        {"ssd_nodata", test_ssd_nodata},
        {"ssd_large", test_ssd_large},
        {"stride", test_stride},
        {"best_vs_naive", test_best_vs_naive},
        {"best_cost", test_best_cost},
        {"best_smooth", test_best_smooth},
        {"best_near_ties", test_best_near_ties},
        {"best_large", test_best_large},
        {"best_self", test_best_self},
        {"best_empty", test_best_empty},
        {"best_few", test_best_few},
        {"errors", test_errors},
        {"determinism", test_determinism},
        {"threads", test_threads},
        {"cancel", test_cancel},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
