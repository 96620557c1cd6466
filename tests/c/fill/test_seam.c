/*
 * test_seam.c - the graph-cut seam finder against a brute-force search
 * over all labellings of tiny windows, and on windows with an obvious
 * optimal seam (a ramp of mismatch, a diagonal band of agreement, two
 * disjoint overlaps); errors; timing on typical window sizes.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <time.h>

#include "harness.h"
#include "terrasynth.h"

/* ---- the oracle: the cost rule of ts_seam_graphcut, written plainly ---- */

static int both_nan(float a, float b)
{
    return isnan(a) && isnan(b);
}

/* M of the pair (p, q): |a-b| summed over the cells where both exist;
 * doubled when only one cell of the pair has both; 0 when none has. */
static double oracle_weight(const float *a, const float *b, int p, int q)
{
    int dp = !isnan(a[p]) && !isnan(b[p]), dq = !isnan(a[q]) && !isnan(b[q]);
    double mp = dp ? fabs((double)a[p] - b[p]) : 0.0, mq = dq ? fabs((double)a[q] - b[q]) : 0.0;
    if (dp && dq)
        return mp + mq;
    return 2.0 * (mp + mq);
}

static double oracle_cost(int w, int h, const float *a, const float *b,
                          const unsigned char *labels)
{
    double c = 0.0;
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            int p = y * w + x;
            if (both_nan(a[p], b[p]))
                continue;
            if (x + 1 < w && !both_nan(a[p + 1], b[p + 1]) && labels[p] != labels[p + 1])
                c += oracle_weight(a, b, p, p + 1);
            if (y + 1 < h && !both_nan(a[p + w], b[p + w]) && labels[p] != labels[p + w])
                c += oracle_weight(a, b, p, p + w);
        }
    return c;
}

/* Label a cell must take, or -1 when free. */
static int oracle_forced(float a, float b, unsigned char c)
{
    if (isnan(a) && isnan(b))
        return 0;
    if (isnan(a))
        return 1;
    if (isnan(b))
        return 0;
    if (c == TS_SEAM_OLD)
        return 0;
    if (c == TS_SEAM_NEW)
        return 1;
    return -1;
}

/* Minimum cost over all labellings consistent with the forced cells. */
static double oracle_min(int w, int h, const float *a, const float *b, const unsigned char *con)
{
    int n = w * h, free_cells[32], n_free = 0, i;
    unsigned char labels[64];
    unsigned long m;
    double best = INFINITY;
    for (i = 0; i < n; i++) {
        int f = oracle_forced(a[i], b[i], con ? con[i] : 0);
        labels[i] = (unsigned char)(f < 0 ? 0 : f);
        if (f < 0)
            free_cells[n_free++] = i;
    }
    for (m = 0; m < (1ul << n_free); m++) {
        double c;
        for (i = 0; i < n_free; i++)
            labels[free_cells[i]] = (unsigned char)((m >> i) & 1u);
        c = oracle_cost(w, h, a, b, labels);
        if (c < best)
            best = c;
    }
    return best;
}

static int close_rel(double x, double y)
{
    return fabs(x - y) <= 1e-9 * fmax(1.0, fmax(fabs(x), fabs(y)));
}

static double rand_value(uint64_t *rng, int quantised)
{
    double v = 10.0 * th_uniform(rng);
    return quantised ? floor(v * 2.0) / 2.0 : v;
}

/* ---- (a) brute force on tiny windows ---- */

