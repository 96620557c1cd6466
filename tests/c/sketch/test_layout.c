/*
 * test_layout.c - the layout stage of sketch-guided synthesis
 * (algorithms/src/sketch/layout.c) and what it stands on: the nearest feature cell
 * of the distance transform against brute force, valley floors made to
 * descend on a branching network, a valley's way out along the lowest way
 * (brute force), and the corrections themselves: a flat
 * land takes the sketch's ridge, fixed cells never change, strength 0
 * changes nothing, valley floors descend cell by cell, and a steep valley
 * stroke's staircase leaves no stripes across the valley.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <limits.h>

#include "harness.h"
#include "layout.h"
#include "relief_guide.h"
#include "terrasynth.h"

/* ---- the nearest feature cell == brute force ---- */
static void test_nearest_brute_force(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t s = 17;
    int rep;
    for (rep = 0; rep < 30; rep++) {
        int w = 1 + (int)(th_uniform(&s) * 60), h = 1 + (int)(th_uniform(&s) * 45), i, bad = 0;
        double density = rep == 0 ? 0.0 : th_uniform(&s) * 0.08;
        unsigned char *m = malloc((size_t)w * h);
        float *d = malloc((size_t)w * h * sizeof(float));
        int32_t *nr = malloc((size_t)w * h * sizeof(int32_t));
        for (i = 0; i < w * h; i++)
            m[i] = th_uniform(&s) < density;
        ts_ctx_set_threads(ctx, 1 + rep % 3);
        CHECK(ts__distance_transform_nearest(ctx, m, w, h, d, nr) == TS_OK);
        for (i = 0; i < w * h && !bad; i++) {
            int x = i % w, y = i / w, u, v;
            double best = INFINITY;
            for (v = 0; v < h; v++)
                for (u = 0; u < w; u++)
                    if (m[v * w + u])
                        best = fmin(best, hypot(u - x, v - y));
            if (isinf(best)) {
                CHECK(nr[i] == -1);
                bad |= nr[i] != -1;
                continue;
            }
            /* a feature cell, at the brute-force distance */
            if (!(nr[i] >= 0 && nr[i] < w * h && m[nr[i]] &&
                  fabs(hypot(nr[i] % w - x, nr[i] / w - y) - best) <= 1e-9 &&
                  fabs(d[i] - best) <= 1e-4 * (1 + best))) {
                CHECK_MSG(0, "rep %d cell (%d, %d): nearest %d, distance %g, brute force %g", rep,
                          x, y, nr[i], d[i], best);
                bad = 1;
            }
        }
        free(m);
        free(d);
        free(nr);
    }
    ts_ctx_free(ctx);
}

/* ---- a network of valleys made to descend ---- */

/* A trunk along row 20 from x = 0 (the outlet, on the edge) through a
 * junction at x = 40 to x = 60, and a tributary down column 40 from y = 2;
 * paths stored in both directions; bumpy levels on their cells. */
typedef struct y_net {
    ts_feature_vertex v[200];
    ts_feature_node nodes[4];
    ts_feature_path paths[3];
    ts_features f;
} y_net;

static void y_network(y_net *g, int W, int H, float *level, uint64_t *s)
{
    size_t at = 0;
    int i;
    memset(g, 0, sizeof *g);
    for (i = 0; i < W * H; i++)
        level[i] = NAN;
    g->nodes[0] = (ts_feature_node){0, 20, 0, 1, TS_VALLEY};  /* outlet */
    g->nodes[1] = (ts_feature_node){40, 20, 0, 3, TS_VALLEY}; /* junction */
    g->nodes[2] = (ts_feature_node){60, 20, 0, 1, TS_VALLEY};
    g->nodes[3] = (ts_feature_node){40, 2, 0, 1, TS_VALLEY};
    /* trunk below the junction, stored from the junction down to the outlet */
    g->paths[0] = (ts_feature_path){TS_VALLEY, 1, 0, at, 41, 0, 0, 0, 0};
    for (i = 40; i >= 0; i--)
        g->v[at++] = (ts_feature_vertex){i, 20, 0};
    /* trunk above, from the junction up */
    g->paths[1] = (ts_feature_path){TS_VALLEY, 1, 2, at, 21, 0, 0, 0, 0};
    for (i = 40; i <= 60; i++)
        g->v[at++] = (ts_feature_vertex){i, 20, 0};
    /* tributary, from its source down to the junction */
    g->paths[2] = (ts_feature_path){TS_VALLEY, 3, 1, at, 19, 0, 0, 0, 0};
    for (i = 2; i <= 20; i++)
        g->v[at++] = (ts_feature_vertex){40, i, 0};
    for (i = 0; i <= 60; i++)
        level[20 * W + i] = (float)(100.0 + 2.0 * i + 30.0 * th_uniform(s));
    for (i = 2; i < 20; i++)
        level[i * W + 40] = (float)(250.0 + 3.0 * (20 - i) + 40.0 * th_uniform(s));
    g->f.width = W;
    g->f.height = H;
    g->f.nodes = g->nodes;
    g->f.n_nodes = 4;
    g->f.paths = g->paths;
    g->f.n_paths = 3;
    g->f.verts = g->v;
    g->f.n_verts = at;
}

