/*
 * test_tps.c - thin-plate spline fit, bending energy and raster warp
 * (algorithms/src/sketch/tps.c): interpolation, affine reproduction, rigid and
 * scale behaviour of the bending energy, special cases and errors, and a
 * slow oracle (naive Gauss-Jordan on the unnormalised system).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "terrasynth.h"
#include "tps.h"

#define NMAX TS_TPS_MAX

/* n random source points in [0, extent)^2 at least min_dist apart, and
 * targets displaced by up to +-disp per axis. */
static void random_config(uint64_t *rng, int n, double extent, double min_dist, double disp,
                          double *sx, double *sy, double *dx, double *dy)
{
    int i = 0, j;
    while (i < n) {
        double x = extent * th_uniform(rng), y = extent * th_uniform(rng);
        int ok = 1;
        for (j = 0; j < i; j++)
            if (hypot(x - sx[j], y - sy[j]) < min_dist)
                ok = 0;
        if (!ok)
            continue;
        sx[i] = x;
        sy[i] = y;
        dx[i] = x + disp * (2.0 * th_uniform(rng) - 1.0);
        dy[i] = y + disp * (2.0 * th_uniform(rng) - 1.0);
        i++;
    }
}

static double kernel(double r2)
{
    return r2 > 0.0 ? r2 * log(r2) : 0.0;
}

static void test_interpolates_control_points(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t rng = 11;
    int n, rep, i;
    for (n = 3; n <= 12; n++)
        for (rep = 0; rep < 20; rep++) {
            double sx[NMAX], sy[NMAX], dx[NMAX], dy[NMAX];
            ts_tps t;
            random_config(&rng, n, 64.0, 1.0, 6.0, sx, sy, dx, dy);
            CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t) == TS_OK);
            CHECK(t.n == n);
            CHECK(t.bending >= 0.0 && isfinite(t.bending));
            for (i = 0; i < n; i++) {
                double ox, oy;
                ts__tps_map(&t, sx[i], sy[i], &ox, &oy);
                CHECK_NEAR(ox, dx[i], 1e-9);
                CHECK_NEAR(oy, dy[i], 1e-9);
            }
        }
    /* far from the origin (large map coordinates) */
    for (rep = 0; rep < 20; rep++) {
        double sx[NMAX], sy[NMAX], dx[NMAX], dy[NMAX];
        ts_tps t;
        random_config(&rng, 8, 128.0, 2.0, 10.0, sx, sy, dx, dy);
        for (i = 0; i < 8; i++) {
            sx[i] += 5000.0;
            sy[i] -= 3000.0;
        }
        CHECK(ts__tps_fit(ctx, 8, sx, sy, dx, dy, 0.0, &t) == TS_OK);
        for (i = 0; i < 8; i++) {
            double ox, oy;
            ts__tps_map(&t, sx[i], sy[i], &ox, &oy);
            CHECK_NEAR(ox, dx[i], 1e-9);
            CHECK_NEAR(oy, dy[i], 1e-9);
        }
    }
    ts_ctx_free(ctx);
}

static void test_affine_reproduced(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t rng = 12;
    int rep, i, k;
    for (rep = 0; rep < 50; rep++) {
        double sx[NMAX], sy[NMAX], dx[NMAX], dy[NMAX], A[6];
        int n = 3 + rep % 14;
        ts_tps t;
        for (k = 0; k < 6; k++)
            A[k] = 4.0 * th_uniform(&rng) - 2.0;
        A[0] *= 20.0;
        A[3] *= 20.0;
        random_config(&rng, n, 64.0, 1.0, 0.0, sx, sy, dx, dy);
        for (i = 0; i < n; i++) {
            dx[i] = A[0] + A[1] * sx[i] + A[2] * sy[i];
            dy[i] = A[3] + A[4] * sx[i] + A[5] * sy[i];
        }
        CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t) == TS_OK);
        CHECK_MSG(t.bending < 1e-9, "bending %g, n %d", t.bending, n);
        for (k = 0; k < 100; k++) {
            double x = 200.0 * th_uniform(&rng) - 70.0, y = 200.0 * th_uniform(&rng) - 70.0;
            double ox, oy;
            ts__tps_map(&t, x, y, &ox, &oy);
            CHECK_NEAR(ox, A[0] + A[1] * x + A[2] * y, 1e-9);
            CHECK_NEAR(oy, A[3] + A[4] * x + A[5] * y, 1e-9);
        }
    }
    ts_ctx_free(ctx);
}