static void test_brute_force(void)
{
    static const int sizes[][2] = {{3, 4}, {4, 3}, {4, 4}, {2, 6}, {5, 3}, {1, 7}};
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed;
    int checked = 0;
    for (seed = 1; seed <= 600; seed++) {
        uint64_t rng = seed * 6364136223846793005ull + 1442695040888963407ull;
        int w = sizes[seed % 6][0], h = sizes[seed % 6][1], n = w * h, i, n_free = 0;
        int quantised = (int)(seed % 2), stride = w + (int)(seed % 3);
        float a_buf[64], b_buf[64], a[16], b[16];
        unsigned char con[16], labels[16];
        double p_nan_old = 0.4 * th_uniform(&rng), p_nan_new = 0.3 * th_uniform(&rng);
        double p_con = 0.3 * th_uniform(&rng), cost = -1, best;
        ts_raster old, patch;
        for (i = 0; i < n; i++) {
            a[i] = (float)rand_value(&rng, quantised);
            /* patches are usually close to old: small mismatches, some equal */
            b[i] = th_uniform(&rng) < 0.2 ? a[i] : (float)(a[i] + rand_value(&rng, quantised) - 5.0);
            if (th_uniform(&rng) < p_nan_old)
                a[i] = NAN;
            if (th_uniform(&rng) < p_nan_new)
                b[i] = NAN;
            con[i] = TS_SEAM_FREE;
            if (!isnan(a[i]) && !isnan(b[i]) && th_uniform(&rng) < p_con)
                con[i] = (th_rand(&rng) & 1) ? TS_SEAM_OLD : TS_SEAM_NEW;
            n_free += oracle_forced(a[i], b[i], con[i]) < 0;
        }
        if (n_free > 14)
            continue;
        /* the window as views with a stride */
        for (i = 0; i < n; i++) {
            a_buf[(i / w) * stride + i % w] = a[i];
            b_buf[(i / w) * stride + i % w] = b[i];
        }
        old = ts_raster_wrap(a_buf, w, h, stride);
        patch = ts_raster_wrap(b_buf, w, h, stride);
        memset(labels, 0xaa, sizeof labels);
        CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_OK);
        best = oracle_min(w, h, a, b, con);
        CHECK_MSG(close_rel(cost, best), "seed %llu: cost %.17g, brute-force minimum %.17g",
                  (unsigned long long)seed, cost, best);
        CHECK_MSG(close_rel(oracle_cost(w, h, a, b, labels), best),
                  "seed %llu: labels cost %.17g, minimum %.17g", (unsigned long long)seed,
                  oracle_cost(w, h, a, b, labels), best);
        for (i = 0; i < n; i++) {
            int f = oracle_forced(a[i], b[i], con[i]);
            CHECK(labels[i] <= 1);
            if (f >= 0)
                CHECK_MSG(labels[i] == f, "seed %llu cell %d: label %d, forced %d",
                          (unsigned long long)seed, i, labels[i], f);
        }
        checked++;
    }
    CHECK(checked > 400);
    ts_ctx_free(ctx);
}

/* ---- (b) obvious seams ---- */

/* Old covers columns 0..14, the patch columns 4..w-1: the overlap is
 * columns 4..14, with mismatch |x - 9.3| in every row.  Each row must be
 * cut once between column 3 (old only) and 15 (patch only); the cheapest
 * cut is between 9 and 10 (0.3 + 0.7), and no vertical pair is cut. */
static void test_ramp_seam(void)
{
    enum { W = 19, H = 7 };
    ts_ctx *ctx = ts_ctx_new();
    float a[W * H], b[W * H];
    unsigned char labels[W * H];
    ts_raster old = ts_raster_wrap(a, W, H, W), patch = ts_raster_wrap(b, W, H, W);
    double cost = -1;
    int x, y;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            float base = (float)(100.0 + 3.0 * x - 2.0 * y);
            a[y * W + x] = x <= 14 ? base : NAN;
            b[y * W + x] = x >= 4 ? (float)(base + ((x + y) % 2 ? 1 : -1) * fabs(x - 9.3)) : NAN;
        }
    CHECK(ts_seam_graphcut(ctx, &old, &patch, NULL, labels, &cost) == TS_OK);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            CHECK_MSG(labels[y * W + x] == (x >= 10), "cell (%d, %d): label %d", x, y,
                      labels[y * W + x]);
    CHECK_NEAR(cost, H * 1.0, 1e-4);
    ts_ctx_free(ctx);
}

/* Old and patch over the whole window, equal only on a diagonal band two
 * cells wide (x - y in {K, K+1}); the left column is forced old and the
 * right column new.  The only zero-cost seam runs inside the band. */
static void test_diagonal_band(void)
{
    enum { W = 16, H = 10, K = 4 };
    ts_ctx *ctx = ts_ctx_new();
    float a[W * H], b[W * H];
    unsigned char labels[W * H], con[W * H];
    ts_raster old = ts_raster_wrap(a, W, H, W), patch = ts_raster_wrap(b, W, H, W);
    double cost = -1;
    int x, y;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int d = x - y, p = y * W + x;
            a[p] = (float)(50.0 + 0.5 * x * y);
            b[p] = (d == K || d == K + 1) ? a[p] : a[p] + 1.0f + 0.1f * (float)((x * 7 + y) % 5);
            con[p] = x == 0 ? TS_SEAM_OLD : x == W - 1 ? TS_SEAM_NEW : TS_SEAM_FREE;
        }
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_OK);
    CHECK_NEAR(cost, 0.0, 0);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            CHECK_MSG(labels[y * W + x] == (x - y > K), "cell (%d, %d): label %d", x, y,
                      labels[y * W + x]);
    ts_ctx_free(ctx);
}

/* ---- (c) two disjoint overlaps ---- */

