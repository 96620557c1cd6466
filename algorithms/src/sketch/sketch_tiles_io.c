/*
 * sketch_tiles_io.c - a sketch in tiles as bytes (a TerraSynth addition):
 * laid out once, its windows served later by any process.  A versioned,
 * portable layout (little-endian whatever the machine), read back only
 * after every size and value is checked (a file is untrusted data).  The
 * core does no file I/O: the caller writes and reads the bytes.
 *
 *   "TSKETCH\n" (8 bytes), u32 version (1), u32 K, u32 W, u32 H, u64 key,
 *   u64 n_runs, u64 n_ridges, u64 dict_len, then the output's nodata as
 *   n_runs (u64 first cell, u64 cells) ascending and apart, the ridge cells
 *   as n_ridges u64 ascending, the coarse pass as f32[ceil(W/K) *
 *   ceil(H/K)] (finite or NaN), the dictionary's bytes (ts_dictionary_to_bytes;
 *   none when K = 1), and u64 FNV-1a of every byte before it.  The coarse
 *   pass's drainage area is recomputed, not stored.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "sketch_amplify.h"

#define ST_MAGIC "TSKETCH\n"
#define ST_VERSION 1u
#define ST_HEADER 56
#define ST_SUM 8
#define ST_MAX_K 16
#define ST_MAX_SIDE (1 << 22) /* cells: far past any grid a machine holds */

/* The runs of the output's nodata cells (NULL, 0 when none). */
static size_t st_runs(const ts_sketch_tiles *t, unsigned char *to)
{
    size_t n = (size_t)t->W * (size_t)t->H, i = 0, k = 0;
    while (t->nodata && i < n) {
        size_t a;
        for (; i < n && !t->nodata[i]; i++)
            ;
        if (i == n)
            break;
        for (a = i; i < n && t->nodata[i]; i++)
            ;
        if (to) {
            ts__put_u64(to + 16 * k, a);
            ts__put_u64(to + 16 * k + 8, i - a);
        }
        k++;
    }
    return k;
}

TS_API ts_status ts_sketch_tiles_to_bytes(ts_ctx *ctx, const ts_sketch_tiles *t, uint64_t key,
                                          unsigned char **bytes, size_t *len)
{
    unsigned char *dict = NULL, *b, *p;
    size_t dict_len = 0, n_runs, n_coarse, total, i;
    ts__clear(ctx);
    if (!t || !bytes || !len)
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles", "missing sketch in tiles or output");
    *bytes = NULL;
    *len = 0;
    if (t->dict && ts_dictionary_to_bytes(ctx, t->dict, &dict, &dict_len) != TS_OK)
        return ts_ctx_status(ctx);
    n_runs = st_runs(t, NULL);
    n_coarse = (size_t)t->coarse.width * (size_t)t->coarse.height;
    total = ST_HEADER + 16 * n_runs + 8 * t->n_ridges + 4 * n_coarse + dict_len + ST_SUM;
    if (!(b = malloc(total))) {
        free(dict);
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory (%zu bytes)", total);
    }
    memcpy(b, ST_MAGIC, 8);
    ts__put_u32(b + 8, ST_VERSION);
    ts__put_u32(b + 12, (uint32_t)t->K);
    ts__put_u32(b + 16, (uint32_t)t->W);
    ts__put_u32(b + 20, (uint32_t)t->H);
    ts__put_u64(b + 24, key);
    ts__put_u64(b + 32, n_runs);
    ts__put_u64(b + 40, t->n_ridges);
    ts__put_u64(b + 48, dict_len);
    p = b + ST_HEADER;
    st_runs(t, p);
    p += 16 * n_runs;
    for (i = 0; i < t->n_ridges; i++, p += 8)
        ts__put_u64(p, t->ridges[i]);
    for (i = 0; i < (size_t)t->coarse.height; i++, p += 4 * (size_t)t->coarse.width)
        ts__le_copy(p, t->coarse.data + i * (size_t)t->coarse.stride, (size_t)t->coarse.width, 4);
    if (dict_len)
        memcpy(p, dict, dict_len);
    free(dict);
    ts__put_u64(b + total - ST_SUM, ts_checksum(0, b, total - ST_SUM));
    *bytes = b;
    *len = total;
    return TS_OK;
}

/* The header's sizes against len; 0 when they add up. */
static int st_sizes_bad(const unsigned char *b, size_t len, uint32_t *K, uint32_t *W, uint32_t *H,
                        uint64_t *n_runs, uint64_t *n_ridges, uint64_t *dict_len)
{
    uint64_t w, h, left = len - ST_HEADER - ST_SUM;
    *K = ts__get_u32(b + 12);
    *W = ts__get_u32(b + 16);
    *H = ts__get_u32(b + 20);
    *n_runs = ts__get_u64(b + 32);
    *n_ridges = ts__get_u64(b + 40);
    *dict_len = ts__get_u64(b + 48);
    if (*K < 1 || *K > ST_MAX_K || *W < 1 || *H < 1 || *W > ST_MAX_SIDE || *H > ST_MAX_SIDE ||
        (*K == 1) != (*dict_len == 0))
        return 1;
    w = (*W + *K - 1) / *K;
    h = (*H + *K - 1) / *K;
    if (*n_runs > left / 16 || *n_ridges > left / 8 || w * h > left / 4 || *dict_len > left)
        return 1;
    return 16 * *n_runs + 8 * *n_ridges + 4 * w * h + *dict_len != left;
}

