/*
 * depression_breaching.c - the drainage stage after every method: closed
 * depressions removed by least-cost breaching (after Lindsay 2016) or by
 * filling, each from the pit it drains, within a bounded radius.
 *
 * A pit is a cell lower than its eight neighbours in the order (height, grid
 * index), so a flat has one pit, at its first cell.  A cell beside the grid's
 * edge or beside nodata drains out and is never a pit.  From each pit, on the
 * surface as given:
 *   breach: the path of least cost (the sum of the heights its cells stand
 *     above the pit, plus a little per step) to a target: a cell lower than
 *     the pit, or one that drains out; the path's cells lowered each a
 *     little below the one before (Lindsay's small decrement), never raised;
 *     where a cell is cut deeper than s / 16 (s the banks' slope), the
 *     cells within cut / s of it (2 to radius / 2) lowered by the cut
 *     tapered to nothing there (ours, cut_banks: banks falling to the
 *     channel, a valley through the rim where Lindsay cuts a slot one cell
 *     wide).
 *   fill: the path to a target whose highest cell is lowest (the spill);
 *     the cells reached below the spill's height raised to it.
 * The searches reach at most `radius` cells (Chebyshev) from their pit; a
 * pit with no target within it is kept.  The stage's output is the minimum
 * (breach) or maximum (fill) of every pit's change: it does not depend on
 * the order the pits are taken in, so threads give the same bytes, and a
 * cell's result depends only on the cells within ts_drainage_margin of it
 * (2 radius + 2; radius / 2 more for a breach with banks), so a window
 * computed with that margin is the window of the whole.
 *
 * Cells flagged TS_CELL_FIXED (pins, water, drawn valleys) never change and
 * a channel never crosses them unless they are its target (water at or below
 * the pit takes it); the land beside water is never cut below it;
 * a channel crosses TS_CELL_BARRIER cells (drawn ridges), or a diagonal
 * between two of them, only where it has no other way out (a ring drawn
 * closed spills over its lowest saddle, as water would).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../base/internal.h"

/* ---- declarations and window arithmetic ------------------------------ */

/* the most cells a fill's lake may cover (a 32 x 32 pond for radius 128) */
#define DR_LAKE_MAX(r) ((size_t)((r) / 4) * (size_t)((r) / 4))
#define DR_AUTO_SAMPLE 1000000 /* cells sampled for the automatic bank slope */
/* how far the floor beside a shallow cell is looked for: past the band of shallow cells a
 * front end marks (a quarter of the radius, Chebyshev) */
#define DR_FLOOR_REACH(r) ((r) / 2 + 2)

TS_API int ts_drainage_margin(const ts_drainage_params *p)
{
    int m;
    if (!p || p->mode == TS_DRAINAGE_KEEP)
        return 0;
    /* a channel (R from its pit) read on the surface (R), its banks (R / 2), the floor
     * beside a shallow cell it crosses */
    m = 2 * p->radius + 2;
    if (p->mode == TS_DRAINAGE_BREACH && p->bank_slope != 0) /* -1: whatever it becomes */
        m += p->radius / 2;
    if (p->mode == TS_DRAINAGE_BREACH && p->shallow_depth > 0)
        m += DR_FLOOR_REACH(p->radius);
    return m;
}

TS_API double ts_drainage_depth_of(const ts_drainage_params *p)
{
    if (!p || !(p->max_depth == -1))
        return p ? p->max_depth : 0.0;
    return p->bank_slope > 0 ? p->bank_slope * (double)p->radius / 8.0 : 0.0;
}

TS_API double ts_drainage_bank_slope_auto(const ts_raster *exemplars, int n)
{
    size_t total = 0, m = 0, step, k = 0;
    float *v;
    double r;
    int e, x, y;
    for (e = 0; e < n; e++)
        if (exemplars[e].width > 2 && exemplars[e].height > 2)
            total += (size_t)(exemplars[e].width - 2) * (size_t)(exemplars[e].height - 2);
    if (!total)
        return 0.0;
    step = total / DR_AUTO_SAMPLE + 1; /* every step-th interior cell, in raster order */
    v = malloc((total / step + 1) * sizeof *v);
    if (!v)
        return 0.0;
    for (e = 0; e < n; e++) {
        const ts_raster *r0 = &exemplars[e];
        for (y = 1; y < r0->height - 1; y++)
            for (x = 1; x < r0->width - 1; x++, k++) {
                float gx, gy;
                if (k % step)
                    continue;
                gx = 0.5f * (TS_PIX(r0, x + 1, y) - TS_PIX(r0, x - 1, y));
                gy = 0.5f * (TS_PIX(r0, x, y + 1) - TS_PIX(r0, x, y - 1));
                if (!isnan(gx) && !isnan(gy))
                    v[m++] = hypotf(gx, gy);
            }
    }
    if (!m) {
        free(v);
        return 0.0;
    }
    ts__sort_floats(v, m);
    r = (double)v[(m - 1) / 2];
    free(v);
    return isfinite(r) ? r : 0.0;
}

