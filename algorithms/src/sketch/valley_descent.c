/*
 * valley_descent.c - valley floors that descend to their outlets along the
 * sketch's feature graph (a TerraSynth addition, used by layout.c): the
 * mean of filling and carving the floor levels path by path.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "layout.h"

/*
 * Valley floors that descend (no valley climbs over a saddle), on the
 * sketch's feature graph: in every connected network, the outlet is the
 * endpoint nearest where water leaves it: the grid's edge, or, within a
 * patch, another network it runs into (a side valley drawn short of its
 * trunk); ties: the lowest; a network without endpoints takes its node
 * nearest the edge.  Breadth first from the outlet over
 * the nodes, every path runs from the node reached first (downstream) to
 * the other.  `fill` walks each path upstream raising every vertex to the
 * level below it, `carve` walks it downstream lowering every vertex to the
 * level above it (a node takes the lowest of the paths that reach it from
 * upstream); both never rise downstream, and neither does their mean,
 * which replaces level[] on the paths' cells.  Other cells are left as
 * they are.  O(vertices).
 */
/* The valley networks: comp[node] (-1 for other kinds), and net[cell]
 * the network of the valley path through the cell (-1 none). */
static ts_status descent_networks(ts_ctx *ctx, const ts_layout_spec *s, int32_t **net,
                                  int32_t **comp)
{
    const ts_features *f = s->features;
    size_t nn = f->n_nodes, i, k, n = (size_t)s->width * (size_t)s->height;
    int32_t c = 0;
    int changed = 1;
    *net = ts__malloc_array(n, sizeof(int32_t));
    *comp = ts__malloc_array(nn + 1, sizeof(int32_t));
    if (!*net || !*comp)
        return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
    for (i = 0; i < nn; i++)
        (*comp)[i] = f->nodes[i].kind == TS_VALLEY ? c++ : -1;
    /* joined along valley paths: the least label of a network wins */
    while (changed) {
        changed = 0;
        for (k = 0; k < f->n_paths; k++) {
            const ts_feature_path *p = &f->paths[k];
            int32_t a, b;
            if (p->kind != TS_VALLEY || p->node_a >= nn || p->node_b >= nn)
                continue;
            a = (*comp)[p->node_a];
            b = (*comp)[p->node_b];
            if (a >= 0 && b >= 0 && a != b) {
                (*comp)[p->node_a] = (*comp)[p->node_b] = TS_MIN(a, b);
                changed = 1;
            }
        }
    }
    for (i = 0; i < n; i++)
        (*net)[i] = -1;
    for (k = 0; k < f->n_paths; k++) {
        const ts_feature_path *p = &f->paths[k];
        size_t j;
        if (p->kind != TS_VALLEY || p->node_a >= nn)
            continue;
        for (j = 0; j < p->count; j++) {
            const ts_feature_vertex *v = &f->verts[p->first + j];
            if (v->x >= 0 && v->y >= 0 && v->x < s->width && v->y < s->height)
                (*net)[(size_t)v->y * (size_t)s->width + (size_t)v->x] = (*comp)[p->node_a];
        }
    }
    return TS_OK;
}

/* The distance (cells, rounded down) from (x, y) to the nearest cell of a
 * valley network other than `own`, within a patch; INT_MAX beyond. */
static int descent_other(const ts_layout_spec *s, const int32_t *net, int32_t own, int x, int y)
{
    int r = s->patch, u, v, best = INT_MAX;
    for (v = TS_MAX(0, y - r); v <= TS_MIN(s->height - 1, y + r); v++)
        for (u = TS_MAX(0, x - r); u <= TS_MIN(s->width - 1, x + r); u++) {
            int32_t c = net[(size_t)v * (size_t)s->width + (size_t)u];
            if (c >= 0 && c != own) {
                int d = (int)hypot(u - x, v - y);
                if (d <= r && d < best)
                    best = d;
            }
        }
    return best;
}

/* What the descent of every network shares: the graph, the levels, the
 * networks (descent_networks) and the work arrays: order, a network's
 * nodes; qpath, its paths in the order reached from the outlet; down, per
 * path its downstream node (-1 unused); nfill, ncarve per node and vfill,
 * vcarve per vertex, the filled and carved levels. */
typedef struct descent_work {
    const ts_layout_spec *s;
    const ts_features *f;
    float *level;
    size_t nn, np;
    size_t *order, *qpath;
    long *down;
    double *nfill, *ncarve, *vfill, *vcarve;
    unsigned char *seen;
    int32_t *net, *comp;
} descent_work;

/* Is path p a valley path the descent uses (two cells at least, both nodes
 * on the graph)? */
static int descent_used(const ts_feature_path *p, size_t nn)
{
    return p->kind == TS_VALLEY && p->count >= 2 && p->node_a < nn && p->node_b < nn;
}

