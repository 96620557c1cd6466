/*
 * test_context.c - the context's errors (algorithms/src/context.c): a
 * stage may wrap the message a deeper stage left in the same context (the
 * arguments alias the message), the failing input is reported as a number,
 * not parsed back out of text, and a call that succeeds clears both.
 * Cancel: a worker's child context obeys its parent's cancel flag (and a
 * worker can raise it for all), a new call on the parent starts
 * uncancelled, and a PPA cancelled while its valley worker runs returns
 * "cancelled" with no leak or hang.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>

#include "harness.h"
#include "internal.h"
#include "terrasynth.h"

static void test_wrap_own_message(void)
{
    ts_ctx *ctx = ts_ctx_new();
    char longer[2000];
    ts_fail(ctx, TS_ERR_NUMERIC, "ppa", "every cell is nodata");
    ts_fail(ctx, TS_ERR_NUMERIC, "sketch", "PPA on the sketch: %s", ts_ctx_message(ctx));
    CHECK(strcmp(ts_ctx_message(ctx), "sketch: PPA on the sketch: ppa: every cell is nodata") == 0);
    CHECK(ts_ctx_status(ctx) == TS_ERR_NUMERIC);
    /* twice more, growing past the buffer: cut, still terminated */
    memset(longer, 'x', sizeof longer - 1);
    longer[sizeof longer - 1] = '\0';
    ts_fail(ctx, TS_ERR_ARG, "a", "%s", longer);
    ts_fail(ctx, TS_ERR_ARG, "b", "%s and %s", ts_ctx_message(ctx), ts_ctx_message(ctx));
    CHECK(strncmp(ts_ctx_message(ctx), "b: a: xxx", 9) == 0);
    CHECK(strlen(ts_ctx_message(ctx)) == 1023);
    ts_ctx_free(ctx);
}

static void test_failed_input(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex[2], out;
    ts_synth_params p = ts_synth_params_default();
    CHECK(ts_ctx_failed_input(ctx) == -1);
    /* the second exemplar is smaller than a patch: the synthesis names it */
    CHECK(ts_raster_alloc(ctx, 100, 100, &ex[0]) == TS_OK);
    CHECK(ts_raster_alloc(ctx, 20, 20, &ex[1]) == TS_OK);
    CHECK(ts_raster_alloc(ctx, 80, 80, &out) == TS_OK);
    {
        int i;
        for (i = 0; i < 100 * 100; i++)
            ex[0].data[i] = (float)(i % 37);
        for (i = 0; i < 20 * 20; i++)
            ex[1].data[i] = (float)(i % 11);
    }
    p.patch_size.value = 32;
    p.overlap.value = 8;
    CHECK(ts_synth_patches(ctx, ex, 2, &p, &out, NULL, NULL) == TS_ERR_SIZE);
    CHECK(ts_ctx_failed_input(ctx) == 1);
    CHECK(strstr(ts_ctx_message(ctx), "exemplar 2") != NULL);
    /* a wrapping stage keeps the input; a new call clears it */
    ts_fail(ctx, TS_ERR_SIZE, "job", "%s", "wrapped");
    CHECK(ts_ctx_failed_input(ctx) == 1);
    CHECK(ts_synth_patches(ctx, ex, 1, &p, &out, NULL, NULL) == TS_OK);
    CHECK(ts_ctx_failed_input(ctx) == -1);
    /* a failure about no input names none */
    ts_fail(ctx, TS_ERR_ARG, "x", "no input");
    CHECK(ts_ctx_failed_input(ctx) == -1);
    ts_raster_free(&ex[0]);
    ts_raster_free(&ex[1]);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

static void test_child_cancel(void)
{
    ts_ctx *parent = ts_ctx_new(), *a, *b;
    ts_ctx_set_seed(parent, 77);
    ts_ctx_set_threads(parent, 3);
    a = ts__ctx_child(parent);
    b = ts__ctx_child(parent);
    CHECK(a && b);
    CHECK(ts_ctx_seed(a) == 77);
    CHECK(!ts__cancelled(parent) && !ts__cancelled(a) && !ts__cancelled(b));
    CHECK(ts_progress(a, 0.5, "x") == TS_OK);
    /* one worker stops the others and the caller */
    ts__cancel(a);
    CHECK(ts__cancelled(parent) && ts__cancelled(b));
    CHECK(ts_progress(b, 0.5, "x") == TS_ERR_CANCELLED);
    CHECK(ts__check_cancel(parent) == TS_ERR_CANCELLED);
    CHECK(strstr(ts_ctx_message(parent), "cancelled") != NULL);
    /* a child's new call does not clear its parent's flag; the parent's does */
    ts_clear(b);
    CHECK(ts__cancelled(b));
    ts_clear(parent);
    CHECK(!ts__cancelled(parent) && !ts__cancelled(a) && !ts__cancelled(b));
    ts_ctx_free(a);
    ts_ctx_free(b);
    ts_ctx_free(parent);
}

static int stop_calls;
static int stop_at_second(double done, const char *msg, void *user)
{
    (void)done;
    (void)msg;
    (void)user;
    return ++stop_calls < 2;
}

static void test_ppa_cancel_with_worker(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster dem;
    ts_features *f = NULL;
    ts_ppa_params p = ts_ppa_params_default();
    int x, y, W = 400;
    CHECK(ts_raster_alloc(ctx, W, W, &dem) == TS_OK);
    for (y = 0; y < W; y++)
        for (x = 0; x < W; x++)
            dem.data[(size_t)y * W + x] = (float)(50.0 * sin(x * 0.07) * cos(y * 0.05) + 0.1 * x);
    p.features = TS_PPA_BOTH;
    ts_ctx_set_threads(ctx, 2);
    ts_ctx_set_progress(ctx, stop_at_second, NULL);
    stop_calls = 0;
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f) == TS_ERR_CANCELLED);
    CHECK(f == NULL);
    /* the same context works again: the flag was the call's */
    ts_ctx_set_progress(ctx, NULL, NULL);
    CHECK(ts_ppa_extract(ctx, &dem, NULL, &p, &f) == TS_OK);
    CHECK(f && f->n_paths > 0);
    ts_features_free(f);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"wrap_own_message", test_wrap_own_message},
        {"failed_input", test_failed_input},
        {"child_cancel", test_child_cancel},
        {"ppa_cancel_with_worker", test_ppa_cancel_with_worker},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
