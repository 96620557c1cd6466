/*
 * dictionary_io.c - a dictionary as bytes, to be built once and reused: a
 * versioned, portable layout (little-endian whatever the machine), and a
 * reader that checks every size against the bytes it is given (a file is
 * untrusted data).  The core does no file I/O: the caller writes and reads
 * the bytes.
 *
 *   "TSDICT\r\n" (8 bytes), u32 version (3), u32 factor, u32 patch, u32 d,
 *   u32 hd, u64 n, u32 flags (bit 0: irradiance), u32 n_classes K,
 *   u32 n_layers L, then L names of TS_LAYER_NAME bytes (0-padded), then
 *   f32 dh[n*d], f32 du[n*d], f32 hh[n*hd], f64 a[n], f64 s[n],
 *   i32 exemplar[n], i32 x[n], i32 y[n], f32 dx[n*d] (context), then f32 dl[n*d] (with the
 *   irradiance), f32 dc[n*K] and u8 hc[n*hd] (with classes), f32 ll[n*L*hd], and (version 3)
 *   u64 FNV-1a of every byte before it: a changed or cut file is refused, not read.  Every
 *   value is checked too (finite, within 1e7: no terrain has more); version 2 (no checksum)
 *   is still read.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "amplify.h"

#define DICT_MAGIC "TSDICT\r\n"
#define DICT_VERSION 3u
#define DICT_SUM 8 /* the checksum's bytes */
#define DICT_HEADER 52

static size_t dict_bytes(uint64_t n, uint32_t d, uint32_t hd, int irr, uint32_t K, uint32_t L)
{
    return DICT_HEADER + (size_t)L * TS_LAYER_NAME +
           (size_t)n * ((size_t)d * 12 + (size_t)hd * 4 + 16 + 12 + (irr ? (size_t)d * 4 : 0) +
                        (size_t)K * 4 + (K ? (size_t)hd : 0) + (size_t)L * hd * 4);
}

TS_API ts_status ts_dictionary_to_bytes(ts_ctx *ctx, const ts_dictionary *dict,
                                        unsigned char **bytes, size_t *len)
{
    unsigned char *b, *p;
    size_t n, total;
    ts__clear(ctx);
    if (!dict || !bytes || !len)
        return ts__fail(ctx, TS_ERR_ARG, "dictionary", "missing dictionary or output");
    n = dict->n;
    total = dict_bytes(n, (uint32_t)dict->d, (uint32_t)dict->hd, dict->dl != NULL,
                       (uint32_t)dict->n_classes, (uint32_t)dict->n_layers) +
            DICT_SUM;
    b = malloc(total);
    if (!b)
        return ts__fail(ctx, TS_ERR_NOMEM, "dictionary", "out of memory (%zu bytes)", total);
    memcpy(b, DICT_MAGIC, 8);
    ts__put_u32(b + 8, DICT_VERSION);
    ts__put_u32(b + 12, (uint32_t)dict->factor);
    ts__put_u32(b + 16, (uint32_t)dict->patch);
    ts__put_u32(b + 20, (uint32_t)dict->d);
    ts__put_u32(b + 24, (uint32_t)dict->hd);
    ts__put_u64(b + 28, (uint64_t)n);
    ts__put_u32(b + 36, 0);
    ts__put_u32(b + 40, dict->dl ? 1u : 0u);
    ts__put_u32(b + 44, (uint32_t)dict->n_classes);
    ts__put_u32(b + 48, (uint32_t)dict->n_layers);
    p = b + DICT_HEADER;
    for (int l = 0; l < dict->n_layers; l++) {
        memset(p, 0, TS_LAYER_NAME);
        memcpy(p, dict->layer_names[l], strlen(dict->layer_names[l]));
        p += TS_LAYER_NAME;
    }
    ts__le_copy(p, dict->dh, n * dict->d, 4), p += n * dict->d * 4;
    ts__le_copy(p, dict->du, n * dict->d, 4), p += n * dict->d * 4;
    ts__le_copy(p, dict->hh, n * dict->hd, 4), p += n * dict->hd * 4;
    ts__le_copy(p, dict->a, n, 8), p += n * 8;
    ts__le_copy(p, dict->s, n, 8), p += n * 8;
    ts__le_copy(p, dict->exemplar, n, 4), p += n * 4;
    ts__le_copy(p, dict->x, n, 4), p += n * 4;
    ts__le_copy(p, dict->y, n, 4), p += n * 4;
    ts__le_copy(p, dict->dx, n * dict->d, 4), p += n * dict->d * 4;
    if (dict->dl)
        ts__le_copy(p, dict->dl, n * dict->d, 4), p += n * dict->d * 4;
    if (dict->n_classes) {
        ts__le_copy(p, dict->dc, n * dict->n_classes, 4), p += n * dict->n_classes * 4;
        memcpy(p, dict->hc, n * dict->hd), p += n * dict->hd;
    }
    if (dict->n_layers)
        ts__le_copy(p, dict->ll, n * dict->n_layers * dict->hd, 4);
    ts__put_u64(b + total - DICT_SUM, ts_checksum(0, b, total - DICT_SUM));
    *bytes = b;
    *len = total;
    return TS_OK;
}

