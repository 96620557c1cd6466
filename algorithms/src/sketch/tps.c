/*
 * tps.c - thin-plate spline warps for feature patch matching (Zhou et al.
 * 2007 section 4.1; Bookstein 1989): fit R^2 -> R^2 through control points,
 * bending energy as the deformation cost c_d, bilinear raster resampling.
 *
 * The fit centres the source points and scales them to unit RMS radius,
 * solves [K + lambda I, P; P^T, 0][w; a] = [v; 0] for both outputs at once
 * by dense LU with partial pivoting in double, then converts w and a back to
 * the caller's coordinates (exact algebra, see tps_fit_general).
 * Cost: fit O(n^3) with n <= 16; map O(n); warp O(w h n), rows in parallel.
 * Thread-safe: no globals; one ctx per thread.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <string.h>

#include "internal.h"
#include "tps.h"

#define TPS_DIM (TS_TPS_MAX + 3)
/* Smallest eigenvalue / largest of the normalised source scatter below
 * which the source points count as collinear. */
#define TPS_COLLINEAR_EPS 1e-10
/* Pivot magnitude, relative to the largest matrix entry, that counts as 0. */
#define TPS_PIVOT_EPS 1e-13
/* Snapping distance (in cells) of source positions to cell centres. */
#define TPS_SNAP 1e-9
/* Outputs of at least this many cells are warped in parallel. */
#define TPS_PARALLEL_CELLS 32768

/* U(r) = r^2 log r^2 from r^2; U(0) = 0. */
static double tps_kernel(double r2)
{
    return r2 > 0.0 ? r2 * log(r2) : 0.0;
}

static void tps_identity(ts_tps *t)
{
    memset(t, 0, sizeof *t);
    t->ax[1] = 1.0;
    t->ay[2] = 1.0;
}

/* Solve A X = B in place for m unknowns and 2 right-hand sides (columns of
 * b) by LU with partial pivoting; a is m x TPS_DIM, destroyed.  Returns
 * nonzero if a pivot is below TPS_PIVOT_EPS times the largest entry. */
static int tps_solve(double a[][TPS_DIM], double b[][2], int m)
{
    double scale = 0.0;
    int i, j, k;
    for (i = 0; i < m; i++)
        for (j = 0; j < m; j++)
            scale = TS_MAX(scale, fabs(a[i][j]));
    if (!(scale > 0.0))
        return 1;
    for (k = 0; k < m; k++) {
        int p = k;
        for (i = k + 1; i < m; i++)
            if (fabs(a[i][k]) > fabs(a[p][k]))
                p = i;
        if (!(fabs(a[p][k]) > TPS_PIVOT_EPS * scale))
            return 1;
        if (p != k) {
            for (j = 0; j < m; j++) {
                double tmp = a[k][j];
                a[k][j] = a[p][j];
                a[p][j] = tmp;
            }
            for (j = 0; j < 2; j++) {
                double tmp = b[k][j];
                b[k][j] = b[p][j];
                b[p][j] = tmp;
            }
        }
        for (i = k + 1; i < m; i++) {
            double f = a[i][k] / a[k][k];
            if (f == 0.0)
                continue;
            for (j = k + 1; j < m; j++)
                a[i][j] -= f * a[k][j];
            b[i][0] -= f * b[k][0];
            b[i][1] -= f * b[k][1];
        }
    }
    for (k = m - 1; k >= 0; k--) {
        for (j = 0; j < 2; j++) {
            double s = b[k][j];
            for (i = k + 1; i < m; i++)
                s -= a[k][i] * b[i][j];
            b[k][j] = s / a[k][k];
        }
    }
    return 0;
}

/* n == 2: the similarity z -> alpha z + beta (complex numbers) through both
 * pairs; the caller checked that the source points differ. */
static void tps_fit_similarity(const double *sx, const double *sy, const double *dx,
                               const double *dy, ts_tps *out)
{
    double ux = sx[1] - sx[0], uy = sy[1] - sy[0];
    double vx = dx[1] - dx[0], vy = dy[1] - dy[0];
    double den = ux * ux + uy * uy;
    double re = (vx * ux + vy * uy) / den; /* alpha = v / u */
    double im = (vy * ux - vx * uy) / den;
    out->ax[1] = re;
    out->ax[2] = -im;
    out->ax[0] = dx[0] - (re * sx[0] - im * sy[0]);
    out->ay[1] = im;
    out->ay[2] = re;
    out->ay[0] = dy[0] - (im * sx[0] + re * sy[0]);
}