static void rigid(double *x, double *y, int n, double angle, double tx, double ty)
{
    double c = cos(angle), s = sin(angle);
    int i;
    for (i = 0; i < n; i++) {
        double xx = c * x[i] - s * y[i] + tx, yy = s * x[i] + c * y[i] + ty;
        x[i] = xx;
        y[i] = yy;
    }
}

static void test_bending_rigid_invariance(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t rng = 13;
    int rep, i;
    for (rep = 0; rep < 30; rep++) {
        double sx[NMAX], sy[NMAX], dx[NMAX], dy[NMAX];
        int n = 4 + rep % 10; /* n = 3 is always affine: bending 0 */
        ts_tps t0, t1, t2;
        random_config(&rng, n, 64.0, 2.0, 8.0, sx, sy, dx, dy);
        CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t0) == TS_OK);
        CHECK(t0.bending > 1e-6);
        /* the whole configuration moved rigidly */
        rigid(sx, sy, n, 0.7 + rep, 31.0, -17.0);
        rigid(dx, dy, n, 0.7 + rep, 31.0, -17.0);
        CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t1) == TS_OK);
        CHECK_MSG(fabs(t1.bending - t0.bending) <= 1e-9 * t0.bending, "%.17g vs %.17g", t1.bending,
                  t0.bending);
        /* target moved on its own: the same map up to a rigid motion */
        rigid(dx, dy, n, -2.1, 400.0, 9.0);
        CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t2) == TS_OK);
        CHECK_MSG(fabs(t2.bending - t0.bending) <= 1e-9 * t0.bending, "%.17g vs %.17g", t2.bending,
                  t0.bending);
        for (i = 0; i < n; i++) { /* still interpolating after the move */
            double ox, oy;
            ts__tps_map(&t2, sx[i], sy[i], &ox, &oy);
            CHECK_NEAR(ox, dx[i], 1e-9);
            CHECK_NEAR(oy, dy[i], 1e-9);
        }
    }
    ts_ctx_free(ctx);
}

/* Documented scaling: source and target scaled together -> unchanged;
 * source only -> 1 / s^2. */
static void test_bending_scaling(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t rng = 14;
    double sx[NMAX], sy[NMAX], dx[NMAX], dy[NMAX], s = 3.5;
    ts_tps t0, t1, t2;
    int i, n = 7;
    random_config(&rng, n, 64.0, 2.0, 8.0, sx, sy, dx, dy);
    CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t0) == TS_OK);
    for (i = 0; i < n; i++) {
        sx[i] *= s;
        sy[i] *= s;
    }
    CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t1) == TS_OK);
    CHECK_NEAR(t1.bending * s * s / t0.bending, 1.0, 1e-9);
    for (i = 0; i < n; i++) {
        dx[i] *= s;
        dy[i] *= s;
    }
    CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t2) == TS_OK);
    CHECK_NEAR(t2.bending / t0.bending, 1.0, 1e-9);
    ts_ctx_free(ctx);
}

static void test_bending_monotone_in_displacement(void)
{
    ts_ctx *ctx = ts_ctx_new();
    double sx[5] = {0, 40, 40, 0, 20}, sy[5] = {0, 0, 40, 40, 20};
    double dx[5], dy[5], prev = -1.0;
    int step, i;
    for (step = 0; step <= 10; step++) {
        ts_tps t;
        for (i = 0; i < 5; i++) {
            dx[i] = sx[i];
            dy[i] = sy[i];
        }
        dx[4] += 0.8 * step;
        dy[4] += 0.3 * step;
        CHECK(ts__tps_fit(ctx, 5, sx, sy, dx, dy, 0.0, &t) == TS_OK);
        if (step == 0)
            CHECK(t.bending < 1e-12);
        else
            CHECK_MSG(t.bending > prev, "step %d: %g <= %g", step, t.bending, prev);
        prev = t.bending;
    }
    ts_ctx_free(ctx);
}

