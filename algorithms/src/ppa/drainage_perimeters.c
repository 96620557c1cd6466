/*
 * drainage_perimeters.c - the tiles' perimeters of the drainage area
 * (drainage_area.c) and the rounds across tiles: phase A's spill heights
 * (each tile's minimum spanning forest of its labels, one minimax search
 * from the boundary for F on every perimeter cell), D across the tiles'
 * borders (kept: the flats of each tile and their relaxation; routed: the
 * halo cells a routing reads), phase C's exits summed in flow order, and
 * the phases run on the tiles by the workers.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

/* Append an edge to a growing list; -1 when out of memory. */
static int edge_push(ppa_dr_edge **e, size_t *n, size_t *cap, uint64_t u, uint64_t v, float w)
{
    if (*n == *cap) {
        size_t nc = *cap ? 2 * *cap : 1024;
        ppa_dr_edge *g = realloc(*e, nc * sizeof *g);
        if (!g)
            return -1;
        *e = g;
        *cap = nc;
    }
    (*e)[*n].u = u;
    (*e)[*n].v = v;
    (*e)[*n].w = w;
    (*n)++;
    return 0;
}

/* By weight, then nodes: one total order (the forest does not depend on qsort). */
static int edge_cmp(const void *pa, const void *pb)
{
    const ppa_dr_edge *a = pa, *b = pb;
    if (a->w != b->w)
        return a->w < b->w ? -1 : 1;
    if (a->u != b->u)
        return a->u < b->u ? -1 : 1;
    return a->v < b->v ? -1 : a->v > b->v;
}

/* Phase A on tile t: its labels' minimum spanning forest into the job's
 * edges, and its perimeter heights. */
static int phase_a(ppa_dr_job *j, ppa_dr_tile *k)
{
    int x, y, d;
    size_t pb = j->pbase[k->t], np = ppa_dr_perim_count(k->w, k->h), ne = 0, cap = 0, i, kept = 0;
    ppa_dr_edge *e = NULL;
    uint32_t *uf = NULL;
    int rc = -1;
    if (ppa_dr_tile_flood(k) != 0)
        return -1;
    if (j->Fc) /* kept: the tile's F alone and its labels, for PPA_PH_FLATS */
        for (y = 0; y < k->h; y++)
            for (x = 0; x < k->w; x++) {
                size_t g = (size_t)(k->y0 + y) * (size_t)j->W + (size_t)(k->x0 + x);
                j->Fc[g] = k->cell[ppa_dr_hx(k, x, y)].v;
                j->Dc[g] = k->cell[ppa_dr_hx(k, x, y)].L;
            }
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            long p = ppa_dr_perim_local(k->w, k->h, x, y);
            size_t c = ppa_dr_hx(k, x, y);
            if (p >= 0) {
                j->ph[pb + (size_t)p] = k->cell[c].v;
                j->pbnd[pb + (size_t)p] = k->bnd[(size_t)y * (size_t)k->w + (size_t)x];
            }
            if (isnan(k->cell[c].v))
                continue;
            for (d = 0; d < 4; d++) { /* E, SE, S, SW: each pair once */
                int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
                size_t n;
                if (nx < 0 || ny < 0 || nx >= k->w || ny >= k->h)
                    continue;
                n = ppa_dr_hx(k, nx, ny);
                if (isnan(k->cell[n].v) || k->cell[n].L == k->cell[c].L)
                    continue;
                if (edge_push(&e, &ne, &cap, TS_MIN(k->cell[c].L, k->cell[n].L),
                              TS_MAX(k->cell[c].L, k->cell[n].L),
                              TS_MAX(k->cell[c].v, k->cell[n].v)) != 0)
                    goto done;
            }
        }
    /* the minimum spanning forest of the labels (Kruskal): it keeps every
     * least spill height between two labels */
    uf = ts__malloc_array(np + 2, sizeof *uf);
    if (!uf)
        goto done;
    for (i = 0; i < np + 2; i++)
        uf[i] = (uint32_t)i;
    if (ne > 1)
        qsort(e, ne, sizeof *e, edge_cmp);
    for (i = 0; i < ne; i++) {
        uint32_t ru = ppa_uf_find(uf, (uint32_t)e[i].u), rv = ppa_uf_find(uf, (uint32_t)e[i].v);
        if (ru == rv)
            continue;
        uf[ru] = rv;
        /* labels to nodes: 1 the boundary (node 0), 2 + k perimeter cell pb + k */
        e[kept].u = e[i].u == 1 ? 0 : 1 + pb + (e[i].u - 2);
        e[kept].v = e[i].v == 1 ? 0 : 1 + pb + (e[i].v - 2);
        e[kept].w = e[i].w;
        kept++;
    }
    pthread_mutex_lock(&j->lock);
    if (j->n_edges + kept > j->cap_edges) {
        size_t nc = TS_MAX(2 * j->cap_edges, j->n_edges + kept + 1024);
        ppa_dr_edge *g = realloc(j->edges, nc * sizeof *g);
        if (!g) {
            pthread_mutex_unlock(&j->lock);
            goto done;
        }
        j->edges = g;
        j->cap_edges = nc;
    }
    if (kept)
        memcpy(j->edges + j->n_edges, e, kept * sizeof *e);
    j->n_edges += kept;
    pthread_mutex_unlock(&j->lock);
    rc = 0;