/* ---- one search ------------------------------------------------------- */

typedef struct dr_heap_item {
    double key, key2; /* cost (breach) or spill (fill); then the height */
    int64_t gid;      /* the grid index: ties broken alike in every window */
    int at;           /* index in the search box */
} dr_heap_item;

/* Scratch of one thread: a (2R + 1)^2 box around the pit. */
typedef struct dr_scratch {
    int side;
    double *cost;
    int *parent;
    unsigned *stamp; /* box cell seen in search number `epoch` */
    unsigned epoch;
    dr_heap_item *heap;
    size_t n_heap, cap_heap;
    int *path;
} dr_scratch;

typedef struct dr_job {
    const float *z0; /* the surface as given (w x h, row-major) */
    float *out;      /* z0 with the fills (atomic max) or the channels and banks cut (atomic min) */
    const unsigned char *flags;    /* or NULL */
    const unsigned char *out_mask; /* per cell: 1 where it drains out (drains_out_of) */
    const float *shore;            /* per cell: shore_level_of, or NULL when there is no water */
    int w, h;
    int64_t gx0, gy0, gw, gh;
    int lo[2], hi[2]; /* pits looked for in [lo, hi) */
    int mode, radius;
    double max_depth;     /* > 0: no cut deeper (breach) */
    double shallow_depth; /* > 0 (a breach with flags): the same from a pit on a
                             TS_CELL_SHALLOW cell below the floor beside it */
    const float *floor;   /* with shallow_depth: per cell, the nearest fixed cell's height
                             (ts__nearest_fixed_levels), NaN none */
    double banks;         /* > 0: the banks' slope per cell (breach) */
    const int *pits;
    size_t n_pits;
    atomic_size_t resolved;
    atomic_int failed;
    const ts_ctx *ctx;
} dr_job;

static int heap_less(const dr_heap_item *a, const dr_heap_item *b)
{
    if (a->key != b->key)
        return a->key < b->key;
    if (a->key2 != b->key2)
        return a->key2 < b->key2;
    return a->gid < b->gid;
}

static int heap_push(dr_scratch *s, dr_heap_item it)
{
    size_t i;
    if (s->n_heap == s->cap_heap) {
        size_t c = s->cap_heap ? 2 * s->cap_heap : 256;
        dr_heap_item *h = realloc(s->heap, c * sizeof *h);
        if (!h)
            return -1;
        s->heap = h;
        s->cap_heap = c;
    }
    i = s->n_heap++;
    while (i > 0 && heap_less(&it, &s->heap[(i - 1) / 2])) {
        s->heap[i] = s->heap[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    s->heap[i] = it;
    return 0;
}

static dr_heap_item heap_pop(dr_scratch *s)
{
    dr_heap_item top = s->heap[0], last = s->heap[--s->n_heap];
    size_t i = 0, n = s->n_heap;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n)
            break;
        if (c + 1 < n && heap_less(&s->heap[c + 1], &s->heap[c]))
            c++;
        if (!heap_less(&s->heap[c], &last))
            break;
        s->heap[i] = s->heap[c];
        i = c;
    }
    if (n)
        s->heap[i] = last;
    return top;
}

static const int DX[8] = {-1, 0, 1, -1, 1, -1, 0, 1};
static const int DY[8] = {-1, -1, -1, 0, 0, 1, 1, 1};

/* Is local cell (x, y) off the grid? */
static int off_grid(const dr_job *j, int x, int y)
{
    int64_t gx = j->gx0 + x, gy = j->gy0 + y;
    return gx < 0 || gy < 0 || gx >= j->gw || gy >= j->gh;
}

/* Does cell (x, y) (on the grid, with data) drain out: beside the grid's
 * edge or beside nodata?  Once per cell into j->out_mask. */
static int drains_out_of(const dr_job *j, int x, int y)
{
    int d;
    for (d = 0; d < 8; d++) {
        int u = x + DX[d], v = y + DY[d];
        if (off_grid(j, u, v))
            return 1;
        if (u < 0 || v < 0 || u >= j->w || v >= j->h)
            continue; /* beyond the window: never asked for a pit's neighbours */
        if (isnan(j->z0[(size_t)v * (size_t)j->w + (size_t)u]) ||
            (j->flags && (j->flags[(size_t)v * (size_t)j->w + (size_t)u] & TS_CELL_NODATA)))
            return 1;
    }
    return 0;
}

static int drains_out(const dr_job *j, int x, int y)
{
    return j->out_mask[(size_t)y * (size_t)j->w + (size_t)x];
}

static int64_t gid_of(const dr_job *j, int x, int y)
{
    return (j->gy0 + y) * j->gw + (j->gx0 + x);
}

/* Is (x, y) a pit: data, free, not draining out, lower than its eight
 * neighbours in (height, grid index)? */
