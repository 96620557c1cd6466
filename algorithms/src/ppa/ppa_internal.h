/*
 * ppa_internal.h - private helpers shared by the PPA stages: the forest as
 * one byte of neighbour bits per cell.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_PPA_INTERNAL_H
#define TS_PPA_INTERNAL_H

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

/* Neighbour directions: bit d of a cell's byte links it to the neighbour at
 * ppa_dir[d].  The opposite direction is (d + 4) & 7. */
static const int ppa_dir[8][2] = {{1, 0},  {1, 1},   {0, 1},  {-1, 1},
                                  {-1, 0}, {-1, -1}, {0, -1}, {1, -1}};

static inline int ppa_dir_of(int dx, int dy)
{
    int d;
    for (d = 0; d < 8; d++)
        if (ppa_dir[d][0] == dx && ppa_dir[d][1] == dy)
            return d;
    return -1;
}

/* The number of links of a cell (a table: without -mpopcnt the builtin is
 * a library call). */
static const unsigned char ppa_degree_of[256] = {
    0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 1, 2, 2, 3, 2, 3, 3, 4, 2, 3, 3, 4, 3, 4, 4, 5,
    1, 2, 2, 3, 2, 3, 3, 4, 2, 3, 3, 4, 3, 4, 4, 5, 2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6,
    1, 2, 2, 3, 2, 3, 3, 4, 2, 3, 3, 4, 3, 4, 4, 5, 2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6,
    2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6, 3, 4, 4, 5, 4, 5, 5, 6, 4, 5, 5, 6, 5, 6, 6, 7,
    1, 2, 2, 3, 2, 3, 3, 4, 2, 3, 3, 4, 3, 4, 4, 5, 2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6,
    2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6, 3, 4, 4, 5, 4, 5, 5, 6, 4, 5, 5, 6, 5, 6, 6, 7,
    2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6, 3, 4, 4, 5, 4, 5, 5, 6, 4, 5, 5, 6, 5, 6, 6, 7,
    3, 4, 4, 5, 4, 5, 5, 6, 4, 5, 5, 6, 5, 6, 6, 7, 4, 5, 5, 6, 5, 6, 6, 7, 5, 6, 6, 7, 6, 7, 7, 8,
};
static inline int ppa_degree(unsigned char bits)
{
    return ppa_degree_of[bits];
}

/* Length of the step from cell (x, y) in direction d: cells or metres. */
static inline double ppa_step_length(const ts_grid_metrics *m, int y, int d)
{
    int dy = ppa_dir[d][1];
    return ts_step_length(m, dy < 0 ? y - 1 : y, ppa_dir[d][0] != 0, dy != 0);
}

/* Branch lengths are sums of steps in fixed point (1/1024 of a cell or a
 * metre): integer sums do not depend on the order of the steps, so a
 * branch measured in pieces (ppa_tiled.c) has the very length of the same
 * branch walked cell by cell (ppa_branch.c). */
#define PPA_LENGTH_SCALE 1024.0
static inline int64_t ppa_length_q(double len)
{
    return (int64_t)llround(len * PPA_LENGTH_SCALE);
}
static inline int64_t ppa_step_q(const ts_grid_metrics *m, int y, int d)
{
    return ppa_length_q(ppa_step_length(m, y, d));
}

/* Order-preserving map of a segment weight to an unsigned key, inverted so
 * that ascending keys mean descending weights (more important first). */
static inline uint32_t ppa_weight_key(float w)
{
    uint32_t u;
    memcpy(&u, &w, sizeof u);
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return ~u;
}

/* Rows [y0, y1) of strip k of n over h rows (strips side by side). */
static inline void ppa_strip_rows(int h, size_t k, int n, int *y0, int *y1)
{
    *y0 = (int)((int64_t)h * (int64_t)k / n);
    *y1 = (int)((int64_t)h * (int64_t)(k + 1) / n);
}

