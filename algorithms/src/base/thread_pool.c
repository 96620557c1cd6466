/*
 * thread_pool.c - the worker threads of a context, started once and reused
 * by every ts__parallel_for of its calls (and of its workers' child
 * contexts), instead of a pthread_create and join per loop.
 *
 * A loop's chunks go on one queue; the calling thread runs the first chunk
 * and then helps with whatever is queued (its own chunks or anyone's)
 * until its loop is done.  Helping means a loop started inside a worker
 * (nested parallelism, or two callers sharing the pool, like the PPA's
 * ridge and valley threads) never waits on a thread that is itself
 * waiting: there is always someone running the queue.  Which thread runs a
 * chunk never changes the chunk, so results do not depend on it.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <pthread.h>
#include <stdlib.h>

#include "internal.h"

#define POOL_MAX 63 /* workers: with the caller, the 64 of ts__thread_count */

typedef struct pool_loop {
    int remaining; /* chunks not yet finished (under the pool's mutex) */
} pool_loop;

typedef struct pool_task {
    ts_range_fn fn;
    void *arg;
    size_t begin, end;
    pool_loop *loop;
    struct pool_task *next;
} pool_task;

struct ts__pool {
    pthread_mutex_t mu;
    pthread_cond_t work; /* a task was queued, or stop */
    pthread_cond_t done; /* a loop finished */
    pool_task *head, *tail;
    pthread_t tid[POOL_MAX];
    int n_workers;
    int stop;
};

/* Pop the first task (mutex held); NULL if none. */
static pool_task *pool_pop(ts__pool *p)
{
    pool_task *t = p->head;
    if (t) {
        p->head = t->next;
        if (!p->head)
            p->tail = NULL;
    }
    return t;
}

/* Run t without the mutex, then count it off (mutex held on entry and exit). */
static void pool_run_task(ts__pool *p, pool_task *t)
{
    pool_loop *loop = t->loop;
    pthread_mutex_unlock(&p->mu);
    t->fn(t->arg, t->begin, t->end);
    pthread_mutex_lock(&p->mu);
    if (--loop->remaining == 0)
        pthread_cond_broadcast(&p->done);
}

static void *pool_worker(void *arg)
{
    ts__pool *p = arg;
    pthread_mutex_lock(&p->mu);
    for (;;) {
        pool_task *t = pool_pop(p);
        if (t) {
            pool_run_task(p, t);
            continue;
        }
        if (p->stop)
            break;
        pthread_cond_wait(&p->work, &p->mu);
    }
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

static ts__pool *pool_new(void)
{
    ts__pool *p = calloc(1, sizeof *p);
    if (!p)
        return NULL;
    if (pthread_mutex_init(&p->mu, NULL) != 0) {
        free(p);
        return NULL;
    }
    if (pthread_cond_init(&p->work, NULL) != 0) {
        pthread_mutex_destroy(&p->mu);
        free(p);
        return NULL;
    }
    if (pthread_cond_init(&p->done, NULL) != 0) {
        pthread_cond_destroy(&p->work);
        pthread_mutex_destroy(&p->mu);
        free(p);
        return NULL;
    }
    return p;
}

/* Start workers until there are `want` (mutex held); fewer if the system
 * refuses threads, which only means the callers do more themselves. */
static void pool_grow(ts__pool *p, int want)
{
    if (want > POOL_MAX)
        want = POOL_MAX;
    while (p->n_workers < want && pthread_create(&p->tid[p->n_workers], NULL, pool_worker, p) == 0)
        p->n_workers++;
}

static void pool_free(ts__pool *p)
{
    int i;
    if (!p)
        return;
    pthread_mutex_lock(&p->mu);
    p->stop = 1;
    pthread_cond_broadcast(&p->work);
    pthread_mutex_unlock(&p->mu);
    for (i = 0; i < p->n_workers; i++)
        pthread_join(p->tid[i], NULL);
    pthread_cond_destroy(&p->done);
    pthread_cond_destroy(&p->work);
    pthread_mutex_destroy(&p->mu);
    free(p);
}

void ts__pool_slot_init(ts__pool_slot *slot)
{
    pthread_mutex_init(&slot->mu, NULL);
    slot->pool = NULL;
}

void ts__pool_slot_destroy(ts__pool_slot *slot)
{
    pool_free(slot->pool);
    slot->pool = NULL;
    pthread_mutex_destroy(&slot->mu);
}

int ts__pool_workers(ts__pool_slot *slot)
{
    int n = 0;
    pthread_mutex_lock(&slot->mu);
    if (slot->pool) {
        pthread_mutex_lock(&slot->pool->mu);
        n = slot->pool->n_workers;
        pthread_mutex_unlock(&slot->pool->mu);
    }
    pthread_mutex_unlock(&slot->mu);
    return n;
}

void ts__pool_for(ts__pool_slot *slot, int nt, size_t n, ts_range_fn fn, void *arg)
{
    pool_task tasks[64];
    pool_loop loop;
    ts__pool *p;
    int t;
    if (nt > 64)
        nt = 64;
    if (nt <= 1 || n <= 1) {
        fn(arg, 0, n);
        return;
    }
    /* the pool, started on first use */
    pthread_mutex_lock(&slot->mu);
    if (!slot->pool)
        slot->pool = pool_new();
    p = slot->pool;
    pthread_mutex_unlock(&slot->mu);
    if (!p) { /* no memory for a pool: in sequence, same result */
        fn(arg, 0, n);
        return;
    }
    for (t = 0; t < nt; t++) {
        tasks[t].fn = fn;
        tasks[t].arg = arg;
        tasks[t].begin = n * (size_t)t / (size_t)nt;
        tasks[t].end = n * (size_t)(t + 1) / (size_t)nt;
        tasks[t].loop = &loop;
        tasks[t].next = t + 1 < nt ? &tasks[t + 1] : NULL;
    }
    pthread_mutex_lock(&p->mu);
    pool_grow(p, nt - 1);
    loop.remaining = nt - 1;
    if (p->tail)
        p->tail->next = &tasks[1];
    else
        p->head = &tasks[1];
    p->tail = &tasks[nt - 1];
    pthread_cond_broadcast(&p->work);
    pthread_cond_broadcast(&p->done); /* callers waiting on their loops help too */
    pthread_mutex_unlock(&p->mu);
    /* the first chunk here, then help until every chunk of this loop is done */
    fn(arg, tasks[0].begin, tasks[0].end);
    pthread_mutex_lock(&p->mu);
    while (loop.remaining > 0) {
        pool_task *q = pool_pop(p);
        if (q)
            pool_run_task(p, q);
        else
            pthread_cond_wait(&p->done, &p->mu);
    }
    pthread_mutex_unlock(&p->mu);
}
