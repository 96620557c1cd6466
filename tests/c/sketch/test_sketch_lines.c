/*
 * test_sketch_lines.c - a sketch drawn as lines made into a feature graph
 * (algorithms/src/sketch/sketch_lines.c), against plain oracles: the cells
 * of a line against a dense sampling of it (every path cell is one the
 * line passes through, every cell it passes through is next to a path
 * cell, the chain is 8-connected); junctions counted by hand for a T (with
 * and without snapping), an X, lines of two kinds crossing (no junction), a
 * ring, a line leaving the grid, a lollipop; heights interpolated linearly.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "internal.h"

#define W 120
#define H 100

static ts_features *graph(const ts_sketch_line *l, size_t n, double snap)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_features *f = NULL;
    CHECK(ts_features_from_lines(ctx, W, H, l, n, snap, &f) == TS_OK);
    ts_ctx_free(ctx);
    return f;
}

static int degree_count(const ts_features *f, int degree)
{
    size_t i;
    int c = 0;
    for (i = 0; i < f->n_nodes; i++)
        c += f->nodes[i].degree == degree;
    return c;
}

/* Every path: consecutive vertices 8-adjacent, ends on its nodes' cells,
 * mask bits on every vertex, degrees = path ends at the node. */
static void check_graph(const ts_features *f)
{
    size_t k, j, i;
    for (k = 0; k < f->n_paths; k++) {
        const ts_feature_path *p = &f->paths[k];
        const ts_feature_vertex *a = &f->verts[p->first], *b = &f->verts[p->first + p->count - 1];
        CHECK(p->count >= 2);
        CHECK(a->x == f->nodes[p->node_a].x && a->y == f->nodes[p->node_a].y);
        CHECK(b->x == f->nodes[p->node_b].x && b->y == f->nodes[p->node_b].y);
        for (j = 0; j < p->count; j++) {
            const ts_feature_vertex *v = &f->verts[p->first + j];
            CHECK(f->mask[(size_t)v->y * W + (size_t)v->x] & p->kind);
            if (j)
                CHECK(abs(v->x - v[-1].x) <= 1 && abs(v->y - v[-1].y) <= 1 &&
                      (v->x != v[-1].x || v->y != v[-1].y));
        }
    }
    for (i = 0; i < f->n_nodes; i++) {
        int ends = 0;
        for (k = 0; k < f->n_paths; k++)
            ends += (f->paths[k].node_a == i) + (f->paths[k].node_b == i);
        CHECK_MSG(ends == f->nodes[i].degree, "node %zu: %d ends, degree %d", i, ends,
                  f->nodes[i].degree);
        CHECK(f->nodes[i].degree == 1 || f->nodes[i].degree >= 3);
    }
}

static void test_cells_of_a_line(void)
{
    double x[3] = {3.3, 61.7, 110.2}, y[3] = {7.9, 52.4, 91.6};
    ts_sketch_line l = {TS_VALLEY, 3, x, y, NULL};
    ts_features *f = graph(&l, 1, 2.0);
    unsigned char dense[W * H];
    size_t k, c, n_path = 0;
    int kx, ky;
    memset(dense, 0, sizeof dense);
    /* the oracle: the line sampled every 0.001 cells */
    for (k = 0; k + 1 < 3; k++) {
        double len = hypot(x[k + 1] - x[k], y[k + 1] - y[k]);
        long s, steps = (long)(len / 0.001);
        for (s = 0; s <= steps; s++) {
            double t = (double)s / (double)steps;
            int cx = (int)floor(x[k] + t * (x[k + 1] - x[k]));
            int cy = (int)floor(y[k] + t * (y[k + 1] - y[k]));
            dense[cy * W + cx] = 1;
        }
    }
    CHECK(f->n_paths == 1 && f->n_nodes == 2);
    CHECK(degree_count(f, 1) == 2);
    check_graph(f);
    for (c = 0; c < (size_t)W * H; c++) {
        if (f->mask[c]) {
            n_path++;
            CHECK_MSG(dense[c], "cell %zu on the path, not on the line", c);
        }
        if (dense[c]) {
            int near = 0;
            for (ky = -1; ky <= 1; ky++)
                for (kx = -1; kx <= 1; kx++) {
                    long nx = (long)(c % W) + kx, ny = (long)(c / W) + ky;
                    if (nx >= 0 && ny >= 0 && nx < W && ny < H && f->mask[ny * W + nx])
                        near = 1;
                }
            CHECK_MSG(near, "cell %zu on the line, no path cell next to it", c);
        }
    }
    CHECK(f->verts[f->paths[0].first].x == 3 && f->verts[f->paths[0].first].y == 7);
    CHECK(f->mask[91 * W + 110] == TS_VALLEY);
    CHECK(n_path == f->paths[0].count);
    ts_features_free(f);
}