done:
    free(e);
    free(uf);
    return rc;
}

/* The F of every perimeter cell: a minimax search from the boundary over
 * the tiles' forests and the pairs of neighbouring perimeter cells. */
int ppa_dr_solve_perimeter_f(ppa_dr_job *j)
{
    size_t nn = j->np + 1, i, t, *off = NULL, *adj = NULL;
    float *ew = NULL, *best = NULL;
    unsigned char *done = NULL;
    ppa_radix_heap q;
    uint32_t counter = 0;
    int rc = -1, d;
    memset(&q, 0, sizeof q);
    /* the pairs of neighbouring perimeter cells of different tiles */
    for (t = 0; t < j->ntiles; t++) {
        int x0, y0, w, h, x, y;
        ppa_dr_tile_rect(j, t, &x0, &y0, &w, &h);
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                long lp = ppa_dr_perim_local(w, h, x, y);
                size_t p;
                if (lp < 0)
                    continue;
                p = j->pbase[t] + (size_t)lp;
                if (isnan(j->ph[p]))
                    continue;
                for (d = 0; d < 8; d++) {
                    int gx = x0 + x + ppa_dir[d][0], gy = y0 + y + ppa_dir[d][1];
                    size_t qq;
                    uint64_t u, v;
                    if (gx < 0 || gy < 0 || gx >= j->W || gy >= j->H ||
                        (gx >= x0 && gy >= y0 && gx < x0 + w && gy < y0 + h))
                        continue;
                    qq = ppa_dr_perim_of(j, gx, gy);
                    if (qq < p || isnan(j->ph[qq]))
                        continue;
                    u = j->pbnd[p] ? 0 : 1 + p;
                    v = j->pbnd[qq] ? 0 : 1 + qq;
                    if (u == v)
                        continue;
                    if (edge_push(&j->edges, &j->n_edges, &j->cap_edges, u, v,
                                  TS_MAX(j->ph[p], j->ph[qq])) != 0)
                        return -1;
                }
            }
    }
    off = ts__calloc_array(nn + 1, sizeof *off);
    adj = ts__malloc_array(2 * j->n_edges + 1, sizeof *adj);
    ew = ts__malloc_array(2 * j->n_edges + 1, sizeof *ew);
    best = ts__malloc_array(nn, sizeof *best);
    done = ts__calloc_array(nn, 1);
    if (!off || !adj || !ew || !best || !done)
        goto out;
    for (i = 0; i < j->n_edges; i++) {
        off[j->edges[i].u + 1]++;
        off[j->edges[i].v + 1]++;
    }
    for (i = 0; i < nn; i++)
        off[i + 1] += off[i];
    {
        size_t *fill = ts__malloc_array(nn, sizeof *fill);
        if (!fill)
            goto out;
        memcpy(fill, off, nn * sizeof *fill);
        for (i = 0; i < j->n_edges; i++) {
            const ppa_dr_edge *e = &j->edges[i];
            adj[fill[e->u]] = e->v;
            ew[fill[e->u]++] = e->w;
            adj[fill[e->v]] = e->u;
            ew[fill[e->v]++] = e->w;
        }
        free(fill);
    }
    for (i = 0; i < nn; i++)
        best[i] = INFINITY;
    best[0] = -INFINITY;
    if (ppa_rh_push(&q, ppa_flood_key(-INFINITY, counter++), 0) != 0)
        goto out;
    while (q.size) {
        ppa_rh_item it;
        size_t u, a;
        float lv;
        if (ppa_rh_pop(&q, &it) != 0)
            goto out;
        u = (size_t)it.v;
        if (done[u])
            continue;
        done[u] = 1;
        lv = ppa_key_height(it.key);
        for (a = off[u]; a < off[u + 1]; a++) {
            size_t v = adj[a];
            float nl = TS_MAX(lv, ew[a]);
            if (!done[v] && nl < best[v]) {
                best[v] = nl;
                if (ppa_rh_push(&q, ppa_flood_key(nl, counter++), v) != 0)
                    goto out;
            }
        }
    }
    for (i = 0; i < j->np; i++)
        j->G[i] = isnan(j->ph[i]) ? NAN : j->pbnd[i] ? j->ph[i] : TS_MAX(best[i + 1], j->ph[i]);
    rc = 0;
