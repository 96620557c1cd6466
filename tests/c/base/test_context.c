/*
 * test_context.c - the context's errors (algorithms/src/base/context.c): a
 * stage may wrap the message a deeper stage left in the same context (the
 * arguments alias the message), the failing input is reported as a number,
 * not parsed back out of text, and a call that succeeds clears both.
 * Cancel: a worker's child context obeys its parent's cancel flag (and a
 * worker can raise it for all), a new call on the parent starts
 * uncancelled, and a PPA cancelled while its valley worker runs returns
 * "cancelled" with no leak or hang.
 * Thread pool: every index is run exactly once, nested loops and loops
 * from several threads sharing one pool finish, and the workers are
 * started once, not per loop.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>

#include "harness.h"
#include "internal.h"
#include "terrasynth.h"

static void test_wrap_own_message(void)
{
    ts_ctx *ctx = ts_ctx_new();
    char longer[2000];
    ts__fail(ctx, TS_ERR_NUMERIC, "ppa", "every cell is nodata");
    ts__fail(ctx, TS_ERR_NUMERIC, "sketch", "PPA on the sketch: %s", ts_ctx_message(ctx));
    CHECK(strcmp(ts_ctx_message(ctx), "sketch: PPA on the sketch: ppa: every cell is nodata") == 0);
    CHECK(ts_ctx_status(ctx) == TS_ERR_NUMERIC);
    /* twice more, growing past the buffer: cut, still terminated */
    memset(longer, 'x', sizeof longer - 1);
    longer[sizeof longer - 1] = '\0';
    ts__fail(ctx, TS_ERR_ARG, "a", "%s", longer);
    ts__fail(ctx, TS_ERR_ARG, "b", "%s and %s", ts_ctx_message(ctx), ts_ctx_message(ctx));
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
    CHECK(ts_synth_patches(ctx, ex, 2, &p, NULL, &out, NULL) == TS_ERR_SIZE);
    CHECK(ts_ctx_failed_input(ctx) == 1);
    CHECK(strstr(ts_ctx_message(ctx), "exemplar 2") != NULL);
    /* a wrapping stage keeps the input; a new call clears it */
    ts__fail(ctx, TS_ERR_SIZE, "job", "%s", "wrapped");
    CHECK(ts_ctx_failed_input(ctx) == 1);
    CHECK(ts_synth_patches(ctx, ex, 1, &p, NULL, &out, NULL) == TS_OK);
    CHECK(ts_ctx_failed_input(ctx) == -1);
    /* a failure about no input names none */
    ts__fail(ctx, TS_ERR_ARG, "x", "no input");
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
    CHECK(ts__progress(a, 0.5, "x") == TS_OK);
    /* one worker stops the others and the caller */
    ts__cancel(a);
    CHECK(ts__cancelled(parent) && ts__cancelled(b));
    CHECK(ts__progress(b, 0.5, "x") == TS_ERR_CANCELLED);
    CHECK(ts__check_cancel(parent) == TS_ERR_CANCELLED);
    CHECK(strstr(ts_ctx_message(parent), "cancelled") != NULL);
    /* a child's new call does not clear its parent's flag; the parent's does */
    ts__clear(b);
    CHECK(ts__cancelled(b));
    ts__clear(parent);
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

typedef struct count_job {
    atomic_int *hits;
    const ts_ctx *ctx; /* for a nested loop, or NULL */
} count_job;

static void count_range(void *arg, size_t b, size_t e)
{
    count_job *j = arg;
    size_t i;
    for (i = b; i < e; i++)
        atomic_fetch_add(&j->hits[i], 1);
}

/* each index runs a nested loop over 50 indices of its own row */
static void nested_range(void *arg, size_t b, size_t e)
{
    count_job *j = arg;
    size_t i;
    for (i = b; i < e; i++) {
        count_job inner = {j->hits + 50 * i, NULL};
        ts__parallel_for(j->ctx, 50, count_range, &inner);
    }
}

typedef struct caller_job {
    ts_ctx *ctx;
    atomic_int *hits;
    int ok;
} caller_job;

static void *caller_run(void *arg)
{
    caller_job *c = arg;
    int round, i;
    c->ok = 1;
    for (round = 0; round < 200; round++) {
        count_job j = {c->hits, NULL};
        for (i = 0; i < 1000; i++)
            atomic_store(&c->hits[i], 0);
        ts__parallel_for(c->ctx, 1000, count_range, &j);
        for (i = 0; i < 1000; i++)
            c->ok &= atomic_load(&c->hits[i]) == 1;
    }
    return NULL;
}

