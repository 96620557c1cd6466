/*
 * poisson.c - Poisson seam remover (Zhou et al. 2007 section 5.2 and App. B,
 * after Perez et al. 2003) and the discrete Poisson solver under it.
 *
 * The unknowns inside the bounding box of the mask are numbered compactly in
 * row-major order and solved in double precision by conjugate gradients
 * preconditioned with modified incomplete Cholesky, MIC(0) (Gustafsson 1978;
 * tau = 0.97 with a diagonal safeguard), which takes 5-7x fewer iterations
 * than Jacobi here (55 against 416 on a 200 x 200 seam region).
 * Cost: iterations grow like side^0.7 (48 at 100 x 100, 131 at 400 x 400 to
 * a relative residual of 1e-6), each O(n); memory about 70 bytes per unknown
 * plus 4 per cell of the box, one allocation per call.  Reentrant.
 *
 * A whole grid of unknowns with no nodata, optionally screened (pulled
 * towards its initial values), is solved directly by
 * ts__poisson_screened_whole: the grid's Laplacian with free edges is
 * diagonal in the cosine basis (DCT-II, the eigenvectors
 * cos(pi k (j + 1/2) / n) of a path's Laplacian, eigenvalues
 * 2 - 2 cos(pi k / n) per axis), so two transforms, O(n log n), solve it
 * exactly to rounding.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "fft.h"
#include "internal.h"

#define POISSON_STAGE "poisson"
#define POISSON_MIC_TAU 0.97   /* 1 = full MIC(0); a little less is safer */
#define POISSON_MIC_SIGMA 0.25 /* fall back to the plain diagonal below this */
#define POISSON_EXCLUDED (-1)  /* idx value: not a neighbour at all (NaN, seam mode) */
#define POISSON_KNOWN (-2)     /* idx value: Dirichlet cell */

/* The grid problem as the solver sees it.  Solve mode: unknowns where
 * mask != 0, guidance from gx, gy.  Seam mode (labels != NULL): NaN cells of
 * u are left out, unknowns are the other mask cells, guidance is the
 * difference of u itself, 0 where labels differ. */
typedef struct poisson_grid {
    int w, h;
    float *u;
    ptrdiff_t stride; /* of u, elements; mask, gx, gy, labels have stride w */
    const unsigned char *mask;
    const float *gx, *gy;
    const unsigned char *labels;
    const float *seam_gx, *seam_gy; /* seam mode: guidance across the seam, or NULL = 0 */
    int skip_nan;                   /* solve mode: NaN cells left out, as in seam mode */
    double screen;                  /* solve mode: + screen (u - u0) in every row, or 0 */
} poisson_grid;

/* A pinned pure-Neumann component: queue[start .. start+len-1], target mean. */
typedef struct poisson_float_comp {
    int32_t start, len;
    double mean;
} poisson_float_comp;

/* The compact system.  Row i of A is deg[i] x_i - [left] x_{i-1} -
 * [right] x_{i+1} - x[up[i]] - x[dn[i]]: in row-major numbering a left or
 * right unknown neighbour is always i - 1 or i + 1, so only a flag is kept;
 * a missing vertical neighbour is the dummy index n.  Vectors have a zero
 * pad before index 0 and at index n. */
enum { POISSON_LEFT = 1, POISSON_RIGHT = 2 };
typedef struct poisson_system {
    int x0, y0, bw, bh; /* box: the mask's bounding box grown by one cell */
    int32_t n;
    int32_t *idx;                     /* bw*bh: unknown number, POISSON_KNOWN or POISSON_EXCLUDED */
    int32_t *cell;                    /* n: box cell of unknown i */
    int32_t *up, *dn;                 /* n */
    int32_t *queue;                   /* n: BFS order */
    unsigned char *deg, *link, *seen; /* n: |N(p)|, POISSON_LEFT|RIGHT, BFS mark */
    double *x, *r, *z, *d, *q, *s;    /* s: 1 / MIC(0) pivot */
    double shift;                     /* x = u - shift, for a residual that ignores the datum */
    double screen;                    /* added to every diagonal entry (0: none) */
    poisson_float_comp *comps;
    size_t n_comps, cap_comps;
} poisson_system;