/* Regularisation: larger lambda, smoother (bending non-increasing). */
static void test_lambda_smooths(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t rng = 15;
    double sx[NMAX], sy[NMAX], dx[NMAX], dy[NMAX], prev = INFINITY, err = 0.0;
    double lambdas[5] = {0.0, 1.0, 10.0, 100.0, 1e4};
    int k, i, n = 9;
    random_config(&rng, n, 64.0, 2.0, 8.0, sx, sy, dx, dy);
    for (k = 0; k < 5; k++) {
        ts_tps t;
        CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, lambdas[k], &t) == TS_OK);
        CHECK_MSG(t.bending <= prev * (1.0 + 1e-12), "lambda %g: %g > %g", lambdas[k], t.bending,
                  prev);
        prev = t.bending;
        if (k == 4)
            for (i = 0; i < n; i++) {
                double ox, oy;
                ts__tps_map(&t, sx[i], sy[i], &ox, &oy);
                err = fmax(err, hypot(ox - dx[i], oy - dy[i]));
            }
    }
    CHECK(err > 1e-3); /* no longer interpolating */
    ts_ctx_free(ctx);
}

/* The oracle: the same system in the caller's coordinates, no scaling,
 * equations ordered [P^T; K + lambda I P] so that plain Gauss-Jordan without
 * pivoting finds non-zero pivots on generic configurations. */
static int naive_tps(int n, const double *sx, const double *sy, const double *v, double lambda,
                     double *w, double *a)
{
    double m[NMAX + 3][NMAX + 4];
    int dim = n + 3, i, j, r;
    memset(m, 0, sizeof m);
    for (j = 0; j < n; j++) { /* rows 0..2: sum w = 0, sum w x = 0, sum w y = 0 */
        m[0][j] = 1.0;
        m[1][j] = sx[j];
        m[2][j] = sy[j];
    }
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++)
            m[3 + i][j] =
                kernel((sx[i] - sx[j]) * (sx[i] - sx[j]) + (sy[i] - sy[j]) * (sy[i] - sy[j]));
        m[3 + i][i] += lambda;
        m[3 + i][n] = 1.0;
        m[3 + i][n + 1] = sx[i];
        m[3 + i][n + 2] = sy[i];
        m[3 + i][dim] = v[i];
    }
    for (r = 0; r < dim; r++) {
        double p = m[r][r];
        if (p == 0.0)
            return 1;
        for (j = 0; j <= dim; j++)
            m[r][j] /= p;
        for (i = 0; i < dim; i++) {
            double f = m[i][r];
            if (i == r || f == 0.0)
                continue;
            for (j = 0; j <= dim; j++)
                m[i][j] -= f * m[r][j];
        }
    }
    for (i = 0; i < n; i++)
        w[i] = m[i][dim];
    for (i = 0; i < 3; i++)
        a[i] = m[n + i][dim];
    return 0;
}

static double naive_eval(int n, const double *sx, const double *sy, const double *w,
                         const double *a, double x, double y)
{
    double f = a[0] + a[1] * x + a[2] * y;
    int i;
    for (i = 0; i < n; i++)
        f += w[i] * kernel((x - sx[i]) * (x - sx[i]) + (y - sy[i]) * (y - sy[i]));
    return f;
}

static void test_against_naive_solver(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t rng = 16;
    int rep, k, i;
    for (rep = 0; rep < 40; rep++) {
        double sx[NMAX], sy[NMAX], dx[NMAX], dy[NMAX], wx[NMAX], wy[NMAX], ax[3], ay[3];
        double lambda = (rep % 4 == 3) ? 2.5 : 0.0, be = 0.0;
        int n = 3 + rep % 8;
        ts_tps t;
        /* well conditioned: spread-out points in a few-cell box */
        random_config(&rng, n, 8.0, 1.0, 1.5, sx, sy, dx, dy);
        CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, lambda, &t) == TS_OK);
        if (naive_tps(n, sx, sy, dx, lambda, wx, ax) || naive_tps(n, sx, sy, dy, lambda, wy, ay)) {
            CHECK_MSG(0, "oracle hit a zero pivot (rep %d)", rep);
            continue;
        }
        for (k = 0; k < 50; k++) {
            double x = 16.0 * th_uniform(&rng) - 4.0, y = 16.0 * th_uniform(&rng) - 4.0;
            double ox, oy;
            ts__tps_map(&t, x, y, &ox, &oy);
            CHECK_NEAR(ox, naive_eval(n, sx, sy, wx, ax, x, y), 1e-9);
            CHECK_NEAR(oy, naive_eval(n, sx, sy, wy, ay, x, y), 1e-9);
        }
        for (i = 0; i < n; i++) {
            int j;
            for (j = 0; j < n; j++) {
                double kij =
                    kernel((sx[i] - sx[j]) * (sx[i] - sx[j]) + (sy[i] - sy[j]) * (sy[i] - sy[j]));
                be += kij * (wx[i] * wx[j] + wy[i] * wy[j]);
            }
        }
        CHECK_NEAR(t.bending, be, 1e-9 * fmax(1.0, be));
    }
    ts_ctx_free(ctx);
}

