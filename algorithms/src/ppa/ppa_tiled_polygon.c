/*
 * ppa_tiled_polygon.c - polygon breaking in tiles (steps 2-3 of the PPA of
 * ppa_tiled.c): each tile's own maximum spanning forest, shrunk to what
 * matters outside it (twigs that reach no border segment peeled, the rest
 * contracted to its junctions and border cells, each contracted path
 * weighted by its least important segment), one Kruskal over the
 * contracted paths and the segments crossing tile borders, and each tile's
 * part of the whole's forest.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

static float win_h(const ppa_tiled *t, int x, int y)
{
    return t->win[(size_t)(y - t->wy0) * (size_t)t->ww + (size_t)(x - t->wx0)];
}

/* The tile's own forest of kind ks (segments with both ends in the core). */
static ts_status tile_forest(ppa_tiled *t, const ppa_kind_state *ks)
{
    ts_raster cr;
    ts_progress_saved sv;
    ts_status st;
    cr.width = t->w;
    cr.height = t->h;
    cr.stride = t->w;
    cr.data = t->core;
    memset(t->adj, 0, (size_t)t->w * (size_t)t->h);
    sv = ts__progress_push(t->ctx, t->frac, t->frac);
    st = ppa_spanning_forest(t->ctx, &cr, t->ct, ks->kind, t->adj);
    ts__progress_pop(t->ctx, sv);
    return st;
}

/* Does the segment between core cell (x, y) and outside cell (x, y) +
 * ppa_dir[d] exist?  Its canonical form (a, k) in *a_x, *a_y, *k. */
static int border_segment(const ppa_tiled *t, const ppa_kind_state *ks, int x, int y, int d,
                          int *ax, int *ay, int *k)
{
    ts_raster wr;
    int ox = x + ppa_dir[d][0], oy = y + ppa_dir[d][1];
    if (ox < 0 || oy < 0 || ox >= t->W || oy >= t->H)
        return 0;
    if (d < 4) {
        *ax = x, *ay = y, *k = ppa_k_of_dir[d];
    } else {
        *ax = ox, *ay = oy, *k = ppa_k_of_dir[d - 4];
    }
    if (!(t->wt[(size_t)(*ay - t->wy0) * (size_t)t->ww + (size_t)(*ax - t->wx0)] & ks->kind))
        return 0;
    wr.width = t->ww;
    wr.height = t->wh;
    wr.stride = t->ww;
    wr.data = t->win;
    return ppa_segment_exists(&wr, t->wt, ks->kind, *ax - t->wx0, *ay - t->wy0, *k, ks->sign);
}

static uint32_t seg_key(const ppa_tiled *t, const ppa_kind_state *ks, int ax, int ay, int k)
{
    int bx = ax + ppa_connect_step[k][0], by = ay + ppa_connect_step[k][1];
    return ppa_weight_key(ks->sign * (win_h(t, ax, ay) + win_h(t, bx, by)));
}

/* The canonical segment between neighbouring core cells p (local) and its
 * neighbour in direction d: global index and key. */
static void core_segment(const ppa_tiled *t, const ppa_kind_state *ks, int px, int py, int d,
                         uint64_t *idx, uint32_t *key)
{
    int ax = px, ay = py, k;
    if (d < 4) {
        k = ppa_k_of_dir[d];
    } else {
        ax += ppa_dir[d][0];
        ay += ppa_dir[d][1];
        k = ppa_k_of_dir[d - 4];
    }
    *idx = ppa_gcell(t, t->x0 + ax, t->y0 + ay) * 4 + (uint64_t)k;
    *key = seg_key(t, ks, t->x0 + ax, t->y0 + ay, k);
}

static int edge_less(const ppa_cut_edge *a, const ppa_cut_edge *b)
{
    return a->key < b->key || (a->key == b->key && a->idx < b->idx);
}

static int edge_cmp(const void *pa, const void *pb)
{
    const ppa_cut_edge *a = pa, *b = pb;
    return edge_less(a, b) ? -1 : edge_less(b, a);
}

static int edge_cmp_idx(const void *pa, const void *pb)
{
    const ppa_cut_edge *a = pa, *b = pb;
    return a->idx < b->idx ? -1 : (a->idx > b->idx);
}

static int u64_cmp(const void *pa, const void *pb)
{
    uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
    return a < b ? -1 : (a > b);
}

/* Phase 1 for one tile and kind: its border segments (those it owns) and
 * its forest contracted to the border cells. */
