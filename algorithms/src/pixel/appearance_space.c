/*
 * appearance_space.c - the neighbourhoods compared in the corrections,
 * reduced by principal components analysis (Cruz et al. section II.A,
 * after Lefebvre and Hoppe 2005: "the eigenvectors that represent the
 * directions containing at least 95 % of the energy").
 *
 * A neighbourhood n (k x k heights at the level's spacing) is its mean mu
 * on every cell plus its shape s = n - mu.  The two parts are orthogonal,
 * so the sum of squared differences splits exactly:
 *
 *     SSD(n, n') = k^2 (mu - mu')^2 + |s - s'|^2.
 *
 * A neighbourhood's appearance vector is (k mu, P s), P the principal
 * directions of the exemplars' shapes at the level that hold `energy` of
 * their variance.  The mean is kept exactly: a terrain's neighbourhoods
 * differ most by their height, and principal components of the raw heights
 * would keep little else (at the finest levels the shape is a few per cent
 * of the energy); this split is our reading of the paper, named as such.
 * With energy 1 every direction is kept and the distance between two
 * appearance vectors is the SSD (the tests compare both).
 *
 * The roughness term (ours, named as such): with lambda > 0 the vector ends
 * with sqrt(lambda) |s|, so the distance also holds lambda (|s| - |s'|)^2.
 * Where the target is a patchwork of several places (across a seam, after
 * jitter) no real neighbourhood is near it, and |s' - t|^2 = |s'|^2 -
 * 2 s'.t + |t|^2 is then smallest for the smoothest candidate: without the
 * term the outputs were gentler than the exemplars at every scale finer than
 * the coarsest (mean |h(p) - h(p + 8)| 0.75-0.96 x the exemplar's on
 * ../shared/data/dem at 1024^2, 0.91-1.03 at the coarsest spacing).  The
 * target's roughness is that of the heights its neighbours' coordinates
 * give, before any guide (coordinate_synthesis.c).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pixel.h"

/* At most this many shapes per exemplar enter a level's covariance. */
#define PIX_PCA_SAMPLES 4000

/* The k x k heights around cell (u, v) of a level at spacing sp. */
static void gather(const float *level, int width, int u, int v, int k, int sp, float *t)
{
    int r = k / 2, a, b;
    for (b = -r; b <= r; b++)
        for (a = -r; a <= r; a++)
            t[(b + r) * k + a + r] = level[(size_t)(v + b * sp) * width + u + a * sp];
}

void ts__pix_appearance(const float *basis, int m, int k, const float *t, float *out)
{
    int d = k * k, i, j;
    float mu = 0, c[81];
    for (j = 0; j < d; j++)
        mu += t[j];
    mu /= (float)d;
    for (j = 0; j < d; j++)
        c[j] = t[j] - mu;
    out[0] = (float)k * mu;
    for (i = 0; i < m; i++) {
        const float *row = basis + (size_t)i * d;
        float s = 0;
        for (j = 0; j < d; j++)
            s += row[j] * c[j];
        out[1 + i] = s;
    }
}

float ts__pix_roughness(int k, const float *t)
{
    int d = k * k, j;
    double mu = 0, s = 0;
    for (j = 0; j < d; j++)
        mu += t[j];
    mu /= d;
    for (j = 0; j < d; j++)
        s += (t[j] - mu) * (t[j] - mu);
    return (float)sqrt(s);
}

typedef struct eig_pair {
    double value;
    int index;
} eig_pair;

static int by_value_desc(const void *x, const void *y)
{
    const eig_pair *a = x, *b = y;
    return a->value < b->value   ? 1
           : a->value > b->value ? -1
                                 : (a->index > b->index) - (a->index < b->index);
}