out:
    ppa_rh_free(&q);
    free(off);
    free(adj);
    free(ew);
    free(best);
    free(done);
    return rc;
}

/* After a routing of tile k: the halo cells whose D it read or could
 * have, for D enters a routing only between cells of equal F: a perimeter
 * cell's D from a halo cell of its F, and the flow of a perimeter cell to
 * the neighbour of least (F, D), where a halo cell competes by D only with
 * a cell of its F (the perimeter cell or another neighbour of it).  A
 * change of D anywhere else leaves the routing as it is. */
static void halo_sensitivity(ppa_dr_job *j, ppa_dr_tile *k)
{
    unsigned char *sens = j->hsens + j->hbase[k->t];
    int x, y, d, e;
    memset(sens, 0, ppa_dr_halo_count(k->w, k->h));
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x += (y == 0 || y == k->h - 1) ? 1 : TS_MAX(1, k->w - 1)) {
            const ppa_dr_cell *c = &k->cell[ppa_dr_hx(k, x, y)];
            if (isnan(c->v))
                continue;
            for (d = 0; d < 8; d++) {
                int qx = x + ppa_dir[d][0], qy = y + ppa_dir[d][1];
                const ppa_dr_cell *q;
                int hit;
                if (qx >= 0 && qy >= 0 && qx < k->w && qy < k->h)
                    continue;
                q = &k->cell[ppa_dr_hx(k, qx, qy)];
                if (isnan(q->v))
                    continue;
                hit = q->v == c->v;
                for (e = 0; e < 8 && !hit; e++)
                    if (e != d) {
                        const ppa_dr_cell *r =
                            &k->cell[ppa_dr_hx(k, x + ppa_dir[e][0], y + ppa_dir[e][1])];
                        hit = r->v == q->v;
                    }
                if (hit)
                    sens[ppa_dr_halo_index(k->w, k->h, qx, qy)] = 1;
            }
        }
}

/* Kept: tile k's perimeter D, from its cells', into Dnew. */
static void kept_perimeter_d(ppa_dr_job *j, const ppa_dr_tile *k)
{
    size_t pb = j->pbase[k->t], q, np = ppa_dr_perim_count(k->w, k->h);
    int x, y;
    for (q = 0; q < np; q++) {
        ppa_dr_perim_xy(k->w, k->h, q, &x, &y);
        j->Dnew[pb + q] = j->Dc[(size_t)(k->y0 + y) * (size_t)j->W + (size_t)(k->x0 + x)];
    }
}

/* The offsets of the 8 neighbours in a raster of width W. */
static void neighbour_offsets(int W, ptrdiff_t off[8])
{
    int d;
    for (d = 0; d < 8; d++)
        off[d] = (ptrdiff_t)ppa_dir[d][1] * W + ppa_dir[d][0];
}

/* F and D of tile k where its flow is kept, without routing it: after
 * Barnes (2016), a cell's F is the greater of its F in the tile alone and
 * the F of the seed whose flood reached it first (its label; a boundary
 * seed's is its height): a lower way out through another seed would cross
 * into that seed's region at a spill height the tiles' forests keep, and
 * so would have lowered this seed's F.  Then D by its definition: 0 on
 * boundary cells and cells with a lower neighbour (across the border by
 * the perimeter F), the rest breadth-first along the flats of the tile
 * (across tiles: the rounds of tile_relax). */
