/*
 * test_streams.c - the stream network (stream_network.c) against its
 * definition: the flow and areas by naive_flow.h (relaxation, paths walked
 * cell by cell), the Strahler order by recursion up the inflows, the links
 * checked vertex by vertex; a hand-made confluence; any thread count.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "naive_flow.h"
#include "terrasynth.h"

/* The Strahler order of stream cell c by its definition: 1 with no stream
 * inflow, else the highest inflow order i, plus one when two or more
 * inflows have it (memoised in ord, 0 = not known). */
static int strahler(size_t c, size_t n, const long *to, const unsigned char *stream, int *ord)
{
    size_t k;
    int best = 0, nbest = 0;
    if (ord[c])
        return ord[c];
    for (k = 0; k < n; k++)
        if (stream[k] && to[k] == (long)c) {
            int o = strahler(k, n, to, stream, ord);
            if (o > best)
                best = o, nbest = 1;
            else if (o == best)
                nbest++;
        }
    ord[c] = best == 0 ? 1 : best + (nbest >= 2);
    return ord[c];
}

/* Check net against the definition on dem with threshold thr; 0 if equal. */
static int check_network(const ts_raster *dem, double thr, const ts_stream_network *net, int trial)
{
    int w = dem->width, h = dem->height, bad0 = th_checks_failed;
    size_t n = (size_t)w * h, c, i, k, heads = 0;
    float *area = malloc(n * sizeof *area);
    long *to = malloc(n * sizeof *to);
    unsigned char *stream = calloc(n, 1), *seen = calloc(n, 1);
    int *ord = calloc(n, sizeof *ord), *inflow = calloc(n, sizeof *inflow);
    naive_flow(dem, area, to);
    for (c = 0; c < n; c++)
        stream[c] = !isnan(area[c]) && area[c] >= thr;
    for (c = 0; c < n; c++)
        if (stream[c] && to[c] >= 0)
            inflow[to[c]]++;
    for (c = 0; c < n; c++)
        if (stream[c] && inflow[c] != 1 && to[c] >= 0)
            heads++; /* a head or a confluence that flows on starts a link */
    CHECK_MSG(net->n_links == heads, "trial %d: %zu links, %zu starts", trial, net->n_links, heads);
    for (i = 0; i < net->n_links && th_checks_failed == bad0; i++) {
        const ts_stream_link *L = &net->links[i];
        const ts_feature_vertex *v = &net->verts[L->first];
        size_t first = (size_t)v[0].y * w + v[0].x, last, own;
        CHECK_MSG(L->count >= 2, "trial %d link %zu: %zu vertices", trial, i, L->count);
        CHECK(stream[first] && inflow[first] != 1);
        if (i > 0) { /* in raster order of their first cells */
            const ts_feature_vertex *p = &net->verts[net->links[i - 1].first];
            CHECK((size_t)p->y * w + p->x < first);
        }
        CHECK_MSG(L->order == strahler(first, n, to, stream, ord), "trial %d link %zu: order %d",
                  trial, i, L->order);
        for (k = 0; k < L->count; k++) {
            c = (size_t)v[k].y * w + v[k].x;
            CHECK(stream[c]);
            CHECK(v[k].z == TS_PIX(dem, v[k].x, v[k].y));
            if (k + 1 < L->count) {
                CHECK_MSG(to[c] == (long)((size_t)v[k + 1].y * w + v[k + 1].x),
                          "trial %d link %zu vertex %zu: not the flow", trial, i, k);
                CHECK(strahler(c, n, to, stream, ord) == L->order);
                if (k > 0)
                    CHECK(inflow[c] == 1);
                CHECK(!seen[c]); /* each cell in one link (but for its last vertex) */
                seen[c] = 1;
            }
        }
        last = (size_t)v[L->count - 1].y * w + v[L->count - 1].x;
        CHECK(inflow[last] >= 2 || to[last] < 0);
        if (L->down >= 0) {
            const ts_feature_vertex *d = &net->verts[net->links[L->down].first];
            CHECK(inflow[last] >= 2 && to[last] >= 0);
            CHECK((size_t)d->y * w + d->x == last);
        } else {
            CHECK(to[last] < 0);
        }
        own = inflow[last] >= 2 ? (size_t)v[L->count - 2].y * w + v[L->count - 2].x : last;
        CHECK_MSG(L->area == area[own], "trial %d link %zu: area %g, naive %g", trial, i, L->area,
                  area[own]);
    }
    /* every stream cell that flows on lies on a link */
    for (c = 0; c < n; c++)
        if (stream[c] && to[c] >= 0 && !seen[c]) {
            CHECK_MSG(0, "trial %d: stream cell %zu on no link", trial, c);
            break;
        }
    free(area);
    free(to);
    free(stream);
    free(seen);
    free(ord);
    free(inflow);
    return th_checks_failed != bad0;
}

