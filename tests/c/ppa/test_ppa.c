/*
 * test_ppa.c - PPA on synthetic DEMs with known truth, and polygon breaking
 * (Kruskal) against naive repeated polygon breaking.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "naive_flow.h"
#include "ppa_internal.h"
#include "terrasynth.h"

typedef double (*surface_fn)(double x, double y);

static ts_raster make_dem(ts_ctx *ctx, int w, int h, surface_fn f)
{
    ts_raster r;
    int x, y;
    if (ts_raster_alloc(ctx, w, h, &r) != TS_OK)
        abort();
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            TS_PIX(&r, x, y) = (float)f(x, y);
    return r;
}

/* The PPA by profiles alone (the paper's; min_drainage 0): valleys as ridges. */
static ts_features *run_ppa(ts_ctx *ctx, const ts_raster *dem, int features)
{
    ts_ppa_params p = ts_ppa_params_default();
    ts_features *f = NULL;
    p.features = features;
    p.min_drainage = 0;
    if (ts_ppa_extract(ctx, dem, NULL, &p, &f) != TS_OK) {
        fprintf(stderr, "ppa failed: %s\n", ts_ctx_message(ctx));
        return NULL;
    }
    return f;
}

static size_t count_nodes(const ts_features *f, int kind, int min_degree, int max_degree)
{
    size_t i, n = 0;
    for (i = 0; i < f->n_nodes; i++)
        if (f->nodes[i].kind == kind && f->nodes[i].degree >= min_degree &&
            f->nodes[i].degree <= max_degree)
            n++;
    return n;
}

static size_t count_mask(const ts_features *f, int bit)
{
    size_t i, n = 0;
    for (i = 0; i < (size_t)f->width * (size_t)f->height; i++)
        n += (f->mask[i] & bit) != 0;
    return n;
}

/* Forest check from the paths alone: with the path steps as edges over the
 * distinct cells, edges = vertices - components and no step closes a cycle. */
static int find_root(int *parent, int v)
{
    while (parent[v] != v)
        v = parent[v] = parent[parent[v]];
    return v;
}

static void check_forest_kind(const ts_features *f, int kind)
{
    size_t n = (size_t)f->width * (size_t)f->height, i, k, verts = 0, edges = 0, comps = 0;
    int *parent = malloc(n * sizeof *parent);
    unsigned char *seen = calloc(n, 1);
    int cycle = 0;
    for (i = 0; i < n; i++)
        parent[i] = (int)i;
    for (i = 0; i < f->n_paths; i++) {
        const ts_feature_path *p = &f->paths[i];
        if (p->kind != kind)
            continue;
        CHECK(p->count >= 2);
        for (k = 0; k < p->count; k++) {
            const ts_feature_vertex *v = &f->verts[p->first + k];
            int id = v->y * f->width + v->x;
            if (!seen[id]) {
                seen[id] = 1;
                verts++;
            }
            if (k > 0) {
                const ts_feature_vertex *u = &f->verts[p->first + k - 1];
                int a = find_root(parent, u->y * f->width + u->x), b = find_root(parent, id);
                CHECK(abs(u->x - v->x) <= 1 && abs(u->y - v->y) <= 1);
                edges++;
                if (a == b)
                    cycle = 1;
                else
                    parent[a] = b;
            }
        }
        /* path ends are the nodes it names */
        CHECK(f->verts[p->first].x == f->nodes[p->node_a].x &&
              f->verts[p->first].y == f->nodes[p->node_a].y);
        CHECK(f->verts[p->first + p->count - 1].x == f->nodes[p->node_b].x &&
              f->verts[p->first + p->count - 1].y == f->nodes[p->node_b].y);
    }
    for (i = 0; i < n; i++)
        if (seen[i] && find_root(parent, (int)i) == (int)i)
            comps++;
    CHECK(!cycle);
    CHECK_MSG(edges == verts - comps, "edges %zu, vertices %zu, components %zu", edges, verts,
              comps);
    /* every masked cell lies on a path of its kind */
    for (i = 0; i < n; i++)
        if ((f->mask[i] & kind) && !seen[i]) {
            CHECK_MSG(0, "mask cell %zu is on no path", i);
            break;
        }
    free(parent);
    free(seen);
}

/* Each kind is a forest on its own (a saddle cell may be on both). */
static void check_forest(const ts_features *f)
{
    check_forest_kind(f, TS_RIDGE);
    check_forest_kind(f, TS_VALLEY);
}

/* Profiles are cut short at the raster edge, so the last two cells of an
 * axis may hook; truth is checked away from the edge. */
static int near_edge(const ts_features *f, const ts_feature_vertex *v)
{
    return v->x < 2 || v->y < 2 || v->x >= f->width - 2 || v->y >= f->height - 2;
}

/* ---- straight Gaussian ridge: one path within one cell of the crest ---- */
static double ridge_straight(double x, double y)
{
    return 500.0 * exp(-(y - 30.3) * (y - 30.3) / (2 * 6.0 * 6.0)) + 0.05 * x;
}