static void tile_flats(ppa_dr_job *j, ppa_dr_tile *k)
{
    size_t pb = j->pbase[k->t], head = 0, tail = 0;
    ptrdiff_t off[8];
    int x, y, d;
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t g = (size_t)(k->y0 + y) * (size_t)j->W + (size_t)(k->x0 + x);
            uint32_t lab = j->Dc[g];
            if (lab >= 2 && j->G[pb + lab - 2] > j->Fc[g])
                j->Fc[g] = j->G[pb + lab - 2];
        }
    neighbour_offsets(j->W, off);
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t g = (size_t)(k->y0 + y) * (size_t)j->W + (size_t)(k->x0 + x);
            float f = j->Fc[g];
            uint32_t dv = PPA_DR_DINF;
            if (isnan(f)) {
                j->Dc[g] = PPA_DR_DINF;
                continue;
            }
            if (x > 0 && y > 0 && x < k->w - 1 && y < k->h - 1) { /* inside the tile */
                for (d = 0; d < 8; d++) {
                    float nf = j->Fc[(size_t)((ptrdiff_t)g + off[d])];
                    if (!(nf >= f)) /* lower, or nodata (a boundary cell) */
                        dv = 0;
                }
                goto classified;
            }
            for (d = 0; d < 8 && dv; d++) {
                int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
                int gx = k->x0 + nx, gy = k->y0 + ny;
                float nf;
                if (gx < 0 || gy < 0 || gx >= j->W || gy >= j->H) {
                    dv = 0; /* on the DEM's edge: a boundary cell */
                    break;
                }
                nf = nx >= 0 && ny >= 0 && nx < k->w && ny < k->h
                         ? j->Fc[(size_t)gy * (size_t)j->W + (size_t)gx]
                         : j->G[ppa_dr_perim_of(j, gx, gy)];
                if (isnan(nf) || nf < f)
                    dv = 0; /* beside nodata (a boundary cell), or a lower neighbour */
            }
        classified:
            j->Dc[g] = dv;
            if (!dv)
                k->order[tail++] = (uint32_t)(y * k->w + x);
        }
    while (head < tail) {
        size_t c = k->order[head++], g;
        int cx = (int)(c % (size_t)k->w), cy = (int)(c / (size_t)k->w);
        uint32_t du;
        float f;
        g = (size_t)(k->y0 + cy) * (size_t)j->W + (size_t)(k->x0 + cx);
        f = j->Fc[g];
        du = j->Dc[g];
        for (d = 0; d < 8; d++) {
            int nx = cx + ppa_dir[d][0], ny = cy + ppa_dir[d][1];
            size_t gn;
            if (nx < 0 || ny < 0 || nx >= k->w || ny >= k->h)
                continue;
            gn = (size_t)(k->y0 + ny) * (size_t)j->W + (size_t)(k->x0 + nx);
            if (j->Dc[gn] == PPA_DR_DINF && j->Fc[gn] == f) {
                j->Dc[gn] = du + 1;
                k->order[tail++] = (uint32_t)(ny * k->w + nx);
            }
        }
    }
    kept_perimeter_d(j, k);
}

/* Kept: D of tile k lowered where a neighbour across its border offers a
 * lower D on a flat, and on along the flat (breadth-first on D). */
static int tile_relax(ppa_dr_job *j, ppa_dr_tile *k)
{
    int x, y, d;
    ppa_rh_reset(&k->q);
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x += (y == 0 || y == k->h - 1) ? 1 : TS_MAX(1, k->w - 1)) {
            size_t g = (size_t)(k->y0 + y) * (size_t)j->W + (size_t)(k->x0 + x);
            float f = j->Fc[g];
            uint32_t dv = j->Dc[g];
            if (isnan(f) || dv == 0)
                continue;
            for (d = 0; d < 8; d++) {
                int gx = k->x0 + x + ppa_dir[d][0], gy = k->y0 + y + ppa_dir[d][1];
                size_t q;
                if (gx < 0 || gy < 0 || gx >= j->W || gy >= j->H ||
                    (gx >= k->x0 && gy >= k->y0 && gx < k->x0 + k->w && gy < k->y0 + k->h))
                    continue;
                q = ppa_dr_perim_of(j, gx, gy);
                if (j->G[q] == f && j->D[q] != PPA_DR_DINF && j->D[q] + 1 < dv)
                    dv = j->D[q] + 1;
            }
            if (dv < j->Dc[g]) {
                j->Dc[g] = dv;
                if (ppa_rh_push(&k->q, dv, g) != 0)
                    return -1;
            }
        }
    while (k->q.size) {
        ppa_rh_item it;
        size_t g;
        int cx, cy;
        uint32_t du;
        float f;
        if (ppa_rh_pop(&k->q, &it) != 0)
            return -1;
        g = (size_t)it.v;
        du = (uint32_t)it.key;
        if (du != j->Dc[g])
            continue; /* stale */
        f = j->Fc[g];
        cx = (int)(g % (size_t)j->W);
        cy = (int)(g / (size_t)j->W);
        for (d = 0; d < 8; d++) {
            int nx = cx + ppa_dir[d][0], ny = cy + ppa_dir[d][1];
            size_t gn;
            if (nx < k->x0 || ny < k->y0 || nx >= k->x0 + k->w || ny >= k->y0 + k->h)
                continue;
            gn = (size_t)ny * (size_t)j->W + (size_t)nx;
            if (j->Fc[gn] == f && j->Dc[gn] > du + 1) {
                j->Dc[gn] = du + 1;
                if (ppa_rh_push(&k->q, du + 1, gn) != 0)
                    return -1;
            }
        }
    }
    kept_perimeter_d(j, k);
    return 0;
}

