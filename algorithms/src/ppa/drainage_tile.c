/*
 * drainage_tile.c - one tile of the drainage area (drainage_area.c): read
 * with a halo of one cell, its priority-flood from its own boundary and
 * perimeter cells (phase A: F of the tile alone, the labels), its routing by
 * one flood keyed (F, D) from its perimeter's F and its neighbours' D
 * (steps 1-3 on the tile), and its areas summed down the flow (step 4).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <pthread.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

int ppa_dr_tile_alloc(ppa_dr_tile *k, int tw, int th)
{
    size_t hn = (size_t)(tw + 2) * (size_t)(th + 2), n = (size_t)tw * (size_t)th;
    memset(k, 0, sizeof *k);
    k->cell = ts__malloc_array(hn, sizeof *k->cell);
    k->dir = ts__malloc_array(n, 1);
    k->bnd = ts__malloc_array(n, 1);
    k->indeg = ts__malloc_array(n, 1);
    /* doubles of the tile, or floats of the tile with its halo */
    k->acc = ts__malloc_array(TS_MAX(n, (hn + 1) / 2), sizeof *k->acc);
    k->order = ts__malloc_array(n, sizeof *k->order);
    return k->cell && k->dir && k->bnd && k->indeg && k->acc && k->order ? 0 : -1;
}

void ppa_dr_tile_free(ppa_dr_tile *k)
{
    free(k->cell);
    free(k->dir);
    free(k->bnd);
    free(k->indeg);
    free(k->acc);
    free(k->order);
    ppa_rh_free(&k->q);
}

/* Read tile t with its halo (NaN off the DEM); its boundary cells. */
int ppa_dr_tile_read(ppa_dr_job *j, ppa_dr_tile *k, size_t t)
{
    int rx0, ry0, rx1, ry1, x, y, d;
    ts_status st;
    k->t = (int)t;
    ppa_dr_tile_rect(j, t, &k->x0, &k->y0, &k->w, &k->h);
    k->hw = k->w + 2;
    rx0 = TS_MAX(0, k->x0 - 1);
    ry0 = TS_MAX(0, k->y0 - 1);
    rx1 = TS_MIN(j->W, k->x0 + k->w + 1);
    ry1 = TS_MIN(j->H, k->y0 + k->h + 1);
    pthread_mutex_lock(&j->lock);
    st = j->read(j->user, rx0, ry0, rx1 - rx0, ry1 - ry0, (float *)k->acc);
    pthread_mutex_unlock(&j->lock);
    if (st != TS_OK)
        return -1;
    for (y = -1; y <= k->h; y++)
        for (x = -1; x <= k->w; x++) {
            int gx = k->x0 + x, gy = k->y0 + y;
            k->cell[ppa_dr_hx(k, x, y)].v =
                gx < rx0 || gy < ry0 || gx >= rx1 || gy >= ry1
                    ? NAN
                    : ((const float *)
                           k->acc)[(size_t)(gy - ry0) * (size_t)(rx1 - rx0) + (size_t)(gx - rx0)];
        }
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            int b = 0;
            if (!isnan(k->cell[ppa_dr_hx(k, x, y)].v))
                for (d = 0; d < 8 && !b; d++)
                    b = isnan(k->cell[ppa_dr_hx(k, x + ppa_dir[d][0], y + ppa_dir[d][1])].v);
            k->bnd[(size_t)y * (size_t)k->w + (size_t)x] = (unsigned char)b;
        }
    return 0;
}

/* Phase A's priority-flood of the tile from its own seeds, boundary and
 * perimeter cells at their heights, each labelling the cells it reaches
 * (1: the boundary, 2 + k: perimeter cell k).  F of the tile alone. */
int ppa_dr_tile_flood(ppa_dr_tile *k)
{
    int x, y, d;
    uint32_t counter = 0;
    ppa_rh_reset(&k->q);
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t c = ppa_dr_hx(k, x, y);
            float hv = k->cell[c].v, lv;
            long p = ppa_dr_perim_local(k->w, k->h, x, y);
            k->cell[c].L = 0; /* not reached; v is the height until it is */
            if (isnan(hv))
                continue;
            if (k->bnd[(size_t)y * (size_t)k->w + (size_t)x])
                lv = hv, k->cell[c].L = 1;
            else if (p >= 0)
                lv = hv, k->cell[c].L = 2 + (uint32_t)p;
            else
                continue;
            k->cell[c].v = lv;
            if (ppa_rh_push(&k->q, ppa_flood_key(lv, counter++), c) != 0)
                return -1;
        }
    while (k->q.size) {
        ppa_rh_item it;
        int cx, cy;
        float level;
        if (ppa_rh_pop(&k->q, &it) != 0)
            return -1;
        level = ppa_key_height(it.key);
        cx = (int)(it.v % (size_t)k->hw) - 1;
        cy = (int)(it.v / (size_t)k->hw) - 1;
        for (d = 0; d < 8; d++) {
            int nx = cx + ppa_dir[d][0], ny = cy + ppa_dir[d][1];
            size_t c;
            float nh;
            if (nx < 0 || ny < 0 || nx >= k->w || ny >= k->h)
                continue;
            c = ppa_dr_hx(k, nx, ny);
            if (k->cell[c].L)
                continue;
            nh = k->cell[c].v;
            if (isnan(nh))
                continue;
            k->cell[c].L = k->cell[it.v].L;
            k->cell[c].v = nh > level ? nh : level;
            if (ppa_rh_push(&k->q, ppa_flood_key(k->cell[c].v, counter++), c) != 0)
                return -1;
        }
    }
    return 0;
}

