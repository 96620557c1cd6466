/*
 * test_poisson.c - the Poisson solver against a dense direct solve of the
 * same system, a manufactured solution, and the seam remover's properties
 * (seam gradient not raised, Dirichlet cells kept, NaN cells untouched).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <time.h>

#include "harness.h"
#include "internal.h"
#include "terrasynth.h"

static double now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

#include "poisson_oracle.h"

/* ---- ts_poisson_solve against the oracle ---- */

static void run_dense_case(ts_ctx *ctx, int w, int h, double p_unknown, uint64_t *seed,
                           double *worst)
{
    size_t n = (size_t)w * h, c;
    unsigned char *mask = malloc(n), *cls = malloc(n);
    float *gx = malloc(n * sizeof *gx), *gy = malloc(n * sizeof *gy), *u = malloc(n * sizeof *u);
    float *u0 = malloc(n * sizeof *u0);
    double *gr = malloc(n * sizeof *gr), *gd = malloc(n * sizeof *gd), *ref = malloc(n * sizeof *ref);
    double scale = 1.0, err = 0.0;
    ts_status st;
    for (c = 0; c < n; c++) {
        mask[c] = th_uniform(seed) < p_unknown;
        cls[c] = mask[c] ? REF_UNKNOWN : REF_KNOWN;
        gx[c] = (float)(6.0 * th_uniform(seed) - 3.0);
        gy[c] = (float)(6.0 * th_uniform(seed) - 3.0);
        u[c] = (float)(50.0 + 100.0 * th_uniform(seed)); /* boundary or initial guess */
        u0[c] = u[c];
        gr[c] = gx[c];
        gd[c] = gy[c];
        ref[c] = u[c];
    }
    CHECK(ref_solve(w, h, cls, gr, gd, ref));
    st = ts_poisson_solve(ctx, w, h, mask, gx, gy, u, 1e-10, 1000);
    CHECK_MSG(st == TS_OK, "%dx%d: %s", w, h, ts_ctx_message(ctx));
    for (c = 0; c < n; c++)
        scale = fmax(scale, fabs(ref[c]));
    for (c = 0; c < n; c++) {
        if (mask[c])
            err = fmax(err, fabs(u[c] - ref[c]));
        else
            CHECK(u[c] == u0[c]); /* Dirichlet cells are not written */
    }
    CHECK_MSG(err <= 1e-5 * scale, "%dx%d: max error %g (scale %g)", w, h, err, scale);
    *worst = fmax(*worst, err / scale);
    free(mask);
    free(cls);
    free(gx);
    free(gy);
    free(u);
    free(u0);
    free(gr);
    free(gd);
    free(ref);
}

static void test_dense_reference(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 11;
    double worst = 0.0;
    static const int sizes[][2] = {{6, 5}, {7, 7}, {5, 8}, {1, 9}, {9, 1}, {3, 3}, {12, 10}};
    size_t k;
    int t;
    for (k = 0; k < sizeof sizes / sizeof sizes[0]; k++)
        for (t = 0; t < 8; t++)
            run_dense_case(ctx, sizes[k][0], sizes[k][1], 0.3 + 0.08 * t, &seed, &worst);
    /* every cell unknown: pure Neumann, pinned to the initial mean */
    for (k = 0; k < sizeof sizes / sizeof sizes[0]; k++)
        run_dense_case(ctx, sizes[k][0], sizes[k][1], 2.0, &seed, &worst);
    printf("     dense reference: worst relative error %.2e\n", worst);
    ts_ctx_free(ctx);
}

/* ---- NaN cells left out (ts__poisson_solve_valid) against the oracle ---- */

/* Unknowns, known cells and NaN cells at random: the NaN cells are REF_OUT
 * in the dense system (no equation, no term in their neighbours'). */
