/*
 * feature_tree.c - the feature tree of Zhou et al. 2007 section 4: the
 * patch sites of a PPA feature graph, each with its control points, in
 * breadth-first order from a root (a branch point where there is one), or
 * in raster order (for the comparison of Fig. 8).
 *
 * Sites: a branch point (degree d) with d + 1 control points (the point and
 * where each outgoing path crosses the patch's inscribed circle); an
 * endpoint with 2; path sites every `path_step` cells along each chain,
 * away from its ends, with P0 (the chain point), P1 and P2 (the crossings
 * of the circle).  Control points are relative to the site's centre.
 * Cost: O(feature cells).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "feature_tree.h"

typedef struct site_buf {
    ts_feature_site *s;
    size_t n, cap;
} site_buf;

static ts_feature_site *tree_push(site_buf *b)
{
    if (b->n == b->cap) {
        size_t nc = b->cap ? 2 * b->cap : 64;
        ts_feature_site *ns = realloc(b->s, nc * sizeof *ns);
        if (!ns)
            return NULL;
        b->s = ns;
        b->cap = nc;
    }
    memset(&b->s[b->n], 0, sizeof b->s[b->n]);
    return &b->s[b->n++];
}

/* Vertex k of path p, walking from its node_a end (dir 0) or node_b end (dir 1). */
static const ts_feature_vertex *tree_vertex(const ts_features *f, const ts_feature_path *p,
                                            size_t k, int from_b)
{
    return &f->verts[p->first + (from_b ? p->count - 1 - k : k)];
}

/* Walk path p from vertex index k0 (in the walking direction from_b) until
 * the distance to the centre reaches r; returns the control point. */
static void tree_cross(const ts_features *f, const ts_feature_path *p, size_t k0, int from_b,
                       double cx, double cy, double r, double *px, double *py)
{
    size_t k;
    const ts_feature_vertex *v = tree_vertex(f, p, k0, from_b);
    for (k = k0; k < p->count; k++) {
        v = tree_vertex(f, p, k, from_b);
        if (hypot(v->x - cx, v->y - cy) >= r)
            break;
    }
    *px = v->x - cx;
    *py = v->y - cy;
}

static int tree_arm_cmp(const void *a, const void *b)
{
    double x = ((const double *)a)[0], y = ((const double *)b)[0];
    return (x > y) - (x < y);
}

/* A node site: centre + one control point per incident path, by angle. */
static ts_status tree_node_site(const ts_features *f, size_t node, double r, site_buf *b)
{
    const ts_feature_node *nd = &f->nodes[node];
    double arms[TS_SITE_MAX_ARMS][3]; /* angle, x, y */
    int n = 0, i;
    size_t k;
    ts_feature_site *s;
    for (k = 0; k < f->n_paths && n < TS_SITE_MAX_ARMS; k++) {
        const ts_feature_path *p = &f->paths[k];
        double px, py;
        if (p->node_a != node && p->node_b != node)
            continue;
        if (p->node_a == node) {
            tree_cross(f, p, 0, 0, nd->x, nd->y, r, &px, &py);
            arms[n][1] = px;
            arms[n][2] = py;
            arms[n][0] = atan2(py, px);
            n++;
        }
        if (p->node_b == node && n < TS_SITE_MAX_ARMS) {
            tree_cross(f, p, 0, 1, nd->x, nd->y, r, &px, &py);
            arms[n][1] = px;
            arms[n][2] = py;
            arms[n][0] = atan2(py, px);
            n++;
        }
    }
    if (n == 0)
        return TS_OK;
    qsort(arms, (size_t)n, sizeof arms[0], tree_arm_cmp);
    if (!(s = tree_push(b)))
        return TS_ERR_NOMEM;
    s->type = n >= 3 ? TS_SITE_BRANCH : TS_SITE_ENDPOINT;
    if (n == 2)
        s->type = TS_SITE_PATH; /* a degree-2 node: only happens on odd graphs */
    s->degree = n;
    s->kind = nd->kind;
    s->cx = nd->x;
    s->cy = nd->y;
    s->node = (long)node;
    s->path = -1;
    s->n_ctrl = n + 1;
    s->px[0] = s->py[0] = 0.0;
    for (i = 0; i < n; i++) {
        s->px[i + 1] = arms[i][1];
        s->py[i + 1] = arms[i][2];
    }
    return TS_OK;
}

