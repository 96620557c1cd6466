/*
 * dammed_basins.c - the basins a breach leaves beside a drawn valley's floor
 * raised to plains graded to their pour points (ours:
 * ts_drainage_params.floodplain_relief), on the whole grid.
 *
 * A drawn valley's floor is fixed, and the land beside it (TS_CELL_SHALLOW)
 * is cut at most the shallow depth, so that no trench runs along the floor.
 * A basin there lower than the floor (a junction's land laid out lower than
 * the floor that crosses it) can then only drain by cutting the floor itself
 * down the valley, and the breach keeps it.  Real land beside a valley is
 * graded to it: the floor is its base level, and what lies below it is a
 * plain of the valley's fill.  So:
 *   - a priority flood (Barnes et al. 2014: a heap of the cells by height
 *     from the grid's edge and the cells beside nodata inwards, a queue for
 *     the cells it raises; after Zhou et al. 2016, a cell reached from lower
 *     land and with no lower cell beside it left is taken at once, out of
 *     the heap) gives each cell its spill level, the lowest level at which
 *     water standing on it would flow out;
 *   - the cells below their spill form the basins (8-connected); a basin
 *     any of whose cells or their eight neighbours is TS_CELL_SHALLOW (the
 *     band beside a floor) is dammed, unless one is a fixed cell not water
 *     below its spill (a pin's: land raised round it would stand as a step);
 *   - a dammed basin deeper than `relief` is raised above its spill, to a
 *     plain graded to its pour point: z' = spill + relief / 3 (steps / most
 *     steps + 1) + fine, the steps taken within the basin from the cells
 *     beside the pour point, fine the cell's height above the mean of its
 *     basin's cells within 2 cells clamped to +-relief / 3 (the land's own
 *     shape at the scale of a few cells: a low plain with the land's grain,
 *     not a lake's flat); so spill < z' <= spill + relief; no cell lowered,
 *     fixed cells left as they are.
 * The breach that follows cuts what pits the plain's shape leaves, no deeper
 * than `relief`, down to the pour point.  The flood's levels are a function
 * of the surface alone, so the result does not depend on the order of the
 * cells' ties.  A grid with no cell that dams is drained once, no flood.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../base/internal.h"

typedef struct db_item {
    float z;
    uint32_t at;
} db_item;

typedef struct db_heap {
    db_item *v;
    size_t n, cap;
} db_heap;

static int db_less(db_item a, db_item b)
{
    return a.z < b.z || (a.z == b.z && a.at < b.at);
}

static int db_push(db_heap *h, float z, uint32_t at)
{
    size_t i;
    if (h->n == h->cap) {
        size_t cap = h->cap ? 2 * h->cap : 4096;
        db_item *v = realloc(h->v, cap * sizeof *v);
        if (!v)
            return -1;
        h->v = v;
        h->cap = cap;
    }
    i = h->n++;
    h->v[i].z = z;
    h->v[i].at = at;
    while (i > 0 && db_less(h->v[i], h->v[(i - 1) / 2])) {
        db_item t = h->v[i];
        h->v[i] = h->v[(i - 1) / 2];
        h->v[(i - 1) / 2] = t;
        i = (i - 1) / 2;
    }
    return 0;
}

static db_item db_pop(db_heap *h)
{
    db_item top = h->v[0];
    size_t i = 0;
    h->v[0] = h->v[--h->n];
    for (;;) {
        size_t l = 2 * i + 1, r = l + 1, m = i;
        if (l < h->n && db_less(h->v[l], h->v[m]))
            m = l;
        if (r < h->n && db_less(h->v[r], h->v[m]))
            m = r;
        if (m == i)
            break;
        db_item t = h->v[i];
        h->v[i] = h->v[m];
        h->v[m] = t;
        i = m;
    }
    return top;
}

static const int DX[8] = {-1, 0, 1, -1, 1, -1, 0, 1}, DY[8] = {-1, -1, -1, 0, 0, 1, 1, 1};

/* The index of cell c's neighbour k (DX, DY) on a w x h grid, -1 off the grid. */
static ptrdiff_t nb_of(int w, int h, uint32_t c, int k)
{
    int u = (int)(c % (uint32_t)w) + DX[k], v = (int)(c / (uint32_t)w) + DY[k];
    return u < 0 || v < 0 || u >= w || v >= h ? -1 : (ptrdiff_t)v * w + u;
}

