/*
 * test_basin_lift.c - the basins a breach leaves wider than it reaches,
 * lifted and breached again (ts_drainage_params.basin_block): the lift
 * against a slow, obviously-correct oracle (the blocks' minima found cell by
 * cell, filled by relaxation with a grade, after Planchon and Darboux 2001:
 * each block not draining out is lowered to its minimum where that stands
 * above its lowest neighbour's level, else to that level + grade, until
 * nothing changes; the depth at each block's centre taken bilinearly and
 * smoothed by a box of f + 1 cells along rows and columns), and the whole
 * stage against a fill by relaxation of the result: a bowl far wider than
 * the radius, which the breach alone keeps, drains.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "internal.h"
#include "terrasynth.h"

#include "fill_oracle.h"

/* A bowl of the given radius and depth in a surface tilted a little, with
 * bumps and noise: a wide basin full of small pits. */
static void bowl_surface(float *z, int w, int h, double radius, double depth, uint64_t seed)
{
    int x, y;
    double cx = 0.45 * w, cy = 0.55 * h;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double d = sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy)) / radius;
            double v = 0.05 * x + (d < 1 ? -depth * (1 - d * d) : 0.0);
            v += 2.0 * sin(0.37 * x) * cos(0.29 * y) + 1.5 * th_uniform(&seed);
            z[(size_t)y * (size_t)w + (size_t)x] = (float)v;
        }
}

/* The oracle's lift of z (no nodata; the cells flagged fixed kept, their blocks draining
 * out, a block of fixed cells alone at no height) with blocks of f and the grade, keep of
 * each block's depth left: into out. */
static void oracle_lift(const float *z, const unsigned char *fl, int w, int h, int f, double grade,
                        double keep, double *out)
{
    int cw = (w + f - 1) / f, ch = (h + f - 1) / f, x, y, i, j, d, changed;
    double *m = malloc((size_t)cw * ch * sizeof *m), *lev = malloc((size_t)cw * ch * sizeof *lev);
    unsigned char *out_blk = calloc((size_t)cw * ch, 1);
    double *bil = malloc((size_t)w * h * sizeof *bil);
    for (j = 0; j < ch; j++)
        for (i = 0; i < cw; i++) {
            double lo = INFINITY;
            int drains = i == 0 || j == 0 || i == cw - 1 || j == ch - 1;
            for (y = j * f; y < (j + 1) * f && y < h; y++)
                for (x = i * f; x < (i + 1) * f && x < w; x++) {
                    if (fl && (fl[(size_t)y * w + x] & TS_CELL_FIXED))
                        drains = 1;
                    else if (z[(size_t)y * w + x] < lo)
                        lo = z[(size_t)y * w + x];
                }
            m[(size_t)j * cw + i] = lo;
            out_blk[(size_t)j * cw + i] = (unsigned char)drains;
            /* a block of fixed cells alone lets the land beside it drain into it */
            lev[(size_t)j * cw + i] = !drains ? INFINITY : lo == INFINITY ? -INFINITY : lo;
        }
    do {
        changed = 0;
        for (j = 0; j < ch; j++)
            for (i = 0; i < cw; i++) {
                double lo = INFINITY, nv;
                if (out_blk[(size_t)j * cw + i])
                    continue;
                for (d = 0; d < 9; d++) {
                    int a = i + d % 3 - 1, b = j + d / 3 - 1;
                    if (d != 4 && a >= 0 && b >= 0 && a < cw && b < ch &&
                        lev[(size_t)b * cw + a] < lo)
                        lo = lev[(size_t)b * cw + a];
                }
                nv = m[(size_t)j * cw + i] > lo ? m[(size_t)j * cw + i] : lo + grade;
                if (nv < lev[(size_t)j * cw + i]) {
                    lev[(size_t)j * cw + i] = nv;
                    changed = 1;
                }
            }
    } while (changed);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            /* the cell's centre among the blocks' centres, (i + 1/2) f - 1/2 */
            double u = (x + 0.5) / f - 0.5, v = (y + 0.5) / f - 0.5, r = 0;
            u = u < 0 ? 0 : u > cw - 1 ? cw - 1 : u;
            v = v < 0 ? 0 : v > ch - 1 ? ch - 1 : v;
            for (j = 0; j < ch; j++)
                for (i = 0; i < cw; i++) {
                    double wt = (fabs(u - i) < 1 ? 1 - fabs(u - i) : 0) *
                                (fabs(v - j) < 1 ? 1 - fabs(v - j) : 0);
                    if (wt > 0 && m[(size_t)j * cw + i] < INFINITY &&
                        lev[(size_t)j * cw + i] - m[(size_t)j * cw + i] > keep)
                        r += wt * (lev[(size_t)j * cw + i] - m[(size_t)j * cw + i] - keep);
                }
            bil[(size_t)y * w + x] = r;
        }
    /* smoothed: the mean over the cells within f / 2 along the row of the means within f / 2
     * along the column (each window cut at the grid's edge) */
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t k = (size_t)y * w + x;
            double sum = 0;
            int rows = 0, a, b;
            for (b = y - f / 2; b <= y + f / 2; b++) {
                double rs = 0;
                int cols = 0;
                if (b < 0 || b >= h)
                    continue;
                for (a = x - f / 2; a <= x + f / 2; a++)
                    if (a >= 0 && a < w) {
                        rs += bil[(size_t)b * w + a];
                        cols++;
                    }
                sum += rs / cols;
                rows++;
            }
            out[k] =
                fl && (fl[k] & TS_CELL_FIXED) ? z[k] : z[k] + (sum / rows > 0 ? sum / rows : 0);
        }
    free(bil);
    free(m);
    free(lev);
    free(out_blk);
}

