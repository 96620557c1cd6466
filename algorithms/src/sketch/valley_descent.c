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

ts_status ts__valley_descend(ts_ctx *ctx, const ts_layout_spec *s, float *level)
{
    const ts_features *f = s->features;
    int W = s->width, H = s->height;
    size_t nn, np, i, k, head, tail;
    size_t *order = NULL, *qpath = NULL;
    long *down = NULL; /* per path: its downstream node, -1 unused */
    double *nfill = NULL, *ncarve = NULL, *vfill = NULL, *vcarve = NULL;
    unsigned char *seen = NULL;
    int32_t *net = NULL, *comp = NULL;
    ts_status st = TS_OK;
    if (!f || !f->n_paths)
        return TS_OK;
    nn = f->n_nodes;
    np = f->n_paths;
    order = ts__malloc_array(nn + 1, sizeof *order);
    qpath = ts__malloc_array(np + 1, sizeof *qpath);
    down = ts__malloc_array(np + 1, sizeof *down);
    nfill = ts__malloc_array(nn + 1, sizeof *nfill);
    ncarve = ts__malloc_array(nn + 1, sizeof *ncarve);
    vfill = ts__malloc_array(f->n_verts + 1, sizeof *vfill);
    vcarve = ts__malloc_array(f->n_verts + 1, sizeof *vcarve);
    seen = ts__calloc_array(nn + 1, 1);
    if (!order || !qpath || !down || !nfill || !ncarve || !vfill || !vcarve || !seen) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
#define LD_CELL(v) ((size_t)(v)->y * (size_t)W + (size_t)(v)->x)
#define LD_USED(p) ((p)->kind == TS_VALLEY && (p)->count >= 2 && (p)->node_a < nn && (p)->node_b < nn)
#define LD_BORDER(nd) TS_MIN(TS_MIN((nd)->x, W - 1 - (nd)->x), TS_MIN((nd)->y, H - 1 - (nd)->y))
    for (k = 0; k < np; k++)
        down[k] = -1;
    if ((st = descent_networks(ctx, s, &net, &comp)) != TS_OK)
        goto done;
    for (i = 0; i < nn; i++) {
        size_t first, best = nn, comp_end;
        int bd = 0, best_end = 0;
        if (seen[i] || f->nodes[i].kind != TS_VALLEY)
            continue;
        /* the network of node i (nodes only through used paths) */
        tail = 0;
        order[tail++] = i;
        seen[i] = 1;
        for (head = 0; head < tail; head++)
            for (k = 0; k < np; k++) {
                const ts_feature_path *p = &f->paths[k];
                size_t o;
                if (!LD_USED(p) || (p->node_a != order[head] && p->node_b != order[head]))
                    continue;
                o = p->node_a == order[head] ? p->node_b : p->node_a;
                if (!seen[o]) {
                    seen[o] = 1;
                    order[tail++] = o;
                }
            }
        comp_end = tail;
        for (head = 0; head < comp_end; head++) {
            const ts_feature_node *nd = &f->nodes[order[head]];
            int d = LD_BORDER(nd), end = nd->degree == 1;
            if (end)
                d = TS_MIN(d, descent_other(s, net, comp[order[head]], nd->x, nd->y));
            float lv = level[(size_t)nd->y * (size_t)W + (size_t)nd->x];
            if (best == nn || end > best_end ||
                (end == best_end &&
                 (d < bd ||
                  (d == bd &&
                   lv < level[(size_t)f->nodes[best].y * (size_t)W + (size_t)f->nodes[best].x])))) {
                best = order[head];
                bd = d;
                best_end = end;
            }
        }
        /* breadth first from the outlet: paths point downstream */
        for (head = 0; head < comp_end; head++)
            seen[order[head]] = 2;
        first = 0;
        tail = 0;
        order[tail++] = best;
        seen[best] = 3;
        {
            size_t n_q = 0;
            for (head = first; head < tail; head++)
                for (k = 0; k < np; k++) {
                    const ts_feature_path *p = &f->paths[k];
                    size_t o;
                    if (!LD_USED(p) || down[k] >= 0 ||
                        (p->node_a != order[head] && p->node_b != order[head]))
                        continue;
                    down[k] = (long)order[head];
                    qpath[n_q++] = k;
                    o = p->node_a == order[head] ? p->node_b : p->node_a;
                    if (seen[o] != 3) {
                        seen[o] = 3;
                        order[tail++] = o;
                    }
                }
            /* fill: paths in the order reached, each walked upstream */
            for (head = 0; head < tail; head++) {
                const ts_feature_node *nd = &f->nodes[order[head]];
                nfill[order[head]] = -INFINITY;
                ncarve[order[head]] = level[(size_t)nd->y * (size_t)W + (size_t)nd->x];
            }
            nfill[best] = level[(size_t)f->nodes[best].y * (size_t)W + (size_t)f->nodes[best].x];
            for (k = 0; k < n_q; k++) {
                const ts_feature_path *p = &f->paths[qpath[k]];
                int from_b = (size_t)down[qpath[k]] == p->node_b;
                size_t up = from_b ? p->node_a : p->node_b, j;
                double prev = nfill[down[qpath[k]]];
                for (j = 0; j < p->count; j++) {
                    size_t vi = p->first + (from_b ? p->count - 1 - j : j);
                    double lv = level[LD_CELL(&f->verts[vi])];
                    prev = isnan(lv) ? prev : fmax(prev, lv);
                    vfill[vi] = prev;
                }
                nfill[up] = fmax(nfill[up], prev);
            }
            /* carve: paths in the reverse order, each walked downstream */
            for (k = n_q; k-- > 0;) {
                const ts_feature_path *p = &f->paths[qpath[k]];
                int from_b = (size_t)down[qpath[k]] == p->node_b;
                size_t up = from_b ? p->node_a : p->node_b, j;
                double prev = ncarve[up];
                for (j = 0; j < p->count; j++) {
                    size_t vi = p->first + (from_b ? j : p->count - 1 - j);
                    double lv = level[LD_CELL(&f->verts[vi])];
                    prev = isnan(lv) ? prev : fmin(prev, lv);
                    vcarve[vi] = prev;
                }
                ncarve[down[qpath[k]]] = fmin(ncarve[down[qpath[k]]], prev);
            }
            /* the paths' cells take the mean; a node's cell its own */
            for (k = 0; k < n_q; k++) {
                const ts_feature_path *p = &f->paths[qpath[k]];
                size_t j;
                for (j = 1; j + 1 < p->count; j++) {
                    size_t vi = p->first + j;
                    size_t c = LD_CELL(&f->verts[vi]);
                    if (!isnan(level[c]))
                        level[c] = (float)(0.5 * (vfill[vi] + vcarve[vi]));
                }
            }
            for (head = 0; head < tail; head++) {
                const ts_feature_node *nd = &f->nodes[order[head]];
                size_t c = (size_t)nd->y * (size_t)W + (size_t)nd->x;
                if (!isnan(level[c]) && isfinite(nfill[order[head]]))
                    level[c] = (float)(0.5 * (nfill[order[head]] + ncarve[order[head]]));
            }
        }
    }
#undef LD_CELL
#undef LD_USED
#undef LD_BORDER
done:
    free(order);
    free(qpath);
    free(down);
    free(nfill);
    free(ncarve);
    free(vfill);
    free(vcarve);
    free(seen);
    free(net);
    free(comp);
    return st;
}
