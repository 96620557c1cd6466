/*
 * naive_flow.h - the flow and drainage area of a DEM by their definition
 * (algorithms/src/ppa/drainage_area.c), the slow way: the oracle of the
 * PPA's drainage test and of the stream network.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_TEST_NAIVE_FLOW_H
#define TS_TEST_NAIVE_FLOW_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"
#include "terrasynth.h"

/* Drainage area by the definition (drainage_area.c), the slow way: F by
 * relaxation (F = height on the boundary, else max(height, least F of the
 * neighbours), repeated until nothing changes), D likewise on flats, each
 * cell's flow to its neighbour of least (F, D), and the area of a cell
 * counted by walking every cell's path down to where it leaves the DEM.
 * to_out (NULL: not wanted): each cell's flow, the row-major index of the
 * neighbour it drains to, -1 off the DEM or on nodata. */
static void naive_flow(const ts_raster *dem, float *area, long *to_out)
{
    int w = dem->width, h = dem->height, x, y, d, changed;
    size_t n = (size_t)w * h, c, k;
    float *F = malloc(n * sizeof *F);
    unsigned *D = malloc(n * sizeof *D);
    long *to = malloc(n * sizeof *to);
    unsigned char *bnd = calloc(n, 1);
#define NV(x, y) ((x) < 0 || (y) < 0 || (x) >= w || (y) >= h || isnan(TS_PIX(dem, x, y)))
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            c = (size_t)y * w + x;
            F[c] = NAN;
            D[c] = UINT32_MAX;
            if (NV(x, y))
                continue;
            for (d = 0; d < 8; d++)
                if (NV(x + ppa_dir[d][0], y + ppa_dir[d][1]))
                    bnd[c] = 1;
            F[c] = bnd[c] ? TS_PIX(dem, x, y) : INFINITY;
        }
    do {
        changed = 0;
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                float lo = INFINITY, nf;
                c = (size_t)y * w + x;
                if (NV(x, y) || bnd[c])
                    continue;
                for (d = 0; d < 8; d++)
                    if (!NV(x + ppa_dir[d][0], y + ppa_dir[d][1]))
                        lo = fminf(lo, F[(size_t)(y + ppa_dir[d][1]) * w + x + ppa_dir[d][0]]);
                nf = fmaxf(TS_PIX(dem, x, y), lo);
                if (nf < F[c])
                    F[c] = nf, changed = 1;
            }
    } while (changed);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            c = (size_t)y * w + x;
            if (NV(x, y))
                continue;
            if (bnd[c])
                D[c] = 0;
            for (d = 0; d < 8; d++)
                if (!NV(x + ppa_dir[d][0], y + ppa_dir[d][1]) &&
                    F[(size_t)(y + ppa_dir[d][1]) * w + x + ppa_dir[d][0]] < F[c])
                    D[c] = 0;
        }
    do {
        changed = 0;
        for (c = 0; c < n; c++) {
            x = (int)(c % w);
            y = (int)(c / w);
            if (NV(x, y))
                continue;
            for (d = 0; d < 8; d++) {
                size_t nb = (size_t)(y + ppa_dir[d][1]) * w + x + ppa_dir[d][0];
                if (!NV(x + ppa_dir[d][0], y + ppa_dir[d][1]) && F[nb] == F[c] &&
                    D[nb] != UINT32_MAX && D[nb] + 1 < D[c])
                    D[c] = D[nb] + 1, changed = 1;
            }
        }
    } while (changed);
    for (c = 0; c < n; c++) {
        long best = -1;
        x = (int)(c % w);
        y = (int)(c / w);
        to[c] = -1;
        if (NV(x, y) || bnd[c])
            continue;
        for (d = 0; d < 8; d++) {
            long nb = (long)(y + ppa_dir[d][1]) * w + x + ppa_dir[d][0];
            if (NV(x + ppa_dir[d][0], y + ppa_dir[d][1]))
                continue;
            if (F[nb] < F[best < 0 ? (long)c : best] ||
                (F[nb] == F[best < 0 ? (long)c : best] && D[nb] < D[best < 0 ? (long)c : best]))
                best = nb;
        }
        to[c] = best;
    }
#undef NV
    for (c = 0; c < n; c++)
        area[c] = isnan(F[c]) ? NAN : 0.0f;
    for (c = 0; c < n; c++)
        if (!isnan(F[c]))
            for (k = c;; k = (size_t)to[k]) {
                area[k] += 1.0f;
                if (to[k] < 0)
                    break;
            }
    if (to_out)
        memcpy(to_out, to, n * sizeof *to);
    free(F);
    free(D);
    free(to);
    free(bnd);
}

#endif