static void test_nan_cells_reference(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 23;
    static const int sizes[][2] = {{7, 6}, {9, 9}, {1, 8}, {12, 10}, {5, 11}};
    size_t k;
    int t;
    double worst = 0.0;
    for (k = 0; k < sizeof sizes / sizeof sizes[0]; k++)
        for (t = 0; t < 10; t++) {
            int w = sizes[k][0], h = sizes[k][1];
            size_t n = (size_t)w * h, c;
            unsigned char *mask = malloc(n), *cls = malloc(n);
            float *gx = malloc(n * sizeof *gx), *gy = malloc(n * sizeof *gy);
            float *u = malloc(n * sizeof *u), *u0 = malloc(n * sizeof *u0);
            double *gr = malloc(n * sizeof *gr), *gd = malloc(n * sizeof *gd);
            double *ref = malloc(n * sizeof *ref), scale = 1.0, err = 0.0;
            double p_nan = 0.05 * t, p_known = t % 2 ? 0.0 : 0.25; /* odd: pure Neumann */
            for (c = 0; c < n; c++) {
                double r = th_uniform(&seed);
                cls[c] = r < p_nan ? REF_OUT : r < p_nan + p_known ? REF_KNOWN : REF_UNKNOWN;
                mask[c] = cls[c] != REF_KNOWN; /* a NaN cell may be in the mask: left out */
                gx[c] = (float)(4.0 * th_uniform(&seed) - 2.0);
                gy[c] = (float)(4.0 * th_uniform(&seed) - 2.0);
                u[c] = cls[c] == REF_OUT ? NAN : (float)(200.0 + 50.0 * th_uniform(&seed));
                if (cls[c] == REF_OUT && th_uniform(&seed) < 0.5)
                    gx[c] = gy[c] = NAN; /* guidance on edges to NaN cells is not read */
                u0[c] = u[c];
                gr[c] = gx[c];
                gd[c] = gy[c];
                ref[c] = u[c];
            }
            /* the oracle reads guidance only on edges between used cells */
            for (c = 0; c < n; c++) {
                if (isnan(gr[c]))
                    gr[c] = 0.0;
                if (isnan(gd[c]))
                    gd[c] = 0.0;
            }
            CHECK(ref_solve(w, h, cls, gr, gd, ref));
            CHECK_MSG(ts__poisson_solve_valid(ctx, w, h, mask, gx, gy, u, 1e-10, 1000, 0.0) == TS_OK,
                      "%s", ts_ctx_message(ctx));
            for (c = 0; c < n; c++)
                if (!isnan(ref[c]))
                    scale = fmax(scale, fabs(ref[c]));
            for (c = 0; c < n; c++) {
                if (cls[c] == REF_OUT)
                    CHECK(isnan(u[c]));
                else if (cls[c] == REF_KNOWN)
                    CHECK(u[c] == u0[c]);
                else
                    err = fmax(err, fabs(u[c] - ref[c]));
            }
            CHECK_MSG(err <= 1e-5 * scale, "%dx%d case %d: max error %g", w, h, t, err);
            worst = fmax(worst, err / scale);
            free(mask);
            free(cls);
            free(gx);
            free(gy);
            free(u);
            free(u0);
            free(gr);
            free(gd);
            free(ref);
        }
    printf("     NaN cells left out: worst relative error %.2e\n", worst);
    ts_ctx_free(ctx);
}

/* ---- manufactured solution ---- */

static double manufactured(int x, int y)
{
    double s = x / 40.0, t = y / 40.0;
    return 3.0 * s * s - 2.0 * s * t + 5.0 * t + sin(x / 3.0);
}

/* Exact forward differences of u*, u* on known cells, garbage elsewhere. */
static void manufactured_setup(int w, int h, const unsigned char *mask, float *gx, float *gy,
                               float *u, uint64_t *seed)
{
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t c = (size_t)y * w + x;
            gx[c] = x + 1 < w ? (float)(manufactured(x + 1, y) - manufactured(x, y)) : NAN;
            gy[c] = y + 1 < h ? (float)(manufactured(x, y + 1) - manufactured(x, y)) : NAN;
            u[c] = mask[c] ? (float)(1e4 * (th_uniform(seed) - 0.5)) : (float)manufactured(x, y);
        }
}

static void irregular_mask(int w, int h, unsigned char *mask, uint64_t *seed)
{
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            mask[(size_t)y * w + x] =
                0.5 * sin(x / 7.0) + 0.5 * cos(y / 5.0) + 0.4 * sin((x + 2 * y) / 11.0) > -0.4 &&
                th_uniform(seed) > 0.02;
}