static int is_pit(const dr_job *j, int x, int y)
{
    size_t i = (size_t)y * (size_t)j->w + (size_t)x;
    float z = j->z0[i];
    int64_t g = gid_of(j, x, y);
    int d;
    if (isnan(z) || (j->flags && (j->flags[i] & (TS_CELL_FIXED | TS_CELL_NODATA))))
        return 0;
    if (drains_out(j, x, y))
        return 0;
    for (d = 0; d < 8; d++) {
        int u = x + DX[d], v = y + DY[d];
        float zn = j->z0[(size_t)v * (size_t)j->w + (size_t)u];
        if (zn < z || (zn == z && gid_of(j, u, v) < g))
            return 0;
    }
    return 1;
}

/* *p = v where v is lower (up: higher), atomically: the result does not depend
 * on the order the threads come in. */
static void atomic_toward(float *p, float v, int up)
{
    uint32_t *u = (uint32_t *)(void *)p;
    uint32_t old = __atomic_load_n(u, __ATOMIC_RELAXED), nw;
    float cur;
    for (;;) {
        memcpy(&cur, &old, sizeof cur);
        if (!(up ? v > cur : v < cur))
            return;
        memcpy(&nw, &v, sizeof nw);
        if (__atomic_compare_exchange_n(u, &old, nw, 0, __ATOMIC_RELAXED, __ATOMIC_RELAXED))
            return;
    }
}

/* May a channel step from (x, y) to (u, v) (neighbours, both in the
 * window)?  Not diagonally between two barrier cells. */
static int step_ok(const dr_job *j, int x, int y, int u, int v)
{
    if (!j->flags || u == x || v == y)
        return 1;
    return !((j->flags[(size_t)y * (size_t)j->w + (size_t)u] & TS_CELL_BARRIER) &&
             (j->flags[(size_t)v * (size_t)j->w + (size_t)x] & TS_CELL_BARRIER));
}

#define DR_STEP_COST 1e-4   /* metres per step: the shorter of two equal channels */
#define DR_DECREMENT 1e-3   /* height units: the fall from one channel cell to the next */
#define DR_BARRIER_COST 1e7 /* metres: a channel over a drawn ridge, the last resort */

/* What one search looks for from its pit. */
typedef struct dr_query {
    const float *z;       /* the surface searched */
    int minimax;          /* 1: the path whose highest cell is lowest (the spill);
                             0: the cheapest channel */
    double level;         /* the pit's level: a target is lower */
    double max_depth;     /* 0, or: cells higher than level + this are not crossed */
    double shallow_depth; /* 0, or: TS_CELL_SHALLOW cells higher than level + this neither */
} dr_query;

static int box_index(const dr_job *j, const dr_scratch *s, int px, int py, int at)
{
    return (py + at / s->side - j->radius) * j->w + (px + at % s->side - j->radius);
}

/* The highest water level beside cell (x, y) (TS_CELL_WATER neighbours), or
 * -infinity: the land beside water is never cut below it.  Once per cell into
 * j->shore. */
static double shore_level_of(const dr_job *j, int x, int y)
{
    double top = -INFINITY;
    int d;
    if (j->flags[(size_t)y * (size_t)j->w + (size_t)x] & TS_CELL_WATER)
        return -INFINITY; /* water itself: a target, never cut */
    for (d = 0; d < 8; d++) {
        int u = x + DX[d], v = y + DY[d];
        size_t i;
        if (u < 0 || v < 0 || u >= j->w || v >= j->h)
            continue;
        i = (size_t)v * (size_t)j->w + (size_t)u;
        if ((j->flags[i] & TS_CELL_WATER) && (double)j->z0[i] > top)
            top = (double)j->z0[i];
    }
    return top;
}

static double shore_level(const dr_job *j, int x, int y)
{
    return j->shore ? (double)j->shore[(size_t)y * (size_t)j->w + (size_t)x] : -INFINITY;
}

/* A search from pit (px, py) in its box: the box index of the target it
 * reaches (a cell lower than q->level, or one that drains out), -1 if none within the radius, -2
 * out of memory.  s->cost holds the key of every cell reached (cost, or height of the path's
 * highest cell), s->parent the way back. */