static void test_straight_ridge(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster dem = make_dem(ctx, 120, 61, ridge_straight);
    ts_features *f = run_ppa(ctx, &dem, TS_PPA_BOTH);
    size_t i, k, longest = 0;
    CHECK(f != NULL);
    if (f) {
        check_forest(f);
        CHECK_MSG(count_nodes(f, TS_RIDGE, 3, 8) == 0, "branch points: %zu",
                  count_nodes(f, TS_RIDGE, 3, 8));
        for (i = 0; i < f->n_paths; i++) {
            const ts_feature_path *p = &f->paths[i];
            CHECK(p->kind == TS_RIDGE);
            if (p->count > longest)
                longest = p->count;
            for (k = 0; k < p->count; k++)
                if (!near_edge(f, &f->verts[p->first + k]))
                    CHECK_MSG(fabs(f->verts[p->first + k].y - 30.3) <= 1.0, "vertex row %d",
                              f->verts[p->first + k].y);
        }
        CHECK_MSG(f->n_paths == 1, "%zu paths", f->n_paths);
        CHECK_MSG(longest >= 110, "longest path has %zu cells", longest);
        CHECK(count_mask(f, TS_VALLEY) == 0);
    }
    ts_features_free(f);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

/* ---- Y-shaped ridge: exactly one branch point near the junction ---- */
static double ridge_y(double x, double y)
{
    /* three ridge arms from (60, 60) at 90, 210 and 330 degrees */
    static const double ang[3] = {90.0, 210.0, 330.0};
    double best = 0.0;
    int a;
    for (a = 0; a < 3; a++) {
        double t = ang[a] * 3.14159265358979 / 180.0, ux = cos(t), uy = -sin(t);
        double px = x - 60.0, py = y - 60.0, along = px * ux + py * uy;
        double across = fabs(px * uy - py * ux), v;
        if (along < 0)
            across = sqrt(px * px + py * py);
        v = 400.0 * exp(-across * across / (2 * 5.0 * 5.0)) - 0.8 * (along > 0 ? along : 0);
        if (v > best || a == 0)
            best = v;
    }
    return best + 0.01 * x + 0.003 * y;
}

static void test_y_ridge(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster dem = make_dem(ctx, 121, 121, ridge_y);
    ts_features *f = run_ppa(ctx, &dem, TS_PPA_RIDGES);
    CHECK(f != NULL);
    if (f) {
        size_t i, nb = 0;
        check_forest(f);
        for (i = 0; i < f->n_nodes; i++)
            if (f->nodes[i].degree >= 3) {
                nb++;
                CHECK(f->nodes[i].degree == 3);
                CHECK_MSG(hypot(f->nodes[i].x - 60.0, f->nodes[i].y - 60.0) <= 3.0,
                          "branch point at %d,%d", f->nodes[i].x, f->nodes[i].y);
            }
        CHECK_MSG(nb == 1, "%zu branch points", nb);
        CHECK_MSG(count_nodes(f, TS_RIDGE, 1, 1) == 3, "%zu endpoints",
                  count_nodes(f, TS_RIDGE, 1, 1));
        CHECK(f->n_paths == 3);
    }
    ts_features_free(f);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

/* ---- V-valley ---- */
static double valley_v(double x, double y)
{
    return 3.0 * fabs(y - 25.4) + 0.02 * x + 100.0;
}

static void test_v_valley(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster dem = make_dem(ctx, 100, 50, valley_v);
    ts_features *f = run_ppa(ctx, &dem, TS_PPA_BOTH);
    CHECK(f != NULL);
    if (f) {
        size_t i, k;
        check_forest(f);
        CHECK_MSG(f->n_paths == 1, "%zu paths", f->n_paths);
        CHECK(count_mask(f, TS_RIDGE) == 0);
        CHECK(count_mask(f, TS_VALLEY) >= 90);
        for (i = 0; i < f->n_paths; i++) {
            CHECK(f->paths[i].kind == TS_VALLEY);
            for (k = 0; k < f->paths[i].count; k++)
                if (!near_edge(f, &f->verts[f->paths[i].first + k]))
                    CHECK(abs(f->verts[f->paths[i].first + k].y - 25) <= 1);
        }
    }
    ts_features_free(f);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

/* ---- cone and pit: no valleys on a cone, no ridges in a pit ---- */
static double cone(double x, double y)
{
    return 1000.0 - 2.0 * hypot(x - 40.2, y - 39.7);
}
static double pit(double x, double y)
{
    return 2.0 * hypot(x - 40.2, y - 39.7);
}

static void test_cone_and_pit(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster c = make_dem(ctx, 81, 81, cone), p = make_dem(ctx, 81, 81, pit);
    ts_features *fc = run_ppa(ctx, &c, TS_PPA_BOTH), *fp = run_ppa(ctx, &p, TS_PPA_BOTH);
    CHECK(fc && fp);
    if (fc && fp) {
        check_forest(fc);
        check_forest(fp);
        CHECK(count_mask(fc, TS_VALLEY) == 0);
        CHECK(count_mask(fp, TS_RIDGE) == 0);
        /* the apex is a ridge cell of the cone and a valley cell of the pit */
        CHECK(fc->mask[40 * 81 + 40] & TS_RIDGE);
        CHECK(fp->mask[40 * 81 + 40] & TS_VALLEY);
    }
    ts_features_free(fc);
    ts_features_free(fp);
    ts_raster_free(&c);
    ts_raster_free(&p);
    ts_ctx_free(ctx);
}

/* ---- planes: no features at all ---- */
static double flat(double x, double y) { (void)x; (void)y; return 250.0; }
static double tilted(double x, double y) { return 3.0 * x - 1.5 * y + 10.0; }

static void test_planes(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster a = make_dem(ctx, 64, 48, flat), b = make_dem(ctx, 64, 48, tilted);
    ts_features *fa = run_ppa(ctx, &a, TS_PPA_BOTH), *fb = run_ppa(ctx, &b, TS_PPA_BOTH);
    CHECK(fa && fb);
    if (fa && fb) {
        CHECK(fa->n_paths == 0 && fa->n_nodes == 0 && count_mask(fa, 3) == 0);
        CHECK(fb->n_paths == 0 && fb->n_nodes == 0 && count_mask(fb, 3) == 0);
    }
    ts_features_free(fa);
    ts_features_free(fb);
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_ctx_free(ctx);
}

/* ---- nodata: never a target, never bridged ---- */
static void test_nodata_hole(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster dem = make_dem(ctx, 120, 61, ridge_straight);
    ts_features *f;
    int x, y;
    /* a hole straddling the crest, and a nodata border column */
    for (y = 20; y < 40; y++)
        for (x = 55; x < 62; x++)
            TS_PIX(&dem, x, y) = NAN;
    for (y = 0; y < 61; y++)
        TS_PIX(&dem, 0, y) = NAN;
    f = run_ppa(ctx, &dem, TS_PPA_BOTH);
    CHECK(f != NULL);
    if (f) {
        size_t i, k;
        check_forest(f);
        for (y = 0; y < 61; y++)
            for (x = 0; x < 120; x++)
                if (isnan(TS_PIX(&dem, x, y)))
                    CHECK(f->mask[y * 120 + x] == 0);
        /* no path steps across the hole */
        for (i = 0; i < f->n_paths; i++)
            for (k = 1; k < f->paths[i].count; k++) {
                const ts_feature_vertex *u = &f->verts[f->paths[i].first + k - 1],
                                        *v = &f->verts[f->paths[i].first + k];
                CHECK(!((u->x < 55 && v->x >= 62) || (v->x < 55 && u->x >= 62)));
            }
        CHECK_MSG(f->n_paths == 2, "%zu ridge paths (expected one on each side)", f->n_paths);
    }
    ts_features_free(f);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

/* ---- noise: still a forest, and thread count does not matter ---- */
static void test_noise_forest_and_threads(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster dem;
    ts_features *f1 = NULL, *f2 = NULL;
    ts_ppa_params p = ts_ppa_params_default();
    uint64_t s = 7;
    int x, y;
    ts_raster_alloc(ctx, 150, 110, &dem);
    for (y = 0; y < 110; y++)
        for (x = 0; x < 150; x++)
            TS_PIX(&dem, x, y) = (float)(100.0 * th_uniform(&s) + 20.0 * sin(x / 9.0) * cos(y / 7.0));
    p.features = TS_PPA_BOTH;
    p.min_branch_length.value = 3;
    ts_ctx_set_threads(ctx, 1);
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f1) == TS_OK);
    ts_ctx_set_threads(ctx, 3);
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f2) == TS_OK);
    if (f1 && f2) {
        check_forest(f1);
        CHECK(f1->n_paths > 10);
        CHECK(memcmp(f1->mask, f2->mask, 150 * 110) == 0);
        CHECK(f1->n_paths == f2->n_paths && f1->n_verts == f2->n_verts);
    }
    ts_features_free(f1);
    ts_features_free(f2);
    ts_raster_free(&dem);
    /* tall enough for strips of rows (64 at least, one per thread): 1 thread against 5
     * and 8 (strips contracted and joined), both kinds */
    ts_raster_alloc(ctx, 120, 700, &dem);
    for (y = 0; y < 700; y++)
        for (x = 0; x < 120; x++)
            TS_PIX(&dem, x, y) = (float)(100.0 * th_uniform(&s) + 40.0 * sin(x / 11.0) * cos(y / 13.0));
    ts_ctx_set_threads(ctx, 1);
    f1 = f2 = NULL;
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f1) == TS_OK);
    for (x = 5; x <= 8; x += 3) {
        ts_ctx_set_threads(ctx, x);
        CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f2) == TS_OK);
        if (f1 && f2) {
            size_t q;
            int same = 1;
            CHECK_MSG(memcmp(f1->mask, f2->mask, 120 * 700) == 0, "%d threads", x);
            CHECK(f1->n_paths == f2->n_paths && f1->n_verts == f2->n_verts &&
                  f1->n_nodes == f2->n_nodes);
            /* the graph too (made in strips of rows): the same nodes, paths, vertices */
            for (q = 0; same && q < f1->n_nodes && q < f2->n_nodes; q++)
                same = f1->nodes[q].x == f2->nodes[q].x && f1->nodes[q].y == f2->nodes[q].y &&
                       f1->nodes[q].degree == f2->nodes[q].degree;
            for (q = 0; same && q < f1->n_paths && q < f2->n_paths; q++)
                same = f1->paths[q].node_a == f2->paths[q].node_a &&
                       f1->paths[q].node_b == f2->paths[q].node_b &&
                       f1->paths[q].first == f2->paths[q].first &&
                       f1->paths[q].count == f2->paths[q].count &&
                       f1->paths[q].length == f2->paths[q].length;
            for (q = 0; same && q < f1->n_verts && q < f2->n_verts; q++)
                same = f1->verts[q].x == f2->verts[q].x && f1->verts[q].y == f2->verts[q].y;
            CHECK_MSG(same, "the feature graph differs on %d threads", x);
        }
        ts_features_free(f2);
        f2 = NULL;
    }
    if (f1)
        check_forest(f1);
    ts_features_free(f1);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