static void test_special_cases(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_tps t;
    double ox, oy;
    /* n = 1: translation */
    {
        double sx = 3.0, sy = 4.0, dx = 10.5, dy = -2.0;
        CHECK(ts__tps_fit(ctx, 1, &sx, &sy, &dx, &dy, 0.0, &t) == TS_OK);
        CHECK(t.bending == 0.0);
        ts__tps_map(&t, 3.0, 4.0, &ox, &oy);
        CHECK_NEAR(ox, 10.5, 1e-12);
        CHECK_NEAR(oy, -2.0, 1e-12);
        ts__tps_map(&t, -100.0, 7.0, &ox, &oy);
        CHECK_NEAR(ox, -92.5, 1e-12);
        CHECK_NEAR(oy, 1.0, 1e-12);
    }
    /* n = 2: similarity, here a 90-degree turn with scale 2 about (1, 1),
     * then a shift by (5, 0) */
    {
        double sx[2] = {1.0, 3.0}, sy[2] = {1.0, 1.0}, dx[2] = {6.0, 6.0}, dy[2] = {1.0, 5.0};
        CHECK(ts__tps_fit(ctx, 2, sx, sy, dx, dy, 0.0, &t) == TS_OK);
        CHECK(t.bending == 0.0);
        ts__tps_map(&t, 1.0, 1.0, &ox, &oy);
        CHECK_NEAR(ox, 6.0, 1e-12);
        CHECK_NEAR(oy, 1.0, 1e-12);
        ts__tps_map(&t, 3.0, 1.0, &ox, &oy);
        CHECK_NEAR(ox, 6.0, 1e-12);
        CHECK_NEAR(oy, 5.0, 1e-12);
        ts__tps_map(&t, 1.0, 2.0, &ox, &oy); /* (0, 1) -> 2 * (-1, 0) */
        CHECK_NEAR(ox, 4.0, 1e-12);
        CHECK_NEAR(oy, 1.0, 1e-12);
        sx[1] = sx[0];
        sy[1] = sy[0];
        CHECK(ts__tps_fit(ctx, 2, sx, sy, dx, dy, 0.0, &t) == TS_ERR_ARG);
    }
    ts_ctx_free(ctx);
}

static void test_errors(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_tps t;
    double sx[4] = {0, 1, 2, 3}, sy[4] = {0, 2, 4, 6}, dx[4] = {0, 1, 2, 3}, dy[4] = {1, 0, 1, 0};
    double ox, oy, big[17] = {0};
    /* collinear */
    CHECK(ts__tps_fit(ctx, 4, sx, sy, dx, dy, 0.0, &t) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "collinear") != NULL);
    CHECK(t.n == 0 && isinf(t.bending));
    ts__tps_map(&t, 2.0, 3.0, &ox, &oy); /* identity after a failure */
    CHECK(ox == 2.0 && oy == 3.0);
    CHECK(ts__tps_fit(ctx, 3, sx, sy, dx, dy, 1.0, &t) == TS_ERR_ARG);
    /* all coinciding */
    CHECK(ts__tps_fit(ctx, 3, big, big, dx, dy, 0.0, &t) == TS_ERR_ARG);
    /* non-finite input */
    sy[3] = 1.0; /* no longer collinear */
    CHECK(ts__tps_fit(ctx, 4, sx, sy, dx, dy, 0.0, &t) == TS_OK);
    dx[2] = NAN;
    CHECK(ts__tps_fit(ctx, 4, sx, sy, dx, dy, 0.0, &t) == TS_ERR_ARG);
    dx[2] = 2.0;
    sx[1] = INFINITY;
    CHECK(ts__tps_fit(ctx, 4, sx, sy, dx, dy, 0.0, &t) == TS_ERR_ARG);
    sx[1] = 1.0;
    CHECK(ts__tps_fit(ctx, 4, sx, sy, dx, dy, NAN, &t) == TS_ERR_ARG);
    CHECK(ts__tps_fit(ctx, 4, sx, sy, dx, dy, -1.0, &t) == TS_ERR_ARG);
    /* n out of range */
    CHECK(ts__tps_fit(ctx, 0, sx, sy, dx, dy, 0.0, &t) == TS_ERR_ARG);
    CHECK(ts__tps_fit(ctx, 17, big, big, big, big, 0.0, &t) == TS_ERR_ARG);
    CHECK(ts__tps_fit(ctx, 4, NULL, sy, dx, dy, 0.0, &t) == TS_ERR_ARG);
    /* repeated source point with lambda = 0: singular; lambda > 0 copes */
    {
        double rx[4] = {0, 10, 0, 0}, ry[4] = {0, 0, 10, 10}, qx[4] = {0, 10, 0, 1},
               qy[4] = {0, 0, 10, 11};
        CHECK(ts__tps_fit(ctx, 4, rx, ry, qx, qy, 0.0, &t) == TS_ERR_NUMERIC);
        CHECK(ts__tps_fit(ctx, 4, rx, ry, qx, qy, 0.5, &t) == TS_OK);
    }
    ts_ctx_free(ctx);
}