static int search(const dr_job *j, dr_scratch *s, int px, int py, const dr_query *q)
{
    const int R = j->radius, side = s->side, start = R * side + R;
    const float zp = q->z[(size_t)py * (size_t)j->w + (size_t)px];
    dr_heap_item it;
    if (++s->epoch == 0) {
        memset(s->stamp, 0, (size_t)side * (size_t)side * sizeof *s->stamp);
        s->epoch = 1;
    }
    s->n_heap = 0;
    it.key = q->minimax ? zp : 0.0;
    it.key2 = zp;
    it.gid = gid_of(j, px, py);
    it.at = start;
    s->cost[start] = it.key;
    s->parent[start] = -1;
    s->stamp[start] = s->epoch;
    if (heap_push(s, it) != 0)
        return -2;
    while (s->n_heap) {
        int bx, by, x, y, d;
        size_t i;
        it = heap_pop(s);
        if (it.key > s->cost[it.at])
            continue; /* a stale entry */
        bx = it.at % side;
        by = it.at / side;
        x = px + bx - R;
        y = py + by - R;
        i = (size_t)y * (size_t)j->w + (size_t)x;
        if (it.at != start && ((double)q->z[i] < q->level || drains_out(j, x, y) ||
                               (j->flags && (j->flags[i] & TS_CELL_FIXED))))
            return it.at; /* (a fixed cell is pushed only at or below the level) */
        for (d = 0; d < 8; d++) {
            int u = x + DX[d], v = y + DY[d], bu = bx + DX[d], bv = by + DY[d], at;
            size_t ni;
            float zn;
            double c;
            dr_heap_item nx;
            if (bu < 0 || bv < 0 || bu >= side || bv >= side || u < 0 || v < 0 || u >= j->w ||
                v >= j->h)
                continue; /* (past the window: off the grid) */
            ni = (size_t)v * (size_t)j->w + (size_t)u;
            zn = q->z[ni];
            at = bv * side + bu;
            if (isnan(zn) || (j->flags && (j->flags[ni] & TS_CELL_NODATA)))
                continue;
            /* fixed cells: only as a target, at or below the level (water at
             * the pit's height takes its water) */
            if (j->flags && (j->flags[ni] & TS_CELL_FIXED) && !((double)zn <= q->level))
                continue;
            if (q->max_depth > 0 && (double)zn > q->level + q->max_depth)
                continue;
            /* a shallow cell (beside a drawn valley's floor) is cut no deeper than the
             * shallow depth by any pit's channel, not only by its own pits' (a channel
             * from farther off ran a trench along the fixed floor), unless the channel
             * stays at or above the floor nearest the cell: a side gully down to it */
            if (!q->minimax && q->shallow_depth > 0 && (j->flags[ni] & TS_CELL_SHALLOW) &&
                (double)zn > q->level + q->shallow_depth && !(q->level >= (double)j->floor[ni]))
                continue;
            /* the land beside water is never cut below the water */
            if (!q->minimax && j->flags && shore_level(j, u, v) > q->level)
                continue;
            if (q->minimax) {
                c = it.key > (double)zn ? it.key : (double)zn;
            } else {
                c = it.key + ((double)zn > q->level ? (double)zn - q->level : 0.0) + DR_STEP_COST;
                /* a drawn ridge: crossed only where no other way is (its
                 * lowest saddle, as water spills over it), a diagonal
                 * between two of its cells as a crossing */
                if (j->flags && (((j->flags[ni] & TS_CELL_BARRIER) && !((double)zn < q->level)) ||
                                 !step_ok(j, x, y, u, v)))
                    c += DR_BARRIER_COST;
            }
            if (s->stamp[at] == s->epoch && s->cost[at] <= c)
                continue;
            s->stamp[at] = s->epoch;
            s->cost[at] = c;
            s->parent[at] = it.at;
            nx.key = c;
            nx.key2 = zn;
            nx.gid = gid_of(j, u, v);
            nx.at = at;
            if (heap_push(s, nx) != 0)
                return -2;
        }
    }
    return -1;
}

/* The number of cells of the depression below `level` that search s found. */
static size_t lake_cells(const dr_scratch *s, double level)
{
    size_t c, n = 0, nb = (size_t)s->side * (size_t)s->side;
    for (c = 0; c < nb; c++)
        n += s->stamp[c] == s->epoch && s->cost[c] < level;
    return n;
}

/* Does the depression below `level` that search s found reach the border
 * of its box (so it may go on past it: not known whole)? */
static int lake_at_border(const dr_scratch *s, double level)
{
    int k, side = s->side;
    for (k = 0; k < side; k++) {
        int e[4], m;
        e[0] = k;
        e[1] = (side - 1) * side + k;
        e[2] = k * side;
        e[3] = k * side + side - 1;
        for (m = 0; m < 4; m++)
            if (s->stamp[e[m]] == s->epoch && s->cost[e[m]] < level)
                return 1;
    }
    return 0;
}

/* Phase 1 (fill) for pit (px, py): its depression raised to its spill.  1
 * done, 0 no way out within the radius, a lake wider than the radius or of
 * more than DR_LAKE_MAX cells, or a fixed cell below the spill; -1 out of
 * memory. */