/* ---- branch reduction (in buckets of rows, side by side) equals the rules ---- */
/* The rules of ppa_branch.c, as plainly as they can be written: in each
 * pass every endpoint is walked to the first cell of degree != 2; isolated
 * paths shorter than the minimum go; at each junction its short branches
 * go, except the longest (one other arm) or the two longest (no other arm),
 * ranked by length then start; all of a pass's decisions are taken on the
 * forest as it was, then applied; until a pass changes nothing. */
typedef struct naive_branch {
    uint32_t start, junction;
    int64_t length;
} naive_branch;

static uint32_t naive_walk(const unsigned char *adj, int w, uint32_t start, int64_t *len)
{
    uint32_t cur = start, prev = UINT32_MAX;
    *len = 0;
    for (;;) {
        int d, x = (int)(cur % (uint32_t)w), y = (int)(cur / (uint32_t)w);
        uint32_t nxt = UINT32_MAX;
        if (cur != start && ppa_degree(adj[cur]) != 2)
            return cur;
        for (d = 0; d < 8; d++)
            if (adj[cur] & (1u << d)) {
                uint32_t c = (uint32_t)((y + ppa_dir[d][1]) * w + x + ppa_dir[d][0]);
                if (c != prev) {
                    nxt = c;
                    *len += ppa_step_q(NULL, y, d);
                    break;
                }
            }
        if (nxt == UINT32_MAX)
            return cur;
        prev = cur;
        cur = nxt;
    }
}

/* Cut the chain from start up to (not including) stop, or all of it (stop too) */
static void naive_cut(unsigned char *adj, int w, int h, uint32_t start, uint32_t stop, int whole)
{
    uint32_t cur = start, prev = UINT32_MAX;
    while (cur != stop) {
        int d, x = (int)(cur % (uint32_t)w), y = (int)(cur / (uint32_t)w);
        uint32_t nxt = UINT32_MAX;
        for (d = 0; d < 8; d++)
            if (adj[cur] & (1u << d)) {
                uint32_t c = (uint32_t)((y + ppa_dir[d][1]) * w + x + ppa_dir[d][0]);
                if (c != prev)
                    nxt = c;
            }
        /* cut every link of cur */
        for (d = 0; d < 8; d++)
            if (adj[cur] & (1u << d)) {
                int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
                if (nx >= 0 && ny >= 0 && nx < w && ny < h)
                    adj[ny * w + nx] &= (unsigned char)~(1u << ((d + 4) & 7));
            }
        adj[cur] = 0;
        if (nxt == UINT32_MAX)
            break;
        prev = cur;
        cur = nxt;
    }
    if (whole)
        adj[stop] = 0;
}

static void naive_branch_reduction(unsigned char *adj, int w, int h, int64_t min_q)
{
    size_t n = (size_t)w * (size_t)h, i, j, k, nb;
    naive_branch *br = malloc(n * sizeof *br);
    unsigned char *go = malloc(n);
    int changed = 1;
    while (changed) {
        changed = 0;
        nb = 0;
        for (i = 0; i < n; i++)
            if (ppa_degree(adj[i]) == 1) {
                br[nb].start = (uint32_t)i;
                br[nb].junction = naive_walk(adj, w, (uint32_t)i, &br[nb].length);
                nb++;
            }
        memset(go, 0, nb);
        for (i = 0; i < nb; i++) {
            int deg = ppa_degree(adj[br[i].junction]), other, rank = 0, leaves = 0;
            if (deg == 1) { /* an isolated path: judged once, whole */
                go[i] = br[i].start < br[i].junction && br[i].length < min_q ? 2 : 0;
                continue;
            }
            if (br[i].length >= min_q)
                continue;
            for (j = 0; j < nb; j++) {
                if (br[j].junction != br[i].junction)
                    continue;
                leaves++;
                if (br[j].length > br[i].length ||
                    (br[j].length == br[i].length && br[j].start < br[i].start))
                    rank++;
            }
            other = deg - leaves;
            go[i] = !((other <= 0 && rank < 2) || (other == 1 && rank == 0));
        }
        for (k = 0; k < nb; k++)
            if (go[k]) {
                naive_cut(adj, w, h, br[k].start, br[k].junction, go[k] == 2);
                changed = 1;
            }
    }
    free(br);
    free(go);
}

