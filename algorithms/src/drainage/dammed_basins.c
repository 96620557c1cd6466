/*
 * dammed_basins.c - the basins a breach leaves wider than it reaches, lifted
 * and breached again (ts_drainage_params.basin_block; see ts__lift_basins), and the basins a
 * breach leaves beside a drawn valley's floor
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

/* The cells of dem that differ from z0 (its surface as given, row-major) and their mean
 * absolute change, into info. */
static void change_of(const ts_raster *dem, const float *z0, ts_drainage_info *info)
{
    size_t changed = 0, i;
    double sum = 0.0;
    int x, y;
    for (y = 0; y < dem->height; y++)
        for (x = 0; x < dem->width; x++) {
            i = (size_t)y * (size_t)dem->width + (size_t)x;
            if (TS_PIX(dem, x, y) != z0[i]) {
                changed++;
                sum += fabs((double)TS_PIX(dem, x, y) - (double)z0[i]);
            }
        }
    info->cells_changed = changed;
    info->mean_change = changed ? sum / (double)changed : 0.0;
}

/* The whole grid drained, then its dammed basins raised to plains (dammed_basins.c) and
 * drained again; info against the surface as given. */
ts_status ts__drain_with_plains(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags,
                                const ts_drainage_params *p, ts_drainage_info *info)
{
    int w = dem->width, h = dem->height, y;
    size_t n = (size_t)w * (size_t)h, i, basins = 0, raised = 0;
    float *z0, *z;
    ts_drainage_info first;
    ts_progress_saved sv;
    ts_status st;
    for (i = 0; i < n && !(flags[i] & TS_CELL_SHALLOW); i++)
        ;
    if (i == n) /* nothing dams a basin */
        return ts__drain_pass(ctx, dem, flags, 0, 0, w, h, p, info);
    memset(&first, 0, sizeof first);
    z0 = malloc(n * sizeof *z0);
    z = malloc(n * sizeof *z);
    if (!z0 || !z) {
        free(z0);
        free(z);
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for %d x %d cells", w, h);
    }
    for (y = 0; y < h; y++)
        memcpy(z0 + (size_t)y * (size_t)w, &TS_PIX(dem, 0, y), (size_t)w * sizeof *z0);
    sv = ts__progress_push(ctx, 0.0, 0.8); /* the second pass: the last 20 % */
    st = ts__drain_pass(ctx, dem, flags, 0, 0, w, h, p, &first);
    ts__progress_pop(ctx, sv);
    for (y = 0; st == TS_OK && y < h; y++)
        memcpy(z + (size_t)y * (size_t)w, &TS_PIX(dem, 0, y), (size_t)w * sizeof *z);
    if (st == TS_OK &&
        ts__raise_dammed_basins(z, flags, w, h, p->floodplain_relief, &basins, &raised) != 0)
        st = ts__fail(ctx, TS_ERR_NOMEM, "drainage",
                      "out of memory for the basins of %d x %d cells", w, h);
    if (st == TS_OK && basins) {
        for (y = 0; y < h; y++)
            memcpy(&TS_PIX(dem, 0, y), z + (size_t)y * (size_t)w, (size_t)w * sizeof *z);
        sv = ts__progress_push(ctx, 0.8, 1.0);
        st = ts__drain_pass(ctx, dem, flags, 0, 0, w, h, p, NULL);
        ts__progress_pop(ctx, sv);
    } else if (st == TS_OK)
        st = ts__progress(ctx, 1.0, "drainage");
    if (st == TS_OK && info) {
        *info = first;
        change_of(dem, z0, info);
        info->basins_raised = basins;
        info->cells_raised = raised;
    }
    free(z0);
    free(z);
    return st;
}

/* ---- basins wider than a breach reaches, lifted (basin_block) ------ */

/* The lowest cell of each f x f block of z into m (cw x ch; INFINITY for a block of nodata
 * alone), and whether the block drains out (seed): on the grid's edge, or holding nodata or a
 * fixed cell. */
static void block_minima(const ts_raster *z, const unsigned char *flags, int f, int cw, int ch,
                         float *m, unsigned char *seed)
{
    int w = z->width, h = z->height;
    int x, y;
    size_t c;
    for (c = 0; c < (size_t)cw * (size_t)ch; c++) {
        m[c] = INFINITY;
        seed[c] = (int)(c % (size_t)cw) == 0 || (int)(c % (size_t)cw) == cw - 1 ||
                  (int)(c / (size_t)cw) == 0 || (int)(c / (size_t)cw) == ch - 1;
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            float v = TS_PIX(z, x, y);
            c = (size_t)(y / f) * (size_t)cw + (size_t)(x / f);
            if (isnan(v) || (flags && (flags[i] & (TS_CELL_NODATA | TS_CELL_FIXED))))
                seed[c] = 1;
            else if (v < m[c])
                m[c] = v;
        }
}

