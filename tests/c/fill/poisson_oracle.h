/*
 * poisson_oracle.h - the Poisson tests' oracle: the linear system of
 * ts_poisson_solve written out densely and solved by Gaussian elimination
 * (static functions; include once per test program).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_TEST_POISSON_ORACLE_H
#define TS_TEST_POISSON_ORACLE_H

#include <math.h>
#include <stdlib.h>

/* ---- the oracle: the linear system written out densely ---- */

enum { REF_OUT = 0, REF_KNOWN = 1, REF_UNKNOWN = 2 };

/* Gaussian elimination with partial pivoting on the n x n system a x = b
 * (both destroyed); returns 0 if singular. */
static int ref_gauss(double *a, double *b, double *x, int n)
{
    int i, j, k;
    for (k = 0; k < n; k++) {
        int piv = k;
        for (i = k + 1; i < n; i++)
            if (fabs(a[i * n + k]) > fabs(a[piv * n + k]))
                piv = i;
        if (fabs(a[piv * n + k]) < 1e-12)
            return 0;
        if (piv != k) {
            double t;
            for (j = 0; j < n; j++) {
                t = a[k * n + j];
                a[k * n + j] = a[piv * n + j];
                a[piv * n + j] = t;
            }
            t = b[k];
            b[k] = b[piv];
            b[piv] = t;
        }
        for (i = k + 1; i < n; i++) {
            double f = a[i * n + k] / a[k * n + k];
            for (j = k; j < n; j++)
                a[i * n + j] -= f * a[k * n + j];
            b[i] -= f * b[k];
        }
    }
    for (i = n - 1; i >= 0; i--) {
        double sum = b[i];
        for (j = i + 1; j < n; j++)
            sum -= a[i * n + j] * x[j];
        x[i] = sum / a[i * n + i];
    }
    return 1;
}

/*
 * The system exactly as documented: for each unknown p and each neighbour q
 * inside the grid and not REF_OUT, one term u_p - u_q = d_pq, where d_pq is
 * -gr[p] (q right), gr[q] (q left), -gd[p] (q below), gd[q] (q above); known
 * q move to the right-hand side.  A component of unknowns that touches no
 * known cell gets its first equation replaced by "sum = count * mean of the
 * initial values".  u (double, w*h) is read for boundary and initial values
 * and receives the solution on unknowns.  Returns 0 if singular.
 */
static int ref_solve(int w, int h, const unsigned char *cls, const double *gr, const double *gd,
                     double *u)
{
    int *id = malloc((size_t)w * h * sizeof *id), *comp, *stack;
    int n = 0, c, i, ok, ncomp = 0;
    double *a, *b, *x;
    static const int dx[4] = {1, -1, 0, 0}, dy[4] = {0, 0, 1, -1};
    for (c = 0; c < w * h; c++)
        id[c] = cls[c] == REF_UNKNOWN ? n++ : -1;
    a = calloc((size_t)n * n + 1, sizeof *a);
    b = calloc((size_t)n + 1, sizeof *b);
    x = calloc((size_t)n + 1, sizeof *x);
    comp = malloc(((size_t)n + 1) * sizeof *comp);
    stack = malloc(((size_t)n + 1) * sizeof *stack);
    for (c = 0; c < w * h; c++) {
        int px = c % w, py = c / w, k, p = id[c];
        if (p < 0)
            continue;
        for (k = 0; k < 4; k++) {
            int qx = px + dx[k], qy = py + dy[k], q;
            double d;
            if (qx < 0 || qy < 0 || qx >= w || qy >= h || cls[qy * w + qx] == REF_OUT)
                continue;
            q = qy * w + qx;
            if (k == 0)
                d = -gr[c];
            else if (k == 1)
                d = gr[q];
            else if (k == 2)
                d = -gd[c];
            else
                d = gd[q];
            a[p * n + p] += 1.0;
            b[p] += d;
            if (id[q] >= 0)
                a[p * n + id[q]] -= 1.0;
            else
                b[p] += u[q];
        }
    }
    /* components by flood fill over cells */
    for (i = 0; i < n; i++)
        comp[i] = -1;
    for (c = 0; c < w * h; c++) {
        int top = 0, touches = 0, first = id[c], k;
        double sum = 0.0;
        if (id[c] < 0 || comp[id[c]] >= 0)
            continue;
        comp[id[c]] = ncomp;
        stack[top++] = c;
        while (top) {
            int e = stack[--top], ex = e % w, ey = e / w;
            sum += u[e];
            for (k = 0; k < 4; k++) {
                int qx = ex + dx[k], qy = ey + dy[k], q;
                if (qx < 0 || qy < 0 || qx >= w || qy >= h)
                    continue;
                q = qy * w + qx;
                if (cls[q] == REF_KNOWN)
                    touches = 1;
                else if (cls[q] == REF_UNKNOWN && comp[id[q]] < 0) {
                    comp[id[q]] = ncomp;
                    stack[top++] = q;
                }
            }
        }
        if (!touches) {
            for (i = 0; i < n; i++)
                a[first * n + i] = comp[i] == ncomp ? 1.0 : 0.0;
            b[first] = sum; /* sum of x = sum of the initial values */
        }
        ncomp++;
    }
    ok = ref_gauss(a, b, x, n);
    for (c = 0; c < w * h; c++)
        if (id[c] >= 0)
            u[c] = x[id[c]];
    free(id);
    free(a);
    free(b);
    free(x);
    free(comp);
    free(stack);
    return ok;
}

#endif