static int fill_pit(dr_job *j, dr_scratch *s, int px, int py)
{
    const float zp = j->z0[(size_t)py * (size_t)j->w + (size_t)px];
    dr_query q;
    double level;
    size_t c, nb = (size_t)s->side * (size_t)s->side;
    int found;
    memset(&q, 0, sizeof q);
    q.z = j->z0;
    q.minimax = 1;
    q.level = zp;
    found = search(j, s, px, py, &q);
    if (found < 0)
        return found == -2 ? -1 : 0;
    level = (double)(float)s->cost[found]; /* as the lake stores it */
    if (!(level > zp))
        return 1;
    if (lake_at_border(s, level) || lake_cells(s, level) > DR_LAKE_MAX(j->radius))
        return 0; /* wider than the radius, or more than a small lake: kept */
    for (c = 0; c < nb; c++)
        if (s->stamp[c] == s->epoch && s->cost[c] < level) {
            size_t i = (size_t)box_index(j, s, px, py, (int)c);
            if (j->flags && (j->flags[i] & TS_CELL_FIXED) && j->z0[i] < level)
                return 0;
        }
    for (c = 0; c < nb; c++)
        if (s->stamp[c] == s->epoch && s->cost[c] < level) {
            size_t i = (size_t)box_index(j, s, px, py, (int)c);
            if ((double)j->z0[i] < level)
                atomic_toward(&j->out[i], (float)level, 1);
        }
    return 1;
}

/* How far up its banks a cell d cells from the channel stands, in units of
 * the banks' slope: d less a cell, rounded over the two cells next to the
 * channel (d^2 / 4 there) so the valley's floor is not a V's crease. */
static double bank_reach(double d)
{
    return d < 2.0 ? 0.25 * d * d : d - 1.0;
}

/* The banks of channel cell (cx, cy), cut to height hc from z: over the
 * cells within rr = (z - hc) / banks of it (2 to radius / 2), the cut
 * tapered to nothing at rr: with t = bank_reach(d) / bank_reach(rr) (d the
 * cell's distance), land at least as high as z keeps its relief, lowered by
 * the cut times (1 - t), lower land is lowered to hc + (z - hc) t if that is
 * below it.  Fixed, barrier (a drawn ridge), nodata and off-grid cells are
 * kept, and none goes below the water beside it. */
static void cut_banks(dr_job *j, int cx, int cy, float hc, float z)
{
    const double cut = (double)z - (double)hc;
    double rr;
    int r, u, v;
    if (!(j->banks > 0) || !(cut > j->banks / 16.0))
        return;
    rr = cut / j->banks;
    if (rr < 2.0) /* a shallow cut: its neighbours halved, not a slot */
        rr = 2.0;
    if (rr > j->radius / 2)
        rr = j->radius / 2;
    r = (int)ceil(rr);
    for (v = cy - r; v <= cy + r; v++)
        for (u = cx - r; u <= cx + r; u++) {
            double d = hypot((double)(u - cx), (double)(v - cy)), nv, zi, t;
            size_t i;
            if (!(d < rr) || (u == cx && v == cy) || u < 0 || v < 0 || u >= j->w || v >= j->h ||
                off_grid(j, u, v))
                continue;
            i = (size_t)v * (size_t)j->w + (size_t)u;
            zi = (double)j->z0[i];
            if (isnan(zi) ||
                (j->flags && (j->flags[i] & (TS_CELL_FIXED | TS_CELL_BARRIER | TS_CELL_NODATA))))
                continue;
            t = bank_reach(d) / bank_reach(rr);
            nv = zi >= (double)z ? zi - cut * (1.0 - t) : (double)hc + cut * t;
            if (!(nv < zi))
                continue;
            if (j->flags) {
                double w = shore_level(j, u, v);
                if (w > nv)
                    nv = w;
            }
            atomic_toward(&j->out[i], (float)nv, 0);
        }
}

/* Phase 2 for pit (px, py): the cheapest channel from the pit (no cut
 * deeper than max_depth) to lower land or out, its cells on a profile
 * falling evenly, and its banks.  1 cut, 0 none, -1 out of memory. */
static int breach_pit(dr_job *j, dr_scratch *s, int px, int py)
{
    const float zp = j->z0[(size_t)py * (size_t)j->w + (size_t)px];
    const double level = zp;
    dr_query q;
    int found, k, n;
    memset(&q, 0, sizeof q);
    q.z = j->z0;
    q.minimax = 0;
    q.level = level;
    q.max_depth = j->max_depth;
    q.shallow_depth = j->shallow_depth;
    if (j->shallow_depth > 0 &&
        (j->flags[(size_t)py * (size_t)j->w + (size_t)px] & TS_CELL_SHALLOW) &&
        !(level >= (double)j->floor[(size_t)py * (size_t)j->w + (size_t)px]))
        q.max_depth = j->shallow_depth; /* a pit below the floor beside it */
    found = search(j, s, px, py, &q);
    if (found < 0)
        return found == -2 ? -1 : 0;
    n = 0;
    for (k = found; k >= 0; k = s->parent[k])
        s->path[n++] = k;
    {
        size_t ti = (size_t)box_index(j, s, px, py, found);
        float zt = j->z0[ti], prev = zp;
        /* each cell a little below the one before (Lindsay's small
         * decrement), the cut no deeper than the level needs */
        double drop = DR_DECREMENT;
        if ((double)zt < level && (level - (double)zt) / (double)(n - 1) < drop)
            drop = (level - (double)zt) / (double)(n - 1);
        for (k = n - 2; k >= 0; k--) { /* path[n - 1] is the pit */
            int at = s->path[k], step = n - 1 - k;
            int cx = px + at % s->side - j->radius, cy = py + at / s->side - j->radius;
            size_t i = (size_t)box_index(j, s, px, py, at);
            float v = (float)(level - drop * (double)step);
            float below = nextafterf(prev, -INFINITY);
            if (v > below)
                v = below;
            if (j->flags && (j->flags[i] & TS_CELL_FIXED))
                v = j->z0[i]; /* a fixed target (water) is never changed */
            else if (j->flags) {
                double w = shore_level(j, cx, cy); /* never below the water beside it */
                if (w > (double)v)
                    v = (float)w;
            }
            atomic_toward(&j->out[i], v, 0);
            if (v < j->z0[i])
                cut_banks(j, cx, cy, v, j->z0[i]);
            prev = v;
        }
    }
    return 1;
}