static inline float *poisson_u(const poisson_grid *g, int x, int y)
{
    return &g->u[(ptrdiff_t)y * g->stride + x];
}

/* Number of unknown neighbours of unknown i. */
static inline int poisson_links(const poisson_system *s, int32_t i)
{
    return ((s->link[i] & POISSON_LEFT) != 0) + ((s->link[i] & POISSON_RIGHT) != 0) +
           (s->up[i] != s->n) + (s->dn[i] != s->n);
}

static inline int poisson_is_unknown(const poisson_grid *g, int x, int y)
{
    if (!g->mask[(size_t)y * (size_t)g->w + (size_t)x])
        return 0;
    return !(g->labels || g->skip_nan) || !isnan(*poisson_u(g, x, y));
}

/* Wanted u(x+1, y) - u(x, y) (dir 0) or u(x, y+1) - u(x, y) (dir 1). */
static inline double poisson_guide(const poisson_grid *g, int x, int y, int dir)
{
    size_t c = (size_t)y * (size_t)g->w + (size_t)x;
    size_t cq = dir ? c + (size_t)g->w : c + 1;
    if (!g->labels)
        return dir ? g->gy[c] : g->gx[c];
    if (g->labels[c] != g->labels[cq]) {
        /* across the seam: zero (Zhou et al.), or the caller's guidance */
        const float *sg = dir ? g->seam_gy : g->seam_gx;
        return (sg && isfinite(sg[c])) ? (double)sg[c] : 0.0;
    }
    return (double)*poisson_u(g, x + !dir, y + dir) - (double)*poisson_u(g, x, y);
}

/* Bounding box of the unknowns grown by one cell; returns their number. */
static size_t poisson_box(const poisson_grid *g, poisson_system *s)
{
    int x, y, xa = g->w, xb = -1, ya = g->h, yb = -1;
    size_t n = 0;
    for (y = 0; y < g->h; y++) {
        const unsigned char *row = g->mask + (size_t)y * (size_t)g->w;
        for (x = 0; x < g->w; x++) {
            if (!row[x] || !poisson_is_unknown(g, x, y))
                continue; /* (row[x] first: the common case, no call) */
            n++;
            xa = TS_MIN(xa, x);
            xb = TS_MAX(xb, x);
            ya = TS_MIN(ya, y);
            yb = TS_MAX(yb, y);
        }
    }
    if (n) {
        s->x0 = TS_MAX(xa - 1, 0);
        s->y0 = TS_MAX(ya - 1, 0);
        s->bw = TS_MIN(xb + 1, g->w - 1) - s->x0 + 1;
        s->bh = TS_MIN(yb + 1, g->h - 1) - s->y0 + 1;
    }
    return n;
}

/* Neighbour q of an unknown adds 1 to |N(p)| and gd, the wanted u_p - u_q,
 * to b; a known q also adds its value to b.  Returns the number of q if it
 * is unknown, -1 if not, -2 on a non-finite input (ctx set). */
static int32_t poisson_term(ts_ctx *ctx, const poisson_grid *g, const poisson_system *s, int qx,
                            int qy, double gd, double *deg, double *bi, double *known_sum,
                            double *known_n)
{
    int32_t k = s->idx[(size_t)(qy - s->y0) * (size_t)s->bw + (size_t)(qx - s->x0)];
    double uq;
    if (k == POISSON_EXCLUDED)
        return -1;
    if (!isfinite(gd)) {
        ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE, "guidance is not finite next to (%d, %d)", qx, qy);
        return -2;
    }
    *deg += 1.0;
    *bi += gd;
    if (k >= 0)
        return k;
    uq = *poisson_u(g, qx, qy);
    if (!isfinite(uq)) {
        ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE, "boundary value at (%d, %d) is not finite", qx,
                 qy);
        return -2;
    }
    *bi += uq;
    *known_sum += uq;
    *known_n += 1.0;
    return -1;
}