static void test_manufactured(void)
{
    ts_ctx *ctx = ts_ctx_new();
    const int w = 100, h = 80;
    unsigned char *mask = malloc((size_t)w * h);
    float *gx = malloc(sizeof(float) * w * h), *gy = malloc(sizeof(float) * w * h);
    float *u = malloc(sizeof(float) * w * h);
    uint64_t seed = 5;
    double err = 0.0;
    size_t n_unknown = 0;
    int x, y;
    irregular_mask(w, h, mask, &seed);
    manufactured_setup(w, h, mask, gx, gy, u, &seed);
    CHECK_MSG(ts_poisson_solve(ctx, w, h, mask, gx, gy, u, 1e-8, 2000) == TS_OK, "%s",
              ts_ctx_message(ctx));
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            n_unknown += mask[y * w + x] != 0;
            err = fmax(err, fabs(u[y * w + x] - manufactured(x, y)));
        }
    CHECK(n_unknown > 4000 && n_unknown < 7900);
    CHECK_MSG(err < 1e-4, "max error %g", err);
    printf("     manufactured 100x80: %zu unknowns, max error %.2e\n", n_unknown, err);
    free(mask);
    free(gx);
    free(gy);
    free(u);
    ts_ctx_free(ctx);
}

/* Smallest max_iter that converges (exponential search, then bisection). */
static int min_iterations(ts_ctx *ctx, int w, int h, const unsigned char *mask, const float *gx,
                          const float *gy, const float *u0, float *u, double tol)
{
    int lo = 0, hi = 1;
    for (;;) {
        memcpy(u, u0, sizeof(float) * w * h);
        if (ts_poisson_solve(ctx, w, h, mask, gx, gy, u, tol, hi) == TS_OK)
            break;
        lo = hi;
        hi *= 2;
        if (hi > 100000)
            return -1;
    }
    while (hi - lo > 1) {
        int mid = lo + (hi - lo) / 2;
        memcpy(u, u0, sizeof(float) * w * h);
        if (ts_poisson_solve(ctx, w, h, mask, gx, gy, u, tol, mid) == TS_OK)
            hi = mid;
        else
            lo = mid;
    }
    return hi;
}

static void test_iterations_and_time(void)
{
    ts_ctx *ctx = ts_ctx_new();
    static const int sides[] = {50, 100, 200, 400};
    int iters[4], k;
    double t_ms = 0.0;
    for (k = 0; k < 4; k++) {
        int side = sides[k], x, y;
        size_t n = (size_t)side * side;
        unsigned char *mask = malloc(n);
        float *gx = malloc(n * sizeof(float)), *gy = malloc(n * sizeof(float));
        float *u0 = malloc(n * sizeof(float)), *u = malloc(n * sizeof(float));
        uint64_t seed = 3;
        double err = 0.0;
        for (y = 0; y < side; y++)
            for (x = 0; x < side; x++)
                mask[y * side + x] = x > 0 && y > 0 && x < side - 1 && y < side - 1;
        manufactured_setup(side, side, mask, gx, gy, u0, &seed);
        iters[k] = min_iterations(ctx, side, side, mask, gx, gy, u0, u, 1e-6);
        CHECK(iters[k] > 0);
        if (side == 400) {
            /* irregular mask: time one full solve */
            irregular_mask(side, side, mask, &seed);
            manufactured_setup(side, side, mask, gx, gy, u, &seed);
            t_ms = now_ms();
            CHECK(ts_poisson_solve(ctx, side, side, mask, gx, gy, u, 1e-6, 5000) == TS_OK);
            t_ms = now_ms() - t_ms;
            for (y = 0; y < side; y++)
                for (x = 0; x < side; x++)
                    err = fmax(err, fabs(u[y * side + x] - manufactured(x, y)));
            CHECK_MSG(err < 1e-2, "400x400 max error %g", err); /* tolerance 1e-6 only */
        }
        free(mask);
        free(gx);
        free(gy);
        free(u0);
        free(u);
    }
    printf("     iterations to 1e-6 (square, Dirichlet frame): 50: %d, 100: %d, 200: %d, "
           "400: %d\n",
           iters[0], iters[1], iters[2], iters[3]);
    printf("     400x400 irregular mask solve: %.1f ms\n", t_ms);
    /* MIC(0) grows like sqrt(side); plain CG or Jacobi would grow like side */
    CHECK_MSG(iters[3] < 3 * iters[1], "%d vs %d", iters[3], iters[1]);
    ts_ctx_free(ctx);
}