ts_status ppa_tile_contract(ppa_tiled *t, ppa_kind_state *ks)
{
    int w = t->w, h = t->h, x, y, d;
    size_t n = (size_t)w * (size_t)h, nq = 0, i;
    ts_status st = tile_forest(t, ks);
    if (st != TS_OK)
        return st;
    memset(t->term, 0, n);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            int gx = t->x0 + x, gy = t->y0 + y, ax, ay, k;
            if (x > 0 && y > 0 && x < w - 1 && y < h - 1) {
                x = w - 2; /* interior cells have no border segment */
                continue;
            }
            if (!(t->ct[(size_t)y * (size_t)w + (size_t)x] & ks->kind))
                continue;
            for (d = 0; d < 8; d++) {
                if (ppa_in_core(t, gx + ppa_dir[d][0], gy + ppa_dir[d][1]) ||
                    !border_segment(t, ks, gx, gy, d, &ax, &ay, &k))
                    continue;
                t->term[(size_t)y * (size_t)w + (size_t)x] = 1;
                if (d < 4) { /* owned here */
                    ppa_cut_edge e;
                    e.u = ppa_gcell(t, ax, ay);
                    e.v = ppa_gcell(t, ax + ppa_connect_step[k][0], ay + ppa_connect_step[k][1]);
                    e.idx = e.u * 4 + (uint64_t)k;
                    e.key = seg_key(t, ks, ax, ay, k);
                    e.border = 1;
                    if (ppa_grow((void **)&ks->edges, &ks->cap_edges, ks->n_edges + 1, sizeof e))
                        return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory");
                    ks->edges[ks->n_edges++] = e;
                }
            }
        }
    /* twigs that reach no border cell are final: peel them */
    memcpy(t->work, t->adj, n);
    for (i = 0; i < n; i++)
        if (!t->term[i] && ppa_degree(t->work[i]) == 1)
            t->queue[nq++] = (uint32_t)i;
    while (nq) {
        uint32_t c = t->queue[--nq], nb;
        int cx = (int)(c % (uint32_t)w), cy = (int)(c / (uint32_t)w);
        if (ppa_degree(t->work[c]) != 1)
            continue;
        d = __builtin_ctz(t->work[c]);
        nb = (uint32_t)((cy + ppa_dir[d][1]) * w + cx + ppa_dir[d][0]);
        t->work[c] = 0;
        t->work[nb] &= (unsigned char)~(1u << ((d + 4) & 7));
        if (!t->term[nb] && ppa_degree(t->work[nb]) == 1)
            t->queue[nq++] = nb;
    }
    /* contract what is left to its junctions and border cells */
    for (i = 0; i < n; i++) {
        unsigned char bits = t->work[i];
        if (!bits || (!t->term[i] && ppa_degree(bits) == 2))
            continue;
        while (bits) {
            int d0 = __builtin_ctz(bits), cd = d0;
            int cx = (int)(i % (size_t)w), cy = (int)(i / (size_t)w);
            uint64_t worst_idx = 0, idx;
            uint32_t worst_key = 0, key;
            int first = 1;
            size_t cur;
            bits &= (unsigned char)(bits - 1);
            for (;;) {
                core_segment(t, ks, cx, cy, cd, &idx, &key);
                if (first || key > worst_key || (key == worst_key && idx > worst_idx)) {
                    worst_key = key;
                    worst_idx = idx;
                    first = 0;
                }
                cx += ppa_dir[cd][0];
                cy += ppa_dir[cd][1];
                cur = (size_t)cy * (size_t)w + (size_t)cx;
                if (t->term[cur] || ppa_degree(t->work[cur]) != 2)
                    break;
                cd = __builtin_ctz(t->work[cur] & (unsigned char)~(1u << ((cd + 4) & 7)));
            }
            if (i < cur) {
                ppa_cut_edge e;
                e.u = ppa_gcell(t, t->x0 + (int)(i % (size_t)w), t->y0 + (int)(i / (size_t)w));
                e.v = ppa_gcell(t, t->x0 + cx, t->y0 + cy);
                e.idx = worst_idx;
                e.key = worst_key;
                e.border = 0;
                if (ppa_grow((void **)&ks->edges, &ks->cap_edges, ks->n_edges + 1, sizeof e))
                    return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory");
                ks->edges[ks->n_edges++] = e;
            }
        }
    }
    return TS_OK;
}

/* Sorted distinct endpoints of n items read by get(i, 0/1). */
uint64_t *ppa_vertex_list(const void *items, size_t n, size_t size, size_t *n_out)
{
    uint64_t *v = ts__malloc_array(2 * n + 1, sizeof *v);
    size_t i, u = 0;
    if (!v)
        return NULL;
    for (i = 0; i < n; i++) { /* u and v are the first two fields of both item types */
        const uint64_t *p = (const uint64_t *)((const char *)items + i * size);
        v[2 * i] = p[0];
        v[2 * i + 1] = p[1];
    }
    qsort(v, 2 * n, sizeof *v, u64_cmp);
    for (i = 0; i < 2 * n; i++)
        if (u == 0 || v[i] != v[u - 1])
            v[u++] = v[i];
    *n_out = u;
    return v;
}

/* Phase 1, whole: one Kruskal over the contracted paths and border
 * segments: which tile segments go, which border segments stay. */