/* Stored values no dictionary holds: the descriptors are unit vectors (or 0), so each
 * component lies within +-1; the fine heights are normalised, within +-1e7; a carried
 * layer may be NaN (no value there) but not infinite; indices and cells are not negative. */
static int floats_bad(const float *v, size_t n, float lim, int nan_ok)
{
    size_t i;
    for (i = 0; v && i < n; i++)
        if (!(v[i] >= -lim && v[i] <= lim) && !(nan_ok && isnan(v[i])))
            return 1;
    return 0;
}

static int dict_values_bad(const ts_dictionary *d)
{
    size_t n = d->n, k, dd = (size_t)d->d, hd = (size_t)d->hd;
    const float unit = 1.001f;
    if (floats_bad(d->dh, n * dd, unit, 0) || floats_bad(d->du, n * dd, unit, 0) ||
        floats_bad(d->dx, n * dd, unit, 0) || floats_bad(d->dl, n * dd, unit, 0) ||
        floats_bad(d->dc, n * (size_t)d->n_classes, unit, 0) ||
        floats_bad(d->hh, n * hd, 1e7f, 0) ||
        floats_bad(d->ll, n * (size_t)d->n_layers * hd, FLT_MAX, 1))
        return 1;
    for (k = 0; k < n; k++)
        if (d->exemplar[k] < 0 || d->x[k] < 0 || d->y[k] < 0)
            return 1;
    return 0;
}