static void test_branch_reduction_equals_naive(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int trial;
    for (trial = 0; trial < 24; trial++) {
        uint64_t s = 500 + (uint64_t)trial;
        int w = trial % 3 == 0 ? 300 : trial % 3 == 1 ? 40 : 90;
        int h = trial % 3 == 0 ? 30 : trial % 3 == 1 ? 260 : 90, x, y, d;
        size_t n = (size_t)w * (size_t)h, i, ne = 0;
        unsigned char *adj = calloc(n, 1), *a1 = malloc(n), *a2 = malloc(n);
        uint32_t *uf = malloc(n * sizeof *uf), *order;
        struct { uint32_t a, b; int d; } *e = malloc(4 * n * sizeof *e);
        double *key = malloc(4 * n * sizeof *key);
        int64_t min_q = ppa_length_q(trial % 4 == 0 ? 3.0 : trial % 4 == 1 ? 10.0 : trial % 4 == 2 ? 25.0 : 60.0);
        double dens = trial % 2 ? 0.55 : 0.8;
        unsigned char *on = malloc(n);
        /* a random spanning forest of random cells (Kruskal on random weights, 8 neighbours) */
        for (i = 0; i < n; i++) {
            on[i] = th_uniform(&s) < dens;
            uf[i] = (uint32_t)i;
        }
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++)
                for (d = 0; d < 4; d++) {
                    int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
                    if (nx < 0 || ny < 0 || nx >= w || ny >= h || !on[y * w + x] ||
                        !on[ny * w + nx])
                        continue;
                    e[ne].a = (uint32_t)(y * w + x);
                    e[ne].b = (uint32_t)(ny * w + nx);
                    e[ne].d = d;
                    key[ne] = th_uniform(&s);
                    ne++;
                }
        order = malloc((ne + 1) * sizeof *order);
        for (i = 0; i < ne; i++)
            order[i] = (uint32_t)i;
        for (i = ne; i > 1; i--) { /* a random order is a random weight order */
            size_t r = (size_t)(th_uniform(&s) * (double)i), t;
            if (r >= i)
                r = i - 1;
            t = order[i - 1];
            order[i - 1] = order[r];
            order[r] = (uint32_t)t;
        }
        for (i = 0; i < ne; i++) {
            uint32_t ra = ppa_uf_find(uf, e[order[i]].a), rb = ppa_uf_find(uf, e[order[i]].b);
            if (ra == rb)
                continue;
            uf[ra] = rb;
            adj[e[order[i]].a] |= (unsigned char)(1u << e[order[i]].d);
            adj[e[order[i]].b] |= (unsigned char)(1u << ((e[order[i]].d + 4) & 7));
        }
        memcpy(a1, adj, n);
        naive_branch_reduction(a1, w, h, min_q);
        for (x = 1; x <= 5; x += 4) {
            size_t diff = 0, left = 0, before = 0;
            memcpy(a2, adj, n);
            ts_ctx_set_threads(ctx, x);
            CHECK(ppa_branch_reduction(ctx, w, h, a2, NULL, (double)min_q / PPA_LENGTH_SCALE) ==
                  TS_OK);
            for (i = 0; i < n; i++) {
                diff += a1[i] != a2[i];
                left += a1[i] != 0;
                before += adj[i] != 0;
            }
            CHECK_MSG(diff == 0, "trial %d (%dx%d), %d threads: %zu cells differ from the rules",
                      trial, w, h, x, diff);
            /* something removed, something kept */
            CHECK_MSG(left > 0 && left < before, "trial %d: %zu of %zu cells left", trial, left,
                      before);
        }
        free(adj);
        free(a1);
        free(a2);
        free(uf);
        free(e);
        free(key);
        free(order);
        free(on);
    }
    ts_ctx_free(ctx);
}

/* ---- profile recognition (early-exit scans) equals the definition ---- */
/* The textbook rule: along some direction, the lowest (highest) value on
 * each side within half the profile, stopping at the edge or nodata, lies
 * more than the threshold below (above) the cell. */
static unsigned char naive_profile_cell(const ts_raster *dem, int x, int y, int half, float thr,
                                        int kinds)
{
    static const int dir[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    float z = TS_PIX(dem, x, y);
    unsigned char bits = 0;
    int d, side, i;
    if (isnan(z))
        return 0;
    for (d = 0; d < 4; d++) {
        float lo[2], hi[2];
        int seen[2];
        for (side = 0; side < 2; side++) {
            int sx = side ? -dir[d][0] : dir[d][0], sy = side ? -dir[d][1] : dir[d][1];
            lo[side] = INFINITY;
            hi[side] = -INFINITY;
            seen[side] = 0;
            for (i = 1; i <= half; i++) {
                int xx = x + i * sx, yy = y + i * sy;
                if (xx < 0 || yy < 0 || xx >= dem->width || yy >= dem->height ||
                    isnan(TS_PIX(dem, xx, yy)))
                    break;
                lo[side] = fminf(lo[side], TS_PIX(dem, xx, yy));
                hi[side] = fmaxf(hi[side], TS_PIX(dem, xx, yy));
                seen[side] = 1;
            }
        }
        if (!seen[0] || !seen[1])
            continue;
        if ((kinds & TS_RIDGE) && z - lo[0] > thr && z - lo[1] > thr)
            bits |= TS_RIDGE;
        if ((kinds & TS_VALLEY) && hi[0] - z > thr && hi[1] - z > thr)
            bits |= TS_VALLEY;
    }
    return bits;
}

static void test_profile_recognition_equals_naive(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t s = 99;
    int rep;
    for (rep = 0; rep < 24; rep++) {
        int w = 20 + (int)(th_uniform(&s) * 60), h = 15 + (int)(th_uniform(&s) * 50);
        int len = 3 + 2 * (rep % 12), kinds = 1 + rep % 3, x, y, bad = 0;
        float thr = (float)(th_uniform(&s) * 30.0);
        ts_raster dem;
        unsigned char *got = malloc((size_t)w * h);
        ts_raster_alloc(ctx, w, h, &dem);
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                double v = 40.0 * sin(x / (2.0 + rep)) * cos(y / 3.0) + 25.0 * th_uniform(&s);
                TS_PIX(&dem, x, y) = th_uniform(&s) < 0.05 ? NAN : (float)v;
            }
        ts_ctx_set_threads(ctx, 1 + rep % 3);
        CHECK(ts_ppa_profile_recognition(ctx, &dem, len, thr, kinds, got) == TS_OK);
        for (y = 0; y < h && !bad; y++)
            for (x = 0; x < w; x++) {
                unsigned char want = naive_profile_cell(&dem, x, y, len / 2, thr, kinds);
                if (got[y * w + x] != want) {
                    CHECK_MSG(0, "rep %d cell (%d, %d): %u, naive %u", rep, x, y, got[y * w + x],
                              want);
                    bad = 1;
                    break;
                }
            }
        free(got);
        ts_raster_free(&dem);
    }
    ts_ctx_free(ctx);
}

