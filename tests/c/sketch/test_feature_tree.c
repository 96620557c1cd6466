/*
 * test_feature_tree.c - the feature tree of sketch-guided synthesis
 * (algorithms/src/sketch/feature_tree.c): on a hand-made Y (a branch point with
 * three chains, two of them stored from their far end), the sites come
 * breadth first from the branch point, every chain's path sites laid
 * outward from it (distance from the branch point increasing), the control
 * points on the circle, the branch's arms sorted by angle; raster order
 * sorts by row then column.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "feature_tree.h"
#include "harness.h"
#include "tps.h"

/* Chain from (x0, y0) to (x1, y1) (both included, 4-step straight lines). */
static size_t add_chain(ts_feature_vertex *v, size_t at, int x0, int y0, int x1, int y1)
{
    int n = abs(x1 - x0) > abs(y1 - y0) ? abs(x1 - x0) : abs(y1 - y0), i;
    for (i = 0; i <= n; i++) {
        v[at + (size_t)i].x = x0 + (x1 - x0) * i / n;
        v[at + (size_t)i].y = y0 + (y1 - y0) * i / n;
        v[at + (size_t)i].z = 0.0f;
    }
    return (size_t)n + 1;
}

static void test_tree_order(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_feature_vertex verts[400];
    ts_feature_node nodes[4] = {{60, 60, 0, 3, TS_RIDGE},
                                {60, 0, 0, 1, TS_RIDGE},
                                {119, 60, 0, 1, TS_RIDGE},
                                {0, 60, 0, 1, TS_RIDGE}};
    ts_feature_path paths[3];
    ts_features f;
    ts_feature_site *sites = NULL;
    size_t n_sites = 0, at = 0, i;
    int saw_branch = 0;
    memset(&f, 0, sizeof f);
    memset(paths, 0, sizeof paths);
    /* chain 0 stored from the far end (node_a = endpoint, node_b = branch) */
    paths[0].kind = TS_RIDGE;
    paths[0].node_a = 1;
    paths[0].node_b = 0;
    paths[0].first = at;
    paths[0].count = add_chain(verts, at, 60, 0, 60, 60);
    at += paths[0].count;
    /* chain 1 stored from the branch */
    paths[1].kind = TS_RIDGE;
    paths[1].node_a = 0;
    paths[1].node_b = 2;
    paths[1].first = at;
    paths[1].count = add_chain(verts, at, 60, 60, 119, 60);
    at += paths[1].count;
    /* chain 2 from the far end again */
    paths[2].kind = TS_RIDGE;
    paths[2].node_a = 3;
    paths[2].node_b = 0;
    paths[2].first = at;
    paths[2].count = add_chain(verts, at, 0, 60, 60, 60);
    at += paths[2].count;
    f.width = f.height = 120;
    f.nodes = nodes;
    f.n_nodes = 4;
    f.paths = paths;
    f.n_paths = 3;
    f.verts = verts;
    f.n_verts = at;
    CHECK(ts__feature_sites(ctx, &f, TS_RIDGE, 10.0, 8.0, 1, &sites, &n_sites) == TS_OK);
    CHECK(n_sites > 6);
    if (getenv("TS_TEST_VERBOSE"))
        for (i = 0; i < n_sites; i++)
            fprintf(stderr, "site %zu type %d path %ld at %g,%g\n", i, sites[i].type, sites[i].path,
                    sites[i].cx, sites[i].cy);
    /* the root first: the branch point, arms on the circle, by angle */
    CHECK(sites[0].type == TS_SITE_BRANCH && sites[0].cx == 60 && sites[0].cy == 60);
    CHECK(sites[0].n_ctrl == 4);
    for (i = 1; i < 4; i++) {
        CHECK_NEAR(hypot(sites[0].px[i], sites[0].py[i]), 10.0, 0.5);
        if (i > 1)
            CHECK(atan2(sites[0].py[i], sites[0].px[i]) > atan2(sites[0].py[i - 1], sites[0].px[i - 1]));
    }
    /* each chain's path sites come in a run, moving away from the branch */
    {
        long prev_path = -1;
        double prev_d = -1.0;
        for (i = 1; i < n_sites; i++) {
            const ts_feature_site *s = &sites[i];
            double d = hypot(s->cx - 60, s->cy - 60);
            if (s->type == TS_SITE_BRANCH)
                saw_branch = 1;
            if (s->type != TS_SITE_PATH)
                continue;
            if (s->path == prev_path)
                CHECK_MSG(d > prev_d, "chain %ld: site at %g after %g", s->path, d, prev_d);
            else
                CHECK_MSG(d < 25.0, "chain %ld starts %g from the branch", s->path, d);
            prev_path = s->path;
            prev_d = d;
            CHECK(s->n_ctrl == 3);
            CHECK_NEAR(hypot(s->px[1], s->py[1]), 10.0, 1.0);
            CHECK_NEAR(hypot(s->px[2], s->py[2]), 10.0, 1.0);
        }
    }
    CHECK(!saw_branch);
    free(sites);
    /* raster order: by row, then column */
    CHECK(ts__feature_sites(ctx, &f, TS_RIDGE, 10.0, 8.0, 0, &sites, &n_sites) == TS_OK);
    for (i = 1; i < n_sites; i++)
        CHECK(sites[i].cy > sites[i - 1].cy ||
              (sites[i].cy == sites[i - 1].cy && sites[i].cx >= sites[i - 1].cx));
    free(sites);
    ts_ctx_free(ctx);
}

