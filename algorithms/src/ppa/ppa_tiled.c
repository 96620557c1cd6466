/*
 * ppa_tiled.c - the PPA of a DEM too large for memory, read window by
 * window, with the very output of the whole-raster run (ppa.c).
 *
 * Every step is either local or made exact across tiles:
 *   1. profile recognition is local: a tile's targets are computed on a
 *      window with a margin of half a profile and two cells;
 *   2-3. the maximum spanning forest (polygon breaking) of the whole is the
 *      forest of the union of the tiles' own forests and the segments that
 *      cross tile borders.  Each tile's forest is shrunk to what matters
 *      outside it: twigs that reach no border segment are final; the rest
 *      is contracted to the junctions and border cells, each contracted
 *      path weighted by its least important segment (any cycle through the
 *      path contains all of it, so that segment alone can be the one a
 *      cycle loses).  One Kruskal over the contracted paths and the border
 *      segments, in the same total order (weight, then the global index of
 *      the segment) as the whole-raster run, says which segments go;
 *   4. branch reduction runs on the forest's chain graph (vertices: cells
 *      of degree other than 2 and cells with a border segment; edges: the
 *      chains between them, with their lengths in fixed point), pass by
 *      pass exactly as ppa_branch.c walks cells.
 * Tiles are read three times (forest, chains, output); what is held for
 * the whole raster is the contracted forests (O(border cells)) and the
 * chain graph (O(chains): about 0.27 per cell per kind before branch
 * reduction, so still O(cells); running the first reduction pass inside
 * the tiles is the next step).
 * tests/c/test_ppa.c compares the output with ts_ppa_extract.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

/* Passes of branch reduction run inside the tiles (each on the tile with a
 * halo), when every tile's are certain; fewer otherwise. */
#ifndef PPA_TILE_PASSES
#define PPA_TILE_PASSES 3
#endif

/* An edge of the global Kruskal: a contracted path of one tile's forest,
 * or a segment crossing a tile border. */
typedef struct cut_edge {
    uint64_t u, v;   /* global cells */
    uint64_t idx;    /* the segment (global cell a x 4 + k) that goes if the edge closes a cycle */
    uint32_t key;    /* its weight key */
    uint32_t border; /* 1: a border segment (u = a, v = b) */
} cut_edge;

/* A chain between two vertices of the forest's chain graph. */
typedef struct chain {
    uint64_t u, v;
    int64_t length;
} chain;

typedef struct kind_state {
    int kind;
    float sign;
    cut_edge *edges; /* phase 1; then the border segments kept, sorted by idx */
    size_t n_edges, cap_edges;
    uint64_t *dropped; /* segments of tile forests that are not in the whole's forest, sorted */
    size_t n_dropped;
    uint32_t *border_chain; /* per kept border segment: its chain */
    chain *chains;
    size_t n_chains, cap_chains;
    size_t *chain_base; /* per tile: its first chain */
    unsigned char *dead;
    const ts_grid_metrics *m; /* branch lengths in metres, or NULL: in cells */
    int64_t min_q;            /* the kind's minimum branch length, fixed point */
} kind_state;

typedef struct window {
    int x0, y0, w, h; /* in the raster */
    unsigned char *adj, *unc;
    const ts_grid_metrics *m;
    uint32_t *visit;
    size_t n_visit, cap_visit;
} window;

typedef struct tiled {
    ts_ctx *ctx;
    int W, H, T, ntx, nty, margin, half;
    float threshold[2]; /* ridges, valleys */
    int kinds;
    uint64_t *channel;  /* valleys with the drainage test: bit per DEM cell, set where
                           the drainage area is at least min_drainage (NULL: no test) */
    ts_window_read_fn read;
    void *user;
    kind_state ks[2];
    /* the tile at hand */
    int x0, y0, w, h, wx0, wy0, ww, wh;
    float *win;
    unsigned char *wt;
    float *core;
    unsigned char *ct, *adj, *work, *term;
    uint32_t *queue;
    struct chain_clear *clears;
    size_t n_clears, cap_clears;
    /* the first passes of branch reduction, in tiles */
    int halo, passes;
    double frac; /* the progress of the phase at hand, which the stages' own hold at */
    unsigned char *strip[2][3], *strip_nd[3]; /* three tile rows of the whole's forest */
    struct window wn;
} tiled;

static uint64_t gcell(const tiled *t, int x, int y)
{
    return (uint64_t)y * (uint64_t)t->W + (uint64_t)x;
}

static int in_core(const tiled *t, int x, int y)
{
    return x >= t->x0 && y >= t->y0 && x < t->x0 + t->w && y < t->y0 + t->h;
}

static int grow(void **p, size_t *cap, size_t need, size_t elem)
{
    size_t ncap;
    void *np;
    if (need <= *cap)
        return 0;
    ncap = *cap ? *cap : 1024;
    while (ncap < need)
        ncap *= 2;
    np = realloc(*p, ncap * elem);
    if (!np)
        return -1;
    *p = np;
    *cap = ncap;
    return 0;
}

/* Read tile ti with its margin; targets of every kind on the window. */
static ts_status tile_load(tiled *t, int ti)
{
    int tx = ti % t->ntx, ty = ti / t->ntx, y;
    ts_raster wr;
    ts_status st;
    ts_progress_saved sv;
    t->x0 = tx * t->T;
    t->y0 = ty * t->T;
    t->w = TS_MIN(t->T, t->W - t->x0);
    t->h = TS_MIN(t->T, t->H - t->y0);
    t->wx0 = TS_MAX(0, t->x0 - t->margin);
    t->wy0 = TS_MAX(0, t->y0 - t->margin);
    t->ww = TS_MIN(t->W, t->x0 + t->w + t->margin) - t->wx0;
    t->wh = TS_MIN(t->H, t->y0 + t->h + t->margin) - t->wy0;
    if ((st = t->read(t->user, t->wx0, t->wy0, t->ww, t->wh, t->win)) != TS_OK)
        return t->ctx->status != TS_OK ? t->ctx->status
                                       : ts__fail(t->ctx, st, "ppa", "cannot read the DEM");
    wr.width = t->ww;
    wr.height = t->wh;
    wr.stride = t->ww;
    wr.data = t->win;
    /* the stages' own progress holds still at the tiles' */
    sv = ts__progress_push(t->ctx, t->frac, t->frac);
    st = ppa_profile_targets(t->ctx, &wr, 2 * t->half + 1, t->threshold[0], t->threshold[1],
                             t->kinds, t->wt);
    ts__progress_pop(t->ctx, sv);
    if (st != TS_OK)
        return st;
    if (t->channel) /* valleys where the water runs (as ts_ppa_extract) */
        for (y = 0; y < t->wh; y++) {
            int x;
            unsigned char *row = t->wt + (size_t)y * (size_t)t->ww;
            for (x = 0; x < t->ww; x++) {
                uint64_t g = gcell(t, t->wx0 + x, t->wy0 + y);
                if ((row[x] & TS_VALLEY) && !ppa_channel(t->channel, g))
                    row[x] &= (unsigned char)~TS_VALLEY;
            }
        }
    for (y = 0; y < t->h; y++) {
        size_t o = (size_t)(t->y0 - t->wy0 + y) * (size_t)t->ww + (size_t)(t->x0 - t->wx0);
        memcpy(t->core + (size_t)y * (size_t)t->w, t->win + o, (size_t)t->w * sizeof(float));
        memcpy(t->ct + (size_t)y * (size_t)t->w, t->wt + o, (size_t)t->w);
    }
    return TS_OK;
}