/* The blocks' fill (lev, cw x ch) of their minima m: a priority flood from the seeds (a block
 * of nodata alone at -INFINITY, so the blocks beside it keep their minima; every block holding
 * nodata is a seed), each block reached from the lowest block beside it raised to grade above
 * that one where it is not higher (Barnes et al. 2014's flood with an epsilon: a block in a
 * basin then has a way out falling grade a block; land outside the basins keeps its minima).
 * -1 out of memory. */
static int blocks_fill(const float *m, const unsigned char *seed, int cw, int ch, double grade,
                       float *lev)
{
    size_t nc = (size_t)cw * (size_t)ch, c;
    unsigned char *done = calloc(nc, 1);
    db_heap hp = {NULL, 0, 0};
    int k, rc = -1;
    if (!done)
        return -1;
    for (c = 0; c < nc; c++)
        if (seed[c]) {
            lev[c] = isinf(m[c]) ? -INFINITY : m[c];
            done[c] = 1;
            if (db_push(&hp, lev[c], (uint32_t)c) != 0)
                goto out;
        }
    while (hp.n) {
        db_item top = db_pop(&hp);
        for (k = 0; k < 8; k++) {
            ptrdiff_t j = nb_of(cw, ch, top.at, k);
            if (j < 0 || done[j])
                continue;
            done[j] = 1;
            lev[j] = m[j];
            if (m[j] <= top.z) {
                lev[j] = (float)((double)top.z + grade);
                if (!(lev[j] > top.z) && grade > 0) /* grade below a float's step there */
                    lev[j] = nextafterf(top.z, INFINITY);
            }
            if (db_push(&hp, lev[j], (uint32_t)j) != 0)
                goto out;
        }
    }
    rc = 0;
out:
    free(hp.v);
    free(done);
    return rc;
}

/* Cell t's centre among n blocks' centres ((i + 1/2) f - 1/2), clamped at the outer ones: the
 * two blocks it lies between and its weight on the second. */
static double centre_between(int t, int f, int n, int *i0, int *i1)
{
    double u = ((double)t + 0.5) / (double)f - 0.5;
    u = u < 0 ? 0 : u > n - 1 ? n - 1 : u;
    *i0 = (int)u;
    *i1 = *i0 + 1 < n ? *i0 + 1 : *i0;
    return u - *i0;
}

/* The blocks' depths d (cw x ch) at every cell of a w x h grid into r, bilinear between the
 * blocks' centres. */
static void depth_bilinear(const float *d, int cw, int ch, int f, int w, int h, double *r)
{
    int x, y, i0, i1, j0, j1;
    for (y = 0; y < h; y++) {
        double b = centre_between(y, f, ch, &j0, &j1);
        const float *d0 = d + (size_t)j0 * (size_t)cw, *d1 = d + (size_t)j1 * (size_t)cw;
        for (x = 0; x < w; x++) {
            double a = centre_between(x, f, cw, &i0, &i1);
            r[(size_t)y * (size_t)w + (size_t)x] =
                (1 - b) * ((1 - a) * d0[i0] + a * d0[i1]) + b * ((1 - a) * d1[i0] + a * d1[i1]);
        }
    }
}

/* The mean of v[k - rad..k + rad] (those within v[0..n)) for every k, into out (a running
 * sum). */
static void box_mean_line(const double *v, int n, int rad, double *out)
{
    double sum = 0.0;
    int k;
    for (k = 0; k < rad && k < n; k++)
        sum += v[k];
    for (k = 0; k < n; k++) {
        int lo = k - rad, hi = k + rad;
        if (hi < n)
            sum += v[hi];
        out[k] = sum / (double)((hi < n ? hi : n - 1) - (lo > 0 ? lo : 0) + 1);
        if (lo >= 0)
            sum -= v[lo];
    }
}

/* r (w x h) smoothed by a box of 2 rad + 1 cells along the rows, then the columns (the
 * bilinear field's creases at the blocks' centres rounded off).  -1 out of memory. */
static int box_smooth(double *r, int w, int h, int rad)
{
    int n = w > h ? w : h, x, y;
    double *line = malloc((size_t)n * sizeof *line), *col = malloc((size_t)n * sizeof *col);
    if (!line || !col) {
        free(line);
        free(col);
        return -1;
    }
    for (y = 0; y < h; y++) {
        box_mean_line(r + (size_t)y * (size_t)w, w, rad, line);
        memcpy(r + (size_t)y * (size_t)w, line, (size_t)w * sizeof *line);
    }
    for (x = 0; x < w; x++) {
        for (y = 0; y < h; y++)
            col[y] = r[(size_t)y * (size_t)w + (size_t)x];
        box_mean_line(col, h, rad, line);
        for (y = 0; y < h; y++)
            r[(size_t)y * (size_t)w + (size_t)x] = line[y];
    }
    free(line);
    free(col);
    return 0;
}