/* Kept, once D holds still: tile k's flow from F and D (the neighbours'
 * too: nothing is written to them now), into k->dir and j->dirs. */
static void tile_dirs_kept(ppa_dr_job *j, ppa_dr_tile *k)
{
    ptrdiff_t off[8];
    int x, y, d;
    neighbour_offsets(j->W, off);
    for (y = 0; y < k->h; y++) {
        int gy = k->y0 + y;
        unsigned char *row = k->dir + (size_t)y * (size_t)k->w;
        for (x = 0; x < k->w; x++) {
            int gx = k->x0 + x, best = PPA_DR_DIR_OUT;
            size_t g = (size_t)gy * (size_t)j->W + (size_t)gx;
            float bf = j->Fc[g], nf[8];
            uint32_t bd = j->Dc[g];
            if (isnan(bf)) {
                row[x] = 255;
                continue;
            }
            if (gx > 0 && gy > 0 && gx < j->W - 1 && gy < j->H - 1) {
                /* a boundary cell (beside nodata) drains off the DEM */
                for (d = 0; d < 8; d++)
                    if (isnan(nf[d] = j->Fc[(size_t)((ptrdiff_t)g + off[d])]))
                        break;
                if (d == 8)
                    for (d = 0; d < 8; d++)
                        if (nf[d] <= bf) {
                            uint32_t nd = j->Dc[(size_t)((ptrdiff_t)g + off[d])];
                            if (nf[d] < bf || nd < bd) {
                                best = d;
                                bf = nf[d];
                                bd = nd;
                            }
                        }
            }
            row[x] = (unsigned char)best;
        }
        memcpy(j->dirs + (size_t)gy * (size_t)j->W + (size_t)k->x0, row, (size_t)k->w);
    }
}

/* Cell c of tile k, taken after the cell it drains to: its exit (the
 * perimeter cell by which its flow leaves the tile, k->cell[].L), and
 * where that flow enters the next tile. */
static void tile_exit(ppa_dr_job *j, ppa_dr_tile *k, size_t c)
{
    size_t pb = j->pbase[k->t];
    int dd = k->dir[c], cx = (int)(c % (size_t)k->w), cy = (int)(c / (size_t)k->w), tx, ty;
    long p = ppa_dr_perim_local(k->w, k->h, cx, cy);
    uint32_t ex = PPA_DR_DINF;
    if (dd < 8) {
        tx = cx + ppa_dir[dd][0];
        ty = cy + ppa_dir[dd][1];
        if (tx < 0 || ty < 0 || tx >= k->w || ty >= k->h) {
            ex = (uint32_t)p;
            j->target[pb + (size_t)p] = ppa_dr_perim_of(j, k->x0 + tx, k->y0 + ty);
            j->A[pb + (size_t)p] = k->acc[c];
        } else {
            ex = k->cell[ppa_dr_hx(k, tx, ty)].L;
        }
    }
    k->cell[ppa_dr_hx(k, cx, cy)].L = ex;
    if (p >= 0)
        j->link[pb + (size_t)p] = ex == PPA_DR_DINF ? PPA_DR_NONE : pb + ex;
}

/* Kept: tile k's areas alone, then its exits (C), downstream first. */
static void tile_exits_kept(ppa_dr_job *j, ppa_dr_tile *k)
{
    size_t i, n = ppa_dr_tile_topo_areas(j, k, NULL);
    for (i = n; i-- > 0;)
        tile_exit(j, k, k->order[i]);
}