/* ---- polygon breaking: Kruskal equals naive repeated polygon breaking ---- */

/* Find a cycle among the live segments with DFS; return the index of its
 * least important segment (lowest weight; on ties the later index), or -1. */
typedef struct naive_graph {
    size_t n_cells, n_segs;
    const ts_ppa_segment *segs;
    unsigned char *alive;
} naive_graph;

static int naive_dfs(const naive_graph *g, size_t v, long via, int *state, long *parent_seg,
                     size_t *parent_v, long *cycle_start, long *cycle_seg)
{
    size_t i;
    state[v] = 1;
    for (i = 0; i < g->n_segs; i++) {
        size_t u;
        if (!g->alive[i] || (long)i == via)
            continue;
        if (g->segs[i].a == v)
            u = g->segs[i].b;
        else if (g->segs[i].b == v)
            u = g->segs[i].a;
        else
            continue;
        if (state[u] == 1) {
            *cycle_start = (long)u;
            *cycle_seg = (long)i;
            parent_v[u] = parent_v[u]; /* cycle closes at u */
            (void)parent_seg;
            parent_v[v] = parent_v[v];
            /* record the closing vertex v for the walk back */
            parent_seg[g->n_cells] = (long)v;
            return 1;
        }
        if (state[u] == 0) {
            parent_seg[u] = (long)i;
            parent_v[u] = v;
            if (naive_dfs(g, u, (long)i, state, parent_seg, parent_v, cycle_start, cycle_seg))
                return 1;
        }
    }
    state[v] = 2;
    return 0;
}

static int less_important(const ts_ppa_segment *s, size_t i, size_t j)
{
    /* is i less important than j? */
    if (s[i].weight != s[j].weight)
        return s[i].weight < s[j].weight;
    return i > j;
}

static long naive_find_cycle_min(const naive_graph *g)
{
    size_t v;
    int *state = calloc(g->n_cells, sizeof *state);
    long *parent_seg = malloc((g->n_cells + 1) * sizeof *parent_seg);
    size_t *parent_v = malloc(g->n_cells * sizeof *parent_v);
    long result = -1;
    for (v = 0; v < g->n_cells && result < 0; v++) {
        long cs = -1, cseg = -1;
        if (state[v])
            continue;
        if (naive_dfs(g, v, -1, state, parent_seg, parent_v, &cs, &cseg)) {
            /* walk from the closing vertex back to the cycle start */
            size_t w = (size_t)parent_seg[g->n_cells];
            long best = cseg;
            while ((long)w != cs) {
                long sgi = parent_seg[w];
                if (less_important(g->segs, (size_t)sgi, (size_t)best))
                    best = sgi;
                w = parent_v[w];
            }
            result = best;
        }
    }
    free(state);
    free(parent_seg);
    free(parent_v);
    return result;
}

static void test_kruskal_equals_naive(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int trial;
    for (trial = 0; trial < 40; trial++) {
        uint64_t s = 1000 + (uint64_t)trial;
        int w = 6 + trial % 7 + (trial >= 30 ? 20 : 0), h = 5 + trial % 5 + (trial >= 30 ? 15 : 0);
        int x, y, kind = trial % 4 < 2 ? TS_RIDGE : TS_VALLEY;
        ts_raster dem;
        unsigned char *targets = malloc((size_t)w * h), *keep;
        ts_ppa_segment *segs = NULL;
        size_t n = 0, i;
        naive_graph g;
        long m;
        ts_raster_alloc(ctx, w, h, &dem);
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                /* quantised heights make ties, which the order must break the same way */
                TS_PIX(&dem, x, y) = (float)(int)(th_uniform(&s) * (trial % 2 ? 5 : 1000));
                targets[y * w + x] = th_uniform(&s) < (trial % 5 ? 0.75 : 0.97) ? kind : 0;
            }
        if (trial % 3 == 0)
            TS_PIX(&dem, w / 2, h / 2) = NAN, targets[(h / 2) * w + w / 2] = 0;
        CHECK(ts_ppa_target_connection(ctx, &dem, targets, kind, &segs, &n) == TS_OK);
        keep = malloc(n ? n : 1);
        CHECK(ts_ppa_polygon_breaking(ctx, segs, n, (size_t)w * h, keep) == TS_OK);
        g.n_cells = (size_t)w * h;
        g.n_segs = n;
        g.segs = segs;
        g.alive = malloc(n ? n : 1);
        memset(g.alive, 1, n);
        while ((m = naive_find_cycle_min(&g)) >= 0)
            g.alive[m] = 0;
        for (i = 0; i < n; i++)
            CHECK_MSG(g.alive[i] == keep[i], "trial %d segment %zu: naive %d kruskal %d", trial,
                      i, g.alive[i], keep[i]);
        /* the lean way (triangles' least segments left out, straight into neighbour bits,
         * on 1 to 3 threads): the naive forest's bits */
        {
            unsigned char *want = calloc((size_t)w * h, 1), *got = calloc((size_t)w * h, 1);
            int bad = 0;
            for (i = 0; i < n; i++)
                if (g.alive[i]) {
                    int dx = (int)(segs[i].b % (uint32_t)w) - (int)(segs[i].a % (uint32_t)w);
                    int dy = (int)(segs[i].b / (uint32_t)w) - (int)(segs[i].a / (uint32_t)w);
                    int d = ppa_dir_of(dx, dy);
                    want[segs[i].a] |= (unsigned char)(1u << d);
                    want[segs[i].b] |= (unsigned char)(1u << ((d + 4) & 7));
                }
            ts_ctx_set_threads(ctx, 1 + trial % 3);
            CHECK(ppa_spanning_forest(ctx, &dem, targets, kind, got) == TS_OK);
            for (i = 0; i < (size_t)w * h; i++)
                bad += want[i] != got[i];
            CHECK_MSG(bad == 0, "trial %d: the lean forest differs at %d cells", trial, bad);
            {
                /* in strips of rows, each strip's forest contracted, then joined: any
                 * number of strips, down to one row each, gives the naive forest */
                int strips[4] = {2, 3, h / 2, h}, si;
                for (si = 0; si < 4; si++) {
                    memset(got, 0, (size_t)w * h);
                    bad = 0;
                    CHECK(ppa_spanning_forest_strips(ctx, &dem, targets, kind, got,
                                                     strips[si]) == TS_OK);
                    for (i = 0; i < (size_t)w * h; i++)
                        bad += want[i] != got[i];
                    CHECK_MSG(bad == 0, "trial %d, %d strips: the forest differs at %d cells",
                              trial, strips[si], bad);
                }
            }
            free(want);
            free(got);
        }
        free(g.alive);
        free(keep);
        free(segs);
        free(targets);
        ts_raster_free(&dem);
    }
    ts_ctx_free(ctx);
}

