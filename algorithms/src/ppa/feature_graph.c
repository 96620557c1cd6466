/*
 * feature_graph.c - the feature graph of Zhou et al. 2007 section 3:
 * isolated features (endpoints, degree 1; branch points, degree >= 3) and
 * curvilinear features (paths: the chains of cells between them).
 * Built from the PPA forest; a forest in, a forest out
 * (edges = nodes - components).
 * Cost: O(feature cells), in strips of rows side by side: each strip's
 * nodes, then the paths from its nodes, into its own lists, joined in strip
 * order, so the graph is the same on any number of threads (nodes in
 * row-major order, paths by their lower node, then direction).
 */
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

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

/* One strip's share of the graph. */
typedef struct graph_part {
    ts_feature_node *nodes;
    ts_feature_path *paths;
    ts_feature_vertex *verts;
    size_t n_nodes, n_paths, n_verts, cap_nodes, cap_paths, cap_verts;
    size_t node_base; /* the index of its first node in the whole graph */
    int failed;
} graph_part;

typedef struct graph_job {
    const ts_raster *dem;
    const unsigned char *adj;
    const ts_grid_metrics *m;
    int kind, n_parts;
    ts_features *f;
    uint32_t *node_of; /* cell -> node index in the whole graph + 1, 0 if not a node */
    graph_part *parts;
} graph_job;

/* The strips' nodes (indices local to the strip, made global later). */
static void graph_nodes(void *arg, size_t begin, size_t end)
{
    graph_job *j = arg;
    int w = j->dem->width;
    size_t k;
    for (k = begin; k < end; k++) {
        graph_part *p = &j->parts[k];
        int y0, y1, x, y;
        ppa_strip_rows(j->dem->height, k, j->n_parts, &y0, &y1);
        for (y = y0; y < y1; y++)
            for (x = 0; x < w; x++) {
                size_t i = (size_t)y * (size_t)w + (size_t)x;
                int deg = ppa_degree(j->adj[i]);
                j->node_of[i] = 0;
                if (deg)
                    j->f->mask[i] |= (unsigned char)j->kind;
                if (deg == 1 || deg >= 3) {
                    ts_feature_node *nd;
                    if (graph_grow((void **)&p->nodes, &p->cap_nodes, p->n_nodes + 1,
                                   sizeof *p->nodes)) {
                        p->failed = 1;
                        break;
                    }
                    nd = &p->nodes[p->n_nodes++];
                    nd->x = x;
                    nd->y = y;
                    nd->z = j->dem->data[(ptrdiff_t)y * j->dem->stride + x];
                    nd->degree = deg;
                    nd->kind = j->kind;
                    j->node_of[i] = (uint32_t)p->n_nodes; /* local + 1 for now */
                }
            }
    }
}

/* The node indices made global (the strips' bases known). */
static void graph_number(void *arg, size_t begin, size_t end)
{
    graph_job *j = arg;
    int w = j->dem->width;
    size_t k;
    for (k = begin; k < end; k++) {
        int y0, y1;
        size_t i, i0, i1;
        ppa_strip_rows(j->dem->height, k, j->n_parts, &y0, &y1);
        i0 = (size_t)y0 * (size_t)w;
        i1 = (size_t)y1 * (size_t)w;
        for (i = i0; i < i1; i++)
            if (j->node_of[i])
                j->node_of[i] += (uint32_t)j->parts[k].node_base;
    }
}

/* The paths from the strips' nodes, each from its lower-indexed node. */
static void graph_paths(void *arg, size_t begin, size_t end)
{
    graph_job *j = arg;
    const unsigned char *adj = j->adj;
    const ts_raster *dem = j->dem;
    int w = dem->width;
    size_t k;
    for (k = begin; k < end; k++) {
        graph_part *p = &j->parts[k];
        int y0, y1;
        size_t i, i0, i1;
        ppa_strip_rows(j->dem->height, k, j->n_parts, &y0, &y1);
        i0 = (size_t)y0 * (size_t)w;
        i1 = (size_t)y1 * (size_t)w;
        for (i = i0; i < i1 && !p->failed; i++) {
            int d;
            if (!j->node_of[i])
                continue;
            for (d = 0; d < 8; d++) {
                size_t cur = i, first = p->n_verts, count = 0;
                int from = -1, dd = d;
                double len = 0.0, zsum = 0.0;
                float zmin = INFINITY, zmax = -INFINITY;
                ts_feature_path *pa;
                if (!(adj[i] & (1u << d)))
                    continue;
                /* walk to the next node */
                for (;;) {
                    int x = (int)(cur % (size_t)w), y = (int)(cur / (size_t)w);
                    float z = dem->data[(ptrdiff_t)y * dem->stride + x];
                    ts_feature_vertex *v;
                    if (graph_grow((void **)&p->verts, &p->cap_verts, p->n_verts + 1,
                                   sizeof *p->verts)) {
                        p->failed = 1;
                        break;
                    }
                    v = &p->verts[p->n_verts++];
                    v->x = x;
                    v->y = y;
                    v->z = z;
                    count++;
                    zsum += z;
                    if (z < zmin)
                        zmin = z;
                    if (z > zmax)
                        zmax = z;
                    if (cur != i && j->node_of[cur])
                        break;
                    if (from >= 0) {
                        unsigned char bits = adj[cur] & (unsigned char)~(1u << from);
                        dd = __builtin_ctz(bits);
                    }
                    len += ppa_step_length(j->m, y, dd);
                    cur = (size_t)(y + ppa_dir[dd][1]) * (size_t)w + (size_t)(x + ppa_dir[dd][0]);
                    from = (dd + 4) & 7;
                }
                if (p->failed)
                    break;
                /* keep each path once: from its lower-indexed node */
                if (cur < i) {
                    p->n_verts = first;
                    continue;
                }
                if (graph_grow((void **)&p->paths, &p->cap_paths, p->n_paths + 1,
                               sizeof *p->paths)) {
                    p->failed = 1;
                    break;
                }
                pa = &p->paths[p->n_paths++];
                pa->kind = j->kind;
                pa->node_a = j->node_of[i] - 1;
                pa->node_b = j->node_of[cur] - 1;
                pa->first = first; /* within the strip's vertices for now */
                pa->count = count;
                pa->length = len;
                pa->zmin = zmin;
                pa->zmax = zmax;
                pa->zmean = (float)(zsum / (double)count);
            }
        }
    }
}

