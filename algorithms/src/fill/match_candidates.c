/*
 * match_candidates.c - the k best separated candidates of a masked-SSD
 * query (Zhou et al. 2007 section 4.2): ts_matcher_best reads the float
 * map of match_ssd.c in order and rescores in double only what the float
 * error bound cannot rule out.  Thread-safety: one thread per matcher at a
 * time; results do not depend on the thread count.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "match_ssd.h"

/* Bound on |float map - exact SSD| relative to sum M T'^2 + known * max E'^2
 * (observed <= ~1e-6 in tests/c/fill/test_match_ssd.c; float eps is 6e-8). */
#define MATCH_FLOAT_ERR 1e-5

/* ---- k best: a stream of map entries, separation, exact rescoring ------ */

typedef struct match_pick {
    float v;    /* float map value */
    size_t idx; /* y * nx + x */
} match_pick;

typedef struct match_exact {
    double e; /* exact SSD */
    size_t idx;
} match_exact;

/* Total orders: by value, ties by index (lower y, then lower x). */
static int match_pick_less(const match_pick *a, const match_pick *b)
{
    return a->v < b->v || (a->v == b->v && a->idx < b->idx);
}

static int match_pick_cmp(const void *a, const void *b)
{
    return match_pick_less(a, b) ? -1 : match_pick_less(b, a);
}

static int match_exact_less(const match_exact *a, const match_exact *b)
{
    return a->e < b->e || (a->e == b->e && a->idx < b->idx);
}

/* Rearrange a[0, n) so that a[k] is the k-th lowest, lower ones before it
 * and higher ones after (quickselect, median-of-three pivots; keys are
 * distinct because indices are). */
static void match_select(match_pick *a, ptrdiff_t n, ptrdiff_t k)
{
    ptrdiff_t lo = 0, hi = n - 1;
    while (hi > lo) {
        const ptrdiff_t mid = lo + (hi - lo) / 2;
        match_pick t, pivot;
        ptrdiff_t i = lo, j = hi;
        if (match_pick_less(&a[mid], &a[lo])) {
            t = a[mid], a[mid] = a[lo], a[lo] = t;
        }
        if (match_pick_less(&a[hi], &a[lo])) {
            t = a[hi], a[hi] = a[lo], a[lo] = t;
        }
        if (match_pick_less(&a[hi], &a[mid])) {
            t = a[hi], a[hi] = a[mid], a[mid] = t;
        }
        pivot = a[mid];
        while (i <= j) {
            while (match_pick_less(&a[i], &pivot))
                i++;
            while (match_pick_less(&pivot, &a[j]))
                j--;
            if (i <= j) {
                t = a[i], a[i] = a[j], a[j] = t;
                i++;
                j--;
            }
        }
        if (k <= j)
            hi = j;
        else if (k >= i)
            lo = i;
        else
            return;
    }
}

/* The cap lowest finite entries of positions [from, to) of the map (row y
 * at map + y * pitch, nx entries) above `after` (NULL: no bound), unsorted,
 * in buf (room for 2 * cap).  Candidates are appended; when buf is full a
 * quickselect keeps the cap lowest and raises the bar: O(1) amortised per
 * entry whatever the order of the values (a smooth map in scan order is
 * the worst case of a bounded heap). */
static size_t match_scan(const float *map, size_t pitch, size_t nx, size_t from, size_t to,
                         size_t cap, const match_pick *after, match_pick *buf)
{
    const float *row = map + from / nx * pitch;
    float bar = INFINITY; /* entries come in index order: the value decides */
    size_t n = 0, i, x = from % nx;
    for (i = from; i < to; i++, x++) {
        match_pick item;
        if (x == nx) {
            x = 0;
            row += pitch;
        }
        item.v = row[x];
        item.idx = i;
        if (!(item.v < bar) || (after && !match_pick_less(after, &item)))
            continue;
        buf[n++] = item;
        if (n == 2 * cap) {
            match_select(buf, (ptrdiff_t)n, (ptrdiff_t)cap - 1);
            n = cap;
            bar = buf[cap - 1].v;
        }
    }
    if (n > cap)
        match_select(buf, (ptrdiff_t)n, (ptrdiff_t)cap - 1);
    return TS_MIN(n, cap);
}

