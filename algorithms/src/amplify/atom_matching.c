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
 * stay in cache), four sums at a time; tests/c/test_amplify.c checks the
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

double ts__amp_score(const double w[4], double dot_h, double dot_u, double da, double ds,
                     double sigma_a, double sigma_s)
{
    double ga = sigma_a > 0 ? exp(-(da * da) / (sigma_a * sigma_a)) : (da == 0 ? 1.0 : 0.0);
    double gs = sigma_s > 0 ? exp(-(ds * ds) / (sigma_s * sigma_s)) : (ds == 0 ? 1.0 : 0.0);
    return w[0] * 0.5 * (1.0 + dot_h) + w[1] * ga + w[2] * gs + w[3] * 0.5 * (1.0 + dot_u);
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
 * v[0..n): the distances to the left and to the right of q are two ascending
 * lists; merged from q outwards, the (n/2+1)-th taken is it. */
static double median_distance(const double *v, size_t n, double q)
{
    size_t lo = 0, hi = n, k, taken;
    ptrdiff_t i;
    size_t j;
    double last = 0;
    while (lo < hi) { /* the first v[j] > q */
        size_t mid = lo + (hi - lo) / 2;
        if (v[mid] <= q)
            lo = mid + 1;
        else
            hi = mid;
    }
    i = (ptrdiff_t)lo - 1;
    j = lo;
    k = n / 2;
    for (taken = 0; taken <= k; taken++) {
        if (i >= 0 && (j >= n || q - v[i] <= v[j] - q))
            last = q - v[i--];
        else
            last = v[j++] - q;
    }
    return last;
}

typedef struct match_job {
    const ts_dictionary *dict;
    const float *ph, *pu;
    const double *pa, *ps, *w;
    size_t np;
    int *best;
    float *score, *coef;
    int fail;
} match_job;

static void match_range(void *arg, size_t begin, size_t end)
{
    match_job *m = arg;
    const ts_dictionary *D = m->dict;
    size_t na = D->n, b0, a0, i, k;
    int d = D->d;
    float *dh = malloc(PATCH_TILE * na * sizeof *dh);
    float *du = malloc(PATCH_TILE * na * sizeof *du);
    const double ln2 = log(2.0);
    if (!dh || !du) {
        free(dh);
        free(du);
        m->fail = 1; /* the caller reports it: never a silently flat patch */
        return;
    }
    for (b0 = begin; b0 < end; b0 += PATCH_TILE) {
        size_t b1 = b0 + PATCH_TILE < end ? b0 + PATCH_TILE : end;
        /* the dot products, tile by tile */
        for (a0 = 0; a0 < na; a0 += ATOM_TILE) {
            size_t a1 = a0 + ATOM_TILE < na ? a0 + ATOM_TILE : na;
            for (i = b0; i < b1; i++) {
                const float *ph = m->ph + i * (size_t)d, *pu = m->pu + i * (size_t)d;
                float *rh = dh + (i - b0) * na, *ru = du + (i - b0) * na;
                for (k = a0; k < a1; k++) {
                    rh[k] = dot(ph, D->dh + k * (size_t)d, d);
                    ru[k] = m->w[3] > 0 ? dot(pu, D->du + k * (size_t)d, d) : 0.0f;
                }
            }
        }
        for (i = b0; i < b1; i++) {
            const float *rh = dh + (i - b0) * na, *ru = du + (i - b0) * na;
            double sa, ss, best = -1.0;
            int bk = -1;
            if (isnan(m->pa[i])) { /* an all-nodata patch */
                m->best[i] = -1;
                m->score[i] = 0;
                m->coef[i] = 0;
                continue;
            }
            sa = median_distance(D->a_sorted, na, m->pa[i]) / sqrt(ln2);
            ss = median_distance(D->s_sorted, na, m->ps[i]) / sqrt(ln2);
            for (k = 0; k < na; k++) {
                double g;
                /* the Gaussians are at most 1: an atom that cannot beat the best even
                 * with both at 1 is passed without computing them (exact: a tie never
                 * replaces the best) */
                double bound = m->w[0] * 0.5 * (1.0 + rh[k]) + m->w[3] * 0.5 * (1.0 + ru[k]) +
                               m->w[1] + m->w[2];
                if (bound <= best)
                    continue;
                g = ts__amp_score(m->w, rh[k], ru[k], m->pa[i] - D->a[k], m->ps[i] - D->s[k], sa,
                                  ss);
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
    free(du);
}

int ts__match_atoms(const ts_ctx *ctx, const ts_dictionary *dict, const float *ph, const float *pu,
                    const double *pa, const double *ps, size_t np, const double w[4], int *best,
                    float *score, float *coef)
{
    match_job m = {dict, ph, pu, pa, ps, w, np, best, score, coef, 0};
    ts__parallel_for(ctx, np, match_range, &m);
    return m.fail ? -1 : 0;
}