/* Path sites along p every `step` cells of chain, at least r from both ends. */
static ts_status tree_path_sites(const ts_features *f, size_t path, double r, double step,
                                 site_buf *b)
{
    const ts_feature_path *p = &f->paths[path];
    double along = 0.0, next = r;
    size_t k;
    double total = 0.0;
    for (k = 1; k < p->count; k++) {
        const ts_feature_vertex *u = &f->verts[p->first + k - 1], *v = &f->verts[p->first + k];
        total += hypot(v->x - u->x, v->y - u->y);
    }
    if (total < 2.0 * r)
        return TS_OK;
    for (k = 1; k < p->count; k++) {
        const ts_feature_vertex *u = &f->verts[p->first + k - 1], *v = &f->verts[p->first + k];
        ts_feature_site *s;
        double x1, y1, x2, y2;
        along += hypot(v->x - u->x, v->y - u->y);
        if (along < next || along > total - r)
            continue;
        next = along + step;
        tree_cross(f, p, p->count - 1 - k, 1, v->x, v->y, r, &x1, &y1); /* backwards */
        tree_cross(f, p, k, 0, v->x, v->y, r, &x2, &y2);                /* forwards */
        if (!(s = tree_push(b)))
            return TS_ERR_NOMEM;
        s->type = TS_SITE_PATH;
        s->degree = 2;
        s->kind = p->kind;
        s->cx = v->x;
        s->cy = v->y;
        s->node = -1;
        s->path = (long)path;
        s->n_ctrl = 3;
        s->px[0] = s->py[0] = 0.0;
        s->px[1] = x1;
        s->py[1] = y1;
        s->px[2] = x2;
        s->py[2] = y2;
    }
    return TS_OK;
}

static int tree_raster_cmp(const void *a, const void *b)
{
    const ts_feature_site *p = a, *q = b;
    if (p->cy != q->cy)
        return p->cy < q->cy ? -1 : 1;
    return (p->cx > q->cx) - (p->cx < q->cx);
}

ts_status ts__feature_sites(ts_ctx *ctx, const ts_features *f, int kind, double radius,
                            double path_step, int breadth_first, ts_feature_site **sites,
                            size_t *n_sites)
{
    site_buf b = {NULL, 0, 0};
    unsigned char *node_done = NULL, *path_done = NULL;
    size_t *queue = NULL, qh = 0, qt = 0, i, k;
    ts_status st = TS_OK;
    *sites = NULL;
    *n_sites = 0;
    if (!f || !(radius > 0) || !(path_step > 0))
        return ts__fail(ctx, TS_ERR_ARG, "feature tree", "missing features or bad radius/step");
    node_done = ts__calloc_array(f->n_nodes + 1, 1);
    path_done = ts__calloc_array(f->n_paths + 1, 1);
    queue = ts__malloc_array(f->n_nodes + 1, sizeof *queue);
    if (!node_done || !path_done || !queue) {
        st = TS_ERR_NOMEM;
        goto done;
    }
    /* one tree per component: roots are branch points first (highest
     * degree, then lowest index), then endpoints */
    for (;;) {
        long root = -1;
        for (i = 0; i < f->n_nodes; i++) {
            if (node_done[i] || !(f->nodes[i].kind & kind))
                continue;
            if (root < 0 || f->nodes[i].degree > f->nodes[root].degree)
                root = (long)i;
        }
        if (root < 0)
            break;
        node_done[root] = 1;
        queue[qt++] = (size_t)root;
        while (qh < qt) {
            size_t nd = queue[qh++];
            if ((st = tree_node_site(f, nd, radius, &b)) != TS_OK)
                goto done;
            for (k = 0; k < f->n_paths; k++) {
                const ts_feature_path *p = &f->paths[k];
                size_t other;
                if (path_done[k] || !(p->kind & kind) || (p->node_a != nd && p->node_b != nd))
                    continue;
                path_done[k] = 1;
                {
                    /* chains are laid outward from the node already placed */
                    size_t first = b.n, lo, hi;
                    if ((st = tree_path_sites(f, k, radius, path_step, &b)) != TS_OK)
                        goto done;
                    if (p->node_b == nd && p->node_a != nd)
                        for (lo = first, hi = b.n; lo + 1 < hi; lo++, hi--) {
                            ts_feature_site t = b.s[lo];
                            b.s[lo] = b.s[hi - 1];
                            b.s[hi - 1] = t;
                        }
                }
                other = p->node_a == nd ? p->node_b : p->node_a;
                if (!node_done[other]) {
                    node_done[other] = 1;
                    queue[qt++] = other;
                }
            }
        }
    }
    if (!breadth_first && b.n)
        qsort(b.s, b.n, sizeof *b.s, tree_raster_cmp);
done:
    free(node_done);
    free(path_done);
    free(queue);
    if (st != TS_OK) {
        free(b.s);
        return ts__fail(ctx, st, "feature tree", "out of memory");
    }
    *sites = b.s;
    *n_sites = b.n;
    return TS_OK;
}

int ts__feature_arm(int arms, int i, int rot, int mirror)
{
    if (i == 0)
        return 0;
    /* mirrored exemplars (y flipped) run their arms the other way round */
    return 1 + (mirror ? (2 * arms - (i - 1) - rot) % arms : (i - 1 + rot) % arms);
}