static void test_t_junction_snaps(void)
{
    double ax[2] = {10.5, 100.5}, ay[2] = {50.5, 50.5};
    double bx[2] = {55.5, 55.5}, by[2] = {10.5, 49.3}; /* ends 1.2 cells short */
    ts_sketch_line l[2] = {{TS_VALLEY, 2, ax, ay, NULL}, {TS_VALLEY, 2, bx, by, NULL}};
    ts_features *f = graph(l, 2, 2.0), *g;
    CHECK(f->n_paths == 3);
    CHECK(degree_count(f, 3) == 1 && degree_count(f, 1) == 3);
    check_graph(f);
    {
        size_t i;
        for (i = 0; i < f->n_nodes; i++)
            if (f->nodes[i].degree == 3)
                CHECK(f->nodes[i].x == 55 && f->nodes[i].y == 50);
    }
    /* no snapping: two separate lines */
    g = graph(l, 2, 0.0);
    CHECK(g->n_paths == 2 && degree_count(g, 1) == 4);
    check_graph(g);
    ts_features_free(f);
    ts_features_free(g);
}

static void test_crossings(void)
{
    double ax[2] = {10.2, 100.7}, ay[2] = {12.3, 88.1};
    double bx[2] = {95.1, 15.4}, by[2] = {9.7, 90.2};
    ts_sketch_line same[2] = {{TS_RIDGE, 2, ax, ay, NULL}, {TS_RIDGE, 2, bx, by, NULL}};
    ts_sketch_line kinds[2] = {{TS_RIDGE, 2, ax, ay, NULL}, {TS_VALLEY, 2, bx, by, NULL}};
    ts_features *f = graph(same, 2, 1.0), *g = graph(kinds, 2, 1.0);
    /* an X: one node of degree 4, four arms */
    CHECK(f->n_paths == 4 && degree_count(f, 4) == 1 && degree_count(f, 1) == 4);
    check_graph(f);
    /* a ridge across a valley: no junction, both lines whole */
    CHECK(g->n_paths == 2 && degree_count(g, 1) == 4);
    check_graph(g);
    {
        size_t c, both = 0;
        for (c = 0; c < (size_t)W * H; c++)
            both += g->mask[c] == (TS_RIDGE | TS_VALLEY);
        CHECK(both >= 1);
    }
    ts_features_free(f);
    ts_features_free(g);
    {
        /* diagonals through cell centres: walked alone they pass each other
         * corner to corner without a common cell; the crossing point joins them */
        double cx[2] = {0.5, 99.5}, cy[2] = {0.5, 99.5}, dx[2] = {0.5, 99.5}, dy[2] = {99.5, 0.5};
        ts_sketch_line d[2] = {{TS_VALLEY, 2, cx, cy, NULL}, {TS_VALLEY, 2, dx, dy, NULL}};
        ts_features *h = graph(d, 2, 0.0);
        CHECK(h->n_paths == 4 && degree_count(h, 4) == 1);
        check_graph(h);
        ts_features_free(h);
    }
}