static void test_descend(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 70, H = 30, x, y, rep;
    float *level = malloc((size_t)W * H * sizeof(float));
    float *orig = malloc((size_t)W * H * sizeof(float));
    ts_layout_spec sp;
    y_net *g = malloc(sizeof *g);
    uint64_t s = 9;
    memset(&sp, 0, sizeof sp);
    sp.kind = TS_VALLEY;
    sp.width = W;
    sp.height = H;
    for (rep = 0; rep < 10; rep++) {
        y_network(g, W, H, level, &s);
        sp.features = &g->f;
        memcpy(orig, level, (size_t)W * H * sizeof(float));
        CHECK(ts__valley_descend(ctx, &sp, level) == TS_OK);
        /* downstream (towards x = 0 on the trunk, towards row 20 on the
         * tributary, then the trunk) never climbs */
        for (x = 1; x <= 60; x++)
            CHECK_MSG(level[20 * W + x - 1] <= level[20 * W + x], "trunk %d: %g > %g", x,
                      level[20 * W + x - 1], level[20 * W + x]);
        for (y = 3; y <= 20; y++)
            CHECK_MSG(level[y * W + 40] <= level[(y - 1) * W + 40], "tributary %d", y);
        /* between the lowest and the highest of the old levels; other
         * cells untouched */
        for (x = 0; x < W * H; x++)
            if (!isnan(orig[x])) {
                CHECK(level[x] >= 99.0f && level[x] <= 400.0f);
            } else {
                CHECK(isnan(level[x]));
            }
    }
    /* levels that already descend stay as they are */
    y_network(g, W, H, level, &s);
    for (x = 0; x <= 60; x++)
        level[20 * W + x] = (float)(100 + x);
    for (y = 2; y < 20; y++)
        level[y * W + 40] = (float)(140 + 20 - y);
    memcpy(orig, level, (size_t)W * H * sizeof(float));
    CHECK(ts__valley_descend(ctx, &sp, level) == TS_OK);
    for (x = 0; x < W * H; x++)
        if (!isnan(orig[x]))
            CHECK(level[x] == orig[x]);
    /* no graph: nothing changes */
    sp.features = NULL;
    CHECK(ts__valley_descend(ctx, &sp, level) == TS_OK);
    free(g);
    free(level);
    free(orig);
    ts_ctx_free(ctx);
}

/* ---- drawn valleys that drain ---- */

/* The slow oracle: a cell drains when it is on the grid's edge or has a
 * neighbour no higher that drains (relaxed until nothing changes). */
static void drains_naive(const float *z, int W, int H, unsigned char *dr)
{
    int x, y, dx, dy, changed = 1;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            dr[y * W + x] = x == 0 || y == 0 || x == W - 1 || y == H - 1;
    while (changed) {
        changed = 0;
        for (y = 1; y < H - 1; y++)
            for (x = 1; x < W - 1; x++) {
                if (dr[y * W + x])
                    continue;
                for (dy = -1; dy <= 1 && !dr[y * W + x]; dy++)
                    for (dx = -1; dx <= 1; dx++)
                        if ((dx || dy) && dr[(y + dy) * W + x + dx] &&
                            z[(y + dy) * W + x + dx] <= z[y * W + x]) {
                            dr[y * W + x] = 1;
                            changed = 1;
                            break;
                        }
            }
    }
}

/* The highest level among the floor cells nearest cell c (brute force). */
static float nearest_floor_level(const unsigned char *fo, const float *z, int W, int H, int c)
{
    long best = LONG_MAX;
    float lvl = -INFINITY;
    int i;
    for (i = 0; i < W * H; i++)
        if (fo[i]) {
            long dx = i % W - c % W, dy = i / W - c / W, d = dx * dx + dy * dy;
            if (d < best || (d == best && z[i] > lvl)) {
                lvl = d < best ? z[i] : fmaxf(lvl, z[i]);
                best = d;
            }
        }
    return lvl;
}

/* Whether a vertex of f lies within r cells (Chebyshev) of (x, y). */
static int near_cell(const ts_features *f, int x, int y, int r)
{
    size_t k;
    for (k = 0; k < f->n_verts; k++)
        if (abs(f->verts[k].x - x) <= r && abs(f->verts[k].y - y) <= r)
            return 1;
    return 0;
}

