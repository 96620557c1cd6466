/*
 * seam_graphcut.c - graph-cut optimal seam finder (Zhou et al. 2007
 * section 5.1 and App. A, after Kwatra et al. 2003).  Every cell of a
 * window either keeps the output's current content (old, label 0, the
 * source side) or takes the new patch (label 1, the sink side); the seam
 * minimises the summed mismatch M (eq. 1) of 4-adjacent pairs across it
 * (eq. 2).  Only the free overlap cells become graph nodes: links to
 * forced neighbours are folded into terminal capacities, so no infinite
 * capacity is ever needed.  One max-flow (maxflow.c) on <= w*h nodes and
 * <= 2*w*h edges, near-linear in practice; about 110 bytes per cell.
 * Thread-safe with one ctx per thread.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>

#include "internal.h"
#include "maxflow.h"

#define SEAM_STAGE "seam graph cut"

/* What a cell of the window is. */
enum {
    SEAM_CELL_FREE = 0, /* in the overlap, not constrained: a graph node */
    SEAM_CELL_OLD = 1,  /* must keep old (patch is nodata, or constrained) */
    SEAM_CELL_NEW = 2,  /* must take the patch (old is nodata, or constrained) */
    SEAM_CELL_EMPTY = 3 /* both nodata: nothing there, label 0, no links */
};

/*
 * M of eq. 1 for 4-adjacent cells s, t with mismatches ds = |a(s) - b(s)|
 * and dt (NaN where the cell is outside the overlap).  Eq. 1 needs both
 * contents at both cells; on the rim of the overlap one cell has only one
 * of them.  There the defined term is doubled: the seam then costs what an
 * interior seam between two cells of that mismatch would, instead of
 * nothing, which would otherwise pull every seam onto the rim of the
 * overlap (no blending at all).  Between two cells outside the overlap
 * the contents abut whatever the labels, and eq. 2 sums over the overlap
 * only: 0.
 */
static double seam_weight(double ds, double dt)
{
    if (!isnan(ds) && !isnan(dt))
        return ds + dt;
    if (!isnan(ds))
        return 2.0 * ds;
    if (!isnan(dt))
        return 2.0 * dt;
    return 0.0;
}

/* Classify every cell and store its mismatch; counts the free cells.
 * Fails with TS_ERR_ARG on contradictory or unknown constraints and on
 * infinite elevations. */
static ts_status seam_classify(ts_ctx *ctx, const ts_raster *old, const ts_raster *patch,
                               const unsigned char *constraint, unsigned char *cls, double *diff,
                               size_t *n_free)
{
    int w = old->width, h = old->height, x, y;
    size_t n = 0;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t p = (size_t)y * (size_t)w + (size_t)x;
            double a = TS_PIX(old, x, y), b = TS_PIX(patch, x, y);
            int c = constraint ? constraint[p] : TS_SEAM_FREE;
            if (isinf(a) || isinf(b))
                return ts__fail(ctx, TS_ERR_ARG, SEAM_STAGE, "%s is infinite at cell (%d, %d)",
                                isinf(a) ? "old" : "the patch", x, y);
            if (c != TS_SEAM_FREE && c != TS_SEAM_OLD && c != TS_SEAM_NEW)
                return ts__fail(ctx, TS_ERR_ARG, SEAM_STAGE,
                                "constraint %d at cell (%d, %d) is not TS_SEAM_FREE, "
                                "TS_SEAM_OLD or TS_SEAM_NEW",
                                c, x, y);
            if (c == TS_SEAM_NEW && isnan(b))
                return ts__fail(ctx, TS_ERR_ARG, SEAM_STAGE,
                                "cell (%d, %d) is forced to the patch (TS_SEAM_NEW) but the "
                                "patch is nodata there",
                                x, y);
            if (c == TS_SEAM_OLD && isnan(a))
                return ts__fail(ctx, TS_ERR_ARG, SEAM_STAGE,
                                "cell (%d, %d) is forced to keep old (TS_SEAM_OLD) but old is "
                                "nodata there",
                                x, y);
            diff[p] = NAN;
            if (isnan(a) && isnan(b)) {
                cls[p] = SEAM_CELL_EMPTY;
            } else if (isnan(a)) {
                cls[p] = SEAM_CELL_NEW;
            } else if (isnan(b)) {
                cls[p] = SEAM_CELL_OLD;
            } else {
                diff[p] = fabs(a - b);
                cls[p] = c == TS_SEAM_OLD   ? SEAM_CELL_OLD
                         : c == TS_SEAM_NEW ? SEAM_CELL_NEW
                                            : SEAM_CELL_FREE;
                n += cls[p] == SEAM_CELL_FREE;
            }
        }
    *n_free = n;
    return TS_OK;
}

/* Link 4-adjacent cells s, t.  A free-free pair is an edge of capacity M
 * both ways; a free cell next to a forced one pays M when it takes the
 * other label, i.e. a terminal capacity towards the forced side (source =
 * old).  Pairs of forced cells never change and need no link. */
