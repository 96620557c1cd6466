/*
 * relief_start.c - where the coarsest level starts, without a guide (ours,
 * named as such: a TerraSynth addition to Lefebvre and Hoppe's
 * multiresolution synthesis).
 *
 * Started from a coordinate per cell chosen at random, the corrections of
 * the coarsest level compare each cell's neighbourhood with heights drawn
 * at random from the whole exemplar: the nearest real neighbourhood to such
 * noise is one of middle height, so the output keeps the exemplar's
 * foothills and loses its plains and its peaks (Mackay 30 m: heights
 * 1969..2464 m for an exemplar of 1745..3312 m, 384 x 384).  The relief
 * start gives the coarsest level a smooth random relief instead: a field of
 * the absolute position and the seed, whose every value is mapped to the
 * exemplar's level-0 height of the same rank, so the output starts with the
 * exemplar's plains and mountains in their proportions, laid out at random.
 *
 * The field: Gaussian values on a square lattice of spacing S cells,
 * stratified in blocks of 4 x 4 nodes (each block holds the 16 strata of the
 * normal distribution once, in an order from a hash of the block and the
 * seed: any 4S x 4S of the grid holds the whole range, from plain to peak),
 * interpolated by a cubic B-spline (smooth, no lattice creases) and divided
 * by the interpolation weights' norm.  A value's rank is read off the
 * field's own distribution, sampled once (it does not depend on S or the
 * seed).  S: the exemplars' relief at the coarsest level's spacing D, matched:
 * the mean |h(p) - h(p + D)| of the level-0 stacks over usable cells equals
 * the field's (mapped to the same heights) at one S, found by bisection on a
 * fixed sample.  Every value is a function of the position, the seed and the
 * exemplars: a window equals the same window of a whole run.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pixel.h"

#define RELIEF_B 4                       /* the strata blocks' side, in nodes */
#define RELIEF_STRATA (RELIEF_B * RELIEF_B)
#define RELIEF_SAMPLES 16384             /* the field's distribution, sampled */
#define RELIEF_PAIRS 4096                /* the calibration's sample of pairs */

/* The standard normal distribution function. */
static double phi_cdf(double z)
{
    return 0.5 * erfc(-z / sqrt(2.0));
}

/* Its inverse, by bisection (64 halvings of [-10, 10]: exact to the last
 * bit that matters; called 16 times per preparation). */