typedef struct match_batch_job {
    const float *map; /* row y at map + y * pitch */
    size_t pitch, nx;
    const match_pick *after;
    size_t npos, cap;
    int nslots;
    match_pick *heaps; /* nslots * 2 * cap: a selection buffer per slice */
    size_t count[TS__MATCH_MAX_SLOTS];
} match_batch_job;

static void match_batch_slot(void *arg, size_t begin, size_t end)
{
    match_batch_job *job = arg;
    size_t slot;
    for (slot = begin; slot < end; slot++)
        job->count[slot] =
            match_scan(job->map, job->pitch, job->nx, job->npos * slot / (size_t)job->nslots,
                       job->npos * (slot + 1) / (size_t)job->nslots, job->cap, job->after,
                       job->heaps + slot * 2 * job->cap);
}

/* Min-heap of exact entries. */
static void match_exact_push(match_exact *h, size_t *n, match_exact item)
{
    size_t c = (*n)++;
    while (c > 0 && match_exact_less(&item, &h[(c - 1) / 2])) {
        h[c] = h[(c - 1) / 2];
        c = (c - 1) / 2;
    }
    h[c] = item;
}

static match_exact match_exact_pop(match_exact *h, size_t *n)
{
    const match_exact top = h[0], item = h[--*n];
    size_t p = 0;
    for (;;) {
        size_t l = 2 * p + 1, small;
        if (l >= *n)
            break;
        small = (l + 1 < *n && match_exact_less(&h[l + 1], &h[l])) ? l + 1 : l;
        if (!match_exact_less(&h[small], &item))
            break;
        h[p] = h[small];
        p = small;
    }
    if (*n > 0)
        h[p] = item;
    return top;
}

/* Taken positions for the Chebyshev separation test.  With sep x sep
 * buckets, two positions in one bucket are closer than sep, so a bucket
 * holds at most one taken position: a hash keyed by bucket finds the
 * candidates in the 3 x 3 neighbouring buckets in O(1). */
typedef struct match_sep {
    int sep;
    int64_t gx;   /* buckets per row */
    size_t cap;   /* power of two >= 2 * max taken */
    int64_t *key; /* bucket id, -1 = empty */
    int *px, *py; /* the taken position in that slot */
} match_sep;

static ts_status match_sep_init(match_sep *s, int sep, int nx, int k)
{
    size_t cap = 16, i;
    memset(s, 0, sizeof *s);
    s->sep = sep;
    if (sep <= 1)
        return TS_OK;
    s->gx = (nx + (int64_t)sep - 1) / sep;
    while (cap < 2 * (size_t)k)
        cap *= 2;
    s->cap = cap;
    s->key = ts__malloc_array(cap, sizeof *s->key);
    s->px = ts__malloc_array(cap, sizeof *s->px);
    s->py = ts__malloc_array(cap, sizeof *s->py);
    if (!s->key || !s->px || !s->py)
        return TS_ERR_NOMEM;
    for (i = 0; i < cap; i++)
        s->key[i] = -1;
    return TS_OK;
}

static void match_sep_free(match_sep *s)
{
    free(s->key);
    free(s->px);
    free(s->py);
}

static size_t match_sep_slot(const match_sep *s, int64_t key)
{
    size_t h = (size_t)(((uint64_t)key * 0x9e3779b97f4a7c15ull) >> 20) & (s->cap - 1);
    while (s->key[h] != -1 && s->key[h] != key)
        h = (h + 1) & (s->cap - 1);
    return h;
}