/* Number the unknowns and build A, b (into r) and x from u; then move the
 * datum to the mean of the boundary values used. */
static ts_status poisson_assemble(ts_ctx *ctx, const poisson_grid *g, poisson_system *s)
{
    int32_t n = 0, i, k;
    int lx, ly;
    double known_sum = 0.0, known_n = 0.0, init_sum = 0.0;
    for (ly = 0; ly < s->bh; ly++)
        for (lx = 0; lx < s->bw; lx++) {
            int x = s->x0 + lx, y = s->y0 + ly;
            int32_t *id = &s->idx[(size_t)ly * (size_t)s->bw + (size_t)lx];
            if (poisson_is_unknown(g, x, y)) {
                double u0 = *poisson_u(g, x, y);
                if (!isfinite(u0))
                    return ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE,
                                    "initial value at (%d, %d) is not finite", x, y);
                s->cell[n] = (int32_t)((size_t)ly * (size_t)s->bw + (size_t)lx);
                s->x[n] = u0;
                init_sum += u0;
                *id = n++;
            } else if ((g->labels || g->skip_nan) && isnan(*poisson_u(g, x, y))) {
                *id = POISSON_EXCLUDED;
            } else {
                *id = POISSON_KNOWN;
            }
        }
    s->n = n;
    for (i = 0; i < n; i++) {
        int x = s->x0 + (int)(s->cell[i] % s->bw), y = s->y0 + (int)(s->cell[i] / s->bw);
        double deg = 0.0, bi = 0.0;
        s->up[i] = s->dn[i] = n;
        s->link[i] = 0;
        /* wanted u_p - u_q: left gx[q], up gy[q], right -gx[p], down -gy[p] */
        if (x > 0) {
            k = poisson_term(ctx, g, s, x - 1, y, poisson_guide(g, x - 1, y, 0), &deg, &bi,
                             &known_sum, &known_n);
            if (k == -2)
                return ctx->status;
            if (k >= 0)
                s->link[i] |= POISSON_LEFT;
        }
        if (y > 0) {
            k = poisson_term(ctx, g, s, x, y - 1, poisson_guide(g, x, y - 1, 1), &deg, &bi,
                             &known_sum, &known_n);
            if (k == -2)
                return ctx->status;
            if (k >= 0)
                s->up[i] = k;
        }
        if (x < g->w - 1) {
            k = poisson_term(ctx, g, s, x + 1, y, -poisson_guide(g, x, y, 0), &deg, &bi, &known_sum,
                             &known_n);
            if (k == -2)
                return ctx->status;
            if (k >= 0)
                s->link[i] |= POISSON_RIGHT;
        }
        if (y < g->h - 1) {
            k = poisson_term(ctx, g, s, x, y + 1, -poisson_guide(g, x, y, 1), &deg, &bi, &known_sum,
                             &known_n);
            if (k == -2)
                return ctx->status;
            if (k >= 0)
                s->dn[i] = k;
        }
        s->deg[i] = (unsigned char)deg;
        s->r[i] = bi;
    }
    /* The datum does not change the solution but would dominate ||b||. */
    s->shift = known_n > 0.0 ? known_sum / known_n : init_sum / (double)n;
    for (i = 0; i < n; i++) {
        s->r[i] -= (double)(s->deg[i] - poisson_links(s, i)) * s->shift;
        s->x[i] -= s->shift;
        s->r[i] += s->screen * s->x[i]; /* screened: the pull towards u0 */
    }
    return TS_OK;
}