static void test_trivial_and_empty(void)
{
    ts_ctx *ctx = ts_ctx_new();
    unsigned char mask[30];
    float gx[30], gy[30], u[30];
    int i;
    for (i = 0; i < 30; i++) {
        mask[i] = i % 6 != 0 && i % 6 != 5;
        gx[i] = gy[i] = 0.0f;
        u[i] = mask[i] ? 1234.5f : 0.0f;
    }
    /* b = 0: the answer is exactly 0 whatever the initial guess */
    CHECK(ts_poisson_solve(ctx, 6, 5, mask, gx, gy, u, 1e-6, 10) == TS_OK);
    for (i = 0; i < 30; i++)
        CHECK(u[i] == 0.0f);
    /* no unknowns: nothing happens, NaN anywhere is fine */
    memset(mask, 0, sizeof mask);
    u[3] = NAN;
    gx[4] = NAN;
    CHECK(ts_poisson_solve(ctx, 6, 5, mask, gx, gy, u, 1e-6, 10) == TS_OK);
    CHECK(isnan(u[3]));
    /* one cell, no neighbours: keeps its value */
    mask[0] = 1;
    u[0] = 7.0f;
    CHECK(ts_poisson_solve(ctx, 1, 1, mask, gx, gy, u, 1e-6, 10) == TS_OK);
    CHECK(u[0] == 7.0f);
    ts_ctx_free(ctx);
}

/* ---- seam remover ---- */

static double plane(int x, int y) { return 0.3 * x + 0.2 * y + 100.0; }

/* Max |u(q) - u(p)| over 4-adjacent pairs with different labels. */
static double seam_gradient(const ts_raster *r, const unsigned char *labels)
{
    double g = 0.0;
    int x, y;
    for (y = 0; y < r->height; y++)
        for (x = 0; x < r->width; x++) {
            size_t c = (size_t)y * r->width + x;
            if (x + 1 < r->width && labels[c] != labels[c + 1])
                g = fmax(g, fabs(TS_PIX(r, x + 1, y) - TS_PIX(r, x, y)));
            if (y + 1 < r->height && labels[c] != labels[c + r->width])
                g = fmax(g, fabs(TS_PIX(r, x, y + 1) - TS_PIX(r, x, y)));
        }
    return g;
}

static void test_seam_two_planes(void)
{
    ts_ctx *ctx = ts_ctx_new();
    const int w = 60, h = 40;
    ts_raster m, before;
    unsigned char labels[60 * 40], region[60 * 40];
    double g0, g1, err = 0.0;
    int x, y;
    ts_raster_alloc(ctx, w, h, &m);
    ts_raster_alloc(ctx, w, h, &before);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            labels[y * w + x] = x >= 30;
            region[y * w + x] = x >= 15 && x < 45;
            TS_PIX(&m, x, y) = (float)(plane(x, y) + (x >= 30 ? 10.0 : 0.0));
            TS_PIX(&before, x, y) = TS_PIX(&m, x, y);
        }
    g0 = seam_gradient(&m, labels);
    CHECK(ts_poisson_seam_remove(ctx, &m, labels, region) == TS_OK);
    g1 = seam_gradient(&m, labels);
    CHECK_MSG(g1 < 1.0 && g1 <= g0, "seam gradient %g -> %g", g0, g1);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            /* 1-D along x: the 10.3 missing over 31 edges is spread evenly */
            double lift = x < 15 ? 0.0 : x >= 45 ? 10.0 : (x - 14) * 10.3 / 31.0 - (x >= 30) * 0.3;
            if (!region[y * w + x])
                CHECK(TS_PIX(&m, x, y) == TS_PIX(&before, x, y));
            err = fmax(err, fabs(TS_PIX(&m, x, y) - (plane(x, y) + lift)));
        }
    CHECK_MSG(err < 1e-3, "max error to the analytic ramp %g", err);
    for (y = 0; y < h; y++) { /* continuous with the boundary */
        CHECK(fabs(TS_PIX(&m, 15, y) - TS_PIX(&m, 14, y)) < 1.0);
        CHECK(fabs(TS_PIX(&m, 45, y) - TS_PIX(&m, 44, y)) < 1.0);
    }
    printf("     two planes: seam gradient %.3f -> %.3f\n", g0, g1);
    ts_raster_free(&m);
    ts_raster_free(&before);
    ts_ctx_free(ctx);
}