/* The key of a cell in the routing flood: F, then D. */
static uint64_t route_key(float f, uint32_t d)
{
    return ppa_flood_key(f, 0) | d;
}

#define ST_NEW 0  /* not reached */
#define ST_HEAP 1 /* reached: F known, D may still fall (perimeter cells) */
#define ST_DONE 2 /* taken */

/* F, D, the flow and the in-tile order of the tile, by one flood whose keys
 * are (F, D): a cell reached from a cell taken at (f, d) gets F = max(its
 * height, f) and D = 0 if that is above f, else d + 1; cells are taken in
 * (F, D) order, so D is the steps to the flat's way out (breadth-first,
 * within each level), and every cell is taken after the cell it drains to.
 * Seeds: boundary cells (F = height, D = 0) and, in tiles, perimeter cells
 * at their F (solved) with D from the halo (lowered when a cell of the tile
 * offers less).  Then each cell's flow (k->dir) and k->order (downstream
 * first); returns the number of cells taken, or (size_t)-1. */
size_t ppa_dr_tile_route(ppa_dr_job *j, ppa_dr_tile *k, const uint32_t *Dsrc)
{
    int x, y, d, multi = j->ntiles > 1;
    size_t pb = j->pbase[k->t], taken = 0;
    unsigned char *st = k->indeg;
    ppa_rh_reset(&k->q);
    /* the halo: F and D of the neighbours' perimeter cells */
    for (y = -1; y <= k->h; y++)
        for (x = -1; x <= k->w; x++) {
            size_t c, p;
            if (x >= 0 && y >= 0 && x < k->w && y < k->h)
                continue;
            c = ppa_dr_hx(k, x, y);
            k->cell[c].L = PPA_DR_DINF;
            if (isnan(k->cell[c].v))
                continue;
            p = ppa_dr_perim_of(j, k->x0 + x, k->y0 + y);
            k->cell[c].v = j->G[p];
            k->cell[c].L = Dsrc[p];
        }
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t i0 = (size_t)y * (size_t)k->w + (size_t)x, c = ppa_dr_hx(k, x, y);
            long p;
            st[i0] = ST_NEW;
            if (isnan(k->cell[c].v))
                continue;
            if (k->bnd[i0]) {
                k->cell[c].L = 0;
            } else if (multi && (p = ppa_dr_perim_local(k->w, k->h, x, y)) >= 0) {
                float f = j->G[pb + (size_t)p];
                uint32_t dv = PPA_DR_DINF;
                k->cell[c].v = f;
                for (d = 0; d < 8 && dv; d++) {
                    int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
                    const ppa_dr_cell *n;
                    if (nx >= 0 && ny >= 0 && nx < k->w && ny < k->h)
                        continue;
                    n = &k->cell[ppa_dr_hx(k, nx, ny)];
                    if (n->v < f)
                        dv = 0;
                    else if (n->v == f && n->L != PPA_DR_DINF && n->L + 1 < dv)
                        dv = n->L + 1;
                }
                k->cell[c].L = dv;
            } else {
                continue;
            }
            st[i0] = ST_HEAP;
            if (ppa_rh_push(&k->q, route_key(k->cell[c].v, k->cell[c].L), c) != 0)
                return (size_t)-1;
        }
    while (k->q.size) {
        ppa_rh_item it;
        int cx, cy;
        const ppa_dr_cell *u;
        if (ppa_rh_pop(&k->q, &it) != 0)
            return (size_t)-1;
        cx = (int)(it.v % (size_t)k->hw) - 1;
        cy = (int)(it.v / (size_t)k->hw) - 1;
        if (st[(size_t)cy * (size_t)k->w + (size_t)cx] == ST_DONE ||
            (uint32_t)it.key != k->cell[it.v].L)
            continue; /* taken, or a stale entry */
        st[(size_t)cy * (size_t)k->w + (size_t)cx] = ST_DONE;
        k->order[taken++] = (uint32_t)((size_t)cy * (size_t)k->w + (size_t)cx);
        u = &k->cell[it.v];
        for (d = 0; d < 8; d++) {
            int nx = cx + ppa_dir[d][0], ny = cy + ppa_dir[d][1];
            size_t ni, c;
            ppa_dr_cell *n;
            uint32_t dv;
            if (nx < 0 || ny < 0 || nx >= k->w || ny >= k->h)
                continue;
            ni = (size_t)ny * (size_t)k->w + (size_t)nx;
            c = ppa_dr_hx(k, nx, ny);
            n = &k->cell[c];
            if (st[ni] == ST_DONE || isnan(n->v))
                continue;
            if (st[ni] == ST_NEW) {
                if (n->v > u->v) {
                    n->L = 0;
                } else {
                    n->v = u->v;
                    n->L = u->L == PPA_DR_DINF ? PPA_DR_DINF : u->L + 1;
                }
                st[ni] = ST_HEAP;
            } else {
                /* a waiting cell: its F is known; a way out through u? */
                dv = n->v > u->v ? 0 : u->L == PPA_DR_DINF ? PPA_DR_DINF : u->L + 1;
                if (dv >= n->L)
                    continue;
                n->L = dv;
            }
            if (ppa_rh_push(&k->q, route_key(n->v, n->L), c) != 0)
                return (size_t)-1;
        }
    }
    /* the flow: to the neighbour of least (F, D), ties to the first */
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t i0 = (size_t)y * (size_t)k->w + (size_t)x;
            const ppa_dr_cell *c = &k->cell[ppa_dr_hx(k, x, y)];
            int best = PPA_DR_DIR_OUT;
            float bf = c->v;
            uint32_t bd = c->L;
            if (isnan(bf)) {
                k->dir[i0] = 255;
                continue;
            }
            if (!k->bnd[i0])
                for (d = 0; d < 8; d++) {
                    const ppa_dr_cell *n =
                        &k->cell[ppa_dr_hx(k, x + ppa_dir[d][0], y + ppa_dir[d][1])];
                    if (n->v < bf || (n->v == bf && n->L < bd)) {
                        best = d;
                        bf = n->v;
                        bd = n->L;
                    }
                }
            k->dir[i0] = (unsigned char)best;
        }
    return taken;
}