/* 1 if position idx is at least sep from every taken position. */
static int match_sep_ok(const match_sep *s, int nx, size_t idx)
{
    const int x = (int)(idx % (size_t)nx), y = (int)(idx / (size_t)nx);
    int64_t bx, by, dx, dy;
    if (s->sep <= 1)
        return 1;
    bx = x / s->sep;
    by = y / s->sep;
    for (dy = -1; dy <= 1; dy++)
        for (dx = -1; dx <= 1; dx++) {
            size_t h;
            if (bx + dx < 0 || by + dy < 0 || bx + dx >= s->gx)
                continue;
            h = match_sep_slot(s, (by + dy) * s->gx + bx + dx);
            if (s->key[h] != -1 && abs(s->px[h] - x) < s->sep && abs(s->py[h] - y) < s->sep)
                return 0;
        }
    return 1;
}

/* The added cost of position idx (0 without a cost map). */
static double match_cost(const ts_matcher *m, size_t idx)
{
    return m->cost ? m->cost_w * (double)m->cost[idx] : 0.0;
}

/* Add the cost map to the float SSD map left in rows1; returns the
 * largest cost added. */
static double match_add_cost(const ts_matcher *m)
{
    const size_t pitch = 2 * (size_t)m->stride;
    float *map = (float *)m->rows1;
    double most = 0.0;
    int x, y;
    if (!m->cost)
        return 0.0;
    for (y = 0; y < m->ny; y++)
        for (x = 0; x < m->nx; x++) {
            const double c = match_cost(m, (size_t)y * (size_t)m->nx + (size_t)x);
            float *v = map + (size_t)y * pitch + (size_t)x;
            if (isfinite(*v))
                *v = (float)((double)*v + c);
            most = c > most ? c : most;
        }
    return most;
}

/* Take position idx if it is far enough from the taken ones. */
static int match_take(match_sep *s, int nx, size_t idx, double ssd, ts_candidate *out, int *nt)
{
    if (!match_sep_ok(s, nx, idx))
        return 0;
    out[*nt].x = (int)(idx % (size_t)nx);
    out[*nt].y = (int)(idx / (size_t)nx);
    out[*nt].ssd = ssd;
    (*nt)++;
    if (s->sep > 1) {
        const int64_t key = (int64_t)(out[*nt - 1].y / s->sep) * s->gx + out[*nt - 1].x / s->sep;
        const size_t h = match_sep_slot(s, key);
        s->key[h] = key;
        s->px[h] = out[*nt - 1].x;
        s->py[h] = out[*nt - 1].y;
    }
    return 1;
}

/* Known target cells as offsets into the exemplar and values in double. */
typedef struct match_known {
    size_t n;
    ptrdiff_t *off;
    double *val;
} match_known;

static ts_status match_known_init(match_known *kn, const ts_matcher *m, const ts_raster *t)
{
    int i, j;
    kn->n = 0;
    kn->off = ts__malloc_array((size_t)m->pw * (size_t)m->ph, sizeof *kn->off);
    kn->val = ts__malloc_array((size_t)m->pw * (size_t)m->ph, sizeof *kn->val);
    if (!kn->off || !kn->val)
        return TS_ERR_NOMEM;
    for (j = 0; j < m->ph; j++)
        for (i = 0; i < m->pw; i++)
            if (isfinite(TS_PIX(t, i, j))) {
                kn->off[kn->n] = (ptrdiff_t)j * m->ex.stride + i;
                kn->val[kn->n] = TS_PIX(t, i, j);
                kn->n++;
            }
    return TS_OK;
}

static void match_known_free(match_known *kn)
{
    free(kn->off);
    free(kn->val);
}

/* The exact SSD of window idx, in double, in the target's row-major order. */
static double match_exact_ssd(const ts_matcher *m, const match_known *kn, size_t idx)
{
    const float *e = m->ex.data + (ptrdiff_t)(idx / (size_t)m->nx) * m->ex.stride +
                     (ptrdiff_t)(idx % (size_t)m->nx);
    double s = 0.0;
    size_t c;
    for (c = 0; c < kn->n; c++) {
        const double d = kn->val[c] - e[kn->off[c]];
        s += d * d;
    }
    return s;
}