static void test_valley_breach(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 70, H = 30, x, rep;
    float *z = malloc((size_t)W * H * sizeof(float)), *z0 = malloc((size_t)W * H * sizeof(float));
    float *level = malloc((size_t)W * H * sizeof(float));
    unsigned char *dr = malloc((size_t)W * H), *fl = calloc((size_t)W * H, 1);
    unsigned char *fo = malloc((size_t)W * H);
    y_net *g = malloc(sizeof *g);
    uint64_t s = 21;
    int cut;
    for (rep = 0; rep < 8; rep++) {
        ts_raster r = ts_raster_wrap(z, W, H, W);
        size_t k;
        int bad = 0;
        y_network(g, W, H, level, &s);
        /* a bumpy land with pits, higher towards the east, and a wall
         * across the trunk near its outlet (the tributary's source at
         * (40, 2) is 2 cells from the edge) */
        for (x = 0; x < W * H; x++)
            z[x] = (float)(200.0 + 2.0 * (x % W) + 60.0 * th_uniform(&s));
        for (x = 0; x < H; x++)
            z[x * W + 6] = 600.0f;
        if (rep % 2)
            fl[12 * W + 3] = TS_CELL_FIXED; /* a fixed cell off the valleys */
        memcpy(z0, z, (size_t)W * H * sizeof(float));
        memset(fo, 0, (size_t)W * H);
        CHECK(ts__valley_breach(ctx, &g->f, &r, fl, 16, fo) == TS_OK);
        /* fixed cells stay; the floor may be filled where that moves fewer metres
         * than cutting, and the land beside a filled floor rises to it at most */
        for (x = 0; x < W * H; x++)
            if (((fl[x] & TS_CELL_FIXED) && z[x] != z0[x]) ||
                (!fo[x] && z[x] > z0[x] && z[x] > nearest_floor_level(fo, z, W, H, x) + 1e-3f))
                bad = 1;
        CHECK_MSG(!bad, "a fixed cell moved, or land rose above the floor beside it");
        /* the floor (within 2 cells of the drawn one, patch / 10 at least 2)
         * drains, and it passes within 2 cells of every drawn cell */
        drains_naive(z, W, H, dr);
        for (x = 0; x < W * H; x++)
            if (fo[x]) {
                CHECK_MSG(dr[x], "rep %d: floor cell %d,%d holds water", rep, x % W, x / W);
                CHECK_MSG(near_cell(&g->f, x % W, x / W, 2), "rep %d: floor cell %d,%d far", rep,
                          x % W, x / W);
            }
        for (k = 0; k < g->f.n_verts; k++) {
            const ts_feature_vertex *v = &g->f.verts[k];
            int dx, dy, hit = 0;
            for (dy = -2; dy <= 2; dy++)
                for (dx = -2; dx <= 2; dx++)
                    if (v->x + dx >= 0 && v->x + dx < W && v->y + dy >= 0 && v->y + dy < H)
                        hit |= fo[(v->y + dy) * W + v->x + dx];
            CHECK_MSG(hit, "rep %d: no floor near valley cell %d,%d", rep, v->x, v->y);
        }
        /* the wall is cut where the trunk's floor crosses it, and lowered beside
         * the cut (a gorge, not a one-cell slot), less far off */
        for (cut = -1, x = 18; x <= 22; x++)
            if (fo[x * W + 6])
                cut = x;
        CHECK(cut >= 0 && z[cut * W + 6] < 600.0f);
        CHECK_MSG(cut >= 0 && z[(cut - 2) * W + 6] < 600.0f &&
                      z[2 * W + 6] >= z[(cut - 2) * W + 6] && z[(cut - 2) * W + 6] > z[cut * W + 6],
                  "rep %d: the wall 2 cells off the cut at row %d is not lowered towards it", rep,
                  cut);
        memset(fl, 0, (size_t)W * H);
    }
    free(z);
    free(z0);
    free(level);
    free(dr);
    free(fl);
    free(fo);
    free(g);
    ts_ctx_free(ctx);
}

/* ---- the corrections ---- */

/* An exemplar with ridges: rows of a sine, 60 cells a period. */
static void make_exemplar(ts_raster *ex)
{
    int x, y;
    for (y = 0; y < ex->height; y++)
        for (x = 0; x < ex->width; x++)
            TS_PIX(ex, x, y) =
                (float)(500.0 + 200.0 * sin(2.0 * 3.14159265358979323846 * x / 60.0) +
                        20.0 * sin(0.7 * y + 0.3 * x));
}

/* The layout of one exemplar (with its profile) over a W x H sketch mask. */
static ts_layout_spec layout_spec(const unsigned char *mask, int kind, int W, int H,
                                  const ts_raster *ex, const ts_relief_profile *prof, int P)
{
    ts_layout_spec sp;
    memset(&sp, 0, sizeof sp);
    sp.sketch_mask = mask;
    sp.kind = kind;
    sp.width = W;
    sp.height = H;
    sp.exemplars = ex;
    sp.n_exemplars = 1;
    sp.profs = prof;
    sp.patch = P;
    return sp;
}

/* One valley path through the n cells vv[0..n) (its two ends the nodes nn[0], nn[1],
 * taken from the cells): the feature graph the valley floor's descent walks. */
/* A feature graph over caller-owned arrays. */
static void wrap_features(ts_features *ff, ts_feature_node *nn, size_t n_nodes, ts_feature_path *pp,
                          size_t n_paths, ts_feature_vertex *vv, size_t n_verts, int W, int H)
{
    memset(ff, 0, sizeof *ff);
    ff->width = W;
    ff->height = H;
    ff->nodes = nn;
    ff->n_nodes = n_nodes;
    ff->paths = pp;
    ff->n_paths = n_paths;
    ff->verts = vv;
    ff->n_verts = n_verts;
}

static void one_valley_path(ts_features *ff, ts_feature_node nn[2], ts_feature_path *pp,
                            ts_feature_vertex *vv, size_t n, int W, int H)
{
    nn[0] = (ts_feature_node){vv[0].x, vv[0].y, 0, 1, TS_VALLEY};
    nn[1] = (ts_feature_node){vv[n - 1].x, vv[n - 1].y, 0, 1, TS_VALLEY};
    pp[0] = (ts_feature_path){TS_VALLEY, 0, 1, 0, n, 0, 0, 0, 0};
    wrap_features(ff, nn, 2, pp, 1, vv, n, W, H);
}