/* --- warp ------------------------------------------------------------- */

static ts_raster make_src(ts_ctx *ctx, int w, int h)
{
    ts_raster r;
    int x, y;
    if (ts_raster_alloc(ctx, w, h, &r) != TS_OK)
        abort();
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            TS_PIX(&r, x, y) = (float)(100.0 + 3.0 * x - 2.0 * y + 5.0 * sin(0.9 * x * y));
    return r;
}

static int same_cell(float a, float b)
{
    return (isnan(a) && isnan(b)) || a == b;
}

static void test_warp_identity(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster src = make_src(ctx, 23, 17), out;
    double sx[4] = {0, 23, 23, 0}, sy[4] = {0, 0, 17, 17};
    ts_tps t;
    int x, y, bad = 0;
    TS_PIX(&src, 5, 6) = NAN;
    CHECK(ts__tps_fit(ctx, 4, sx, sy, sx, sy, 0.0, &t) == TS_OK);
    CHECK(ts_raster_alloc(ctx, 23, 17, &out) == TS_OK);
    CHECK(ts__tps_warp(ctx, &t, &src, 0.0, 0.0, &out) == TS_OK);
    for (y = 0; y < 17; y++)
        for (x = 0; x < 23; x++)
            bad += !same_cell(TS_PIX(&out, x, y), TS_PIX(&src, x, y));
    CHECK_MSG(bad == 0, "%d cells differ", bad);
    /* offset by whole cells: a sub-window */
    ts_raster_free(&out);
    CHECK(ts_raster_alloc(ctx, 10, 8, &out) == TS_OK);
    CHECK(ts__tps_warp(ctx, &t, &src, 4.0, 3.0, &out) == TS_OK);
    bad = 0;
    for (y = 0; y < 8; y++)
        for (x = 0; x < 10; x++)
            bad += !same_cell(TS_PIX(&out, x, y), TS_PIX(&src, x + 4, y + 3));
    CHECK_MSG(bad == 0, "%d cells differ", bad);
    ts_raster_free(&out);
    ts_raster_free(&src);
    ts_ctx_free(ctx);
}

static void test_warp_integer_shift(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster src = make_src(ctx, 20, 15), out;
    double px = 10.0, py = 7.0, qx = 13.0, qy = 5.0; /* T(x, y) = (x + 3, y - 2) */
    ts_tps t;
    int x, y, bad = 0, nan_ok = 1;
    CHECK(ts__tps_fit(ctx, 1, &px, &py, &qx, &qy, 0.0, &t) == TS_OK);
    CHECK(ts_raster_alloc(ctx, 20, 15, &out) == TS_OK);
    CHECK(ts__tps_warp(ctx, &t, &src, 0.0, 0.0, &out) == TS_OK);
    for (y = 0; y < 15; y++)
        for (x = 0; x < 20; x++) {
            int xs = x + 3, ys = y - 2;
            if (xs >= 20 || ys < 0)
                nan_ok &= isnan(TS_PIX(&out, x, y));
            else
                bad += !same_cell(TS_PIX(&out, x, y), TS_PIX(&src, xs, ys));
        }
    CHECK_MSG(bad == 0, "%d cells differ", bad);
    CHECK(nan_ok);
    ts_raster_free(&out);
    ts_raster_free(&src);
    ts_ctx_free(ctx);
}