/* qsort's order of match_exact_less. */
static int match_exact_cmp(const void *a, const void *b)
{
    return match_exact_less(a, b) ? -1 : match_exact_less(b, a);
}

/* No known target cell: every valid window has SSD 0; take them in
 * row-major order, or with a cost map in order of cost (then index); -1
 * when out of memory. */
static int match_best_empty(const ts_matcher *m, match_sep *s, int k, ts_candidate *out)
{
    const size_t n = (size_t)m->nx * (size_t)m->ny;
    size_t i, nv = 0;
    match_exact *order;
    int nt = 0;
    if (!m->cost) {
        for (i = 0; i < n && nt < k; i++)
            if (m->valid[i])
                match_take(s, m->nx, i, 0.0, out, &nt);
        return nt;
    }
    if (!(order = ts__malloc_array(n, sizeof *order)))
        return -1;
    for (i = 0; i < n; i++)
        if (m->valid[i])
            order[nv++] = (match_exact){match_cost(m, i), i};
    qsort(order, nv, sizeof *order, match_exact_cmp);
    for (i = 0; i < nv && nt < k; i++)
        match_take(s, m->nx, order[i].idx, order[i].e, out, &nt);
    free(order);
    return nt;
}

/*
 * The greedy k best in exact order (exact SSD, then index), reading the
 * float map as a stream in (value, index) order with |map - exact| <=
 * delta.  Rescored entries wait in a heap; the lowest is decided (taken if
 * far enough from the taken ones, else dropped) once it is below the next
 * stream value minus delta, as no unseen window can then precede it.  A
 * stream entry already too close to a taken window is dropped unscored:
 * that window precedes it, so the full greedy would drop it too.  The
 * stream comes in batches of the cap lowest entries above the last one
 * read (one pass over the map per batch, cap x 4 each time).
 */
static ts_status match_best_search(ts_ctx *ctx, const ts_matcher *m, const match_known *kn,
                                   double delta, match_sep *s, int k, ts_candidate *out,
                                   int *n_found)
{
    const size_t npos = (size_t)m->nx * (size_t)m->ny;
    const int nslots = TS_MIN(ts__match_workers(ctx, npos, npos), TS__MATCH_MAX_SLOTS);
    size_t cap = TS_MIN(m->n_valid, 1024 + 64 * (size_t)k);
    match_batch_job *job = malloc(sizeof *job);
    match_exact *wait = NULL;
    size_t n_wait = 0, cap_wait = 0;
    match_pick last;
    int have_last = 0, nt = 0, exhausted = 0;
    ts_status st = TS_OK;
    if (!job)
        return TS_ERR_NOMEM;
    job->heaps = NULL;
    while (st == TS_OK && nt < k && !exhausted) {
        size_t n = 0, i, slot;
        job->map = (const float *)m->rows1; /* where ts__match_map left it */
        job->pitch = 2 * (size_t)m->stride;
        job->nx = (size_t)m->nx;
        job->after = have_last ? &last : NULL;
        job->npos = npos;
        job->cap = cap;
        job->nslots = cap > npos / 16 ? 1 : nslots; /* big batches: one slice, bounded memory */
        free(job->heaps);
        job->heaps = ts__malloc_array((size_t)job->nslots * 2 * cap, sizeof *job->heaps);
        if (!job->heaps) {
            st = TS_ERR_NOMEM;
            break;
        }
        if (job->nslots > 1)
            ts__parallel_for(ctx, (size_t)job->nslots, match_batch_slot, job);
        else
            match_batch_slot(job, 0, 1);
        /* the union of the slices' cap lowest holds the cap lowest overall */
        for (slot = 0; slot < (size_t)job->nslots; slot++) {
            memmove(job->heaps + n, job->heaps + slot * 2 * cap,
                    job->count[slot] * sizeof *job->heaps);
            n += job->count[slot];
        }
        qsort(job->heaps, n, sizeof *job->heaps, match_pick_cmp);
        exhausted = n < cap; /* every remaining entry is in this batch */
        n = TS_MIN(n, cap);
        for (i = 0; i < n && nt < k; i++) {
            const match_pick p = job->heaps[i];
            last = p;
            have_last = 1;
            while (n_wait > 0 && nt < k && wait[0].e < (double)p.v - delta) {
                const match_exact a = match_exact_pop(wait, &n_wait);
                match_take(s, m->nx, a.idx, a.e, out, &nt);
            }
            if (nt == k || !match_sep_ok(s, m->nx, p.idx))
                continue;
            if (n_wait == cap_wait) {
                size_t grow = cap_wait ? 2 * cap_wait : 256;
                match_exact *w = realloc(wait, grow * sizeof *w);
                if (!w) {
                    st = TS_ERR_NOMEM;
                    break;
                }
                wait = w;
                cap_wait = grow;
            }
            match_exact_push(
                wait, &n_wait,
                (match_exact){match_exact_ssd(m, kn, p.idx) + match_cost(m, p.idx), p.idx});
        }
        cap = cap > m->n_valid / 4 ? m->n_valid : 4 * cap;
    }
    /* the stream is exhausted: what waits is in exact order */
    while (st == TS_OK && nt < k && n_wait > 0) {
        const match_exact a = match_exact_pop(wait, &n_wait);
        match_take(s, m->nx, a.idx, a.e, out, &nt);
    }
    if (st == TS_OK)
        *n_found = nt;
    free(job->heaps);
    free(job);
    free(wait);
    return st;
}

