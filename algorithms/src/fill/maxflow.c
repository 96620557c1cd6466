/*
 * maxflow.c - minimum s-t cut by maximum flow, the Boykov-Kolmogorov
 * algorithm (Boykov & Kolmogorov 2004, "An Experimental Comparison of
 * Min-Cut/Max-Flow Algorithms for Energy Minimization in Vision"), for the
 * graph-cut seam finder (Zhou et al. 2007 section 5.1, App. A).  A source
 * tree and a sink tree grow from the terminals; an arc joining them closes
 * an augmenting path; arcs saturated by the augmentation cut off orphans,
 * which are re-attached to their tree (adoption) or freed.  The trees are
 * reused between augmentations, which makes grid graphs near-linear in
 * practice (worst case O(m n^2 |C|)).  Memory: 32 bytes per node and per
 * edge, plus 8 bytes per node while solving; up to 2^31 - 1 nodes.  A
 * graph is used by one thread at a time; separate graphs are independent.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "internal.h"
#include "maxflow.h"

/* Special values of the 32-bit node and arc indices. */
#define MF_NONE UINT32_MAX                     /* parent: free node; next: not queued */
#define MF_TERMINAL (UINT32_MAX - 1u)          /* parent: the node hangs from its terminal */
#define MF_ORPHAN (UINT32_MAX - 2u)            /* parent: lost, awaiting adoption */
#define MF_MAX_COUNT ((size_t)UINT32_MAX - 3u) /* arcs stay below */
#define MF_MAX_NODES ((size_t)INT32_MAX)       /* so that dist fits its 31 bits */

/* Infinite capacities are stored as this finite value.  Finite amounts
 * below ~1e284 vanish when added to or taken from it, so it behaves as
 * infinity without ever computing INFINITY - INFINITY, and a flow below
 * half of it proves a finite minimum cut. */
#define MF_INF_CAP 1e300

/* A node's tree membership, apart from its adjacency: the path walks
 * (augmentation, adoption) touch only these 16 bytes per step, and the
 * parent node is stored next to the parent arc (it is the arc's head) so
 * that a step is a single dependent load. */
typedef struct mf_tree {
    uint32_t parent;          /* arc from this node to its tree parent, or a special value */
    uint32_t up;              /* the parent node, when parent is an arc */
    uint32_t stamp;           /* time at which dist was last known exact */
    unsigned int dist : 31;   /* arcs to the terminal along the tree (roots: 1) */
    unsigned int in_sink : 1; /* 1 in the sink tree, 0 in the source tree */
} mf_tree;

typedef struct mf_node {
    uint32_t first; /* first outgoing arc (list through mf_arc.next) */
    uint32_t next;  /* active queue link; the tail links to itself */
    double tr_cap;  /* residual source capacity (> 0) or minus sink capacity (< 0) */
} mf_node;

/* Arcs come in reverse pairs 2k, 2k+1: the sister of arc a is a ^ 1. */
typedef struct mf_arc {
    uint32_t head;
    uint32_t next; /* next arc with the same tail */
    double r_cap;  /* residual capacity */
} mf_arc;

struct ts_maxflow {
    mf_node *nodes;
    mf_tree *tree;
    size_t n_nodes;
    mf_arc *arcs;
    size_t n_arcs, cap_arcs;
    double flow;
    uint32_t queue_head, queue_tail;
    uint32_t *orphans; /* FIFO of one augmentation's orphans */
    uint32_t *path;    /* nodes of the augmenting path */
    size_t orphan_head, orphan_tail;
    uint32_t time;
    int solved;
};

static double maxflow_clamp(double cap)
{
    return cap > MF_INF_CAP ? MF_INF_CAP : cap;
}

static void maxflow_activate(ts_maxflow *g, uint32_t i)
{
    if (g->nodes[i].next != MF_NONE)
        return;
    g->nodes[i].next = i;
    if (g->queue_tail == MF_NONE)
        g->queue_head = i;
    else
        g->nodes[g->queue_tail].next = i;
    g->queue_tail = i;
}

/* Next queued node still in a tree, or MF_NONE. */
static uint32_t maxflow_next_active(ts_maxflow *g)
{
    while (g->queue_head != MF_NONE) {
        uint32_t i = g->queue_head;
        mf_node *n = &g->nodes[i];
        g->queue_head = n->next == i ? MF_NONE : n->next;
        if (g->queue_head == MF_NONE)
            g->queue_tail = MF_NONE;
        n->next = MF_NONE;
        if (g->tree[i].parent != MF_NONE)
            return i;
    }
    return MF_NONE;
}

