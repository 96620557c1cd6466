/*
 * test_poisson_screened.c - the Poisson solves on a whole grid (two cosine
 * transforms) and screened (pulled towards the initial heights, by the
 * transforms and by MIC-PCG), against the dense oracle, against each other
 * and against their normal equations written out cell by cell.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "internal.h"
#include "poisson_oracle.h"
#include "terrasynth.h"

/* ---- a whole grid with no nodata (the cosine-transform path) ---- */

/* The worst residual of the screened normal equations over the unknowns
 * (mask set, u0 not NaN): per cell sum over its neighbours with a value of
 * (u_p - u_q) + s (u_p - u0_p) - b_p, b_p the guidance on those edges
 * (fixed cells enter as boundary values). */
static double screened_residual(int w, int h, const unsigned char *mask, const float *gx,
                                const float *gy, const float *u, const float *u0, double s)
{
    double worst = 0.0;
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            double lu = 0.0, b = 0.0;
            if (!mask[i] || isnan(u0[i]))
                continue;
            if (x > 0 && !isnan(u[i - 1])) {
                lu += (double)u[i] - u[i - 1];
                b += gx[i - 1];
            }
            if (x + 1 < w && !isnan(u[i + 1])) {
                lu += (double)u[i] - u[i + 1];
                b -= gx[i];
            }
            if (y > 0 && !isnan(u[i - (size_t)w])) {
                lu += (double)u[i] - u[i - (size_t)w];
                b += gy[i - (size_t)w];
            }
            if (y + 1 < h && !isnan(u[i + (size_t)w])) {
                lu += (double)u[i] - u[i + (size_t)w];
                b -= gy[i];
            }
            worst = fmax(worst, fabs(lu + s * ((double)u[i] - u0[i]) - b));
        }
    return worst;
}

/* ts__poisson_screened_whole, unscreened: against the dense oracle (small
 * grids, thin ones included) and against MIC-PCG to a tight tolerance (a
 * larger grid), the initial mean kept; screened: the normal equations
 * (L + s) u = b + s u0 checked cell by cell, and a change wider than
 * 1 / sqrt(s) damped. */
static void test_whole_grid_direct(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 31;
    static const int sizes[][2] = {{1, 1}, {1, 7}, {6, 1}, {2, 2}, {7, 5}, {12, 10}, {9, 16}};
    size_t k, c;
    double worst = 0.0;
    for (k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        int w = sizes[k][0], h = sizes[k][1];
        size_t n = (size_t)w * h;
        unsigned char *mask = malloc(n), *cls = malloc(n);
        float *gx = malloc(n * sizeof *gx), *gy = malloc(n * sizeof *gy),
              *u = malloc(n * sizeof *u);
        double *gr = malloc(n * sizeof *gr), *gd = malloc(n * sizeof *gd),
               *ref = malloc(n * sizeof *ref);
        double scale = 1.0, err = 0.0, m0 = 0.0, m1 = 0.0;
        for (c = 0; c < n; c++) {
            cls[c] = REF_UNKNOWN;
            mask[c] = 1;
            gx[c] = (float)(4.0 * th_uniform(&seed) - 2.0);
            gy[c] = (float)(4.0 * th_uniform(&seed) - 2.0);
            u[c] = (float)(300.0 + 80.0 * th_uniform(&seed));
            gr[c] = gx[c];
            gd[c] = gy[c];
            ref[c] = u[c];
            m0 += u[c];
        }
        CHECK(ref_solve(w, h, cls, gr, gd, ref));
        CHECK_MSG(ts__poisson_screened_whole(ctx, w, h, gx, gy, u, 0.0) == TS_OK, "%s",
                  ts_ctx_message(ctx));
        for (c = 0; c < n; c++) {
            scale = fmax(scale, fabs(ref[c]));
            err = fmax(err, fabs(u[c] - ref[c]));
            m1 += u[c];
        }
        CHECK_MSG(err <= 1e-5 * scale, "%dx%d: max error %g", w, h, err);
        CHECK_NEAR(m1 / n, m0 / n, 1e-4);
        worst = fmax(worst, err / scale);
        free(mask);
        free(cls);
        free(gx);
        free(gy);
        free(u);
        free(gr);
        free(gd);
        free(ref);
    }
    { /* 301 x 203 against the iterative solver of ts_poisson_solve */
        int w = 301, h = 203;
        size_t n = (size_t)w * h;
        unsigned char *mask = malloc(n);
        float *gx = malloc(n * sizeof *gx), *gy = malloc(n * sizeof *gy);
        float *u = malloc(n * sizeof *u), *v = malloc(n * sizeof *v);
        double err = 0.0;
        for (c = 0; c < n; c++) {
            int x = (int)(c % (size_t)w), y = (int)(c / (size_t)w);
            mask[c] = 1;
            gx[c] = (float)(0.5 * sin(0.05 * x + 0.02 * y) + th_uniform(&seed) - 0.5);
            gy[c] = (float)(0.3 * cos(0.03 * y) + th_uniform(&seed) - 0.5);
            u[c] = v[c] = (float)(1000.0 + 10.0 * th_uniform(&seed));
        }
        CHECK(ts__poisson_screened_whole(ctx, w, h, gx, gy, u, 0.0) == TS_OK);
        CHECK_MSG(ts_poisson_solve(ctx, w, h, mask, gx, gy, v, 1e-11, 20000) == TS_OK, "%s",
                  ts_ctx_message(ctx));
        for (c = 0; c < n; c++)
            err = fmax(err, fabs((double)u[c] - v[c]));
        CHECK_MSG(err <= 2e-3, "301x203: max difference %g m", err);
        printf("     whole grid, direct: worst relative error %.2e; 301 x 203 against MIC-PCG "
               "%.2e\n",
               worst, err);
        /* screened, s = 1 / 20^2: per cell (L + s) u - s u0 = b (from the
         * float heights: to float rounding), and a tilt of the whole grid
         * asked by the guidance mostly refused */
        {
            double s = 1.0 / 400.0, worst_r = 0.0, tilt0, tilt1;
            float *u0 = malloc(n * sizeof *u0);
            int y;
            memcpy(u0, u, n * sizeof *u);
            for (c = 0; c < n; c++)
                gx[c] += 0.5f; /* every step east 0.5 higher */
            CHECK(ts__poisson_screened_whole(ctx, w, h, gx, gy, u, s) == TS_OK);
            worst_r = screened_residual(w, h, mask, gx, gy, u, u0, s);
            tilt0 = tilt1 = 0.0;
            for (y = 0; y < h; y++) {
                tilt0 += (double)u0[(size_t)y * w + w - 1] - u0[(size_t)y * w];
                tilt1 += (double)u[(size_t)y * w + w - 1] - u[(size_t)y * w];
            }
            tilt0 /= h;
            tilt1 /= h;
            printf("     screened 1/20^2: worst residual %.2e; east-west rise %.1f -> %.1f "
                   "(an exact fit: %.1f more)\n",
                   worst_r, tilt0, tilt1, 0.5 * (w - 1));
            CHECK_MSG(worst_r < 2e-3, "residual %g", worst_r);
            /* 150 asked across the grid; within 20 cells of the edges only */
            CHECK(tilt1 - tilt0 > 5.0 && tilt1 - tilt0 < 0.25 * 0.5 * (w - 1));
            free(u0);
        }
        /* guidance that is not finite is refused, u unchanged */
        gx[5 * w + 7] = NAN;
        memcpy(v, u, n * sizeof *u);
        CHECK(ts__poisson_screened_whole(ctx, w, h, gx, gy, u, 0.0) == TS_ERR_ARG);
        CHECK(memcmp(u, v, n * sizeof *u) == 0);
        CHECK(ts__poisson_screened_whole(ctx, w, h, gx, gy, u, -1.0) == TS_ERR_ARG);
        free(mask);
        free(gx);
        free(gy);
        free(u);
        free(v);
    }
    ts_ctx_free(ctx);
}

