/*
 * window_choice.c - the neighbourhood size of pixel synthesis chosen as Cruz
 * et al. (section II.A) choose it: for k in {3, 5, 7, 9}, the number of
 * principal components that hold 95 % of the variance of the exemplars'
 * k x k neighbourhoods (each less its mean), over k x k; the k with the
 * smallest ratio (ties: the smaller k).  The eigenvalues come from cyclic
 * Jacobi rotations (a symmetric matrix of at most 81 x 81).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pixel.h"

int ts__pix_eigenvalues(double *a, int n, double *ev)
{
    return ts__pix_eigen(a, n, ev, NULL);
}

int ts__pix_eigen(double *a, int n, double *ev, double *vec)
{
    int sweep, p, q, i;
    if (vec)
        for (p = 0; p < n; p++)
            for (q = 0; q < n; q++)
                vec[p * n + q] = p == q;
    for (sweep = 0; sweep < 100; sweep++) {
        double off = 0, tot = 0;
        for (p = 0; p < n; p++)
            for (q = 0; q < n; q++) {
                tot += a[p * n + q] * a[p * n + q];
                if (p != q)
                    off += a[p * n + q] * a[p * n + q];
            }
        if (off <= 1e-22 * (tot > 0 ? tot : 1))
            break;
        for (p = 0; p < n - 1; p++)
            for (q = p + 1; q < n; q++) {
                double apq = a[p * n + q], app, aqq, theta, t, c, s;
                if (fabs(apq) < 1e-300)
                    continue;
                app = a[p * n + p];
                aqq = a[q * n + q];
                theta = (aqq - app) / (2 * apq);
                t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1));
                c = 1 / sqrt(t * t + 1);
                s = t * c;
                for (i = 0; i < n; i++) { /* columns p and q */
                    double aip = a[i * n + p], aiq = a[i * n + q];
                    a[i * n + p] = c * aip - s * aiq;
                    a[i * n + q] = s * aip + c * aiq;
                }
                if (vec)
                    for (i = 0; i < n; i++) { /* the rotations' product, column by column */
                        double vip = vec[i * n + p], viq = vec[i * n + q];
                        vec[i * n + p] = c * vip - s * viq;
                        vec[i * n + q] = s * vip + c * viq;
                    }
                for (i = 0; i < n; i++) { /* rows p and q */
                    double api = a[p * n + i], aqi = a[q * n + i];
                    a[p * n + i] = c * api - s * aqi;
                    a[q * n + i] = s * api + c * aqi;
                }
            }
    }
    for (i = 0; i < n; i++)
        ev[i] = a[i * n + i];
    return sweep < 100 ? 0 : -1;
}

static int cmp_desc(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return a < b ? 1 : a > b ? -1 : 0;
}

double ts__pix_pca_ratio(const ts_raster *ex, int n, int k)
{
    int d = k * k, r = k / 2, e, i, j, a, b;
    double *cov = calloc((size_t)d * d, sizeof *cov), *v = malloc((size_t)d * sizeof *v);
    double *ev = malloc((size_t)d * sizeof *ev), tot = 0, acc = 0;
    size_t count = 0;
    int m;
    if (!cov || !v || !ev) {
        free(cov);
        free(v);
        free(ev);
        return -1;
    }
    for (e = 0; e < n; e++) {
        const ts_raster *x = &ex[e];
        int step = 1;
        while ((size_t)((x->width - k) / step + 1) * (size_t)((x->height - k) / step + 1) > 4000)
            step++;
        for (j = r; j + r < x->height; j += step)
            for (i = r; i + r < x->width; i += step) {
                double mean = 0;
                int ok = 1;
                for (b = -r; b <= r && ok; b++)
                    for (a = -r; a <= r; a++) {
                        float h = TS_PIX(x, i + a, j + b);
                        if (isnan(h)) {
                            ok = 0;
                            break;
                        }
                        v[(b + r) * k + a + r] = h;
                        mean += h;
                    }
                if (!ok)
                    continue;
                mean /= d;
                for (a = 0; a < d; a++)
                    v[a] -= mean;
                for (a = 0; a < d; a++)
                    for (b = 0; b < d; b++)
                        cov[a * d + b] += v[a] * v[b];
                count++;
            }
    }
    if (count < 2 || ts__pix_eigenvalues(cov, d, ev) != 0) {
        free(cov);
        free(v);
        free(ev);
        return -1;
    }
    qsort(ev, (size_t)d, sizeof *ev, cmp_desc);
    for (a = 0; a < d; a++)
        tot += ev[a] > 0 ? ev[a] : 0;
    for (m = 0; m < d && acc < 0.95 * tot; m++)
        acc += ev[m] > 0 ? ev[m] : 0;
    free(cov);
    free(v);
    free(ev);
    return tot > 0 ? (double)m / d : 1.0;
}

int ts__pix_choose_window(const ts_raster *ex, int n)
{
    int k, best = 5;
    double best_ratio = 2;
    for (k = 3; k <= 9; k += 2) {
        double ratio = ts__pix_pca_ratio(ex, n, k);
        if (ratio >= 0 && ratio < best_ratio - 1e-12) {
            best_ratio = ratio;
            best = k;
        }
    }
    return best;
}