/* ---- the floor beside the shallow cells --------------------------------- */

/* Is source (sx, sy) before (tx, ty) in raster order? */
static int src_before(int sx, int sy, int tx, int ty)
{
    return sy < ty || (sy == ty && sx < tx);
}

float *ts__nearest_fixed_levels(const float *z, const unsigned char *flags, int w, int h, int reach)
{
    static const int NX[4] = {-1, 0, 1, -1}, NY[4] = {-1, -1, -1, 0};
    size_t n = (size_t)w * (size_t)h, i;
    int32_t *d = malloc(n * sizeof *d);
    int16_t *ox = malloc(n * sizeof *ox), *oy = malloc(n * sizeof *oy);
    float *lv = malloc(n * sizeof *lv);
    const int32_t cap = 5 * (reach < 0 ? 0 : reach > 4096 ? 4096 : reach);
    int pass, x, y, k;
    if (!d || !ox || !oy || !lv) {
        free(d);
        free(ox);
        free(oy);
        free(lv);
        return NULL;
    }
    for (i = 0; i < n; i++) {
        d[i] = (flags[i] & TS_CELL_FIXED) && !isnan(z[i]) ? 0 : INT32_MAX;
        ox[i] = oy[i] = 0;
    }
    /* forward: from the neighbours above and to the left; backward: below and right */
    for (pass = 0; pass < 2; pass++) {
        const int s = pass ? -1 : 1;
        int yy, xx;
        for (yy = 0; yy < h; yy++)
            for (xx = 0; xx < w; xx++) {
                size_t c;
                x = pass ? w - 1 - xx : xx;
                y = pass ? h - 1 - yy : yy;
                c = (size_t)y * (size_t)w + (size_t)x;
                for (k = 0; k < 4; k++) {
                    int u = x + s * NX[k], v = y + s * NY[k], sx, sy;
                    size_t nb;
                    int32_t nd;
                    if (u < 0 || v < 0 || u >= w || v >= h)
                        continue;
                    nb = (size_t)v * (size_t)w + (size_t)u;
                    if (d[nb] == INT32_MAX)
                        continue;
                    nd = d[nb] + (NX[k] && NY[k] ? 7 : 5);
                    if (nd > cap)
                        continue;
                    sx = u + ox[nb];
                    sy = v + oy[nb];
                    if (nd < d[c] || (nd == d[c] && src_before(sx, sy, x + ox[c], y + oy[c]))) {
                        d[c] = nd;
                        ox[c] = (int16_t)(sx - x);
                        oy[c] = (int16_t)(sy - y);
                    }
                }
            }
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            i = (size_t)y * (size_t)w + (size_t)x;
            lv[i] =
                d[i] == INT32_MAX ? NAN : z[(size_t)(y + oy[i]) * (size_t)w + (size_t)(x + ox[i])];
        }
    free(d);
    free(ox);
    free(oy);
    return lv;
}

/* ---- the stage ---------------------------------------------------------- */

static int scratch_init(dr_scratch *s, int R)
{
    size_t nb;
    memset(s, 0, sizeof *s);
    s->side = 2 * R + 1;
    nb = (size_t)s->side * (size_t)s->side;
    s->cost = malloc(nb * sizeof *s->cost);
    s->parent = malloc(nb * sizeof *s->parent);
    s->stamp = calloc(nb, sizeof *s->stamp);
    s->path = malloc(nb * sizeof *s->path);
    return s->cost && s->parent && s->stamp && s->path ? 0 : -1;
}

static void scratch_free(dr_scratch *s)
{
    free(s->cost);
    free(s->parent);
    free(s->stamp);
    free(s->heap);
    free(s->path);
}

