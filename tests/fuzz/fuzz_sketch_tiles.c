/*
 * fuzz_sketch_tiles.c - libFuzzer target for a sketch in tiles as bytes (a
 * recipe's coarse pass file): any bytes must give a sketch in tiles or a
 * clean error, never a crash, a leak or undefined behaviour.  The input's
 * last 8 bytes are replaced by its checksum first, so the fuzzer reaches
 * the checks behind it (sizes, order, values); one that loads makes a
 * window and its ridges and goes back to the same bytes.
 *
 * Build: tools/fuzz.sh sketch_tiles (clang -fsanitize=fuzzer,address,undefined);
 * seeds: made by tools/fuzz.sh from small recipes.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "terrasynth.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_sketch_tiles *t = NULL;
    unsigned char *b = malloc(size + 1), *again = NULL;
    uint64_t key = 0;
    size_t len = 0;
    if (!ctx || !b) {
        ts_ctx_free(ctx);
        free(b);
        return 0;
    }
    memcpy(b, data, size);
    if (size >= 16) {
        uint64_t sum = ts_checksum(0, b, size - 8);
        int k;
        for (k = 0; k < 8; k++)
            b[size - 8 + k] = (unsigned char)(sum >> (8 * k));
    }
    if (ts_sketch_tiles_from_bytes(ctx, b, size, &key, &t) == TS_OK) {
        ts_raster w;
        unsigned char flags[16 * 16];
        /* the bytes it loads from are the bytes it writes */
        if (ts_sketch_tiles_to_bytes(ctx, t, key, &again, &len) == TS_OK &&
            (len != size || memcmp(again, b, len) != 0))
            abort();
        free(again);
        if (ts_raster_alloc(ctx, 16, 16, &w) == TS_OK) {
            (void)ts_sketch_tiles_window(ctx, t, 0, 0, &w, NULL);
            ts_raster_free(&w);
        }
        memset(flags, 0, sizeof flags);
        ts_sketch_tiles_ridges(t, 0, 0, 16, 16, flags, 1);
        ts_sketch_tiles_free(t);
    }
    free(b);
    ts_ctx_free(ctx);
    return 0;
}