static void test_warp_half_cells_and_nodata(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster src = make_src(ctx, 12, 10), out;
    double px = 0.0, py = 0.0, qx = 0.5, qy = 0.0, ry = 0.5;
    ts_tps t;
    int x, y;
    /* half a cell along x: mean of the two neighbours */
    CHECK(ts__tps_fit(ctx, 1, &px, &py, &qx, &qy, 0.0, &t) == TS_OK);
    CHECK(ts_raster_alloc(ctx, 12, 10, &out) == TS_OK);
    CHECK(ts__tps_warp(ctx, &t, &src, 0.0, 0.0, &out) == TS_OK);
    for (y = 0; y < 10; y++) {
        for (x = 0; x < 11; x++) {
            double m = 0.5 * ((double)TS_PIX(&src, x, y) + TS_PIX(&src, x + 1, y));
            CHECK_NEAR(TS_PIX(&out, x, y), m, 1e-5 * fabs(m));
        }
        CHECK(isnan(TS_PIX(&out, 11, y))); /* past the last centre */
    }
    /* half a cell along both axes: mean of four; NaN spreads to the four
     * outputs whose support holds it */
    TS_PIX(&src, 6, 4) = NAN;
    CHECK(ts__tps_fit(ctx, 1, &px, &py, &qx, &ry, 0.0, &t) == TS_OK);
    CHECK(ts__tps_warp(ctx, &t, &src, 0.0, 0.0, &out) == TS_OK);
    for (y = 0; y < 9; y++)
        for (x = 0; x < 11; x++) {
            int touches = (x == 5 || x == 6) && (y == 3 || y == 4);
            if (touches) {
                CHECK(isnan(TS_PIX(&out, x, y)));
            } else {
                double m = 0.25 * ((double)TS_PIX(&src, x, y) + TS_PIX(&src, x + 1, y) +
                                   TS_PIX(&src, x, y + 1) + TS_PIX(&src, x + 1, y + 1));
                CHECK_NEAR(TS_PIX(&out, x, y), m, 1e-5 * fabs(m));
            }
        }
    /* a warp that lands left of the first centre */
    qx = -0.6;
    CHECK(ts__tps_fit(ctx, 1, &px, &py, &qx, &py, 0.0, &t) == TS_OK);
    CHECK(ts__tps_warp(ctx, &t, &src, 0.0, 0.0, &out) == TS_OK);
    CHECK(isnan(TS_PIX(&out, 0, 0)));
    CHECK(!isnan(TS_PIX(&out, 1, 0)));
    /* bad arguments */
    CHECK(ts__tps_warp(ctx, &t, &src, NAN, 0.0, &out) == TS_ERR_ARG);
    CHECK(ts__tps_warp(ctx, NULL, &src, 0.0, 0.0, &out) == TS_ERR_ARG);
    ts_raster_free(&out);
    ts_raster_free(&src);
    ts_ctx_free(ctx);
}

/* A curved warp: parallel (large output) equals the serial path, and the
 * warp agrees with direct bilinear sampling through ts__tps_map. */
static void test_warp_curved_parallel(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster src = make_src(ctx, 300, 260), big, small;
    double sx[5] = {20, 280, 280, 20, 150}, sy[5] = {20, 20, 240, 240, 130};
    double dx[5] = {25, 270, 285, 15, 160}, dy[5] = {18, 30, 235, 245, 120};
    ts_tps t;
    int x, y, bad = 0;
    ts_ctx_set_threads(ctx, 4);
    CHECK(ts__tps_fit(ctx, 5, sx, sy, dx, dy, 0.0, &t) == TS_OK);
    CHECK(t.bending > 0.0);
    CHECK(ts_raster_alloc(ctx, 300, 260, &big) == TS_OK);
    CHECK(ts_raster_alloc(ctx, 300, 20, &small) == TS_OK);
    CHECK(ts__tps_warp(ctx, &t, &src, 0.0, 0.0, &big) == TS_OK);
    CHECK(ts__tps_warp(ctx, &t, &src, 0.0, 100.0, &small) == TS_OK);
    for (y = 0; y < 20; y++)
        for (x = 0; x < 300; x++)
            bad += !same_cell(TS_PIX(&small, x, y), TS_PIX(&big, x, y + 100));
    CHECK_MSG(bad == 0, "%d cells differ", bad);
    for (y = 0; y < 260; y += 7)
        for (x = 0; x < 300; x += 5) {
            double px, py, fx, fy, tx, ty, v;
            int i0, j0;
            ts__tps_map(&t, x + 0.5, y + 0.5, &px, &py);
            fx = px - 0.5;
            fy = py - 0.5;
            if (fx < 0.0 || fy < 0.0 || fx >= 299.0 || fy >= 259.0) {
                CHECK(isnan(TS_PIX(&big, x, y)));
                continue;
            }
            i0 = (int)floor(fx);
            j0 = (int)floor(fy);
            tx = fx - i0;
            ty = fy - j0;
            v = (1 - tx) * (1 - ty) * TS_PIX(&src, i0, j0) +
                tx * (1 - ty) * TS_PIX(&src, i0 + 1, j0) +
                (1 - tx) * ty * TS_PIX(&src, i0, j0 + 1) + tx * ty * TS_PIX(&src, i0 + 1, j0 + 1);
            CHECK_NEAR(TS_PIX(&big, x, y), v, 1e-4);
        }
    ts_raster_free(&small);
    ts_raster_free(&big);
    ts_raster_free(&src);
    ts_ctx_free(ctx);
}

