/*
 * similarity_sets.c - k-coherence similarity sets (Lefebvre and Hoppe 2005,
 * section 3.3, after Tong et al. 2002): for every usable cell of every
 * exemplar and level, the `coherence - 1` other cells whose appearance
 * vectors are nearest to its own, found with a kd-tree; the corrections then
 * take as candidates, besides each neighbour's coherent coordinate
 * S(p + d) - h d, the members of its similarity set shifted alike.
 *
 * A cell's set leaves out the cells of its own exemplar less than one level
 * spacing away in both axes (at the finest level: the cell itself): they
 * are the same sample of the level.  (Measured on five DEMs x two seeds:
 * leaving out cells within half a window as well, (k/2 + 1) spacings, took
 * 3.5 x longer and raised the mean slope W1 from 2.5 to 4.1 degrees.)  Turned and
 * mirrored candidates share the sets of the exemplar as given: turning two
 * neighbourhoods alike keeps their distance.
 *
 * The kd-tree: cells split at the median of the axis of widest spread,
 * leaves of at most 8 points; an exact search keeps the K best in a sorted
 * array and visits the far side of a split only while the split plane is
 * nearer than the K-th best.  The tests compare it with a plain scan.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "pixel.h"

#define LEAF 8

struct pix_kdtree {
    const float *pts; /* n x dim, not owned */
    size_t n;
    int dim;
    int32_t *idx;   /* points in tree order */
    int32_t *nodes; /* per node: split axis (-1: leaf) */
    float *split;   /* per node: split value */
    size_t n_nodes;
};

/* Point i before point j on axis a: by value, then by index. */
static int before(const pix_kdtree *t, int a, int32_t i, int32_t j)
{
    float x = t->pts[(size_t)i * t->dim + a], y = t->pts[(size_t)j * t->dim + a];
    return x < y || (x == y && i < j);
}

/* Node i covers idx[lo, hi); children 2i + 1 and 2i + 2. */
static void build(pix_kdtree *t, size_t node, size_t lo, size_t hi)
{
    int dim = t->dim, a, best = 0;
    float bestspread = -1;
    size_t mid, i, left, right;
    if (hi - lo <= LEAF || node * 2 + 2 >= t->n_nodes) {
        t->nodes[node] = -1;
        return;
    }
    for (a = 0; a < dim; a++) {
        float mn = INFINITY, mx = -INFINITY;
        for (i = lo; i < hi; i++) {
            float v = t->pts[(size_t)t->idx[i] * dim + a];
            mn = v < mn ? v : mn;
            mx = v > mx ? v : mx;
        }
        if (mx - mn > bestspread) {
            bestspread = mx - mn;
            best = a;
        }
    }
    /* the median by quickselect, in the total order (value, index) */
    mid = lo + (hi - lo) / 2;
    left = lo;
    right = hi;
    while (right - left > 1) {
        size_t store = left;
        int32_t pv = t->idx[left + (right - left) / 2], tmp;
        t->idx[left + (right - left) / 2] = t->idx[right - 1];
        t->idx[right - 1] = pv;
        for (i = left; i + 1 < right; i++)
            if (before(t, best, t->idx[i], pv)) {
                tmp = t->idx[i];
                t->idx[i] = t->idx[store];
                t->idx[store++] = tmp;
            }
        t->idx[right - 1] = t->idx[store];
        t->idx[store] = pv;
        if (store == mid)
            break;
        if (mid < store)
            right = store;
        else
            left = store + 1;
    }
    t->nodes[node] = best;
    t->split[node] = t->pts[(size_t)t->idx[mid] * dim + best];
    build(t, node * 2 + 1, lo, mid);
    build(t, node * 2 + 2, mid, hi);
}