/* Union-find with path halving and union by rank (the spanning forests'). */
static inline uint32_t ppa_uf_find(uint32_t *parent, uint32_t v)
{
    while (parent[v] != v) {
        parent[v] = parent[parent[v]];
        v = parent[v];
    }
    return v;
}

/* Join the trees of roots ra != rb. */
static inline void ppa_uf_union(uint32_t *parent, unsigned char *rank, uint32_t ra, uint32_t rb)
{
    if (rank[ra] < rank[rb]) {
        uint32_t t = ra;
        ra = rb;
        rb = t;
    }
    parent[rb] = ra;
    if (rank[ra] == rank[rb])
        rank[ra]++;
}

/* Segment k (ppa_connect_step) from a cell is ppa_dir direction
 * ppa_dir_of_k[k]; the other way round, direction d (0..3) is segment
 * ppa_k_of_dir[d]. */
static const int ppa_dir_of_k[4] = {0, 3, 2, 1};
static const int ppa_k_of_dir[4] = {0, 3, 2, 1};

/* Target connection's segments from a cell: k = 0..3 for E, SW, S, SE
 * (ppa_connect_step); does segment k from target (x, y) exist (neighbour a
 * target, diagonals not over nodata, the crossing rule)?  sign: 1 for
 * ridges, -1 for valleys. */
extern const int ppa_connect_step[4][2];
int ppa_segment_exists(const ts_raster *dem, const unsigned char *t, int kind, int x, int y, int k,
                       float sign);

/* Steps 2 and 3 at once, lean (ppa_polygon.c): the maximum spanning forest
 * of the kind's segments straight into adj (one byte of neighbour bits per
 * cell, zeroed by the caller), without the segments that are the least
 * important of a triangle (never in the forest).  The same forest as
 * ts_ppa_target_connection + ts_ppa_polygon_breaking; DEMs under 2^30
 * cells. */
ts_status ppa_spanning_forest(ts_ctx *ctx, const ts_raster *dem, const unsigned char *targets,
                              int kind, unsigned char *adj);
/* The same in n_strips strips of rows (1..height), side by side: the same
 * forest on any number (ppa_spanning_forest takes one per thread, strips
 * of 64 rows at least). */
ts_status ppa_spanning_forest_strips(ts_ctx *ctx, const ts_raster *dem,
                                     const unsigned char *targets, int kind, unsigned char *adj,
                                     int n_strips);

/* Profile recognition (ppa_profile.c) with a threshold per kind. */
ts_status ppa_profile_targets(ts_ctx *ctx, const ts_raster *dem, int profile_length,
                              double threshold_ridges, double threshold_valleys, int kinds,
                              unsigned char *targets);

/* The drainage area of every valid cell, in cells (NaN on nodata), the flow
 * as drainage_area.c defines it, made in tiles of `tile` cells (the same
 * areas on any tiling): the DEM read window by window (read is called
 * under a lock), each tile's areas handed to emit (under the lock).  keep:
 * hold F, D and the flow of every cell (9 bytes a cell) so that each tile
 * is flooded once and never routed; else (bounded memory) tiles are routed
 * in rounds and once more for the areas.  dir (w*h) is each cell's flow:
 * ppa_dir direction 0..7, PPA_DR_DIR_OUT off the DEM, 255 nodata. */
typedef void (*ppa_area_fn)(void *user, int x0, int y0, int w, int h, const float *area,
                            const unsigned char *dir);
ts_status ppa_drainage(ts_ctx *ctx, int width, int height, int tile, int keep,
                       ts_window_read_fn read, void *user, ppa_area_fn emit, void *emit_user);
/* The tiles of the flow routing: in one piece, one tile (one flood); in
 * ppa_tiled.c, the PPA's tiles, at most this. */
#ifndef PPA_DRAINAGE_TILE
#define PPA_DRAINAGE_TILE 16384
#endif
/* ... and from this many threads on, tiles of this size in one piece too,
 * their flow kept (one tile and tiles of 512 take the same work on one
 * thread; side by side, tiles pay from a few threads on: bench/README.md) */