/* Level l's principal directions: basis (m x k^2, rows) and m. */
static int level_basis(const ts_pixel_exemplars *ex, int l, double energy, float **basis, int *m)
{
    int k = ex->kl[l], d = k * k, sp = 1 << (ex->levels - l), e, i, j;
    double *cov = calloc((size_t)d * d, sizeof *cov), *sum = calloc((size_t)d, sizeof *sum);
    double *ev = malloc((size_t)d * sizeof *ev), *vec = malloc((size_t)d * d * sizeof *vec);
    float *t = malloc((size_t)d * sizeof *t);
    eig_pair *pairs = malloc((size_t)d * sizeof *pairs);
    double count = 0, tot = 0, acc = 0;
    int rc = -1, keep;
    *basis = NULL;
    *m = 0;
    if (!cov || !sum || !ev || !vec || !t || !pairs)
        goto done;
    for (e = 0; e < ex->n_given; e++) {
        const pix_stack *s = &ex->stacks[e];
        size_t n = s->n_usable[l], step = n / PIX_PCA_SAMPLES + 1, c;
        for (c = 0; c < n; c += step) {
            int32_t idx = s->usable_list[l][c];
            double mu = 0;
            gather(s->level[l], s->width, idx % s->width, idx / s->width, k, sp, t);
            for (j = 0; j < d; j++)
                mu += t[j];
            mu /= d;
            for (i = 0; i < d; i++) {
                double a = t[i] - mu;
                sum[i] += a;
                for (j = 0; j <= i; j++)
                    cov[i * d + j] += a * (t[j] - mu);
            }
            count++;
        }
    }
    if (count < 1)
        goto done;
    for (i = 0; i < d; i++)
        for (j = 0; j <= i; j++) {
            double c = (cov[i * d + j] - sum[i] * sum[j] / count) / count;
            cov[i * d + j] = cov[j * d + i] = c;
        }
    if (ts__pix_eigen(cov, d, ev, vec) != 0)
        goto done;
    for (i = 0; i < d; i++) {
        pairs[i].value = ev[i] > 0 ? ev[i] : 0;
        pairs[i].index = i;
        tot += pairs[i].value;
    }
    qsort(pairs, (size_t)d, sizeof *pairs, by_value_desc);
    if (energy >= 1)
        keep = d; /* every direction: the distance is the SSD */
    else
        for (keep = 0; keep < d && acc < energy * tot; keep++)
            acc += pairs[keep].value;
    *basis = malloc((size_t)(keep ? keep : 1) * d * sizeof **basis);
    if (!*basis)
        goto done;
    for (i = 0; i < keep; i++)
        for (j = 0; j < d; j++)
            (*basis)[(size_t)i * d + j] = (float)vec[j * d + pairs[i].index];
    *m = keep;
    rc = 0;
done:
    free(cov);
    free(sum);
    free(ev);
    free(vec);
    free(t);
    free(pairs);
    return rc;
}

typedef struct app_job {
    ts_pixel_exemplars *ex;
    double energy;
    int rows; /* rows per task */
    size_t per_level;
    int fail;
} app_job;

static void level_bases(void *arg, size_t begin, size_t end)
{
    app_job *j = arg;
    size_t l;
    for (l = begin; l < end; l++) {
        int m;
        if (level_basis(j->ex, (int)l, j->energy, &j->ex->basis[l], &m) != 0)
            j->fail = 1;
        else
            j->ex->dim[l] = 1 + m + (j->ex->rough > 0);
    }
}

/* Task t: exemplar e, level l, a band of rows: their cells' appearance
 * vectors, a row at a time (each principal direction a k x k correlation at
 * the level's spacing, summed over whole rows so the compiler vectorises
 * it); the same sums as ts__pix_appearance, in another order. */