/*
 * n >= 3.  With m the centroid and s the RMS radius of the sources,
 * u = (x - m) / s and the spline is fitted in u:
 *   f = A0 + A1 u + A2 v + sum W_i U(|u - u_i|).
 * As U(r / s) = (U(r) - L r^2) / s^2 with L = log s^2, and
 * sum W_i |x - c_i|^2 = s^2 sum W_i |u_i|^2 whenever P^T W = 0, this is
 * the spline with w = W / s^2, a1 = A1 / s, a2 = A2 / s and
 * a0 = A0 - (A1 mx + A2 my) / s - L sum W_i |u_i|^2 in the caller's
 * coordinates.  The same identities give K + lambda I in x <-> K_u +
 * (lambda / s^2) I in u, and w^T K w = W^T K_u W / s^2.
 */
static ts_status tps_fit_general(ts_ctx *ctx, int n, const double *sx, const double *sy,
                                 const double *dx, const double *dy, double lambda, ts_tps *out)
{
    double ux[TS_TPS_MAX], uy[TS_TPS_MAX];
    double a[TPS_DIM][TPS_DIM], k[TS_TPS_MAX][TS_TPS_MAX], b[TPS_DIM][2];
    double mx = 0.0, my = 0.0, r2 = 0.0, s, s2, lam, L;
    double cxx = 0.0, cyy = 0.0, cxy = 0.0, tr, disc, ev_min, ev_max;
    double be_x = 0.0, be_y = 0.0, wu2_x = 0.0, wu2_y = 0.0;
    int m = n + 3, i, j;

    for (i = 0; i < n; i++) {
        mx += sx[i];
        my += sy[i];
    }
    mx /= n;
    my /= n;
    for (i = 0; i < n; i++)
        r2 += (sx[i] - mx) * (sx[i] - mx) + (sy[i] - my) * (sy[i] - my);
    s = sqrt(r2 / n);
    if (!(s > 0.0) || !isfinite(s))
        return ts__fail(ctx, TS_ERR_ARG, "tps", "control points coincide");
    for (i = 0; i < n; i++) {
        ux[i] = (sx[i] - mx) / s;
        uy[i] = (sy[i] - my) / s;
        cxx += ux[i] * ux[i];
        cyy += uy[i] * uy[i];
        cxy += ux[i] * uy[i];
    }
    /* eigenvalues of the 2x2 scatter matrix */
    tr = 0.5 * (cxx + cyy);
    disc = sqrt(0.25 * (cxx - cyy) * (cxx - cyy) + cxy * cxy);
    ev_max = tr + disc;
    ev_min = tr - disc;
    if (ev_min <= TPS_COLLINEAR_EPS * ev_max)
        return ts__fail(ctx, TS_ERR_ARG, "tps", "control points are collinear");

    s2 = s * s;
    lam = lambda / s2;
    memset(a, 0, sizeof a);
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) {
            double ex = ux[i] - ux[j], ey = uy[i] - uy[j];
            k[i][j] = i == j ? 0.0 : tps_kernel(ex * ex + ey * ey);
            a[i][j] = k[i][j];
        }
        a[i][i] += lam;
        a[i][n] = a[n][i] = 1.0;
        a[i][n + 1] = a[n + 1][i] = ux[i];
        a[i][n + 2] = a[n + 2][i] = uy[i];
        b[i][0] = dx[i];
        b[i][1] = dy[i];
    }
    for (i = n; i < m; i++)
        b[i][0] = b[i][1] = 0.0;
    if (tps_solve(a, b, m))
        return ts__fail(ctx, TS_ERR_NUMERIC, "tps", "singular system (repeated control points?)");

    for (i = 0; i < n; i++) {
        double kx = 0.0, ky = 0.0;
        for (j = 0; j < n; j++) {
            kx += k[i][j] * b[j][0];
            ky += k[i][j] * b[j][1];
        }
        be_x += b[i][0] * kx;
        be_y += b[i][1] * ky;
        wu2_x += b[i][0] * (ux[i] * ux[i] + uy[i] * uy[i]);
        wu2_y += b[i][1] * (ux[i] * ux[i] + uy[i] * uy[i]);
    }
    L = log(s2);
    out->n = n;
    for (i = 0; i < n; i++) {
        out->cx[i] = sx[i];
        out->cy[i] = sy[i];
        out->wx[i] = b[i][0] / s2;
        out->wy[i] = b[i][1] / s2;
    }
    out->ax[1] = b[n + 1][0] / s;
    out->ax[2] = b[n + 2][0] / s;
    out->ax[0] = b[n][0] - (b[n + 1][0] * mx + b[n + 2][0] * my) / s - L * wu2_x;
    out->ay[1] = b[n + 1][1] / s;
    out->ay[2] = b[n + 2][1] / s;
    out->ay[0] = b[n][1] - (b[n + 1][1] * mx + b[n + 2][1] * my) / s - L * wu2_y;
    out->bending = TS_MAX(be_x, 0.0) / s2 + TS_MAX(be_y, 0.0) / s2;
    if (!isfinite(out->bending))
        return ts__fail(ctx, TS_ERR_NUMERIC, "tps", "non-finite bending energy");
    return TS_OK;
}