static double terrain(double x, double y, double phase)
{
    return 300.0 + 40.0 * sin(x / 9.0 + phase) * cos(y / 13.0 - phase) + 15.0 * sin((x + y) / 5.0);
}

/* A curved seam in a ring-shaped band between two rough terrains. */
static void make_ring(int w, int h, ts_raster *m, unsigned char *labels, unsigned char *region,
                      uint64_t *seed)
{
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double dx = x - w / 2.0, dy = y - h / 2.0, r = sqrt(dx * dx + dy * dy);
            double a = atan2(dy, dx);
            size_t c = (size_t)y * w + x;
            labels[c] = r < 32.0 + 4.0 * sin(3.0 * a);
            region[c] = r > 20.0 && r < 45.0;
            TS_PIX(m, x, y) = (float)(labels[c] ? terrain(x, y, 1.0) + 25.0
                                                : terrain(x, y, 0.0) + 3.0 * th_uniform(seed));
        }
}

static void test_seam_ring(void)
{
    ts_ctx *ctx = ts_ctx_new();
    const int w = 120, h = 100;
    ts_raster m, before;
    unsigned char *labels = malloc((size_t)w * h), *region = malloc((size_t)w * h);
    uint64_t seed = 9;
    double g0, g1, t;
    int x, y;
    ts_raster_alloc(ctx, w, h, &m);
    ts_raster_alloc(ctx, w, h, &before);
    make_ring(w, h, &m, labels, region, &seed);
    memcpy(before.data, m.data, sizeof(float) * w * h);
    g0 = seam_gradient(&m, labels);
    t = now_ms();
    CHECK(ts_poisson_seam_remove(ctx, &m, labels, region) == TS_OK);
    t = now_ms() - t;
    g1 = seam_gradient(&m, labels);
    CHECK_MSG(g1 <= g0 && g1 < 0.5 * g0, "seam gradient %g -> %g", g0, g1);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            if (!region[y * w + x])
                CHECK(TS_PIX(&m, x, y) == TS_PIX(&before, x, y));
    printf("     ring band: seam gradient %.2f -> %.2f (%.2f ms)\n", g0, g1, t);
    /* no seam: labels all equal leave the field as it is */
    memcpy(m.data, before.data, sizeof(float) * w * h);
    memset(labels, 1, (size_t)w * h);
    CHECK(ts_poisson_seam_remove(ctx, &m, labels, region) == TS_OK);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            CHECK_NEAR(TS_PIX(&m, x, y), TS_PIX(&before, x, y), 1e-4);
    free(labels);
    free(region);
    ts_raster_free(&m);
    ts_raster_free(&before);
    ts_ctx_free(ctx);
}

/* NaN cells stay NaN and act like the grid edge; a view with a stride only
 * touches its own cells; the seam remover equals the dense oracle. */