/* The cell of vertex v. */
static size_t descent_cell(const descent_work *dw, const ts_feature_vertex *v)
{
    return (size_t)v->y * (size_t)dw->s->width + (size_t)v->x;
}

/* The distance (cells) from node nd to the grid's nearest edge. */
static int descent_border(const descent_work *dw, const ts_feature_node *nd)
{
    int W = dw->s->width, H = dw->s->height;
    return TS_MIN(TS_MIN(nd->x, W - 1 - nd->x), TS_MIN(nd->y, H - 1 - nd->y));
}

/* The network of node i (nodes only through used paths) into order[],
 * marked seen; returns how many nodes it has. */
static size_t descent_network(descent_work *dw, size_t i)
{
    const ts_features *f = dw->f;
    size_t *order = dw->order, head, tail = 0, k;
    order[tail++] = i;
    dw->seen[i] = 1;
    for (head = 0; head < tail; head++)
        for (k = 0; k < dw->np; k++) {
            const ts_feature_path *p = &f->paths[k];
            size_t o;
            if (!descent_used(p, dw->nn) || (p->node_a != order[head] && p->node_b != order[head]))
                continue;
            o = p->node_a == order[head] ? p->node_b : p->node_a;
            if (!dw->seen[o]) {
                dw->seen[o] = 1;
                order[tail++] = o;
            }
        }
    return tail;
}

/* The outlet of the network's comp_end nodes in order[]: an endpoint
 * before any other node, then the nearest the grid's edge (an endpoint:
 * or another network within a patch), then the lowest. */
static size_t descent_outlet(const descent_work *dw, size_t comp_end)
{
    const ts_features *f = dw->f;
    const float *level = dw->level;
    int W = dw->s->width, bd = 0, best_end = 0;
    size_t best = dw->nn, head;
    for (head = 0; head < comp_end; head++) {
        const ts_feature_node *nd = &f->nodes[dw->order[head]];
        int d = descent_border(dw, nd), end = nd->degree == 1;
        if (end)
            d = TS_MIN(d, descent_other(dw->s, dw->net, dw->comp[dw->order[head]], nd->x, nd->y));
        float lv = level[(size_t)nd->y * (size_t)W + (size_t)nd->x];
        if (best == dw->nn || end > best_end ||
            (end == best_end &&
             (d < bd ||
              (d == bd &&
               lv < level[(size_t)f->nodes[best].y * (size_t)W + (size_t)f->nodes[best].x])))) {
            best = dw->order[head];
            bd = d;
            best_end = end;
        }
    }
    return best;
}

/* Breadth first from the outlet over the network's comp_end nodes: paths
 * point downstream (down[]), qpath lists them in the order reached and
 * order[] the nodes reached (*tail of them); returns how many paths. */
static size_t descent_orient(descent_work *dw, size_t best, size_t comp_end, size_t *tail)
{
    const ts_features *f = dw->f;
    size_t *order = dw->order, head, k, n_q = 0;
    for (head = 0; head < comp_end; head++)
        dw->seen[order[head]] = 2;
    *tail = 0;
    order[(*tail)++] = best;
    dw->seen[best] = 3;
    for (head = 0; head < *tail; head++)
        for (k = 0; k < dw->np; k++) {
            const ts_feature_path *p = &f->paths[k];
            size_t o;
            if (!descent_used(p, dw->nn) || dw->down[k] >= 0 ||
                (p->node_a != order[head] && p->node_b != order[head]))
                continue;
            dw->down[k] = (long)order[head];
            dw->qpath[n_q++] = k;
            o = p->node_a == order[head] ? p->node_b : p->node_a;
            if (dw->seen[o] != 3) {
                dw->seen[o] = 3;
                order[(*tail)++] = o;
            }
        }
    return n_q;
}

/* fill: paths in the order reached, each walked upstream, every vertex
 * raised to the level below it. */
static void descent_fill(descent_work *dw, size_t best, size_t tail, size_t n_q)
{
    const ts_features *f = dw->f;
    const float *level = dw->level;
    int W = dw->s->width;
    size_t head, k;
    for (head = 0; head < tail; head++) {
        const ts_feature_node *nd = &f->nodes[dw->order[head]];
        dw->nfill[dw->order[head]] = -INFINITY;
        dw->ncarve[dw->order[head]] = level[(size_t)nd->y * (size_t)W + (size_t)nd->x];
    }
    dw->nfill[best] = level[(size_t)f->nodes[best].y * (size_t)W + (size_t)f->nodes[best].x];
    for (k = 0; k < n_q; k++) {
        const ts_feature_path *p = &f->paths[dw->qpath[k]];
        int from_b = (size_t)dw->down[dw->qpath[k]] == p->node_b;
        size_t up = from_b ? p->node_a : p->node_b, j;
        double prev = dw->nfill[dw->down[dw->qpath[k]]];
        for (j = 0; j < p->count; j++) {
            size_t vi = p->first + (from_b ? p->count - 1 - j : j);
            double lv = level[descent_cell(dw, &f->verts[vi])];
            prev = isnan(lv) ? prev : fmax(prev, lv);
            dw->vfill[vi] = prev;
        }
        dw->nfill[up] = fmax(dw->nfill[up], prev);
    }
}

