/*
 * fuzz_dictionary.c - libFuzzer target for the dictionary format: any bytes
 * as a dictionary must give a dictionary or a clean error, never a crash, a
 * leak or undefined behaviour; a dictionary that loads amplifies a small
 * input (every value read is used) and goes back to the same bytes.
 *
 * Build: tools/fuzz.sh dictionary (clang -fsanitize=fuzzer,address,undefined);
 * seeds: tests/fuzz/dictionary_corpus (made by tools/fuzz.sh from a small build).
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
    ts_dictionary *d = NULL;
    if (ctx && ts_dictionary_from_bytes(ctx, data, size, &d) == TS_OK) {
        unsigned char *again = NULL;
        size_t len = 0;
        int f = 0, p = 0, x, y;
        ts_amplify_params ap = ts_amplify_params_default();
        ts_raster in, out;
        ts_dictionary_shape(d, &f, &p);
        ap.factor = f;
        ap.patch = p;
        /* the bytes it loads from are the bytes it writes (version 3) */
        if (ts_dictionary_to_bytes(ctx, d, &again, &len) == TS_OK && data[8] == 3 &&
            (len != size || memcmp(again, data, len) != 0))
            abort();
        free(again);
        if (ts_raster_alloc(ctx, 2 * p, 2 * p, &in) == TS_OK) {
            if (ts_raster_alloc(ctx, 2 * p * f, 2 * p * f, &out) == TS_OK) {
                for (y = 0; y < 2 * p; y++)
                    for (x = 0; x < 2 * p; x++)
                        TS_PIX(&in, x, y) = (float)(100 + 3 * x + ((x * 7 + y * 13) % 11));
                (void)ts_amplify(ctx, &in, NULL, d, &ap, &out, NULL, NULL);
                ts_raster_free(&out);
            }
            ts_raster_free(&in);
        }
        ts_dictionary_free(d);
    }
    ts_ctx_free(ctx);
    return 0;
}