TS_API ts_status ts_dictionary_from_bytes(ts_ctx *ctx, const unsigned char *bytes, size_t len,
                                          ts_dictionary **out)
{
    ts_dictionary *d;
    const unsigned char *p;
    uint32_t version, factor, patch, dd, hd, flags, K, L;
    uint64_t n;
    size_t k;
    int l;
    ts__clear(ctx);
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, "dictionary", "no output given");
    *out = NULL;
    if (bytes && len >= 8 && len < DICT_HEADER && !memcmp(bytes, DICT_MAGIC, 8))
        return ts__fail(ctx, TS_ERR_ARG, "dictionary",
                        "damaged: cut to %zu bytes (its header alone has %d)", len, DICT_HEADER);
    if (!bytes || len < DICT_HEADER || memcmp(bytes, DICT_MAGIC, 8) != 0)
        return ts__fail(ctx, TS_ERR_ARG, "dictionary", "not a TerraSynth dictionary");
    version = ts__get_u32(bytes + 8);
    if (version != DICT_VERSION && version != 2)
        return ts__fail(ctx, TS_ERR_ARG, "dictionary",
                        "version %u; this TerraSynth reads versions 2 and %u", version,
                        DICT_VERSION);
    if (version == DICT_VERSION) {
        if (len < DICT_HEADER + DICT_SUM)
            return ts__fail(ctx, TS_ERR_ARG, "dictionary", "damaged: cut to %zu bytes", len);
        if (ts_checksum(0, bytes, len - DICT_SUM) != ts__get_u64(bytes + len - DICT_SUM))
            return ts__fail(ctx, TS_ERR_ARG, "dictionary",
                            "damaged: its checksum does not match its %zu bytes (changed or "
                            "cut after it was built): build it again",
                            len);
        len -= DICT_SUM;
    }
    factor = ts__get_u32(bytes + 12);
    patch = ts__get_u32(bytes + 16);
    dd = ts__get_u32(bytes + 20);
    hd = ts__get_u32(bytes + 24);
    n = ts__get_u64(bytes + 28);
    flags = ts__get_u32(bytes + 40);
    K = ts__get_u32(bytes + 44);
    L = ts__get_u32(bytes + 48);
    if (factor < 2 || factor > 16 || patch < 4 || patch > 64 || dd != patch * patch ||
        hd != dd * factor * factor || n < 1 || n > ((uint64_t)1 << 31) || flags > 1 ||
        K > TS_MAX_CLASSES || L > TS_MAX_LAYERS || dict_bytes(n, dd, hd, (int)flags, K, L) != len)
        return ts__fail(ctx, TS_ERR_ARG, "dictionary",
                        "damaged: its header (factor %u, patch %u, %llu atoms) does not match "
                        "its %zu bytes",
                        factor, patch, (unsigned long long)n, len);
    d = calloc(1, sizeof *d);
    if (!d)
        return ts__fail(ctx, TS_ERR_NOMEM, "dictionary", "out of memory");
    d->factor = (int)factor;
    d->patch = (int)patch;
    d->d = (int)dd;
    d->hd = (int)hd;
    d->n = (size_t)n;
    d->n_classes = (int)K;
    d->n_layers = (int)L;
    p = bytes + DICT_HEADER;
    for (l = 0; l < (int)L; l++, p += TS_LAYER_NAME) {
        memcpy(d->layer_names[l], p, TS_LAYER_NAME);
        if (d->layer_names[l][TS_LAYER_NAME - 1] != 0 || !d->layer_names[l][0] ||
            d->layer_names[l][strspn(d->layer_names[l], "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmn"
                                                        "opqrstuvwxyz0123456789_-")] != 0) {
            ts_dictionary_free(d);
            return ts__fail(ctx, TS_ERR_ARG, "dictionary", "damaged: layer %d has no name", l + 1);
        }
    }
    if (flags & 1)
        d->dl = ts__malloc_array(d->n * dd, 4);
    if (K) {
        d->dc = ts__malloc_array(d->n * K, 4);
        d->hc = ts__malloc_array(d->n * hd, 1);
    }
    if (L)
        d->ll = ts__malloc_array(d->n * L * hd, 4);
    d->dh = ts__malloc_array(d->n * dd, 4);
    d->dx = ts__malloc_array(d->n * dd, 4);
    d->du = ts__malloc_array(d->n * dd, 4);
    d->hh = ts__malloc_array(d->n * hd, 4);
    d->a = ts__malloc_array(d->n, 8);
    d->s = ts__malloc_array(d->n, 8);
    d->exemplar = ts__malloc_array(d->n, 4);
    d->x = ts__malloc_array(d->n, 4);
    d->y = ts__malloc_array(d->n, 4);
    if (!d->dh || !d->du || !d->hh || !d->a || !d->s || !d->exemplar || !d->x || !d->y || !d->dx ||
        ((flags & 1) && !d->dl) || (K && (!d->dc || !d->hc)) || (L && !d->ll)) {
        ts_dictionary_free(d);
        return ts__fail(ctx, TS_ERR_NOMEM, "dictionary", "out of memory for %zu atoms", d->n);
    }
    ts__le_copy((unsigned char *)d->dh, p, d->n * dd, 4), p += d->n * dd * 4;
    ts__le_copy((unsigned char *)d->du, p, d->n * dd, 4), p += d->n * dd * 4;
    ts__le_copy((unsigned char *)d->hh, p, d->n * hd, 4), p += d->n * hd * 4;
    ts__le_copy((unsigned char *)d->a, p, d->n, 8), p += d->n * 8;
    ts__le_copy((unsigned char *)d->s, p, d->n, 8), p += d->n * 8;
    ts__le_copy((unsigned char *)d->exemplar, p, d->n, 4), p += d->n * 4;
    ts__le_copy((unsigned char *)d->x, p, d->n, 4), p += d->n * 4;
    ts__le_copy((unsigned char *)d->y, p, d->n, 4), p += d->n * 4;
    ts__le_copy((unsigned char *)d->dx, p, d->n * dd, 4), p += d->n * dd * 4;
    if (d->dl)
        ts__le_copy((unsigned char *)d->dl, p, d->n * dd, 4), p += d->n * dd * 4;
    if (K) {
        ts__le_copy((unsigned char *)d->dc, p, d->n * K, 4), p += d->n * K * 4;
        memcpy(d->hc, p, d->n * hd), p += d->n * hd;
        for (k = 0; k < d->n * hd; k++)
            if (d->hc[k] > K) {
                ts_dictionary_free(d);
                return ts__fail(ctx, TS_ERR_ARG, "dictionary", "damaged: a class code past %u", K);
            }
    }
    if (L)
        ts__le_copy((unsigned char *)d->ll, p, d->n * L * hd, 4);
    if (dict_values_bad(d)) {
        ts_dictionary_free(d);
        return ts__fail(ctx, TS_ERR_ARG, "dictionary",
                        "damaged: a value no dictionary holds (not a number, infinite, or "
                        "out of its range)");
    }
    /* what matching relies on: finite descriptors, a positive deviation */
    for (k = 0; k < d->n; k++)
        if (!(d->s[k] > 0) || !(d->a[k] == d->a[k]) || d->a[k] > 1e7 || d->a[k] < -1e7 ||
            d->s[k] > 1e7) {
            ts_dictionary_free(d);
            return ts__fail(ctx, TS_ERR_ARG, "dictionary",
                            "damaged: atom %zu has no usable "
                            "altitude or deviation",
                            k);
        }
    if (ts__dict_sort(d) != 0) {
        ts_dictionary_free(d);
        return ts__fail(ctx, TS_ERR_NOMEM, "dictionary", "out of memory");
    }
    *out = d;
    return TS_OK;
}

TS_API void ts_dictionary_shape(const ts_dictionary *dict, int *factor, int *patch)
{
    *factor = dict ? dict->factor : 0;
    *patch = dict ? dict->patch : 0;
}
