/*
 * context.c - the ts_ctx: errors, progress and cancel, seed, threads.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <time.h>

#include "internal.h"

TS_API const char *ts_version(void)
{
    return TS_VERSION_STRING; /* the project's version, from CMakeLists.txt */
}

TS_API const char *ts_status_str(ts_status status)
{
    switch (status) {
    case TS_OK:
        return "success";
    case TS_ERR_NOMEM:
        return "out of memory";
    case TS_ERR_ARG:
        return "invalid argument";
    case TS_ERR_SIZE:
        return "invalid size";
    case TS_ERR_CANCELLED:
        return "cancelled";
    case TS_ERR_NUMERIC:
        return "numerical failure";
    case TS_ERR_INTERNAL:
        return "internal error";
    }
    return "unknown status";
}

TS_API ts_ctx *ts_ctx_new(void)
{
    ts_ctx *ctx = calloc(1, sizeof *ctx);
    if (!ctx)
        return NULL;
    ctx->prog_lo = 0.0;
    ctx->prog_hi = 1.0;
    ctx->input = -1;
    atomic_init(&ctx->cancel_own, 0);
    ctx->cancel = &ctx->cancel_own;
    ts__pool_slot_init(&ctx->pool_own);
    ctx->pool = &ctx->pool_own;
    return ctx;
}

ts_ctx *ts__ctx_child(ts_ctx *parent)
{
    ts_ctx *c = ts_ctx_new();
    if (!c)
        return NULL;
    c->seed = parent->seed;
    c->threads = parent->threads;
    c->cancel = parent->cancel;
    c->pool = parent->pool;
    return c;
}

int ts__cancelled(const ts_ctx *ctx)
{
    return atomic_load(ctx->cancel) != 0;
}

void ts__cancel(ts_ctx *ctx)
{
    atomic_store(ctx->cancel, 1);
}

ts_status ts__check_cancel(ts_ctx *ctx)
{
    if (!atomic_load(ctx->cancel))
        return TS_OK;
    return ts__fail(ctx, TS_ERR_CANCELLED, "terrasynth", "cancelled by the caller");
}

TS_API void ts_ctx_free(ts_ctx *ctx)
{
    if (!ctx)
        return;
    ts__pool_slot_destroy(&ctx->pool_own);
    free(ctx);
}

TS_API void ts_ctx_set_progress(ts_ctx *ctx, ts_progress_fn fn, void *user)
{
    ctx->progress = fn;
    ctx->progress_user = user;
}

TS_API void ts_ctx_set_notice(ts_ctx *ctx, ts_notice_fn fn, void *user)
{
    ctx->notice = fn;
    ctx->notice_user = user;
}

void ts__notice(ts_ctx *ctx, const char *stage, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    if (!ctx->notice)
        return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    ctx->notice(stage, msg, ctx->notice_user);
}

TS_API void ts_ctx_get_progress(const ts_ctx *ctx, ts_progress_fn *fn, void **user)
{
    *fn = ctx->progress;
    *user = ctx->progress_user;
}

TS_API void ts_ctx_set_seed(ts_ctx *ctx, uint64_t seed)
{
    ctx->seed = seed;
}
TS_API uint64_t ts_ctx_seed(const ts_ctx *ctx)
{
    return ctx->seed;
}
TS_API void ts_ctx_set_threads(ts_ctx *ctx, int threads)
{
    ctx->threads = threads < 0 ? 0 : threads;
}
TS_API int ts_ctx_threads(const ts_ctx *ctx)
{
    return ctx->threads;
}
TS_API ts_status ts_ctx_status(const ts_ctx *ctx)
{
    return ctx->status;
}
TS_API const char *ts_ctx_message(const ts_ctx *ctx)
{
    return ctx->message;
}
TS_API int ts_ctx_failed_input(const ts_ctx *ctx)
{
    return ctx->status == TS_OK ? -1 : ctx->input;
}

void ts__clear(ts_ctx *ctx)
{
    ctx->status = TS_OK;
    ctx->message[0] = '\0';
    ctx->input = -1;
    /* a new call on a context of its own starts uncancelled; a worker's
     * context keeps obeying its parent */
    if (ctx->cancel == &ctx->cancel_own)
        atomic_store(&ctx->cancel_own, 0);
}