/* The floor follows the valley's own lowest line: a V valley whose bottom
 * wanders up to 2 cells either side of the straight drawn line (rising away
 * from the outlet on the edge at y = 0).  The floor is the bottom, row by row
 * (the cells the land is lowest in; only the ends join the drawn end cells),
 * it drains and nothing beside it holds water; a floor carved along the drawn
 * line would dam the bottom wherever it lies off the line. */
static int bottom_x(int y)
{
    return 30 + (int)lround(2.0 * sin(y / 5.0));
}

static void test_valley_thalweg(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 60, H = 48, x, y;
    float *z = malloc((size_t)W * H * sizeof(float));
    unsigned char *dr = malloc((size_t)W * H), *fo = calloc((size_t)W * H, 1);
    ts_feature_vertex vv[48];
    ts_feature_node nn[2];
    ts_feature_path pp[1];
    ts_features ff;
    ts_raster r = ts_raster_wrap(z, W, H, W);
    for (y = 0; y < H; y++) {
        vv[y] = (ts_feature_vertex){30, y, 0};
        for (x = 0; x < W; x++)
            z[y * W + x] = (float)(500.0 + 2.0 * y + 6.0 * abs(x - bottom_x(y)));
    }
    one_valley_path(&ff, nn, pp, vv, (size_t)H, W, H);
    CHECK(ts__valley_breach(ctx, &ff, &r, NULL, 16, fo) == TS_OK);
    for (y = 3; y < H - 3; y++) {
        int n = 0;
        CHECK_MSG(fo[y * W + bottom_x(y)], "row %d: the bottom at %d is not the floor", y,
                  bottom_x(y));
        for (x = 0; x < W; x++)
            n += fo[y * W + x];
        CHECK_MSG(n <= 2, "row %d: %d floor cells", y, n);
    }
    drains_naive(z, W, H, dr);
    for (x = 0; x < W * H; x++)
        CHECK_MSG(dr[x], "cell %d,%d holds water", x % W, x / W);
    free(z);
    free(dr);
    free(fo);
    ts_ctx_free(ctx);
}

/* Two drawn valleys whose ways down would make a ring: the west one ends a
 * few cells from the east one (and drains into it: a channel), and the east
 * one's way out over the lowest pass runs down a trough through the west
 * one.  The east one's water passes the west one by and leaves at the
 * edge: every carve cell has a way down (no TS_ERR_INTERNAL), and both
 * floors drain. */
static void test_valley_no_ring(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 64, H = 64, x, y, k;
    float *z = malloc((size_t)W * H * sizeof(float));
    unsigned char *dr = malloc((size_t)W * H), *fo = calloc((size_t)W * H, 1);
    ts_feature_vertex vv[29 + 25];
    ts_feature_node nn[4];
    ts_feature_path pp[2];
    ts_features ff;
    ts_raster r = ts_raster_wrap(z, W, H, W);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            z[y * W + x] = (float)(100.0 + 3.0 * x + 2.0 * abs(y - 32));
    for (k = 0; k < 29; k++)
        vv[k] = (ts_feature_vertex){12 + k, 32, 0};
    for (k = 0; k < 25; k++)
        vv[29 + k] = (ts_feature_vertex){46, 20 + k, 0};
    nn[0] = (ts_feature_node){12, 32, 0, 1, TS_VALLEY};
    nn[1] = (ts_feature_node){40, 32, 0, 1, TS_VALLEY};
    nn[2] = (ts_feature_node){46, 20, 0, 1, TS_VALLEY};
    nn[3] = (ts_feature_node){46, 44, 0, 1, TS_VALLEY};
    pp[0] = (ts_feature_path){TS_VALLEY, 0, 1, 0, 29, 0, 0, 0, 0};
    pp[1] = (ts_feature_path){TS_VALLEY, 2, 3, 29, 25, 0, 0, 0, 0};
    wrap_features(&ff, nn, 4, pp, 2, vv, 29 + 25, W, H);
    CHECK_MSG(ts__valley_breach(ctx, &ff, &r, NULL, 8, fo) == TS_OK, "%s", ts_ctx_message(ctx));
    drains_naive(z, W, H, dr);
    for (x = 0; x < W * H; x++) {
        CHECK_MSG(isfinite(z[x]), "cell %d,%d: %g", x % W, x / W, z[x]);
        CHECK_MSG(!fo[x] || dr[x], "floor cell %d,%d holds water", x % W, x / W);
    }
    free(z);
    free(dr);
    free(fo);
    ts_ctx_free(ctx);
}

/* The lowest level at which water at cell c0 reaches the grid's edge
 * (brute force: for every candidate level, the cells at or below it that
 * join c0 breadth first). */