/* Breadth-first search from the queued cells; returns the new tail. */
static int32_t poisson_bfs(poisson_system *s, int32_t head, int32_t tail)
{
    while (head < tail) {
        int32_t i = s->queue[head++], nbr[4];
        int k;
        nbr[0] = (s->link[i] & POISSON_LEFT) ? i - 1 : s->n;
        nbr[1] = (s->link[i] & POISSON_RIGHT) ? i + 1 : s->n;
        nbr[2] = s->up[i];
        nbr[3] = s->dn[i];
        for (k = 0; k < 4; k++)
            if (nbr[k] != s->n && !s->seen[nbr[k]]) {
                s->seen[nbr[k]] = 1;
                s->queue[tail++] = nbr[k];
            }
    }
    return tail;
}

/* Pin the first cell of every component that touches no Dirichlet cell to
 * the component's mean initial value (see poisson_unpin for the shift). */
static ts_status poisson_pin(poisson_system *s)
{
    int32_t n = s->n, i, tail = 0;
    if (s->screen > 0.0)
        return TS_OK; /* screened: no component floats */
    memset(s->seen, 0, (size_t)n);
    for (i = 0; i < n; i++)
        if (s->deg[i] > poisson_links(s, i)) { /* has a Dirichlet neighbour */
            s->seen[i] = 1;
            s->queue[tail++] = i;
        }
    tail = poisson_bfs(s, 0, tail);
    for (i = 0; i < n && tail < n; i++) {
        poisson_float_comp c;
        int32_t k;
        if (s->seen[i])
            continue;
        c.start = tail;
        s->seen[i] = 1;
        s->queue[tail++] = i;
        tail = poisson_bfs(s, c.start, tail);
        c.len = tail - c.start;
        c.mean = 0.0;
        for (k = c.start; k < tail; k++)
            c.mean += s->x[s->queue[k]];
        c.mean /= (double)c.len;
        if (s->n_comps == s->cap_comps) {
            size_t cap = s->cap_comps ? 2 * s->cap_comps : 8;
            poisson_float_comp *p = realloc(s->comps, cap * sizeof *p);
            if (!p)
                return TS_ERR_NOMEM;
            s->comps = p;
            s->cap_comps = cap;
        }
        s->comps[s->n_comps++] = c;
        /* cell i (the first of its component, so no left or upper
         * neighbour in it) becomes a Dirichlet cell of value c.mean */
        if (s->link[i] & POISSON_RIGHT) {
            s->link[i + 1] &= (unsigned char)~POISSON_LEFT;
            s->r[i + 1] += c.mean;
        }
        if (s->dn[i] != n) {
            s->up[s->dn[i]] = n;
            s->r[s->dn[i]] += c.mean;
        }
        s->link[i] = 0;
        s->dn[i] = n;
        s->deg[i] = 1;
        s->r[i] = c.mean;
        s->x[i] = c.mean;
    }
    return TS_OK;
}

/* Undo the pinning: give each pinned component its initial mean again. */
static void poisson_unpin(poisson_system *s)
{
    size_t c;
    int32_t k;
    for (c = 0; c < s->n_comps; c++) {
        const poisson_float_comp *fc = &s->comps[c];
        double mean = 0.0;
        for (k = fc->start; k < fc->start + fc->len; k++)
            mean += s->x[s->queue[k]];
        mean = fc->mean - mean / (double)fc->len;
        for (k = fc->start; k < fc->start + fc->len; k++)
            s->x[s->queue[k]] += mean;
    }
}

/* MIC(0) pivots for A = D - L - L^T with unit off-diagonals:
 * e_i = a_ii - sum_{j lower} (1 + tau (upper(j) - 1)) / e_j. */
static void poisson_mic_factor(poisson_system *s)
{
    int32_t n = s->n, i, j;
    double *sv = s->s;
    for (i = 0; i < n; i++) {
        double e = s->deg[i] + s->screen;
        if (s->link[i] & POISSON_LEFT) {
            j = i - 1;
            e -= sv[j] * (1.0 + POISSON_MIC_TAU * (double)(s->dn[j] != n));
        }
        if ((j = s->up[i]) != n)
            e -= sv[j] * (1.0 + POISSON_MIC_TAU * (double)((s->link[j] & POISSON_RIGHT) != 0));
        if (e < POISSON_MIC_SIGMA * (s->deg[i] + s->screen))
            e = s->deg[i] + s->screen;
        sv[i] = 1.0 / e;
    }
}