/* ---- public API -------------------------------------------------------- */

TS_API ts_status ts_matcher_best(ts_ctx *ctx, ts_matcher *m, const ts_raster *target, int k,
                                 int min_separation, ts_candidate *out, int *n_found)
{
    ts_status st;
    match_sep sep;
    match_known kn = {0, NULL, NULL};
    double sum_t2 = 0.0, delta;
    ts_progress_saved saved;
    ts__clear(ctx);
    if (n_found)
        *n_found = 0;
    if ((st = ts__match_check_target(ctx, m, target)) != TS_OK)
        return st;
    if (k < 1)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "k must be at least 1, got %d", k);
    if (min_separation < 0)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "min_separation must be >= 0, got %d",
                        min_separation);
    if (!out || !n_found)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "missing output candidates");
    if (match_sep_init(&sep, min_separation, m->nx, k) != TS_OK ||
        match_known_init(&kn, m, target) != TS_OK) {
        match_sep_free(&sep);
        match_known_free(&kn);
        return ts__fail(ctx, TS_ERR_NOMEM, TS__MATCH_STAGE, "cannot allocate for k = %d", k);
    }
    if (kn.n == 0) {
        int nt = match_best_empty(m, &sep, k, out);
        match_sep_free(&sep);
        match_known_free(&kn);
        if (nt < 0)
            return ts__fail(ctx, TS_ERR_NOMEM, TS__MATCH_STAGE, "cannot allocate for k = %d", k);
        *n_found = nt;
        return ts__progress(ctx, 1.0, "best candidates");
    }
    saved = ts__progress_push(ctx, 0.0, 0.9);
    st = ts__match_map(ctx, m, target, NULL, &sum_t2);
    ts__progress_pop(ctx, saved);
    if (st == TS_OK) {
        delta = MATCH_FLOAT_ERR * (sum_t2 + (double)kn.n * m->max_dev2 + match_add_cost(m));
        st = match_best_search(ctx, m, &kn, delta, &sep, k, out, n_found);
        if (st != TS_OK)
            st = ts__fail(ctx, st, TS__MATCH_STAGE, "cannot allocate the candidate stream");
        else
            st = ts__progress(ctx, 1.0, "best candidates");
    }
    match_sep_free(&sep);
    match_known_free(&kn);
    return st;
}