static float lowest_way_out(const float *z, int W, int H, int c0)
{
    int n = W * H, i, *q = malloc((size_t)n * sizeof *q);
    unsigned char *seen = malloc((size_t)n);
    float best = INFINITY;
    for (i = 0; i < n; i++) {
        int head = 0, tail = 0, out = 0;
        float lv = z[i];
        if (lv < z[c0] || lv >= best)
            continue;
        memset(seen, 0, (size_t)n);
        q[tail++] = c0;
        seen[c0] = 1;
        while (head < tail && !out) {
            int c = q[head++], x = c % W, y = c / W, dx, dy;
            out = x == 0 || y == 0 || x == W - 1 || y == H - 1;
            for (dy = -1; dy <= 1; dy++)
                for (dx = -1; dx <= 1; dx++) {
                    int nx = x + dx, ny = y + dy, nc = ny * W + nx;
                    if (nx < 0 || ny < 0 || nx >= W || ny >= H || seen[nc] || z[nc] > lv)
                        continue;
                    seen[nc] = 1;
                    q[tail++] = nc;
                }
        }
        if (out)
            best = lv;
    }
    free(q);
    free(seen);
    return best;
}

/* A drawn valley whose end lies in a bowl (the land rises 8 m a cell all
 * round it), with one low winding corridor (rising 1 m a cell) out to the
 * east edge: the way out the layout is given (ts__valley_outlets) is a new
 * valley path from the valley's end node to the grid's edge, its highest
 * cell no higher than the lowest way out (brute force), every cell of it
 * in the mask; the drawn paths stay as they were. */
static void test_valley_way_out(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 64, H = 64, x, y, k;
    float *z = malloc((size_t)W * H * sizeof(float)), pass, top = -INFINITY;
    unsigned char *mask = calloc((size_t)W * H, 1);
    ts_feature_vertex vv[25];
    ts_feature_node nn[2];
    ts_feature_path pp[1];
    ts_features ff, *with = NULL;
    ts_raster r = ts_raster_wrap(z, W, H, W);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            z[y * W + x] = (float)(300.0 + 8.0 * hypot(x - 32, y - 32));
    for (k = 0; k < 25; k++) { /* the valley, its end at (32, 44) */
        vv[k] = (ts_feature_vertex){32, 20 + k, 0};
        mask[(20 + k) * W + 32] = TS_VALLEY;
        z[(20 + k) * W + 32] = (float)(300.0 - k);
    }
    for (k = 1; k <= 40; k++) { /* the corridor: south-east, then east */
        int cx = 32 + (k < 12 ? k / 2 : k - 6), cy = 44 + (k < 12 ? k : 11);
        for (x = cx - 1; x <= cx + 1 && cx < W; x++)
            if (x < W)
                z[cy * W + x] = fminf(z[cy * W + x], (float)(276.0 + k));
    }
    one_valley_path(&ff, nn, pp, vv, 25, W, H);
    ff.mask = mask;
    pass = lowest_way_out(z, W, H, 44 * W + 32);
    CHECK_MSG(ts__valley_outlets(ctx, &ff, &r, NULL, 8, &with) == TS_OK, "%s", ts_ctx_message(ctx));
    CHECK(with && with->n_paths == 2 && with->n_nodes == 3);
    if (with && with->n_paths == 2 && with->n_nodes == 3) {
        const ts_feature_path *c = &with->paths[1];
        const ts_feature_vertex *e = &with->verts[c->first + c->count - 1];
        CHECK(with->paths[0].count == 25 && with->paths[0].first == 0);
        CHECK(c->kind == TS_VALLEY && c->node_a == 1 && with->nodes[1].degree == 2);
        CHECK(with->verts[c->first].x == 32 && with->verts[c->first].y == 44);
        CHECK_MSG(e->x == 0 || e->y == 0 || e->x == W - 1 || e->y == H - 1,
                  "the way out ends at %d,%d", e->x, e->y);
        for (k = 0; k < (int)c->count; k++) {
            const ts_feature_vertex *v = &with->verts[c->first + (size_t)k];
            top = fmaxf(top, z[v->y * W + v->x]);
            CHECK(with->mask[v->y * W + v->x] & TS_VALLEY);
        }
        CHECK_MSG(top <= pass + 0.01f, "the way out climbs to %g, the lowest way %g", top, pass);
    }
    ts_features_free(with);
    free(z);
    free(mask);
    ts_ctx_free(ctx);
}

/* Whether a floor cell lies within r cells (Chebyshev) of (x, y). */
static int near_floor(const unsigned char *fo, int W, int H, int x, int y, int r)
{
    int u, v;
    for (v = y - r; v <= y + r; v++)
        for (u = x - r; u <= x + r; u++)
            if (u >= 0 && v >= 0 && u < W && v < H && fo[v * W + u])
                return 1;
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* A gorge with the land's own walls: a V valley falling west, dammed by a
 * wall 80 m high and a few cells thick that crosses it aslant, with bumps.  The floor is cut
 * through the wall; where the cut makes the land it lowers steeper, it is
 * nowhere steeper than the land's steep slope (the 95th percentile of the
 * central-difference gradient, computed here) beyond a margin for the
 * floor's own fall, more than 3 cells off the floor (where the floor's own
 * change is smoothed): no step where the cut's depth changes from one floor
 * cell to the next. */