#ifndef PPA_DRAINAGE_TILES_FROM
#define PPA_DRAINAGE_TILES_FROM 4
#endif
#ifndef PPA_DRAINAGE_TILE_THREADS
#define PPA_DRAINAGE_TILE_THREADS 512
#endif
/* The tiles of a DEM in memory's flow routing with the context's threads. */
static inline int ppa_drainage_tile(const ts_ctx *ctx)
{
    return ts__thread_count(ctx, 64) >= PPA_DRAINAGE_TILES_FROM ? PPA_DRAINAGE_TILE_THREADS
                                                                 : PPA_DRAINAGE_TILE;
}
/* The drainage test: *bits (allocated here, a bit a cell, row-major) set on
 * the cells that drain at least min_drainage cells, by ppa_drainage. */
ts_status ppa_channels(ts_ctx *ctx, int width, int height, int tile, int keep,
                       ts_window_read_fn read, void *user, double min_drainage, uint64_t **bits);
static inline int ppa_channel(const uint64_t *bits, size_t c)
{
    return (int)(bits[c >> 6] >> (c & 63) & 1);
}
/* A window of a raster in memory (user: the const ts_raster *). */
ts_status ppa_raster_window(void *dem, int x0, int y0, int w, int h, float *buf);
/* The same of a DEM in memory into area (width x height). */
ts_status ppa_drainage_area(ts_ctx *ctx, const ts_raster *dem, float *area, int tile, int keep);

/* ---- the drainage area in tiles: drainage_area.c runs the phases,
 * drainage_tile.c works on one tile, drainage_perimeters.c on the tiles'
 * perimeters and the rounds across tiles ---- */

/* ---- a radix heap (Ahuja et al. 1990) of unique, never falling keys ---- */

/* Height, then the order of arrival, as one 64-bit key (the float's bits
 * made to sort as unsigned, then a counter). */
static inline uint64_t ppa_flood_key(float h, uint32_t count)
{
    uint32_t u;
    h += 0.0f; /* -0 and +0 are one height */
    memcpy(&u, &h, sizeof u);
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return (uint64_t)u << 32 | count;
}

static inline float ppa_key_height(uint64_t key)
{
    uint32_t u = (uint32_t)(key >> 32);
    float h;
    u = (u & 0x80000000u) ? (u & 0x7fffffffu) : ~u;
    memcpy(&h, &u, sizeof h);
    return h;
}

typedef struct ppa_rh_item {
    uint64_t key;
    uint64_t v;
} ppa_rh_item;

/* An item waits in the bucket of the highest bit where its key differs
 * from the last key taken and only moves down. */
typedef struct ppa_radix_heap {
    ppa_rh_item *b[65];
    size_t n[65], cap[65];
    uint64_t last;
    size_t size;
} ppa_radix_heap;

static inline int ppa_rh_bucket(const ppa_radix_heap *q, uint64_t key)
{
    return key == q->last ? 0 : 64 - __builtin_clzll(key ^ q->last);
}

static inline int ppa_rh_append(ppa_radix_heap *q, int i, ppa_rh_item it)
{
    if (q->n[i] == q->cap[i]) {
        size_t nc = q->cap[i] ? 2 * q->cap[i] : 256;
        ppa_rh_item *g = realloc(q->b[i], nc * sizeof *g);
        if (!g)
            return -1;
        q->b[i] = g;
        q->cap[i] = nc;
    }
    q->b[i][q->n[i]++] = it;
    return 0;
}

static inline int ppa_rh_push(ppa_radix_heap *q, uint64_t key, uint64_t v)
{
    ppa_rh_item it;
    it.key = key;
    it.v = v;
    if (ppa_rh_append(q, ppa_rh_bucket(q, key), it) != 0)
        return -1;
    q->size++;
    return 0;
}