static void drain_range(void *arg, size_t begin, size_t end)
{
    dr_job *j = arg;
    dr_scratch s;
    size_t k, done = 0;
    memset(&s, 0, sizeof s);
    if (scratch_init(&s, j->radius) != 0) {
        atomic_store(&j->failed, 1);
        scratch_free(&s);
        return;
    }
    for (k = begin; k < end; k++) {
        int px = j->pits[k] % j->w, py = j->pits[k] / j->w, r;
        if ((k - begin) % 256 == 0 && (ts__cancelled(j->ctx) || atomic_load(&j->failed)))
            break;
        r = j->mode == TS_DRAINAGE_FILL ? fill_pit(j, &s, px, py) : breach_pit(j, &s, px, py);
        if (r < 0) {
            atomic_store(&j->failed, 1);
            break;
        }
        done += (size_t)r;
    }
    atomic_fetch_add(&j->resolved, done);
    scratch_free(&s);
}

/* What every search asks of a cell again and again, once per cell: whether
 * it drains out, and (with water) the water beside it. */
static ts_status dr_cell_tables(ts_ctx *ctx, dr_job *j, unsigned char **mask, float **shore)
{
    size_t n = (size_t)j->w * (size_t)j->h, i, water = 0;
    int x, y;
    *shore = NULL;
    if (!(*mask = malloc(n)))
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for %d x %d cells", j->w,
                        j->h);
    for (i = 0; j->flags && i < n; i++)
        water += (j->flags[i] & TS_CELL_WATER) != 0;
    if (water && !(*shore = malloc(n * sizeof **shore)))
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for %d x %d cells", j->w,
                        j->h);
    for (y = 0; y < j->h; y++)
        for (x = 0; x < j->w; x++) {
            i = (size_t)y * (size_t)j->w + (size_t)x;
            (*mask)[i] = (unsigned char)(!off_grid(j, x, y) && drains_out_of(j, x, y));
            if (*shore)
                (*shore)[i] = (float)shore_level_of(j, x, y);
        }
    j->out_mask = *mask;
    j->shore = *shore;
    return TS_OK;
}

/* The pits in [lo, hi), in raster order. */
static ts_status find_pits(ts_ctx *ctx, dr_job *j, int **pits, size_t *n)
{
    size_t cap = 0;
    int x, y;
    *pits = NULL;
    *n = 0;
    for (y = j->lo[1]; y < j->hi[1]; y++)
        for (x = j->lo[0]; x < j->hi[0]; x++) {
            if (!is_pit(j, x, y))
                continue;
            if (*n == cap) {
                size_t c = cap ? 2 * cap : 1024;
                int *p = realloc(*pits, c * sizeof *p);
                if (!p) {
                    free(*pits);
                    *pits = NULL;
                    return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for the pits");
                }
                *pits = p;
                cap = c;
            }
            (*pits)[(*n)++] = y * j->w + x;
        }
    return TS_OK;
}

static ts_status drain_status(ts_ctx *ctx, const dr_job *j)
{
    if (atomic_load(&j->failed))
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for a pit's search");
    return ts__check_cancel(ctx);
}

/* One pass of the stage on dem (checked), every pit drained on the surface as given. */
ts_status ts__drain_pass(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags, int64_t gx0,
                         int64_t gy0, int64_t gw, int64_t gh, const ts_drainage_params *p,
                         ts_drainage_info *info)
{
    dr_job j;
    float *z0 = NULL, *out = NULL, *floor = NULL, *shore = NULL;
    unsigned char *out_mask = NULL;
    int *pits = NULL;
    size_t n_pits = 0, i, n;
    int x, y, a;
    ts_status st;
    n = (size_t)dem->width * (size_t)dem->height;
    z0 = malloc(n * sizeof *z0);
    out = malloc(n * sizeof *out);
    if (!z0 || !out) {
        free(z0);
        free(out);
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for %d x %d cells",
                        dem->width, dem->height);
    }
    for (y = 0; y < dem->height; y++)
        memcpy(z0 + (size_t)y * (size_t)dem->width, &TS_PIX(dem, 0, y),
               (size_t)dem->width * sizeof *z0);
    memcpy(out, z0, n * sizeof *out);
    memset(&j, 0, sizeof j);
    j.z0 = z0;
    j.out = out;
    j.banks = p->bank_slope > 0 ? p->bank_slope : 0.0;
    j.max_depth = ts_drainage_depth_of(p);
    j.shallow_depth =
        p->shallow_depth > 0 && flags && p->mode == TS_DRAINAGE_BREACH ? p->shallow_depth : 0.0;
    j.flags = flags;
    /* the floor a shallow cell stands beside: the nearest fixed cell within the
     * reach of the shallow cells' band (a quarter of the radius, diagonally) */
    if (j.shallow_depth > 0 &&
        !(floor = ts__nearest_fixed_levels(z0, flags, dem->width, dem->height,
                                           DR_FLOOR_REACH(p->radius)))) {
        free(z0);
        free(out);
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory for %d x %d cells",
                        dem->width, dem->height);
    }
    j.floor = floor;
    j.w = dem->width;
    j.h = dem->height;
    j.gx0 = gx0;
    j.gy0 = gy0;
    j.gw = gw;
    j.gh = gh;
    j.mode = p->mode;
    j.radius = p->radius;
    j.ctx = ctx;
    /* pits whose search stays in the window: radius + 1 from a side that is
     * not the grid's edge (a pit's neighbours and its whole box known) */
    for (a = 0; a < 2; a++) {
        int64_t g0 = a ? gy0 : gx0, size = a ? dem->height : dem->width, gsz = a ? gh : gw;
        j.lo[a] = g0 > 0 ? p->radius + 1 : 0;
        j.hi[a] = (int)(g0 + size < gsz ? size - p->radius - 1 : size);
        if (g0 < 0) /* cells off the grid: not looked at */
            j.lo[a] = (int)-g0;
        if (g0 + size > gsz)
            j.hi[a] = (int)(gsz - g0);
    }
    st = dr_cell_tables(ctx, &j, &out_mask, &shore);
    if (st == TS_OK)
        st = find_pits(ctx, &j, &pits, &n_pits);
    if (st == TS_OK)
        st = ts__progress(ctx, 0.1, "drainage");
    j.pits = pits;
    j.n_pits = n_pits;
    atomic_init(&j.resolved, 0);
    atomic_init(&j.failed, 0);
    /* every pit's fill, or its channel and banks, searched on the surface as given */
    if (st == TS_OK && n_pits) {
        ts__parallel_for(ctx, n_pits, drain_range, &j);
        st = drain_status(ctx, &j);
    }
    if (st == TS_OK) {
        double sum = 0.0;
        size_t changed = 0;
        for (y = 0; y < dem->height; y++)
            for (x = 0; x < dem->width; x++) {
                i = (size_t)y * (size_t)dem->width + (size_t)x;
                if (out[i] != z0[i]) {
                    changed++;
                    sum += fabs((double)out[i] - (double)z0[i]);
                }
                TS_PIX(dem, x, y) = out[i];
            }
        if (info) {
            info->pits = n_pits;
            info->resolved = atomic_load(&j.resolved);
            info->cells_changed = changed;
            info->mean_change = changed ? sum / (double)changed : 0.0;
        }
        st = ts__progress(ctx, 1.0, "drainage");
    }
    free(pits);
    free(floor);
    free(out_mask);
    free(shore);
    free(z0);
    free(out);
    return st;
}