pix_kdtree *ts__pix_kdtree_build(const float *pts, size_t n, int dim)
{
    pix_kdtree *t = calloc(1, sizeof *t);
    size_t i, leaves = 1;
    if (!t)
        return NULL;
    t->pts = pts;
    t->n = n;
    t->dim = dim;
    while (leaves * LEAF < n)
        leaves *= 2;
    t->n_nodes = 2 * leaves - 1;
    t->idx = ts__malloc_array(n ? n : 1, sizeof *t->idx);
    t->nodes = ts__malloc_array(t->n_nodes, sizeof *t->nodes);
    t->split = ts__malloc_array(t->n_nodes, sizeof *t->split);
    if (!t->idx || !t->nodes || !t->split) {
        ts__pix_kdtree_free(t);
        return NULL;
    }
    for (i = 0; i < n; i++)
        t->idx[i] = (int32_t)i;
    build(t, 0, 0, n);
    return t;
}

void ts__pix_kdtree_free(pix_kdtree *t)
{
    if (!t)
        return;
    free(t->idx);
    free(t->nodes);
    free(t->split);
    free(t);
}

typedef struct knn_state {
    const pix_kdtree *t;
    const float *q;
    int K, found;
    int32_t *best;
    float *bd; /* ascending */
    int (*keep)(void *arg, int32_t i);
    void *arg;
} knn_state;

static void offer(knn_state *s, int32_t i)
{
    const float *p = s->t->pts + (size_t)i * s->t->dim;
    float d = 0;
    int a, pos;
    for (a = 0; a < s->t->dim; a++) {
        float e = p[a] - s->q[a];
        d += e * e;
    }
    if (s->found == s->K &&
        (d > s->bd[s->K - 1] || (d == s->bd[s->K - 1] && i > s->best[s->K - 1])))
        return;
    if (s->keep && !s->keep(s->arg, i))
        return;
    pos = s->found < s->K ? s->found++ : s->K - 1;
    /* insert in order of distance, then index (a total order: the same set on any tree) */
    while (pos > 0 && (s->bd[pos - 1] > d || (s->bd[pos - 1] == d && s->best[pos - 1] > i))) {
        s->bd[pos] = s->bd[pos - 1];
        s->best[pos] = s->best[pos - 1];
        pos--;
    }
    s->bd[pos] = d;
    s->best[pos] = i;
}

/* rd: the squared distance from q to the node's cell, off its per-axis parts
 * (Arya and Mount's incremental distance: tighter than the split plane alone). */
static void search(knn_state *s, size_t node, size_t lo, size_t hi, float rd, float *off)
{
    const pix_kdtree *t = s->t;
    size_t mid, i;
    int a = t->nodes[node];
    float diff, old, rd2;
    if (a < 0) {
        for (i = lo; i < hi; i++)
            offer(s, t->idx[i]);
        return;
    }
    mid = lo + (hi - lo) / 2;
    diff = s->q[a] - t->split[node];
    old = off[a];
    rd2 = rd - old * old + diff * diff;
    if (diff < 0) {
        search(s, node * 2 + 1, lo, mid, rd, off);
        if (s->found < s->K || rd2 <= s->bd[s->K - 1]) {
            off[a] = diff;
            search(s, node * 2 + 2, mid, hi, rd2, off);
            off[a] = old;
        }
    } else {
        search(s, node * 2 + 2, mid, hi, rd, off);
        if (s->found < s->K || rd2 <= s->bd[s->K - 1]) {
            off[a] = diff;
            search(s, node * 2 + 1, lo, mid, rd2, off);
            off[a] = old;
        }
    }
}

int ts__pix_kdtree_knn(const pix_kdtree *t, const float *q, int K,
                       int (*keep)(void *arg, int32_t i), void *arg, int32_t *out, float *d2)
{
    knn_state s = {t, q, K, 0, out, d2, keep, arg};
    float off[96] = {0};
    if (K < 1 || !t->n || t->dim > 96)
        return 0;
    search(&s, 0, 0, t->n, 0, off);
    return s.found;
}

typedef struct sim_job {
    ts_pixel_exemplars *ex;
    int l, K; /* K - 1 others per cell */
    const float *pts;
    const int32_t *pt_e, *pt_cell;
    const pix_kdtree *tree;
    size_t off; /* the batch's first point */
    int fail;
} sim_job;