/* Whether cell c of z has a neighbour not yet reached (closed) lower than itself. */
static int lower_open(const float *z, const unsigned char *closed, int w, int h, uint32_t c)
{
    int k;
    for (k = 0; k < 8; k++) {
        ptrdiff_t j = nb_of(w, h, c, k);
        if (j < 0)
            continue;
        if (!closed[j] && z[j] < z[c])
            return 1;
    }
    return 0;
}

/* The spill level of every cell of z (w x h, NaN nodata) into `level` (NaN for nodata): the
 * grid's edge and the cells beside nodata drain out.  -1 out of memory. */
int ts__spill_levels(const float *z, int w, int h, float *level)
{
    size_t n = (size_t)w * (size_t)h, qh = 0, qt = 0, nt = 0;
    unsigned char *closed = calloc(n, 1);
    uint32_t *queue = malloc(n * sizeof *queue), *up = malloc(n * sizeof *up);
    db_heap heap = {NULL, 0, 0};
    int x, y, k, rc = -1;
    if (!closed || !queue || !up)
        goto done;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            int out = x == 0 || y == 0 || x == w - 1 || y == h - 1;
            level[i] = z[i];
            if (isnan(z[i])) {
                closed[i] = 1;
                continue;
            }
            for (k = 0; k < 8 && !out; k++)
                out = isnan(z[i + (ptrdiff_t)DY[k] * w + DX[k]]);
            if (out) {
                closed[i] = 1;
                if (db_push(&heap, z[i], (uint32_t)i) != 0)
                    goto done;
            }
        }
    /* queue: cells raised to the level of the cell that reached them; up: cells reached
     * from lower, at their own height (final: their way out never rises above it), taken
     * at once unless a lower cell beside them is not reached yet (then in height order) */
    while (qh < qt || nt || heap.n) {
        uint32_t c;
        int early = 0;
        if (qh < qt) {
            c = queue[qh++];
        } else if (nt) {
            c = up[--nt];
            if (lower_open(z, closed, w, h, c)) {
                if (db_push(&heap, z[c], c) != 0)
                    goto done;
                continue;
            }
            early = 1; /* out of height order: its neighbours, none lower, at their own */
        } else {
            c = db_pop(&heap).at;
        }
        for (k = 0; k < 8; k++) {
            ptrdiff_t j = nb_of(w, h, c, k);
            if (j < 0)
                continue;
            if (closed[j])
                continue;
            closed[j] = 1;
            if (z[j] <= level[c] && !early) {
                level[j] = level[c];
                queue[qt++] = (uint32_t)j;
            } else {
                up[nt++] = (uint32_t)j;
            }
        }
    }
    rc = 0;
done:
    free(closed);
    free(queue);
    free(up);
    free(heap.v);
    return rc;
}

/* What a cell in or beside a basin of level `lv` says of it: DB_DAMMED, a drawn valley floor's
 * bank (TS_CELL_SHALLOW: the floor lies in that band); DB_HELD, a fixed cell not water below the
 * basin's level (a pin's: the land raised round it would stand as a step against it). */
enum { DB_DAMMED = 1, DB_HELD = 2 };

static int damming(const float *z, const unsigned char *flags, size_t i, float lv)
{
    return ((flags[i] & TS_CELL_SHALLOW) ? DB_DAMMED : 0) |
           ((flags[i] & TS_CELL_FIXED) && !(flags[i] & TS_CELL_WATER) && z[i] < lv ? DB_HELD : 0);
}

/* One basin from cell s (below its spill): its cells into `cells` (n), its depth, and
 * whether a dammed one.  seen marks the cells taken. */