static float win_h(const tiled *t, int x, int y)
{
    return t->win[(size_t)(y - t->wy0) * (size_t)t->ww + (size_t)(x - t->wx0)];
}

/* The tile's own forest of kind ks (segments with both ends in the core). */
static ts_status tile_forest(tiled *t, const kind_state *ks)
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
static int border_segment(const tiled *t, const kind_state *ks, int x, int y, int d, int *ax,
                          int *ay, int *k)
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

static uint32_t seg_key(const tiled *t, const kind_state *ks, int ax, int ay, int k)
{
    int bx = ax + ppa_connect_step[k][0], by = ay + ppa_connect_step[k][1];
    return ppa_weight_key(ks->sign * (win_h(t, ax, ay) + win_h(t, bx, by)));
}

/* The canonical segment between neighbouring core cells p (local) and its
 * neighbour in direction d: global index and key. */
static void core_segment(const tiled *t, const kind_state *ks, int px, int py, int d, uint64_t *idx,
                         uint32_t *key)
{
    int ax = px, ay = py, k;
    if (d < 4) {
        k = ppa_k_of_dir[d];
    } else {
        ax += ppa_dir[d][0];
        ay += ppa_dir[d][1];
        k = ppa_k_of_dir[d - 4];
    }
    *idx = gcell(t, t->x0 + ax, t->y0 + ay) * 4 + (uint64_t)k;
    *key = seg_key(t, ks, t->x0 + ax, t->y0 + ay, k);
}

static int edge_less(const cut_edge *a, const cut_edge *b)
{
    return a->key < b->key || (a->key == b->key && a->idx < b->idx);
}

static int edge_cmp(const void *pa, const void *pb)
{
    const cut_edge *a = pa, *b = pb;
    return edge_less(a, b) ? -1 : edge_less(b, a);
}

static int edge_cmp_idx(const void *pa, const void *pb)
{
    const cut_edge *a = pa, *b = pb;
    return a->idx < b->idx ? -1 : (a->idx > b->idx);
}

static int u64_cmp(const void *pa, const void *pb)
{
    uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
    return a < b ? -1 : (a > b);
}

/* First position in sorted v[0..n) not below key. */
static size_t u64_lower(const uint64_t *v, size_t n, uint64_t key)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (v[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

static size_t edge_lower(const cut_edge *v, size_t n, uint64_t idx)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (v[mid].idx < idx)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* Phase 1 for one tile and kind: its border segments (those it owns) and
 * its forest contracted to the border cells. */
static ts_status tile_contract(tiled *t, kind_state *ks)
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
                if (in_core(t, gx + ppa_dir[d][0], gy + ppa_dir[d][1]) ||
                    !border_segment(t, ks, gx, gy, d, &ax, &ay, &k))
                    continue;
                t->term[(size_t)y * (size_t)w + (size_t)x] = 1;
                if (d < 4) { /* owned here */
                    cut_edge e;
                    e.u = gcell(t, ax, ay);
                    e.v = gcell(t, ax + ppa_connect_step[k][0], ay + ppa_connect_step[k][1]);
                    e.idx = e.u * 4 + (uint64_t)k;
                    e.key = seg_key(t, ks, ax, ay, k);
                    e.border = 1;
                    if (grow((void **)&ks->edges, &ks->cap_edges, ks->n_edges + 1, sizeof e))
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
                cut_edge e;
                e.u = gcell(t, t->x0 + (int)(i % (size_t)w), t->y0 + (int)(i / (size_t)w));
                e.v = gcell(t, t->x0 + cx, t->y0 + cy);
                e.idx = worst_idx;
                e.key = worst_key;
                e.border = 0;
                if (grow((void **)&ks->edges, &ks->cap_edges, ks->n_edges + 1, sizeof e))
                    return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory");
                ks->edges[ks->n_edges++] = e;
            }
        }
    }
    return TS_OK;
}