/* A node enters the orphan FIFO at most once per augmentation: adopted
 * nodes hang from verified, orphan-free chains that cannot be cut again
 * before the next augmentation, so n_nodes slots suffice. */
static void maxflow_make_orphan(ts_maxflow *g, uint32_t i)
{
    g->tree[i].parent = MF_ORPHAN;
    g->orphans[g->orphan_tail++] = i;
}

/* Push the bottleneck along the path through `mid`, an arc from a
 * source-tree node to a sink-tree node; saturated tree links make orphans.
 * The first pass records the path (source side, then sink side) so the
 * second does not chase the parent links again. */
static void maxflow_augment(ts_maxflow *g, uint32_t mid)
{
    mf_node *nodes = g->nodes;
    mf_tree *tree = g->tree;
    mf_arc *arcs = g->arcs;
    uint32_t *path = g->path;
    size_t n_src, n = 0, k;
    double b = arcs[mid].r_cap;
    uint32_t i;

    for (i = arcs[mid ^ 1u].head; tree[i].parent != MF_TERMINAL; i = tree[i].up) {
        path[n++] = i;
        if (arcs[tree[i].parent ^ 1u].r_cap < b)
            b = arcs[tree[i].parent ^ 1u].r_cap;
    }
    if (nodes[i].tr_cap < b)
        b = nodes[i].tr_cap;
    path[n++] = i;
    n_src = n;
    for (i = arcs[mid].head; tree[i].parent != MF_TERMINAL; i = tree[i].up) {
        path[n++] = i;
        if (arcs[tree[i].parent].r_cap < b)
            b = arcs[tree[i].parent].r_cap;
    }
    if (-nodes[i].tr_cap < b)
        b = -nodes[i].tr_cap;
    path[n++] = i;

    arcs[mid].r_cap -= b;
    arcs[mid ^ 1u].r_cap += b;
    /* source side: flow runs parent -> child, i.e. along the sister of the parent arc */
    for (k = 0; k + 1 < n_src; k++) {
        uint32_t a = tree[path[k]].parent;
        arcs[a].r_cap += b;
        arcs[a ^ 1u].r_cap -= b;
        if (arcs[a ^ 1u].r_cap == 0)
            maxflow_make_orphan(g, path[k]);
    }
    i = path[n_src - 1];
    nodes[i].tr_cap -= b;
    if (nodes[i].tr_cap == 0)
        maxflow_make_orphan(g, i);
    /* sink side: flow runs child -> parent, along the parent arc */
    for (k = n_src; k + 1 < n; k++) {
        uint32_t a = tree[path[k]].parent;
        arcs[a ^ 1u].r_cap += b;
        arcs[a].r_cap -= b;
        if (arcs[a].r_cap == 0)
            maxflow_make_orphan(g, path[k]);
    }
    i = path[n - 1];
    nodes[i].tr_cap += b;
    if (nodes[i].tr_cap == 0)
        maxflow_make_orphan(g, i);
    g->flow += b;
}

/* Distance from j to its terminal if j's chain reaches the terminal
 * without meeting an orphan, else MF_NONE.  Exact distances found on the
 * way are stamped with the current time so later walks stop early. */
static uint32_t maxflow_origin(ts_maxflow *g, uint32_t j)
{
    mf_tree *tree = g->tree;
    uint32_t k = j, d = 0;
    for (;;) {
        uint32_t p = tree[k].parent;
        if (tree[k].stamp == g->time) {
            d += tree[k].dist;
            break;
        }
        d++;
        if (p == MF_TERMINAL) {
            tree[k].stamp = g->time;
            tree[k].dist = 1;
            break;
        }
        if (p == MF_ORPHAN)
            return MF_NONE;
        k = tree[k].up;
    }
    for (k = j; tree[k].stamp != g->time; k = tree[k].up) {
        tree[k].stamp = g->time;
        tree[k].dist = d--;
    }
    return tree[j].dist;
}

/* Re-attach orphan i to the closest valid node of its tree, or free it:
 * then its tree neighbours that could reach it become active again and
 * its children become orphans. */