static void test_seam_nan_stride_reference(void)
{
    ts_ctx *ctx = ts_ctx_new();
    enum { W = 9, H = 7, PAD = 3 };
    float big[(H + 2) * (W + PAD)];
    unsigned char labels[W * H], region[W * H], cls[W * H];
    double gr[W * H], gd[W * H], ref[W * H], err = 0.0;
    uint64_t seed = 21;
    int trial, x, y;
    for (trial = 0; trial < 40; trial++) {
        ts_raster m = ts_raster_wrap(big + (W + PAD) + 1, W, H, W + PAD);
        size_t c;
        for (c = 0; c < sizeof big / sizeof big[0]; c++)
            big[c] = -999.0f;
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                c = (size_t)y * W + x;
                labels[c] = x + 2.0 * th_uniform(&seed) > W / 2.0;
                region[c] = th_uniform(&seed) < (trial < 5 ? 1.0 : 0.7);
                TS_PIX(&m, x, y) = th_uniform(&seed) < 0.15
                                       ? NAN
                                       : (float)(20.0 * th_uniform(&seed) + 5.0 * labels[c]);
            }
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                c = (size_t)y * W + x;
                cls[c] = isnan(TS_PIX(&m, x, y)) ? REF_OUT : region[c] ? REF_UNKNOWN : REF_KNOWN;
                ref[c] = TS_PIX(&m, x, y);
                gr[c] = x + 1 < W && labels[c] == labels[c + 1]
                            ? (double)TS_PIX(&m, x + 1, y) - TS_PIX(&m, x, y) : 0.0;
                gd[c] = y + 1 < H && labels[c] == labels[c + W]
                            ? (double)TS_PIX(&m, x, y + 1) - TS_PIX(&m, x, y) : 0.0;
            }
        CHECK(ref_solve(W, H, cls, gr, gd, ref));
        CHECK_MSG(ts_poisson_seam_remove(ctx, &m, labels, region) == TS_OK, "%s",
                  ts_ctx_message(ctx));
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                c = (size_t)y * W + x;
                if (cls[c] == REF_OUT)
                    CHECK(isnan(TS_PIX(&m, x, y)));
                else
                    err = fmax(err, fabs(TS_PIX(&m, x, y) - ref[c]));
            }
        for (c = 0; c < sizeof big / sizeof big[0]; c++) {
            ptrdiff_t off = (ptrdiff_t)c - (W + PAD) - 1;
            int in_view = off >= 0 && off / (W + PAD) < H && off % (W + PAD) < W;
            if (!in_view)
                CHECK(big[c] == -999.0f);
        }
    }
    CHECK_MSG(err < 1e-3, "max error to the dense oracle %g", err); /* values ~25: 4e-5 */
    printf("     seam remover vs dense oracle (NaN cells, stride): max error %.2e\n", err);
    ts_ctx_free(ctx);
}

/* Region = the whole grid: no Dirichlet cell, the mean is kept and the
 * step disappears completely (the adjusted gradients are then consistent). */
static void test_seam_pure_neumann(void)
{
    ts_ctx *ctx = ts_ctx_new();
    const int w = 40, h = 20;
    ts_raster m;
    unsigned char labels[40 * 20], region[40 * 20];
    double mean0 = 0.0, mean1 = 0.0;
    int x, y;
    ts_raster_alloc(ctx, w, h, &m);
    memset(region, 1, sizeof region);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            labels[y * w + x] = x >= 20;
            TS_PIX(&m, x, y) = (float)(plane(x, y) + (x >= 20 ? 10.0 : 0.0));
            mean0 += TS_PIX(&m, x, y);
        }
    CHECK(ts_poisson_seam_remove(ctx, &m, labels, region) == TS_OK);
    for (y = 0; y < h; y++) {
        CHECK_NEAR(TS_PIX(&m, 20, y) - TS_PIX(&m, 19, y), 0.0, 1e-3);
        CHECK_NEAR(TS_PIX(&m, 10, y) - TS_PIX(&m, 9, y), 0.3, 1e-3);
        for (x = 0; x < w; x++)
            mean1 += TS_PIX(&m, x, y);
    }
    CHECK_NEAR(mean1 / (w * h), mean0 / (w * h), 1e-3);

    /* an island of the region walled in by NaN: pinned on its own, while
     * the rest of the region has Dirichlet cells on the grid's left edge */
    mean0 = mean1 = 0.0;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            int wall = (x == 24 || x == 36) && y >= 4 && y <= 14;
            wall |= (y == 4 || y == 14) && x >= 24 && x <= 36;
            region[y * w + x] = x > 0;
            labels[y * w + x] = x >= 30;
            TS_PIX(&m, x, y) = wall ? NAN : (float)(plane(x, y) + (x >= 30 ? 10.0 : 0.0));
            if (x > 24 && x < 36 && y > 4 && y < 14)
                mean0 += TS_PIX(&m, x, y);
        }
    CHECK(ts_poisson_seam_remove(ctx, &m, labels, region) == TS_OK);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            int wall = (x == 24 || x == 36) && y >= 4 && y <= 14;
            wall |= (y == 4 || y == 14) && x >= 24 && x <= 36;
            CHECK(wall == (isnan(TS_PIX(&m, x, y)) != 0));
            if (x > 24 && x < 36 && y > 4 && y < 14)
                mean1 += TS_PIX(&m, x, y);
            if (x == 0)
                CHECK(TS_PIX(&m, x, y) == (float)plane(x, y));
        }
    CHECK_NEAR(mean1, mean0, 1e-2); /* 99 cells */
    for (y = 5; y < 14; y++)
        CHECK_NEAR(TS_PIX(&m, 30, y) - TS_PIX(&m, 29, y), 0.0, 1e-3);
    ts_raster_free(&m);
    ts_ctx_free(ctx);
}