TS_API ts_status ts_drainage_apply(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags,
                                   int64_t gx0, int64_t gy0, int64_t gw, int64_t gh,
                                   const ts_drainage_params *p, ts_drainage_info *info)
{
    ts__clear(ctx);
    if (info)
        memset(info, 0, sizeof *info);
    if (!dem || !dem->data || !p || dem->width < 1 || dem->height < 1 || gw < 1 || gh < 1)
        return ts__fail(ctx, TS_ERR_ARG, "drainage", "no surface");
    if (p->mode < TS_DRAINAGE_KEEP || p->mode > TS_DRAINAGE_FILL)
        return ts__fail(ctx, TS_ERR_ARG, "drainage", "mode %d is not keep, breach or fill",
                        p->mode);
    if (!(p->max_depth >= 0 || p->max_depth == -1))
        return ts__fail(ctx, TS_ERR_ARG, "drainage", "depth %g is not -1, 0 or more", p->max_depth);
    if (!(p->bank_slope >= 0 || p->bank_slope == -1))
        return ts__fail(ctx, TS_ERR_ARG, "drainage", "bank slope %g is not -1, 0 or more",
                        p->bank_slope);
    if (p->radius < 1 || p->radius > TS_DRAINAGE_RADIUS_MAX)
        return ts__fail(ctx, TS_ERR_ARG, "drainage", "radius %d is not 1..%d", p->radius,
                        TS_DRAINAGE_RADIUS_MAX);
    if (gx0 > gw || gy0 > gh || gx0 + dem->width < 0 || gy0 + dem->height < 0)
        return ts__fail(ctx, TS_ERR_ARG, "drainage", "the window is off the grid");
    if (p->mode == TS_DRAINAGE_KEEP)
        return TS_OK;
    if (p->mode == TS_DRAINAGE_BREACH && p->basin_block > 0) {
        if (gx0 != 0 || gy0 != 0 || gw != dem->width || gh != dem->height)
            return ts__fail(ctx, TS_ERR_ARG, "drainage",
                            "basins are lifted on the whole grid only, not a window");
        if (!(p->basin_grade >= 0))
            return ts__fail(ctx, TS_ERR_ARG, "drainage", "basin grade %g is below 0",
                            p->basin_grade);
        return ts__drain_lifted(ctx, dem, flags, p, info);
    }
    if (p->mode == TS_DRAINAGE_BREACH && p->floodplain_relief > 0 && flags) {
        if (gx0 != 0 || gy0 != 0 || gw != dem->width || gh != dem->height)
            return ts__fail(ctx, TS_ERR_ARG, "drainage",
                            "dammed basins are raised on the whole grid only, not a window");
        return ts__drain_with_plains(ctx, dem, flags, p, info);
    }
    return ts__drain_pass(ctx, dem, flags, gx0, gy0, gw, gh, p, info);
}