static void maxflow_adopt(ts_maxflow *g, uint32_t i)
{
    mf_node *nodes = g->nodes;
    mf_tree *tree = g->tree;
    mf_arc *arcs = g->arcs;
    uint32_t sink = tree[i].in_sink, best = MF_NONE, best_d = MF_NONE, a;

    for (a = nodes[i].first; a != MF_NONE; a = arcs[a].next) {
        uint32_t j = arcs[a].head, d;
        /* the tree link must carry flow towards the sink: j -> i in the
         * source tree, i -> j in the sink tree */
        double cap = sink ? arcs[a].r_cap : arcs[a ^ 1u].r_cap;
        if (cap == 0 || tree[j].parent == MF_NONE || tree[j].in_sink != sink)
            continue;
        d = maxflow_origin(g, j);
        if (d < best_d) {
            best_d = d;
            best = a;
        }
    }
    if (best != MF_NONE) {
        tree[i].parent = best;
        tree[i].up = arcs[best].head;
        tree[i].stamp = g->time;
        tree[i].dist = best_d + 1;
        return;
    }
    tree[i].parent = MF_NONE;
    for (a = nodes[i].first; a != MF_NONE; a = arcs[a].next) {
        uint32_t j = arcs[a].head, p = tree[j].parent;
        if (p == MF_NONE || tree[j].in_sink != sink)
            continue;
        if ((sink ? arcs[a].r_cap : arcs[a ^ 1u].r_cap) > 0)
            maxflow_activate(g, j);
        if (p != MF_TERMINAL && p != MF_ORPHAN && tree[j].up == i)
            maxflow_make_orphan(g, j);
    }
}

/* Grow the tree of active node i by one layer.  Returns an arc from the
 * source tree to the sink tree if the trees touch, else MF_NONE. */
static uint32_t maxflow_grow(ts_maxflow *g, uint32_t i)
{
    mf_node *nodes = g->nodes;
    mf_tree *tree = g->tree;
    mf_arc *arcs = g->arcs;
    uint32_t sink = tree[i].in_sink, a;

    for (a = nodes[i].first; a != MF_NONE; a = arcs[a].next) {
        uint32_t j = arcs[a].head;
        if ((sink ? arcs[a ^ 1u].r_cap : arcs[a].r_cap) == 0)
            continue;
        if (tree[j].parent == MF_NONE) {
            tree[j].in_sink = sink;
            tree[j].parent = a ^ 1u;
            tree[j].up = i;
            tree[j].stamp = tree[i].stamp;
            tree[j].dist = tree[i].dist + 1;
            maxflow_activate(g, j);
        } else if (tree[j].in_sink != sink) {
            return sink ? a ^ 1u : a;
        }
    }
    return MF_NONE;
}

ts_maxflow *ts__maxflow_new(size_t n_nodes, size_t edge_hint)
{
    ts_maxflow *g;
    size_t i;
    if (n_nodes > MF_MAX_NODES)
        return NULL;
    g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    if (edge_hint > MF_MAX_COUNT / 2)
        edge_hint = MF_MAX_COUNT / 2;
    g->cap_arcs = edge_hint < 8 ? 16 : 2 * edge_hint;
    g->n_nodes = n_nodes;
    g->nodes = ts__malloc_array(n_nodes, sizeof *g->nodes);
    g->tree = ts__malloc_array(n_nodes, sizeof *g->tree);
    g->arcs = ts__malloc_array(g->cap_arcs, sizeof *g->arcs);
    if (!g->nodes || !g->tree || !g->arcs) {
        ts__maxflow_free(g);
        return NULL;
    }
    for (i = 0; i < n_nodes; i++) {
        mf_node *n = &g->nodes[i];
        mf_tree *t = &g->tree[i];
        n->first = n->next = MF_NONE;
        n->tr_cap = 0.0;
        t->parent = t->up = MF_NONE;
        t->stamp = 0;
        t->dist = t->in_sink = 0;
    }
    g->queue_head = g->queue_tail = MF_NONE;
    return g;
}

void ts__maxflow_free(ts_maxflow *g)
{
    if (!g)
        return;
    free(g->nodes);
    free(g->tree);
    free(g->arcs);
    free(g->orphans);
    free(g->path);
    free(g);
}