static void test_valley_gorge(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 120, H = 80, x, y, dx, dy, k = 0;
    float *z = malloc((size_t)W * H * sizeof(float)), *z0 = malloc((size_t)W * H * sizeof(float));
    double *g = malloc((size_t)W * H * sizeof(double)), s95, worst = 0.0;
    unsigned char *fo = calloc((size_t)W * H, 1);
    ts_feature_vertex vv[120];
    ts_feature_node nn[2];
    ts_feature_path pp[1];
    ts_features ff;
    ts_raster r = ts_raster_wrap(z, W, H, W);
    uint64_t s = 5;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            z[y * W + x] = (float)(100.0 + 0.5 * x + 1.5 * abs(y - 40) +
                                   (abs(x - 60 - (y - 40)) <= 1 && abs(y - 40) <= 25 ? 80.0 : 0.0) +
                                   th_uniform(&s));
    for (x = 0; x < W; x++)
        vv[x] = (ts_feature_vertex){W - 1 - x, 40, 0};
    one_valley_path(&ff, nn, pp, vv, (size_t)W, W, H);
    for (y = 1; y < H - 1; y++)
        for (x = 1; x < W - 1; x++) {
            double gx = 0.5 * (z[y * W + x + 1] - z[y * W + x - 1]);
            double gy = 0.5 * (z[(y + 1) * W + x] - z[(y - 1) * W + x]);
            g[k++] = sqrt(gx * gx + gy * gy);
        }
    qsort(g, (size_t)k, sizeof *g, cmp_double);
    s95 = g[(size_t)(0.95 * (k - 1))];
    memcpy(z0, z, (size_t)W * H * sizeof(float));
    CHECK(ts__valley_breach(ctx, &ff, &r, NULL, 32, fo) == TS_OK);
    CHECK_MSG(z[40 * W + 60] < z0[40 * W + 60] - 60.0f, "the wall is not cut: %g -> %g",
              z0[40 * W + 60], z[40 * W + 60]);
    for (y = 1; y < H - 1; y++)
        for (x = 1; x < W - 1; x++) {
            int c = y * W + x;
            if (z[c] > z0[c] - 0.5f || near_floor(fo, W, H, x, y, 3))
                continue; /* the land the cut lowers, off the floor's own smoothing */
            for (dy = -1; dy <= 1; dy++)
                for (dx = -1; dx <= 1; dx++) {
                    int e = c + dy * W + dx;
                    double now = fabs((double)z[c] - z[e]), was = fabs((double)z0[c] - z0[e]);
                    if ((dx || dy) && !near_floor(fo, W, H, x + dx, y + dy, 3) &&
                        z[e] < z0[e] - 0.5f && now > 1.1 * was + 1.0)
                        worst = fmax(worst, now / hypot(dx, dy)); /* made steeper */
                }
        }
    CHECK_MSG(worst <= 1.25 * s95 + 1.0,
              "a wall of the cut climbs %.1f m a cell (steep slope %.1f)", worst, s95);
    free(z);
    free(z0);
    free(g);
    free(fo);
    ts_ctx_free(ctx);
}

/* The floor's fit against the least total change a dynamic program finds
 * (the best heights of a monotone fit in weighted L1 are among the data's;
 * a metre filled costs eight cut): a straight
 * valley rising from its outlet at y = 0, with a wall across it, a pit on its
 * floor and noise.  The floor (the valley's bottom, the drawn line here) must
 * never rise towards the outlet and cost no more than the optimum: the
 * wall cut (2 cells), the pit filled (1 cell). */
/* A metre filled costs 8 metres cut (valley_floor.c's TS_FLOOR_FILL). */
static double fill_cut_cost(double z, double t)
{
    return t > z ? 8.0 * (t - z) : z - t;
}

static double monotone_l1_optimum(const double *z, int n)
{
    double *v = malloc((size_t)n * sizeof *v), *dp = malloc((size_t)n * sizeof *dp), best;
    int i, k, j;
    for (i = 0; i < n; i++)
        v[i] = z[i];
    for (i = 1; i < n; i++) /* the candidate heights, sorted */
        for (j = i; j > 0 && v[j - 1] > v[j]; j--) {
            double t = v[j];
            v[j] = v[j - 1];
            v[j - 1] = t;
        }
    for (k = 0; k < n; k++)
        dp[k] = fill_cut_cost(z[0], v[k]);
    for (i = 1; i < n; i++) { /* t_i >= t_(i-1): the best of the lower candidates */
        double run = INFINITY;
        for (k = 0; k < n; k++) {
            run = fmin(run, dp[k]);
            dp[k] = run + fill_cut_cost(z[i], v[k]);
        }
    }
    for (best = INFINITY, k = 0; k < n; k++)
        best = fmin(best, dp[k]);
    free(v);
    free(dp);
    return best;
}

