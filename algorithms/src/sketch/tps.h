/*
 * tps.h - private thin-plate spline warps of the library (Zhou et al. 2007
 * section 4.1, after Bookstein 1989): fit a 2-D spline through control
 * points, evaluate it, and resample a raster through it.  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_TPS_H
#define TS_TPS_H

#include "terrasynth.h"

#define TS_TPS_MAX 16

/*
 * A 2-D thin-plate spline R^2 -> R^2, a plain value (no pointers):
 *   out_x(x, y) = ax[0] + ax[1] x + ax[2] y + sum_i wx[i] U(|(x, y) - (cx[i], cy[i])|)
 * and likewise out_y with ay, wy; U(r) = r^2 log r^2, U(0) = 0.
 * Only the first n entries of cx, cy, wx, wy are meaningful.
 */
typedef struct ts_tps {
    int n;                                 /* control points, 1..TS_TPS_MAX (0: identity) */
    double cx[TS_TPS_MAX], cy[TS_TPS_MAX]; /* source control points */
    double wx[TS_TPS_MAX], wy[TS_TPS_MAX]; /* kernel weights of the x and y outputs */
    double ax[3], ay[3];                   /* affine part: out = a0 + a1 x + a2 y */
    double bending;                        /* w_x^T K w_x + w_y^T K w_y, see ts__tps_fit */
} ts_tps;

/*
 * Fit the spline mapping (src_x[i], src_y[i]) -> (dst_x[i], dst_y[i]),
 * i < n (all four arrays borrowed, n entries).  lambda = 0 interpolates
 * (exact at the control points); lambda > 0 solves [K + lambda I, P; P^T, 0]
 * instead, an approximating fit that gets smoother as lambda grows
 * (lambda in squared source units, as K).
 *
 * Special cases (w = 0, bending 0): n == 1 is a pure translation; n == 2
 * the similarity (rotation, uniform scale, translation) through both
 * points (lambda is not used for n <= 2).  For n >= 3 the source points
 * must not be collinear.
 *
 * out->bending is the raw quadratic form w_x^T K w_x + w_y^T K w_y with
 * K_ij = U(|c_i - c_j|) (clamped at 0 against rounding).  It is
 * proportional to Bookstein's integral bending energy (the integral of
 * f_xx^2 + 2 f_xy^2 + f_yy^2 over the plane, summed over both outputs,
 * equals 16 pi times it for this U), is 0 for affine maps, and is invariant
 * under rigid motions of the source or of the target points.  Scaling:
 * scaling source and target together by s leaves it unchanged; scaling the
 * source only multiplies it by 1/s^2 (the target only: by s^2).  So
 * compare the bending of candidates in the same coordinate frame.
 *
 * Returns TS_OK; TS_ERR_ARG for NULL arguments, n outside 1..TS_TPS_MAX,
 * non-finite coordinates, lambda < 0 or non-finite, coinciding points
 * (n == 2, or all n points) or collinear source points (n >= 3: "control
 * points are collinear"; the caller skips such a candidate);
 * TS_ERR_NUMERIC for a singular system (e.g. a repeated source point with
 * lambda = 0).  On error *out is the identity (n = 0) with bending
 * +INFINITY.  Cost O(n^3), n <= 16.  Thread-safe (ctx per thread).
 */
ts_status ts__tps_fit(ts_ctx *ctx, int n, const double *src_x, const double *src_y,
                      const double *dst_x, const double *dst_y, double lambda, ts_tps *out);

/* Evaluate the spline at (x, y) into (*ox, *oy).  O(n); no allocation. */
void ts__tps_map(const ts_tps *t, double x, double y, double *ox, double *oy);

/* Jacobian of the spline at (x, y): j = {dout_x/dx, dout_x/dy, dout_y/dx,
 * dout_y/dy} (analytic). */
void ts__tps_jacobian(const ts_tps *t, double x, double y, double j[4]);

/*
 * Does the spline fold over the square of half-side r around (cx, cy)?
 * The Jacobian determinant is sampled on an n x n lattice (n >= 2) over
 * the square: 1 when its sign differs anywhere from the centre's (the map turns
 * over: a fold), when its magnitude leaves [1/max_ratio, max_ratio] (areas
 * squeezed or stretched that far: the terrain's slopes would change as
 * much), when one direction is stretched more than max_ratio times the
 * other (the ratio of the Jacobian's singular values), or when the centre's
 * determinant is 0; 0 otherwise.  A mirrored map has a
 * negative determinant everywhere and does not fold.
 */
int ts__tps_folds(const ts_tps *t, double cx, double cy, double r, int n, double max_ratio);

/*
 * Warp: out(x, y) = src(T(x + 0.5 + ox, y + 0.5 + oy)) for every cell of
 * `out` (caller-allocated, its width x height defines the output; must not
 * overlap src), where T = *t maps output coordinates to source coordinates
 * in which the centre of source cell (i, j) is (i + 0.5, j + 0.5).
 * Bilinear interpolation between the four surrounding source cell centres;
 * a source position within 1e-9 cells of a cell centre (per axis) is
 * snapped to it, so near-identity warps reproduce cells exactly.  NaN where
 * T falls outside the rectangle spanned by the outermost cell centres of src,
 * or where a source cell with non-zero bilinear weight is NaN.
 * src and t are borrowed.  TS_ERR_ARG for NULL or empty rasters, a
 * non-finite offset or a spline with n outside 0..TS_TPS_MAX.
 * Cost O(width * height * n); rows run in parallel for large outputs.
 */
ts_status ts__tps_warp(ts_ctx *ctx, const ts_tps *t, const ts_raster *src, double ox, double oy,
                       ts_raster *out);

#endif