typedef struct keep_arg {
    const sim_job *j;
    int32_t e, x, y, reach;
} keep_arg;

/* Not the cell itself nor its own exemplar's cells within `reach`. */
static int keep_far(void *arg, int32_t i)
{
    const keep_arg *k = arg;
    const pix_stack *s;
    int32_t c, dx, dy;
    if (k->j->pt_e[i] != k->e)
        return 1;
    s = &k->j->ex->stacks[k->e];
    c = k->j->pt_cell[i];
    dx = c % s->width - k->x;
    dy = c / s->width - k->y;
    return dx >= k->reach || dx <= -k->reach || dy >= k->reach || dy <= -k->reach;
}

static void sim_rows(void *arg, size_t begin, size_t end)
{
    sim_job *j = arg;
    int K = j->K, dim = j->ex->dim[j->l];
    int32_t *out = malloc((size_t)K * sizeof *out);
    float *d2 = malloc((size_t)K * sizeof *d2);
    size_t p;
    if (!out || !d2) {
        free(out);
        free(d2);
        j->fail = 1;
        return;
    }
    for (p = j->off + begin; p < j->off + end; p++) {
        const pix_stack *s = &j->ex->stacks[j->pt_e[p]];
        keep_arg ka = {j, j->pt_e[p], j->pt_cell[p] % s->width, j->pt_cell[p] / s->width,
                       1 << (j->ex->levels - j->l)};
        int found =
                ts__pix_kdtree_knn(j->tree, j->pts + p * (size_t)dim, K, keep_far, &ka, out, d2),
            i;
        int32_t *dst = s->sim[j->l] + (size_t)j->pt_cell[p] * (size_t)K;
        for (i = 0; i < K; i++) /* fewer found (a tiny exemplar): the others -1 */
            dst[i] = i < found ? out[i] : -1;
    }
    free(out);
    free(d2);
}

static double sim_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

#define SIM_BATCHES 32        /* a level's points in this many steps: progress, cancel */

/* Level l's sets in SIM_BATCHES steps (the same sets as in one: each point's
 * search is its own), with progress and cancel between steps.  After a
 * level's first step the rest of the analysis is projected from its rate
 * (a finer level's as the square root of the values it compares): past
 * notice_seconds, once, a notice says how long and what takes less.
 * 0, -1 (a worker's memory; j->fail) or -3 (cancelled). */
static int sim_level_batches(ts_ctx *ctx, sim_job *j, size_t n, int l, int levels, int coherence,
                             double notice_seconds, int *noticed)
{
    size_t b, lo, hi;
    double t0 = sim_now();
    for (b = 0; b < SIM_BATCHES; b++) {
        lo = n * b / SIM_BATCHES;
        hi = n * (b + 1) / SIM_BATCHES;
        j->off = lo;
        if (hi > lo)
            ts__parallel_for(ctx, hi - lo, sim_rows, j);
        if (j->fail)
            return -1;
        if (ts__progress(ctx, 0.05 + 0.9 * (l + (b + 1.0) / SIM_BATCHES) / (levels + 1.0),
                         "similarity sets") != TS_OK)
            return -3;
        if (b == 0 && !*noticed && hi > lo) {
            double level = (sim_now() - t0) * SIM_BATCHES;
            double rest = level * (SIM_BATCHES - 1.0) / SIM_BATCHES;
            int k, minutes;
            for (k = l + 1; k <= levels; k++) /* measured: between none and linear */
                rest += level * sqrt((double)j->ex->dim[k] / j->ex->dim[l]);
            minutes = (int)(rest / 60.0 + 0.5);
            if (rest > notice_seconds) {
                *noticed = 1;
                ts__notice(ctx, "pixel",
                           "the exemplars' similarity sets (coherence %d, up to %d values a "
                           "neighbourhood, %zu cells a level) take about %d minute%s more: "
                           "--pca-energy 0.95, a smaller --window, smaller exemplars or "
                           "--coherence 1 take less",
                           coherence, j->ex->dim[levels], n, minutes ? minutes : 1,
                           minutes > 1 ? "s" : "");
            }
        }
    }
    return 0;
}