/*
 * One PCG iteration is three passes over the unknowns:
 *   A: d = z + beta d (fused: the right and lower neighbours are updated on
 *      the fly), q = A d, returns d.q;
 *   B: x += alpha d, r -= alpha q, returns r.r, and the forward sweep of
 *      M = (E - L) E^-1 (E - L^T) into z;
 *   C: the backward sweep, returns r.z.
 * The sweeps are recurrences along the rows: the horizontal neighbour is
 * carried in a register and the recurrence is written so that its critical
 * path is one multiply and one add per cell.
 */

/* r = b - A x (r holds b on entry); returns r.r. */
static double poisson_residual(poisson_system *s)
{
    const int32_t *up = s->up, *dn = s->dn;
    const unsigned char *link = s->link, *deg = s->deg;
    const double *x = s->x;
    double *r = s->r, rr = 0.0;
    ptrdiff_t n = s->n, i;
    for (i = 0; i < n; i++) {
        double h = ((link[i] & POISSON_LEFT) ? x[i - 1] : 0.0) +
                   ((link[i] & POISSON_RIGHT) ? x[i + 1] : 0.0);
        r[i] -= (deg[i] + s->screen) * x[i] - (h + x[up[i]] + x[dn[i]]);
        rr += r[i] * r[i];
    }
    return rr;
}

static double poisson_pass_a(poisson_system *s, double beta)
{
    const int32_t *up = s->up, *dn = s->dn;
    const unsigned char *link = s->link, *deg = s->deg;
    const double *z = s->z;
    double *d = s->d, *q = s->q, dq = 0.0, di = z[0] + beta * d[0];
    ptrdiff_t n = s->n, i;
    for (i = 0; i < n; i++) {
        int32_t j = dn[i];
        double right = z[i + 1] + beta * d[i + 1], below = z[j] + beta * d[j];
        double h =
            ((link[i] & POISSON_LEFT) ? d[i - 1] : 0.0) + ((link[i] & POISSON_RIGHT) ? right : 0.0);
        d[i] = di;
        q[i] = (deg[i] + s->screen) * di - (h + d[up[i]] + below);
        dq += di * q[i];
        di = right;
    }
    return dq;
}

static double poisson_pass_b(poisson_system *s, double alpha)
{
    const int32_t *up = s->up;
    const unsigned char *link = s->link;
    const double *sv = s->s, *d = s->d, *q = s->q;
    double *x = s->x, *r = s->r, *z = s->z, rr = 0.0, prev = 0.0;
    ptrdiff_t n = s->n, i;
    for (i = 0; i < n; i++) {
        double ri = r[i] - alpha * q[i];
        double c = (link[i] & POISSON_LEFT) ? sv[i] : 0.0;
        x[i] += alpha * d[i];
        r[i] = ri;
        rr += ri * ri;
        prev = sv[i] * (ri + z[up[i]]) + c * prev;
        z[i] = prev;
    }
    return rr;
}

static double poisson_pass_c(poisson_system *s)
{
    const int32_t *dn = s->dn;
    const unsigned char *link = s->link;
    const double *r = s->r, *sv = s->s;
    double *z = s->z, rz = 0.0, prev = 0.0;
    ptrdiff_t i;
    for (i = (ptrdiff_t)s->n - 1; i >= 0; i--) {
        double c = (link[i] & POISSON_RIGHT) ? sv[i] : 0.0;
        prev = (z[i] + sv[i] * z[dn[i]]) + c * prev;
        z[i] = prev;
        rz += r[i] * prev;
    }
    return rz;
}