/* The areas of the tile, with `in` flowing into perimeter cells (NULL:
 * none): summed down the flow, upstream first. */
void ppa_dr_tile_areas(ppa_dr_job *j, ppa_dr_tile *k, size_t taken, const double *in)
{
    size_t i, pb = j->pbase[k->t];
    int x, y;
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            long p = ppa_dr_perim_local(k->w, k->h, x, y);
            k->acc[(size_t)y * (size_t)k->w + (size_t)x] =
                1.0 + (in && p >= 0 ? in[pb + (size_t)p] : 0.0);
        }
    for (i = taken; i-- > 0;) {
        size_t c = k->order[i];
        int dd = k->dir[c], tx, ty;
        if (dd == PPA_DR_DIR_OUT)
            continue;
        tx = (int)(c % (size_t)k->w) + ppa_dir[dd][0];
        ty = (int)(c / (size_t)k->w) + ppa_dir[dd][1];
        if (tx >= 0 && ty >= 0 && tx < k->w && ty < k->h)
            k->acc[(size_t)ty * (size_t)k->w + (size_t)tx] += k->acc[c];
    }
}

/* Tile k's areas with `in` (NULL: none) flowing into its perimeter cells,
 * summed down the flow k->dir in a topological order found from the flow
 * alone, upstream first, into k->order (returned: how many).  The sums
 * are of whole numbers of cells, exact in doubles, so any such order
 * gives the areas ppa_dr_tile_areas gives. */
size_t ppa_dr_tile_topo_areas(ppa_dr_job *j, ppa_dr_tile *k, const double *in)
{
    size_t n = (size_t)k->w * (size_t)k->h, i, tail = 0, pb = j->pbase[k->t];
    int x, y;
    memset(k->indeg, 0, n);
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t c = (size_t)y * (size_t)k->w + (size_t)x;
            int dd = k->dir[c], tx, ty;
            k->acc[c] = 1.0;
            if (dd >= 8)
                continue;
            tx = x + ppa_dir[dd][0];
            ty = y + ppa_dir[dd][1];
            if (tx >= 0 && ty >= 0 && tx < k->w && ty < k->h)
                k->indeg[(size_t)ty * (size_t)k->w + (size_t)tx]++;
        }
    if (in) {
        size_t np = ppa_dr_perim_count(k->w, k->h), q;
        for (q = 0; q < np; q++) {
            ppa_dr_perim_xy(k->w, k->h, q, &x, &y);
            k->acc[(size_t)y * (size_t)k->w + (size_t)x] += in[pb + q];
        }
    }
    /* from each source down its path, as far as the cells whose every
     * upstream cell is in (255: a cell taken) */
    for (i = 0; i < n; i++) {
        size_t c = i;
        if (k->indeg[c])
            continue;
        k->indeg[c] = 255;
        k->order[tail++] = (uint32_t)c;
        for (;;) {
            int dd = k->dir[c], tx, ty;
            size_t t;
            if (dd >= 8)
                break;
            tx = (int)(c % (size_t)k->w) + ppa_dir[dd][0];
            ty = (int)(c / (size_t)k->w) + ppa_dir[dd][1];
            if (tx < 0 || ty < 0 || tx >= k->w || ty >= k->h)
                break;
            t = (size_t)ty * (size_t)k->w + (size_t)tx;
            k->acc[t] += k->acc[c];
            if (--k->indeg[t])
                break;
            k->indeg[t] = 255;
            k->order[tail++] = (uint32_t)t;
            c = t;
        }
    }
    return tail;
}