int ts__lift_basins(ts_raster *z, const unsigned char *flags, int f, double grade, double keep,
                    unsigned char *lifted)
{
    int w = z->width, h = z->height, cw = (w + f - 1) / f, ch = (h + f - 1) / f, x, y;
    size_t nc = (size_t)cw * (size_t)ch, n = (size_t)w * (size_t)h, c;
    float *m = malloc(nc * sizeof *m), *lev = malloc(nc * sizeof *lev);
    unsigned char *seed = malloc(nc);
    double *r = malloc(n * sizeof *r);
    int rc = -1;
    if (!m || !lev || !seed || !r)
        goto out;
    block_minima(z, flags, f, cw, ch, m, seed);
    if (blocks_fill(m, seed, cw, ch, grade, lev) != 0)
        goto out;
    for (c = 0; c < nc; c++) /* the fill's depth at each block's centre, less keep */
        lev[c] = isinf(m[c]) || !((double)lev[c] - (double)m[c] > keep)
                     ? 0.0f
                     : (float)((double)lev[c] - (double)m[c] - keep);
    depth_bilinear(lev, cw, ch, f, w, h, r);
    if (box_smooth(r, w, h, f / 2) != 0)
        goto out;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            float *v = &TS_PIX(z, x, y);
            if (isnan(*v) || (flags && (flags[i] & (TS_CELL_NODATA | TS_CELL_FIXED))))
                continue;
            if (r[i] > 0 && (float)((double)*v + r[i]) > *v) {
                *v = (float)((double)*v + r[i]);
                if (lifted)
                    lifted[i] = 1;
            }
        }
    rc = 0;
out:
    free(m);
    free(lev);
    free(seed);
    free(r);
    return rc;
}

ts_status ts__drain_lifted(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags,
                           const ts_drainage_params *p, ts_drainage_info *info)
{
    int w = dem->width, h = dem->height, y, round;
    size_t n = (size_t)w * (size_t)h, i, left = 0;
    float *z0 = malloc(n * sizeof *z0);
    unsigned char *up = calloc(n, 1);
    ts_drainage_params q = *p;
    ts_drainage_info first, d;
    ts_progress_saved sv;
    ts_status st = TS_OK;
    if (!z0 || !up) {
        free(z0);
        free(up);
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for %d x %d cells", w, h);
    }
    for (y = 0; y < h; y++)
        memcpy(z0 + (size_t)y * (size_t)w, &TS_PIX(dem, 0, y), (size_t)w * sizeof *z0);
    q.basin_block = 0;
    memset(&first, 0, sizeof first);
    /* drained, then the basins the breach leaves lifted and drained again, twice: the first
     * breach takes every basin within its reach, the lifts only what it leaves; the first lift
     * stops half the deepest cut below the fill (the breach cuts that through the rim near
     * the way out: the basin keeps that much of its relief), the second lifts whatever the
     * breach still leaves to the fill; on land that drains a lift changes only flats */
    for (round = 0; st == TS_OK && round < 3; round++) {
        if (round > 0 &&
            ts__lift_basins(dem, flags, p->basin_block, p->basin_grade,
                            round == 1 ? 0.5 * ts_drainage_depth_of(&q) : 0.0, up) != 0) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "drainage",
                          "out of memory for the basins of %d x %d cells", w, h);
            break;
        }
        memset(&d, 0, sizeof d);
        /* the first pass, most of the work, the first 80 % of the stage's progress */
        sv = ts__progress_push(ctx, round == 0 ? 0.0 : 0.7 + 0.1 * round,
                               round == 0 ? 0.8 : 0.8 + 0.1 * round);
        st = round == 0 && q.floodplain_relief > 0 && flags
                 ? ts__drain_with_plains(ctx, dem, flags, &q, &d)
                 : ts__drain_pass(ctx, dem, flags, 0, 0, w, h, &q, &d);
        ts__progress_pop(ctx, sv);
        if (round == 0)
            first = d;
        left = d.pits - d.resolved;
    }
    if (st == TS_OK && info) {
        *info = first;
        info->resolved = first.pits > left ? first.pits - left : 0;
        change_of(dem, z0, info);
        for (i = 0; i < n; i++)
            info->cells_lifted += up[i];
    }
    free(z0);
    free(up);
    return st;
}
