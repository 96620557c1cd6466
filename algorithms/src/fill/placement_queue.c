/*
 * placement_queue.c - the order of the grow fill (Zhou et al. 2007 section
 * 4.2: patches placed where most is already filled), as a priority queue.
 *
 * The needed patch positions wait in a binary heap, best first: the most
 * filled cells in the window, ties to the one nearest the centre, then to
 * the lowest index (the order a scan of every position gives).  Each
 * position knows its slot, so a position whose window changed moves in a
 * logarithm of the positions.  The fill's time per cell then stays flat as
 * the output grows, where a scan of every position per placement grew with
 * the square of the positions.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>

#include "placement_queue.h"

static int queue_better(const ts__pos_queue *q, int a, int b)
{
    if (q->pos[a].overlap != q->pos[b].overlap)
        return q->pos[a].overlap > q->pos[b].overlap;
    if (q->dist[a] != q->dist[b])
        return q->dist[a] < q->dist[b];
    return a < b;
}

static void queue_set(ts__pos_queue *q, int i, int j)
{
    q->heap[i] = j;
    q->slot[j] = i;
}

static void queue_up(ts__pos_queue *q, int i)
{
    int j = q->heap[i];
    while (i > 0 && queue_better(q, j, q->heap[(i - 1) / 2])) {
        queue_set(q, i, q->heap[(i - 1) / 2]);
        i = (i - 1) / 2;
    }
    queue_set(q, i, j);
}

static void queue_down(ts__pos_queue *q, int i)
{
    int j = q->heap[i];
    for (;;) {
        int c = 2 * i + 1;
        if (c >= q->n)
            break;
        if (c + 1 < q->n && queue_better(q, q->heap[c + 1], q->heap[c]))
            c++;
        if (!queue_better(q, q->heap[c], j))
            break;
        queue_set(q, i, q->heap[c]);
        i = c;
    }
    queue_set(q, i, j);
}

void ts__queue_fix(ts__pos_queue *q, int j)
{
    int i;
    if (!q->slot)
        return; /* no queue (raster order) */
    i = q->slot[j];
    if (i < 0 && q->pos[j].needed) {
        q->heap[q->n] = j;
        q->slot[j] = q->n++;
        queue_up(q, q->n - 1);
    } else if (i >= 0 && !q->pos[j].needed) {
        int last = q->heap[--q->n];
        q->slot[j] = -1;
        if (last != j) {
            queue_set(q, i, last);
            queue_up(q, i);
            queue_down(q, q->slot[last]);
        }
    } else if (i >= 0) {
        queue_up(q, i);
        queue_down(q, q->slot[j]);
    }
}

void ts__axis_near(const int *coords, int n, int c, int dist, int *lo, int *hi)
{
    int a = 0, b;
    while (a < n && coords[a] <= c - dist)
        a++;
    b = a;
    while (b < n && coords[b] < c + dist)
        b++;
    *lo = a;
    *hi = b;
}


int ts__queue_init(ts__pos_queue *q, ts__placement *pos, int n_pos, int cx, int cy)
{
    int i;
    q->pos = pos;
    q->n = 0;
    q->heap = ts__malloc_array((size_t)n_pos, sizeof *q->heap);
    q->slot = ts__malloc_array((size_t)n_pos, sizeof *q->slot);
    q->dist = ts__malloc_array((size_t)n_pos, sizeof *q->dist);
    if (!q->heap || !q->slot || !q->dist) {
        ts__queue_free(q);
        return -1;
    }
    for (i = 0; i < n_pos; i++) {
        q->slot[i] = -1;
        q->dist[i] = labs((long)pos[i].x - cx) + labs((long)pos[i].y - cy);
        ts__queue_fix(q, i);
    }
    return 0;
}

void ts__queue_free(ts__pos_queue *q)
{
    free(q->heap);
    free(q->slot);
    free(q->dist);
    q->heap = q->slot = NULL;
    q->dist = NULL;
    q->n = 0;
}

int ts__queue_best(ts__pos_queue *q, const int *xs, int nx, const int *ys, int ny, int apart,
                   int gap)
{
    int x0, x1, y0, y1, ix, iy, pick, n_out = 0;
    int out[64];
    ts__placement *pos = q->pos;
    if (apart < 0)
        return q->n ? q->heap[0] : -1;
    ts__axis_near(xs, nx, pos[apart].x, gap, &x0, &x1);
    ts__axis_near(ys, ny, pos[apart].y, gap, &y0, &y1);
    if ((x1 - x0) * (y1 - y0) > 64) { /* (patches overlapping by more than half) a scan */
        int k;
        pick = -1;
        for (k = 0; k < q->n; k++) {
            int j = q->heap[k];
            if (abs(pos[j].x - pos[apart].x) < gap && abs(pos[j].y - pos[apart].y) < gap)
                continue;
            if (pick < 0 || queue_better(q, j, pick))
                pick = j;
        }
        return pick;
    }
    for (iy = y0; iy < y1; iy++)
        for (ix = x0; ix < x1; ix++) {
            int j = ix + nx * iy;
            if (q->slot[j] >= 0) {
                pos[j].needed = 0; /* out for the look */
                ts__queue_fix(q, j);
                out[n_out++] = j;
            }
        }
    pick = q->n ? q->heap[0] : -1;
    while (n_out > 0) {
        int j = out[--n_out];
        pos[j].needed = 1;
        ts__queue_fix(q, j);
    }
    return pick;
}