/* The message is formatted into a buffer of its own first: the arguments
 * may be the context's current message (a stage wrapping what a deeper one
 * said). */
static ts_status ctx_fail_v(ts_ctx *ctx, ts_status status, int input, const char *stage,
                            const char *fmt, va_list ap)
{
    char buf[sizeof ctx->message];
    int n = snprintf(buf, sizeof buf, "%s: ", stage);
    if (n >= 0 && (size_t)n < sizeof buf)
        vsnprintf(buf + n, sizeof buf - (size_t)n, fmt, ap);
    memcpy(ctx->message, buf, sizeof buf);
    ctx->status = status;
    ctx->input = input;
    return status;
}

ts_status ts__fail(ts_ctx *ctx, ts_status status, const char *stage, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    ctx_fail_v(ctx, status, ctx->status != TS_OK ? ctx->input : -1, stage, fmt, ap);
    va_end(ap);
    return status;
}

ts_status ts__fail_input(ts_ctx *ctx, ts_status status, int input, const char *stage,
                         const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    ctx_fail_v(ctx, status, input, stage, fmt, ap);
    va_end(ap);
    return status;
}

ts_status ts__progress(ts_ctx *ctx, double frac, const char *msg)
{
    double done;
    if (atomic_load(ctx->cancel))
        return ts__check_cancel(ctx);
    if (!ctx->progress)
        return TS_OK;
    if (frac < 0.0)
        frac = 0.0;
    if (frac > 1.0)
        frac = 1.0;
    done = ctx->prog_lo + frac * (ctx->prog_hi - ctx->prog_lo);
    if (!ctx->progress(done, msg, ctx->progress_user)) {
        atomic_store(ctx->cancel, 1); /* the workers stop too */
        return ts__fail(ctx, TS_ERR_CANCELLED, "terrasynth", "cancelled by the caller");
    }
    return TS_OK;
}

ts_progress_saved ts__progress_push(ts_ctx *ctx, double lo, double hi)
{
    ts_progress_saved s = {ctx->prog_lo, ctx->prog_hi};
    double span = ctx->prog_hi - ctx->prog_lo;
    ctx->prog_lo = s.lo + lo * span;
    ctx->prog_hi = s.lo + hi * span;
    return s;
}

void ts__progress_pop(ts_ctx *ctx, ts_progress_saved saved)
{
    ctx->prog_lo = saved.lo;
    ctx->prog_hi = saved.hi;
}

int ts__thread_count(const ts_ctx *ctx, size_t work_items)
{
    long n = ctx->threads;
    if (n <= 0) {
        n = sysconf(_SC_NPROCESSORS_ONLN);
        if (n < 1)
            n = 1;
    }
    if (n > 64)
        n = 64;
    if ((size_t)n > work_items)
        n = (long)(work_items ? work_items : 1);
    return (int)n;
}

void ts__parallel_for(const ts_ctx *ctx, size_t n, ts_range_fn fn, void *arg)
{
    if (n == 0)
        return;
    ts__pool_for(ctx->pool, ts__thread_count(ctx, n), n, fn, arg);
}

int ts__float_cmp(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

uint64_t ts__hash_words(uint64_t seed, const uint64_t *words, int n)
{
    uint64_t z = seed ^ 0x9e3779b97f4a7c15ull;
    int i;
    for (i = 0; i < n; i++) {
        z += words[i] * 0xbf58476d1ce4e5b9ull + 0x9e3779b97f4a7c15ull;
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        z ^= z >> 31;
    }
    return z;
}

void *ts__malloc_array(size_t n, size_t size)
{
    if (size && n > SIZE_MAX / size)
        return NULL;
    return malloc((n && size) ? n * size : 1);
}

void *ts__calloc_array(size_t n, size_t size)
{
    if (size && n > SIZE_MAX / size)
        return NULL;
    return calloc(n ? n : 1, size ? size : 1);
}

double ts__now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}