static void project_rows(void *arg, size_t begin, size_t end)
{
    app_job *j = arg;
    ts_pixel_exemplars *ex = j->ex;
    int k = ex->window, r, d = k * k, maxw = 0, e; /* the widest window */
    float *acc, *mu;
    size_t task;
    for (e = 0; e < ex->n_given; e++)
        if (ex->stacks[e].width > maxw)
            maxw = ex->stacks[e].width;
    acc = malloc((size_t)maxw * (size_t)(d + 2) * sizeof *acc);
    if (!acc) {
        j->fail = 1;
        return;
    }
    mu = acc + (size_t)maxw * (size_t)(d + 1);
    for (task = begin; task < end; task++) {
        size_t per_stack = (size_t)(ex->levels + 1) * j->per_level;
        int l = (int)(task % per_stack / j->per_level), band = (int)(task % j->per_level);
        int sp = 1 << (ex->levels - l), dim = ex->dim[l], x, y, i, a, b;
        int m = dim - 1 - (ex->rough > 0); /* principal directions */
        k = ex->kl[l];
        r = k / 2;
        d = k * k;
        pix_stack *s = &ex->stacks[task / per_stack];
        int w = s->width, x0 = r * sp, x1 = w - r * sp, n = x1 - x0;
        const float *basis = ex->basis[l];
        for (y = band * j->rows; y < (band + 1) * j->rows && y < s->height; y++) {
            float *out = s->app[l] + (size_t)y * w * (size_t)dim;
            memset(out, 0, (size_t)w * (size_t)dim * sizeof *out);
            if (y < r * sp || y >= s->height - r * sp || n <= 0)
                continue;
            for (x = 0; x < n; x++)
                mu[x] = 0;
            for (b = -r; b <= r; b++)
                for (a = -r; a <= r; a++) {
                    const float *src = s->level[l] + (size_t)(y + b * sp) * w + x0 + a * sp;
                    for (x = 0; x < n; x++)
                        mu[x] += src[x];
                }
            for (x = 0; x < n; x++)
                mu[x] /= (float)d;
            for (i = 0; i < m; i++) {
                const float *row = basis + (size_t)i * d;
                float *ai = acc + (size_t)i * maxw;
                for (x = 0; x < n; x++)
                    ai[x] = 0;
                for (b = -r; b <= r; b++)
                    for (a = -r; a <= r; a++) {
                        const float *src = s->level[l] + (size_t)(y + b * sp) * w + x0 + a * sp;
                        float wt = row[(b + r) * k + a + r];
                        for (x = 0; x < n; x++) /* less the mean first: no cancellation */
                            ai[x] += wt * (src[x] - mu[x]);
                    }
            }
            if (ex->rough > 0) { /* the roughness: row m of acc (m <= k^2; mu is row k^2 + 1) */
                float *ai = acc + (size_t)m * maxw;
                for (x = 0; x < n; x++)
                    ai[x] = 0;
                for (b = -r; b <= r; b++)
                    for (a = -r; a <= r; a++) {
                        const float *src = s->level[l] + (size_t)(y + b * sp) * w + x0 + a * sp;
                        for (x = 0; x < n; x++)
                            ai[x] += (src[x] - mu[x]) * (src[x] - mu[x]);
                    }
                for (x = 0; x < n; x++)
                    ai[x] = ex->rough * sqrtf(ai[x]);
            }
            for (x = 0; x < n; x++) {
                float *o = out + (size_t)(x0 + x) * dim;
                o[0] = (float)k * mu[x];
                for (i = 0; i < dim - 1; i++)
                    o[1 + i] = acc[(size_t)i * maxw + x];
            }
        }
    }
    free(acc);
}

int ts__pix_appearance_build(const ts_ctx *ctx, ts_pixel_exemplars *ex, double energy)
{
    app_job j = {ex, energy, 32, 0, 0};
    int e, l, maxh = 0;
    ts__parallel_for(ctx, (size_t)ex->levels + 1, level_bases, &j);
    if (j.fail)
        return -1;
    for (e = 0; e < ex->n_given; e++) {
        pix_stack *s = &ex->stacks[e];
        if (!(s->app = calloc((size_t)ex->levels + 1, sizeof *s->app)))
            return -1;
        for (l = 0; l <= ex->levels; l++)
            if (!(s->app[l] = ts__malloc_array((size_t)s->width * (size_t)s->height,
                                               (size_t)ex->dim[l] * sizeof **s->app)))
                return -1;
        if (s->height > maxh)
            maxh = s->height;
    }
    j.per_level = ((size_t)maxh + (size_t)j.rows - 1) / (size_t)j.rows;
    ts__parallel_for(ctx, (size_t)ex->n_given * (size_t)(ex->levels + 1) * j.per_level,
                     project_rows, &j);
    return j.fail ? -1 : 0;
}