/* Old exists on columns 0..4 and 11..15 (two earlier patches), the patch
 * everywhere; columns 0 and 15 are forced old.  Per row, the mismatch
 * profile puts the cheapest cut between columns 1|2 (0.2 + 0.1) on the
 * left and 13|14 (0.1 + 0.2) on the right. */
static void test_disjoint_overlap(void)
{
    enum { W = 16, H = 6 };
    static const double d_left[5] = {5, 0.2, 0.1, 3, 4};
    static const double d_right[5] = {4, 3, 0.1, 0.2, 5};
    ts_ctx *ctx = ts_ctx_new();
    float a[W * H], b[W * H];
    unsigned char labels[W * H], con[W * H];
    ts_raster old = ts_raster_wrap(a, W, H, W), patch = ts_raster_wrap(b, W, H, W);
    double cost = -1;
    int x, y;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int p = y * W + x;
            b[p] = (float)(20.0 + x + 0.25 * y);
            a[p] = x <= 4 ? b[p] + (float)d_left[x] : x >= 11 ? b[p] - (float)d_right[x - 11] : NAN;
            con[p] = (x == 0 || x == W - 1) ? TS_SEAM_OLD : TS_SEAM_FREE;
        }
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_OK);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            CHECK_MSG(labels[y * W + x] == (x >= 2 && x <= 13), "cell (%d, %d): label %d", x, y,
                      labels[y * W + x]);
    CHECK_NEAR(cost, H * 0.6, 1e-4);
    ts_ctx_free(ctx);
}

/* ---- (d) errors ---- */

static void test_errors(void)
{
    ts_ctx *ctx = ts_ctx_new();
    float a[12], b[12];
    unsigned char con[12], labels[12];
    ts_raster old = ts_raster_wrap(a, 4, 3, 4), patch = ts_raster_wrap(b, 4, 3, 4), small;
    double cost;
    int i;
    for (i = 0; i < 12; i++) {
        a[i] = (float)i;
        b[i] = (float)(2 * i);
        con[i] = TS_SEAM_FREE;
    }
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_OK);
    CHECK(strcmp(ts_ctx_message(ctx), "") == 0);
    /* forced to the patch where the patch is nodata */
    b[5] = NAN;
    con[5] = TS_SEAM_NEW;
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "seam graph cut") != NULL);
    CHECK(strstr(ts_ctx_message(ctx), "(1, 1)") != NULL);
    CHECK(strstr(ts_ctx_message(ctx), "patch is nodata") != NULL);
    /* forced to keep old where old is nodata */
    b[5] = 1.0f;
    con[5] = TS_SEAM_FREE;
    a[7] = NAN;
    con[7] = TS_SEAM_OLD;
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "old is nodata") != NULL);
    /* an empty cell cannot be forced either way */
    b[7] = NAN;
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_ERR_ARG);
    con[7] = TS_SEAM_FREE;
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_OK);
    CHECK(labels[7] == 0);
    /* unknown constraint value */
    con[2] = 3;
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "constraint 3") != NULL);
    con[2] = TS_SEAM_FREE;
    /* sizes, missing arguments, infinities */
    small = ts_raster_wrap(b, 3, 3, 4);
    CHECK(ts_seam_graphcut(ctx, &old, &small, con, labels, &cost) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "4 x 3") != NULL);
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, NULL, &cost) == TS_ERR_ARG);
    CHECK(ts_seam_graphcut(ctx, NULL, &patch, con, labels, &cost) == TS_ERR_ARG);
    small = ts_raster_wrap(b, 0, 3, 4);
    old.width = 0;
    CHECK(ts_seam_graphcut(ctx, &old, &small, con, labels, &cost) == TS_ERR_SIZE);
    old.width = 4;
    a[0] = INFINITY;
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_ERR_ARG);
    a[0] = 0.0f;
    /* ts__clear: a good call after a failed one has an empty message */
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, NULL) == TS_OK);
    CHECK(ts_ctx_status(ctx) == TS_OK && strcmp(ts_ctx_message(ctx), "") == 0);
    ts_ctx_free(ctx);
}

/* ---- (e) no mismatch, no cost ---- */

static void test_zero_cost(void)
{
    enum { W = 23, H = 17 };
    ts_ctx *ctx = ts_ctx_new();
    float a[W * H], b[W * H];
    unsigned char labels[W * H], con[W * H];
    ts_raster old = ts_raster_wrap(a, W, H, W), patch = ts_raster_wrap(b, W, H, W);
    uint64_t rng = 5;
    int seed, i;
    for (seed = 0; seed < 20; seed++) {
        double cost = -1;
        for (i = 0; i < W * H; i++) {
            a[i] = b[i] = (float)(1000.0 * th_uniform(&rng));
            if (th_uniform(&rng) < 0.3)
                a[i] = NAN;
            else if (th_uniform(&rng) < 0.3)
                b[i] = NAN;
            con[i] = TS_SEAM_FREE;
            if (!isnan(a[i]) && !isnan(b[i]) && th_uniform(&rng) < 0.2)
                con[i] = (th_rand(&rng) & 1) ? TS_SEAM_OLD : TS_SEAM_NEW;
        }
        CHECK(ts_seam_graphcut(ctx, &old, &patch, seed % 2 ? con : NULL, labels, &cost) == TS_OK);
        CHECK_NEAR(cost, 0.0, 0);
    }
    ts_ctx_free(ctx);
}

