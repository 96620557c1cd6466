/*
 * gaussian_stack.c - the exemplars' Gaussian stacks (Lefebvre and Hoppe
 * 2005, Cruz et al. section II.A): L + 1 levels of the exemplar's size,
 * level L the exemplar, level l blurred by a Gaussian of sigma 2^(L-l-1)
 * (half the spacing 2^(L-l) of the level's samples), nodata left out of
 * every average.  A coordinate is usable at a level when its k x k
 * neighbourhood at the level's spacing lies inside the exemplar on valid
 * cells: exemplar borders are kept by this safety margin, never by
 * wrapping.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pixel.h"

int ts__pix_blur(const float *in, int w, int h, double sigma, float *out)
{
    int r = (int)ceil(3.0 * sigma), x, y, i;
    double *kern, *tmp, *wt;
    if (!(sigma > 0)) {
        memcpy(out, in, (size_t)w * (size_t)h * sizeof *out);
        return 0;
    }
    kern = malloc((size_t)(2 * r + 1) * sizeof *kern);
    tmp = malloc((size_t)w * (size_t)h * sizeof *tmp);
    wt = malloc((size_t)w * (size_t)h * sizeof *wt);
    if (!kern || !tmp || !wt) {
        free(kern);
        free(tmp);
        free(wt);
        return -1;
    }
    for (i = -r; i <= r; i++)
        kern[i + r] = exp(-0.5 * i * i / (sigma * sigma));
    /* across: the weighted sum and the weights of the valid cells */
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double s = 0, sw = 0;
            for (i = -r; i <= r; i++) {
                int xx = x + i;
                float v;
                if (xx < 0 || xx >= w)
                    continue;
                v = in[(size_t)y * w + xx];
                if (isnan(v))
                    continue;
                s += kern[i + r] * v;
                sw += kern[i + r];
            }
            tmp[(size_t)y * w + x] = s;
            wt[(size_t)y * w + x] = sw;
        }
    /* down: both sums, then their ratio (NaN where the centre is nodata) */
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double s = 0, sw = 0;
            for (i = -r; i <= r; i++) {
                int yy = y + i;
                if (yy < 0 || yy >= h)
                    continue;
                s += kern[i + r] * tmp[(size_t)yy * w + x];
                sw += kern[i + r] * wt[(size_t)yy * w + x];
            }
            out[(size_t)y * w + x] =
                isnan(in[(size_t)y * w + x]) || !(sw > 0) ? NAN : (float)(s / sw);
        }
    free(kern);
    free(tmp);
    free(wt);
    return 0;
}

/* qsort context: level 0's heights (qsort has none; one build at a time per thread) */
static _Thread_local const float *sort_level;

static int by_height_cmp(const void *a, const void *b)
{
    int32_t i = *(const int32_t *)a, j = *(const int32_t *)b;
    float x = sort_level[i], y = sort_level[j];
    return x < y ? -1 : x > y ? 1 : (i > j) - (i < j);
}

void ts__pix_stack_free(pix_stack *s, int L)
{
    free(s->by_height);
    int l;
    for (l = 0; l <= L; l++) {
        if (s->level)
            free(s->level[l]);
        if (s->usable)
            free(s->usable[l]);
        if (s->usable_list)
            free(s->usable_list[l]);
        if (s->app)
            free(s->app[l]);
        if (s->sim)
            free(s->sim[l]);
    }
    free(s->app);
    free(s->sim);
    free(s->level);
    free(s->usable);
    free(s->usable_list);
    free(s->n_usable);
    memset(s, 0, sizeof *s);
}

int ts__pix_stack_alloc(const ts_raster *ex, int L, pix_stack *s)
{
    memset(s, 0, sizeof *s);
    s->width = ex->width;
    s->height = ex->height;
    s->level = calloc((size_t)L + 1, sizeof *s->level);
    s->usable = calloc((size_t)L + 1, sizeof *s->usable);
    s->usable_list = calloc((size_t)L + 1, sizeof *s->usable_list);
    s->n_usable = calloc((size_t)L + 1, sizeof *s->n_usable);
    if (!s->level || !s->usable || !s->usable_list || !s->n_usable) {
        ts__pix_stack_free(s, L);
        return -1;
    }
    return 0;
}

int ts__pix_stack_level(const ts_raster *ex, int L, int k, int l, pix_stack *s)
{
    int w = ex->width, h = ex->height, x, y, r = k / 2, sp = 1 << (L - l), a, b;
    float *base = ts__malloc_array((size_t)w * (size_t)h, sizeof *base);
    size_t n = 0;
    s->level[l] = ts__malloc_array((size_t)w * (size_t)h, sizeof **s->level);
    s->usable[l] = calloc((size_t)w * (size_t)h, 1);
    if (!base || !s->level[l] || !s->usable[l]) {
        free(base);
        return -1;
    }
    for (y = 0; y < h; y++)
        memcpy(base + (size_t)y * w, &TS_PIX(ex, 0, y), (size_t)w * sizeof *base);
    if (ts__pix_blur(base, w, h, l == L ? 0.0 : 0.5 * sp, s->level[l]) != 0) {
        free(base);
        return -1;
    }
    free(base);
    for (y = r * sp; y < h - r * sp; y++)
        for (x = r * sp; x < w - r * sp; x++) {
            int ok = 1;
            for (b = -r; b <= r && ok; b++)
                for (a = -r; a <= r; a++)
                    if (isnan(s->level[l][(size_t)(y + b * sp) * w + x + a * sp])) {
                        ok = 0;
                        break;
                    }
            s->usable[l][(size_t)y * w + x] = (unsigned char)ok;
            n += (size_t)ok;
        }
    s->n_usable[l] = n;
    s->usable_list[l] = ts__malloc_array(n ? n : 1, sizeof **s->usable_list);
    if (!s->usable_list[l])
        return -1;
    n = 0;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            if (s->usable[l][(size_t)y * w + x])
                s->usable_list[l][n++] = (int32_t)((size_t)y * w + x);
    return 0;
}

int ts__pix_stack_finish(pix_stack *s)
{
    /* level 0's usable cells by height: where a guide's coarsest heights are found */
    s->by_height = ts__malloc_array(s->n_usable[0] ? s->n_usable[0] : 1, sizeof *s->by_height);
    if (!s->by_height)
        return -1;
    memcpy(s->by_height, s->usable_list[0], s->n_usable[0] * sizeof *s->by_height);
    sort_level = s->level[0];
    qsort(s->by_height, s->n_usable[0], sizeof *s->by_height, by_height_cmp);
    return 0;
}

int ts__pix_stack_build(const ts_raster *ex, int L, int k, pix_stack *s)
{
    int l;
    if (ts__pix_stack_alloc(ex, L, s) != 0)
        return -1;
    for (l = 0; l <= L; l++)
        if (ts__pix_stack_level(ex, L, k, l, s) != 0) {
            ts__pix_stack_free(s, L);
            return -1;
        }
    if (ts__pix_stack_finish(s) != 0) {
        ts__pix_stack_free(s, L);
        return -1;
    }
    return 0;
}
