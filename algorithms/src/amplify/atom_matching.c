/*
 * atom_matching.c - matching patches to atoms (Argudo et al. 2017, section
 * 5): g = sum_j w_j g_j with g_h = (1 + P_h . D_h) / 2 (orientation kept),
 * g_a and g_s Gaussians k(x) = exp(-x^2 / sigma^2) of the mean altitude and
 * mean deviation differences with sigma set so that k is 0.5 at the median
 * difference over the atoms, and g_u = (1 + P_u . D_u) / 2 on the drainage.
 * The best atom k = argmax_i g(P, D_i).
 *
 * The dot products of every patch with every atom are the cost: they are
 * computed over tiles (a block of patches against a block of atoms, so both
 * stay in cache), four sums at a time; tests/c/amplify/test_amplify.c checks the
 * choice against a plain loop over every atom.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "amplify.h"

#define PATCH_TILE 16
#define ATOM_TILE 128

double ts__amp_score(const double w[AMP_NW], double dot_h, double dot_u, double dot_l, double dot_c,
                     double dot_x, double da, double ds, double sigma_a, double sigma_s)
{
    double ga = sigma_a > 0 ? exp(-(da * da) / (sigma_a * sigma_a)) : (da == 0 ? 1.0 : 0.0);
    double gs = sigma_s > 0 ? exp(-(ds * ds) / (sigma_s * sigma_s)) : (ds == 0 ? 1.0 : 0.0);
    return w[AMP_WH] * 0.5 * (1.0 + dot_h) + w[AMP_WA] * ga + w[AMP_WS] * gs +
           w[AMP_WU] * 0.5 * (1.0 + dot_u) + w[AMP_WL] * 0.5 * (1.0 + dot_l) + w[AMP_WC] * dot_c +
           w[AMP_WX] * 0.5 * (1.0 + dot_x);
}

/* Four lanes of floats (GCC/Clang vector extension: SSE on x86-64, NEON on
 * arm64, plain code elsewhere); loads through memcpy, so no alignment is
 * assumed.  The lanes are summed in a fixed order: the same bytes on every
 * run. */
typedef float v4f __attribute__((vector_size(16)));

static float dot(const float *a, const float *b, int d)
{
    v4f s0 = {0, 0, 0, 0}, s1 = {0, 0, 0, 0};
    float tail = 0;
    int i = 0;
    for (; i + 8 <= d; i += 8) {
        v4f a0, a1, b0, b1;
        memcpy(&a0, a + i, 16);
        memcpy(&a1, a + i + 4, 16);
        memcpy(&b0, b + i, 16);
        memcpy(&b1, b + i + 4, 16);
        s0 += a0 * b0;
        s1 += a1 * b1;
    }
    for (; i + 4 <= d; i += 4) {
        v4f a0, b0;
        memcpy(&a0, a + i, 16);
        memcpy(&b0, b + i, 16);
        s0 += a0 * b0;
    }
    for (; i < d; i++)
        tail += a[i] * b[i];
    s0 += s1;
    return ((s0[0] + s0[1]) + (s0[2] + s0[3])) + tail;
}

/* The median (element n/2 in ascending order) of |q - v[j]| over the sorted
 * v[0..n): the distances to the left of q (q - v[i], i falling) and to its
 * right (v[j] - q, j rising) are two ascending lists, and the median is the
 * (n/2+1)-th smallest of both together: a binary search for how many of
 * them come from the left list, O(log n). */
static double median_distance(const double *v, size_t n, double q)
{
    size_t lo = 0, hi = n, m = n / 2 + 1, a_lo, a_hi, a, b;
    double l, r;
    while (lo < hi) { /* the first v[j] > q: lo to the left, n - lo to the right */
        size_t mid = lo + (hi - lo) / 2;
        if (v[mid] <= q)
            lo = mid + 1;
        else
            hi = mid;
    }
    /* the fewest a taken from the left with the left's next no smaller than the
     * right's last taken (b = m - a from the right) */
    a_lo = m > n - lo ? m - (n - lo) : 0;
    a_hi = m < lo ? m : lo;
    while (a_lo < a_hi) {
        a = a_lo + (a_hi - a_lo) / 2;
        b = m - a;
        if (a < lo && b > 0 && q - v[lo - 1 - a] < v[lo + b - 1] - q)
            a_lo = a + 1;
        else
            a_hi = a;
    }
    a = a_lo;
    b = m - a;
    l = a > 0 ? q - v[lo - a] : -1.0;
    r = b > 0 ? v[lo + b - 1] - q : -1.0;
    return l > r ? l : r;
}

typedef struct match_job {
    const ts_dictionary *dict;
    const amp_patches *pt;
    const double *w;
    int *best;
    float *score, *coef;
    int fail;
} match_job;

