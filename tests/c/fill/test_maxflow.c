/*
 * test_maxflow.c - the Boykov-Kolmogorov max-flow of maxflow.c against
 * oracles: hand-computed cuts, a brute-force minimum cut over all 2^n
 * labellings of tiny random graphs (with zero and infinite capacities), a
 * dense Edmonds-Karp on medium graphs, and max-flow/min-cut duality plus
 * timing on large grids.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <time.h>

#include "harness.h"
#include "maxflow.h"

/* ---- a graph as plain data, shared by the solver and the oracles ---- */

typedef struct tg_edge {
    int a, b;
    double cab, cba;
} tg_edge;

typedef struct test_graph {
    int n, n_edges;
    double *src, *snk;
    tg_edge *edges;
} test_graph;

static test_graph tg_new(int n, int max_edges)
{
    test_graph g;
    g.n = n;
    g.n_edges = 0;
    g.src = calloc((size_t)n + 1, sizeof *g.src);
    g.snk = calloc((size_t)n + 1, sizeof *g.snk);
    g.edges = calloc((size_t)max_edges + 1, sizeof *g.edges);
    if (!g.src || !g.snk || !g.edges)
        abort();
    return g;
}

static void tg_free(test_graph *g)
{
    free(g->src);
    free(g->snk);
    free(g->edges);
}

static void tg_edge_add(test_graph *g, int a, int b, double cab, double cba)
{
    tg_edge *e = &g->edges[g->n_edges++];
    e->a = a;
    e->b = b;
    e->cab = cab;
    e->cba = cba;
}

/* Capacity of the cut given by sink_side (1 = sink side, 0 = source side). */
static double tg_cut_cost(const test_graph *g, const unsigned char *sink_side)
{
    double c = 0.0;
    int i;
    for (i = 0; i < g->n; i++)
        c += sink_side[i] ? g->src[i] : g->snk[i];
    for (i = 0; i < g->n_edges; i++) {
        const tg_edge *e = &g->edges[i];
        if (!sink_side[e->a] && sink_side[e->b])
            c += e->cab;
        if (!sink_side[e->b] && sink_side[e->a])
            c += e->cba;
    }
    return c;
}

/* The oracle for tiny graphs: the minimum over all 2^n labellings. */
static double tg_brute_min_cut(const test_graph *g)
{
    unsigned char side[16];
    double best = INFINITY;
    unsigned long m, n_lab = 1ul << g->n;
    int i;
    for (m = 0; m < n_lab; m++) {
        double c;
        for (i = 0; i < g->n; i++)
            side[i] = (unsigned char)((m >> i) & 1u);
        c = tg_cut_cost(g, side);
        if (c < best)
            best = c;
    }
    return best;
}

/* The oracle for medium graphs: Edmonds-Karp on a dense matrix, node n is
 * the source and n+1 the sink. */
static double tg_edmonds_karp(const test_graph *g)
{
    int n = g->n + 2, s = g->n, t = g->n + 1, i, head, tail;
    double *cap = calloc((size_t)n * (size_t)n, sizeof *cap), flow = 0.0;
    int *prev = malloc((size_t)n * sizeof *prev), *queue = malloc((size_t)n * sizeof *queue);
    if (!cap || !prev || !queue)
        abort();
    for (i = 0; i < g->n; i++) {
        cap[s * n + i] += g->src[i];
        cap[i * n + t] += g->snk[i];
    }
    for (i = 0; i < g->n_edges; i++) {
        const tg_edge *e = &g->edges[i];
        cap[e->a * n + e->b] += e->cab;
        cap[e->b * n + e->a] += e->cba;
    }
    for (;;) {
        double b = INFINITY;
        int v;
        for (i = 0; i < n; i++)
            prev[i] = -1;
        prev[s] = s;
        queue[0] = s;
        head = 0;
        tail = 1;
        while (head < tail && prev[t] < 0) {
            int u = queue[head++];
            for (v = 0; v < n; v++)
                if (prev[v] < 0 && cap[u * n + v] > 0) {
                    prev[v] = u;
                    queue[tail++] = v;
                }
        }
        if (prev[t] < 0)
            break;
        for (v = t; v != s; v = prev[v])
            if (cap[prev[v] * n + v] < b)
                b = cap[prev[v] * n + v];
        for (v = t; v != s; v = prev[v]) {
            cap[prev[v] * n + v] -= b;
            cap[v * n + prev[v]] += b;
        }
        flow += b;
    }
    free(cap);
    free(prev);
    free(queue);
    return flow;
}