int ts__maxflow_add_tweights(ts_maxflow *g, size_t node, double cap_source, double cap_sink)
{
    double cs, ct, t;
    if (node >= g->n_nodes || !(cap_source >= 0) || !(cap_sink >= 0) || g->solved)
        return -1;
    /* the node's previous capacities, with their common part already
     * counted as flow, plus the new ones */
    t = g->nodes[node].tr_cap;
    cs = maxflow_clamp(maxflow_clamp(cap_source) + (t > 0 ? t : 0));
    ct = maxflow_clamp(maxflow_clamp(cap_sink) + (t < 0 ? -t : 0));
    g->flow += cs < ct ? cs : ct;
    g->nodes[node].tr_cap = cs - ct;
    return 0;
}

int ts__maxflow_add_edge(ts_maxflow *g, size_t a, size_t b, double cap_ab, double cap_ba)
{
    mf_arc *arc;
    uint32_t k;
    if (a >= g->n_nodes || b >= g->n_nodes || !(cap_ab >= 0) || !(cap_ba >= 0) || g->solved)
        return -1;
    if (a == b || (cap_ab == 0 && cap_ba == 0))
        return 0; /* never cut, or nothing to cut */
    if (g->n_arcs + 2 > g->cap_arcs) {
        size_t cap = g->cap_arcs * 2;
        mf_arc *grown;
        if (cap > MF_MAX_COUNT)
            cap = MF_MAX_COUNT & ~(size_t)1;
        if (g->n_arcs + 2 > cap || cap > SIZE_MAX / sizeof *g->arcs)
            return -1;
        grown = realloc(g->arcs, cap * sizeof *g->arcs);
        if (!grown)
            return -1;
        g->arcs = grown;
        g->cap_arcs = cap;
    }
    k = (uint32_t)g->n_arcs;
    g->n_arcs += 2;
    arc = &g->arcs[k];
    arc[0].head = (uint32_t)b;
    arc[0].next = g->nodes[a].first;
    arc[0].r_cap = maxflow_clamp(cap_ab);
    g->nodes[a].first = k;
    arc[1].head = (uint32_t)a;
    arc[1].next = g->nodes[b].first;
    arc[1].r_cap = maxflow_clamp(cap_ba);
    g->nodes[b].first = k + 1;
    return 0;
}

int ts__maxflow_solve(ts_maxflow *g, double *flow)
{
    mf_node *nodes = g->nodes;
    mf_tree *tree = g->tree;
    uint32_t i, current = MF_NONE;
    if (!g->solved) {
        /* a path visits a node at most once, plus its two ends */
        if (!g->orphans)
            g->orphans = ts__malloc_array(g->n_nodes, sizeof *g->orphans);
        if (!g->path)
            g->path = ts__malloc_array(g->n_nodes + 2, sizeof *g->path);
        if (!g->orphans || !g->path)
            return -1;
        g->solved = 1;
        for (i = 0; i < (uint32_t)g->n_nodes; i++) {
            if (nodes[i].tr_cap == 0)
                continue;
            tree[i].in_sink = nodes[i].tr_cap < 0;
            tree[i].parent = MF_TERMINAL;
            tree[i].stamp = 0;
            tree[i].dist = 1;
            maxflow_activate(g, i);
        }
        for (;;) {
            uint32_t mid;
            /* a node that just closed a path may touch the other tree again */
            i = current;
            if (i == MF_NONE || tree[i].parent == MF_NONE)
                i = maxflow_next_active(g);
            current = MF_NONE;
            if (i == MF_NONE)
                break;
            mid = maxflow_grow(g, i);
            if (mid == MF_NONE)
                continue;
            current = i;
            if (++g->time == 0) { /* wrapped: forget every stamp */
                size_t k;
                for (k = 0; k < g->n_nodes; k++)
                    tree[k].stamp = 0;
                g->time = 1;
            }
            g->orphan_head = g->orphan_tail = 0;
            maxflow_augment(g, mid);
            while (g->orphan_head < g->orphan_tail)
                maxflow_adopt(g, g->orphans[g->orphan_head++]);
        }
    }
    if (flow)
        *flow = g->flow >= 0.5 * MF_INF_CAP ? INFINITY : g->flow;
    return 0;
}

int ts__maxflow_is_sink(const ts_maxflow *g, size_t node)
{
    const mf_tree *n;
    if (node >= g->n_nodes)
        return 0;
    n = &g->tree[node];
    /* free nodes are not reachable from the source: sink side */
    return n->parent == MF_NONE || n->in_sink;
}