/* Take the least item (q->size > 0) into *out; -1 when out of memory. */
static inline int ppa_rh_pop(ppa_radix_heap *q, ppa_rh_item *out)
{
    if (q->n[0] == 0) {
        int i = 1;
        size_t j, m = 0, cnt;
        ppa_rh_item *src;
        while (q->n[i] == 0)
            i++;
        for (j = 1; j < q->n[i]; j++)
            if (q->b[i][j].key < q->b[i][m].key)
                m = j;
        q->last = q->b[i][m].key;
        src = q->b[i];
        cnt = q->n[i];
        q->n[i] = 0;
        for (j = 0; j < cnt; j++)
            if (ppa_rh_append(q, ppa_rh_bucket(q, src[j].key), src[j]) != 0) {
                memmove(src, src + j, (cnt - j) * sizeof *src); /* the heap stays whole */
                q->n[i] = cnt - j;
                return -1;
            }
    }
    q->size--;
    *out = q->b[0][--q->n[0]];
    return 0;
}

static inline void ppa_rh_reset(ppa_radix_heap *q)
{
    int i;
    for (i = 0; i < 65; i++)
        q->n[i] = 0;
    q->last = 0;
    q->size = 0;
}

static inline void ppa_rh_free(ppa_radix_heap *q)
{
    int i;
    for (i = 0; i < 65; i++)
        free(q->b[i]);
}

/* ---- the job ---- */

#define PPA_DR_NONE UINT64_MAX
#define PPA_DR_DINF UINT32_MAX
#define PPA_DR_DIR_OUT 8 /* drains off the DEM */

/* The phases (ppa_dr_job.phase). */
enum { PPA_PH_LABELS, PPA_PH_ROUTE, PPA_PH_FLATS, PPA_PH_RELAX, PPA_PH_FLOW, PPA_PH_AREAS };

typedef struct ppa_dr_edge {
    uint64_t u, v; /* global nodes: 0 the boundary, 1 + p perimeter cell p */
    float w;
} ppa_dr_edge;

typedef struct ppa_dr_job {
    ts_ctx *ctx;
    int W, H, T, ntx, nty;
    size_t ntiles, np;
    ts_window_read_fn read;
    void *user;
    ppa_area_fn emit;
    void *emit_user;
    pthread_mutex_t lock; /* reads, emits, the edge list */
    atomic_int failed;
    atomic_size_t next;  /* the next tile a worker takes */
    size_t *pbase;       /* per tile (and one past): its first perimeter cell */
    float *ph;           /* perimeter heights (NaN: nodata) */
    unsigned char *pbnd; /* perimeter cell on the boundary */
    float *G;            /* perimeter F */
    uint32_t *D, *Dnew;  /* perimeter D (PPA_DR_DINF: not known) */
    unsigned char *due;  /* the tiles the phase at hand runs on */
    ppa_dr_edge *edges;
    size_t n_edges, cap_edges;
    uint64_t *target, *link; /* phase C: where a tile exit's flow enters; by what exit a
                                perimeter cell's flow leaves its tile */
    double *A, *in;          /* an exit's area in its tile; what flows into a perimeter cell */
    /* kept (in memory, not in bounded memory): each cell's F, D and flow
     * (W x H), so that a tile is routed once: D across tiles is relaxed on
     * the flats alone, the flow and the areas follow from F and D */
    float *Fc;
    uint32_t *Dc;
    unsigned char *dirs;
    size_t *hbase;        /* per tile (and one past): its first halo cell in hsens */
    unsigned char *hsens; /* the halo cells whose D the tile's last routing could read */
    int phase;
} ppa_dr_job;

/* A cell of a tile: its height, F once flooded (side by side with L: the
 * flood visits cells in height order, all over the tile; one cache line a
 * row of neighbours), and L: its label (phase A), D (B-D), exit (C). */
typedef struct ppa_dr_cell {
    float v;
    uint32_t L;
} ppa_dr_cell;

/* A tile's working set: the tile with a halo of one cell. */
typedef struct ppa_dr_tile {
    int t, x0, y0, w, h, hw;
    ppa_dr_cell *cell;
    unsigned char *dir, *bnd, *indeg;
    double *acc; /* also the buffer of reads and of the areas handed out */
    uint32_t *order;
    ppa_radix_heap q;
} ppa_dr_tile;