/* Solve with maxflow.c; side (may be NULL) receives ts__maxflow_is_sink. */
static double tg_solve(const test_graph *g, unsigned char *side)
{
    ts_maxflow *mf = ts__maxflow_new((size_t)g->n, (size_t)g->n_edges);
    double flow = NAN;
    int i;
    CHECK(mf != NULL);
    if (!mf)
        return NAN;
    for (i = 0; i < g->n; i++)
        CHECK(ts__maxflow_add_tweights(mf, (size_t)i, g->src[i], g->snk[i]) == 0);
    for (i = 0; i < g->n_edges; i++) {
        const tg_edge *e = &g->edges[i];
        CHECK(ts__maxflow_add_edge(mf, (size_t)e->a, (size_t)e->b, e->cab, e->cba) == 0);
    }
    CHECK(ts__maxflow_solve(mf, &flow) == 0);
    if (side)
        for (i = 0; i < g->n; i++)
            side[i] = (unsigned char)ts__maxflow_is_sink(mf, (size_t)i);
    ts__maxflow_free(mf);
    return flow;
}

static int close_rel(double a, double b)
{
    if (isinf(a) || isinf(b))
        return a == b;
    return fabs(a - b) <= 1e-9 * fmax(1.0, fmax(fabs(a), fabs(b)));
}

/* A random capacity: often zero, sometimes an integer (ties), else real. */
static double rand_cap(uint64_t *rng, double p_zero)
{
    double u = th_uniform(rng);
    if (u < p_zero)
        return 0.0;
    if (th_uniform(rng) < 0.3)
        return (double)(1 + th_rand(rng) % 5);
    return 10.0 * th_uniform(rng);
}

/* Random graph: n nodes, each ordered pair present with probability
 * density (parallel edges and one-way edges included).  p_inf: chance of
 * an infinite terminal capacity, never on both terminals of one node;
 * arc_inf: chance of an infinite arc capacity. */
static test_graph random_graph(uint64_t *rng, int n, double density, double p_inf, double arc_inf)
{
    test_graph g = tg_new(n, n * n + 4);
    int i, j;
    for (i = 0; i < n; i++) {
        g.src[i] = rand_cap(rng, 0.4);
        g.snk[i] = rand_cap(rng, 0.4);
        if (th_uniform(rng) < p_inf) {
            if (th_rand(rng) & 1)
                g.src[i] = INFINITY;
            else
                g.snk[i] = INFINITY;
        }
    }
    for (i = 0; i < n; i++)
        for (j = i + 1; j < n; j++) {
            double cab, cba;
            if (th_uniform(rng) >= density)
                continue;
            cab = rand_cap(rng, 0.2); /* one call per statement: a fixed draw order */
            cba = rand_cap(rng, 0.4);
            tg_edge_add(&g, i, j, cab, cba);
            if (th_uniform(rng) < arc_inf)
                g.edges[g.n_edges - 1].cab = INFINITY;
        }
    /* a few parallel edges */
    for (i = 0; i < 3 && n >= 2; i++) {
        int a = (int)(th_rand(rng) % (uint64_t)n), b = (int)(th_rand(rng) % (uint64_t)n);
        double cab = rand_cap(rng, 0.3), cba = rand_cap(rng, 0.3);
        if (a != b)
            tg_edge_add(&g, a, b, cab, cba);
    }
    return g;
}

/* flow == brute-force minimum, and the labelling's cut equals the flow */
static void check_against_brute(const test_graph *g, uint64_t seed)
{
    unsigned char side[16];
    double flow = tg_solve(g, side), best = tg_brute_min_cut(g);
    CHECK_MSG(close_rel(flow, best), "seed %llu n %d: flow %.17g, brute-force cut %.17g",
              (unsigned long long)seed, g->n, flow, best);
    if (isfinite(best))
        CHECK_MSG(close_rel(tg_cut_cost(g, side), flow),
                  "seed %llu: labelling cuts %.17g, flow %.17g", (unsigned long long)seed,
                  tg_cut_cost(g, side), flow);
}

