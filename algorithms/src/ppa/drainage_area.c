/*
 * drainage_area.c - the drainage area of every cell (in cells), for the
 * PPA's `min_drainage`: valley targets that drain fewer cells are hollows
 * above the channel heads, not valleys where the water runs.
 *
 * The flow, defined cell by cell so that any tiling gives it exactly:
 *   1. F, the filled height: the least, over the paths from the cell to the
 *      boundary (valid cells on the DEM's edge or beside nodata), of the
 *      highest cell on the path (depressions fill to their spill height;
 *      Barnes, Lehman and Mulla 2014).
 *   2. D, on flats of F: 0 on boundary cells and cells with a lower
 *      neighbour, else 1 + the least D of the neighbours of equal F (the
 *      steps to the flat's way out).
 *   3. A boundary cell drains off the DEM; any other cell to its neighbour
 *      of least (F, D), ties to the first in ppa_dir order: (F, D) falls
 *      along every path, so the flow is a forest.
 *   4. The area of a cell: itself and every cell draining through it.
 * In tiles (bounded memory, tiles in parallel), after Barnes (2016, 2017):
 *   A. each tile flooded from its own perimeter and boundary cells, which
 *      label the cells they reach; the least spill height between two
 *      labels is an edge, and the tile keeps the minimum spanning forest of
 *      its labels; with the edges between perimeter cells of neighbouring
 *      tiles, one minimax search from the boundary gives F on every
 *      perimeter cell (F of a cell inside is then the flood of its tile
 *      from its perimeter at those heights);
 *   B. D on each tile from its own ways out and its neighbours' perimeter
 *      D, in rounds until no perimeter D falls (flats across tiles);
 *   C. each tile's flow and areas; where the flow leaves a tile: its area
 *      so far, where it enters, and for each perimeter cell the cell its
 *      flow leaves the tile by; summed over the tiles' exits in flow order;
 *   D. each tile's areas with what flows in from its neighbours.
 * Two ways through B-D.  Kept (in memory, `keep`): F, D and the flow of
 * every cell are held (9 bytes a cell), so no tile is routed: F is the
 * greater of the tile's own flood and its label's perimeter F, D is found
 * breadth-first on the flats and relaxed across tiles, the flow, exits and
 * areas follow in a topological order.  Routed (bounded memory, for
 * ppa_tiled.c): each round routes its tiles by one flood keyed (F, D) and
 * keeps their exits; a tile is routed again only when a neighbour's D that
 * its routing could read has changed; D routes each tile once more.
 * One tile is steps 1-4 at once, by one routing.  tests/c/test_ppa.c compares the areas
 * with the definition computed naively (F by relaxation, the flow cell by
 * cell) on several tilings.
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

/* ---- a radix heap (Ahuja et al. 1990) of unique, never falling keys ---- */

/* Height, then the order of arrival, as one 64-bit key (the float's bits
 * made to sort as unsigned, then a counter). */
static uint64_t flood_key(float h, uint32_t count)
{
    uint32_t u;
    h += 0.0f; /* -0 and +0 are one height */
    memcpy(&u, &h, sizeof u);
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return (uint64_t)u << 32 | count;
}

static float key_height(uint64_t key)
{
    uint32_t u = (uint32_t)(key >> 32);
    float h;
    u = (u & 0x80000000u) ? (u & 0x7fffffffu) : ~u;
    memcpy(&h, &u, sizeof h);
    return h;
}

typedef struct rh_item {
    uint64_t key;
    uint64_t v;
} rh_item;

/* An item waits in the bucket of the highest bit where its key differs
 * from the last key taken and only moves down. */
typedef struct radix_heap {
    rh_item *b[65];
    size_t n[65], cap[65];
    uint64_t last;
    size_t size;
} radix_heap;

static int rh_bucket(const radix_heap *q, uint64_t key)
{
    return key == q->last ? 0 : 64 - __builtin_clzll(key ^ q->last);
}

static int rh_append(radix_heap *q, int i, rh_item it)
{
    if (q->n[i] == q->cap[i]) {
        size_t nc = q->cap[i] ? 2 * q->cap[i] : 256;
        rh_item *g = realloc(q->b[i], nc * sizeof *g);
        if (!g)
            return -1;
        q->b[i] = g;
        q->cap[i] = nc;
    }
    q->b[i][q->n[i]++] = it;
    return 0;
}

static int rh_push(radix_heap *q, uint64_t key, uint64_t v)
{
    rh_item it;
    it.key = key;
    it.v = v;
    if (rh_append(q, rh_bucket(q, key), it) != 0)
        return -1;
    q->size++;
    return 0;
}

/* Take the least item (q->size > 0) into *out; -1 when out of memory. */
static int rh_pop(radix_heap *q, rh_item *out)
{
    if (q->n[0] == 0) {
        int i = 1;
        size_t j, m = 0, cnt;
        rh_item *src;
        while (q->n[i] == 0)
            i++;
        for (j = 1; j < q->n[i]; j++)
            if (q->b[i][j].key < q->b[i][m].key)
                m = j;
        q->last = q->b[i][m].key;
        src = q->b[i];
        cnt = q->n[i];
        q->n[i] = 0;
        for (j = 0; j < cnt; j++)
            if (rh_append(q, rh_bucket(q, src[j].key), src[j]) != 0) {
                memmove(src, src + j, (cnt - j) * sizeof *src); /* the heap stays whole */
                q->n[i] = cnt - j;
                return -1;
            }
    }
    q->size--;
    *out = q->b[0][--q->n[0]];
    return 0;
}

