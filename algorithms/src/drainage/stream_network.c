/*
 * stream_network.c - the flow lines of a DEM (ours): the streams a
 * drainage-area threshold draws, as links with their Strahler order.
 *
 * The flow is the PPA's drainage test's (ppa/drainage_area.c): depressions
 * filled to their spill, flats crossed to their way out, each cell to its
 * neighbour of least (filled height, steps out), a cell on the DEM's edge
 * or beside nodata off the DEM; the drainage area of a cell is itself and
 * every cell whose flow passes through it.  A cell draining at least
 * min_area cells is a stream cell; its flow goes to a stream cell (the area
 * grows downstream) or off the DEM, so the stream cells are a forest whose
 * roots are outlets.
 *
 * Strahler order (Strahler 1957): a head (no stream cell flows into it) is
 * 1; a cell where two or more inflows of the highest order i meet is i + 1,
 * any other cell the highest order of its inflows.
 *
 * A link runs from a head or a confluence (two or more inflows) down to the
 * next confluence (its last vertex, shared with the links that start there)
 * or to its outlet; one order along it.  Links are listed by their first
 * cell in raster order, their vertices from upstream to downstream, so the
 * network depends on the DEM and min_area alone (any tiling of the flow
 * gives the same areas and directions).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../ppa/ppa_internal.h"

#define SN_NONE ((size_t)-1)

typedef struct sn_cell {
    uint64_t g; /* row-major index in the grid */
    float area;
    unsigned char dir;
} sn_cell;

typedef struct sn_collect {
    sn_cell *c;
    size_t n, cap;
    int width;
    double min_area;
    int failed;
} sn_collect;

/* ppa_drainage's tiles: their stream cells kept (called under its lock). */
static void collect(void *user, int x0, int y0, int w, int h, const float *area,
                    const unsigned char *dir)
{
    sn_collect *s = user;
    int x, y;
    for (y = 0; y < h && !s->failed; y++)
        for (x = 0; x < w; x++) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            if (dir[i] == 255 || !(area[i] >= s->min_area))
                continue;
            if (s->n == s->cap) {
                size_t cap = s->cap ? 2 * s->cap : 4096;
                sn_cell *c = realloc(s->c, cap * sizeof *c);
                if (!c) {
                    s->failed = 1;
                    return;
                }
                s->c = c;
                s->cap = cap;
            }
            s->c[s->n].g = (uint64_t)(y0 + y) * (uint64_t)s->width + (uint64_t)(x0 + x);
            s->c[s->n].area = area[i];
            s->c[s->n].dir = dir[i];
            s->n++;
        }
}

static int by_index(const void *a, const void *b)
{
    uint64_t u = ((const sn_cell *)a)->g, v = ((const sn_cell *)b)->g;
    return u < v ? -1 : u > v;
}

static size_t find_cell(const sn_cell *c, size_t n, uint64_t g)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (c[mid].g < g)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < n && c[lo].g == g ? lo : SN_NONE;
}

/* Where each stream cell flows (SN_NONE: off the DEM), its inflows and its
 * Strahler order, upstream first (Kahn's order over the forest). */
typedef struct sn_forest {
    size_t *down;
    unsigned char *indeg, *order;
} sn_forest;