/* Phases A, B (with C's exits) and D on a tile. */
static int tile_phase(ppa_dr_job *j, ppa_dr_tile *k, size_t t)
{
    size_t pb = j->pbase[t], i, n;
    int x, y;
    if (j->phase == PPA_PH_FLATS || j->phase == PPA_PH_RELAX || j->phase == PPA_PH_FLOW ||
        (j->phase == PPA_PH_AREAS && j->Fc)) {
        /* kept: no reading, no routing */
        k->t = (int)t;
        ppa_dr_tile_rect(j, t, &k->x0, &k->y0, &k->w, &k->h);
        k->hw = k->w + 2;
        if (j->phase == PPA_PH_FLATS) {
            tile_flats(j, k);
            return 0;
        }
        if (j->phase == PPA_PH_RELAX)
            return tile_relax(j, k);
        if (j->phase == PPA_PH_FLOW) {
            tile_dirs_kept(j, k);
            tile_exits_kept(j, k);
            return 0;
        }
        for (y = 0; y < k->h; y++)
            memcpy(k->dir + (size_t)y * (size_t)k->w,
                   j->dirs + (size_t)(k->y0 + y) * (size_t)j->W + (size_t)k->x0, (size_t)k->w);
        ppa_dr_tile_topo_areas(j, k, j->in);
        goto emit;
    }
    if (ppa_dr_tile_read(j, k, t) != 0)
        return -1;
    if (j->phase == PPA_PH_LABELS)
        return phase_a(j, k);
    n = ppa_dr_tile_route(j, k, j->D);
    if (n == (size_t)-1)
        return -1;
    if (j->phase == PPA_PH_ROUTE) {
        /* D from the neighbours' last D */
        for (y = 0; y < k->h; y++)
            for (x = 0; x < k->w; x++) {
                long p = ppa_dr_perim_local(k->w, k->h, x, y);
                if (p >= 0)
                    j->Dnew[pb + (size_t)p] = k->cell[ppa_dr_hx(k, x, y)].L;
            }
        /* C, from this routing (the last one of the tile's is made on the
         * final D): the exits, perimeter cells draining into another tile;
         * then each perimeter cell's exit, downstream first (k->cell[].L
         * reused) */
        ppa_dr_tile_areas(j, k, n, NULL);
        for (i = pb; i < j->pbase[t + 1]; i++) { /* an earlier routing's exits go */
            j->target[i] = PPA_DR_NONE;
            j->A[i] = 0;
        }
        for (i = 0; i < n; i++)
            tile_exit(j, k, k->order[i]);
        halo_sensitivity(j, k);
        return 0;
    }
    ppa_dr_tile_areas(j, k, n, j->ntiles > 1 ? j->in : NULL);
emit:
    /* the areas, as floats over the doubles (float i lies within doubles
     * 0..i, read before it is written) */
    {
        float *out = (float *)k->acc;
        for (i = 0; i < (size_t)k->w * (size_t)k->h; i++) {
            double a = k->acc[i];
            out[i] = k->dir[i] == 255 ? NAN : (float)a;
        }
    }
    pthread_mutex_lock(&j->lock);
    j->emit(j->emit_user, k->x0, k->y0, k->w, k->h, (const float *)k->acc, k->dir);
    pthread_mutex_unlock(&j->lock);
    return 0;
}

static void job_fail(ppa_dr_job *j)
{
    atomic_store(&j->failed, 1);
}

/* A worker: tiles taken one at a time while any is left (tiles differ in
 * their work; each tile's result is its own, whoever makes it). */
static void tiles_range(void *arg, size_t b, size_t e)
{
    ppa_dr_job *j = arg;
    ppa_dr_tile k;
    size_t t;
    (void)b;
    (void)e;
    if (ppa_dr_tile_alloc(&k, TS_MIN(j->T, j->W), TS_MIN(j->T, j->H)) != 0) {
        job_fail(j);
        ppa_dr_tile_free(&k);
        return;
    }
    while ((t = atomic_fetch_add(&j->next, 1)) < j->ntiles) {
        if (atomic_load(&j->failed) || ts__cancelled(j->ctx))
            break;
        if (!j->due[t])
            continue;
        if (tile_phase(j, &k, t) != 0) {
            job_fail(j);
            break;
        }
    }
    ppa_dr_tile_free(&k);
}