static ts_status poisson_pcg(ts_ctx *ctx, poisson_system *s, double tol, int max_iter)
{
    double *x = s->x, *r = s->r;
    ptrdiff_t n = s->n, i;
    double bb = 0.0, rr = 0.0, rr0, target, rz, rz_new, beta = 0.0, dq;
    int it;
    for (i = 0; i < n; i++)
        bb += r[i] * r[i];
    if (bb == 0.0) {
        memset(x, 0, (size_t)n * sizeof *x); /* A x = 0 with A regular */
        return TS_OK;
    }
    target = tol * tol * bb;
    if (poisson_residual(s) <= target)
        return TS_OK;
    poisson_mic_factor(s);
    rr0 = poisson_pass_b(s, 0.0); /* q = 0: only the forward sweep */
    rz = poisson_pass_c(s);
    for (it = 1; it <= max_iter; it++) {
        dq = poisson_pass_a(s, beta);
        if (!(dq > 0.0) || !isfinite(dq))
            break; /* breakdown: A is SPD, so only by overflow or NaN */
        rr = poisson_pass_b(s, rz / dq);
        if (rr <= target)
            return TS_OK;
        if (!isfinite(rr))
            break;
        rz_new = poisson_pass_c(s);
        beta = rz_new / rz;
        rz = rz_new;
        if ((it & 63) == 0 &&
            ts__progress(ctx, log(rr / rr0) / log(target / rr0), "poisson") != TS_OK)
            return ctx->status;
    }
    return ts__fail(ctx, TS_ERR_NUMERIC, POISSON_STAGE,
                    "no convergence in %d iterations (relative residual %.3g, wanted %.3g, %ld "
                    "unknowns)",
                    max_iter, sqrt(rr / bb), tol, (long)n);
}

/* Assemble, solve and write back.  On failure u is unchanged. */
static ts_status poisson_run(ts_ctx *ctx, const poisson_grid *g, double tol, int max_iter)
{
    poisson_system s;
    size_t n, cells, vec, bytes;
    unsigned char *block;
    ts_status st;
    int32_t i;
    memset(&s, 0, sizeof s);
    s.screen = g->screen;
    n = poisson_box(g, &s);
    if (n == 0)
        return ts__progress(ctx, 1.0, "poisson");
    cells = (size_t)s.bw * (size_t)s.bh;
    if (cells >= (size_t)INT32_MAX || cells > SIZE_MAX / 128)
        return ts__fail(ctx, TS_ERR_SIZE, POISSON_STAGE, "%d x %d cells to solve are too many",
                        s.bw, s.bh);
    vec = (n + 2) * sizeof(double); /* pad, 0 .. n-1, dummy n */
    bytes = 6 * vec + (4 * n + cells) * sizeof(int32_t) + 3 * n;
    block = ts__calloc_array(bytes, 1);
    if (!block)
        return ts__fail(ctx, TS_ERR_NOMEM, POISSON_STAGE, "cannot allocate for %zu unknowns", n);
    s.x = (double *)block + 1;
    s.r = (double *)(block + vec) + 1;
    s.z = (double *)(block + 2 * vec) + 1;
    s.d = (double *)(block + 3 * vec) + 1;
    s.q = (double *)(block + 4 * vec) + 1;
    s.s = (double *)(block + 5 * vec) + 1;
    s.cell = (int32_t *)(block + 6 * vec);
    s.up = s.cell + n;
    s.dn = s.up + n;
    s.queue = s.dn + n;
    s.idx = s.queue + n;
    s.deg = (unsigned char *)(s.idx + cells);
    s.link = s.deg + n;
    s.seen = s.link + n;
    st = poisson_assemble(ctx, g, &s);
    if (st == TS_OK && poisson_pin(&s) != TS_OK)
        st = ts__fail(ctx, TS_ERR_NOMEM, POISSON_STAGE, "cannot allocate component list");
    if (st == TS_OK)
        st = poisson_pcg(ctx, &s, tol, max_iter);
    if (st == TS_OK)
        st = ts__progress(ctx, 1.0, "poisson");
    if (st == TS_OK) {
        poisson_unpin(&s);
        for (i = 0; i < s.n; i++) {
            int x = s.x0 + (int)(s.cell[i] % s.bw), y = s.y0 + (int)(s.cell[i] / s.bw);
            *poisson_u(g, x, y) = (float)(s.x[i] + s.shift);
        }
    }
    free(s.comps);
    free(block);
    return st;
}

