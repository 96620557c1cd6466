/*
 * test_ppa_edges.c - the PPA's rules at their edges, by hand-made cases whose
 * answer is known: branch reduction keeps a branch or an isolated path exactly
 * as long as the minimum and removes one a little shorter (the rule is
 * "shorter than the minimum"); target connection makes no diagonal with one
 * nodata flank, whichever flank it is.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "ppa_internal.h"
#include "terrasynth.h"

enum { W = 64, H = 48 };

/* Join (x, y) and its neighbour in direction d (ppa_dir order). */
static void link(unsigned char *adj, int x, int y, int d)
{
    int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
    adj[y * W + x] |= (unsigned char)(1u << d);
    adj[ny * W + nx] |= (unsigned char)(1u << ((d + 4) & 7));
}

static int cells(const unsigned char *adj)
{
    int i, n = 0;
    for (i = 0; i < W * H; i++)
        n += adj[i] != 0;
    return n;
}

/* An isolated straight path of `steps` steps (steps + 1 cells). */
static void test_isolated_path(void)
{
    ts_ctx *ctx = ts_ctx_new();
    unsigned char adj[W * H];
    int steps, x;
    for (steps = 3; steps <= 20; steps += 17) {
        double mins[3] = {steps - 0.5, steps, steps + 0.01};
        int k;
        for (k = 0; k < 3; k++) {
            memset(adj, 0, sizeof adj);
            for (x = 5; x < 5 + steps; x++)
                link(adj, x, 10, 0); /* east */
            CHECK(ppa_branch_reduction(ctx, W, H, adj, NULL, mins[k]) == TS_OK);
            CHECK_MSG(cells(adj) == (k < 2 ? steps + 1 : 0),
                      "path of %d steps, minimum %g: %d cells left", steps, mins[k], cells(adj));
        }
    }
    ts_ctx_free(ctx);
}

/* A long axis with a side branch of `steps` steps down from its middle. */
static void test_side_branch(void)
{
    ts_ctx *ctx = ts_ctx_new();
    unsigned char adj[W * H];
    int steps = 10, x, y, k;
    double mins[3] = {steps - 0.5, steps, steps + 0.01};
    for (k = 0; k < 3; k++) {
        memset(adj, 0, sizeof adj);
        for (x = 5; x < 55; x++)
            link(adj, x, 20, 0); /* the axis: 50 steps east */
        for (y = 20; y < 20 + steps; y++)
            link(adj, 30, y, 2); /* the branch: south */
        CHECK(ppa_branch_reduction(ctx, W, H, adj, NULL, mins[k]) == TS_OK);
        CHECK_MSG(cells(adj) == 51 + (k < 2 ? steps : 0),
                  "branch of %d steps, minimum %g: %d cells left", steps, mins[k], cells(adj));
        /* the axis stays whole either way */
        for (x = 5; x <= 55; x++)
            CHECK(adj[20 * W + x] != 0);
    }
    ts_ctx_free(ctx);
}

/* Two targets on a diagonal of a 2 x 2 block, one flank nodata, the other a plain cell:
 * no segment between them (a feature never bridges a hole), for either diagonal and
 * either flank. */
static void test_diagonal_with_one_nodata_flank(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int diag, hole;
    for (diag = 0; diag < 2; diag++)
        for (hole = 0; hole < 2; hole++) {
            /* diag 0: targets (0,0) and (1,1), flanks (1,0) and (0,1);
             * diag 1: targets (1,0) and (0,1), flanks (0,0) and (1,1) */
            float v[4] = {5, 6, 7, 8};
            unsigned char t[4] = {0, 0, 0, 0};
            int ta = diag ? 1 : 0, tb = diag ? 2 : 3, fa = diag ? 0 : 1, fb = diag ? 3 : 2;
            ts_raster dem = ts_raster_wrap(v, 2, 2, 2);
            ts_ppa_segment *segs = NULL;
            size_t n = 0, i;
            t[ta] = t[tb] = TS_RIDGE;
            v[hole ? fb : fa] = NAN;
            CHECK(ts_ppa_target_connection(ctx, &dem, t, TS_RIDGE, &segs, &n) == TS_OK);
            for (i = 0; i < n; i++)
                CHECK_MSG(!((segs[i].a == (uint32_t)ta && segs[i].b == (uint32_t)tb) ||
                            (segs[i].a == (uint32_t)tb && segs[i].b == (uint32_t)ta)),
                          "diagonal %d bridges the hole at cell %d", diag, hole ? fb : fa);
            /* with no hole the diagonal is made */
            free(segs);
            v[hole ? fb : fa] = 6.5f;
            CHECK(ts_ppa_target_connection(ctx, &dem, t, TS_RIDGE, &segs, &n) == TS_OK);
            CHECK(n == 1);
            free(segs);
        }
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"isolated_path", test_isolated_path},
        {"side_branch", test_side_branch},
        {"diagonal_with_one_nodata_flank", test_diagonal_with_one_nodata_flank},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