static inline size_t ppa_dr_hx(const ppa_dr_tile *k, int x, int y) /* x, y in [-1, w] x [-1, h] */
{
    return (size_t)(y + 1) * (size_t)k->hw + (size_t)(x + 1);
}

static inline long ppa_dr_perim_local(int w, int h, int x, int y)
{
    if (y == 0)
        return x;
    if (y == h - 1)
        return (long)w + x;
    if (x == 0)
        return 2L * w + (y - 1);
    if (x == w - 1)
        return 2L * w + (h - 2) + (y - 1);
    return -1;
}

static inline size_t ppa_dr_perim_count(int w, int h)
{
    return h == 1 ? (size_t)w : w == 1 ? (size_t)h : 2 * (size_t)w + 2 * (size_t)(h - 2);
}

/* The cell of tile (w x h) whose perimeter index is k. */
static inline void ppa_dr_perim_xy(int w, int h, size_t k, int *x, int *y)
{
    size_t k2;
    if (k < (size_t)w) {
        *x = (int)k, *y = 0;
        return;
    }
    if (k < 2 * (size_t)w) {
        *x = (int)(k - (size_t)w), *y = h - 1;
        return;
    }
    k2 = k - 2 * (size_t)w;
    if (k2 < (size_t)(h - 2))
        *x = 0, *y = 1 + (int)k2;
    else
        *x = w - 1, *y = 1 + (int)(k2 - (size_t)(h - 2));
}

/* The halo of a w x h tile, a ring of 2 (w + 2) + 2 h cells: the row
 * above, the row below, the column left, the column right. */
static inline size_t ppa_dr_halo_count(int w, int h)
{
    return 2 * (size_t)(w + 2) + 2 * (size_t)h;
}

static inline size_t ppa_dr_halo_index(int w, int h, int x, int y) /* (x, y) in the halo */
{
    if (y < 0)
        return (size_t)(x + 1);
    if (y >= h)
        return (size_t)(w + 2) + (size_t)(x + 1);
    if (x < 0)
        return 2 * (size_t)(w + 2) + (size_t)y;
    return 2 * (size_t)(w + 2) + (size_t)h + (size_t)y;
}

static inline void ppa_dr_tile_rect(const ppa_dr_job *j, size_t t, int *x0, int *y0, int *w, int *h)
{
    *x0 = (int)(t % (size_t)j->ntx) * j->T;
    *y0 = (int)(t / (size_t)j->ntx) * j->T;
    *w = TS_MIN(j->T, j->W - *x0);
    *h = TS_MIN(j->T, j->H - *y0);
}

/* The global perimeter index of DEM cell (gx, gy) (every cell beside
 * another tile is on its own tile's perimeter). */
static inline size_t ppa_dr_perim_of(const ppa_dr_job *j, int gx, int gy)
{
    size_t t = (size_t)(gy / j->T) * (size_t)j->ntx + (size_t)(gx / j->T);
    int x0, y0, w, h;
    ppa_dr_tile_rect(j, t, &x0, &y0, &w, &h);
    return j->pbase[t] + (size_t)ppa_dr_perim_local(w, h, gx - x0, gy - y0);
}

/* One tile (drainage_tile.c): its working set for tiles of at most tw x th
 * cells (0, or -1 out of memory) and its release; tile t read with its
 * halo; phase A's priority-flood of the tile alone (F and the labels); its
 * routing by (F, D) from the perimeter's F and Dsrc (the cells taken, or
 * (size_t)-1); its areas summed down the flow in the routing's order, or
 * in a topological order of the flow alone (returned: how many). */
int ppa_dr_tile_alloc(ppa_dr_tile *k, int tw, int th);
void ppa_dr_tile_free(ppa_dr_tile *k);
int ppa_dr_tile_read(ppa_dr_job *j, ppa_dr_tile *k, size_t t);
int ppa_dr_tile_flood(ppa_dr_tile *k);
size_t ppa_dr_tile_route(ppa_dr_job *j, ppa_dr_tile *k, const uint32_t *Dsrc);
void ppa_dr_tile_areas(ppa_dr_job *j, ppa_dr_tile *k, size_t taken, const double *in);
size_t ppa_dr_tile_topo_areas(ppa_dr_job *j, ppa_dr_tile *k, const double *in);