/* Sorted distinct endpoints of n items read by get(i, 0/1). */
static uint64_t *vertex_list(const void *items, size_t n, size_t size, size_t *n_out)
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
static ts_status global_forest(tiled *t, kind_state *ks)
{
    size_t nv, i, n_keep = 0, cap_drop = 0;
    uint64_t *verts = vertex_list(ks->edges, ks->n_edges, sizeof(cut_edge), &nv);
    uint32_t *parent = verts ? ts__malloc_array(nv + 1, sizeof *parent) : NULL;
    unsigned char *rank = verts ? ts__calloc_array(nv + 1, 1) : NULL;
    if (!verts || !parent || !rank)
        goto nomem;
    for (i = 0; i < nv; i++)
        parent[i] = (uint32_t)i;
    if (ks->n_edges)
        qsort(ks->edges, ks->n_edges, sizeof *ks->edges, edge_cmp);
    for (i = 0; i < ks->n_edges; i++) {
        cut_edge e = ks->edges[i];
        uint32_t ra = ppa_uf_find(parent, (uint32_t)u64_lower(verts, nv, e.u));
        uint32_t rb = ppa_uf_find(parent, (uint32_t)u64_lower(verts, nv, e.v));
        if (ra == rb) {
            if (!e.border) {
                if (grow((void **)&ks->dropped, &cap_drop, ks->n_dropped + 1, sizeof *ks->dropped))
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
static ts_status tile_whole_forest(tiled *t, kind_state *ks)
{
    int w = t->w, h = t->h, x, y;
    ts_status st = tile_forest(t, ks);
    if (st != TS_OK)
        return st;
    for (y = 0; y < h; y++) {
        uint64_t lo = gcell(t, t->x0, t->y0 + y) * 4, hi = lo + (uint64_t)w * 4;
        size_t j;
        for (j = u64_lower(ks->dropped, ks->n_dropped, lo);
             j < ks->n_dropped && ks->dropped[j] < hi; j++) {
            int k = (int)(ks->dropped[j] & 3u), d = ppa_dir_of_k[k];
            int ax = (int)(ks->dropped[j] / 4 - gcell(t, t->x0, t->y0 + y)), ay = y;
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
            a = gcell(t, x, y);
            for (j = edge_lower(ks->edges, ks->n_edges, a * 4);
                 j < ks->n_edges && ks->edges[j].idx < a * 4 + 4; j++) {
                int k = (int)(ks->edges[j].idx & 3u), d = ppa_dir_of_k[k];
                int bx = x + ppa_connect_step[k][0], by = y + ppa_connect_step[k][1];
                if (in_core(t, x, y))
                    t->adj[(size_t)(y - t->y0) * (size_t)w + (size_t)(x - t->x0)] |=
                        (unsigned char)(1u << d);
                if (in_core(t, bx, by))
                    t->adj[(size_t)(by - t->y0) * (size_t)w + (size_t)(bx - t->x0)] |=
                        (unsigned char)(1u << ((d + 4) & 7));
            }
        }
    }
    return TS_OK;
}

/* A chain-graph vertex: degree other than 2, or a bit out of the core. */
static int chain_vertex(const tiled *t, int x, int y)
{
    unsigned char bits = t->adj[(size_t)y * (size_t)t->w + (size_t)x];
    int d;
    if (!bits)
        return 0;
    if (ppa_degree(bits) != 2)
        return 1;
    for (d = 0; d < 8; d++)
        if ((bits >> d & 1) && !in_core(t, t->x0 + x + ppa_dir[d][0], t->y0 + y + ppa_dir[d][1]))
            return 1;
    return 0;
}

/* The tile's chains, in a fixed order; phase 2 records them (remove == 0),
 * phase 3 clears the dead ones from adj (remove == 1).  A chain inside the
 * core is taken from its lower end; a border chain by the tile of its a. */
typedef struct chain_clear {
    int x, y, d, ex, ey; /* walk from (x, y) in direction d to (ex, ey); ex < 0: one bit */
} chain_clear;

static ts_status clear_push(tiled *t, int x, int y, int d, int ex, int ey)
{
    chain_clear c;
    c.x = x, c.y = y, c.d = d, c.ex = ex, c.ey = ey;
    if (grow((void **)&t->clears, &t->cap_clears, t->n_clears + 1, sizeof c))
        return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory");
    t->clears[t->n_clears++] = c;
    return TS_OK;
}

/* Clear the dead chains found by tile_chains, once all are found (clearing
 * sooner would change which cells are vertices).  Chains share no cell but
 * their end vertices, so each walk still finds its own cells. */
static void clear_apply(tiled *t)
{
    size_t i;
    int w = t->w;
    for (i = 0; i < t->n_clears; i++) {
        const chain_clear *c = &t->clears[i];
        int px = c->x, py = c->y, pd = c->d;
        t->adj[(size_t)py * (size_t)w + (size_t)px] &= (unsigned char)~(1u << pd);
        if (c->ex < 0)
            continue;
        for (;;) {
            unsigned char *here;
            px += ppa_dir[pd][0];
            py += ppa_dir[pd][1];
            here = &t->adj[(size_t)py * (size_t)w + (size_t)px];
            *here &= (unsigned char)~(1u << ((pd + 4) & 7));
            if (px == c->ex && py == c->ey)
                break;
            pd = __builtin_ctz(*here);
            *here &= (unsigned char)~(1u << pd);
        }
    }
    t->n_clears = 0;
}

static ts_status tile_chains(tiled *t, kind_state *ks, int ti, int remove)
{
    int w = t->w, h = t->h, x, y, d;
    size_t id = ks->chain_base[ti];
    t->n_clears = 0;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            unsigned char bits = t->adj[(size_t)y * (size_t)w + (size_t)x];
            int gx = t->x0 + x, gy = t->y0 + y;
            if (!bits || !chain_vertex(t, x, y))
                continue;
            for (d = 0; d < 8; d++) {
                int cx = x, cy = y, cd = d;
                int64_t len = 0;
                if (!(bits >> d & 1))
                    continue;
                if (!in_core(t, gx + ppa_dir[d][0], gy + ppa_dir[d][1])) {
                    /* a border segment: its chain belongs to the tile of a */
                    uint64_t a =
                        d < 4 ? gcell(t, gx, gy) : gcell(t, gx + ppa_dir[d][0], gy + ppa_dir[d][1]);
                    int k = ppa_k_of_dir[d & 3];
                    size_t j = edge_lower(ks->edges, ks->n_edges, a * 4 + (uint64_t)k);
                    if (j >= ks->n_edges || ks->edges[j].idx != a * 4 + (uint64_t)k)
                        return ts__fail(t->ctx, TS_ERR_INTERNAL, "ppa", "lost border segment");
                    if (d >= 4) {
                        if (remove && ks->dead[ks->border_chain[j]] &&
                            clear_push(t, x, y, d, -1, -1) != TS_OK)
                            return t->ctx->status;
                        continue;
                    }
                    if (!remove) {
                        chain c;
                        c.u = gcell(t, gx, gy);
                        c.v = gcell(t, gx + ppa_dir[d][0], gy + ppa_dir[d][1]);
                        c.length = ppa_step_q(ks->m, gy, d);
                        if (grow((void **)&ks->chains, &ks->cap_chains, ks->n_chains + 1, sizeof c))
                            return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory");
                        ks->border_chain[j] = (uint32_t)ks->n_chains;
                        ks->chains[ks->n_chains++] = c;
                    } else if (ks->dead[id] && clear_push(t, x, y, d, -1, -1) != TS_OK) {
                        return t->ctx->status;
                    }
                    id++;
                    continue;
                }
                /* walk the chain to the next vertex */
                for (;;) {
                    len += ppa_step_q(ks->m, t->y0 + cy, cd);
                    cx += ppa_dir[cd][0];
                    cy += ppa_dir[cd][1];
                    if (chain_vertex(t, cx, cy))
                        break;
                    cd = __builtin_ctz(t->adj[(size_t)cy * (size_t)w + (size_t)cx] &
                                       (unsigned char)~(1u << ((cd + 4) & 7)));
                }
                if ((size_t)cy * (size_t)w + (size_t)cx < (size_t)y * (size_t)w + (size_t)x)
                    continue; /* taken from the other end */
                if (!remove) {
                    chain c;
                    c.u = gcell(t, gx, gy);
                    c.v = gcell(t, t->x0 + cx, t->y0 + cy);
                    c.length = len;
                    if (grow((void **)&ks->chains, &ks->cap_chains, ks->n_chains + 1, sizeof c))
                        return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory");
                    ks->chains[ks->n_chains++] = c;
                } else if (ks->dead[id] && clear_push(t, x, y, d, cx, cy) != TS_OK) {
                    return t->ctx->status;
                }
                id++;
            }
        }
    if (remove)
        clear_apply(t);
    return TS_OK;
}

/* ------------------------------------------------------------------ */
/* Branch reduction on the chain graph, pass by pass as ppa_branch.c   */
/* ------------------------------------------------------------------ */

typedef struct chain_graph {
    size_t nv, nc;
    uint32_t *cu, *cv;    /* chain ends as vertex ids */
    uint32_t *first, *at; /* incidence lists */
    unsigned char *deg;
    unsigned char *dead;
} chain_graph;

typedef struct cg_branch {
    uint32_t start, junction;
    int64_t length;
    int remove;
} cg_branch;

static uint32_t cg_alive(const chain_graph *g, uint32_t v, uint32_t not_this)
{
    uint32_t j;
    for (j = g->first[v]; j < g->first[v + 1]; j++)
        if (!g->dead[g->at[j]] && g->at[j] != not_this)
            return g->at[j];
    return UINT32_MAX;
}

static uint32_t cg_other(const chain_graph *g, uint32_t c, uint32_t v)
{
    return g->cu[c] == v ? g->cv[c] : g->cu[c];
}

static uint32_t cg_walk(const chain_graph *g, const chain *chains, uint32_t start, int64_t *len)
{
    uint32_t cur = start, c = cg_alive(g, start, UINT32_MAX);
    *len = 0;
    for (;;) {
        *len += chains[c].length;
        cur = cg_other(g, c, cur);
        if (g->deg[cur] != 2)
            return cur;
        c = cg_alive(g, cur, c);
    }
}

static void cg_remove(chain_graph *g, uint32_t start, uint32_t stop)
{
    uint32_t cur = start;
    while (cur != stop) {
        uint32_t c = cg_alive(g, cur, UINT32_MAX), next;
        if (c == UINT32_MAX)
            break;
        next = cg_other(g, c, cur);
        g->dead[c] = 1;
        g->deg[cur]--;
        g->deg[next]--;
        cur = next;
    }
}

static int cg_cmp_junction(const void *pa, const void *pb)
{
    const cg_branch *a = pa, *b = pb;
    if (a->junction != b->junction)
        return a->junction < b->junction ? -1 : 1;
    if (a->length != b->length)
        return a->length > b->length ? -1 : 1;
    return a->start < b->start ? -1 : (a->start > b->start);
}

static int u32_cmp(const void *pa, const void *pb)
{
    uint32_t a = *(const uint32_t *)pa, b = *(const uint32_t *)pb;
    return a < b ? -1 : (a > b);
}

static int u32_push(uint32_t **v, size_t *n, size_t *cap, uint32_t x)
{
    if (grow((void **)v, cap, *n + 1, sizeof **v))
        return -1;
    (*v)[(*n)++] = x;
    return 0;
}

static ts_status global_branches(tiled *t, kind_state *ks)
{
    int64_t min_q = ks->min_q;
    chain_graph g;
    uint64_t *verts = NULL;
    uint32_t *ends = NULL, *next = NULL;
    cg_branch *br = NULL;
    size_t i, n_ends = 0, cap_ends = 0, n_next = 0, cap_next = 0, nb, cap_br = 0;
    int changed = 1, pass = 0;
    ts_status st = TS_OK;
    memset(&g, 0, sizeof g);
    g.nc = ks->n_chains;
    verts = vertex_list(ks->chains, g.nc, sizeof(chain), &g.nv);
    ks->dead = ts__calloc_array(g.nc + 1, 1);
    if (!verts || !ks->dead)
        goto nomem;
    g.dead = ks->dead;
    g.cu = ts__malloc_array(g.nc + 1, sizeof *g.cu);
    g.cv = ts__malloc_array(g.nc + 1, sizeof *g.cv);
    g.first = ts__calloc_array(g.nv + 2, sizeof *g.first);
    g.at = ts__malloc_array(2 * g.nc + 1, sizeof *g.at);
    g.deg = ts__calloc_array(g.nv + 1, 1);
    if (!g.cu || !g.cv || !g.first || !g.at || !g.deg)
        goto nomem;
    for (i = 0; i < g.nc; i++) {
        g.cu[i] = (uint32_t)u64_lower(verts, g.nv, ks->chains[i].u);
        g.cv[i] = (uint32_t)u64_lower(verts, g.nv, ks->chains[i].v);
        g.first[g.cu[i] + 1]++;
        g.first[g.cv[i] + 1]++;
        g.deg[g.cu[i]]++;
        g.deg[g.cv[i]]++;
    }
    free(verts);
    verts = NULL;
    for (i = 0; i < g.nv; i++)
        g.first[i + 1] += g.first[i];
    {
        uint32_t *fill = ts__malloc_array(g.nv + 1, sizeof *fill);
        if (!fill)
            goto nomem;
        memcpy(fill, g.first, g.nv * sizeof *fill);
        for (i = 0; i < g.nc; i++) {
            g.at[fill[g.cu[i]]++] = (uint32_t)i;
            g.at[fill[g.cv[i]]++] = (uint32_t)i;
        }
        free(fill);
    }
    for (i = 0; i < g.nv; i++)
        if (g.deg[i] == 1 && u32_push(&ends, &n_ends, &cap_ends, (uint32_t)i))
            goto nomem;
    while (changed) {
        changed = 0;
        nb = 0;
        n_next = 0;
        for (i = 0; i < n_ends; i++) {
            int64_t len;
            uint32_t end, start = ends[i];
            if (g.deg[start] != 1)
                continue;
            end = cg_walk(&g, ks->chains, start, &len);
            if (g.deg[end] == 1) {
                if (end < start)
                    continue;
                if (len < min_q) {
                    cg_remove(&g, start, end);
                    changed = 1;
                } else if (u32_push(&next, &n_next, &cap_next, start) ||
                           u32_push(&next, &n_next, &cap_next, end)) {
                    goto nomem;
                }
                continue;
            }
            if (grow((void **)&br, &cap_br, nb + 1, sizeof *br))
                goto nomem;
            br[nb].start = start;
            br[nb].junction = end;
            br[nb].length = len;
            br[nb].remove = 0;
            nb++;
        }
        if (nb)
            qsort(br, nb, sizeof *br, cg_cmp_junction);
        for (i = 0; i < nb;) {
            size_t j = i, k;
            int other;
            while (j < nb && br[j].junction == br[i].junction)
                j++;
            other = (int)g.deg[br[i].junction] - (int)(j - i);
            for (k = i; k < j; k++) {
                size_t rank = k - i;
                if (br[k].length >= min_q)
                    continue;
                if (other <= 0 && rank < 2)
                    continue;
                if (other == 1 && rank == 0)
                    continue;
                br[k].remove = 1;
            }
            i = j;
        }
        for (i = 0; i < nb; i++)
            if (br[i].remove) {
                cg_remove(&g, br[i].start, br[i].junction);
                changed = 1;
            }
        for (i = 0; i < nb; i++) {
            uint32_t v = br[i].remove ? br[i].junction : br[i].start;
            if (g.deg[v] == 1 && u32_push(&next, &n_next, &cap_next, v))
                goto nomem;
        }
        if (n_next) {
            size_t u = 1;
            qsort(next, n_next, sizeof *next, u32_cmp);
            for (i = 1; i < n_next; i++)
                if (next[i] != next[u - 1])
                    next[u++] = next[i];
            n_next = u;
        }
        {
            uint32_t *tmp = ends;
            size_t tc = cap_ends;
            ends = next;
            cap_ends = cap_next;
            n_ends = n_next;
            next = tmp;
            cap_next = tc;
        }
        if (++pass % 4 == 0 && (st = ts__check_cancel(t->ctx)) != TS_OK)
            break;
    }
    goto done;
nomem:
    st = ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory for the branch reduction");
done:
    free(verts);
    free(g.cu);
    free(g.cv);
    free(g.first);
    free(g.at);
    free(g.deg);
    free(ends);
    free(next);
    free(br);
    return st;
}

/* ------------------------------------------------------------------ */
/* The first passes of branch reduction inside the tiles               */
/* ------------------------------------------------------------------ */

/* A window (a tile with a halo) of the whole forest, and which of its
 * cells are uncertain: their state after a pass may depend on the forest
 * outside the window.  Cells with a link out of the window start
 * uncertain; a chain (a path of degree-2 cells between cells of other
 * degrees) with an uncertain cell is uncertain with both its ends; a
 * branch or a junction whose walks meet an uncertain cell decides
 * nothing.  What is certain after the passes is what the whole run has
 * after the same passes (every decision taken was taken on the same
 * cells as the whole run takes it). */

typedef struct win_branch {
    uint32_t start, junction;
    int64_t length;
    int remove;
} win_branch;

static int win_cmp(const void *pa, const void *pb)
{
    const win_branch *a = pa, *b = pb;
    if (a->junction != b->junction)
        return a->junction < b->junction ? -1 : 1;
    if (a->length != b->length)
        return a->length > b->length ? -1 : 1;
    return a->start < b->start ? -1 : (a->start > b->start);
}

/* Walk from cell c out through direction d over degree-2 cells to the
 * first cell of another degree (returned; UINT32_MAX when the walk leaves
 * the window).  The cells left behind (c first) are listed in wn->visit
 * when record; *bad is set when any cell met is uncertain. */
static uint32_t win_walk(window *wn, uint32_t c, int d, int record, int64_t *len, int *bad)
{
    int w = wn->w;
    *len = 0;
    *bad = wn->unc[c] != 0;
    wn->n_visit = 0;
    for (;;) {
        int x = (int)(c % (uint32_t)w), y = (int)(c / (uint32_t)w);
        int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
        if (record) {
            if (wn->n_visit == wn->cap_visit) {
                size_t ncap = wn->cap_visit ? 2 * wn->cap_visit : 4096;
                uint32_t *nv = realloc(wn->visit, ncap * sizeof *nv);
                if (!nv) {
                    *bad = 2; /* out of memory */
                    return UINT32_MAX;
                }
                wn->visit = nv;
                wn->cap_visit = ncap;
            }
            wn->visit[wn->n_visit++] = c;
        }
        *len += ppa_step_q(wn->m, wn->y0 + y, d);
        if (nx < 0 || ny < 0 || nx >= w || ny >= wn->h) {
            *bad = 1;
            return UINT32_MAX;
        }
        c = (uint32_t)(ny * w + nx);
        if (wn->unc[c])
            *bad = 1;
        if (ppa_degree(wn->adj[c]) != 2)
            return c;
        d = __builtin_ctz(wn->adj[c] & (unsigned char)~(1u << ((d + 4) & 7)));
    }
}

/* Clear the walk from start up to (not including) stop, as ppa_branch.c. */
static void win_remove(window *wn, uint32_t start, uint32_t stop)
{
    int w = wn->w;
    uint32_t cur = start;
    while (cur != stop) {
        unsigned char bits = wn->adj[cur];
        int x = (int)(cur % (uint32_t)w), y = (int)(cur / (uint32_t)w), d;
        uint32_t next;
        if (!bits)
            break;
        d = __builtin_ctz(bits);
        next = (uint32_t)((y + ppa_dir[d][1]) * w + x + ppa_dir[d][0]);
        wn->adj[cur] = 0;
        wn->adj[next] &= (unsigned char)~(1u << ((d + 4) & 7));
        cur = next;
    }
}

/* A chain with an uncertain cell is uncertain, with its two ends. */
static int win_closure(window *wn)
{
    size_t n = (size_t)wn->w * (size_t)wn->h, i, j;
    for (i = 0; i < n; i++) {
        unsigned char bits = wn->adj[i];
        int d;
        if (!bits || ppa_degree(bits) == 2)
            continue;
        for (d = 0; d < 8; d++) {
            int64_t len;
            int bad;
            uint32_t end;
            if (!(bits >> d & 1))
                continue;
            end = win_walk(wn, (uint32_t)i, d, 1, &len, &bad);
            if (bad == 2)
                return -1;
            /* uncertain: leaves the window, or an interior cell is (visit[0] is this end) */
            bad = end == UINT32_MAX;
            for (j = 1; j < wn->n_visit && !bad; j++)
                bad = wn->unc[wn->visit[j]] != 0;
            if (!bad)
                continue;
            for (j = 0; j < wn->n_visit; j++)
                wn->unc[wn->visit[j]] = 1;
            if (end != UINT32_MAX)
                wn->unc[end] = 1;
        }
    }
    return 0;
}

/* `passes` passes of branch reduction on the window; 0, or -1 out of memory. */
static int win_passes(window *wn, int passes, int64_t min_q)
{
    size_t n = (size_t)wn->w * (size_t)wn->h, i, nb = 0, cap = 0;
    win_branch *br = NULL;
    int pass, x, y, d;
    /* cells linked out of the window */
    for (y = 0; y < wn->h; y++)
        for (x = 0; x < wn->w; x++) {
            unsigned char bits = wn->adj[(size_t)y * (size_t)wn->w + (size_t)x];
            wn->unc[(size_t)y * (size_t)wn->w + (size_t)x] = 0;
            if (x > 0 && y > 0 && x < wn->w - 1 && y < wn->h - 1)
                continue;
            for (d = 0; d < 8; d++)
                if ((bits >> d & 1) && (x + ppa_dir[d][0] < 0 || y + ppa_dir[d][1] < 0 ||
                                        x + ppa_dir[d][0] >= wn->w || y + ppa_dir[d][1] >= wn->h))
                    wn->unc[(size_t)y * (size_t)wn->w + (size_t)x] = 1;
        }
    if (win_closure(wn))
        return -1;
    for (pass = 0; pass < passes; pass++) {
        int changed = 0;
        nb = 0;
        for (i = 0; i < n; i++) {
            int64_t len;
            int bad;
            uint32_t end;
            size_t j;
            if (ppa_degree(wn->adj[i]) != 1 || wn->unc[i])
                continue;
            end = win_walk(wn, (uint32_t)i, __builtin_ctz(wn->adj[i]), 1, &len, &bad);
            if (bad == 2)
                goto nomem;
            if (bad || end == UINT32_MAX) {
                /* its fate depends on what is uncertain: so is it */
                for (j = 0; j < wn->n_visit; j++)
                    wn->unc[wn->visit[j]] = 1;
                if (end != UINT32_MAX)
                    wn->unc[end] = 1;
                continue;
            }
            if (ppa_degree(wn->adj[end]) == 1) { /* isolated path */
                if (end < i)
                    continue;
                if (len < min_q) {
                    win_remove(wn, (uint32_t)i, end);
                    wn->adj[end] = 0;
                    changed = 1;
                }
                continue;
            }
            if (nb == cap) {
                size_t ncap = cap ? 2 * cap : 1024;
                win_branch *nbr = realloc(br, ncap * sizeof *nbr);
                if (!nbr)
                    goto nomem;
                br = nbr;
                cap = ncap;
            }
            br[nb].start = (uint32_t)i;
            br[nb].junction = end;
            br[nb].length = len;
            br[nb].remove = 0;
            nb++;
        }
        if (nb)
            qsort(br, nb, sizeof *br, win_cmp);
        for (i = 0; i < nb;) {
            size_t j = i, k;
            uint32_t J = br[i].junction;
            int other, sure = !wn->unc[J];
            while (j < nb && br[j].junction == J)
                j++;
            /* every arm of J must be seen whole */
            for (d = 0; d < 8 && sure; d++) {
                int64_t len;
                int bad;
                if (!(wn->adj[J] >> d & 1))
                    continue;
                if (win_walk(wn, J, d, 0, &len, &bad) == UINT32_MAX || bad)
                    sure = 0;
            }
            other = ppa_degree(wn->adj[J]) - (int)(j - i);
            for (k = i; k < j; k++) {
                size_t rank = k - i;
                if (br[k].length >= min_q)
                    continue;
                if (!sure) {
                    int64_t len;
                    int bad;
                    size_t v;
                    win_walk(wn, br[k].start, __builtin_ctz(wn->adj[br[k].start]), 1, &len, &bad);
                    if (bad == 2)
                        goto nomem;
                    for (v = 0; v < wn->n_visit; v++)
                        wn->unc[wn->visit[v]] = 1;
                    wn->unc[J] = 1;
                    continue;
                }
                if (other <= 0 && rank < 2)
                    continue;
                if (other == 1 && rank == 0)
                    continue;
                br[k].remove = 1;
            }
            i = j;
        }
        for (i = 0; i < nb; i++)
            if (br[i].remove) {
                win_remove(wn, br[i].start, br[i].junction);
                changed = 1;
            }
        if (win_closure(wn))
            goto nomem;
        (void)changed; /* no early stop: what is uncertain may still change */
    }
    free(br);
    return 0;
nomem:
    free(br);
    return -1;
}

static void tile_rect(tiled *t, int ti)
{
    t->x0 = (ti % t->ntx) * t->T;
    t->y0 = (ti / t->ntx) * t->T;
    t->w = TS_MIN(t->T, t->W - t->x0);
    t->h = TS_MIN(t->T, t->H - t->y0);
}

/* Row y of the raster in a cache of three tile rows. */
static unsigned char *strip_row(const tiled *t, unsigned char *const *strips, int y)
{
    int r = y / t->T;
    return strips[r % 3] + (size_t)(y - r * t->T) * (size_t)t->W;
}

/* The whole's forest (and nodata) of tile row r into the cache. */
static ts_status strip_fill(tiled *t, int nk, int r)
{
    int tx, k, x, y;
    ts_status st;
    for (tx = 0; tx < t->ntx; tx++) {
        if ((st = tile_load(t, r * t->ntx + tx)) != TS_OK)
            return st;
        for (y = 0; y < t->h; y++) {
            unsigned char *nd = strip_row(t, t->strip_nd, t->y0 + y) + t->x0;
            for (x = 0; x < t->w; x++)
                nd[x] = isnan(t->core[(size_t)y * (size_t)t->w + (size_t)x]) ? 1 : 0;
        }
        for (k = 0; k < nk; k++) {
            if ((st = tile_whole_forest(t, &t->ks[k])) != TS_OK)
                return st;
            for (y = 0; y < t->h; y++)
                memcpy(strip_row(t, t->strip[k], t->y0 + y) + t->x0,
                       t->adj + (size_t)y * (size_t)t->w, (size_t)t->w);
        }
    }
    return TS_OK;
}

/* The tile's forest of kind k after t->passes passes of branch reduction
 * (on a window with a halo) into t->adj; *exact = 0 when a core cell of it
 * is uncertain. */
static ts_status tile_after_passes(tiled *t, int k, int *exact)
{
    window *wn = &t->wn;
    int y, x;
    if (t->passes == 0) {
        for (y = 0; y < t->h; y++)
            memcpy(t->adj + (size_t)y * (size_t)t->w, strip_row(t, t->strip[k], t->y0 + y) + t->x0,
                   (size_t)t->w);
        return TS_OK;
    }
    wn->x0 = TS_MAX(0, t->x0 - t->halo);
    wn->y0 = TS_MAX(0, t->y0 - t->halo);
    wn->w = TS_MIN(t->W, t->x0 + t->w + t->halo) - wn->x0;
    wn->h = TS_MIN(t->H, t->y0 + t->h + t->halo) - wn->y0;
    wn->m = t->ks[k].m;
    for (y = 0; y < wn->h; y++)
        memcpy(wn->adj + (size_t)y * (size_t)wn->w, strip_row(t, t->strip[k], wn->y0 + y) + wn->x0,
               (size_t)wn->w);
    if (win_passes(wn, t->passes, t->ks[k].min_q) != 0)
        return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory for the branch reduction");
    for (y = 0; y < t->h; y++) {
        size_t o = (size_t)(t->y0 - wn->y0 + y) * (size_t)wn->w + (size_t)(t->x0 - wn->x0);
        for (x = 0; x < t->w; x++)
            if (wn->unc[o + (size_t)x])
                *exact = 0;
        memcpy(t->adj + (size_t)y * (size_t)t->w, wn->adj + o, (size_t)t->w);
    }
    return TS_OK;
}

/* Phases 2 (remove 0: the chains of the forest after the first passes,
 * for the whole's branch reduction) and 3 (remove 1: the dead chains
 * cleared, the codes written), tile row by tile row with the whole's forest
 * of three tile rows at hand.  *exact = 0: a tile's passes were uncertain
 * (phase 2 stops: the caller tries fewer passes). */
static ts_status sweep(tiled *t, int nk, int remove, int *exact,
                       ts_window_write_fn write, void *user)
{
    int r, tx, k, n_tiles = t->ntx * t->nty;
    size_t i;
    ts_status st = TS_OK;
    for (r = 0; r < t->nty && st == TS_OK; r++) {
        t->frac = (double)(r * t->ntx) / n_tiles;
        if (r == 0 && (st = strip_fill(t, nk, 0)) != TS_OK)
            break;
        if (r + 1 < t->nty && (st = strip_fill(t, nk, r + 1)) != TS_OK)
            break;
        for (tx = 0; tx < t->ntx && st == TS_OK; tx++) {
            int ti = r * t->ntx + tx, y;
            unsigned char *codes = t->work;
            t->frac = (double)ti / n_tiles;
            tile_rect(t, ti);
            if (remove)
                memset(codes, 0, (size_t)t->w * (size_t)t->h);
            for (k = 0; k < nk && st == TS_OK; k++) {
                if (!remove)
                    t->ks[k].chain_base[ti] = t->ks[k].n_chains;
                if ((st = tile_after_passes(t, k, exact)) != TS_OK || !*exact)
                    return st;
                if ((st = tile_chains(t, &t->ks[k], ti, remove)) != TS_OK)
                    return st;
                if (remove)
                    for (i = 0; i < (size_t)t->w * (size_t)t->h; i++)
                        if (t->adj[i])
                            codes[i] |= (unsigned char)t->ks[k].kind;
            }
            if (remove) {
                for (y = 0; y < t->h; y++) {
                    const unsigned char *nd = strip_row(t, t->strip_nd, t->y0 + y) + t->x0;
                    for (i = 0; i < (size_t)t->w; i++)
                        if (nd[i])
                            codes[(size_t)y * (size_t)t->w + i] = 255;
                }
                if ((st = write(user, t->x0, t->y0, t->w, t->h, codes)) != TS_OK) {
                    if (t->ctx->status == TS_OK)
                        ts__fail(t->ctx, st, "ppa", "cannot write the axes");
                    return t->ctx->status;
                }
            }
            st = ts__progress(t->ctx, (double)(ti + 1) / n_tiles,
                              remove ? "axes" : "branch reduction in tiles");
        }
    }
    return st;
}

/* ------------------------------------------------------------------ */
/* The pipeline                                                        */
/* ------------------------------------------------------------------ */

static void tiled_free(tiled *t)
{
    int k;
    free(t->win);
    free(t->wt);
    free(t->core);
    free(t->ct);
    free(t->adj);
    free(t->work);
    free(t->term);
    free(t->queue);
    free(t->channel);
    free(t->clears);
    free(t->wn.adj);
    free(t->wn.unc);
    free(t->wn.visit);
    for (k = 0; k < 3; k++) {
        free(t->strip[0][k]);
        free(t->strip[1][k]);
        free(t->strip_nd[k]);
    }
    for (k = 0; k < 2; k++) {
        free(t->ks[k].edges);
        free(t->ks[k].dropped);
        free(t->ks[k].border_chain);
        free(t->ks[k].chains);
        free(t->ks[k].chain_base);
        free(t->ks[k].dead);
    }
}

TS_API ts_status ts_ppa_extract_tiled(ts_ctx *ctx, int width, int height,
                                      const ts_grid_metrics *metrics, const ts_ppa_params *params,
                                      int tile_size, ts_window_read_fn read,
                                      ts_window_write_fn write, void *user,
                                      ts_ppa_tiled_stats *stats)
{
    tiled t;
    int ti, n_tiles, k, nk = 0;
    size_t wcap, tcap;
    double lo = INFINITY, hi = -INFINITY;
    ts_status st = TS_OK;
    ts_progress_saved sv;

    ts__clear(ctx);
    if (!params || !read || !write)
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "missing parameters or window callbacks");
    if (ts_params_validate(ctx, "ppa", params) != TS_OK)
        return ctx->status;
    if (width < 2 || height < 2)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa", "the DEM is %d x %d cells; at least 2 x 2 needed",
                        width, height);
    if (tile_size < 16 || tile_size > 16384)
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "tile size %d: 16..16384 cells", tile_size);
    if (metrics && (!metrics->dx || !metrics->dy))
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "ground metrics without cell sizes");
    if (params->min_branch_length.unit == TS_UNIT_METRES && params->min_branch_length.value >= 0 &&
        !metrics)
        return ts__fail(ctx, TS_ERR_ARG, "ppa",
                        "min_branch_length is in metres but the DEM has no ground metrics "
                        "(no CRS): give it in cells");
    memset(&t, 0, sizeof t);
    t.ctx = ctx;
    t.W = width;
    t.H = height;
    t.T = tile_size;
    t.ntx = (width + tile_size - 1) / tile_size;
    t.nty = (height + tile_size - 1) / tile_size;
    t.half = params->profile_length / 2;
    t.margin = t.half + 2;
    t.read = read;
    t.user = user;
    n_tiles = t.ntx * t.nty;
    wcap = (size_t)TS_MIN(width, tile_size + 2 * t.margin) *
           (size_t)TS_MIN(height, tile_size + 2 * t.margin);
    tcap = (size_t)tile_size * (size_t)tile_size;
    t.win = ts__malloc_array(wcap, sizeof *t.win);
    t.wt = ts__malloc_array(wcap, 1);
    t.core = ts__malloc_array(tcap, sizeof *t.core);
    t.ct = ts__malloc_array(tcap, 1);
    t.adj = ts__malloc_array(tcap, 1);
    t.work = ts__malloc_array(tcap, 1);
    t.term = ts__malloc_array(tcap, 1);
    t.queue = ts__malloc_array(tcap, sizeof *t.queue);
    if (!t.win || !t.wt || !t.core || !t.ct || !t.adj || !t.work || !t.term || !t.queue) {
        tiled_free(&t);
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "cannot allocate for tiles of %d cells",
                        tile_size);
    }
    if (params->features != TS_PPA_VALLEYS)
        t.ks[nk++].kind = TS_RIDGE;
    if (params->features != TS_PPA_RIDGES)
        t.ks[nk++].kind = TS_VALLEY;
    for (k = 0; k < nk; k++) {
        t.ks[k].sign = t.ks[k].kind == TS_VALLEY ? -1.0f : 1.0f;
        t.ks[k].chain_base = ts__calloc_array((size_t)n_tiles, sizeof *t.ks[k].chain_base);
        if (!t.ks[k].chain_base) {
            tiled_free(&t);
            return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "out of memory");
        }
        t.kinds |= t.ks[k].kind;
    }
    /* the elevation range, for the threshold */
    sv = ts__progress_push(ctx, 0.0, 0.1);
    for (ti = 0; ti < n_tiles && st == TS_OK; ti++) {
        int x0 = (ti % t.ntx) * tile_size, y0 = (ti / t.ntx) * tile_size;
        int w = TS_MIN(tile_size, width - x0), h = TS_MIN(tile_size, height - y0);
        size_t i;
        if ((st = read(user, x0, y0, w, h, t.win)) != TS_OK) {
            if (ctx->status == TS_OK)
                ts__fail(ctx, st, "ppa", "cannot read the DEM");
            st = ctx->status;
            break;
        }
        for (i = 0; i < (size_t)w * (size_t)h; i++)
            if (!isnan(t.win[i])) {
                lo = TS_MIN(lo, (double)t.win[i]);
                hi = TS_MAX(hi, (double)t.win[i]);
            }
        st = ts__progress(ctx, (double)(ti + 1) / n_tiles, "elevation range");
    }
    ts__progress_pop(ctx, sv);
    if (st == TS_OK && !(lo <= hi))
        st = ts__fail(ctx, TS_ERR_NUMERIC, "ppa", "every cell of the DEM is nodata");
    for (k = 0; k < 2; k++)
        t.threshold[k] = (float)TS_MAX(params->threshold,
                                       ppa_kind_fraction(params, k + 1) * (hi - lo));
    for (k = 0; k < nk; k++) {
        int in_metres;
        t.ks[k].min_q = ppa_length_q(ppa_kind_branch(params, t.ks[k].kind, &in_metres));
        t.ks[k].m = in_metres ? metrics : NULL;
    }
    /* valleys where the water runs: the drainage needs the whole DEM */
    if (st == TS_OK && (t.kinds & TS_VALLEY) && params->min_drainage > 0) {
        sv = ts__progress_push(ctx, 0.1, 0.1);
        st = ppa_channels(ctx, width, height, TS_MIN(tile_size, PPA_DRAINAGE_TILE), 0, read, user,
                          params->min_drainage, &t.channel);
        ts__progress_pop(ctx, sv);
    }
    /* 1: tile forests contracted to their borders, one Kruskal for the whole */
    sv = ts__progress_push(ctx, 0.1, 0.4);
    for (ti = 0; ti < n_tiles && st == TS_OK; ti++) {
        t.frac = (double)ti / n_tiles;
        if ((st = tile_load(&t, ti)) != TS_OK)
            break;
        for (k = 0; k < nk && st == TS_OK; k++)
            st = tile_contract(&t, &t.ks[k]);
        if (st == TS_OK)
            st = ts__progress(ctx, (double)(ti + 1) / n_tiles, "polygon breaking in tiles");
    }
    ts__progress_pop(ctx, sv);
    for (k = 0; k < nk && st == TS_OK; k++)
        st = global_forest(&t, &t.ks[k]);
    /* 2: the forest after the first passes of branch reduction (exact in
     * every tile, else fewer passes), its chain graph, the rest of the
     * reduction on it */
    if (st == TS_OK) {
        size_t scap = (size_t)TS_MIN(tile_size, height) * (size_t)width, wcap2;
        /* 256 cells kept the three passes certain on every tile of the mosaics measured
         * (128 too; 64 did not); fewer passes otherwise, never a wrong cell */
        t.halo = TS_MIN(tile_size, TS_MAX(256, tile_size / 8));
        wcap2 = (size_t)TS_MIN(width, tile_size + 2 * t.halo) *
                (size_t)TS_MIN(height, tile_size + 2 * t.halo);
        for (k = 0; k < 3 && st == TS_OK; k++) {
            t.strip_nd[k] = ts__malloc_array(scap, 1);
            t.strip[0][k] = ts__malloc_array(scap, 1);
            t.strip[1][k] = nk > 1 ? ts__malloc_array(scap, 1) : NULL;
            if (!t.strip_nd[k] || !t.strip[0][k] || (nk > 1 && !t.strip[1][k]))
                st = ts__fail(ctx, TS_ERR_NOMEM, "ppa", "cannot allocate three rows of tiles");
        }
        t.wn.adj = ts__malloc_array(wcap2, 1);
        t.wn.unc = ts__malloc_array(wcap2, 1);
        if (st == TS_OK && (!t.wn.adj || !t.wn.unc))
            st = ts__fail(ctx, TS_ERR_NOMEM, "ppa", "cannot allocate for a tile with its halo");
    }
    {
        /* a try with fewer passes goes on from where the last one stopped:
         * progress never goes back */
        double from = 0.4;
        for (t.passes = PPA_TILE_PASSES; st == TS_OK; t.passes--) {
            int exact = 1;
            for (k = 0; k < nk; k++)
                t.ks[k].n_chains = 0;
            t.frac = 0;
            sv = ts__progress_push(ctx, from, 0.7);
            st = sweep(&t, nk, 0, &exact, NULL, NULL);
            ts__progress_pop(ctx, sv);
            if (st != TS_OK || exact)
                break;
            from += (0.7 - from) * t.frac;
        }
    }
    if (stats) {
        stats->passes_in_tiles = t.passes;
        stats->chains_held = t.ks[0].n_chains + t.ks[1].n_chains;
    }
    for (k = 0; k < nk && st == TS_OK; k++) {
        if (t.ks[k].n_chains >= UINT32_MAX)
            st = ts__fail(ctx, TS_ERR_SIZE, "ppa", "too many feature chains");
        else
            st = global_branches(&t, &t.ks[k]);
        free(t.ks[k].chains); /* phase 3 needs only which chains died */
        t.ks[k].chains = NULL;
    }
    /* 3: every tile's axes, written */
    sv = ts__progress_push(ctx, 0.7, 1.0);
    if (st == TS_OK) {
        int exact = 1;
        st = sweep(&t, nk, 1, &exact, write, user);
        if (st == TS_OK && !exact)
            st = ts__fail(ctx, TS_ERR_INTERNAL, "ppa", "tiles: the passes changed between sweeps");
    }
    ts__progress_pop(ctx, sv);
    tiled_free(&t);
    return st;
}