/* Alignments: every (rot, mirror) maps the arms one to one; and the
 * geometry: an exemplar junction that is the sketch's rotated (its arms
 * listed by angle from another start) or mirrored is recovered with zero
 * bending by exactly the alignment that undoes it, against a
 * thin-plate-spline fit made here. */
static void test_junction_alignments(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t rng = 31;
    int arms, rot, mirror, i, rep;
    for (arms = 3; arms <= 6; arms++)
        for (rot = 0; rot < arms; rot++)
            for (mirror = 0; mirror < 2; mirror++) {
                int hit[8] = {0};
                CHECK(ts__feature_arm(arms, 0, rot, mirror) == 0);
                for (i = 1; i <= arms; i++) {
                    int j = ts__feature_arm(arms, i, rot, mirror);
                    CHECK(j >= 1 && j <= arms);
                    if (j >= 1 && j <= arms)
                        hit[j]++;
                }
                for (i = 1; i <= arms; i++)
                    CHECK(hit[i] == 1);
            }
    for (rep = 0; rep < 40; rep++) {
        /* a sketch junction: arms at sorted random angles on a circle of 10 */
        int n = 3 + rep % 4, shift = (int)(th_uniform(&rng) * n) % n, flip = rep % 2;
        double ang[8], sx[8], sy[8], ex[8], ey[8], base = 6.28 * th_uniform(&rng);
        double best = INFINITY;
        int best_rot = -1, best_mirror = -1;
        for (i = 0; i < n; i++)
            ang[i] = 6.283185307 * (i + 0.4 * th_uniform(&rng)) / n;
        sx[0] = sy[0] = 0.0;
        for (i = 0; i < n; i++) {
            sx[i + 1] = 10 * cos(ang[i]);
            sy[i + 1] = 10 * sin(ang[i]);
        }
        /* the exemplar: the same junction turned by `base`, its arms listed
         * from arm `shift` on (sorted by angle as feature_tree does), and
         * mirrored (y flipped, arms then listed the other way) when flip */
        ex[0] = ey[0] = 0.0;
        for (i = 0; i < n; i++) {
            int src = flip ? (shift - i + n) % n : (shift + i) % n;
            double a = ang[src] + base, x = 10 * cos(a), y = 10 * sin(a);
            ex[i + 1] = x;
            ey[i + 1] = flip ? -y : y;
        }
        for (mirror = 0; mirror < 2; mirror++)
            for (rot = 0; rot < n; rot++) {
                double ax[9], ay[9];
                ts_tps t;
                for (i = 0; i <= n; i++) {
                    int j = ts__feature_arm(n, i, rot, mirror);
                    ax[i] = ex[j];
                    ay[i] = mirror ? -ey[j] : ey[j];
                }
                if (ts__tps_fit(ctx, n + 1, ax, ay, sx, sy, 0.0, &t) != TS_OK)
                    continue;
                if (t.bending < best) {
                    best = t.bending;
                    best_rot = rot;
                    best_mirror = mirror;
                }
            }
        CHECK_MSG(best < 1e-9, "rep %d: best bending %g", rep, best);
        CHECK(best_mirror == flip);
        CHECK(best_rot >= 0);
    }
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"tree_order", test_tree_order},
        {"junction_alignments", test_junction_alignments},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