/* The tiles' perimeters and the rounds (drainage_perimeters.c): a phase
 * run on the due tiles by the workers; F of every perimeter cell; what
 * flows into each perimeter cell; whether tile t is to be relaxed again
 * (kept) or routed again (old: the D before the round).  The ints: 0, or
 * -1 out of memory (flat_pairs and halo_changed: 1 when again). */
ts_status ppa_dr_run_phase(ppa_dr_job *j, int phase);
int ppa_dr_solve_perimeter_f(ppa_dr_job *j);
int ppa_dr_solve_inflow(ppa_dr_job *j);
int ppa_dr_flat_pairs(const ppa_dr_job *j, size_t t);
int ppa_dr_halo_changed(const ppa_dr_job *j, size_t t, const uint32_t *old);

/* The parameters of one kind, "auto" resolved (ppa.c): valleys with the
 * drainage test (min_drainage > 0) are channels, mapped with a lower dip
 * and shorter branches than ridges (algorithms/docs/ppa.md). */
#define PPA_AUTO_FRACTION 0.0025
#define PPA_AUTO_FRACTION_CHANNELS 0.0001
#define PPA_AUTO_BRANCH 40.0
#define PPA_AUTO_BRANCH_CHANNELS 10.0
double ppa_kind_fraction(const ts_ppa_params *p, int kind);
/* The minimum branch length of the kind; *in_metres = 1 when it is in metres. */
double ppa_kind_branch(const ts_ppa_params *p, int kind, int *in_metres);

/* PPA step 4, branch reduction: remove branches shorter than min_length
 * (in metres when m != NULL, else cells) from the forest `adj`. */
ts_status ppa_branch_reduction(ts_ctx *ctx, int width, int height, unsigned char *adj,
                               const ts_grid_metrics *m, double min_length);

/* Append the nodes and paths of forest `adj` (kind TS_RIDGE/TS_VALLEY) to
 * the graph f, and set the kind's bit in f->mask. */
ts_status ppa_graph_collect(ts_ctx *ctx, const ts_raster *dem, const unsigned char *adj,
                            const ts_grid_metrics *m, int kind, ts_features *f);

/* ---- the PPA in tiles: ppa_tiled.c runs the steps, ppa_tiled_polygon.c
 * breaks the polygons, ppa_tiled_branch.c reduces the branches ---- */

/* An edge of the global Kruskal: a contracted path of one tile's forest,
 * or a segment crossing a tile border. */
typedef struct ppa_cut_edge {
    uint64_t u, v;   /* global cells */
    uint64_t idx;    /* the segment (global cell a x 4 + k) that goes if the edge closes a cycle */
    uint32_t key;    /* its weight key */
    uint32_t border; /* 1: a border segment (u = a, v = b) */
} ppa_cut_edge;

/* A chain between two vertices of the forest's chain graph. */
typedef struct ppa_chain {
    uint64_t u, v;
    int64_t length;
} ppa_chain;

typedef struct ppa_kind_state {
    int kind;
    float sign;
    ppa_cut_edge *edges; /* phase 1; then the border segments kept, sorted by idx */
    size_t n_edges, cap_edges;
    uint64_t *dropped; /* segments of tile forests that are not in the whole's forest, sorted */
    size_t n_dropped;
    uint32_t *border_chain; /* per kept border segment: its chain */
    ppa_chain *chains;
    size_t n_chains, cap_chains;
    size_t *chain_base; /* per tile: its first chain */
    unsigned char *dead;
    const ts_grid_metrics *m; /* branch lengths in metres, or NULL: in cells */
    int64_t min_q;            /* the kind's minimum branch length, fixed point */
} ppa_kind_state;