static void test_floor_fit(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 61, H = 60, x, y, rep;
    float *z = malloc((size_t)W * H * sizeof(float)), *z0 = malloc((size_t)W * H * sizeof(float));
    unsigned char *fo = malloc((size_t)W * H);
    double floor0[60], change;
    ts_feature_vertex vv[60];
    ts_feature_node nn[2];
    ts_feature_path pp[1];
    ts_features ff;
    ts_raster r = ts_raster_wrap(z, W, H, W);
    uint64_t s = 7;
    for (rep = 0; rep < 6; rep++) {
        for (y = 0; y < H; y++) {
            double f = 500.0 + 2.0 * y + 10.0 * th_uniform(&s);
            if (y == 10 || y == 11)
                f += 150.0; /* a wall across */
            if (y == 30)
                f -= 60.0; /* a pit on the floor */
            floor0[y] = f;
            vv[y] = (ts_feature_vertex){30, y, 0};
            for (x = 0; x < W; x++)
                z[y * W + x] = (float)(f + 50.0 * abs(x - 30));
        }
        memcpy(z0, z, (size_t)W * H * sizeof(float));
        one_valley_path(&ff, nn, pp, vv, (size_t)H, W, H);
        memset(fo, 0, (size_t)W * H);
        CHECK(ts__valley_breach(ctx, &ff, &r, NULL, 16, fo) == TS_OK);
        for (y = 0, change = 0.0; y < H; y++) {
            CHECK_MSG(fo[y * W + 30], "rep %d: row %d's bottom is not the floor", rep, y);
            if (y)
                CHECK_MSG(z[y * W + 30] >= z[(y - 1) * W + 30], "rep %d: the floor falls at %d",
                          rep, y);
            floor0[y] = (double)z0[y * W + 30];
            change += fill_cut_cost(floor0[y], (double)z[y * W + 30]);
        }
        {
            double opt = monotone_l1_optimum(floor0, H);
            CHECK_MSG(change <= opt + 1e-2 * H, "rep %d: the floor moved %.2f m, the optimum %.2f",
                      rep, change, opt);
        }
        CHECK(z[10 * W + 30] < z0[10 * W + 30] - 100.0f); /* the wall cut */
        CHECK(z[30 * W + 30] > z0[30 * W + 30] + 20.0f);  /* the pit filled */
    }
    free(z);
    free(z0);
    free(fo);
    ts_ctx_free(ctx);
}

/* ---- a valley floor made to descend leaves no stripes across the valley ----
 * A steep valley stroke is a staircase of cells (a jog every 4 rows); the floor,
 * bumpy along it, is made to descend.  Beside the floor line, along the valley, the
 * land must change smoothly: the change spread from each cell's nearest floor cell
 * jumped at every jog, and so did a smooth change faded out by the distance to the
 * staircase, which ripples along it (stripes across the valley, seen in hillshades). */
static void test_valley_no_stripes(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 160, H = 220, x, y, P = 32;
    size_t n = (size_t)W * H;
    unsigned char *mask = calloc(n, 1);
    ts_raster ex, out;
    ts_relief_profile prof;
    ts_layout_spec sp;
    static ts_feature_vertex vv[220];
    static ts_feature_node nn[2];
    static ts_feature_path pp[1];
    static ts_features ff;
    double worst_side = 0.0, worst_far = 0.0;
    uint64_t s = 9;
    CHECK(ts_raster_alloc(ctx, 200, 200, &ex) == TS_OK);
    CHECK(ts_raster_alloc(ctx, W, H, &out) == TS_OK);
    make_exemplar(&ex);
    memset(&prof, 0, sizeof prof);
    prof.valid = 1;
    prof.level = 300.0;
    for (y = 0; y < H; y++) {
        int ax = 30 + y / 4;
        mask[(size_t)y * W + (size_t)ax] = TS_VALLEY;
        vv[y] = (ts_feature_vertex){ax, y, 0};
    }
    one_valley_path(&ff, nn, pp, vv, (size_t)H, W, H);
    sp = layout_spec(mask, TS_VALLEY, W, H, &ex, &prof, P);
    sp.features = &ff;
    /* a smooth land, a bumpy floor line */
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&out, x, y) =
                (float)(400.0 + 0.2 * th_uniform(&s) +
                        (x == 30 + y / 4
                             ? 30.0 * sin(0.3 * y) + 150.0 * exp(-pow((y - 110) / 40.0, 2))
                             : 0.0));
    CHECK(ts__layout_apply(ctx, &sp, &out, NULL, 1.0) == TS_OK);
    /* the floor still descends cell by cell (to the outlet at either end) */
    {
        int up = 0, down = 0;
        for (y = 1; y < H; y++) {
            up += TS_PIX(&out, 30 + y / 4, y) > TS_PIX(&out, 30 + (y - 1) / 4, y - 1);
            down += TS_PIX(&out, 30 + y / 4, y) < TS_PIX(&out, 30 + (y - 1) / 4, y - 1);
        }
        CHECK_MSG(up == 0 || down == 0, "the floor rises %d times and falls %d times", up, down);
    }
    /* along the valley, on lines parallel to the stroke's axis (x = 30.375 + y / 4,
     * read by linear interpolation along the row), 3 cells beside it and 40 off it:
     * the largest second difference (a stripe is a kink along the valley) */
    for (y = 20; y + 21 < H; y++) {
        double z[2][3];
        int k, side;
        for (side = 0; side < 2; side++)
            for (k = 0; k < 3; k++) {
                int yy = y - 1 + k;
                double fx = (side ? 70.375 : 33.375) + yy / 4.0, t = fx - floor(fx);
                int x0 = (int)floor(fx);
                z[side][k] = (1 - t) * TS_PIX(&out, x0, yy) + t * TS_PIX(&out, x0 + 1, yy);
            }
        worst_side = fmax(worst_side, fabs(z[0][0] - 2 * z[0][1] + z[0][2]));
        worst_far = fmax(worst_far, fabs(z[1][0] - 2 * z[1][1] + z[1][2]));
    }
    /* measured: 4.7 beside, 0.3 far; 16.5 beside with the change spread from each
     * cell's nearest floor cell, 10.3 with a smooth change faded out by the plain
     * distance to the staircase (bumps of 30 and a hump of 150 on the floor) */
    CHECK_MSG(worst_side <= 7.0 && worst_far <= 1.0,
              "kinks along the valley: %.2f beside the floor line, %.2f far from it", worst_side,
              worst_far);
    ts_raster_free(&ex);
    ts_raster_free(&out);
    free(mask);
    ts_ctx_free(ctx);
}