static void rh_reset(radix_heap *q)
{
    int i;
    for (i = 0; i < 65; i++)
        q->n[i] = 0;
    q->last = 0;
    q->size = 0;
}

static void rh_free(radix_heap *q)
{
    int i;
    for (i = 0; i < 65; i++)
        free(q->b[i]);
}

/* ---- the job ---- */

#define NONE UINT64_MAX
#define DINF UINT32_MAX
#define DIR_OUT 8 /* drains off the DEM */

/* The phases (dr_job.phase). */
enum { PH_LABELS, PH_ROUTE, PH_FLATS, PH_RELAX, PH_FLOW, PH_AREAS };

typedef struct dr_edge {
    uint64_t u, v; /* global nodes: 0 the boundary, 1 + p perimeter cell p */
    float w;
} dr_edge;

typedef struct dr_job {
    ts_ctx *ctx;
    int W, H, T, ntx, nty;
    size_t ntiles, np;
    ts_window_read_fn read;
    void *user;
    ppa_area_fn emit;
    void *emit_user;
    pthread_mutex_t lock; /* reads, emits, the edge list */
    atomic_int failed;
    atomic_size_t next; /* the next tile a worker takes */
    size_t *pbase;       /* per tile (and one past): its first perimeter cell */
    float *ph;           /* perimeter heights (NaN: nodata) */
    unsigned char *pbnd; /* perimeter cell on the boundary */
    float *G;            /* perimeter F */
    uint32_t *D, *Dnew;  /* perimeter D (DINF: not known) */
    unsigned char *due; /* the tiles the phase at hand runs on */
    dr_edge *edges;
    size_t n_edges, cap_edges;
    uint64_t *target, *link; /* phase C: where a tile exit's flow enters; by what exit a
                                perimeter cell's flow leaves its tile */
    double *A, *in;          /* an exit's area in its tile; what flows into a perimeter cell */
    /* kept (in memory, not in bounded memory): each cell's F, D and flow
     * (W x H), so that a tile is routed once: D across tiles is relaxed on
     * the flats alone, the flow and the areas follow from F and D */
    float *Fc;
    uint32_t *Dc;
    unsigned char *dirs;
    size_t *hbase;           /* per tile (and one past): its first halo cell in hsens */
    unsigned char *hsens;    /* the halo cells whose D the tile's last routing could read */
    int phase;
} dr_job;

/* A cell of a tile: its height, F once flooded (side by side with L: the
 * flood visits cells in height order, all over the tile; one cache line a
 * row of neighbours), and L: its label (phase A), D (B-D), exit (C). */
typedef struct dr_cell {
    float v;
    uint32_t L;
} dr_cell;

/* A tile's working set: the tile with a halo of one cell. */
typedef struct dr_tile {
    int t, x0, y0, w, h, hw;
    dr_cell *cell;
    unsigned char *dir, *bnd, *indeg;
    double *acc; /* also the buffer of reads and of the areas handed out */
    uint32_t *order;
    radix_heap q;
} dr_tile;

static size_t hx(const dr_tile *k, int x, int y) /* x, y in [-1, w] x [-1, h] */
{
    return (size_t)(y + 1) * (size_t)k->hw + (size_t)(x + 1);
}

static long perim_local(int w, int h, int x, int y)
{
    if (y == 0)
        return x;
    if (y == h - 1)
        return (long)w + x;
    if (x == 0)
        return 2L * w + (y - 1);
    if (x == w - 1)
        return 2L * w + (h - 2) + (y - 1);
    return -1;
}

static size_t perim_count(int w, int h)
{
    return h == 1 ? (size_t)w : w == 1 ? (size_t)h : 2 * (size_t)w + 2 * (size_t)(h - 2);
}

/* The cell of tile (w x h) whose perimeter index is k. */
static void perim_xy(int w, int h, size_t k, int *x, int *y)
{
    size_t k2;
    if (k < (size_t)w) {
        *x = (int)k, *y = 0;
        return;
    }
    if (k < 2 * (size_t)w) {
        *x = (int)(k - (size_t)w), *y = h - 1;
        return;
    }
    k2 = k - 2 * (size_t)w;
    if (k2 < (size_t)(h - 2))
        *x = 0, *y = 1 + (int)k2;
    else
        *x = w - 1, *y = 1 + (int)(k2 - (size_t)(h - 2));
}

/* The halo of a w x h tile, a ring of 2 (w + 2) + 2 h cells: the row
 * above, the row below, the column left, the column right. */
static size_t halo_count(int w, int h)
{
    return 2 * (size_t)(w + 2) + 2 * (size_t)h;
}

static size_t halo_index(int w, int h, int x, int y) /* (x, y) in the halo */
{
    if (y < 0)
        return (size_t)(x + 1);
    if (y >= h)
        return (size_t)(w + 2) + (size_t)(x + 1);
    if (x < 0)
        return 2 * (size_t)(w + 2) + (size_t)y;
    return 2 * (size_t)(w + 2) + (size_t)h + (size_t)y;
}