static int same_network(const ts_stream_network *a, const ts_stream_network *b)
{
    size_t i;
    if (a->n_links != b->n_links || a->n_verts != b->n_verts)
        return 0;
    for (i = 0; i < a->n_links; i++)
        if (a->links[i].first != b->links[i].first || a->links[i].count != b->links[i].count ||
            a->links[i].order != b->links[i].order || a->links[i].down != b->links[i].down ||
            a->links[i].area != b->links[i].area)
            return 0;
    return !memcmp(a->verts, b->verts, a->n_verts * sizeof *a->verts);
}

static void test_against_definition(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int trial;
    for (trial = 0; trial < 18; trial++) {
        uint64_t s = 900 + (uint64_t)trial;
        int w = 12 + trial % 7 * 5, h = 10 + trial % 5 * 6, x, y, th;
        double thr = trial % 3 == 0 ? 2 : trial % 3 == 1 ? 5 : 20;
        ts_stream_network *net = NULL, *other = NULL;
        ts_raster dem;
        CHECK(ts_raster_alloc(ctx, w, h, &dem) == TS_OK);
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                /* valleys with noise; quantised heights give flats, bowls depressions */
                double v =
                    4 * fabs(sin(x * 0.4)) + 0.5 * y + th_uniform(&s) * (trial % 2 ? 3 : 0.3);
                if (trial % 4 == 2)
                    v -=
                        8.0 * exp(-((x - w / 2.0) * (x - w / 2.0) + (y - h / 2.0) * (y - h / 2.0)) /
                                  (0.04 * w * w));
                TS_PIX(&dem, x, y) = (float)(trial % 3 == 1 ? (int)v : v);
            }
        if (trial % 5 == 3)
            TS_PIX(&dem, w / 2, h / 2) = NAN, TS_PIX(&dem, w / 3, h / 3) = NAN;
        ts_ctx_set_threads(ctx, 1);
        CHECK(ts_stream_network_extract(ctx, &dem, thr, &net) == TS_OK);
        if (net && check_network(&dem, thr, net, trial) == 0)
            for (th = 2; th <= 4; th++) {
                ts_ctx_set_threads(ctx, th);
                CHECK(ts_stream_network_extract(ctx, &dem, thr, &other) == TS_OK);
                CHECK_MSG(other && same_network(net, other), "trial %d: %d threads differ", trial,
                          th);
                ts_stream_network_free(other);
                other = NULL;
            }
        ts_stream_network_free(net);
        ts_raster_free(&dem);
    }
    ts_ctx_free(ctx);
}

/* Two straight valleys meeting in a third: two links of order 1 ending at
 * the confluence, one of order 2 from it to the grid's edge. */
static void test_confluence(void)
{
    ts_ctx *ctx = ts_ctx_new();
    int w = 41, h = 41, x, y;
    ts_stream_network *net = NULL;
    ts_raster dem;
    CHECK(ts_raster_alloc(ctx, w, h, &dem) == TS_OK);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            /* the trunk along x = 20 from y = 20 down to y = 40 (the bottom edge); the
             * branches from the corners (0, 0) and (40, 0) to (20, 20) */
            double across = y >= 20 ? fabs(x - 20.0)
                                    : fmin(fabs((double)(x - y)), fabs((double)(x - (40 - y))));
            TS_PIX(&dem, x, y) = (float)(100.0 - 2.0 * y + 3.0 * across);
        }
    CHECK(ts_stream_network_extract(ctx, &dem, 30, &net) == TS_OK);
    if (net) {
        size_t i, n1 = 0, n2 = 0;
        CHECK_MSG(net->n_links == 3, "%zu links", net->n_links);
        for (i = 0; i < net->n_links; i++) {
            const ts_stream_link *L = &net->links[i];
            const ts_feature_vertex *a = &net->verts[L->first], *b = a + L->count - 1;
            if (L->order == 1) {
                n1++;
                CHECK(b->x == 20 && b->y == 20 && L->down >= 0);
            } else if (L->order == 2) {
                n2++;
                CHECK(a->x == 20 && a->y == 20 && b->x == 20 && b->y == 40 && L->down == -1);
                CHECK(L->area >= 2 * 30);
            }
        }
        CHECK(n1 == 2 && n2 == 1);
        check_network(&dem, 30, net, -1);
    }
    ts_stream_network_free(net);
    /* a threshold below one cell is refused */
    CHECK(ts_stream_network_extract(ctx, &dem, 0.5, &net) == TS_ERR_ARG && !net);
    ts_raster_free(&dem);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"against_definition", test_against_definition},
        {"confluence", test_confluence},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