/* The nodata runs and ridge cells at p, checked and kept. */
static ts_status st_read_cells(ts_ctx *ctx, ts_sketch_tiles *t, const unsigned char *p,
                               uint64_t n_runs)
{
    uint64_t n = (uint64_t)t->W * (uint64_t)t->H, end = 0, k;
    if (n_runs && !(t->nodata = ts__calloc_array((size_t)n, 1)))
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    for (k = 0; k < n_runs; k++, p += 16) {
        uint64_t a = ts__get_u64(p), c = ts__get_u64(p + 8);
        if (a < end || (k && a == end) || c < 1 || c > n || a > n - c)
            return ts__fail(ctx, TS_ERR_ARG, "sketch tiles",
                            "damaged: nodata run %llu is off the grid or out of order",
                            (unsigned long long)k);
        memset(t->nodata + a, 1, (size_t)c);
        end = a + c;
    }
    if (t->n_ridges && !(t->ridges = ts__malloc_array(t->n_ridges, sizeof *t->ridges)))
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    for (k = 0; k < t->n_ridges; k++, p += 8) {
        t->ridges[k] = ts__get_u64(p);
        if (t->ridges[k] >= n || (k && t->ridges[k] <= t->ridges[k - 1]))
            return ts__fail(ctx, TS_ERR_ARG, "sketch tiles",
                            "damaged: ridge cell %llu is off the grid or out of order",
                            (unsigned long long)k);
    }
    return TS_OK;
}

/* The coarse pass at p, every value finite (within 1e7 m) or NaN. */
static ts_status st_read_coarse(ts_ctx *ctx, ts_sketch_tiles *t, const unsigned char *p)
{
    int w = (t->W + t->K - 1) / t->K, h = (t->H + t->K - 1) / t->K, y, x;
    ts_status st = ts_raster_alloc(ctx, w, h, &t->coarse);
    for (y = 0; st == TS_OK && y < h; y++, p += 4 * (size_t)w) {
        float *row = t->coarse.data + (size_t)y * (size_t)t->coarse.stride;
        ts__le_copy((unsigned char *)row, p, (size_t)w, 4);
        for (x = 0; x < w; x++)
            if (!isnan(row[x]) && !(row[x] >= -1e7f && row[x] <= 1e7f))
                return ts__fail(ctx, TS_ERR_ARG, "sketch tiles",
                                "damaged: coarse cell (%d, %d) holds %g", x, y, (double)row[x]);
    }
    return st;
}

TS_API ts_status ts_sketch_tiles_from_bytes(ts_ctx *ctx, const unsigned char *bytes, size_t len,
                                            uint64_t *key, ts_sketch_tiles **out)
{
    ts_sketch_tiles *t;
    uint32_t K, W, H;
    uint64_t n_runs, n_ridges, dict_len;
    const unsigned char *p;
    ts_status st;
    ts__clear(ctx);
    if (!bytes || !out)
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles", "missing bytes or output");
    *out = NULL;
    if (len < 8 || memcmp(bytes, ST_MAGIC, 8) != 0)
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles", "not a sketch in tiles");
    if (len < ST_HEADER + ST_SUM)
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles", "damaged: cut to %zu bytes", len);
    if (ts__get_u32(bytes + 8) != ST_VERSION)
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles", "version %u, this library reads %u",
                        ts__get_u32(bytes + 8), ST_VERSION);
    if (ts_checksum(0, bytes, len - ST_SUM) != ts__get_u64(bytes + len - ST_SUM))
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles",
                        "damaged: its checksum does not match its %zu bytes (changed or cut)", len);
    if (st_sizes_bad(bytes, len, &K, &W, &H, &n_runs, &n_ridges, &dict_len))
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles", "damaged: its sizes do not add up");
    if (!(t = calloc(1, sizeof *t)))
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    t->K = (int)K;
    t->W = (int)W;
    t->H = (int)H;
    t->n_ridges = (size_t)n_ridges;
    p = bytes + ST_HEADER;
    st = st_read_cells(ctx, t, p, n_runs);
    p += 16 * n_runs + 8 * n_ridges;
    if (st == TS_OK)
        st = st_read_coarse(ctx, t, p);
    p += 4 * (size_t)t->coarse.width * (size_t)t->coarse.height;
    if (st == TS_OK && dict_len) {
        int factor, patch;
        if ((st = ts_dictionary_from_bytes(ctx, p, (size_t)dict_len, &t->dict)) == TS_OK) {
            ts_dictionary_shape(t->dict, &factor, &patch);
            if (factor != t->K)
                st = ts__fail(ctx, TS_ERR_ARG, "sketch tiles",
                              "damaged: a dictionary for x %d in a sketch laid out %d x coarser",
                              factor, t->K);
        }
    }
    if (st == TS_OK)
        st = ts__sketch_tiles_guide(ctx, t);
    if (st != TS_OK) {
        ts_sketch_tiles_free(t);
        return st;
    }
    if (key)
        *key = ts__get_u64(bytes + 24);
    *out = t;
    return TS_OK;
}