typedef struct ppa_window {
    int x0, y0, w, h; /* in the raster */
    unsigned char *adj, *unc;
    const ts_grid_metrics *m;
    uint32_t *visit;
    size_t n_visit, cap_visit;
} ppa_window;

typedef struct ppa_tiled {
    ts_ctx *ctx;
    int W, H, T, ntx, nty, margin, half;
    float threshold[2]; /* ridges, valleys */
    int kinds;
    uint64_t *channel; /* valleys with the drainage test: bit per DEM cell, set where
                          the drainage area is at least min_drainage (NULL: no test) */
    ts_window_read_fn read;
    void *user;
    ppa_kind_state ks[2];
    /* the tile at hand */
    int x0, y0, w, h, wx0, wy0, ww, wh;
    float *win;
    unsigned char *wt;
    float *core;
    unsigned char *ct, *adj, *work, *term;
    uint32_t *queue;
    struct ppa_chain_clear *clears;
    size_t n_clears, cap_clears;
    /* the first passes of branch reduction, in tiles */
    int halo, passes;
    double frac; /* the progress of the phase at hand, which the stages' own hold at */
    unsigned char *strip[2][3], *strip_nd[3]; /* three tile rows of the whole's forest */
    struct ppa_window wn;
} ppa_tiled;

/* The raster's index of its cell (x, y). */
static inline uint64_t ppa_gcell(const ppa_tiled *t, int x, int y)
{
    return (uint64_t)y * (uint64_t)t->W + (uint64_t)x;
}

/* Is raster cell (x, y) in the tile at hand? */
static inline int ppa_in_core(const ppa_tiled *t, int x, int y)
{
    return x >= t->x0 && y >= t->y0 && x < t->x0 + t->w && y < t->y0 + t->h;
}

/* Room for `need` items of elem bytes in *p (*cap of them, doubled from
 * 1024); -1 when out of memory. */
static inline int ppa_grow(void **p, size_t *cap, size_t need, size_t elem)
{
    size_t ncap;
    void *np;
    if (need <= *cap)
        return 0;
    ncap = *cap ? *cap : 1024;
    while (ncap < need)
        ncap *= 2;
    np = realloc(*p, ncap * elem);
    if (!np)
        return -1;
    *p = np;
    *cap = ncap;
    return 0;
}

/* First position in sorted v[0..n) not below key. */
static inline size_t ppa_u64_lower(const uint64_t *v, size_t n, uint64_t key)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (v[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* The same among edges sorted by idx. */
static inline size_t ppa_edge_lower(const ppa_cut_edge *v, size_t n, uint64_t idx)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (v[mid].idx < idx)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* Polygon breaking in tiles (ppa_tiled_polygon.c): phase 1 for the tile
 * at hand and kind ks (its border segments and its forest contracted to
 * its border cells); the sorted distinct endpoints (the first two
 * uint64_t of each of n items of size bytes) into a new array of *n_out;
 * phase 1 for the whole (one Kruskal: which tile segments go, which
 * border segments stay); the tile's part of the whole's forest into
 * t->adj. */
ts_status ppa_tile_contract(ppa_tiled *t, ppa_kind_state *ks);
uint64_t *ppa_vertex_list(const void *items, size_t n, size_t size, size_t *n_out);
ts_status ppa_global_forest(ppa_tiled *t, ppa_kind_state *ks);
ts_status ppa_tile_whole_forest(ppa_tiled *t, ppa_kind_state *ks);

/* Branch reduction in tiles (ppa_tiled_branch.c): the chains of tile ti
 * of the forest in t->adj, recorded (remove == 0) or the dead ones cleared
 * (remove == 1); the reduction on the chain graph of the whole, pass by
 * pass; `passes` passes on window wn (0, or -1 out of memory). */
ts_status ppa_tile_chains(ppa_tiled *t, ppa_kind_state *ks, int ti, int remove);
ts_status ppa_global_branches(ppa_tiled *t, ppa_kind_state *ks);
int ppa_win_passes(ppa_window *wn, int passes, int64_t min_q);

#endif