/* ---- hand-computed cases ---- */

static void test_chain(void)
{
    /* S -5-> 0 -3-> 1 -4-> 2 -6-> T: the 0->1 arc is the cut */
    test_graph g = tg_new(3, 2);
    unsigned char side[3];
    g.src[0] = 5;
    g.snk[2] = 6;
    tg_edge_add(&g, 0, 1, 3, 100);
    tg_edge_add(&g, 1, 2, 4, 0);
    CHECK_NEAR(tg_solve(&g, side), 3.0, 0);
    CHECK(side[0] == 0 && side[1] == 1 && side[2] == 1);
    /* arcs that only point backwards carry nothing */
    g.edges[0].cab = 0;
    CHECK_NEAR(tg_solve(&g, side), 0.0, 0);
    tg_free(&g);
}

static void test_diamond(void)
{
    /* a: source 3, sink 2; b: source 2, sink 3; a->b 1.  Flow 5 saturates
     * both source links (a->T 2, a->b->T 1, b->T 2). */
    test_graph g = tg_new(2, 1);
    unsigned char side[2];
    g.src[0] = 3;
    g.snk[0] = 2;
    g.src[1] = 2;
    g.snk[1] = 3;
    tg_edge_add(&g, 0, 1, 1, 0);
    CHECK_NEAR(tg_solve(&g, side), 5.0, 0);
    CHECK(side[0] == 1 && side[1] == 1);
    tg_free(&g);
}

static void test_needs_flow_cancellation(void)
{
    /* sources a(0), b(1), sinks c(2), d(3); a->c, a->d, b->c, each 1.
     * A first path a->c must be undone through c->a for b: flow 2. */
    test_graph g = tg_new(4, 3);
    unsigned char side[4];
    g.src[0] = g.src[1] = 1;
    g.snk[2] = g.snk[3] = 1;
    tg_edge_add(&g, 0, 2, 1, 0);
    tg_edge_add(&g, 0, 3, 1, 0);
    tg_edge_add(&g, 1, 2, 1, 0);
    CHECK_NEAR(tg_solve(&g, side), 2.0, 0);
    CHECK_NEAR(tg_cut_cost(&g, side), 2.0, 0);
    tg_free(&g);
}

static void test_tweights_accumulate(void)
{
    ts_maxflow *mf = ts__maxflow_new(2, 1);
    double flow = -1;
    /* node 0: source 5 + 0, sink 3 + 4 -> min(5, 7) = 5 straight through */
    CHECK(ts__maxflow_add_tweights(mf, 0, 5, 3) == 0);
    CHECK(ts__maxflow_add_tweights(mf, 0, 0, 4) == 0);
    /* node 1: source 2, sink 0; edge 1->0 of 10 adds 2 more via node 0's sink */
    CHECK(ts__maxflow_add_tweights(mf, 1, 2, 0) == 0);
    CHECK(ts__maxflow_add_edge(mf, 1, 0, 10, 0) == 0);
    CHECK(ts__maxflow_solve(mf, &flow) == 0);
    CHECK_NEAR(flow, 7.0, 0);
    CHECK(ts__maxflow_is_sink(mf, 0) == 1 && ts__maxflow_is_sink(mf, 1) == 1);
    /* a second call only reports */
    flow = -1;
    CHECK(ts__maxflow_solve(mf, &flow) == 0);
    CHECK_NEAR(flow, 7.0, 0);
    CHECK(ts__maxflow_add_edge(mf, 0, 1, 1, 1) == -1);
    ts__maxflow_free(mf);
}

static void test_empty_and_isolated(void)
{
    ts_maxflow *mf = ts__maxflow_new(0, 0);
    double flow = -1;
    CHECK(mf != NULL);
    CHECK(ts__maxflow_solve(mf, &flow) == 0 && flow == 0.0);
    ts__maxflow_free(mf);
    mf = ts__maxflow_new(3, 0);
    CHECK(ts__maxflow_add_edge(mf, 0, 1, 2, 2) == 0);
    CHECK(ts__maxflow_add_edge(mf, 2, 2, 5, 5) == 0); /* self-loop: ignored */
    CHECK(ts__maxflow_add_tweights(mf, 2, 4, 0) == 0);
    CHECK(ts__maxflow_solve(mf, &flow) == 0 && flow == 0.0);
    /* reachable from the source: node 2 only; the rest is the sink side */
    CHECK(ts__maxflow_is_sink(mf, 0) == 1 && ts__maxflow_is_sink(mf, 1) == 1);
    CHECK(ts__maxflow_is_sink(mf, 2) == 0);
    ts__maxflow_free(mf);
}