static double phi_inv(double p)
{
    double lo = -10, hi = 10;
    int i;
    for (i = 0; i < 64; i++) {
        double mid = 0.5 * (lo + hi);
        if (phi_cdf(mid) < p)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

static int64_t floor_div(int64_t a, int64_t b)
{
    int64_t q = a / b;
    return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

/* Node (i, j)'s value: its stratum in its block's order (a Fisher-Yates
 * shuffle driven by the block's hash), the stratum's middle quantile. */
static double node_value(const double *strata, int64_t i, int64_t j, uint64_t seed)
{
    int64_t bi = floor_div(i, RELIEF_B), bj = floor_div(j, RELIEF_B);
    int perm[RELIEF_STRATA], k, slot = (int)((j - bj * RELIEF_B) * RELIEF_B + (i - bi * RELIEF_B));
    uint64_t h = 0;
    for (k = 0; k < RELIEF_STRATA; k++)
        perm[k] = k;
    for (k = RELIEF_STRATA - 1; k > 0; k--) {
        int r, t;
        if (k == RELIEF_STRATA - 1 || (k & 7) == 7) /* fresh bits every 8 draws */
            h = ts__pix_hash(bi, bj, k, 9, seed);
        r = (int)((h & 0xff) % (uint64_t)(k + 1));
        h >>= 8;
        t = perm[k];
        perm[k] = perm[r];
        perm[r] = t;
    }
    return strata[perm[slot]];
}

void ts__bspline_weights(double t, double w[4])
{
    double s = 1 - t;
    w[0] = s * s * s / 6;
    w[1] = (3 * t * t * t - 6 * t * t + 4) / 6;
    w[2] = (-3 * t * t * t + 3 * t * t + 3 * t + 1) / 6;
    w[3] = t * t * t / 6;
}

/* The calibration's nodes (seed 0, lattice cells [-1, 72) in x and y), or NULL. */
#define CACHE_SIDE 73
typedef struct node_cache {
    double v[CACHE_SIDE * CACHE_SIDE];
} node_cache;

/* The field at (x, y) in lattice units (from the cache where given: seed 0). */
static double field_cached(const double *strata, const node_cache *cache, double x, double y,
                           uint64_t seed)
{
    double fx = floor(x), fy = floor(y), wx[4], wy[4], z = 0, n2 = 0;
    int64_t ix = (int64_t)fx, iy = (int64_t)fy;
    int a, b;
    ts__bspline_weights(x - fx, wx);
    ts__bspline_weights(y - fy, wy);
    for (b = 0; b < 4; b++)
        for (a = 0; a < 4; a++) {
            double w = wx[a] * wy[b];
            int64_t i = ix - 1 + a, j = iy - 1 + b;
            z += w * (cache && i >= -1 && j >= -1 && i < CACHE_SIDE - 1 && j < CACHE_SIDE - 1
                          ? cache->v[(size_t)(j + 1) * CACHE_SIDE + (size_t)(i + 1)]
                          : node_value(strata, i, j, seed));
            n2 += w * w;
        }
    return z / sqrt(n2);
}

static double field(const double *strata, double x, double y, uint64_t seed)
{
    return field_cached(strata, NULL, x, y, seed);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The rank in [0, 1] of field value z among the sampled ones (linear
 * between samples). */
static double rank_of(const ts_pixel_relief *r, double z)
{
    size_t lo = 0, hi = RELIEF_SAMPLES;
    double a, b;
    while (lo < hi) { /* the first sample not below z */
        size_t mid = lo + (hi - lo) / 2;
        if (r->sorted[mid] < z)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo == 0)
        return 0;
    if (lo == RELIEF_SAMPLES)
        return 1;
    a = r->sorted[lo - 1];
    b = r->sorted[lo];
    return ((double)lo - 1 + (b > a ? (z - a) / (b - a) : 0.5) + 0.5) / RELIEF_SAMPLES;
}

double ts__pix_relief_rank(const ts_pixel_relief *r, double S, double x, double y, uint64_t seed)
{
    return rank_of(r, field(r->strata, x / S, y / S, seed));
}

/* Exemplar s's level-0 height of rank q (its usable cells). */
static double height_of_rank(const pix_stack *s, double q)
{
    size_t n = s->n_usable[0], i = (size_t)(q * (double)n);
    if (i >= n)
        i = n - 1;
    return s->level[0][s->by_height[i]];
}

int ts__pix_relief_build(ts_pixel_exemplars *ex)
{
    ts_pixel_relief *r = &ex->relief;
    int k, e, L = ex->levels, D = 1 << L;
    size_t i;
    double target = 0, lo, hi;
    node_cache *nc = malloc(sizeof *nc);
    r->sorted = malloc(RELIEF_SAMPLES * sizeof *r->sorted);
    if (!r->sorted || !nc) {
        free(nc);
        return -1;
    }
    for (k = 0; k < RELIEF_STRATA; k++)
        r->strata[k] = phi_inv((k + 0.5) / RELIEF_STRATA);
    for (i = 0; i < CACHE_SIDE * CACHE_SIDE; i++)
        nc->v[i] = node_value(r->strata, (int64_t)(i % CACHE_SIDE) - 1,
                              (int64_t)(i / CACHE_SIDE) - 1, 0);
    /* the field's distribution: a fixed sample over 64 x 64 lattice cells */
    for (i = 0; i < RELIEF_SAMPLES; i++) {
        uint64_t h = ts__pix_hash((int64_t)i, 0, 0, 10, 0);
        double x = (double)(h & 0xffffff) / 16777216.0 * 64;
        double y = (double)((h >> 24) & 0xffffff) / 16777216.0 * 64;
        r->sorted[i] = field_cached(r->strata, nc, x, y, 0);
    }
    qsort(r->sorted, RELIEF_SAMPLES, sizeof *r->sorted, cmp_double);
    /* the exemplars' mean height difference at the coarsest spacing D, over pairs of
     * usable cells (each exemplar weighs alike: the coordinates pick them alike) */
    for (e = 0; e < ex->n_given; e++) {
        const pix_stack *s = &ex->stacks[e];
        const float *h0 = s->level[0];
        const unsigned char *u = s->usable[0];
        double sum = 0;
        size_t n = 0;
        int x, y, step = 1 + (int)(sqrt((double)s->width * s->height) / 256);
        for (y = 0; y < s->height; y += step)
            for (x = 0; x < s->width; x += step) {
                size_t c = (size_t)y * (size_t)s->width + (size_t)x;
                if (!u[c])
                    continue;
                if (x + D < s->width && u[c + (size_t)D]) {
                    sum += fabs((double)h0[c + (size_t)D] - h0[c]);
                    n++;
                }
                if (y + D < s->height && u[c + (size_t)D * (size_t)s->width]) {
                    sum += fabs((double)h0[c + (size_t)D * (size_t)s->width] - h0[c]);
                    n++;
                }
            }
        target += n ? sum / (double)n : 0;
    }
    /* the field's, mapped to the same heights, for lattice spacings S: the
     * pairs fixed in lattice units, so it is a smooth function of D / S,
     * falling as S grows */
    lo = D / 4.0;
    hi = D * 256.0;
    for (k = 0; k < 24; k++) {
        double S = sqrt(lo * hi), got = 0;
        for (e = 0; e < ex->n_given; e++) {
            double sum = 0;
            for (i = 0; i < RELIEF_PAIRS; i++) {
                uint64_t h = ts__pix_hash((int64_t)i, 0, 0, 11, 0);
                double x = (double)(h & 0xffffff) / 16777216.0 * 64;
                double y = (double)((h >> 24) & 0xffffff) / 16777216.0 * 64;
                double x2 = x + (i & 1 ? D / S : 0), y2 = y + (i & 1 ? 0 : D / S);
                double a = rank_of(r, field_cached(r->strata, nc, x, y, 0));
                double b = rank_of(r, field_cached(r->strata, nc, x2, y2, 0));
                sum += fabs(height_of_rank(&ex->stacks[e], a) - height_of_rank(&ex->stacks[e], b));
            }
            got += sum / RELIEF_PAIRS;
        }
        if (got > target)
            lo = S; /* too rough: a wider lattice */
        else
            hi = S;
    }
    r->scale = sqrt(lo * hi);
    free(nc);
    return 0;
}

void ts__pix_relief_free(ts_pixel_relief *r)
{
    free(r->sorted);
    memset(r, 0, sizeof *r);
}