static size_t db_basin(const float *z, const float *level, const unsigned char *flags, int w, int h,
                       size_t s, unsigned char *seen, uint32_t *cells, double *depth, int *dammed)
{
    size_t n = 0, head = 0;
    int k;
    cells[n++] = (uint32_t)s;
    seen[s] = 1;
    *depth = 0.0;
    *dammed = 0;
    while (head < n) {
        uint32_t c = cells[head++];
        if ((double)level[c] - (double)z[c] > *depth)
            *depth = (double)level[c] - (double)z[c];
        *dammed |= damming(z, flags, c, level[c]);
        for (k = 0; k < 8; k++) {
            ptrdiff_t j = nb_of(w, h, c, k);
            if (j < 0)
                continue;
            if (isnan(z[j]))
                continue;
            if (!(level[j] > z[j])) {
                *dammed |= damming(z, flags, (size_t)j, level[c]);
                continue;
            }
            if (!seen[j]) {
                seen[j] = 1;
                cells[n++] = (uint32_t)j;
            }
        }
    }
    return n;
}

/* Each cell of a basin (cells[0..m)) its steps (8-connected, within the basin) from the cells
 * beside its pour point (a neighbour outside it at the basin's level) into dist, a queue; the
 * most steps, 0 when it has no pour point. */
static uint32_t db_steps(const float *z, const float *level, int w, int h, const uint32_t *cells,
                         size_t m, uint32_t *dist, uint32_t *queue)
{
    size_t c, qh = 0, qt = 0;
    uint32_t most = 0;
    int k;
    for (c = 0; c < m; c++)
        dist[cells[c]] = UINT32_MAX;
    for (c = 0; c < m; c++) {
        uint32_t i = cells[c];
        for (k = 0; k < 8; k++) {
            ptrdiff_t j = nb_of(w, h, i, k);
            if (j < 0)
                continue;
            if (!isnan(z[j]) && !(level[j] > z[j]) && z[j] <= level[i]) {
                dist[i] = 1;
                queue[qt++] = i;
                break;
            }
        }
    }
    while (qh < qt) {
        uint32_t i = queue[qh++];
        most = dist[i];
        for (k = 0; k < 8; k++) {
            ptrdiff_t j = nb_of(w, h, i, k);
            if (j < 0)
                continue;
            if (!isnan(z[j]) && level[j] > z[j] && dist[j] == UINT32_MAX) {
                dist[j] = dist[i] + 1;
                queue[qt++] = (uint32_t)j;
            }
        }
    }
    return most;
}

/* Cell c's height above the mean of the cells of its basin (below the same spill level) within
 * DB_FINE cells, clamped to +-cap: the land's shape at the scale of a few cells. */
#define DB_FINE 2
static double db_fine(const float *z, const float *level, int w, int h, uint32_t c, double cap)
{
    int cx = (int)(c % (uint32_t)w), cy = (int)(c / (uint32_t)w), u, v, k = 0;
    double sum = 0.0, d;
    for (v = cy - DB_FINE; v <= cy + DB_FINE; v++)
        for (u = cx - DB_FINE; u <= cx + DB_FINE; u++) {
            size_t j = (size_t)v * (size_t)w + (size_t)u;
            if (u < 0 || v < 0 || u >= w || v >= h || !(level[j] > z[j]) || level[j] != level[c])
                continue;
            sum += z[j];
            k++;
        }
    d = (double)z[c] - sum / k;
    return d > cap ? cap : d < -cap ? -cap : d;
}