ts_status ppa_global_forest(ppa_tiled *t, ppa_kind_state *ks)
{
    size_t nv, i, n_keep = 0, cap_drop = 0;
    uint64_t *verts = ppa_vertex_list(ks->edges, ks->n_edges, sizeof(ppa_cut_edge), &nv);
    uint32_t *parent = verts ? ts__malloc_array(nv + 1, sizeof *parent) : NULL;
    unsigned char *rank = verts ? ts__calloc_array(nv + 1, 1) : NULL;
    if (!verts || !parent || !rank)
        goto nomem;
    for (i = 0; i < nv; i++)
        parent[i] = (uint32_t)i;
    if (ks->n_edges)
        qsort(ks->edges, ks->n_edges, sizeof *ks->edges, edge_cmp);
    for (i = 0; i < ks->n_edges; i++) {
        ppa_cut_edge e = ks->edges[i];
        uint32_t ra = ppa_uf_find(parent, (uint32_t)ppa_u64_lower(verts, nv, e.u));
        uint32_t rb = ppa_uf_find(parent, (uint32_t)ppa_u64_lower(verts, nv, e.v));
        if (ra == rb) {
            if (!e.border) {
                if (ppa_grow((void **)&ks->dropped, &cap_drop, ks->n_dropped + 1,
                             sizeof *ks->dropped))
                    goto nomem;
                ks->dropped[ks->n_dropped++] = e.idx;
            }
            continue;
        }
        ppa_uf_union(parent, rank, ra, rb);
        if (e.border)
            ks->edges[n_keep++] = e;
    }
    ks->n_edges = n_keep;
    if (n_keep)
        qsort(ks->edges, n_keep, sizeof *ks->edges, edge_cmp_idx);
    if (ks->n_dropped)
        qsort(ks->dropped, ks->n_dropped, sizeof *ks->dropped, u64_cmp);
    ks->border_chain = ts__malloc_array(n_keep + 1, sizeof *ks->border_chain);
    if (!ks->border_chain)
        goto nomem;
    free(verts);
    free(parent);
    free(rank);
    return TS_OK;
nomem:
    free(verts);
    free(parent);
    free(rank);
    return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory for the tiles' forests");
}

/* The tile's part of the whole's forest: its own forest less the dropped
 * segments, plus the kept border segments (bits pointing out of the core). */
ts_status ppa_tile_whole_forest(ppa_tiled *t, ppa_kind_state *ks)
{
    int w = t->w, h = t->h, x, y;
    ts_status st = tile_forest(t, ks);
    if (st != TS_OK)
        return st;
    for (y = 0; y < h; y++) {
        uint64_t lo = ppa_gcell(t, t->x0, t->y0 + y) * 4, hi = lo + (uint64_t)w * 4;
        size_t j;
        for (j = ppa_u64_lower(ks->dropped, ks->n_dropped, lo);
             j < ks->n_dropped && ks->dropped[j] < hi; j++) {
            int k = (int)(ks->dropped[j] & 3u), d = ppa_dir_of_k[k];
            int ax = (int)(ks->dropped[j] / 4 - ppa_gcell(t, t->x0, t->y0 + y)), ay = y;
            t->adj[(size_t)ay * (size_t)w + (size_t)ax] &= (unsigned char)~(1u << d);
            t->adj[(size_t)(ay + ppa_dir[d][1]) * (size_t)w + (size_t)(ax + ppa_dir[d][0])] &=
                (unsigned char)~(1u << ((d + 4) & 7));
        }
    }
    /* kept border segments with an end in the core: their a lies in the
     * core or on the ring around it */
    for (y = t->y0 - 1; y <= t->y0 + h; y++) {
        int edge_row = y <= t->y0 || y >= t->y0 + h - 1;
        if (y < 0 || y >= t->H)
            continue;
        for (x = t->x0 - 1; x <= t->x0 + w; x++) {
            uint64_t a;
            size_t j;
            if (x < 0 || x >= t->W)
                continue;
            if (!edge_row && x == t->x0 + 1 && w > 2)
                x = t->x0 + w - 1; /* inside the ring: only core cells on the border own some */
            a = ppa_gcell(t, x, y);
            for (j = ppa_edge_lower(ks->edges, ks->n_edges, a * 4);
                 j < ks->n_edges && ks->edges[j].idx < a * 4 + 4; j++) {
                int k = (int)(ks->edges[j].idx & 3u), d = ppa_dir_of_k[k];
                int bx = x + ppa_connect_step[k][0], by = y + ppa_connect_step[k][1];
                if (ppa_in_core(t, x, y))
                    t->adj[(size_t)(y - t->y0) * (size_t)w + (size_t)(x - t->x0)] |=
                        (unsigned char)(1u << d);
                if (ppa_in_core(t, bx, by))
                    t->adj[(size_t)(by - t->y0) * (size_t)w + (size_t)(bx - t->x0)] |=
                        (unsigned char)(1u << ((d + 4) & 7));
            }
        }
    }
    return TS_OK;
}