static void test_bad_arguments(void)
{
    ts_maxflow *mf = ts__maxflow_new(2, 0);
    CHECK(ts__maxflow_add_tweights(mf, 2, 1, 1) == -1);
    CHECK(ts__maxflow_add_tweights(mf, 0, -1, 1) == -1);
    CHECK(ts__maxflow_add_tweights(mf, 0, 1, NAN) == -1);
    CHECK(ts__maxflow_add_edge(mf, 0, 5, 1, 1) == -1);
    CHECK(ts__maxflow_add_edge(mf, 0, 1, -0.5, 1) == -1);
    CHECK(ts__maxflow_add_edge(mf, 0, 1, 1, NAN) == -1);
    ts__maxflow_free(mf);
    ts__maxflow_free(NULL);
    CHECK(ts__maxflow_new((size_t)UINT32_MAX, 0) == NULL);
}

/* ---- infinite capacities ---- */

static void test_infinite_hand(void)
{
    test_graph g = tg_new(3, 2);
    unsigned char side[3];
    /* S -inf-> 0 -4-> 1 -inf-> 2 -inf-> T: finite cut 4 */
    g.src[0] = INFINITY;
    g.snk[2] = INFINITY;
    tg_edge_add(&g, 0, 1, 4, 0);
    tg_edge_add(&g, 1, 2, INFINITY, 0);
    CHECK_NEAR(tg_solve(&g, side), 4.0, 0);
    CHECK(side[0] == 0 && side[1] == 1 && side[2] == 1);
    /* an infinite path: every cut is infinite */
    g.edges[0].cab = INFINITY;
    CHECK(isinf(tg_solve(&g, NULL)));
    tg_free(&g);

    /* one node tied to both terminals by infinite links */
    g = tg_new(1, 0);
    g.src[0] = g.snk[0] = INFINITY;
    CHECK(isinf(tg_solve(&g, NULL)));
    /* infinite on one side, finite on the other: the finite one is the cut */
    g.snk[0] = 2.5;
    CHECK_NEAR(tg_solve(&g, side), 2.5, 0);
    CHECK(side[0] == 0);
    tg_free(&g);
}

static void test_brute_force_random(void)
{
    static const double densities[] = {0.1, 0.3, 0.6, 1.0};
    uint64_t seed;
    for (seed = 1; seed <= 800; seed++) {
        uint64_t rng = seed * 7919u;
        int n = 1 + (int)(th_rand(&rng) % 12);
        test_graph g = random_graph(&rng, n, densities[seed % 4], 0.0, 0.0);
        check_against_brute(&g, seed);
        tg_free(&g);
    }
}

static void test_brute_force_infinite(void)
{
    static const double densities[] = {0.2, 0.5, 0.9};
    uint64_t seed;
    int n_finite = 0, n_infinite = 0;
    for (seed = 1; seed <= 500; seed++) {
        uint64_t rng = seed * 104729u + 17u;
        int n = 2 + (int)(th_rand(&rng) % 11);
        /* infinite terminal links only: a finite cut always exists.  Every
         * third graph also has infinite arcs: the cut may then be infinite. */
        test_graph g = random_graph(&rng, n, densities[seed % 3], 0.3, seed % 3 == 0 ? 0.5 : 0.0);
        double best = tg_brute_min_cut(&g);
        if (seed % 3 != 0)
            CHECK(isfinite(best));
        if (isfinite(best))
            n_finite++;
        else
            n_infinite++;
        check_against_brute(&g, seed);
        tg_free(&g);
    }
    CHECK_MSG(n_finite > 300 && n_infinite > 10, "finite %d, infinite %d", n_finite, n_infinite);
    printf("     %d graphs with a finite cut, %d with none\n", n_finite, n_infinite);
}

