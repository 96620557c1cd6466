/*
 * raster.c - float raster views: wrap, allocate, statistics; the sort of
 * float samples the statistics share.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "internal.h"

TS_API ts_raster ts_raster_wrap(float *data, int width, int height, ptrdiff_t stride)
{
    ts_raster r;
    r.width = width;
    r.height = height;
    r.stride = stride;
    r.data = data;
    return r;
}

TS_API ts_status ts_raster_alloc(ts_ctx *ctx, int width, int height, ts_raster *out)
{
    size_t n, i;
    ts__clear(ctx);
    out->data = NULL;
    out->width = out->height = 0;
    out->stride = 0;
    if (width <= 0 || height <= 0)
        return ts__fail(ctx, TS_ERR_SIZE, "raster", "size %d x %d is empty", width, height);
    if ((size_t)width > ((size_t)PTRDIFF_MAX / sizeof(float)) / (size_t)height)
        return ts__fail(ctx, TS_ERR_SIZE, "raster", "size %d x %d is too large", width, height);
    n = (size_t)width * (size_t)height;
    out->data = ts__malloc_array(n, sizeof(float));
    if (!out->data)
        return ts__fail(ctx, TS_ERR_NOMEM, "raster", "cannot allocate %d x %d cells", width,
                        height);
    for (i = 0; i < n; i++)
        out->data[i] = NAN;
    out->width = width;
    out->height = height;
    out->stride = width;
    return TS_OK;
}

TS_API void ts_raster_free(ts_raster *r)
{
    if (!r)
        return;
    free(r->data);
    r->data = NULL;
    r->width = r->height = 0;
    r->stride = 0;
}

TS_API ts_status ts_raster_stats_compute(ts_ctx *ctx, const ts_raster *r, ts_raster_stats *out)
{
    double sum = 0.0, sum2 = 0.0, mn = INFINITY, mx = -INFINITY, mean;
    size_t nv = 0, total;
    int x, y;
    ts__clear(ctx);
    if (!r || !r->data || r->width <= 0 || r->height <= 0)
        return ts__fail(ctx, TS_ERR_SIZE, "stats", "empty raster");
    for (y = 0; y < r->height; y++) {
        const float *row = r->data + (ptrdiff_t)y * r->stride;
        for (x = 0; x < r->width; x++) {
            float v = row[x];
            if (isnan(v))
                continue;
            nv++;
            sum += v;
            if (v < mn)
                mn = v;
            if (v > mx)
                mx = v;
        }
    }
    total = (size_t)r->width * (size_t)r->height;
    out->n_valid = nv;
    out->n_nodata = total - nv;
    if (nv == 0) {
        out->min = out->max = out->mean = out->stddev = NAN;
        return ts__fail(ctx, TS_ERR_NUMERIC, "stats", "every cell is nodata");
    }
    mean = sum / (double)nv;
    /* second pass for a stable variance */
    for (y = 0; y < r->height; y++) {
        const float *row = r->data + (ptrdiff_t)y * r->stride;
        for (x = 0; x < r->width; x++) {
            float v = row[x];
            if (!isnan(v))
                sum2 += (v - mean) * (v - mean);
        }
    }
    out->min = mn;
    out->max = mx;
    out->mean = mean;
    out->stddev = sqrt(sum2 / (double)nv);
    return TS_OK;
}

/* ---- sorting float samples ------------------------------------------ */

#define SORT_BITS 11
#define SORT_BUCKETS (1u << SORT_BITS)

/* An unsigned key in the floats' order: the sign bit flipped on positives,
 * every bit on negatives; -0 takes +0's key (they compare equal). */
static inline uint32_t sort_key(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    if (u == 0x80000000u)
        u = 0;
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

/* Least-significant-digit radix sort on the keys, three digits of 11, 11
 * and 10 bits: stable, so values that compare equal keep their order (as
 * a stable comparison sort leaves them), in 3 + 1 passes over the data. */
void ts__sort_floats(float *v, size_t n)
{
    size_t(*cnt)[SORT_BUCKETS];
    float *tmp, *src = v, *dst;
    size_t i;
    int d;
    if (n < 64) { /* insertion sort: stable */
        for (i = 1; i < n; i++) {
            float x = v[i];
            uint32_t k = sort_key(x);
            size_t j = i;
            for (; j > 0 && sort_key(v[j - 1]) > k; j--)
                v[j] = v[j - 1];
            v[j] = x;
        }
        return;
    }
    tmp = ts__malloc_array(n, sizeof *tmp);
    cnt = ts__calloc_array(3, sizeof *cnt);
    if (!tmp || !cnt) { /* a stable merge sort in glibc: the same order */
        free(tmp);
        free(cnt);
        qsort(v, n, sizeof *v, ts__float_cmp);
        return;
    }
    for (i = 0; i < n; i++) {
        uint32_t k = sort_key(v[i]);
        cnt[0][k & (SORT_BUCKETS - 1)]++;
        cnt[1][(k >> SORT_BITS) & (SORT_BUCKETS - 1)]++;
        cnt[2][k >> (2 * SORT_BITS)]++;
    }
    dst = tmp;
    for (d = 0; d < 3; d++) {
        size_t sum = 0, b, c;
        int shift = d * SORT_BITS;
        for (b = 0; b < SORT_BUCKETS; b++) {
            c = cnt[d][b];
            cnt[d][b] = sum;
            sum += c;
        }
        for (i = 0; i < n; i++) {
            uint32_t k = sort_key(src[i]) >> shift;
            dst[cnt[d][k & (SORT_BUCKETS - 1)]++] = src[i];
        }
        src = dst;
        dst = src == tmp ? v : tmp;
    }
    memcpy(v, src, n * sizeof *v); /* three passes: the result is in tmp */
    free(tmp);
    free(cnt);
}