static void tile_rect(const dr_job *j, size_t t, int *x0, int *y0, int *w, int *h)
{
    *x0 = (int)(t % (size_t)j->ntx) * j->T;
    *y0 = (int)(t / (size_t)j->ntx) * j->T;
    *w = TS_MIN(j->T, j->W - *x0);
    *h = TS_MIN(j->T, j->H - *y0);
}

/* The global perimeter index of DEM cell (gx, gy) (every cell beside
 * another tile is on its own tile's perimeter). */
static size_t perim_of(const dr_job *j, int gx, int gy)
{
    size_t t = (size_t)(gy / j->T) * (size_t)j->ntx + (size_t)(gx / j->T);
    int x0, y0, w, h;
    tile_rect(j, t, &x0, &y0, &w, &h);
    return j->pbase[t] + (size_t)perim_local(w, h, gx - x0, gy - y0);
}

static void job_fail(dr_job *j)
{
    atomic_store(&j->failed, 1);
}

static int tile_alloc(dr_tile *k, int tw, int th)
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

static void tile_free(dr_tile *k)
{
    free(k->cell);
    free(k->dir);
    free(k->bnd);
    free(k->indeg);
    free(k->acc);
    free(k->order);
    rh_free(&k->q);
}

/* Read tile t with its halo (NaN off the DEM); its boundary cells. */
static int tile_read(dr_job *j, dr_tile *k, size_t t)
{
    int rx0, ry0, rx1, ry1, x, y, d;
    ts_status st;
    k->t = (int)t;
    tile_rect(j, t, &k->x0, &k->y0, &k->w, &k->h);
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
            k->cell[hx(k, x, y)].v =
                gx < rx0 || gy < ry0 || gx >= rx1 || gy >= ry1
                    ? NAN
                    : ((const float *)k->acc)[(size_t)(gy - ry0) * (size_t)(rx1 - rx0) +
                                              (size_t)(gx - rx0)];
        }
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            int b = 0;
            if (!isnan(k->cell[hx(k, x, y)].v))
                for (d = 0; d < 8 && !b; d++)
                    b = isnan(k->cell[hx(k, x + ppa_dir[d][0], y + ppa_dir[d][1])].v);
            k->bnd[(size_t)y * (size_t)k->w + (size_t)x] = (unsigned char)b;
        }
    return 0;
}

/* Phase A's priority-flood of the tile from its own seeds, boundary and
 * perimeter cells at their heights, each labelling the cells it reaches
 * (1: the boundary, 2 + k: perimeter cell k).  F of the tile alone. */
static int tile_flood(dr_tile *k)
{
    int x, y, d;
    uint32_t counter = 0;
    rh_reset(&k->q);
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t c = hx(k, x, y);
            float hv = k->cell[c].v, lv;
            long p = perim_local(k->w, k->h, x, y);
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
            if (rh_push(&k->q, flood_key(lv, counter++), c) != 0)
                return -1;
        }
    while (k->q.size) {
        rh_item it;
        int cx, cy;
        float level;
        if (rh_pop(&k->q, &it) != 0)
            return -1;
        level = key_height(it.key);
        cx = (int)(it.v % (size_t)k->hw) - 1;
        cy = (int)(it.v / (size_t)k->hw) - 1;
        for (d = 0; d < 8; d++) {
            int nx = cx + ppa_dir[d][0], ny = cy + ppa_dir[d][1];
            size_t c;
            float nh;
            if (nx < 0 || ny < 0 || nx >= k->w || ny >= k->h)
                continue;
            c = hx(k, nx, ny);
            if (k->cell[c].L)
                continue;
            nh = k->cell[c].v;
            if (isnan(nh))
                continue;
            k->cell[c].L = k->cell[it.v].L;
            k->cell[c].v = nh > level ? nh : level;
            if (rh_push(&k->q, flood_key(k->cell[c].v, counter++), c) != 0)
                return -1;
        }
    }
    return 0;
}