/* Typical uses: a 200x200 region, and a 40-cell band around a 128 patch. */
static void test_seam_speed(void)
{
    ts_ctx *ctx = ts_ctx_new();
    static const int cfg[][3] = {{202, 0, 0}, {64 + 2 * 20 + 2, 64, 20},
                                 {128 + 2 * 40 + 2, 128, 40}, {256 + 2 * 60 + 2, 256, 60}};
    int k;
    for (k = 0; k < 4; k++) {
        int size = cfg[k][0], patch = cfg[k][1], band = cfg[k][2], x, y, rep, reps = 10;
        size_t n = (size_t)size * size;
        ts_raster m, m0;
        unsigned char *labels = malloc(n), *region = malloc(n);
        uint64_t seed = 4;
        double t, g0, g1;
        size_t n_region = 0;
        ts_raster_alloc(ctx, size, size, &m);
        ts_raster_alloc(ctx, size, size, &m0);
        for (y = 0; y < size; y++)
            for (x = 0; x < size; x++) {
                size_t c = (size_t)y * size + x;
                /* Chebyshev distance from the centre; the patch is the
                 * inside, the seam wanders inside the band around it */
                double cheb = fmax(fabs(x - size / 2.0), fabs(y - size / 2.0));
                if (patch == 0) { /* a 200x200 region with a diagonal seam */
                    region[c] = x > 0 && y > 0 && x < size - 1 && y < size - 1;
                    labels[c] = x + y > size;
                } else {
                    region[c] = cheb >= patch / 2.0 && cheb < patch / 2.0 + band;
                    labels[c] = cheb < patch / 2.0 + band * (0.5 + 0.25 * sin(x / 9.0 + y / 7.0));
                }
                n_region += region[c];
                TS_PIX(&m0, x, y) = (float)(terrain(x, y, labels[c] ? 2.0 : 0.0) +
                                            labels[c] * 30.0 + th_uniform(&seed));
            }
        g0 = seam_gradient(&m0, labels);
        t = 0.0;
        for (rep = 0; rep < reps; rep++) {
            double t0;
            memcpy(m.data, m0.data, n * sizeof(float));
            t0 = now_ms();
            CHECK(ts_poisson_seam_remove(ctx, &m, labels, region) == TS_OK);
            t += now_ms() - t0;
        }
        g1 = seam_gradient(&m, labels);
        CHECK_MSG(g1 <= g0, "seam gradient %g -> %g", g0, g1);
        printf("     seam remover %dx%d, %zu region cells: %.2f ms per call "
               "(seam gradient %.1f -> %.1f)\n",
               size, size, n_region, t / reps, g0, g1);
        free(labels);
        free(region);
        ts_raster_free(&m);
        ts_raster_free(&m0);
    }
    ts_ctx_free(ctx);
}

/* ---- errors ---- */

static int cancel_progress(double done, const char *msg, void *user)
{
    (void)done;
    (void)msg;
    ++*(int *)user;
    return 0;
}