/* ---- crossing diagonals: the lower one is dropped ---- */
static void test_drainage_area_equals_naive(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int trial;
    for (trial = 0; trial < 24; trial++) {
        uint64_t s = 7000 + (uint64_t)trial;
        int w = 5 + trial % 9 + (trial >= 18 ? 25 : 0), h = 4 + trial % 6 + (trial >= 18 ? 20 : 0);
        int x, y;
        size_t n = (size_t)w * h, c, valid = 0;
        double seeds_sum = 0;
        ts_raster dem;
        float *fast = malloc(n * sizeof *fast), *slow = malloc(n * sizeof *slow);
        ts_raster_alloc(ctx, w, h, &dem);
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                /* a valley with noise; quantised heights make flats and ties, pits fill */
                double v = fabs(x - w / 2.0) + 0.3 * y + th_uniform(&s) * (trial % 2 ? 3 : 0.2);
                /* some with a deep bowl: a lake of one level across many tiles */
                if (trial % 5 == 2)
                    v -= 12.0 * exp(-((x - w / 2.0) * (x - w / 2.0) + (y - h / 2.0) * (y - h / 2.0)) /
                                    (0.05 * w * w));
                TS_PIX(&dem, x, y) = (float)(trial % 3 == 0 ? (int)v : v);
            }
        if (trial % 4 == 1)
            TS_PIX(&dem, w / 2, h / 2) = NAN, TS_PIX(&dem, w / 3, h / 2) = NAN;
        naive_flow(&dem, slow, NULL);
        {
            /* one tile, and tiles of 2, 3, 5 and 7 cells: flats and depressions across them */
            static const int tiles[] = {1 << 20, 2, 3, 5, 7};
            int ti;
            for (ti = 0; ti < 10; ti++) {
                size_t bad = 0, first = 0;
                /* the flow kept between the phases, or each tile routed again */
                CHECK(ppa_drainage_area(ctx, &dem, fast, tiles[ti % 5], ti >= 5) == TS_OK);
                for (c = 0; c < n; c++)
                    if (!((isnan(fast[c]) && isnan(slow[c])) || fast[c] == slow[c]) && !bad++)
                        first = c;
                CHECK_MSG(bad == 0, "trial %d tile %d%s: %zu cells, first %zu: fast %g naive %g",
                          trial, tiles[ti % 5], ti >= 5 ? " (kept)" : "", bad, first, fast[first],
                          slow[first]);
            }
        }
        for (c = 0; c < n; c++)
            if (!isnan(slow[c]))
                valid++;
        /* every valid cell drains to exactly one seed: the seeds' areas add up to them all */
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++)
                if ((x == 0 || y == 0 || x == w - 1 || y == h - 1) && !isnan(TS_PIX(&dem, x, y)) &&
                    trial % 4 != 1)
                    seeds_sum += fast[(size_t)y * w + x];
        if (trial % 4 != 1)
            CHECK_MSG(seeds_sum == (double)valid, "trial %d: seeds drain %g of %zu cells", trial,
                      seeds_sum, valid);
        ts_raster_free(&dem);
        free(fast);
        free(slow);
    }
    /* the parameter at work: with every cell asked to drain more than the DEM holds, no
     * valley survives; with 0 the V valley is mapped */
    {
        ts_raster dem = make_dem(ctx, 80, 60, valley_v);
        ts_ppa_params p = ts_ppa_params_default();
        ts_features *f = NULL;
        p.features = TS_VALLEY;
        p.min_drainage = 0;
        CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f) == TS_OK);
        CHECK(count_mask(f, TS_VALLEY) > 0);
        ts_features_free(f);
        f = NULL;
        p.min_drainage = 80.0 * 60.0 + 1.0;
        CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f) == TS_OK);
        CHECK(count_mask(f, TS_VALLEY) == 0);
        ts_features_free(f);
        ts_raster_free(&dem);
    }
    ts_ctx_free(ctx);
}

/* The defaults: valleys where the water runs.  Every valley cell drains at
 * least min_drainage cells by the naive flood; the valleys' threshold is
 * 0.0001 of the range and the ridges' 0.0025 (both auto), and the ridges
 * are those of min_drainage 0; a threshold given is every kind's. */
static void test_channels_by_default(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t s = 4242;
    int w = 160, h = 140, x, y;
    ts_raster dem;
    ts_features *fc = NULL, *fp = NULL;
    ts_ppa_params p = ts_ppa_params_default();
    float *area = malloc((size_t)w * h * sizeof *area);
    size_t i, n = (size_t)w * h, valleys = 0, low = 0, ridge_diff = 0, prof_low = 0;
    ts_raster_alloc(ctx, w, h, &dem);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) /* ridges and ravines on a tilted plane, with noise */
            TS_PIX(&dem, x, y) = (float)(30.0 * sin(0.13 * x) * cos(0.09 * y) +
                                         12.0 * sin(0.31 * x + 0.2 * y) + 0.8 * y +
                                         3.0 * th_uniform(&s));
    naive_flow(&dem, area, NULL);
    CHECK(p.min_drainage == 200 && p.threshold_fraction == -1 && p.min_branch_length.value == -1);
    p.features = TS_PPA_BOTH;
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &fc) == TS_OK);
    p.min_drainage = 0;
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &fp) == TS_OK);
    if (fc && fp) {
        ts_raster_stats st;
        CHECK(ts_raster_stats_compute(ctx, &dem, &st) == TS_OK);
        for (i = 0; i < n; i++) {
            if (fc->mask[i] & TS_VALLEY) {
                valleys++;
                low += !(area[i] >= 200);
            }
            if ((fp->mask[i] & TS_VALLEY) && !(area[i] >= 200))
                prof_low++;
            ridge_diff += (fc->mask[i] & TS_RIDGE) != (fp->mask[i] & TS_RIDGE);
        }
        CHECK_MSG(valleys > 100 && low == 0, "%zu valley cells, %zu drain < 200", valleys, low);
        CHECK_MSG(prof_low > 50, "profile valleys: %zu cells drain < 200", prof_low);
        CHECK(ridge_diff == 0);
        CHECK(fabs(fc->threshold_used - 0.0025 * (st.max - st.min)) < 1e-6 * (st.max - st.min));
        CHECK(fabs(fc->threshold_used_valleys - 0.0001 * (st.max - st.min)) <
              1e-6 * (st.max - st.min));
        CHECK(fp->threshold_used_valleys == fp->threshold_used);
    }
    ts_features_free(fc);
    ts_features_free(fp);
    fc = NULL;
    p = ts_ppa_params_default();
    p.features = TS_PPA_BOTH;
    p.threshold_fraction = 0.01;
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &fc) == TS_OK);
    CHECK(fc && fc->threshold_used == fc->threshold_used_valleys);
    ts_features_free(fc);
    /* on 8 threads and more the drainage runs in tiles of 1024 side by side: the same
     * valleys as on one thread (one tile) */
    {
        ts_raster big;
        ts_features *f1 = NULL, *f8 = NULL;
        int bw = 1300, bh = 1100;
        ts_raster_alloc(ctx, bw, bh, &big);
        for (y = 0; y < bh; y++)
            for (x = 0; x < bw; x++)
                TS_PIX(&big, x, y) = (float)(30.0 * sin(0.013 * x) * cos(0.011 * y) +
                                             12.0 * sin(0.05 * x + 0.03 * y) + 0.02 * y +
                                             (float)(int)(4.0 * th_uniform(&s)));
        p = ts_ppa_params_default();
        p.features = TS_PPA_VALLEYS;
        ts_ctx_set_threads(ctx, 1);
        CHECK(ts_ppa_extract(ctx, &big, NULL, &p, &f1) == TS_OK);
        ts_ctx_set_threads(ctx, 8);
        CHECK(ts_ppa_extract(ctx, &big, NULL, &p, &f8) == TS_OK);
        CHECK(f1 && f8 && count_mask(f1, TS_VALLEY) > 1000 &&
              memcmp(f1->mask, f8->mask, (size_t)bw * bh) == 0);
        ts_features_free(f1);
        ts_features_free(f8);
        ts_raster_free(&big);
        ts_ctx_set_threads(ctx, 0);
        p = ts_ppa_params_default();
    }
    p.threshold_fraction = -0.5; /* -1 is auto; other negatives are no value */
    CHECK(ts_params_validate(ctx, "ppa", &p) == TS_ERR_ARG);
    CHECK(ts_params_set(ctx, "ppa", &p, "threshold_fraction", "-1") == TS_OK);
    CHECK(ts_params_set(ctx, "ppa", &p, "min_branch_length", "-1m") == TS_ERR_ARG);
    ts_raster_free(&dem);
    free(area);
    ts_ctx_free(ctx);
}