/* carve: paths in the reverse order, each walked downstream, every vertex
 * lowered to the level above it. */
static void descent_carve(descent_work *dw, size_t n_q)
{
    const ts_features *f = dw->f;
    size_t k;
    for (k = n_q; k-- > 0;) {
        const ts_feature_path *p = &f->paths[dw->qpath[k]];
        int from_b = (size_t)dw->down[dw->qpath[k]] == p->node_b;
        size_t up = from_b ? p->node_a : p->node_b, j;
        double prev = dw->ncarve[up];
        for (j = 0; j < p->count; j++) {
            size_t vi = p->first + (from_b ? j : p->count - 1 - j);
            double lv = dw->level[descent_cell(dw, &f->verts[vi])];
            prev = isnan(lv) ? prev : fmin(prev, lv);
            dw->vcarve[vi] = prev;
        }
        dw->ncarve[dw->down[dw->qpath[k]]] = fmin(dw->ncarve[dw->down[dw->qpath[k]]], prev);
    }
}

/* The paths' cells take the mean of fill and carve; a node's cell its own. */
static void descent_mean(descent_work *dw, size_t tail, size_t n_q)
{
    const ts_features *f = dw->f;
    float *level = dw->level;
    int W = dw->s->width;
    size_t head, k;
    for (k = 0; k < n_q; k++) {
        const ts_feature_path *p = &f->paths[dw->qpath[k]];
        size_t j;
        for (j = 1; j + 1 < p->count; j++) {
            size_t vi = p->first + j;
            size_t c = descent_cell(dw, &f->verts[vi]);
            if (!isnan(level[c]))
                level[c] = (float)(0.5 * (dw->vfill[vi] + dw->vcarve[vi]));
        }
    }
    for (head = 0; head < tail; head++) {
        const ts_feature_node *nd = &f->nodes[dw->order[head]];
        size_t c = (size_t)nd->y * (size_t)W + (size_t)nd->x;
        if (!isnan(level[c]) && isfinite(dw->nfill[dw->order[head]]))
            level[c] = (float)(0.5 * (dw->nfill[dw->order[head]] + dw->ncarve[dw->order[head]]));
    }
}

ts_status ts__valley_descend(ts_ctx *ctx, const ts_layout_spec *s, float *level)
{
    const ts_features *f = s->features;
    size_t nn, np, i, k;
    descent_work dw;
    ts_status st = TS_OK;
    if (!f || !f->n_paths)
        return TS_OK;
    nn = f->n_nodes;
    np = f->n_paths;
    memset(&dw, 0, sizeof dw);
    dw.s = s;
    dw.f = f;
    dw.level = level;
    dw.nn = nn;
    dw.np = np;
    dw.order = ts__malloc_array(nn + 1, sizeof *dw.order);
    dw.qpath = ts__malloc_array(np + 1, sizeof *dw.qpath);
    dw.down = ts__malloc_array(np + 1, sizeof *dw.down);
    dw.nfill = ts__malloc_array(nn + 1, sizeof *dw.nfill);
    dw.ncarve = ts__malloc_array(nn + 1, sizeof *dw.ncarve);
    dw.vfill = ts__malloc_array(f->n_verts + 1, sizeof *dw.vfill);
    dw.vcarve = ts__malloc_array(f->n_verts + 1, sizeof *dw.vcarve);
    dw.seen = ts__calloc_array(nn + 1, 1);
    if (!dw.order || !dw.qpath || !dw.down || !dw.nfill || !dw.ncarve || !dw.vfill || !dw.vcarve ||
        !dw.seen) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    for (k = 0; k < np; k++)
        dw.down[k] = -1;
    if ((st = descent_networks(ctx, s, &dw.net, &dw.comp)) != TS_OK)
        goto done;
    for (i = 0; i < nn; i++) {
        size_t comp_end, best, tail, n_q;
        if (dw.seen[i] || f->nodes[i].kind != TS_VALLEY)
            continue;
        comp_end = descent_network(&dw, i);
        best = descent_outlet(&dw, comp_end);
        n_q = descent_orient(&dw, best, comp_end, &tail);
        descent_fill(&dw, best, tail, n_q);
        descent_carve(&dw, n_q);
        descent_mean(&dw, tail, n_q);
    }
done:
    free(dw.order);
    free(dw.qpath);
    free(dw.down);
    free(dw.nfill);
    free(dw.ncarve);
    free(dw.vfill);
    free(dw.vcarve);
    free(dw.seen);
    free(dw.net);
    free(dw.comp);
    return st;
}