static void test_errors(void)
{
    ts_ctx *ctx = ts_ctx_new();
    enum { W = 8, H = 6 };
    unsigned char mask[W * H];
    float gx[W * H], gy[W * H], u[W * H], u0[W * H];
    int i, calls = 0;
    for (i = 0; i < W * H; i++) {
        int x = i % W, y = i / W;
        mask[i] = x > 1 && x < W - 2 && y > 1 && y < H - 2;
        gx[i] = gy[i] = 0.5f;
        u0[i] = u[i] = (float)i;
    }
    /* NaN guidance on an edge between two known cells is not used */
    gx[0] = NAN;
    u[W * H - 1] = NAN;
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, 1e-6, 100) == TS_OK);
    u[W * H - 1] = NAN;
    memcpy(u0, u, sizeof u);
    /* ... but on an edge of an unknown it is an error, and u is unchanged */
    gx[2 * W + 1] = NAN; /* edge (1,2)-(2,2): (2,2) is unknown */
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, 1e-6, 100) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "poisson") != NULL);
    CHECK(memcmp(u, u0, sizeof u) == 0);
    gx[2 * W + 1] = 0.5f;
    gy[3 * W + 3] = NAN; /* below an unknown */
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, 1e-6, 100) == TS_ERR_ARG);
    gy[3 * W + 3] = 0.5f;
    u[1 * W + 3] = NAN; /* a boundary value in use */
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, 1e-6, 100) == TS_ERR_ARG);
    u[1 * W + 3] = 1.0f;
    u[3 * W + 3] = INFINITY; /* an initial value */
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, 1e-6, 100) == TS_ERR_ARG);
    u[3 * W + 3] = 1.0f;
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, 1e-6, 100) == TS_OK);
    CHECK(ts_ctx_message(ctx)[0] == '\0');
    /* arguments */
    CHECK(ts_poisson_solve(ctx, 0, H, mask, gx, gy, u, 1e-6, 100) == TS_ERR_SIZE);
    CHECK(ts_poisson_solve(ctx, W, H, NULL, gx, gy, u, 1e-6, 100) == TS_ERR_ARG);
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, 0.0, 100) == TS_ERR_ARG);
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, NAN, 100) == TS_ERR_ARG);
    CHECK(ts_poisson_solve(ctx, W, H, mask, gx, gy, u, 1e-6, -1) == TS_ERR_ARG);
    CHECK(ts_poisson_seam_remove(ctx, NULL, mask, mask) == TS_ERR_ARG);

    /* non-convergence and cancellation on a big problem */
    {
        const int side = 300;
        size_t n = (size_t)side * side, c;
        unsigned char *bm = malloc(n);
        float *bgx = malloc(n * sizeof(float)), *bgy = malloc(n * sizeof(float));
        float *bu = malloc(n * sizeof(float)), *bu0 = malloc(n * sizeof(float));
        uint64_t seed = 8;
        irregular_mask(side, side, bm, &seed);
        manufactured_setup(side, side, bm, bgx, bgy, bu, &seed);
        memcpy(bu0, bu, n * sizeof(float));
        CHECK(ts_poisson_solve(ctx, side, side, bm, bgx, bgy, bu, 1e-6, 1) == TS_ERR_NUMERIC);
        CHECK(strstr(ts_ctx_message(ctx), "converge") != NULL);
        CHECK(memcmp(bu, bu0, n * sizeof(float)) == 0);
        /* a Dirichlet frame only: more than 64 iterations, cancelled in the loop */
        for (c = 0; c < n; c++)
            bm[c] = c % (size_t)side != 0 && c % (size_t)side != (size_t)side - 1 &&
                    c / (size_t)side != 0 && c / (size_t)side != (size_t)side - 1;
        ts_ctx_set_progress(ctx, cancel_progress, &calls);
        CHECK(ts_poisson_solve(ctx, side, side, bm, bgx, bgy, bu, 1e-14, 5000) ==
              TS_ERR_CANCELLED);
        CHECK(calls == 1);
        ts_ctx_set_progress(ctx, NULL, NULL);
        for (c = 0; c < n; c++)
            if (bu[c] != bu0[c] && !(isnan(bu[c]) && isnan(bu0[c])))
                break;
        CHECK(c == n);
        free(bm);
        free(bgx);
        free(bgy);
        free(bu);
        free(bu0);
    }
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"dense_reference", test_dense_reference},
        {"nan_cells_reference", test_nan_cells_reference},
        {"manufactured", test_manufactured},
        {"iterations_and_time", test_iterations_and_time},
        {"trivial_and_empty", test_trivial_and_empty},
        {"seam_two_planes", test_seam_two_planes},
        {"seam_ring", test_seam_ring},
        {"seam_nan_stride_reference", test_seam_nan_stride_reference},
        {"seam_pure_neumann", test_seam_pure_neumann},
        {"seam_speed", test_seam_speed},
        {"errors", test_errors},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