int ts__raise_dammed_basins(float *z, const unsigned char *flags, int w, int h, double relief,
                            size_t *basins, size_t *cells_raised)
{
    size_t n = (size_t)w * (size_t)h, i, m, c;
    float *level = malloc(n * sizeof *level);
    unsigned char *seen = calloc(n, 1);
    uint32_t *cells = malloc(n * sizeof *cells), *dist = malloc(n * sizeof *dist),
             *queue = malloc(n * sizeof *queue);
    double *fine = malloc(n * sizeof *fine);
    int rc = -1;
    *basins = *cells_raised = 0;
    if (n > (size_t)UINT32_MAX)
        goto done;
    if (!level || !seen || !cells || !dist || !queue || !fine ||
        ts__spill_levels(z, w, h, level) != 0)
        goto done;
    for (i = 0; i < n; i++) {
        double depth;
        uint32_t most;
        int dammed;
        if (seen[i] || !(level[i] > z[i]))
            continue;
        m = db_basin(z, level, flags, w, h, i, seen, cells, &depth, &dammed);
        if (dammed != DB_DAMMED || !(depth > relief))
            continue;
        most = db_steps(z, level, w, h, cells, m, dist, queue);
        if (!most)
            continue;
        (*basins)++;
        /* the land's own shape at the scale of a few cells, kept up to a third of the relief */
        for (c = 0; c < m; c++)
            fine[c] = db_fine(z, level, w, h, cells[c], relief / 3.0);
        /* a third of the relief a rise from the pour point, a third above it, the fine shape */
        for (c = 0; c < m; c++) {
            uint32_t j = cells[c];
            float v;
            if ((flags[j] & TS_CELL_FIXED) || dist[j] == UINT32_MAX)
                continue;
            v = (float)((double)level[j] + relief / 3.0 * ((double)dist[j] / (double)most + 1.0) +
                        fine[c]);
            if (v > z[j]) {
                z[j] = v;
                (*cells_raised)++;
            }
        }
    }
    rc = 0;
done:
    free(level);
    free(seen);
    free(cells);
    free(dist);
    free(queue);
    free(fine);
    return rc;
}

/* The whole grid drained, then its dammed basins raised to plains (dammed_basins.c) and
 * drained again; info against the surface as given. */
ts_status ts__drain_with_plains(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags,
                                const ts_drainage_params *p, ts_drainage_info *info)
{
    int w = dem->width, h = dem->height, y, x;
    size_t n = (size_t)w * (size_t)h, i, basins = 0, raised = 0, changed = 0;
    float *z0, *z;
    ts_drainage_info first;
    double sum = 0.0;
    ts_status st;
    for (i = 0; i < n && !(flags[i] & TS_CELL_SHALLOW); i++)
        ;
    if (i == n) /* nothing dams a basin */
        return ts__drain_pass(ctx, dem, flags, 0, 0, w, h, p, info);
    z0 = malloc(n * sizeof *z0);
    z = malloc(n * sizeof *z);
    if (!z0 || !z) {
        free(z0);
        free(z);
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for %d x %d cells", w, h);
    }
    for (y = 0; y < h; y++)
        memcpy(z0 + (size_t)y * (size_t)w, &TS_PIX(dem, 0, y), (size_t)w * sizeof *z0);
    st = ts__drain_pass(ctx, dem, flags, 0, 0, w, h, p, &first);
    for (y = 0; st == TS_OK && y < h; y++)
        memcpy(z + (size_t)y * (size_t)w, &TS_PIX(dem, 0, y), (size_t)w * sizeof *z);
    if (st == TS_OK &&
        ts__raise_dammed_basins(z, flags, w, h, p->floodplain_relief, &basins, &raised) != 0)
        st = ts__fail(ctx, TS_ERR_NOMEM, "drainage",
                      "out of memory for the basins of %d x %d cells", w, h);
    if (st == TS_OK && basins) {
        for (y = 0; y < h; y++)
            memcpy(&TS_PIX(dem, 0, y), z + (size_t)y * (size_t)w, (size_t)w * sizeof *z);
        st = ts__drain_pass(ctx, dem, flags, 0, 0, w, h, p, NULL);
    }
    if (st == TS_OK && info) {
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                i = (size_t)y * (size_t)w + (size_t)x;
                if (TS_PIX(dem, x, y) != z0[i]) {
                    changed++;
                    sum += fabs((double)TS_PIX(dem, x, y) - (double)z0[i]);
                }
            }
        *info = first;
        info->cells_changed = changed;
        info->mean_change = changed ? sum / (double)changed : 0.0;
        info->basins_raised = basins;
        info->cells_raised = raised;
    }
    free(z0);
    free(z);
    return st;
}