static int forest_build(const sn_cell *c, size_t n, int W, int H, sn_forest *f)
{
    unsigned char *left = NULL, *best = NULL, *nbest = NULL;
    size_t *queue = NULL, i, qh = 0, qt = 0;
    int rc = -1;
    f->down = ts__malloc_array(n ? n : 1, sizeof *f->down);
    f->indeg = ts__calloc_array(n ? n : 1, 1);
    f->order = ts__calloc_array(n ? n : 1, 1);
    left = ts__malloc_array(n ? n : 1, 1);
    best = ts__calloc_array(n ? n : 1, 1);
    nbest = ts__calloc_array(n ? n : 1, 1);
    queue = ts__malloc_array(n ? n : 1, sizeof *queue);
    if (!f->down || !f->indeg || !f->order || !left || !best || !nbest || !queue)
        goto out;
    for (i = 0; i < n; i++) {
        int x = (int)(c[i].g % (uint64_t)W), y = (int)(c[i].g / (uint64_t)W), d = c[i].dir;
        f->down[i] = SN_NONE;
        if (d < 8) {
            int nx = x + ppa_dir[d][0], ny = y + ppa_dir[d][1];
            if (nx >= 0 && ny >= 0 && nx < W && ny < H)
                f->down[i] = find_cell(c, n, (uint64_t)ny * (uint64_t)W + (uint64_t)nx);
        }
        if (f->down[i] != SN_NONE)
            f->indeg[f->down[i]]++;
    }
    for (i = 0; i < n; i++) {
        left[i] = f->indeg[i];
        if (!left[i])
            queue[qt++] = i;
    }
    while (qh < qt) {
        size_t u = queue[qh++], v = f->down[u];
        f->order[u] = !f->indeg[u] ? 1 : (unsigned char)(best[u] + (nbest[u] >= 2));
        if (v == SN_NONE)
            continue;
        if (f->order[u] > best[v]) {
            best[v] = f->order[u];
            nbest[v] = 1;
        } else if (f->order[u] == best[v]) {
            nbest[v]++;
        }
        if (--left[v] == 0)
            queue[qt++] = v;
    }
    rc = 0;
out:
    free(left);
    free(best);
    free(nbest);
    free(queue);
    return rc;
}

static int is_start(const sn_forest *f, size_t i)
{
    return f->indeg[i] != 1 && f->down[i] != SN_NONE;
}

/* The links: from each head or confluence that flows on, down to the next
 * confluence or the outlet. */
static int links_build(const sn_cell *c, size_t n, int W, const sn_forest *f,
                       ts_stream_network *net)
{
    size_t i, n_links = 0, n_verts = 0, *link_at = ts__malloc_array(n ? n : 1, sizeof *link_at);
    if (!link_at)
        return -1;
    for (i = 0; i < n; i++) {
        link_at[i] = SN_NONE;
        if (is_start(f, i)) {
            size_t u = i;
            link_at[i] = n_links++;
            n_verts++;
            do {
                u = f->down[u];
                n_verts++;
            } while (f->indeg[u] == 1 && f->down[u] != SN_NONE);
        }
    }
    net->links = ts__calloc_array(n_links ? n_links : 1, sizeof *net->links);
    net->verts = ts__calloc_array(n_verts ? n_verts : 1, sizeof *net->verts);
    if (!net->links || !net->verts) {
        free(link_at);
        return -1;
    }
    for (i = 0; i < n; i++) {
        ts_stream_link *L;
        size_t u = i, above = i; /* the cell before u along the link */
        if (link_at[i] == SN_NONE)
            continue;
        L = &net->links[net->n_links++];
        L->first = net->n_verts;
        L->order = f->order[i];
        for (;;) {
            ts_feature_vertex *v = &net->verts[net->n_verts++];
            v->x = (int)(c[u].g % (uint64_t)W);
            v->y = (int)(c[u].g / (uint64_t)W);
            v->z = NAN;
            if (u != i && (f->indeg[u] != 1 || f->down[u] == SN_NONE))
                break;
            above = u;
            u = f->down[u];
        }
        L->count = net->n_verts - L->first;
        L->down = f->indeg[u] >= 2 && link_at[u] != SN_NONE ? (int64_t)link_at[u] : -1;
        /* the area of its own lowest cell: above the confluence it ends at */
        L->area = c[f->indeg[u] >= 2 ? above : u].area;
    }
    free(link_at);
    return 0;
}