/* ts__poisson_solve_valid screened: on a whole grid the same u as the
 * cosine-transform solve; with NaN cells and fixed cells the screened
 * normal equations hold on every unknown (its edges to used cells only,
 * fixed cells as boundary values). */
static void test_screened_cg(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t seed = 41;
    int w = 97, h = 83, x, y, round;
    size_t n = (size_t)w * h, c;
    unsigned char *mask = malloc(n);
    float *gx = malloc(n * sizeof *gx), *gy = malloc(n * sizeof *gy);
    float *u = malloc(n * sizeof *u), *v = malloc(n * sizeof *v), *u0 = malloc(n * sizeof *u0);
    double s = 1.0 / 144.0;
    for (round = 0; round < 2; round++) {
        double err = 0.0, worst_r = 0.0;
        for (c = 0; c < n; c++) {
            x = (int)(c % (size_t)w);
            y = (int)(c / (size_t)w);
            mask[c] = 1;
            gx[c] = (float)(0.4 * sin(0.07 * y) + th_uniform(&seed) - 0.5 + 0.3);
            gy[c] = (float)(0.3 * cos(0.05 * x) + th_uniform(&seed) - 0.5);
            u[c] = v[c] = u0[c] = (float)(500.0 + 20.0 * th_uniform(&seed));
            if (round == 1 && ((x - 30) * (x - 30) + (y - 40) * (y - 40) < 60 || x == w - 1))
                u[c] = v[c] = u0[c] = NAN; /* nodata: a hole and the last column */
            if (round == 1 && x > 60 && x < 70 && y > 10 && y < 20)
                mask[c] = 0; /* fixed */
        }
        CHECK_MSG(ts__poisson_solve_valid(ctx, w, h, mask, gx, gy, u, 1e-10, 5000, s) == TS_OK,
                  "%s", ts_ctx_message(ctx));
        if (round == 0) {
            CHECK(ts__poisson_screened_whole(ctx, w, h, gx, gy, v, s) == TS_OK);
            for (c = 0; c < n; c++)
                err = fmax(err, fabs((double)u[c] - v[c]));
            CHECK_MSG(err < 1e-3, "whole grid: CG against the transform %g", err);
        }
        for (c = 0; c < n; c++)
            if (round == 1 && (!mask[c] || isnan(u0[c])))
                CHECK(isnan(u0[c]) ? isnan(u[c]) : u[c] == u0[c]);
        worst_r = screened_residual(w, h, mask, gx, gy, u, u0, s);
        printf("     screened CG, %s: worst residual %.2e%s\n",
               round ? "holes and fixed cells" : "whole grid", worst_r,
               round ? "" : " (against the transform below)");
        if (round == 0)
            printf("     whole grid: CG against the transform %.2e\n", err);
        CHECK_MSG(worst_r < 2e-3, "residual %g", worst_r);
    }
    free(mask);
    free(gx);
    free(gy);
    free(u);
    free(v);
    free(u0);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"whole_grid_direct", test_whole_grid_direct},
        {"screened_cg", test_screened_cg},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
