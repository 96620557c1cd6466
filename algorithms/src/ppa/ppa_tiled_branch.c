/*
 * ppa_tiled_branch.c - branch reduction in tiles (step 4 of the PPA of
 * ppa_tiled.c), pass by pass as ppa_branch.c walks cells: the chains of each
 * tile's part of the forest, the reduction on the chain graph of the whole,
 * and the first passes run inside the tiles, each on the tile with a halo.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

/* A chain-graph vertex: degree other than 2, or a bit out of the core. */
static int chain_vertex(const ppa_tiled *t, int x, int y)
{
    unsigned char bits = t->adj[(size_t)y * (size_t)t->w + (size_t)x];
    int d;
    if (!bits)
        return 0;
    if (ppa_degree(bits) != 2)
        return 1;
    for (d = 0; d < 8; d++)
        if ((bits >> d & 1) &&
            !ppa_in_core(t, t->x0 + x + ppa_dir[d][0], t->y0 + y + ppa_dir[d][1]))
            return 1;
    return 0;
}

/* The tile's chains, in a fixed order; phase 2 records them (remove == 0),
 * phase 3 clears the dead ones from adj (remove == 1).  A chain inside the
 * core is taken from its lower end; a border chain by the tile of its a. */
typedef struct ppa_chain_clear {
    int x, y, d, ex, ey; /* walk from (x, y) in direction d to (ex, ey); ex < 0: one bit */
} ppa_chain_clear;

static ts_status clear_push(ppa_tiled *t, int x, int y, int d, int ex, int ey)
{
    ppa_chain_clear c;
    c.x = x, c.y = y, c.d = d, c.ex = ex, c.ey = ey;
    if (ppa_grow((void **)&t->clears, &t->cap_clears, t->n_clears + 1, sizeof c))
        return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory");
    t->clears[t->n_clears++] = c;
    return TS_OK;
}

/* Clear the dead chains found by ppa_tile_chains, once all are found (clearing
 * sooner would change which cells are vertices).  Chains share no cell but
 * their end vertices, so each walk still finds its own cells. */
static void clear_apply(ppa_tiled *t)
{
    size_t i;
    int w = t->w;
    for (i = 0; i < t->n_clears; i++) {
        const ppa_chain_clear *c = &t->clears[i];
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

ts_status ppa_tile_chains(ppa_tiled *t, ppa_kind_state *ks, int ti, int remove)
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
                if (!ppa_in_core(t, gx + ppa_dir[d][0], gy + ppa_dir[d][1])) {
                    /* a border segment: its chain belongs to the tile of a */
                    uint64_t a = d < 4 ? ppa_gcell(t, gx, gy)
                                       : ppa_gcell(t, gx + ppa_dir[d][0], gy + ppa_dir[d][1]);
                    int k = ppa_k_of_dir[d & 3];
                    size_t j = ppa_edge_lower(ks->edges, ks->n_edges, a * 4 + (uint64_t)k);
                    if (j >= ks->n_edges || ks->edges[j].idx != a * 4 + (uint64_t)k)
                        return ts__fail(t->ctx, TS_ERR_INTERNAL, "ppa", "lost border segment");
                    if (d >= 4) {
                        if (remove && ks->dead[ks->border_chain[j]] &&
                            clear_push(t, x, y, d, -1, -1) != TS_OK)
                            return t->ctx->status;
                        continue;
                    }
                    if (!remove) {
                        ppa_chain c;
                        c.u = ppa_gcell(t, gx, gy);
                        c.v = ppa_gcell(t, gx + ppa_dir[d][0], gy + ppa_dir[d][1]);
                        c.length = ppa_step_q(ks->m, gy, d);
                        if (ppa_grow((void **)&ks->chains, &ks->cap_chains, ks->n_chains + 1,
                                     sizeof c))
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
                    ppa_chain c;
                    c.u = ppa_gcell(t, gx, gy);
                    c.v = ppa_gcell(t, t->x0 + cx, t->y0 + cy);
                    c.length = len;
                    if (ppa_grow((void **)&ks->chains, &ks->cap_chains, ks->n_chains + 1, sizeof c))
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

static uint32_t cg_walk(const chain_graph *g, const ppa_chain *chains, uint32_t start, int64_t *len)
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
    if (ppa_grow((void **)v, cap, *n + 1, sizeof **v))
        return -1;
    (*v)[(*n)++] = x;
    return 0;
}

ts_status ppa_global_branches(ppa_tiled *t, ppa_kind_state *ks)
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
    verts = ppa_vertex_list(ks->chains, g.nc, sizeof(ppa_chain), &g.nv);
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
        g.cu[i] = (uint32_t)ppa_u64_lower(verts, g.nv, ks->chains[i].u);
        g.cv[i] = (uint32_t)ppa_u64_lower(verts, g.nv, ks->chains[i].v);
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
            if (ppa_grow((void **)&br, &cap_br, nb + 1, sizeof *br))
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
static uint32_t win_walk(ppa_window *wn, uint32_t c, int d, int record, int64_t *len, int *bad)
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
static void win_remove(ppa_window *wn, uint32_t start, uint32_t stop)
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
static int win_closure(ppa_window *wn)
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
int ppa_win_passes(ppa_window *wn, int passes, int64_t min_q)
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