static void test_corrections(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int W = 160, H = 120, x, y, P = 32;
    size_t n = (size_t)W * H;
    unsigned char *mask = calloc(n, 1), *flags = calloc(n, 1);
    ts_raster ex, out, keep;
    ts_relief_profile prof;
    ts_layout_spec sp;
    uint64_t s = 4;
    CHECK(ts_raster_alloc(ctx, 200, 200, &ex) == TS_OK);
    CHECK(ts_raster_alloc(ctx, W, H, &out) == TS_OK);
    CHECK(ts_raster_alloc(ctx, W, H, &keep) == TS_OK);
    make_exemplar(&ex);
    memset(&prof, 0, sizeof prof);
    prof.valid = 1;
    prof.level = 700.0;
    /* a ridge stroke across the middle row */
    for (x = 10; x < W - 10; x++)
        mask[60 * W + x] = TS_RIDGE;
    sp = layout_spec(mask, TS_RIDGE, W, H, &ex, &prof, P);
    /* a rough flat land */
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&out, x, y) = TS_PIX(&keep, x, y) = (float)(400.0 + 5.0 * th_uniform(&s));
    /* strength 0: nothing changes */
    CHECK(ts__layout_apply(ctx, &sp, &out, NULL, 0.0) == TS_OK);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            CHECK(TS_PIX(&out, x, y) == TS_PIX(&keep, x, y));
    /* a fixed window (a pin) in the corner never changes */
    for (y = 5; y < 25; y++)
        for (x = 5; x < 25; x++)
            flags[y * W + x] = TS_CELL_FIXED;
    CHECK(ts__layout_apply(ctx, &sp, &out, flags, 1.0) == TS_OK);
    for (y = 5; y < 25; y++)
        for (x = 5; x < 25; x++)
            CHECK(TS_PIX(&out, x, y) == TS_PIX(&keep, x, y));
    /* the land now rises to the stroke: higher on it than 20 and 40 cells
     * away on both sides, all along it */
    for (x = 50; x < W - 30; x += 10) {
        double on = TS_PIX(&out, x, 60);
        CHECK(on > TS_PIX(&out, x, 40) + 20.0 && on > TS_PIX(&out, x, 80) + 20.0);
        CHECK(TS_PIX(&out, x, 40) > TS_PIX(&out, x, 20) &&
              TS_PIX(&out, x, 80) > TS_PIX(&out, x, 100));
    }
    /* valleys: a flat land with a bumpy floor along a valley stroke from
     * the west edge: after the corrections the floor descends to the edge */
    memset(mask, 0, n);
    for (x = 0; x < W - 10; x++)
        mask[60 * W + x] = TS_VALLEY;
    {
        /* the valley as a one-path graph, outlet on the west edge */
        static ts_feature_vertex vv[200];
        static ts_feature_node nn[2];
        static ts_feature_path pp[1];
        static ts_features ff;
        for (x = 0; x < W - 10; x++)
            vv[x] = (ts_feature_vertex){x, 60, 0};
        one_valley_path(&ff, nn, pp, vv, (size_t)(W - 10), W, H);
        sp.features = &ff;
    }
    sp.kind = TS_VALLEY;
    prof.level = 300.0;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&out, x, y) =
                (float)(400.0 + 5.0 * th_uniform(&s) + (y == 60 ? 30.0 * sin(0.3 * x) : 0.0));
    CHECK(ts__layout_apply(ctx, &sp, &out, NULL, 1.0) == TS_OK);
    for (x = 1; x < W - 10; x++)
        CHECK(TS_PIX(&out, x - 1, 60) <= TS_PIX(&out, x, 60));
    CHECK(TS_PIX(&out, 80, 60) < TS_PIX(&out, 80, 30) - 20.0);
    ts_raster_free(&ex);
    ts_raster_free(&out);
    ts_raster_free(&keep);
    free(mask);
    free(flags);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"nearest_brute_force", test_nearest_brute_force},
        {"valley_breach", test_valley_breach},
        {"valley_no_ring", test_valley_no_ring},
        {"valley_way_out", test_valley_way_out},
        {"valley_gorge", test_valley_gorge},
        {"valley_thalweg", test_valley_thalweg},
        {"floor_fit", test_floor_fit},
        {"descend", test_descend},
        {"valley_no_stripes", test_valley_no_stripes},
        {"corrections", test_corrections},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