int ts__pix_similarity_build(ts_ctx *ctx, ts_pixel_exemplars *ex, int coherence,
                             double notice_seconds)
{
    int l, e, K = coherence - 1, rc = -1, noticed = 0;
    int64_t base = 0;
    ex->coherence = coherence;
    if (K < 1)
        return 0;
    for (e = 0; e < ex->n_given; e++) {
        ex->cell_base[e] = base;
        base += (int64_t)ex->stacks[e].width * ex->stacks[e].height;
    }
    if (base > INT32_MAX)
        return -2;
    for (l = 0; l <= ex->levels; l++) {
        int dim = ex->dim[l];
        size_t n = 0, p;
        float *pts;
        int32_t *pt_e, *pt_cell;
        sim_job j;
        for (e = 0; e < ex->n_given; e++)
            n += ex->stacks[e].n_usable[l];
        pts = ts__malloc_array(n ? n : 1, (size_t)dim * sizeof *pts);
        pt_e = ts__malloc_array(n ? n : 1, sizeof *pt_e);
        pt_cell = ts__malloc_array(n ? n : 1, sizeof *pt_cell);
        if (!pts || !pt_e || !pt_cell) {
            free(pts);
            free(pt_e);
            free(pt_cell);
            return -1;
        }
        for (e = 0, p = 0; e < ex->n_given; e++) {
            pix_stack *s = &ex->stacks[e];
            size_t c;
            if (!s->sim && !(s->sim = calloc((size_t)ex->levels + 1, sizeof *s->sim)))
                goto fail;
            if (!(s->sim[l] = ts__malloc_array((size_t)s->width * (size_t)s->height,
                                               (size_t)K * sizeof **s->sim)))
                goto fail;
            for (c = 0; c < s->n_usable[l]; c++, p++) {
                int32_t cell = s->usable_list[l][c];
                memcpy(pts + p * (size_t)dim, s->app[l] + (size_t)cell * dim,
                       (size_t)dim * sizeof *pts);
                pt_e[p] = e;
                pt_cell[p] = cell;
            }
        }
        j.ex = ex;
        j.l = l;
        j.K = K;
        j.pts = pts;
        j.pt_e = pt_e;
        j.pt_cell = pt_cell;
        j.fail = 0;
        j.tree = ts__pix_kdtree_build(pts, n, dim);
        if (!j.tree)
            goto fail;
        rc = sim_level_batches(ctx, &j, n, l, ex->levels, coherence, notice_seconds, &noticed);
        ts__pix_kdtree_free((pix_kdtree *)j.tree);
        if (rc != 0 || j.fail)
            goto fail;
        /* the point ids as cells of all the exemplars in a row (ts__pix_similar) */
        for (e = 0; e < ex->n_given; e++) {
            pix_stack *s = &ex->stacks[e];
            size_t c;
            int i;
            for (c = 0; c < s->n_usable[l]; c++) {
                int32_t *d = s->sim[l] + (size_t)s->usable_list[l][c] * (size_t)K;
                for (i = 0; i < K; i++)
                    if (d[i] >= 0)
                        d[i] = (int32_t)(ex->cell_base[pt_e[d[i]]] + pt_cell[d[i]]);
            }
        }
        free(pts);
        free(pt_e);
        free(pt_cell);
        continue;
    fail:
        free(pts);
        free(pt_e);
        free(pt_cell);
        return rc < 0 ? rc : -1;
    }
    return 0;
}

void ts__pix_similar(const ts_pixel_exemplars *ex, int32_t id, int *e, int32_t *cell)
{
    int i = 0;
    while (i + 1 < ex->n_given && ex->cell_base[i + 1] <= id)
        i++;
    *e = i;
    *cell = (int32_t)(id - ex->cell_base[i]);
}
