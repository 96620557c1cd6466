/*
 * fill_oracle.h - the drainage tests' slow, obviously-correct oracle: the
 * depression fill by relaxation (Planchon and Darboux 2001: the water surface
 * starts infinite inside and is lowered to max(z, lowest neighbour's) until
 * nothing changes), which says how deep every closed depression is.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_TEST_FILL_ORACLE_H
#define TS_TEST_FILL_ORACLE_H

#include <math.h>
#include <stdlib.h>

/* The filled surface by relaxation (edge cells and cells beside nodata
 * drain out); NaN stays NaN. */
static void oracle_fill(const float *z, int w, int h, double *wat)
{
    int x, y, d, changed;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            int edge = x == 0 || y == 0 || x == w - 1 || y == h - 1;
            for (d = 0; !edge && d < 9; d++)
                if (isnan(z[(size_t)(y + d / 3 - 1) * (size_t)w + (size_t)(x + d % 3 - 1)]))
                    edge = 1;
            wat[i] = isnan(z[i]) ? NAN : edge ? z[i] : INFINITY;
        }
    do {
        changed = 0;
        for (y = 1; y < h - 1; y++)
            for (x = 1; x < w - 1; x++) {
                size_t i = (size_t)y * (size_t)w + (size_t)x;
                double lo = INFINITY, nv;
                if (isnan(wat[i]))
                    continue;
                for (d = 0; d < 9; d++) {
                    double v = wat[(size_t)(y + d / 3 - 1) * (size_t)w + (size_t)(x + d % 3 - 1)];
                    if (d != 4 && !isnan(v) && v < lo)
                        lo = v;
                }
                nv = lo > z[i] ? lo : z[i];
                if (nv < wat[i]) {
                    wat[i] = nv;
                    changed = 1;
                }
            }
    } while (changed);
}

/* The largest amount the oracle's fill raises a cell, and how many it
 * raises by more than tol. */
static double deepest(const float *z, int w, int h, double tol, size_t *n_over)
{
    double *wat = malloc((size_t)w * (size_t)h * sizeof *wat), worst = 0.0;
    size_t i;
    oracle_fill(z, w, h, wat);
    *n_over = 0;
    for (i = 0; i < (size_t)w * (size_t)h; i++) {
        double d = wat[i] - z[i];
        if (isnan(d))
            continue;
        if (d > worst)
            worst = d;
        if (d > tol)
            (*n_over)++;
    }
    free(wat);
    return worst;
}

#endif