/* The key of a cell in the routing flood: F, then D. */
static uint64_t route_key(float f, uint32_t d)
{
    return flood_key(f, 0) | d;
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
static size_t tile_route(dr_job *j, dr_tile *k, const uint32_t *Dsrc)
{
    int x, y, d, multi = j->ntiles > 1;
    size_t pb = j->pbase[k->t], taken = 0;
    unsigned char *st = k->indeg;
    rh_reset(&k->q);
    /* the halo: F and D of the neighbours' perimeter cells */
    for (y = -1; y <= k->h; y++)
        for (x = -1; x <= k->w; x++) {
            size_t c, p;
            if (x >= 0 && y >= 0 && x < k->w && y < k->h)
                continue;
            c = hx(k, x, y);
            k->cell[c].L = DINF;
            if (isnan(k->cell[c].v))
                continue;
            p = perim_of(j, k->x0 + x, k->y0 + y);
            k->cell[c].v = j->G[p];
            k->cell[c].L = Dsrc[p];
        }
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t i0 = (size_t)y * (size_t)k->w + (size_t)x, c = hx(k, x, y);
            long p;
            st[i0] = ST_NEW;
            if (isnan(k->cell[c].v))
                continue;
            if (k->bnd[i0]) {
                k->cell[c].L = 0;
            } else if (multi && (p = perim_local(k->w, k->h, x, y)) >= 0) {
                float f = j->G[pb + (size_t)p];
                uint32_t dv = DINF;
                k->cell[c].v = f;
                for (d = 0; d < 8 && dv; d++) {
                    int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
                    const dr_cell *n;
                    if (nx >= 0 && ny >= 0 && nx < k->w && ny < k->h)
                        continue;
                    n = &k->cell[hx(k, nx, ny)];
                    if (n->v < f)
                        dv = 0;
                    else if (n->v == f && n->L != DINF && n->L + 1 < dv)
                        dv = n->L + 1;
                }
                k->cell[c].L = dv;
            } else {
                continue;
            }
            st[i0] = ST_HEAP;
            if (rh_push(&k->q, route_key(k->cell[c].v, k->cell[c].L), c) != 0)
                return (size_t)-1;
        }
    while (k->q.size) {
        rh_item it;
        int cx, cy;
        const dr_cell *u;
        if (rh_pop(&k->q, &it) != 0)
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
            dr_cell *n;
            uint32_t dv;
            if (nx < 0 || ny < 0 || nx >= k->w || ny >= k->h)
                continue;
            ni = (size_t)ny * (size_t)k->w + (size_t)nx;
            c = hx(k, nx, ny);
            n = &k->cell[c];
            if (st[ni] == ST_DONE || isnan(n->v))
                continue;
            if (st[ni] == ST_NEW) {
                if (n->v > u->v) {
                    n->L = 0;
                } else {
                    n->v = u->v;
                    n->L = u->L == DINF ? DINF : u->L + 1;
                }
                st[ni] = ST_HEAP;
            } else {
                /* a waiting cell: its F is known; a way out through u? */
                dv = n->v > u->v ? 0 : u->L == DINF ? DINF : u->L + 1;
                if (dv >= n->L)
                    continue;
                n->L = dv;
            }
            if (rh_push(&k->q, route_key(n->v, n->L), c) != 0)
                return (size_t)-1;
        }
    }
    /* the flow: to the neighbour of least (F, D), ties to the first */
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            size_t i0 = (size_t)y * (size_t)k->w + (size_t)x;
            const dr_cell *c = &k->cell[hx(k, x, y)];
            int best = DIR_OUT;
            float bf = c->v;
            uint32_t bd = c->L;
            if (isnan(bf)) {
                k->dir[i0] = 255;
                continue;
            }
            if (!k->bnd[i0])
                for (d = 0; d < 8; d++) {
                    const dr_cell *n = &k->cell[hx(k, x + ppa_dir[d][0], y + ppa_dir[d][1])];
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
static void tile_areas(dr_job *j, dr_tile *k, size_t taken, const double *in)
{
    size_t i, pb = j->pbase[k->t];
    int x, y;
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            long p = perim_local(k->w, k->h, x, y);
            k->acc[(size_t)y * (size_t)k->w + (size_t)x] =
                1.0 + (in && p >= 0 ? in[pb + (size_t)p] : 0.0);
        }
    for (i = taken; i-- > 0;) {
        size_t c = k->order[i];
        int dd = k->dir[c], tx, ty;
        if (dd == DIR_OUT)
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
 * gives the areas tile_areas gives. */
static size_t tile_topo_areas(dr_job *j, dr_tile *k, const double *in)
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
        size_t np = perim_count(k->w, k->h), q;
        for (q = 0; q < np; q++) {
            perim_xy(k->w, k->h, q, &x, &y);
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

/* Append an edge to a growing list; -1 when out of memory. */
static int edge_push(dr_edge **e, size_t *n, size_t *cap, uint64_t u, uint64_t v, float w)
{
    if (*n == *cap) {
        size_t nc = *cap ? 2 * *cap : 1024;
        dr_edge *g = realloc(*e, nc * sizeof *g);
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
    const dr_edge *a = pa, *b = pb;
    if (a->w != b->w)
        return a->w < b->w ? -1 : 1;
    if (a->u != b->u)
        return a->u < b->u ? -1 : 1;
    return a->v < b->v ? -1 : a->v > b->v;
}

/* Phase A on tile t: its labels' minimum spanning forest into the job's
 * edges, and its perimeter heights. */
static int phase_a(dr_job *j, dr_tile *k)
{
    int x, y, d;
    size_t pb = j->pbase[k->t], np = perim_count(k->w, k->h), ne = 0, cap = 0, i, kept = 0;
    dr_edge *e = NULL;
    uint32_t *uf = NULL;
    int rc = -1;
    if (tile_flood(k) != 0)
        return -1;
    if (j->Fc) /* kept: the tile's F alone and its labels, for PH_FLATS */
        for (y = 0; y < k->h; y++)
            for (x = 0; x < k->w; x++) {
                size_t g = (size_t)(k->y0 + y) * (size_t)j->W + (size_t)(k->x0 + x);
                j->Fc[g] = k->cell[hx(k, x, y)].v;
                j->Dc[g] = k->cell[hx(k, x, y)].L;
            }
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x++) {
            long p = perim_local(k->w, k->h, x, y);
            size_t c = hx(k, x, y);
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
                n = hx(k, nx, ny);
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
        dr_edge *g = realloc(j->edges, nc * sizeof *g);
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
static int solve_perimeter_f(dr_job *j)
{
    size_t nn = j->np + 1, i, t, *off = NULL, *adj = NULL;
    float *ew = NULL, *best = NULL;
    unsigned char *done = NULL;
    radix_heap q;
    uint32_t counter = 0;
    int rc = -1, d;
    memset(&q, 0, sizeof q);
    /* the pairs of neighbouring perimeter cells of different tiles */
    for (t = 0; t < j->ntiles; t++) {
        int x0, y0, w, h, x, y;
        tile_rect(j, t, &x0, &y0, &w, &h);
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                long lp = perim_local(w, h, x, y);
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
                    qq = perim_of(j, gx, gy);
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
            const dr_edge *e = &j->edges[i];
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
    if (rh_push(&q, flood_key(-INFINITY, counter++), 0) != 0)
        goto out;
    while (q.size) {
        rh_item it;
        size_t u, a;
        float lv;
        if (rh_pop(&q, &it) != 0)
            goto out;
        u = (size_t)it.v;
        if (done[u])
            continue;
        done[u] = 1;
        lv = key_height(it.key);
        for (a = off[u]; a < off[u + 1]; a++) {
            size_t v = adj[a];
            float nl = TS_MAX(lv, ew[a]);
            if (!done[v] && nl < best[v]) {
                best[v] = nl;
                if (rh_push(&q, flood_key(nl, counter++), v) != 0)
                    goto out;
            }
        }
    }
    for (i = 0; i < j->np; i++)
        j->G[i] = isnan(j->ph[i]) ? NAN : j->pbnd[i] ? j->ph[i] : TS_MAX(best[i + 1], j->ph[i]);
    rc = 0;
out:
    rh_free(&q);
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
static void halo_sensitivity(dr_job *j, dr_tile *k)
{
    unsigned char *sens = j->hsens + j->hbase[k->t];
    int x, y, d, e;
    memset(sens, 0, halo_count(k->w, k->h));
    for (y = 0; y < k->h; y++)
        for (x = 0; x < k->w; x += (y == 0 || y == k->h - 1) ? 1 : TS_MAX(1, k->w - 1)) {
            const dr_cell *c = &k->cell[hx(k, x, y)];
            if (isnan(c->v))
                continue;
            for (d = 0; d < 8; d++) {
                int qx = x + ppa_dir[d][0], qy = y + ppa_dir[d][1];
                const dr_cell *q;
                int hit;
                if (qx >= 0 && qy >= 0 && qx < k->w && qy < k->h)
                    continue;
                q = &k->cell[hx(k, qx, qy)];
                if (isnan(q->v))
                    continue;
                hit = q->v == c->v;
                for (e = 0; e < 8 && !hit; e++)
                    if (e != d) {
                        const dr_cell *r = &k->cell[hx(k, x + ppa_dir[e][0], y + ppa_dir[e][1])];
                        hit = r->v == q->v;
                    }
                if (hit)
                    sens[halo_index(k->w, k->h, qx, qy)] = 1;
            }
        }
}

/* Kept: tile k's perimeter D, from its cells', into Dnew. */
static void kept_perimeter_d(dr_job *j, const dr_tile *k)
{
    size_t pb = j->pbase[k->t], q, np = perim_count(k->w, k->h);
    int x, y;
    for (q = 0; q < np; q++) {
        perim_xy(k->w, k->h, q, &x, &y);
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
static void tile_flats(dr_job *j, dr_tile *k)
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
            uint32_t dv = DINF;
            if (isnan(f)) {
                j->Dc[g] = DINF;
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
                         : j->G[perim_of(j, gx, gy)];
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
            if (j->Dc[gn] == DINF && j->Fc[gn] == f) {
                j->Dc[gn] = du + 1;
                k->order[tail++] = (uint32_t)(ny * k->w + nx);
            }
        }
    }
    kept_perimeter_d(j, k);
}

/* Kept: D of tile k lowered where a neighbour across its border offers a
 * lower D on a flat, and on along the flat (breadth-first on D). */
static int tile_relax(dr_job *j, dr_tile *k)
{
    int x, y, d;
    rh_reset(&k->q);
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
                q = perim_of(j, gx, gy);
                if (j->G[q] == f && j->D[q] != DINF && j->D[q] + 1 < dv)
                    dv = j->D[q] + 1;
            }
            if (dv < j->Dc[g]) {
                j->Dc[g] = dv;
                if (rh_push(&k->q, dv, g) != 0)
                    return -1;
            }
        }
    while (k->q.size) {
        rh_item it;
        size_t g;
        int cx, cy;
        uint32_t du;
        float f;
        if (rh_pop(&k->q, &it) != 0)
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
                if (rh_push(&k->q, du + 1, gn) != 0)
                    return -1;
            }
        }
    }
    kept_perimeter_d(j, k);
    return 0;
}

/* Kept, once D holds still: tile k's flow from F and D (the neighbours'
 * too: nothing is written to them now), into k->dir and j->dirs. */
static void tile_dirs_kept(dr_job *j, dr_tile *k)
{
    ptrdiff_t off[8];
    int x, y, d;
    neighbour_offsets(j->W, off);
    for (y = 0; y < k->h; y++) {
        int gy = k->y0 + y;
        unsigned char *row = k->dir + (size_t)y * (size_t)k->w;
        for (x = 0; x < k->w; x++) {
            int gx = k->x0 + x, best = DIR_OUT;
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
static void tile_exit(dr_job *j, dr_tile *k, size_t c)
{
    size_t pb = j->pbase[k->t];
    int dd = k->dir[c], cx = (int)(c % (size_t)k->w), cy = (int)(c / (size_t)k->w), tx, ty;
    long p = perim_local(k->w, k->h, cx, cy);
    uint32_t ex = DINF;
    if (dd < 8) {
        tx = cx + ppa_dir[dd][0];
        ty = cy + ppa_dir[dd][1];
        if (tx < 0 || ty < 0 || tx >= k->w || ty >= k->h) {
            ex = (uint32_t)p;
            j->target[pb + (size_t)p] = perim_of(j, k->x0 + tx, k->y0 + ty);
            j->A[pb + (size_t)p] = k->acc[c];
        } else {
            ex = k->cell[hx(k, tx, ty)].L;
        }
    }
    k->cell[hx(k, cx, cy)].L = ex;
    if (p >= 0)
        j->link[pb + (size_t)p] = ex == DINF ? NONE : pb + ex;
}

/* Kept: tile k's areas alone, then its exits (C), downstream first. */
static void tile_exits_kept(dr_job *j, dr_tile *k)
{
    size_t i, n = tile_topo_areas(j, k, NULL);
    for (i = n; i-- > 0;)
        tile_exit(j, k, k->order[i]);
}

/* Phases A, B (with C's exits) and D on a tile. */
static int tile_phase(dr_job *j, dr_tile *k, size_t t)
{
    size_t pb = j->pbase[t], i, n;
    int x, y;
    if (j->phase == PH_FLATS || j->phase == PH_RELAX || j->phase == PH_FLOW ||
        (j->phase == PH_AREAS && j->Fc)) {
        /* kept: no reading, no routing */
        k->t = (int)t;
        tile_rect(j, t, &k->x0, &k->y0, &k->w, &k->h);
        k->hw = k->w + 2;
        if (j->phase == PH_FLATS) {
            tile_flats(j, k);
            return 0;
        }
        if (j->phase == PH_RELAX)
            return tile_relax(j, k);
        if (j->phase == PH_FLOW) {
            tile_dirs_kept(j, k);
            tile_exits_kept(j, k);
            return 0;
        }
        for (y = 0; y < k->h; y++)
            memcpy(k->dir + (size_t)y * (size_t)k->w,
                   j->dirs + (size_t)(k->y0 + y) * (size_t)j->W + (size_t)k->x0, (size_t)k->w);
        tile_topo_areas(j, k, j->in);
        goto emit;
    }
    if (tile_read(j, k, t) != 0)
        return -1;
    if (j->phase == PH_LABELS)
        return phase_a(j, k);
    n = tile_route(j, k, j->D);
    if (n == (size_t)-1)
        return -1;
    if (j->phase == PH_ROUTE) {
        /* D from the neighbours' last D */
        for (y = 0; y < k->h; y++)
            for (x = 0; x < k->w; x++) {
                long p = perim_local(k->w, k->h, x, y);
                if (p >= 0)
                    j->Dnew[pb + (size_t)p] = k->cell[hx(k, x, y)].L;
            }
        /* C, from this routing (the last one of the tile's is made on the
         * final D): the exits, perimeter cells draining into another tile;
         * then each perimeter cell's exit, downstream first (k->cell[].L
         * reused) */
        tile_areas(j, k, n, NULL);
        for (i = pb; i < j->pbase[t + 1]; i++) { /* an earlier routing's exits go */
            j->target[i] = NONE;
            j->A[i] = 0;
        }
        for (i = 0; i < n; i++)
            tile_exit(j, k, k->order[i]);
        halo_sensitivity(j, k);
        return 0;
    }
    tile_areas(j, k, n, j->ntiles > 1 ? j->in : NULL);
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
    j->emit(j->emit_user, k->x0, k->y0, k->w, k->h, (const float *)k->acc);
    pthread_mutex_unlock(&j->lock);
    return 0;
}

/* A worker: tiles taken one at a time while any is left (tiles differ in
 * their work; each tile's result is its own, whoever makes it). */
static void tiles_range(void *arg, size_t b, size_t e)
{
    dr_job *j = arg;
    dr_tile k;
    size_t t;
    (void)b;
    (void)e;
    if (tile_alloc(&k, TS_MIN(j->T, j->W), TS_MIN(j->T, j->H)) != 0) {
        job_fail(j);
        tile_free(&k);
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
    tile_free(&k);
}

static ts_status run_phase(dr_job *j, int phase)
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
static int solve_inflow(dr_job *j)
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
        if (j->target[i] != NONE && j->link[j->target[i]] != NONE)
            indeg[j->link[j->target[i]]]++;
    }
    for (i = 0; i < j->np; i++)
        if (j->target[i] != NONE && indeg[i] == 0)
            queue[tail++] = i;
    while (head < tail) {
        size_t e = queue[head++], p = j->target[e], nx;
        j->in[p] += total[e];
        nx = j->link[p];
        if (nx == NONE)
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
static int flat_pairs(const dr_job *j, size_t t)
{
    int x0, y0, w, h, x, y, d;
    size_t k, np;
    tile_rect(j, t, &x0, &y0, &w, &h);
    np = perim_count(w, h);
    for (k = 0; k < np; k++) {
        size_t p = j->pbase[t] + k;
        if (isnan(j->ph[p]) || j->D[p] == 0)
            continue;
        perim_xy(w, h, k, &x, &y);
        for (d = 0; d < 8; d++) {
            int nx = x0 + x + ppa_dir[d][0], ny = y0 + y + ppa_dir[d][1];
            size_t q;
            if (nx < 0 || ny < 0 || nx >= j->W || ny >= j->H ||
                (nx >= x0 && ny >= y0 && nx < x0 + w && ny < y0 + h))
                continue;
            q = perim_of(j, nx, ny);
            if (!isnan(j->ph[q]) && j->G[q] == j->G[p] && j->D[q] != DINF &&
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
static int halo_changed(const dr_job *j, size_t t, const uint32_t *old)
{
    const unsigned char *sens = j->hsens + j->hbase[t];
    int x0, y0, w, h, x, y;
    tile_rect(j, t, &x0, &y0, &w, &h);
    for (y = y0 - 1; y <= y0 + h; y++)
        for (x = x0 - 1; x <= x0 + w; x += (y == y0 - 1 || y == y0 + h) ? 1 : w + 1) {
            size_t p;
            if (x < 0 || y < 0 || x >= j->W || y >= j->H ||
                !sens[halo_index(w, h, x - x0, y - y0)])
                continue;
            p = perim_of(j, x, y);
            if (old[p] != j->D[p])
                return 1;
        }
    return 0;
}

ts_status ppa_drainage(ts_ctx *ctx, int W, int H, int tile, int keep, ts_window_read_fn read,
                       void *user, ppa_area_fn emit, void *emit_user)
{
    dr_job j;
    size_t t, i;
    ts_status st = TS_OK;
    int round;
    memset(&j, 0, sizeof j);
    atomic_init(&j.failed, 0);
    atomic_init(&j.next, 0);
    j.ctx = ctx;
    j.W = W;
    j.H = H;
    j.T = TS_MAX(2, TS_MIN(tile, TS_MAX(W, H)));
    if ((size_t)(j.T + 2) * (size_t)(j.T + 2) >= UINT32_MAX)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa drainage", "tiles of %d cells are too large", tile);
    j.ntx = (W + j.T - 1) / j.T;
    j.nty = (H + j.T - 1) / j.T;
    j.ntiles = (size_t)j.ntx * (size_t)j.nty;
    j.read = read;
    j.user = user;
    j.emit = emit;
    j.emit_user = emit_user;
    pthread_mutex_init(&j.lock, NULL);
    j.pbase = ts__malloc_array(j.ntiles + 1, sizeof *j.pbase);
    j.hbase = ts__malloc_array(j.ntiles + 1, sizeof *j.hbase);
    j.due = ts__malloc_array(j.ntiles, 1);
    if (!j.pbase || !j.due || !j.hbase) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa drainage", "out of memory");
        goto out;
    }
    j.hbase[0] = 0;
    for (t = 0; t < j.ntiles; t++) {
        int x0, y0, w, h;
        tile_rect(&j, t, &x0, &y0, &w, &h);
        j.pbase[t] = j.np;
        j.np += perim_count(w, h);
        j.hbase[t + 1] = j.hbase[t] + halo_count(w, h);
    }
    j.pbase[j.ntiles] = j.np;
    j.hsens = ts__malloc_array(j.hbase[j.ntiles], 1);
    j.ph = ts__malloc_array(j.np, sizeof *j.ph);
    j.pbnd = ts__calloc_array(j.np, 1);
    j.G = ts__malloc_array(j.np, sizeof *j.G);
    j.D = ts__malloc_array(j.np, sizeof *j.D);
    j.Dnew = ts__malloc_array(j.np, sizeof *j.Dnew);
    j.target = ts__malloc_array(j.np, sizeof *j.target);
    j.link = ts__malloc_array(j.np, sizeof *j.link);
    j.A = ts__calloc_array(j.np, sizeof *j.A);
    j.in = ts__calloc_array(j.np, sizeof *j.in);
    if (keep && j.ntiles > 1) {
        j.Fc = ts__malloc_array((size_t)W * (size_t)H, sizeof *j.Fc);
        j.Dc = ts__malloc_array((size_t)W * (size_t)H, sizeof *j.Dc);
        j.dirs = ts__malloc_array((size_t)W * (size_t)H, 1);
    }
    if (!j.ph || !j.pbnd || !j.G || !j.D || !j.Dnew || !j.target || !j.link || !j.A || !j.in ||
        !j.hsens ||
        (keep && j.ntiles > 1 && (!j.Fc || !j.Dc || !j.dirs))) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa drainage", "out of memory for %zu tile borders",
                      j.np);
        goto out;
    }
    for (i = 0; i < j.np; i++) {
        j.D[i] = j.Dnew[i] = DINF;
        j.target[i] = j.link[i] = NONE;
    }
    memset(j.due, 1, j.ntiles);
    if (j.ntiles > 1) {
        /* A: F on the tiles' perimeters */
        if ((st = run_phase(&j, PH_LABELS)) != TS_OK)
            goto out;
        if (solve_perimeter_f(&j) != 0) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "ppa drainage", "out of memory");
            goto out;
        }
        if ((st = ts__progress(ctx, 0.3, "drainage: spill heights")) != TS_OK)
            goto out;
        /* B: D across tiles, in rounds until it holds still, and C: each
         * routing's exits (the last routing of every tile reads the final D) */
        for (round = 0;; round++) {
            int any = 0;
            if ((st = run_phase(&j, !j.Fc ? PH_ROUTE : round == 0 ? PH_FLATS : PH_RELAX)) !=
                TS_OK)
                goto out;
            /* again: the tiles beside a perimeter cell whose D changed (Dnew
             * takes the old D for the test; D falls, round by round, to the
             * flow's D) */
            {
                uint32_t *old = j.D;
                j.D = j.Dnew;
                j.Dnew = old;
            }
            for (t = 0; t < j.ntiles; t++)
                any |= j.due[t] = (unsigned char)(j.Fc ? flat_pairs(&j, t)
                                                       : halo_changed(&j, t, j.Dnew));
            /* a round after the first that lowered no D: the next would be the same */
            if (round > 0 && memcmp(j.Dnew, j.D, j.np * sizeof *j.D) == 0)
                any = 0;
            memcpy(j.Dnew, j.D, j.np * sizeof *j.D);
            if (!any)
                break;
        }
        memset(j.due, 1, j.ntiles);
        if ((st = ts__progress(ctx, 0.6, "drainage: flats")) != TS_OK)
            goto out;
        /* C: the tiles' exits (kept: from F and D now), summed in flow order */
        if (j.Fc && (st = run_phase(&j, PH_FLOW)) != TS_OK)
            goto out;
        if (solve_inflow(&j) != 0) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "ppa drainage", "out of memory");
            goto out;
        }
    }
    /* D: the areas */
    st = run_phase(&j, PH_AREAS);
    if (st == TS_OK)
        st = ts__progress(ctx, 1.0, "drainage");
out:
    pthread_mutex_destroy(&j.lock);
    free(j.pbase);
    free(j.due);
    free(j.ph);
    free(j.pbnd);
    free(j.G);
    free(j.D);
    free(j.Dnew);
    free(j.edges);
    free(j.target);
    free(j.link);
    free(j.A);
    free(j.in);
    free(j.Fc);
    free(j.Dc);
    free(j.dirs);
    free(j.hbase);
    free(j.hsens);
    return st;
}

/* ---- the drainage test: a bit a cell ---- */

typedef struct channel_io {
    uint64_t *bits;
    int width;
    double min_drainage;
} channel_io;

static void channel_emit(void *user, int x0, int y0, int w, int h, const float *area)
{
    channel_io *io = user;
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            if (area[(size_t)y * (size_t)w + (size_t)x] >= io->min_drainage) {
                uint64_t g = (uint64_t)(y0 + y) * (uint64_t)io->width + (uint64_t)(x0 + x);
                io->bits[g >> 6] |= (uint64_t)1 << (g & 63);
            }
}

ts_status ppa_channels(ts_ctx *ctx, int width, int height, int tile, int keep,
                       ts_window_read_fn read, void *user, double min_drainage, uint64_t **bits)
{
    size_t n = (size_t)width * (size_t)height;
    channel_io io;
    ts_status st;
    *bits = ts__calloc_array((n + 63) / 64, sizeof **bits);
    if (!*bits)
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "cannot allocate the drainage bits of %d x %d cells",
                        width, height);
    io.bits = *bits;
    io.width = width;
    io.min_drainage = min_drainage;
    st = ppa_drainage(ctx, width, height, tile, keep, read, user, channel_emit, &io);
    if (st != TS_OK) {
        free(*bits);
        *bits = NULL;
    }
    return st;
}

/* ---- in memory ---- */

typedef struct mem_io {
    const ts_raster *dem;
    float *area;
} mem_io;

ts_status ppa_raster_window(void *dem, int x0, int y0, int w, int h, float *buf)
{
    const ts_raster *r = dem;
    int y;
    for (y = 0; y < h; y++)
        memcpy(buf + (size_t)y * (size_t)w, &TS_PIX(r, x0, y0 + y), (size_t)w * sizeof *buf);
    return TS_OK;
}

static void mem_emit(void *user, int x0, int y0, int w, int h, const float *area)
{
    mem_io *m = user;
    int y;
    for (y = 0; y < h; y++)
        memcpy(m->area + (size_t)(y0 + y) * (size_t)m->dem->width + (size_t)x0,
               area + (size_t)y * (size_t)w, (size_t)w * sizeof *area);
}

ts_status ppa_drainage_area(ts_ctx *ctx, const ts_raster *dem, float *area, int tile, int keep)
{
    mem_io m;
    m.dem = dem;
    m.area = area;
    return ppa_drainage(ctx, dem->width, dem->height, tile, keep, ppa_raster_window, (void *)dem,
                        mem_emit,
                        &m);
}