/* The tiled run reads windows of a DEM held here and writes codes back. */
typedef struct tiled_io {
    const ts_raster *dem;
    unsigned char *codes;
    int reads, writes;
} tiled_io;

static ts_status tiled_read(void *user, int x0, int y0, int w, int h, float *buf)
{
    tiled_io *io = user;
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            buf[(size_t)y * w + x] = TS_PIX(io->dem, x0 + x, y0 + y);
    io->reads++;
    return TS_OK;
}

static ts_status tiled_write(void *user, int x0, int y0, int w, int h, const unsigned char *b)
{
    tiled_io *io = user;
    int y;
    for (y = 0; y < h; y++)
        memcpy(io->codes + (size_t)(y0 + y) * io->dem->width + x0, b + (size_t)y * w, (size_t)w);
    io->writes++;
    return TS_OK;
}

static void test_tiled_equals_whole(void)
{
    ts_ctx *ctx = ts_ctx_new();
    static const int tiles[] = {16, 23, 41, 64, 1000};
    int trial;
    for (trial = 0; trial < 6; trial++) {
        uint64_t s = 900 + (uint64_t)trial;
        int w = 150 + 17 * trial, h = 130 + 9 * trial, x, y, ti;
        double *dx = malloc((size_t)h * sizeof *dx), *dy = malloc((size_t)h * sizeof *dy);
        ts_grid_metrics m;
        ts_ppa_params p = ts_ppa_params_default();
        ts_raster dem;
        ts_features *f = NULL;
        unsigned char *whole = malloc((size_t)w * h), *codes = malloc((size_t)w * h);
        double ph = th_uniform(&s) * 6.0;
        ts_raster_alloc(ctx, w, h, &dem);
        for (y = 0; y < h; y++) {
            dx[y] = 30.0 * cos((40.0 + 0.05 * y) * 3.14159265358979 / 180.0); /* narrowing rows */
            dy[y] = 30.0;
            for (x = 0; x < w; x++)
                TS_PIX(&dem, x, y) =
                    (float)(40.0 * sin(0.11 * x + ph) * cos(0.07 * y) + 25.0 * sin(0.23 * (x + y)) +
                            (trial % 2 ? 8.0 : 2.0) * th_uniform(&s) +
                            (trial == 4 ? 0.0 : 0.2 * x));
        }
        if (trial % 3 == 1) /* a nodata hole across tile borders */
            for (y = h / 3; y < h / 3 + 20; y++)
                for (x = w / 3; x < w / 3 + 30; x++)
                    TS_PIX(&dem, x, y) = NAN;
        m.dx = dx;
        m.dy = dy;
        p.features = trial % 3 == 0 ? TS_PPA_BOTH : trial % 3 == 1 ? TS_PPA_RIDGES : TS_PPA_VALLEYS;
        p.min_branch_length.value = trial < 3 ? 12 : 400;
        p.min_branch_length.unit = trial < 3 ? TS_UNIT_CELLS : TS_UNIT_METRES;
        if (trial == 5)
            p.profile_length = 21, p.threshold_fraction = 0.01;
        CHECK(ts_ppa_extract(ctx, &dem, &m, &p, &f) == TS_OK);
        CHECK(ts_features_codes(ctx, f, &dem, whole) == TS_OK);
        for (ti = 0; ti < (int)(sizeof tiles / sizeof tiles[0]); ti++) {
            tiled_io io = {&dem, codes, 0, 0};
            size_t i, diff = 0;
            memset(codes, 77, (size_t)w * h);
            CHECK_MSG(ts_ppa_extract_tiled(ctx, w, h, &m, &p, tiles[ti], tiled_read, tiled_write,
                                           &io, NULL) == TS_OK,
                      "%s", ts_ctx_message(ctx));
            for (i = 0; i < (size_t)w * h; i++)
                diff += codes[i] != whole[i];
            CHECK_MSG(diff == 0, "trial %d tile %d: %zu of %d cells differ", trial, tiles[ti], diff,
                      w * h);
            CHECK(io.writes ==
                  ((w + tiles[ti] - 1) / tiles[ti]) * ((h + tiles[ti] - 1) / tiles[ti]));
        }
        {
            size_t i, feat = 0;
            for (i = 0; i < (size_t)w * h; i++)
                feat += whole[i] != 0 && whole[i] != 255;
            CHECK_MSG(feat > (size_t)(w + h), "trial %d: only %zu axis cells", trial, feat);
        }
        ts_features_free(f);
        ts_raster_free(&dem);
        free(dx);
        free(dy);
        free(whole);
        free(codes);
    }
    /* refused: a tile too small */
    {
        ts_ppa_params p = ts_ppa_params_default();
        ts_raster dem = make_dem(ctx, 40, 40, valley_v);
        unsigned char codes[1600];
        tiled_io io = {&dem, codes, 0, 0};
        p.features = TS_PPA_VALLEYS;
        CHECK(ts_ppa_extract_tiled(ctx, 40, 40, NULL, &p, 8, tiled_read, tiled_write, &io, NULL) ==
              TS_ERR_ARG);
        ts_raster_free(&dem);
    }
    ts_ctx_free(ctx);
}