ts_status ppa_graph_collect(ts_ctx *ctx, const ts_raster *dem, const unsigned char *adj,
                            const ts_grid_metrics *m, int kind, ts_features *f)
{
    int w = dem->width, h = dem->height, k;
    size_t n = (size_t)w * (size_t)h, add_nodes = 0, add_paths = 0, add_verts = 0, cap;
    graph_job j;
    ts_status st = TS_OK;
    memset(&j, 0, sizeof j);
    if (n >= UINT32_MAX || f->n_nodes >= UINT32_MAX - n)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa feature graph", "too many cells");
    j.dem = dem;
    j.adj = adj;
    j.m = m;
    j.kind = kind;
    j.f = f;
    j.n_parts = ts__thread_count(ctx, (size_t)h / 16 ? (size_t)h / 16 : 1);
    j.node_of = ts__malloc_array(n, sizeof *j.node_of);
    j.parts = ts__calloc_array((size_t)j.n_parts, sizeof *j.parts);
    if (!j.node_of || !j.parts)
        goto nomem;
    ts__parallel_for(ctx, (size_t)j.n_parts, graph_nodes, &j);
    for (k = 0; k < j.n_parts; k++) {
        if (j.parts[k].failed)
            goto nomem;
        j.parts[k].node_base = f->n_nodes + add_nodes;
        add_nodes += j.parts[k].n_nodes;
    }
    ts__parallel_for(ctx, (size_t)j.n_parts, graph_number, &j);
    ts__parallel_for(ctx, (size_t)j.n_parts, graph_paths, &j);
    for (k = 0; k < j.n_parts; k++) {
        if (j.parts[k].failed)
            goto nomem;
        add_paths += j.parts[k].n_paths;
        add_verts += j.parts[k].n_verts;
    }
    /* joined in strip order after what f holds (the other kind's, when in sequence) */
    cap = f->n_nodes;
    if (graph_grow((void **)&f->nodes, &cap, f->n_nodes + add_nodes + 1, sizeof *f->nodes))
        goto nomem;
    cap = f->n_paths;
    if (graph_grow((void **)&f->paths, &cap, f->n_paths + add_paths + 1, sizeof *f->paths))
        goto nomem;
    cap = f->n_verts;
    if (graph_grow((void **)&f->verts, &cap, f->n_verts + add_verts + 1, sizeof *f->verts))
        goto nomem;
    for (k = 0; k < j.n_parts; k++) {
        graph_part *p = &j.parts[k];
        size_t q;
        if (p->n_nodes)
            memcpy(f->nodes + f->n_nodes, p->nodes, p->n_nodes * sizeof *p->nodes);
        for (q = 0; q < p->n_paths; q++) {
            f->paths[f->n_paths + q] = p->paths[q];
            f->paths[f->n_paths + q].first += f->n_verts;
        }
        if (p->n_verts)
            memcpy(f->verts + f->n_verts, p->verts, p->n_verts * sizeof *p->verts);
        f->n_nodes += p->n_nodes;
        f->n_paths += p->n_paths;
        f->n_verts += p->n_verts;
    }
    goto done;
nomem:
    st = ts__fail(ctx, TS_ERR_NOMEM, "ppa feature graph", "out of memory");
done:
    if (j.parts)
        for (k = 0; k < j.n_parts; k++) {
            free(j.parts[k].nodes);
            free(j.parts[k].paths);
            free(j.parts[k].verts);
        }
    free(j.parts);
    free(j.node_of);
    return st;
}