static void test_edmonds_karp_medium(void)
{
    uint64_t seed;
    for (seed = 1; seed <= 60; seed++) {
        uint64_t rng = seed * 31337u;
        int n = 30 + (int)(th_rand(&rng) % 120);
        double density = 3.0 / n + 0.1 * th_uniform(&rng);
        test_graph g = random_graph(&rng, n, density, 0.0, 0.0);
        unsigned char *side = malloc((size_t)n);
        double flow = tg_solve(&g, side), ref = tg_edmonds_karp(&g);
        CHECK_MSG(close_rel(flow, ref), "seed %llu n %d: flow %.17g, Edmonds-Karp %.17g",
                  (unsigned long long)seed, n, flow, ref);
        CHECK(close_rel(tg_cut_cost(&g, side), flow));
        free(side);
        tg_free(&g);
    }
}

/* ---- large graphs: duality, determinism, timing ---- */

static double now_seconds(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A w x h 4-connected grid with random capacities: terminal links of
 * either sign, neighbour links in both directions. */
static test_graph grid_graph(int w, int h, uint64_t seed)
{
    test_graph g = tg_new(w * h, 2 * w * h);
    uint64_t rng = seed;
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            int i = y * w + x;
            double r = 20.0 * th_uniform(&rng) - 10.0, c[4];
            int k;
            for (k = 0; k < 4; k++)
                c[k] = 8.0 * th_uniform(&rng);
            g.src[i] = r > 0 ? r : 0.0;
            g.snk[i] = r < 0 ? -r : 0.0;
            if (x + 1 < w)
                tg_edge_add(&g, i, i + 1, c[0], c[1]);
            if (y + 1 < h)
                tg_edge_add(&g, i, i + w, c[2], c[3]);
        }
    return g;
}

static void run_grid(int w, int h)
{
    test_graph g = grid_graph(w, h, 42u + (uint64_t)w);
    unsigned char *side = malloc((size_t)g.n), *side2 = malloc((size_t)g.n);
    double t0, t1, flow, flow2, cut;
    t0 = now_seconds();
    flow = tg_solve(&g, side);
    t1 = now_seconds();
    cut = tg_cut_cost(&g, side);
    CHECK_MSG(close_rel(cut, flow), "%dx%d grid: flow %.17g, cut %.17g", w, h, flow, cut);
    CHECK(flow > 0);
    flow2 = tg_solve(&g, side2);
    CHECK(flow2 == flow && memcmp(side, side2, (size_t)g.n) == 0);
    printf("     %dx%d grid: flow %.6f, build+solve %.2f ms\n", w, h, flow, 1e3 * (t1 - t0));
    free(side);
    free(side2);
    tg_free(&g);
}

static void test_grid_200(void)
{
    run_grid(200, 200);
}

static void test_grid_300(void)
{
    run_grid(300, 300);
}

static void test_long_chain(void)
{
    /* a 200000-node path: very deep trees; the flow is the smallest link */
    int n = 200000, i;
    test_graph g = tg_new(n, n);
    uint64_t rng = 99;
    double smallest;
    unsigned char *side = malloc((size_t)n);
    g.src[0] = 1000.0;
    g.snk[n - 1] = 1000.0;
    smallest = 1000.0;
    for (i = 0; i + 1 < n; i++) {
        double c = 5.0 + 100.0 * th_uniform(&rng);
        tg_edge_add(&g, i, i + 1, c, 0.5 * c);
        if (c < smallest)
            smallest = c;
    }
    CHECK_NEAR(tg_solve(&g, side), smallest, 0);
    CHECK(close_rel(tg_cut_cost(&g, side), smallest));
    free(side);
    tg_free(&g);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"chain", test_chain},
        {"diamond", test_diamond},
        {"needs_flow_cancellation", test_needs_flow_cancellation},
        {"tweights_accumulate", test_tweights_accumulate},
        {"empty_and_isolated", test_empty_and_isolated},
        {"bad_arguments", test_bad_arguments},
        {"infinite_hand", test_infinite_hand},
        {"brute_force_random", test_brute_force_random},
        {"brute_force_infinite", test_brute_force_infinite},
        {"edmonds_karp_medium", test_edmonds_karp_medium},
        {"long_chain", test_long_chain},
        {"grid_200", test_grid_200},
        {"grid_300", test_grid_300},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