static void test_crossing_diagonals(void)
{
    ts_ctx *ctx = ts_ctx_new();
    float v[4] = {10, 1, 2, 9}; /* (0,0)=10 (1,0)=1 (0,1)=2 (1,1)=9 */
    ts_raster dem = ts_raster_wrap(v, 2, 2, 2);
    unsigned char t[4] = {TS_RIDGE, TS_RIDGE, TS_RIDGE, TS_RIDGE};
    ts_ppa_segment *segs = NULL;
    size_t n = 0, i;
    int has_se = 0, has_sw = 0;
    CHECK(ts_ppa_target_connection(ctx, &dem, t, TS_RIDGE, &segs, &n) == TS_OK);
    CHECK(n == 5); /* 4 sides + 1 diagonal */
    for (i = 0; i < n; i++) {
        if (segs[i].a == 0 && segs[i].b == 3) has_se = 1;
        if (segs[i].a == 1 && segs[i].b == 2) has_sw = 1;
    }
    CHECK(has_se && !has_sw);
    free(segs);
    ts_ctx_free(ctx);
}

/* ---- errors, cancel, parameters ---- */
static double cancel_point = 0.5;

static int cancel_at_half(double done, const char *msg, void *user)
{
    (void)msg;
    (*(int *)user)++;
    return done < cancel_point;
}

static void test_errors_and_cancel(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster dem = make_dem(ctx, 120, 61, ridge_straight), allnan;
    ts_ppa_params p = ts_ppa_params_default();
    ts_features *f = NULL;
    int calls = 0;
    float one = 1.0f;
    ts_raster tiny = ts_raster_wrap(&one, 1, 1, 1);
    /* metres without metrics */
    CHECK(ts_params_set(ctx, "ppa", &p, "min_branch_length", "600m") == TS_OK);
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f) == TS_ERR_ARG && f == NULL);
    CHECK(strstr(ts_ctx_message(ctx), "metres") != NULL);
    p = ts_ppa_params_default();
    /* parameter parsing and ranges */
    CHECK(ts_params_set(ctx, "ppa", &p, "profile_length", "8") == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "odd") != NULL);
    CHECK(ts_params_set(ctx, "ppa", &p, "profile-length", "13") == TS_OK && p.profile_length == 13);
    CHECK(ts_params_set(ctx, "ppa", &p, "threshold", "-1") == TS_ERR_ARG);
    CHECK(ts_params_set(ctx, "ppa", &p, "threshold", "abc") == TS_ERR_ARG);
    CHECK(ts_params_set(ctx, "ppa", &p, "threshold", "nan") == TS_ERR_ARG);
    CHECK(ts_params_set(ctx, "ppa", &p, "features", "valleys") == TS_OK && p.features == TS_PPA_VALLEYS);
    CHECK(ts_params_set(ctx, "ppa", &p, "features", "lakes") == TS_ERR_ARG);
    CHECK(ts_params_set(ctx, "ppa", &p, "bogus", "1") == TS_ERR_ARG);
    CHECK(ts_params_set(ctx, "ppa", &p, "min_branch_length", "12 furlongs") == TS_ERR_ARG);
    p.profile_length = 4;
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f) == TS_ERR_ARG);
    p = ts_ppa_params_default();
    /* too small, all nodata */
    CHECK(ts_ppa_extract(ctx, &tiny, NULL, &p, &f) == TS_ERR_SIZE);
    ts_raster_alloc(ctx, 10, 10, &allnan);
    CHECK(ts_ppa_extract(ctx, &allnan, NULL, &p, &f) == TS_ERR_NUMERIC);
    CHECK(strstr(ts_ctx_message(ctx), "nodata") != NULL);
    /* cancel */
    ts_ctx_set_progress(ctx, cancel_at_half, &calls);
    p.features = TS_PPA_BOTH;
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f) == TS_ERR_CANCELLED && f == NULL);
    CHECK(calls > 0);
    /* cancelling at any stage frees everything (the sanitizer build checks leaks) */
    {
        static const double points[] = {0.01, 0.2, 0.31, 0.45, 0.66, 0.8, 0.97, 1.0};
        size_t i;
        for (i = 0; i < sizeof points / sizeof points[0]; i++) {
            cancel_point = points[i];
            CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f) == TS_ERR_CANCELLED && f == NULL);
            CHECK(strstr(ts_ctx_message(ctx), "cancel") != NULL);
        }
    }
    ts_raster_free(&allnan);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

/* ---- ground metrics: branch length in metres ---- */
static void test_metric_branch_length(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster dem = make_dem(ctx, 120, 61, ridge_straight);
    double dx[61], dy[61];
    ts_grid_metrics m = {dx, dy};
    ts_ppa_params p = ts_ppa_params_default();
    ts_features *f = NULL;
    int y;
    for (y = 0; y < 61; y++)
        dx[y] = 30.0, dy[y] = 30.0;
    /* 119 steps of 30 m: the ridge (3570 m) survives 3000 m, not 4000 m */
    CHECK(ts_params_set(ctx, "ppa", &p, "min_branch_length", "3000m") == TS_OK);
    CHECK(ts_ppa_extract(ctx, &dem, &m, &p, &f) == TS_OK);
    CHECK(f && f->n_paths == 1);
    if (f && f->n_paths == 1)
        CHECK_NEAR(f->paths[0].length, 30.0 * (f->paths[0].count - 1), 30.0 * 3);
    ts_features_free(f);
    f = NULL;
    CHECK(ts_params_set(ctx, "ppa", &p, "min_branch_length", "4000m") == TS_OK);
    CHECK(ts_ppa_extract(ctx, &dem, &m, &p, &f) == TS_OK);
    CHECK(f && f->n_paths == 0);
    ts_features_free(f);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"straight_ridge", test_straight_ridge},
        {"y_ridge", test_y_ridge},
        {"v_valley", test_v_valley},
        {"cone_and_pit", test_cone_and_pit},
        {"planes", test_planes},
        {"nodata_hole", test_nodata_hole},
        {"noise_forest_and_threads", test_noise_forest_and_threads},
        {"kruskal_equals_naive", test_kruskal_equals_naive},
        {"branch_reduction_equals_naive", test_branch_reduction_equals_naive},
        {"profile_recognition_equals_naive", test_profile_recognition_equals_naive},
        {"drainage_area_equals_naive", test_drainage_area_equals_naive},
        {"channels_by_default", test_channels_by_default},
        {"tiled_equals_whole", test_tiled_equals_whole},
        {"crossing_diagonals", test_crossing_diagonals},
        {"errors_and_cancel", test_errors_and_cancel},
        {"metric_branch_length", test_metric_branch_length},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
