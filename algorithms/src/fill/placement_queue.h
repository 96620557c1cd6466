/*
 * placement_queue.h - the grow fill's order as a priority queue
 * (placement_queue.c), shared by the fill and its test.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_PLACEMENT_QUEUE_H
#define TS_PLACEMENT_QUEUE_H

#include "internal.h"

/* A patch position of the fill. */
typedef struct ts__placement {
    int x, y;    /* window top-left in the output */
    int overlap; /* filled cells in the window */
    int needed;  /* still has empty cells to fill */
    /* what the fill placed here: exemplar (-1: nothing yet) and its
     * window's offset from the position (exemplar x - x, y - y) */
    int src_e, src_dx, src_dy;
} ts__placement;

/* The needed positions, best first: most overlap, then nearest the centre
 * (L1 distance of the window's corner to (cx, cy)), then lowest index. */
typedef struct ts__pos_queue {
    ts__placement *pos;
    int *heap;  /* position indices, best first at 0 */
    int *slot;  /* slot of each position in heap, -1 when not in it */
    long *dist; /* each position's distance to the centre */
    int n;      /* positions in the queue */
} ts__pos_queue;

/* The queue of the needed positions among pos[0 .. n_pos); -1 when out of
 * memory. */
int ts__queue_init(ts__pos_queue *q, ts__placement *pos, int n_pos, int cx, int cy);
void ts__queue_free(ts__pos_queue *q);
/* After pos[j] changed (overlap or needed): in the queue when needed, out
 * of it when not, in its place (nothing for a queue never initialised). */
void ts__queue_fix(ts__pos_queue *q, int j);
/* The best position in the queue (-1 if none); with apart >= 0, the best
 * of those not within gap cells of position apart in both x and y
 * (positions on the grid xs[0..nx) x ys[0..ny), index ix + nx iy). */
int ts__queue_best(ts__pos_queue *q, const int *xs, int nx, const int *ys, int ny, int apart,
                   int gap);
/* The indices [*lo, *hi) of the sorted coords[0..n) within dist of c
 * (|coord - c| < dist). */
void ts__axis_near(const int *coords, int n, int c, int dist, int *lo, int *hi);

#endif
