/*
 * amplify.h - private to the amplification stage (Argudo et al. 2017):
 * the dictionary's layout and the matching kernel its tests compare with
 * a brute-force reference.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_AMPLIFY_H
#define TS_AMPLIFY_H

#include "internal.h"

struct ts_dictionary {
    int factor, patch;     /* F, p */
    int d, hd;             /* p*p, (p*F)^2 */
    size_t n;              /* atoms */
    float *dh;             /* n x d: low-resolution normalised elevation D_h (unit vectors) */
    float *du;             /* n x d: normalised log drainage area D_u (unit vectors or 0) */
    float *hh;             /* n x hd: high-resolution D~_h = (H - a) / (s p), with a, s of D */
    double *a;             /* mean altitude D_a */
    double *s;             /* mean deviation D_s (RMS of the centred low-resolution atom) */
    int *exemplar, *x, *y; /* where each atom came from (low-resolution cells) */
    double *a_sorted, *s_sorted; /* a and s in ascending order (the matching's medians) */
};

/* After the atoms are filled: the sorted copies of a and s (0, or -1 when
 * out of memory). */
int ts__dict_sort(ts_dictionary *d);

/* Centre v (d values) and divide by its norm: out = (v - mean) / |v - mean|.
 * *mean and *rms (the norm / sqrt(d)) are returned; a flat v gives zeros and
 * returns 0, else 1. */
int ts__amp_normalise(const float *v, int d, float *out, double *mean, double *rms);

/* The matching weights (h, a, s, u) normalised to sum 1. */
void ts__amp_weights(const ts_amplify_params *p, double w[4]);

/* For each of the np patches (descriptors ph, pu: np x d; pa, ps), the atom
 * with the highest g (ties: the lowest index), its g and P_h . D_h.  Fast
 * kernel: blocked dot products over tiles of patches and atoms.  0, or -1
 * when out of memory. */
int ts__match_atoms(const ts_ctx *ctx, const ts_dictionary *dict, const float *ph, const float *pu,
                    const double *pa, const double *ps, size_t np, const double w[4], int *best,
                    float *score, float *coef);

/* g of one patch against one atom, given the two dot products and the two
 * Gaussian widths (the matching function of section 5). */
double ts__amp_score(const double w[4], double dot_h, double dot_u, double da, double ds,
                     double sigma_a, double sigma_s);

#endif