static void match_range(void *arg, size_t begin, size_t end)
{
    match_job *m = arg;
    const ts_dictionary *D = m->dict;
    const amp_patches *pt = m->pt;
    size_t na = D->n, b0, a0, i, k;
    int d = D->d, K = D->n_classes;
    int use_u = m->w[AMP_WU] > 0, use_l = m->w[AMP_WL] > 0 && pt->pl && D->dl;
    int use_c = m->w[AMP_WC] > 0 && pt->pc && D->dc;
    int use_x = m->w[AMP_WX] > 0 && pt->px;
    float *dh = malloc(PATCH_TILE * na * sizeof *dh);
    double *dx = malloc(PATCH_TILE * na * sizeof *dx); /* w_u g_u + w_l g_l + w_c g_c */
    const double ln2 = log(2.0);
    if (!dh || !dx) {
        free(dh);
        free(dx);
        m->fail = 1; /* the caller reports it: never a silently flat patch */
        return;
    }
    for (b0 = begin; b0 < end; b0 += PATCH_TILE) {
        size_t b1 = b0 + PATCH_TILE < end ? b0 + PATCH_TILE : end;
        /* the dot products, tile by tile */
        for (a0 = 0; a0 < na; a0 += ATOM_TILE) {
            size_t a1 = a0 + ATOM_TILE < na ? a0 + ATOM_TILE : na;
            for (i = b0; i < b1; i++) {
                const float *ph = pt->ph + i * (size_t)d, *pu = pt->pu + i * (size_t)d;
                const float *pl = use_l ? pt->pl + i * (size_t)d : NULL;
                const float *pc = use_c ? pt->pc + i * (size_t)K : NULL;
                const float *px = use_x ? pt->px + i * (size_t)d : NULL;
                float *rh = dh + (i - b0) * na;
                double *rx = dx + (i - b0) * na;
                for (k = a0; k < a1; k++) {
                    double du = use_u ? dot(pu, D->du + k * (size_t)d, d) : 0.0;
                    double dl = use_l ? dot(pl, D->dl + k * (size_t)d, d) : 0.0;
                    double dc = use_c ? dot(pc, D->dc + k * (size_t)K, K) : 0.0;
                    double dxc = use_x ? dot(px, D->dx + k * (size_t)d, d) : 0.0;
                    rh[k] = dot(ph, D->dh + k * (size_t)d, d);
                    rx[k] = m->w[AMP_WU] * 0.5 * (1.0 + du) + m->w[AMP_WL] * 0.5 * (1.0 + dl) +
                            m->w[AMP_WC] * dc + m->w[AMP_WX] * 0.5 * (1.0 + dxc);
                }
            }
        }
        for (i = b0; i < b1; i++) {
            const float *rh = dh + (i - b0) * na;
            double *rx = dx + (i - b0) * na;
            double sa, ss, best = -1.0;
            int bk = -1;
            if (isnan(pt->pa[i])) { /* an all-nodata patch */
                m->best[i] = -1;
                m->score[i] = 0;
                m->coef[i] = 0;
                continue;
            }
            sa = median_distance(D->a_sorted, na, pt->pa[i]) / sqrt(ln2);
            ss = median_distance(D->s_sorted, na, pt->ps[i]) / sqrt(ln2);
            for (k = 0; k < na; k++) {
                double g, ga, gs, da, ds;
                /* the Gaussians are at most 1: an atom that cannot beat the best even
                 * with both at 1 is passed without computing them (exact: a tie never
                 * replaces the best) */
                double base = m->w[AMP_WH] * 0.5 * (1.0 + rh[k]) + rx[k];
                if (base + m->w[AMP_WA] + m->w[AMP_WS] <= best)
                    continue;
                da = pt->pa[i] - D->a[k];
                ds = pt->ps[i] - D->s[k];
                ga = sa > 0 ? exp(-(da * da) / (sa * sa)) : (da == 0 ? 1.0 : 0.0);
                gs = ss > 0 ? exp(-(ds * ds) / (ss * ss)) : (ds == 0 ? 1.0 : 0.0);
                g = base + m->w[AMP_WA] * ga + m->w[AMP_WS] * gs;
                if (g > best) {
                    best = g;
                    bk = (int)k;
                }
            }
            m->best[i] = bk;
            m->score[i] = (float)best;
            m->coef[i] = bk >= 0 ? rh[bk] : 0.0f;
        }
    }
    free(dh);
    free(dx);
}

int ts__match_atoms(const ts_ctx *ctx, const ts_dictionary *dict, const amp_patches *pt,
                    const double w[AMP_NW], int *best, float *score, float *coef)
{
    match_job m = {dict, pt, w, best, score, coef, 0};
    ts__parallel_for(ctx, pt->n, match_range, &m);
    return m.fail ? -1 : 0;
}