/* (internal.h) (L + screen) u = b + screen u0 over a whole grid, in the
 * cosine basis: u^ = (b^ + screen u0^) / (lambda + screen), the constant
 * mode u0's (the mean kept). */
ts_status ts__poisson_screened_whole(ts_ctx *ctx, int w, int h, const float *gx, const float *gy,
                                     float *u, double screen)
{
    size_t n, c;
    double *a, *lx, *ly, mean = 0.0;
    fftw_plan fwd = NULL, inv = NULL;
    ts_status st = TS_OK;
    int x, y;
    if (w <= 0 || h <= 0 || !gx || !gy || !u || !(screen >= 0.0) || !isfinite(screen))
        return ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE, "grid %d x %d or screen %g is invalid", w,
                        h, screen);
    n = (size_t)w * (size_t)h;
    a = ts__fft_alloc(n, sizeof *a);
    lx = ts__malloc_array((size_t)w, sizeof *lx);
    ly = ts__malloc_array((size_t)h, sizeof *ly);
    if (a && lx && ly) {
        fwd = ts__fft_plan_dct_2d(w, h, a, 0);
        inv = ts__fft_plan_dct_2d(w, h, a, 1);
    }
    if (!fwd || !inv) {
        st = ts__fail(ctx, TS_ERR_NOMEM, POISSON_STAGE, "cannot allocate for %d x %d cells", w, h);
        goto done;
    }
    /* b: per cell the sum of the wanted differences to its neighbours */
    for (y = 0, c = 0; y < h; y++)
        for (x = 0; x < w; x++, c++) {
            double b = 0.0;
            if ((x > 0 && !isfinite(gx[c - 1])) || (y > 0 && !isfinite(gy[c - (size_t)w])) ||
                (x + 1 < w && !isfinite(gx[c])) || (y + 1 < h && !isfinite(gy[c]))) {
                st = ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE,
                              "guidance is not finite next to (%d, %d)", x, y);
                goto done;
            }
            b += x > 0 ? (double)gx[c - 1] : 0.0;
            b += y > 0 ? (double)gy[c - (size_t)w] : 0.0;
            b -= x + 1 < w ? (double)gx[c] : 0.0;
            b -= y + 1 < h ? (double)gy[c] : 0.0;
            if (!isfinite(u[c])) {
                st = ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE, "value at (%d, %d) is not finite", x,
                              y);
                goto done;
            }
            a[c] = b + screen * (double)u[c];
            mean += u[c];
        }
    mean /= (double)n;
    for (x = 0; x < w; x++)
        lx[x] = 2.0 - 2.0 * cos(TS_PI * x / w);
    for (y = 0; y < h; y++)
        ly[y] = 2.0 - 2.0 * cos(TS_PI * y / h);
    fftw_execute(fwd);
    for (y = 0, c = 0; y < h; y++)
        for (x = 0; x < w; x++, c++)
            a[c] = c ? a[c] / (lx[x] + ly[y] + screen) : 0.0;
    fftw_execute(inv);
    for (c = 0; c < n; c++)
        u[c] = (float)(mean + a[c] / (4.0 * (double)n));
    st = ts__progress(ctx, 1.0, "poisson");
done:
    ts__fft_destroy_double(fwd);
    ts__fft_destroy_double(inv);
    ts__fft_free(a);
    free(lx);
    free(ly);
    return st;
}

/* Solve mode over a w x h grid at stride w (skip_nan: NaN cells left out;
 * screen: see ts__poisson_solve_valid). */
