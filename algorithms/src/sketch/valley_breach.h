/*
 * valley_breach.h - what the drawn valleys' floors (valley_breach.c) and their
 * course and heights (valley_floor.c) share: the carve cells of the valley
 * networks and their channels, and a binary heap of (level, order) keys.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_VALLEY_BREACH_H
#define TS_VALLEY_BREACH_H

#include <stdint.h>

#include "layout.h"

typedef struct breach {
    int W, H, P;
    int32_t *id;        /* per grid cell: its carve cell, -1 none */
    size_t *cell;       /* per carve cell: its grid cell */
    unsigned char *adj; /* per carve cell: 8 direction bits (valley cells only) */
    int32_t *comp;      /* per carve cell: its network (-1: a channel cell) */
    int32_t *down;      /* per carve cell: the next one downstream, -1 none */
    size_t n, cap;
    int32_t n_comp;
    const unsigned char *flags; /* the user's cells (NULL: none) */
    int *wdist; /* per grid cell: 8-neighbour steps to the nearest water cell (NULL: no water) */
} breach;

static const int BX[8] = {1, 1, 0, -1, -1, -1, 0, 1};
static const int BY[8] = {0, 1, 1, 1, 0, -1, -1, -1};

static inline int popcount8(unsigned v)
{
    int n = 0;
    for (; v; v &= v - 1)
        n++;
    return n;
}

/* A binary heap of (level, arrival) keys for the flood. */
typedef struct fl_item {
    float level;
    uint32_t order;
    int32_t cell;
} fl_item;

static inline int fl_less(const fl_item *a, const fl_item *b)
{
    return a->level < b->level || (a->level == b->level && a->order < b->order);
}

static inline void fl_push(fl_item *h, size_t *n, fl_item it)
{
    size_t i = (*n)++;
    while (i > 0 && fl_less(&it, &h[(i - 1) / 2])) {
        h[i] = h[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    h[i] = it;
}

static inline fl_item fl_pop(fl_item *h, size_t *n)
{
    fl_item top = h[0], last = h[--(*n)];
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= *n)
            break;
        if (c + 1 < *n && fl_less(&h[c + 1], &h[c]))
            c++;
        if (!fl_less(&h[c], &last))
            break;
        h[i] = h[c];
        i = c;
    }
    if (*n)
        h[i] = last;
    return top;
}

/* A grid cell's carve cell (added when it has none); -1 out of memory. */
int32_t ts__breach_add(breach *b, size_t c);

/* The floor along each network moved onto the valley's own lowest line
 * within w cells of the drawn one (valley_floor.c); 0, -1 out of memory. */
int ts__valley_thalweg(ts_ctx *ctx, breach *b, const ts_raster *out, double w, double kappa);

/* The floor's heights made never to rise downstream at the least cost
 * (valley_floor.c); 0, -1 out of memory. */
int ts__valley_fit_floor(const breach *b, const unsigned char *flags, const size_t *order, size_t n,
                         float *z);

#endif