/* A NULL constraint equals an all-free one; the result is reproducible. */
static void test_null_constraint_and_determinism(void)
{
    enum { W = 40, H = 30 };
    ts_ctx *ctx = ts_ctx_new();
    float a[W * H], b[W * H];
    unsigned char l1[W * H], l2[W * H], con[W * H];
    ts_raster old = ts_raster_wrap(a, W, H, W), patch = ts_raster_wrap(b, W, H, W);
    uint64_t rng = 11;
    double c1 = -1, c2 = -2;
    int i;
    for (i = 0; i < W * H; i++) {
        int x = i % W;
        a[i] = x < 25 ? (float)(10.0 * th_uniform(&rng)) : NAN;
        b[i] = x >= 10 ? (float)(10.0 * th_uniform(&rng)) : NAN;
        con[i] = TS_SEAM_FREE;
    }
    CHECK(ts_seam_graphcut(ctx, &old, &patch, NULL, l1, &c1) == TS_OK);
    CHECK(ts_seam_graphcut(ctx, &old, &patch, con, l2, &c2) == TS_OK);
    CHECK(c1 == c2 && memcmp(l1, l2, sizeof l1) == 0);
    ts_ctx_free(ctx);
}

/* ---- timing on typical windows ---- */

static double now_seconds(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* An n x n window in raster-scan placement: old covers the top `band`
 * rows and the left `band` columns (an L-shaped overlap), the patch is
 * complete; both are rough terrain-like fields that differ.  The outer
 * rim of the overlap (row 0, column 0) abuts older output: forced old. */
static void time_window(int n, int band, int reps)
{
    ts_ctx *ctx = ts_ctx_new();
    size_t cells = (size_t)n * (size_t)n;
    float *a = malloc(cells * sizeof *a), *b = malloc(cells * sizeof *b);
    unsigned char *labels = malloc(cells), *con = malloc(cells);
    ts_raster old = ts_raster_wrap(a, n, n, n), patch = ts_raster_wrap(b, n, n, n);
    uint64_t rng = 3;
    double cost = -1, t0, t1;
    int x, y, r, forced_ok = 1;
    for (y = 0; y < n; y++)
        for (x = 0; x < n; x++) {
            double za = 40.0 * sin(0.07 * x) * cos(0.05 * y) + 5.0 * th_uniform(&rng);
            double zb = 40.0 * sin(0.07 * x + 0.4) * cos(0.05 * y - 0.3) + 5.0 * th_uniform(&rng);
            a[(size_t)y * n + x] = (x < band || y < band) ? (float)za : NAN;
            b[(size_t)y * n + x] = (float)zb;
            con[(size_t)y * n + x] = (x == 0 || y == 0) ? TS_SEAM_OLD : TS_SEAM_FREE;
        }
    t0 = now_seconds();
    for (r = 0; r < reps; r++)
        CHECK(ts_seam_graphcut(ctx, &old, &patch, con, labels, &cost) == TS_OK);
    t1 = now_seconds();
    for (y = 0; y < n; y++)
        for (x = 0; x < n; x++)
            if ((x >= band && y >= band && labels[(size_t)y * n + x] != 1) ||
                ((x == 0 || y == 0) && labels[(size_t)y * n + x] != 0))
                forced_ok = 0;
    CHECK(forced_ok);
    CHECK(cost > 0);
    printf("     %dx%d window, %d-cell overlap band: %.3f ms per seam (cost %.1f)\n", n, n, band,
           1e3 * (t1 - t0) / reps, cost);
    free(a);
    free(b);
    free(labels);
    free(con);
    ts_ctx_free(ctx);
}

static void test_timing(void)
{
    time_window(128, 40, 20);
    time_window(512, 170, 1);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"brute_force", test_brute_force},
        {"ramp_seam", test_ramp_seam},
        {"diagonal_band", test_diagonal_band},
        {"disjoint_overlap", test_disjoint_overlap},
        {"errors", test_errors},
        {"zero_cost", test_zero_cost},
        {"null_constraint_and_determinism", test_null_constraint_and_determinism},
        {"timing", test_timing},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