static void test_ring_and_edge(void)
{
    double rx[41], ry[41], ex[2] = {60.5, 60.5}, ey[2] = {40.5, -30.0};
    ts_sketch_line ring = {TS_RIDGE, 41, rx, ry, NULL}, edge = {TS_VALLEY, 2, ex, ey, NULL};
    ts_features *f, *g;
    int i;
    for (i = 0; i <= 40; i++) {
        rx[i] = 60.0 + 30.0 * cos(6.283185307179586 * i / 40.0);
        ry[i] = 50.0 + 30.0 * sin(6.283185307179586 * i / 40.0);
    }
    f = graph(&ring, 1, 1.0);
    CHECK(f->n_paths == 1 && f->n_nodes == 2 && degree_count(f, 1) == 2);
    check_graph(f);
    /* the two ends of the opened ring are neighbours */
    CHECK(abs(f->nodes[0].x - f->nodes[1].x) <= 1 && abs(f->nodes[0].y - f->nodes[1].y) <= 1);
    g = graph(&edge, 1, 1.0);
    CHECK(g->n_paths == 1 && degree_count(g, 1) == 2);
    check_graph(g);
    CHECK(g->verts[g->paths[0].first].y == 40 || g->verts[g->paths[0].first].y == 0);
    {
        size_t k;
        int top = 0;
        for (k = 0; k < g->n_nodes; k++)
            top |= g->nodes[k].y == 0;
        CHECK(top); /* the line leaves the grid at its top edge */
    }
    ts_features_free(f);
    ts_features_free(g);
}

static void test_lollipop(void)
{
    /* a stem, then a loop that comes back to the stem's end */
    double x[6] = {60.5, 60.5, 80.5, 80.5, 40.5, 40.5};
    double y[6] = {95.5, 60.5, 60.5, 20.5, 20.5, 60.5};
    double x2[2] = {40.5, 60.5}, y2[2] = {60.5, 60.5};
    ts_sketch_line l[2] = {{TS_RIDGE, 6, x, y, NULL}, {TS_RIDGE, 2, x2, y2, NULL}};
    ts_features *f = graph(l, 2, 1.0);
    CHECK(degree_count(f, 3) == 1 && degree_count(f, 1) == 1);
    CHECK(f->n_paths == 2);
    check_graph(f);
    ts_features_free(f);
}

static void test_heights_along(void)
{
    double x[2] = {10.5, 90.5}, y[2] = {30.5, 30.5}, z[2] = {100.0, 900.0};
    ts_sketch_line l = {TS_RIDGE, 2, x, y, z};
    ts_features *f = graph(&l, 1, 1.0);
    size_t j;
    CHECK(f->n_paths == 1);
    for (j = 0; j < f->paths[0].count; j++) {
        const ts_feature_vertex *v = &f->verts[f->paths[0].first + j];
        /* linear along the line: z at the cell where the walk first met it */
        double t_lo = (v->x - 10.5) / 80.0, t_hi = (v->x + 1 - 10.5) / 80.0;
        double lo = 100.0 + 800.0 * fmax(0.0, t_lo), hi = 100.0 + 800.0 * fmin(1.0, t_hi);
        CHECK_MSG(v->z >= lo - 1e-3 && v->z <= hi + 1e-3, "x %d: z %g not in %g..%g", v->x,
                  v->z, lo, hi);
    }
    CHECK_NEAR(f->paths[0].zmin, 100.0, 1e-3);
    ts_features_free(f);
}

static void test_bad_arguments(void)
{
    ts_ctx *ctx = ts_ctx_new();
    double x[2] = {1, 5}, y[2] = {1, 5};
    ts_sketch_line l = {7, 2, x, y, NULL};
    ts_features *f = NULL;
    CHECK(ts_features_from_lines(ctx, W, H, &l, 1, 1.0, &f) == TS_ERR_ARG && !f);
    l.kind = TS_RIDGE;
    CHECK(ts_features_from_lines(ctx, 0, H, &l, 1, 1.0, &f) == TS_ERR_ARG && !f);
    CHECK(ts_features_from_lines(ctx, W, H, &l, 1, -1.0, &f) == TS_ERR_ARG && !f);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"cells_of_a_line", test_cells_of_a_line}, {"t_junction_snaps", test_t_junction_snaps},
        {"crossings", test_crossings},             {"ring_and_edge", test_ring_and_edge},
        {"lollipop", test_lollipop},               {"heights_along", test_heights_along},
        {"bad_arguments", test_bad_arguments},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
