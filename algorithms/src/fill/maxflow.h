/*
 * maxflow.h - a generic max-flow / min-cut solver (Boykov-Kolmogorov
 * style augmenting paths with search-tree reuse).  No terrain concepts:
 * nodes and capacities only.  Private to the library; tests include it.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_MAXFLOW_H
#define TS_MAXFLOW_H

#include <stddef.h>

#include "terrasynth.h"

typedef struct ts_maxflow ts_maxflow;

/** A graph with n_nodes nodes (at most 2^31 - 1) and room for about
 *  edge_hint edges (it grows as needed); NULL if out of memory. */
ts_maxflow *ts__maxflow_new(size_t n_nodes, size_t edge_hint);
void ts__maxflow_free(ts_maxflow *g);
/** Add capacities from the source to `node` and from `node` to the sink
 *  (accumulate over calls; non-negative; may be INFINITY).  Returns 0, or
 *  -1 for a bad node, a negative or NaN capacity, or after solve. */
int ts__maxflow_add_tweights(ts_maxflow *g, size_t node, double cap_source, double cap_sink);
/** Add an edge a->b with capacity cap_ab and b->a with cap_ba (>= 0;
 *  may be INFINITY).  Returns 0, or -1 if out of memory or for bad
 *  arguments as above.  Finite capacities must stay far below 1e280. */
int ts__maxflow_add_edge(ts_maxflow *g, size_t a, size_t b, double cap_ab, double cap_ba);
/** Compute the maximum flow (the minimum cut's capacity; INFINITY when
 *  every cut is infinite).  Returns 0, or -1 if out of memory.  Solves
 *  once; later calls only report the flow. */
int ts__maxflow_solve(ts_maxflow *g, double *flow);
/** After solve: 1 if the node is on the sink side of the minimum cut, 0 on
 *  the source side.  Nodes reachable from the source in the residual
 *  graph are on the source side; all others on the sink side. */
int ts__maxflow_is_sink(const ts_maxflow *g, size_t node);

#endif
