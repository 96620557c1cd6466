/*
 * feature_graph.c - the feature graph of Zhou et al. 2007 section 3:
 * isolated features (endpoints, degree 1; branch points, degree >= 3) and
 * curvilinear features (paths: the chains of cells between them).
 * Built from the PPA forest; a forest in, a forest out
 * (edges = nodes - components).
 * Cost: O(feature cells).
 */
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

typedef struct graph_buf {
    ts_features *f;
    size_t cap_nodes, cap_paths, cap_verts;
} graph_buf;

static int graph_grow(void **p, size_t *cap, size_t need, size_t elem)
{
    size_t ncap;
    void *np;
    if (need <= *cap)
        return 0;
    ncap = *cap ? *cap : 256;
    while (ncap < need)
        ncap *= 2;
    np = realloc(*p, ncap * elem);
    if (!np)
        return -1;
    *p = np;
    *cap = ncap;
    return 0;
}

ts_status ppa_graph_collect(ts_ctx *ctx, const ts_raster *dem, const unsigned char *adj,
                            const ts_grid_metrics *m, int kind, ts_features *f)
{
    int w = dem->width, h = dem->height;
    size_t n = (size_t)w * (size_t)h, i;
    size_t *node_of = NULL; /* cell -> node index + 1, 0 if not a node */
    graph_buf gb;
    gb.f = f;
    gb.cap_nodes = f->n_nodes;
    gb.cap_paths = f->n_paths;
    gb.cap_verts = f->n_verts;
    node_of = ts__calloc_array(n, sizeof *node_of);
    if (!node_of)
        goto nomem;
    for (i = 0; i < n; i++) {
        int deg = ppa_degree(adj[i]);
        if (deg)
            f->mask[i] |= (unsigned char)kind;
        if (deg == 1 || deg >= 3) {
            ts_feature_node *nd;
            if (graph_grow((void **)&f->nodes, &gb.cap_nodes, f->n_nodes + 1, sizeof *f->nodes))
                goto nomem;
            nd = &f->nodes[f->n_nodes];
            nd->x = (int)(i % (size_t)w);
            nd->y = (int)(i / (size_t)w);
            nd->z = dem->data[(ptrdiff_t)nd->y * dem->stride + nd->x];
            nd->degree = deg;
            nd->kind = kind;
            node_of[i] = ++f->n_nodes;
        }
    }
    for (i = 0; i < n; i++) {
        int d;
        if (!node_of[i])
            continue;
        for (d = 0; d < 8; d++) {
            size_t cur = i, first = f->n_verts, count = 0;
            int from = -1, dd = d;
            double len = 0.0, zsum = 0.0;
            float zmin = INFINITY, zmax = -INFINITY;
            ts_feature_path *p;
            if (!(adj[i] & (1u << d)))
                continue;
            /* walk to the next node */
            for (;;) {
                int x = (int)(cur % (size_t)w), y = (int)(cur / (size_t)w);
                float z = dem->data[(ptrdiff_t)y * dem->stride + x];
                ts_feature_vertex *v;
                if (graph_grow((void **)&f->verts, &gb.cap_verts, f->n_verts + 1, sizeof *f->verts))
                    goto nomem;
                v = &f->verts[f->n_verts++];
                v->x = x;
                v->y = y;
                v->z = z;
                count++;
                zsum += z;
                if (z < zmin)
                    zmin = z;
                if (z > zmax)
                    zmax = z;
                if (cur != i && node_of[cur])
                    break;
                if (from >= 0) {
                    unsigned char bits = adj[cur] & (unsigned char)~(1u << from);
                    dd = __builtin_ctz(bits);
                }
                len += ppa_step_length(m, y, dd);
                cur = (size_t)(y + ppa_dir[dd][1]) * (size_t)w + (size_t)(x + ppa_dir[dd][0]);
                from = (dd + 4) & 7;
            }
            /* keep each path once: from its lower-indexed node */
            if (cur < i) {
                f->n_verts = first;
                continue;
            }
            if (graph_grow((void **)&f->paths, &gb.cap_paths, f->n_paths + 1, sizeof *f->paths))
                goto nomem;
            p = &f->paths[f->n_paths++];
            p->kind = kind;
            p->node_a = node_of[i] - 1;
            p->node_b = node_of[cur] - 1;
            p->first = first;
            p->count = count;
            p->length = len;
            p->zmin = zmin;
            p->zmax = zmax;
            p->zmean = (float)(zsum / (double)count);
        }
    }
    free(node_of);
    return TS_OK;
nomem:
    free(node_of);
    return ts__fail(ctx, TS_ERR_NOMEM, "ppa feature graph", "out of memory");
}