static int seam_link(ts_maxflow *g, const unsigned char *cls, const double *diff,
                     const uint32_t *node, size_t s, size_t t)
{
    double m;
    size_t fr, fo;
    if (cls[s] == SEAM_CELL_EMPTY || cls[t] == SEAM_CELL_EMPTY)
        return 0;
    if (cls[s] != SEAM_CELL_FREE && cls[t] != SEAM_CELL_FREE)
        return 0;
    m = seam_weight(diff[s], diff[t]);
    if (m == 0)
        return 0;
    if (cls[s] == SEAM_CELL_FREE && cls[t] == SEAM_CELL_FREE)
        return ts__maxflow_add_edge(g, node[s], node[t], m, m);
    fr = cls[s] == SEAM_CELL_FREE ? s : t;
    fo = fr == s ? t : s;
    return cls[fo] == SEAM_CELL_OLD ? ts__maxflow_add_tweights(g, node[fr], m, 0.0)
                                    : ts__maxflow_add_tweights(g, node[fr], 0.0, m);
}

/* Build and solve the graph over the free cells; labels get 0/1 there. */
static ts_status seam_solve(ts_ctx *ctx, int w, int h, const unsigned char *cls, const double *diff,
                            size_t n_free, unsigned char *labels)
{
    size_t n = (size_t)w * (size_t)h, p, k = 0;
    uint32_t *node = ts__malloc_array(n, sizeof *node);
    ts_maxflow *g = ts__maxflow_new(n_free, 2 * n_free);
    int x, y, bad = 0;
    double flow;
    if (!node || !g) {
        free(node);
        ts__maxflow_free(g);
        return ts__fail(ctx, TS_ERR_NOMEM, SEAM_STAGE, "cannot allocate a graph of %zu nodes",
                        n_free);
    }
    for (p = 0; p < n; p++)
        node[p] = cls[p] == SEAM_CELL_FREE ? (uint32_t)k++ : UINT32_MAX;
    for (y = 0; y < h && !bad; y++)
        for (x = 0; x < w; x++) {
            p = (size_t)y * (size_t)w + (size_t)x;
            if (x + 1 < w)
                bad |= seam_link(g, cls, diff, node, p, p + 1);
            if (y + 1 < h)
                bad |= seam_link(g, cls, diff, node, p, p + (size_t)w);
        }
    if (bad || ts__maxflow_solve(g, &flow) != 0) {
        free(node);
        ts__maxflow_free(g);
        return ts__fail(ctx, TS_ERR_NOMEM, SEAM_STAGE, "cannot allocate a graph of %zu nodes",
                        n_free);
    }
    for (p = 0; p < n; p++)
        if (node[p] != UINT32_MAX)
            labels[p] = (unsigned char)ts__maxflow_is_sink(g, node[p]);
    free(node);
    ts__maxflow_free(g);
    return TS_OK;
}

/* c_g of eq. 2 for the final labels: M summed over 4-adjacent pairs with
 * different labels, pairs touching an empty cell excluded. */
static double seam_cost(int w, int h, const unsigned char *cls, const double *diff,
                        const unsigned char *labels)
{
    double c = 0.0;
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t p = (size_t)y * (size_t)w + (size_t)x, q;
            if (cls[p] == SEAM_CELL_EMPTY)
                continue;
            q = p + 1;
            if (x + 1 < w && cls[q] != SEAM_CELL_EMPTY && labels[p] != labels[q])
                c += seam_weight(diff[p], diff[q]);
            q = p + (size_t)w;
            if (y + 1 < h && cls[q] != SEAM_CELL_EMPTY && labels[p] != labels[q])
                c += seam_weight(diff[p], diff[q]);
        }
    return c;
}

TS_API ts_status ts_seam_graphcut(ts_ctx *ctx, const ts_raster *old, const ts_raster *patch,
                                  const unsigned char *constraint, unsigned char *labels,
                                  double *cost)
{
    unsigned char *cls;
    double *diff;
    size_t n, n_free = 0, p;
    ts_status st;
    int w, h;
    ts__clear(ctx);
    if (!old || !patch || !old->data || !patch->data || !labels)
        return ts__fail(ctx, TS_ERR_ARG, SEAM_STAGE, "missing raster or labels");
    w = old->width;
    h = old->height;
    if (patch->width != w || patch->height != h)
        return ts__fail(ctx, TS_ERR_ARG, SEAM_STAGE, "old is %d x %d but the patch is %d x %d", w,
                        h, patch->width, patch->height);
    if (w <= 0 || h <= 0)
        return ts__fail(ctx, TS_ERR_SIZE, SEAM_STAGE, "empty window (%d x %d)", w, h);
    if (old->stride < w || patch->stride < w)
        return ts__fail(ctx, TS_ERR_ARG, SEAM_STAGE, "stride smaller than the width");
    n = (size_t)w * (size_t)h;
    if (n >= UINT32_MAX)
        return ts__fail(ctx, TS_ERR_SIZE, SEAM_STAGE, "window of %d x %d is too large", w, h);
    cls = ts__malloc_array(n, sizeof *cls);
    diff = ts__malloc_array(n, sizeof *diff);
    if (!cls || !diff) {
        free(cls);
        free(diff);
        return ts__fail(ctx, TS_ERR_NOMEM, SEAM_STAGE, "cannot allocate for %d x %d cells", w, h);
    }
    st = seam_classify(ctx, old, patch, constraint, cls, diff, &n_free);
    if (st == TS_OK) {
        for (p = 0; p < n; p++)
            labels[p] = cls[p] == SEAM_CELL_NEW;
        if (n_free > 0)
            st = seam_solve(ctx, w, h, cls, diff, n_free, labels);
    }
    if (st == TS_OK && cost)
        *cost = seam_cost(w, h, cls, diff, labels);
    free(cls);
    free(diff);
    return st;
}