ts_status ts__tps_fit(ts_ctx *ctx, int n, const double *src_x, const double *src_y,
                      const double *dst_x, const double *dst_y, double lambda, ts_tps *out)
{
    ts_status st;
    int i;
    ts__clear(ctx);
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, "tps", "output spline is NULL");
    tps_identity(out);
    out->bending = INFINITY;
    if (n < 1 || n > TS_TPS_MAX)
        return ts__fail(ctx, TS_ERR_ARG, "tps", "%d control points (need 1..%d)", n, TS_TPS_MAX);
    if (!src_x || !src_y || !dst_x || !dst_y)
        return ts__fail(ctx, TS_ERR_ARG, "tps", "control point array is NULL");
    if (!isfinite(lambda) || lambda < 0.0)
        return ts__fail(ctx, TS_ERR_ARG, "tps", "lambda %g must be finite and >= 0", lambda);
    for (i = 0; i < n; i++)
        if (!isfinite(src_x[i]) || !isfinite(src_y[i]) || !isfinite(dst_x[i]) ||
            !isfinite(dst_y[i]))
            return ts__fail(ctx, TS_ERR_ARG, "tps", "control point %d is not finite", i);

    if (n == 1) {
        out->n = 1;
        out->cx[0] = src_x[0];
        out->cy[0] = src_y[0];
        out->ax[0] = dst_x[0] - src_x[0];
        out->ay[0] = dst_y[0] - src_y[0];
        out->bending = 0.0;
        return TS_OK;
    }
    if (n == 2) {
        if (src_x[0] == src_x[1] && src_y[0] == src_y[1])
            return ts__fail(ctx, TS_ERR_ARG, "tps", "control points coincide");
        out->n = 2;
        for (i = 0; i < 2; i++) {
            out->cx[i] = src_x[i];
            out->cy[i] = src_y[i];
        }
        tps_fit_similarity(src_x, src_y, dst_x, dst_y, out);
        out->bending = 0.0;
        return TS_OK;
    }
    st = tps_fit_general(ctx, n, src_x, src_y, dst_x, dst_y, lambda, out);
    if (st != TS_OK) {
        tps_identity(out);
        out->bending = INFINITY;
    }
    return st;
}

void ts__tps_map(const ts_tps *t, double x, double y, double *ox, double *oy)
{
    double fx = t->ax[0] + t->ax[1] * x + t->ax[2] * y;
    double fy = t->ay[0] + t->ay[1] * x + t->ay[2] * y;
    int i;
    for (i = 0; i < t->n; i++) {
        double ex = x - t->cx[i], ey = y - t->cy[i];
        double u = tps_kernel(ex * ex + ey * ey);
        fx += t->wx[i] * u;
        fy += t->wy[i] * u;
    }
    *ox = fx;
    *oy = fy;
}

void ts__tps_jacobian(const ts_tps *t, double x, double y, double j[4])
{
    int i;
    j[0] = t->ax[1];
    j[1] = t->ax[2];
    j[2] = t->ay[1];
    j[3] = t->ay[2];
    for (i = 0; i < t->n; i++) {
        double ex = x - t->cx[i], ey = y - t->cy[i], r2 = ex * ex + ey * ey, g;
        if (r2 <= 0.0)
            continue; /* d(r^2 log r^2) = 2 (log r^2 + 1) (ex, ey), 0 at r = 0 */
        g = 2.0 * (log(r2) + 1.0);
        j[0] += t->wx[i] * g * ex;
        j[1] += t->wx[i] * g * ey;
        j[2] += t->wy[i] * g * ex;
        j[3] += t->wy[i] * g * ey;
    }
}