/* The lift against the oracle: the bowl alone, with a fixed patch (a lake) inside it, and with
 * the lake and part of each block's depth kept. */
static void test_lift_against_oracle(void)
{
    const int w = 150, h = 131, f = 6;
    size_t n = (size_t)w * h, i, lifted = 0, worst_at = 0;
    unsigned char *up = malloc(n);
    float *z = malloc(n * sizeof *z), *z0 = malloc(n * sizeof *z0);
    double *want = malloc(n * sizeof *want), worst;
    unsigned char *fl = calloc(n, 1);
    ts_raster r = ts_raster_wrap(z, w, h, w);
    int pass;
    bowl_surface(z0, w, h, 50, 40, 3);
    for (pass = 0; pass < 3; pass++) {
        double keep = pass == 2 ? 7.5 : 0.0; /* the third: 7.5 of each block's depth kept */
        if (pass == 1) /* a lake at the bowl's bottom: its blocks drain, the land round it kept */
            for (i = 0; i < n; i++)
                if (hypot((double)(i % w) - 0.45 * w, (double)(i / w) - 0.55 * h) < 8)
                    fl[i] = TS_CELL_FIXED | TS_CELL_WATER;
        memcpy(z, z0, n * sizeof *z);
        memset(up, 0, n);
        CHECK(ts__lift_basins(&r, fl, f, 0.5, keep, up) == 0);
        for (lifted = 0, i = 0; i < n; i++)
            lifted += up[i] && z[i] > z0[i];
        oracle_lift(z0, fl, w, h, f, 0.5, keep, want);
        worst = 0;
        for (i = 0; i < n; i++) {
            CHECK(z[i] >= z0[i]);
            if (fabs(z[i] - want[i]) > worst) {
                worst = fabs(z[i] - want[i]);
                worst_at = i;
            }
            if (fl[i])
                CHECK(z[i] == z0[i]);
        }
        CHECK_MSG(worst < 1e-3, "pass %d: cell %zu lifted to %.4f, the oracle's %.4f", pass,
                  worst_at, z[worst_at], want[worst_at]);
        if (!pass)
            CHECK_MSG(lifted > n / 8, "%zu cells lifted: the bowl is not lifted", lifted);
    }
    /* land falling faster than the grade a block everywhere: nothing lifted */
    for (i = 0; i < n; i++)
        z[i] = z0[i] = (float)(3.0 * (double)(i % w) + 2.0 * (double)(i / w));
    memset(up, 0, n);
    CHECK(ts__lift_basins(&r, NULL, f, 0.5, 0.0, up) == 0);
    for (lifted = 0, i = 0; i < n; i++)
        lifted += up[i];
    CHECK_MSG(lifted == 0 && memcmp(z, z0, n * sizeof *z) == 0, "%zu cells lifted on a slope",
              lifted);
    free(z);
    free(z0);
    free(want);
    free(fl);
    free(up);
}

/* A bowl 4 times wider than the radius: the breach keeps it, the stage with basins lifted
 * drains it (the fill by relaxation finds no cell it raises by more than 0.05), the same
 * bytes on 1 and 3 threads, and only on the whole grid. */
static void test_wide_bowl_drains(void)
{
    const int w = 240, h = 200;
    size_t n = (size_t)w * h, left;
    float *z0 = malloc(n * sizeof *z0), *z = malloc(n * sizeof *z), *z3 = malloc(n * sizeof *z3);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_params p = ts_drainage_params_default();
    ts_raster r = ts_raster_wrap(z, w, h, w), r3 = ts_raster_wrap(z3, w, h, w);
    ts_drainage_info info;
    double worst;
    bowl_surface(z0, w, h, 80, 60, 7);
    p.mode = TS_DRAINAGE_BREACH;
    p.radius = 24;
    p.bank_slope = 1.0;
    p.max_depth = -1;
    memcpy(z, z0, n * sizeof *z);
    CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, &info) == TS_OK);
    worst = deepest(z, w, h, 0.05, &left);
    CHECK_MSG(left > n / 20,
              "the breach alone drained the bowl (%zu cells left, %.1f deep): "
              "the case tests nothing",
              left, worst);
    p.basin_block = 4;
    p.basin_grade = 1.0;
    memcpy(z, z0, n * sizeof *z);
    memcpy(z3, z0, n * sizeof *z3);
    ts_ctx_set_threads(ctx, 1);
    CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, &info) == TS_OK);
    ts_ctx_set_threads(ctx, 3);
    CHECK(ts_drainage_apply(ctx, &r3, NULL, 0, 0, w, h, &p, NULL) == TS_OK);
    CHECK(memcmp(z, z3, n * sizeof *z) == 0);
    worst = deepest(z, w, h, 0.05, &left);
    CHECK_MSG(left == 0, "%zu cells left in pits, %.2f deep", left, worst);
    CHECK_MSG(info.cells_lifted > n / 8 && info.cells_changed >= info.cells_lifted,
              "%zu cells lifted, %zu changed", info.cells_lifted, info.cells_changed);
    r = ts_raster_wrap(z + w, w, h - 1, w);
    CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 1, w, h, &p, NULL) == TS_ERR_ARG);
    p.basin_grade = -1;
    r = ts_raster_wrap(z, w, h, w);
    CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, NULL) == TS_ERR_ARG);
    ts_ctx_free(ctx);
    free(z0);
    free(z);
    free(z3);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"lift_against_oracle", test_lift_against_oracle},
        {"wide_bowl_drains", test_wide_bowl_drains},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
