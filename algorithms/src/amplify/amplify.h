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
    int *exemplar, *x, *y; /* where each atom came from (its fine window's origin) */
    double *a_sorted, *s_sorted; /* a and s in ascending order (the matching's medians) */
    /* section 5.6: the normalised mean annual solar irradiance D_l (n x d unit
     * vectors, or 0 where the exemplar had no latitude); NULL when built without */
    float *dl;
    /* section 5.3: the normalised context D_x (n x d): the 3p x 3p neighbourhood of
     * the atom in the low-resolution exemplar, block-averaged by 3 to p x p */
    float *dx;
    /* section 5.4: classes 1..n_classes; dc (n x n_classes) the atom's class
     * vector (the share of its high-resolution cells in each class, scaled to
     * unit length; 0 for an unlabelled atom), hc (n x hd) its class codes
     * (0 = none); both NULL when n_classes is 0 */
    int n_classes;
    float *dc;
    unsigned char *hc;
    /* extra layers carried by the atoms (vegetation, ...): ll (n x n_layers x hd),
     * NaN where the exemplar's layer had none */
    int n_layers;
    char layer_names[TS_MAX_LAYERS][TS_LAYER_NAME];
    float *ll;
};

/* The descriptors of the input's patches, laid out as the atoms' are. */
typedef struct amp_patches {
    size_t n;
    const float *ph, *pu, *pl, *pc; /* n x d, n x d, n x d (or NULL), n x n_classes (or NULL) */
    const float *px;                /* n x d context (or NULL) */
    const double *pa, *ps;
} amp_patches;

/* The weights (h, a, s, u, l, c, x) in this order. */
enum { AMP_WH, AMP_WA, AMP_WS, AMP_WU, AMP_WL, AMP_WC, AMP_WX, AMP_NW };

/* After the atoms are filled: the sorted copies of a and s (0, or -1 when
 * out of memory). */
int ts__dict_sort(ts_dictionary *d);

/* Centre v (d values) and divide by its norm: out = (v - mean) / |v - mean|.
 * *mean and *rms (the norm / sqrt(d)) are returned; a flat v gives zeros and
 * returns 0, else 1. */
int ts__amp_normalise(const float *v, int d, float *out, double *mean, double *rms);

/* The matching weights (h, a, s, u, l, c) normalised to sum 1; l and c
 * only when use_l and use_c. */
void ts__amp_weights(const ts_amplify_params *p, int use_l, int use_c, double w[AMP_NW]);

/* For each patch, the atom with the highest g (ties: the lowest index), its
 * g and P_h . D_h.  Fast kernel: blocked dot products over tiles of patches
 * and atoms.  0, or -1 when out of memory. */
int ts__match_atoms(const ts_ctx *ctx, const ts_dictionary *dict, const amp_patches *pt,
                    const double w[AMP_NW], int *best, float *score, float *coef);

/* g of one patch against one atom, given the dot products (h, u, l, c) and
 * the two Gaussian widths (the matching function of section 5). */
double ts__amp_score(const double w[AMP_NW], double dot_h, double dot_u, double dot_l, double dot_c,
                     double dot_x, double da, double ds, double sigma_a, double sigma_s);

/* The context of the p x p window at (x, y) of r (section 5.3): the 3p x 3p
 * window around it (cells past the edge: the nearest inside), block-averaged
 * by 3 to p x p (nodata left out; a block without data takes the mean of the
 * others) and normalised into out (p * p values; zeros when flat). */
void ts__amp_context(const ts_raster *r, int x, int y, int p, float *out);

/* A class code as read: 0 for none (0 or NaN), 1..TS_MAX_CLASSES, or -1 for
 * anything else. */
int ts__class_code(float v);

#endif
