/*
 * test_placement_queue.c - the grow fill's priority queue (placement_queue.c)
 * against the obviously correct order: a scan of every position for the
 * needed one with the most overlap, then nearest the centre, then the
 * lowest index (with `apart`: skipping those near it), after every one of
 * thousands of random changes of overlap and need.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "placement_queue.h"

/* The reference: the scan the fill used before the queue. */
static int scan_best(const ts__placement *pos, int n, int cx, int cy, int apart, int gap)
{
    int pick = -1, j;
    long best_d = 0;
    for (j = 0; j < n; j++) {
        long d;
        if (!pos[j].needed || j == apart)
            continue;
        if (apart >= 0 && abs(pos[j].x - pos[apart].x) < gap && abs(pos[j].y - pos[apart].y) < gap)
            continue;
        d = labs((long)pos[j].x - cx) + labs((long)pos[j].y - cy);
        if (pick < 0 || pos[j].overlap > pos[pick].overlap ||
            (pos[j].overlap == pos[pick].overlap && d < best_d)) {
            pick = j;
            best_d = d;
        }
    }
    return pick;
}

static int axis(int size, int P, int step, int *c)
{
    int n = 0, v;
    for (v = 0; v + P < size; v += step)
        c[n++] = v;
    c[n++] = size - P;
    return n;
}

static void run_case(uint64_t seed, int W, int H, int P, int step, int n_ops)
{
    int xs[512], ys[512], nx = axis(W, P, step, xs), ny = axis(H, P, step, ys), n = nx * ny;
    int cx = (W - P) / 2, cy = (H - P) / 2, k, bad = 0;
    ts__placement *pos = calloc((size_t)n, sizeof *pos);
    ts__pos_queue q;
    uint64_t s = seed;
    for (k = 0; k < n; k++) {
        pos[k].x = xs[k % nx];
        pos[k].y = ys[k / nx];
        /* few distinct overlaps and distances: many ties, the index decides */
        pos[k].overlap = (int)(th_rand(&s) % 5) * P;
        pos[k].needed = th_rand(&s) % 4 != 0;
    }
    CHECK(ts__queue_init(&q, pos, n, cx, cy) == 0);
    for (k = 0; k < n_ops && !bad; k++) {
        int j = (int)(th_rand(&s) % (uint64_t)n), best, ref, apart, a;
        switch (th_rand(&s) % 3) {
        case 0:
            pos[j].overlap = (int)(th_rand(&s) % 5) * P;
            break;
        case 1:
            pos[j].needed = !pos[j].needed;
            break;
        default:
            pos[j].overlap += P;
        }
        ts__queue_fix(&q, j);
        best = ts__queue_best(&q, xs, nx, ys, ny, -1, P + 4);
        ref = scan_best(pos, n, cx, cy, -1, P + 4);
        if (best != ref) {
            CHECK_MSG(best == ref, "op %d: queue %d, scan %d", k, best, ref);
            bad = 1;
        }
        apart = best >= 0 ? best : 0;
        a = ts__queue_best(&q, xs, nx, ys, ny, apart, P + 4);
        ref = scan_best(pos, n, cx, cy, apart, P + 4);
        if (a != ref) {
            CHECK_MSG(a == ref, "op %d: queue apart %d, scan %d", k, a, ref);
            bad = 1;
        }
        /* the look with apart leaves the queue as it was */
        CHECK(ts__queue_best(&q, xs, nx, ys, ny, -1, P + 4) == best);
    }
    {
        int m = 0;
        for (k = 0; k < n; k++)
            m += pos[k].needed;
        CHECK(q.n == m);
    }
    ts__queue_free(&q);
    free(pos);
}

static void test_against_scan(void)
{
    run_case(1, 300, 200, 16, 12, 4000);  /* overlap a quarter of the patch */
    run_case(2, 520, 130, 32, 16, 4000);  /* half */
    run_case(3, 64, 64, 16, 8, 2000);     /* few positions */
    run_case(4, 1000, 1000, 8, 4, 3000);  /* many, small patches: the box scan fallback */
}

/* A fill's whole run: drain the queue the way the fill does, best first,
 * neighbours' overlap raised, and compare the order with the scan's. */
static void test_drain_order(void)
{
    int xs[64], ys[64], P = 16, step = 12, nx = axis(200, P, step, xs), ny = axis(150, P, step, ys);
    int n = nx * ny, k, steps = 0, same = 1;
    ts__placement *a = calloc((size_t)n, sizeof *a), *b = calloc((size_t)n, sizeof *b);
    ts__pos_queue q;
    for (k = 0; k < n; k++) {
        a[k].x = b[k].x = xs[k % nx];
        a[k].y = b[k].y = ys[k / nx];
        a[k].needed = b[k].needed = 1;
    }
    CHECK(ts__queue_init(&q, a, n, (200 - P) / 2, (150 - P) / 2) == 0);
    for (;;) {
        int p = ts__queue_best(&q, xs, nx, ys, ny, -1, P + 4);
        int r = scan_best(b, n, (200 - P) / 2, (150 - P) / 2, -1, P + 4);
        same &= p == r;
        if (p < 0 || r < 0)
            break;
        for (k = 0; k < n; k++)
            if (abs(a[k].x - a[p].x) < P && abs(a[k].y - a[p].y) < P) {
                a[k].overlap += 10;
                b[k].overlap += 10;
                ts__queue_fix(&q, k);
            }
        a[p].needed = b[p].needed = 0;
        ts__queue_fix(&q, p);
        steps++;
    }
    CHECK_MSG(same, "the queue's order differs from the scan's");
    CHECK(steps == n);
    ts__queue_free(&q);
    free(a);
    free(b);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"against_scan", test_against_scan},
        {"drain_order", test_drain_order},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