/* The vertices' heights, a row of the DEM read at a time. */
static ts_status vertex_heights(ts_ctx *ctx, ts_stream_network *net, ts_window_read_fn read,
                                void *user)
{
    size_t i, k, *idx = ts__malloc_array(net->n_verts ? net->n_verts : 1, sizeof *idx);
    float *row = ts__malloc_array((size_t)net->width, sizeof *row);
    ts_status st = TS_OK;
    int y = -1;
    if (!idx || !row) {
        free(idx);
        free(row);
        return ts__fail(ctx, TS_ERR_NOMEM, "streams", "out of memory");
    }
    /* counting sort of the vertices by row */
    {
        size_t *start = ts__calloc_array((size_t)net->height + 1, sizeof *start);
        if (!start) {
            free(idx);
            free(row);
            return ts__fail(ctx, TS_ERR_NOMEM, "streams", "out of memory");
        }
        for (i = 0; i < net->n_verts; i++)
            start[net->verts[i].y + 1]++;
        for (k = 0; k < (size_t)net->height; k++)
            start[k + 1] += start[k];
        for (i = 0; i < net->n_verts; i++)
            idx[start[net->verts[i].y]++] = i;
        free(start);
    }
    for (k = 0; k < net->n_verts && st == TS_OK; k++) {
        ts_feature_vertex *v = &net->verts[idx[k]];
        if (v->y != y) {
            y = v->y;
            st = read(user, 0, y, net->width, 1, row);
        }
        if (st == TS_OK)
            v->z = row[v->x];
    }
    free(idx);
    free(row);
    return st;
}

TS_API void ts_stream_network_free(ts_stream_network *net)
{
    if (!net)
        return;
    free(net->links);
    free(net->verts);
    free(net);
}

TS_API ts_status ts_stream_network_extract_read(ts_ctx *ctx, int width, int height,
                                                ts_window_read_fn read, void *user, double min_area,
                                                ts_stream_network **out)
{
    sn_collect s;
    sn_forest f = {NULL, NULL, NULL};
    ts_progress_saved sv;
    ts_stream_network *net = NULL;
    ts_status st;
    if (!out || !read || width < 1 || height < 1)
        return ts__fail(ctx, TS_ERR_ARG, "streams", "no DEM or no output");
    *out = NULL;
    if (!(min_area >= 1))
        return ts__fail(ctx, TS_ERR_ARG, "streams", "the least drainage area %g is below one cell",
                        min_area);
    memset(&s, 0, sizeof s);
    s.width = width;
    s.min_area = min_area;
    sv = ts__progress_push(ctx, 0.0, 0.85);
    st = ppa_drainage(ctx, width, height, ppa_drainage_tile(ctx), 1, read, user, collect, &s);
    ts__progress_pop(ctx, sv);
    if (st == TS_OK && s.failed)
        st = ts__fail(ctx, TS_ERR_NOMEM, "streams", "out of memory for %zu stream cells", s.n);
    if (st != TS_OK)
        goto out;
    qsort(s.c, s.n, sizeof *s.c, by_index);
    net = ts__calloc_array(1, sizeof *net);
    if (!net || forest_build(s.c, s.n, width, height, &f) != 0) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "streams", "out of memory for %zu stream cells", s.n);
        goto out;
    }
    net->width = width;
    net->height = height;
    if (links_build(s.c, s.n, width, &f, net) != 0) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "streams", "out of memory for %zu stream cells", s.n);
        goto out;
    }
    if ((st = ts__check_cancel(ctx)) != TS_OK ||
        (st = vertex_heights(ctx, net, read, user)) != TS_OK)
        goto out;
    st = ts__progress(ctx, 1.0, "streams");
out:
    free(s.c);
    free(f.down);
    free(f.indeg);
    free(f.order);
    if (st == TS_OK)
        *out = net;
    else
        ts_stream_network_free(net);
    return st;
}

TS_API ts_status ts_stream_network_extract(ts_ctx *ctx, const ts_raster *dem, double min_area,
                                           ts_stream_network **out)
{
    if (!dem || !dem->data)
        return ts__fail(ctx, TS_ERR_ARG, "streams", "no DEM");
    return ts_stream_network_extract_read(ctx, dem->width, dem->height, ppa_raster_window,
                                          (void *)dem, min_area, out);
}