/* The analytic Jacobian against central differences of ts__tps_map. */
static void test_jacobian_finite_differences(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t rng = 23;
    int rep, k;
    for (rep = 0; rep < 30; rep++) {
        double sx[NMAX], sy[NMAX], dx[NMAX], dy[NMAX], j[4];
        int n = 3 + rep % 8;
        ts_tps t;
        random_config(&rng, n, 40.0, 2.0, 4.0, sx, sy, dx, dy);
        CHECK(ts__tps_fit(ctx, n, sx, sy, dx, dy, 0.0, &t) == TS_OK);
        for (k = 0; k < 20; k++) {
            double x = -5.0 + 50.0 * th_uniform(&rng), y = -5.0 + 50.0 * th_uniform(&rng);
            double h = 1e-5, ax, ay, bx, by, cx, cy, ex, ey;
            ts__tps_jacobian(&t, x, y, j);
            ts__tps_map(&t, x + h, y, &ax, &ay);
            ts__tps_map(&t, x - h, y, &bx, &by);
            ts__tps_map(&t, x, y + h, &cx, &cy);
            ts__tps_map(&t, x, y - h, &ex, &ey);
            CHECK_NEAR(j[0], (ax - bx) / (2 * h), 1e-5 * (1 + fabs(j[0])));
            CHECK_NEAR(j[2], (ay - by) / (2 * h), 1e-5 * (1 + fabs(j[2])));
            CHECK_NEAR(j[1], (cx - ex) / (2 * h), 1e-5 * (1 + fabs(j[1])));
            CHECK_NEAR(j[3], (cy - ey) / (2 * h), 1e-5 * (1 + fabs(j[3])));
        }
    }
    ts_ctx_free(ctx);
}

/* Folds: a rigid map and a mild bend do not fold; swapping two neighbouring
 * arms of a junction turns the map over between them; a mirror does not
 * fold; a uniform scale of 2 (area 4) is a stretch beyond 2.5; a map that
 * stretches one axis 3 times and squeezes the other 3 times keeps areas
 * but is refused. */