/* Phase `phase` on the due tiles, taken by the workers. */
ts_status ppa_dr_run_phase(ppa_dr_job *j, int phase)
{
    j->phase = phase;
    atomic_store(&j->next, 0);
    ts__parallel_for(j->ctx, j->ntiles, tiles_range, j);
    if (atomic_load(&j->failed))
        return j->ctx->status != TS_OK ? j->ctx->status
                                       : ts__fail(j->ctx, TS_ERR_NOMEM, "ppa drainage",
                                                  "out of memory, or the DEM could not be read");
    return ts__check_cancel(j->ctx);
}

/* Sum the tiles' exits in flow order: what flows into each perimeter cell. */
int ppa_dr_solve_inflow(ppa_dr_job *j)
{
    size_t i, head = 0, tail = 0;
    uint32_t *indeg = ts__calloc_array(j->np, sizeof *indeg);
    size_t *queue = ts__malloc_array(j->np + 1, sizeof *queue);
    double *total = ts__malloc_array(j->np, sizeof *total);
    int rc = -1;
    if (!indeg || !queue || !total)
        goto out;
    /* exit e flows into target[e], and on to that cell's exit link[target[e]] */
    for (i = 0; i < j->np; i++) {
        j->in[i] = 0;
        total[i] = j->A[i];
        if (j->target[i] != PPA_DR_NONE && j->link[j->target[i]] != PPA_DR_NONE)
            indeg[j->link[j->target[i]]]++;
    }
    for (i = 0; i < j->np; i++)
        if (j->target[i] != PPA_DR_NONE && indeg[i] == 0)
            queue[tail++] = i;
    while (head < tail) {
        size_t e = queue[head++], p = j->target[e], nx;
        j->in[p] += total[e];
        nx = j->link[p];
        if (nx == PPA_DR_NONE)
            continue;
        total[nx] += total[e];
        if (--indeg[nx] == 0)
            queue[tail++] = nx;
    }
    rc = 0;
out:
    free(indeg);
    free(queue);
    free(total);
    return rc;
}

/* Kept: tile t, does a perimeter cell of it have a neighbour in another
 * tile, of the same F, offering it a lower D?  Then it is relaxed again. */
int ppa_dr_flat_pairs(const ppa_dr_job *j, size_t t)
{
    int x0, y0, w, h, x, y, d;
    size_t k, np;
    ppa_dr_tile_rect(j, t, &x0, &y0, &w, &h);
    np = ppa_dr_perim_count(w, h);
    for (k = 0; k < np; k++) {
        size_t p = j->pbase[t] + k;
        if (isnan(j->ph[p]) || j->D[p] == 0)
            continue;
        ppa_dr_perim_xy(w, h, k, &x, &y);
        for (d = 0; d < 8; d++) {
            int nx = x0 + x + ppa_dir[d][0], ny = y0 + y + ppa_dir[d][1];
            size_t q;
            if (nx < 0 || ny < 0 || nx >= j->W || ny >= j->H ||
                (nx >= x0 && ny >= y0 && nx < x0 + w && ny < y0 + h))
                continue;
            q = ppa_dr_perim_of(j, nx, ny);
            if (!isnan(j->ph[q]) && j->G[q] == j->G[p] && j->D[q] != PPA_DR_DINF &&
                j->D[q] + 1 < j->D[p])
                return 1;
        }
    }
    return 0;
}

/* Tile t: has the D of a cell next to it in another tile, one its last
 * routing could read (halo_sensitivity), changed in the last round (old:
 * before it)?  Then that routing is to be done again; every other tile's
 * stands, exits and flow included. */
int ppa_dr_halo_changed(const ppa_dr_job *j, size_t t, const uint32_t *old)
{
    const unsigned char *sens = j->hsens + j->hbase[t];
    int x0, y0, w, h, x, y;
    ppa_dr_tile_rect(j, t, &x0, &y0, &w, &h);
    for (y = y0 - 1; y <= y0 + h; y++)
        for (x = x0 - 1; x <= x0 + w; x += (y == y0 - 1 || y == y0 + h) ? 1 : w + 1) {
            size_t p;
            if (x < 0 || y < 0 || x >= j->W || y >= j->H ||
                !sens[ppa_dr_halo_index(w, h, x - x0, y - y0)])
                continue;
            p = ppa_dr_perim_of(j, x, y);
            if (old[p] != j->D[p])
                return 1;
        }
    return 0;
}