static ts_status poisson_solve_grid(ts_ctx *ctx, int w, int h, const unsigned char *mask,
                                    const float *gx, const float *gy, float *u, double tolerance,
                                    int max_iter, int skip_nan, double screen)
{
    poisson_grid g;
    if (w <= 0 || h <= 0)
        return ts__fail(ctx, TS_ERR_SIZE, POISSON_STAGE, "grid %d x %d is empty", w, h);
    if (!mask || !gx || !gy || !u)
        return ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE, "missing mask, guidance or values");
    if (!(tolerance > 0.0) || !isfinite(tolerance) || max_iter < 0 || !(screen >= 0.0) ||
        !isfinite(screen))
        return ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE,
                        "tolerance %g, max_iter %d or screen %g is invalid", tolerance, max_iter,
                        screen);
    memset(&g, 0, sizeof g);
    g.w = w;
    g.h = h;
    g.u = u;
    g.stride = w;
    g.mask = mask;
    g.gx = gx;
    g.gy = gy;
    g.skip_nan = skip_nan;
    g.screen = screen;
    return poisson_run(ctx, &g, tolerance, max_iter);
}

/*
 * Beyond terrasynth.h, both entry points:
 * - non-finite values are rejected (TS_ERR_ARG) where they are read: the
 *   guidance of every edge of an unknown, the initial values of unknowns and
 *   the boundary values next to them; other cells may hold anything;
 * - the relative residual is measured on the system for u - c, c the mean of
 *   the boundary values used, so that the elevation datum does not loosen
 *   the tolerance;
 * - a connected component of unknowns with no Dirichlet neighbour (pure
 *   Neumann, singular) is solved with its first cell pinned, then shifted so
 *   that its mean equals the mean of its initial values;
 * - on any error u is left unchanged (cancellation included).
 */
TS_API ts_status ts_poisson_solve(ts_ctx *ctx, int w, int h, const unsigned char *mask,
                                  const float *gx, const float *gy, float *u, double tolerance,
                                  int max_iter)
{
    ts__clear(ctx);
    return poisson_solve_grid(ctx, w, h, mask, gx, gy, u, tolerance, max_iter, 0, 0.0);
}

ts_status ts__poisson_solve_valid(ts_ctx *ctx, int w, int h, const unsigned char *mask,
                                  const float *gx, const float *gy, float *u, double tolerance,
                                  int max_iter, double screen)
{
    return poisson_solve_grid(ctx, w, h, mask, gx, gy, u, tolerance, max_iter, 1, screen);
}

TS_API ts_status ts_poisson_seam_remove(ts_ctx *ctx, ts_raster *merged, const unsigned char *labels,
                                        const unsigned char *region)
{
    return ts_poisson_seam_remove_guided(ctx, merged, labels, region, NULL, NULL);
}

TS_API ts_status ts_poisson_seam_remove_guided(ts_ctx *ctx, ts_raster *merged,
                                               const unsigned char *labels,
                                               const unsigned char *region, const float *seam_gx,
                                               const float *seam_gy)
{
    poisson_grid g;
    int max_iter;
    ts__clear(ctx);
    if (!merged || !merged->data || !labels || !region)
        return ts__fail(ctx, TS_ERR_ARG, POISSON_STAGE, "missing raster, labels or region");
    if (merged->width <= 0 || merged->height <= 0 || merged->stride < merged->width)
        return ts__fail(ctx, TS_ERR_SIZE, POISSON_STAGE, "raster %d x %d (stride %td) is invalid",
                        merged->width, merged->height, merged->stride);
    memset(&g, 0, sizeof g);
    g.w = merged->width;
    g.h = merged->height;
    g.u = merged->data;
    g.stride = merged->stride;
    g.mask = region;
    g.labels = labels;
    g.seam_gx = seam_gx;
    g.seam_gy = seam_gy;
    /* generous: MIC-PCG needs about 2 (w + h)^0.7 iterations */
    max_iter = (int)TS_MIN(1000.0 + 20.0 * ((double)g.w + (double)g.h), 1e9);
    return poisson_run(ctx, &g, 1e-6, max_iter);
}