static void test_folds(void)
{
    ts_ctx *ctx = ts_ctx_new();
    /* a centre and four arms at radius 10 */
    double sx[5] = {0, 10, 0, -10, 0}, sy[5] = {0, 0, 10, 0, -10};
    double dx[5], dy[5];
    ts_tps t;
    int i;
    /* rotation by 30 degrees */
    for (i = 0; i < 5; i++) {
        double c = cos(0.5236), s = sin(0.5236);
        dx[i] = c * sx[i] - s * sy[i] + 3;
        dy[i] = s * sx[i] + c * sy[i] - 2;
    }
    CHECK(ts__tps_fit(ctx, 5, sx, sy, dx, dy, 0.0, &t) == TS_OK);
    CHECK(!ts__tps_folds(&t, 0, 0, 12, 13, 2.5));
    /* a mild bend of one arm */
    memcpy(dx, sx, sizeof dx);
    memcpy(dy, sy, sizeof dy);
    dy[1] = 2.0;
    CHECK(ts__tps_fit(ctx, 5, sx, sy, dx, dy, 0.0, &t) == TS_OK);
    CHECK(!ts__tps_folds(&t, 0, 0, 12, 13, 2.5));
    /* arms 1 and 2 swapped: the map turns over */
    memcpy(dx, sx, sizeof dx);
    memcpy(dy, sy, sizeof dy);
    dx[1] = 0;
    dy[1] = 10;
    dx[2] = 10;
    dy[2] = 0;
    CHECK(ts__tps_fit(ctx, 5, sx, sy, dx, dy, 0.0, &t) == TS_OK);
    CHECK(ts__tps_folds(&t, 0, 0, 12, 13, 2.5));
    /* a mirror (y flipped) is orientation-reversing everywhere: no fold */
    for (i = 0; i < 5; i++) {
        dx[i] = sx[i];
        dy[i] = -sy[i];
    }
    CHECK(ts__tps_fit(ctx, 5, sx, sy, dx, dy, 0.0, &t) == TS_OK);
    CHECK(!ts__tps_folds(&t, 0, 0, 12, 13, 2.5));
    /* uniform scale 2: areas times 4 */
    for (i = 0; i < 5; i++) {
        dx[i] = 2 * sx[i];
        dy[i] = 2 * sy[i];
    }
    CHECK(ts__tps_fit(ctx, 5, sx, sy, dx, dy, 0.0, &t) == TS_OK);
    CHECK(ts__tps_folds(&t, 0, 0, 12, 13, 2.5));
    CHECK(!ts__tps_folds(&t, 0, 0, 12, 13, 4.5));
    /* 3 times along x, a third along y: the same area, too anisotropic */
    for (i = 0; i < 5; i++) {
        dx[i] = 3 * sx[i];
        dy[i] = sy[i] / 3;
    }
    CHECK(ts__tps_fit(ctx, 5, sx, sy, dx, dy, 0.0, &t) == TS_OK);
    CHECK(ts__tps_folds(&t, 0, 0, 12, 13, 2.5));
    CHECK(!ts__tps_folds(&t, 0, 0, 12, 13, 9.5));
    /* a fold caught by orientation alone: x' = x - x^3 / r^2 turns over past |x| = r /
     * sqrt(3); the thin-plate spline through 15 of its points has at the samples -r, 0, r a
     * Jacobian near diag(-0.9, 1), diag(1, 1), diag(-0.9, 1): areas and stretches within
     * the limits, only the sign flipped at the sides */
    {
        double fx[15], fy[15], gx[15], gy[15], r = 10, j[4];
        int a, b, k = 0;
        for (b = -1; b <= 1; b++)
            for (a = -2; a <= 2; a++, k++) { /* at most TS_TPS_MAX (16) points */
                double x = r * a / 2.0, y = r * b;
                fx[k] = x;
                fy[k] = y;
                gx[k] = x - x * x * x / (r * r);
                gy[k] = y;
            }
        CHECK(ts__tps_fit(ctx, 15, fx, fy, gx, gy, 0.0, &t) == TS_OK);
        /* the limits alone would pass it: at the 3 x 3 samples |det| and the stretch are
         * near 1 */
        for (b = -1; b <= 1; b++)
            for (a = -1; a <= 1; a++) {
                double d, f2, disc;
                ts__tps_jacobian(&t, a * r, b * r, j);
                d = j[0] * j[3] - j[1] * j[2];
                f2 = 0.5 * (j[0] * j[0] + j[1] * j[1] + j[2] * j[2] + j[3] * j[3]);
                disc = sqrt(fmax(f2 * f2 - d * d, 0.0));
                CHECK_MSG(fabs(d) > 0.6 && fabs(d) < 1.6, "det %g at (%d, %d)", d, a, b);
                CHECK(sqrt(f2 + disc) <= 1.5 * sqrt(fmax(f2 - disc, 0.0)));
                CHECK(a == 0 ? d > 0 : d < 0);
            }
        CHECK(ts__tps_folds(&t, 0, 0, r, 3, 2.5));
    }
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"interpolates_control_points", test_interpolates_control_points},
        {"affine_reproduced", test_affine_reproduced},
        {"bending_rigid_invariance", test_bending_rigid_invariance},
        {"bending_scaling", test_bending_scaling},
        {"bending_monotone_in_displacement", test_bending_monotone_in_displacement},
        {"lambda_smooths", test_lambda_smooths},
        {"against_naive_solver", test_against_naive_solver},
        {"special_cases", test_special_cases},
        {"errors", test_errors},
        {"warp_identity", test_warp_identity},
        {"warp_integer_shift", test_warp_integer_shift},
        {"warp_half_cells_and_nodata", test_warp_half_cells_and_nodata},
        {"warp_curved_parallel", test_warp_curved_parallel},
        {"jacobian_finite_differences", test_jacobian_finite_differences},
        {"folds", test_folds},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