int ts__tps_folds(const ts_tps *t, double cx, double cy, double r, int n, double max_ratio)
{
    double j[4], d0;
    int a, b;
    ts__tps_jacobian(t, cx, cy, j);
    d0 = j[0] * j[3] - j[1] * j[2];
    if (!(fabs(d0) > 0.0))
        return 1;
    for (b = 0; b < n; b++)
        for (a = 0; a < n; a++) {
            double x = cx + r * (2.0 * a / (n - 1) - 1.0), y = cy + r * (2.0 * b / (n - 1) - 1.0);
            double d, q;
            ts__tps_jacobian(t, x, y, j);
            d = j[0] * j[3] - j[1] * j[2];
            double f2 = 0.5 * (j[0] * j[0] + j[1] * j[1] + j[2] * j[2] + j[3] * j[3]);
            double disc = sqrt(fmax(f2 * f2 - d * d, 0.0)), s1, s2;
            q = fabs(d);
            if (!(d * d0 > 0.0) || !(q >= 1.0 / max_ratio && q <= max_ratio))
                return 1; /* orientation flips (a fold), or squeezed or stretched too far */
            /* singular values: one direction stretched, the other squeezed */
            s1 = sqrt(f2 + disc);
            s2 = sqrt(fmax(f2 - disc, 0.0));
            if (!(s1 <= max_ratio * s2))
                return 1;
        }
    return 0;
}

typedef struct tps_warp_job {
    const ts_tps *t;
    const ts_raster *src;
    ts_raster *out;
    double ox, oy;
} tps_warp_job;

/* Split a source cell coordinate f (cell centres at integers) into a lower
 * cell *i0 and a weight *w of the upper one; 0 if outside [0, size - 1]. */
static int tps_warp_axis(double f, int size, int *i0, double *w)
{
    double r = floor(f + 0.5);
    double fl;
    if (fabs(f - r) <= TPS_SNAP)
        f = r;
    if (!(f >= 0.0 && f <= (double)(size - 1)))
        return 0;
    fl = floor(f);
    *i0 = (int)fl;
    *w = f - fl;
    if (*i0 == size - 1) /* on the last centre: w is 0 */
        *w = 0.0;
    return 1;
}

static void tps_warp_rows(void *arg, size_t begin, size_t end)
{
    const tps_warp_job *job = arg;
    const ts_raster *src = job->src;
    size_t yy;
    for (yy = begin; yy < end; yy++) {
        int y = (int)yy, x;
        for (x = 0; x < job->out->width; x++) {
            double sx, sy, wx, wy, v = 0.0, wsum[2][2];
            int i0, j0, di, dj, bad = 0;
            ts__tps_map(job->t, x + 0.5 + job->ox, y + 0.5 + job->oy, &sx, &sy);
            if (!tps_warp_axis(sx - 0.5, src->width, &i0, &wx) ||
                !tps_warp_axis(sy - 0.5, src->height, &j0, &wy)) {
                TS_PIX(job->out, x, y) = NAN;
                continue;
            }
            wsum[0][0] = (1.0 - wx) * (1.0 - wy);
            wsum[0][1] = wx * (1.0 - wy);
            wsum[1][0] = (1.0 - wx) * wy;
            wsum[1][1] = wx * wy;
            for (dj = 0; dj < 2 && !bad; dj++)
                for (di = 0; di < 2; di++) {
                    float s;
                    if (wsum[dj][di] == 0.0)
                        continue;
                    s = TS_PIX(src, i0 + di, j0 + dj);
                    if (isnan(s)) {
                        bad = 1;
                        break;
                    }
                    v += wsum[dj][di] * (double)s;
                }
            TS_PIX(job->out, x, y) = bad ? NAN : (float)v;
        }
    }
}

ts_status ts__tps_warp(ts_ctx *ctx, const ts_tps *t, const ts_raster *src, double ox, double oy,
                       ts_raster *out)
{
    tps_warp_job job;
    size_t cells;
    ts__clear(ctx);
    if (!t || !src || !out || !src->data || !out->data)
        return ts__fail(ctx, TS_ERR_ARG, "tps", "NULL spline or raster");
    if (t->n < 0 || t->n > TS_TPS_MAX)
        return ts__fail(ctx, TS_ERR_ARG, "tps", "spline with %d control points", t->n);
    if (src->width < 1 || src->height < 1 || out->width < 1 || out->height < 1)
        return ts__fail(ctx, TS_ERR_ARG, "tps", "empty raster (%dx%d -> %dx%d)", src->width,
                        src->height, out->width, out->height);
    if (!isfinite(ox) || !isfinite(oy))
        return ts__fail(ctx, TS_ERR_ARG, "tps", "offset is not finite");
    job.t = t;
    job.src = src;
    job.out = out;
    job.ox = ox;
    job.oy = oy;
    cells = (size_t)out->width * (size_t)out->height;
    if (cells < TPS_PARALLEL_CELLS)
        tps_warp_rows(&job, 0, (size_t)out->height);
    else
        ts__parallel_for(ctx, (size_t)out->height, tps_warp_rows, &job);
    return TS_OK;
}