static void test_thread_pool(void)
{
    ts_ctx *ctx = ts_ctx_new();
    static atomic_int hits[40 * 50];
    size_t i;
    int round, ok = 1, workers;
    ts_ctx_set_threads(ctx, 4);
    CHECK(ts__pool_workers(ctx->pool) == 0); /* started on first use */
    for (round = 0; round < 300; round++) {
        count_job j = {hits, NULL};
        size_t n = 1 + (size_t)round % 37;
        for (i = 0; i < n; i++)
            atomic_store(&hits[i], 0);
        ts__parallel_for(ctx, n, count_range, &j);
        for (i = 0; i < n; i++)
            ok &= atomic_load(&hits[i]) == 1;
    }
    CHECK(ok);
    workers = ts__pool_workers(ctx->pool);
    CHECK(workers == 3); /* the caller is the fourth; none started per loop */
    /* nested loops, 40 x 50 */
    {
        count_job j = {hits, ctx};
        for (i = 0; i < 40 * 50; i++)
            atomic_store(&hits[i], 0);
        ts__parallel_for(ctx, 40, nested_range, &j);
        ok = 1;
        for (i = 0; i < 40 * 50; i++)
            ok &= atomic_load(&hits[i]) == 1;
        CHECK(ok);
    }
    /* two threads with child contexts share the parent's pool */
    {
        static atomic_int ha[1000], hb[1000];
        caller_job a = {ts__ctx_child(ctx), ha, 0}, b = {ts__ctx_child(ctx), hb, 0};
        pthread_t ta, tb;
        CHECK(pthread_create(&ta, NULL, caller_run, &a) == 0);
        CHECK(pthread_create(&tb, NULL, caller_run, &b) == 0);
        pthread_join(ta, NULL);
        pthread_join(tb, NULL);
        CHECK(a.ok && b.ok);
        CHECK(ts__pool_workers(a.ctx->pool) == workers);
        ts_ctx_free(a.ctx);
        ts_ctx_free(b.ctx);
    }
    /* more threads grow the pool; one thread runs on the caller */
    ts_ctx_set_threads(ctx, 6);
    {
        count_job j = {hits, NULL};
        for (i = 0; i < 100; i++)
            atomic_store(&hits[i], 0);
        ts__parallel_for(ctx, 100, count_range, &j);
        CHECK(ts__pool_workers(ctx->pool) == 5);
    }
    ts_ctx_free(ctx); /* joins the workers (ASan/TSan would see them leak) */
}

/* The reference order: by ts__float_cmp, equal values by their index (a
 * stable sort, spelled out). */
typedef struct sort_ref {
    float v;
    size_t i;
} sort_ref;

static int sort_ref_cmp(const void *a, const void *b)
{
    const sort_ref *x = a, *y = b;
    int c = ts__float_cmp(&x->v, &y->v);
    return c ? c : (x->i > y->i) - (x->i < y->i);
}

static void test_sort_floats(void)
{
    static const size_t sizes[] = {0, 1, 2, 5, 63, 64, 65, 300, 4097, 100000};
    static const float specials[] = {0.0f, -0.0f, INFINITY, -INFINITY, 1e-40f, -1e-40f,
                                     FLT_MAX, -FLT_MAX, 1.0f, -1.0f};
    uint64_t rng = 12345;
    size_t k, i;
    for (k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        int round;
        for (round = 0; round < 3; round++) {
            size_t n = sizes[k];
            float *v = malloc((n ? n : 1) * sizeof *v), *w = malloc((n ? n : 1) * sizeof *w);
            sort_ref *r = malloc((n ? n : 1) * sizeof *r);
            for (i = 0; i < n; i++) {
                double u = th_uniform(&rng);
                /* round 0: wide values; 1: few distinct ones (ties); 2: specials mixed in */
                v[i] = round == 0   ? (float)((u - 0.5) * pow(10.0, 40.0 * th_uniform(&rng) - 20.0))
                       : round == 1 ? (float)floor(u * 7.0) - 3.0f
                                    : (u < 0.3 ? specials[(size_t)(u * 33.3) % 10] : (float)(u - 0.6));
                r[i].v = v[i];
                r[i].i = i;
            }
            qsort(r, n, sizeof *r, sort_ref_cmp);
            for (i = 0; i < n; i++)
                w[i] = r[i].v;
            ts__sort_floats(v, n);
            CHECK_MSG(n == 0 || memcmp(v, w, n * sizeof *v) == 0, "n %zu round %d", n, round);
            free(v);
            free(w);
            free(r);
        }
    }
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"wrap_own_message", test_wrap_own_message},
        {"failed_input", test_failed_input},
        {"child_cancel", test_child_cancel},
        {"ppa_cancel_with_worker", test_ppa_cancel_with_worker},
        {"thread_pool", test_thread_pool},
        {"sort_floats", test_sort_floats},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
