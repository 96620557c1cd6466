/*
 * sketch_lines.c - the feature graph of a sketch drawn as lines (ours: the
 * paper paints its sketches; a GIS user digitises them).  The lines are the
 * graph directly, without a rasterise-then-PPA round trip: each line's kind
 * is what the user said, junctions are where lines meet.
 *
 * 1. Snapping: a line end within `snap` cells of another line of its kind
 *    (not near itself) is moved onto that line's nearest point, which
 *    becomes a vertex of both (a T junction, or two ends joined).
 * 2. Each line is walked in steps of at most half a cell; the cells it
 *    visits make an 8-connected chain, consecutive cells joined by an edge
 *    (kept as 8 direction bits per cell and kind, in a hash of the cells
 *    the lines cross: nothing of the grid's size but the mask).  Lines that share a cell
 *    meet there; lines that cross share the cell of their crossing point,
 *    which is added to both as a vertex first.  Cells off the grid are left
 *    out, so a line leaving the grid ends at its edge.
 * 3. The graph on the cells: nodes are the cells with 1 or 3+ edges, paths
 *    the chains of 2-edge cells between them; a ring without a node is
 *    opened at its first cell in raster order.
 * Heights given at the vertices are interpolated along the lines into the
 * vertices' z (NaN elsewhere).  Cost: O(line length in cells x log of it +
 * vertices x segments near them); memory: the mask and about 50 bytes a
 * line cell.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "ppa_internal.h"

static const int DX[8] = {1, 1, 0, -1, -1, -1, 0, 1};
static const int DY[8] = {0, 1, 1, 1, 0, -1, -1, -1};

/* A line being prepared: its points (x, y, z) in cell coordinates. */
typedef struct lpts {
    int kind;
    size_t n, cap;
    double *x, *y, *z;
} lpts;

static int lpts_insert(lpts *l, size_t at, double x, double y, double z)
{
    if (l->n == l->cap) {
        size_t nc = l->cap ? 2 * l->cap : 16;
        double *nx = realloc(l->x, nc * sizeof *nx);
        double *ny = nx ? realloc(l->y, nc * sizeof *ny) : NULL;
        double *nz = ny ? realloc(l->z, nc * sizeof *nz) : NULL;
        if (nx)
            l->x = nx;
        if (ny)
            l->y = ny;
        if (!nz)
            return -1;
        l->z = nz;
        l->cap = nc;
    }
    memmove(l->x + at + 1, l->x + at, (l->n - at) * sizeof *l->x);
    memmove(l->y + at + 1, l->y + at, (l->n - at) * sizeof *l->y);
    memmove(l->z + at + 1, l->z + at, (l->n - at) * sizeof *l->z);
    l->x[at] = x;
    l->y[at] = y;
    l->z[at] = z;
    l->n++;
    return 0;
}

static void lpts_free(lpts *l, size_t n)
{
    size_t i;
    for (i = 0; l && i < n; i++) {
        free(l[i].x);
        free(l[i].y);
        free(l[i].z);
    }
    free(l);
}

/* The nearest point to (px, py) on segment a-b: its parameter t in 0..1
 * and squared distance. */
static double seg_nearest(double ax, double ay, double bx, double by, double px, double py,
                          double *t)
{
    double vx = bx - ax, vy = by - ay, L = vx * vx + vy * vy, s, dx, dy;
    s = L > 0 ? ((px - ax) * vx + (py - ay) * vy) / L : 0.0;
    s = s < 0 ? 0 : s > 1 ? 1 : s;
    dx = ax + s * vx - px;
    dy = ay + s * vy - py;
    *t = s;
    return dx * dx + dy * dy;
}

/* Crossing of segments p0-p1 and q0-q1 strictly inside both: 1 and the
 * parameters along each; 0 otherwise. */
static int seg_cross(double p0x, double p0y, double p1x, double p1y, double q0x, double q0y,
                     double q1x, double q1y, double *s, double *t)
{
    double rx = p1x - p0x, ry = p1y - p0y, ux = q1x - q0x, uy = q1y - q0y;
    double den = rx * uy - ry * ux;
    if (fabs(den) < 1e-12)
        return 0;
    *s = ((q0x - p0x) * uy - (q0y - p0y) * ux) / den;
    *t = ((q0x - p0x) * ry - (q0y - p0y) * rx) / den;
    return *s > 1e-9 && *s < 1 - 1e-9 && *t > 1e-9 && *t < 1 - 1e-9;
}

/* A vertex to insert: into line `line` after vertex `seg`, at parameter s
 * along that segment. */
typedef struct ins {
    size_t line, seg;
    double s, x, y, z;
} ins;

typedef struct insbuf {
    ins *v;
    size_t n, cap;
} insbuf;

static int ins_add(insbuf *b, size_t line, size_t seg, double s, double x, double y, double z)
{
    if (b->n == b->cap) {
        size_t nc = b->cap ? 2 * b->cap : 64;
        ins *nv = realloc(b->v, nc * sizeof *nv);
        if (!nv)
            return -1;
        b->v = nv;
        b->cap = nc;
    }
    b->v[b->n].line = line;
    b->v[b->n].seg = seg;
    b->v[b->n].s = s;
    b->v[b->n].x = x;
    b->v[b->n].y = y;
    b->v[b->n].z = z;
    b->n++;
    return 0;
}

/* Later lines first, then later segments, then farther along: inserting in
 * this order leaves the earlier indices valid. */
static int ins_cmp(const void *pa, const void *pb)
{
    const ins *a = pa, *b = pb;
    if (a->line != b->line)
        return a->line < b->line ? 1 : -1;
    if (a->seg != b->seg)
        return a->seg < b->seg ? 1 : -1;
    return (a->s < b->s) - (a->s > b->s);
}

static int ins_apply(lpts *L, insbuf *b)
{
    size_t i;
    if (b->n)
        qsort(b->v, b->n, sizeof *b->v, ins_cmp);
    for (i = 0; i < b->n; i++)
        if (lpts_insert(&L[b->v[i].line], b->v[i].seg + 1, b->v[i].x, b->v[i].y, b->v[i].z) != 0)
            return -1;
    b->n = 0;
    return 0;
}

/* Buckets of segments on a square lattice of `size` cells. */
typedef struct buckets {
    double x0, y0, size;
    long nx, ny;
    size_t *start; /* nx * ny + 1 offsets into items */
    size_t *items; /* line << 32 | segment */
} buckets;

static void bk_range(const buckets *bk, double a, double b, double lo0, long n, long *i0, long *i1)
{
    *i0 = (long)floor((fmin(a, b) - lo0) / bk->size);
    *i1 = (long)floor((fmax(a, b) - lo0) / bk->size);
    *i0 = *i0 < 0 ? 0 : *i0 >= n ? n - 1 : *i0;
    *i1 = *i1 < 0 ? 0 : *i1 >= n ? n - 1 : *i1;
}

/* Every segment of every line in the buckets its box (grown by pad) meets. */
static int bk_build(buckets *bk, const lpts *L, size_t nl, double pad)
{
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    size_t i, k, total = 0, *cnt;
    int pass;
    memset(bk, 0, sizeof *bk);
    for (i = 0; i < nl; i++)
        for (k = 0; k < L[i].n; k++) {
            x0 = fmin(x0, L[i].x[k]);
            y0 = fmin(y0, L[i].y[k]);
            x1 = fmax(x1, L[i].x[k]);
            y1 = fmax(y1, L[i].y[k]);
        }
    if (!(x1 >= x0))
        return 0;
    bk->size = 16.0 + 4.0 * pad;
    while ((x1 - x0) / bk->size * ((y1 - y0) / bk->size) > 4e6)
        bk->size *= 2.0;
    bk->x0 = x0 - pad;
    bk->y0 = y0 - pad;
    bk->nx = (long)floor((x1 + pad - bk->x0) / bk->size) + 1;
    bk->ny = (long)floor((y1 + pad - bk->y0) / bk->size) + 1;
    bk->start = ts__calloc_array((size_t)(bk->nx * bk->ny) + 1, sizeof *bk->start);
    cnt = ts__calloc_array((size_t)(bk->nx * bk->ny) + 1, sizeof *cnt);
    if (!bk->start || !cnt) {
        free(cnt);
        return -1;
    }
    for (pass = 0; pass < 2; pass++) {
        for (i = 0; i < nl; i++)
            for (k = 0; k + 1 < L[i].n; k++) {
                long a0, a1, b0, b1, u, v;
                bk_range(bk, fmin(L[i].x[k], L[i].x[k + 1]) - pad,
                         fmax(L[i].x[k], L[i].x[k + 1]) + pad, bk->x0, bk->nx, &a0, &a1);
                bk_range(bk, fmin(L[i].y[k], L[i].y[k + 1]) - pad,
                         fmax(L[i].y[k], L[i].y[k + 1]) + pad, bk->y0, bk->ny, &b0, &b1);
                for (v = b0; v <= b1; v++)
                    for (u = a0; u <= a1; u++) {
                        size_t c = (size_t)(v * bk->nx + u);
                        if (pass == 0)
                            cnt[c]++;
                        else
                            bk->items[bk->start[c] + cnt[c]++] = (i << 32) | k;
                    }
            }
        if (pass == 0) {
            size_t c, nb = (size_t)(bk->nx * bk->ny);
            for (c = 0; c < nb; c++) {
                bk->start[c] = total;
                total += cnt[c];
                cnt[c] = 0;
            }
            bk->start[nb] = total;
            if (!(bk->items = ts__malloc_array(total + 1, sizeof *bk->items))) {
                free(cnt);
                return -1;
            }
        }
    }
    free(cnt);
    return 0;
}

static void bk_free(buckets *bk)
{
    free(bk->start);
    free(bk->items);
    bk->start = NULL;
    bk->items = NULL;
}

/* Lines split into segments of at most `step` cells (collinear vertices
 * added), so that every segment sits in a few buckets. */
static int lines_densify(lpts *L, size_t nl, double step)
{
    size_t i, k;
    for (i = 0; i < nl; i++)
        for (k = 0; k + 1 < L[i].n; k++) {
            double dx = L[i].x[k + 1] - L[i].x[k], dy = L[i].y[k + 1] - L[i].y[k];
            double len = hypot(dx, dy);
            if (len > step) {
                double t = step / len;
                if (lpts_insert(&L[i], k + 1, L[i].x[k] + t * dx, L[i].y[k] + t * dy,
                                L[i].z[k] + t * (L[i].z[k + 1] - L[i].z[k])) != 0)
                    return -1;
            }
        }
    return 0;
}

/* Step 1a: line ends of one kind within snap of each other join at the
 * first one's place (by line, first end before last). */
static void lines_join_ends(lpts *L, size_t nl, double snap)
{
    size_t i, j;
    int ei, ej;
    for (i = 0; i < nl; i++)
        for (ei = 0; ei < 2 && L[i].n >= 2; ei++) {
            size_t a = ei ? L[i].n - 1 : 0;
            for (j = 0; j <= i; j++)
                for (ej = 0; ej < 2 && L[j].n >= 2; ej++) {
                    size_t b = ej ? L[j].n - 1 : 0;
                    if ((j == i && ej >= ei) || L[j].kind != L[i].kind)
                        continue;
                    if (hypot(L[i].x[a] - L[j].x[b], L[i].y[a] - L[j].y[b]) <= snap) {
                        L[i].x[a] = L[j].x[b];
                        L[i].y[a] = L[j].y[b];
                        if (isnan(L[i].z[a]))
                            L[i].z[a] = L[j].z[b];
                        goto next_end;
                    }
                }
        next_end:;
        }
}

/* Step 1b: a line end joined to no other end, within snap of another line
 * of its kind (or of its own, farther than 2 snap along it), moves onto the
 * nearest point of that line, which becomes one of its vertices. */
static int lines_snap_ends(lpts *L, size_t nl, double snap, const buckets *bk, insbuf *ib)
{
    size_t i, j;
    int e;
    for (i = 0; i < nl; i++)
        for (e = 0; e < 2 && L[i].n >= 2; e++) {
            size_t a = e ? L[i].n - 1 : 0, q, best_l = 0, best_k = 0;
            double px = L[i].x[a], py = L[i].y[a], best = snap * snap, best_t = 0.0;
            long u, v;
            int found = 0, joined = 0;
            for (j = 0; j < nl && !joined; j++)
                if (L[j].kind == L[i].kind && L[j].n >= 2 && !(j == i))
                    joined = (L[j].x[0] == px && L[j].y[0] == py) ||
                             (L[j].x[L[j].n - 1] == px && L[j].y[L[j].n - 1] == py);
            if (joined || snap <= 0 || !bk->start)
                continue;
            bk_range(bk, px, px, bk->x0, bk->nx, &u, &u);
            bk_range(bk, py, py, bk->y0, bk->ny, &v, &v);
            for (q = bk->start[v * bk->nx + u]; q < bk->start[v * bk->nx + u + 1]; q++) {
                size_t l = (size_t)(bk->items[q] >> 32), k = (size_t)(bk->items[q] & 0xffffffffu);
                double t, d;
                if (L[l].kind != L[i].kind || k + 1 >= L[l].n)
                    continue;
                if (l == i) {
                    /* its own line, away from this end by index (segments
                     * are at most snap long) */
                    size_t far = (size_t)ceil(2.0 * snap) + 2;
                    if (e ? k + far > a : k < far)
                        continue;
                }
                d = seg_nearest(L[l].x[k], L[l].y[k], L[l].x[k + 1], L[l].y[k + 1], px, py, &t);
                if (d < best ||
                    (d == best && found && (l < best_l || (l == best_l && k < best_k)))) {
                    best = d;
                    best_l = l;
                    best_k = k;
                    best_t = t;
                    found = 1;
                }
            }
            if (!found || best == 0.0)
                continue;
            {
                const lpts *b = &L[best_l];
                double qx = b->x[best_k] + best_t * (b->x[best_k + 1] - b->x[best_k]);
                double qy = b->y[best_k] + best_t * (b->y[best_k + 1] - b->y[best_k]);
                double qz = b->z[best_k] + best_t * (b->z[best_k + 1] - b->z[best_k]);
                if (best_t > 0 && best_t < 1 &&
                    ins_add(ib, best_l, best_k, best_t, qx, qy, qz) != 0)
                    return -1;
                L[i].x[a] = qx;
                L[i].y[a] = qy;
                if (isnan(L[i].z[a]))
                    L[i].z[a] = qz;
            }
        }
    return 0;
}

/* Step 2's crossing vertices: every crossing of two segments of lines of
 * one kind (two lines, or a line and itself) becomes a vertex of both. */
static int lines_cross_vertices(const lpts *L, const buckets *bk, insbuf *ib)
{
    long c, nb = bk->nx * bk->ny;
    for (c = 0; c < nb; c++) {
        size_t p, q, lo = bk->start[c], hi = bk->start[c + 1];
        for (p = lo; p < hi; p++)
            for (q = p + 1; q < hi; q++) {
                size_t la = (size_t)(bk->items[p] >> 32), ka = (size_t)(bk->items[p] & 0xffffffffu);
                size_t lb = (size_t)(bk->items[q] >> 32), kb = (size_t)(bk->items[q] & 0xffffffffu);
                double s, t, x, y;
                long u, v;
                if (L[la].kind != L[lb].kind || (la == lb && (ka + 1 >= kb && kb + 1 >= ka)))
                    continue;
                if (!seg_cross(L[la].x[ka], L[la].y[ka], L[la].x[ka + 1], L[la].y[ka + 1],
                               L[lb].x[kb], L[lb].y[kb], L[lb].x[kb + 1], L[lb].y[kb + 1], &s, &t))
                    continue;
                x = L[la].x[ka] + s * (L[la].x[ka + 1] - L[la].x[ka]);
                y = L[la].y[ka] + s * (L[la].y[ka + 1] - L[la].y[ka]);
                bk_range(bk, x, x, bk->x0, bk->nx, &u, &u);
                bk_range(bk, y, y, bk->y0, bk->ny, &v, &v);
                if (v * bk->nx + u != c)
                    continue; /* counted in the bucket of the crossing */
                if (ins_add(ib, la, ka, s, x, y,
                            L[la].z[ka] + s * (L[la].z[ka + 1] - L[la].z[ka])) != 0 ||
                    ins_add(ib, lb, kb, t, x, y,
                            L[lb].z[kb] + t * (L[lb].z[kb + 1] - L[lb].z[kb])) != 0)
                    return -1;
            }
    }
    return 0;
}

/* A cell the lines cross: its edges of one kind, height and node. */
typedef struct cg_cell {
    size_t cell;       /* y * W + x */
    size_t node;       /* the node at the cell + 1 (0: none) */
    float z;           /* the height the lines give the cell (NaN: none) */
    unsigned char dir; /* bit d: an edge to the neighbour (DX[d], DY[d]) */
} cg_cell;

/* The graph under construction: the cells the lines cross, kept in slots
 * (a hash of the cell's index finds its slot): what it costs follows the
 * lines' length, not the grid's size. */
typedef struct cellgraph {
    int W, H;
    cg_cell *s; /* the slots */
    size_t n, cap;
    size_t *hash; /* slot + 1 (0: empty), open addressing; hcap entries */
    size_t hcap;
} cellgraph;

/* The hash entry of cell c: where it is, or the empty one where it goes. */
static size_t cg_entry(const cellgraph *g, size_t c)
{
    size_t h = (size_t)(((uint64_t)c * 0x9e3779b97f4a7c15ull) >> 17) & (g->hcap - 1);
    while (g->hash[h] && g->s[g->hash[h] - 1].cell != c)
        h = (h + 1) & (g->hcap - 1);
    return h;
}

/* The slot of cell c, or (size_t)-1. */
static size_t cg_find(const cellgraph *g, size_t c)
{
    return g->hcap ? g->hash[cg_entry(g, c)] - 1 : (size_t)-1;
}

/* The slot of cell c, made (no edge, no height, no node) when missing;
 * (size_t)-1 out of memory. */
static size_t cg_slot(cellgraph *g, size_t c)
{
    size_t s = cg_find(g, c), k;
    if (s != (size_t)-1)
        return s;
    if (ppa_grow((void **)&g->s, &g->cap, g->n + 1, sizeof *g->s) != 0)
        return (size_t)-1;
    if (2 * (g->n + 1) > g->hcap) { /* at most half full: rebuilt twice as large */
        size_t nh = g->hcap ? 2 * g->hcap : 2048, *hash = ts__calloc_array(nh, sizeof *hash);
        if (!hash)
            return (size_t)-1;
        free(g->hash);
        g->hash = hash;
        g->hcap = nh;
        for (k = 0; k < g->n; k++)
            g->hash[cg_entry(g, g->s[k].cell)] = k + 1;
    }
    s = g->n++;
    g->s[s].cell = c;
    g->s[s].node = 0;
    g->s[s].z = NAN;
    g->s[s].dir = 0;
    g->hash[cg_entry(g, c)] = s + 1;
    return s;
}

static void cg_clear(cellgraph *g)
{
    g->n = 0;
    if (g->hash)
        memset(g->hash, 0, g->hcap * sizeof *g->hash);
}

static void cg_free(cellgraph *g)
{
    free(g->s);
    free(g->hash);
}

static int dir_of(int dx, int dy)
{
    int d;
    for (d = 0; d < 8; d++)
        if (DX[d] == dx && DY[d] == dy)
            return d;
    return -1;
}

/* Step 2 for one line: its cells and edges; -1 out of memory. */
static int lines_walk(cellgraph *g, const lpts *l)
{
    long px = LONG_MIN, py = LONG_MIN;
    size_t k, ps = (size_t)-1; /* the slot of the cell before, when on the grid */
    for (k = 0; k + 1 < l->n || (k == 0 && l->n == 1); k++) {
        double x0 = l->x[k], y0 = l->y[k];
        double x1 = l->n > 1 ? l->x[k + 1] : x0, y1 = l->n > 1 ? l->y[k + 1] : y0;
        double z0 = l->z[k], z1 = l->n > 1 ? l->z[k + 1] : z0;
        double len = hypot(x1 - x0, y1 - y0);
        long steps = (long)ceil(len / 0.5), s;
        if (steps < 1)
            steps = 1;
        for (s = (k == 0 ? 0 : 1); s <= steps; s++) {
            double t = (double)s / (double)steps;
            long cx = (long)floor(x0 + t * (x1 - x0)), cy = (long)floor(y0 + t * (y1 - y0));
            int in = cx >= 0 && cy >= 0 && cx < g->W && cy < g->H;
            size_t sc = (size_t)-1;
            if (cx == px && cy == py)
                continue;
            if (in) {
                double z = z0 + t * (z1 - z0);
                sc = cg_slot(g, (size_t)cy * (size_t)g->W + (size_t)cx);
                if (sc == (size_t)-1)
                    return -1;
                if (isnan(g->s[sc].z) && !isnan(z))
                    g->s[sc].z = (float)z;
                if (ps != (size_t)-1) {
                    int d = dir_of((int)(cx - px), (int)(cy - py));
                    if (d >= 0) {
                        g->s[ps].dir |= (unsigned char)(1u << d);
                        g->s[sc].dir |= (unsigned char)(1u << ((d + 4) % 8));
                    }
                }
            }
            px = cx;
            py = cy;
            ps = sc;
        }
    }
    return 0;
}

static int popcount8(unsigned v)
{
    int n = 0;
    for (; v; v &= v - 1)
        n++;
    return n;
}

/* The growing feature graph. */
typedef struct fbuild {
    ts_features *f;
    size_t cap_n, cap_p, cap_v;
} fbuild;

/* The node at slot s (made when missing). */
static long fb_node(fbuild *b, cellgraph *g, size_t s, int kind)
{
    ts_feature_node *nd;
    if (g->s[s].node)
        return (long)g->s[s].node - 1;
    if (ppa_grow((void **)&b->f->nodes, &b->cap_n, b->f->n_nodes + 1, sizeof *nd) != 0)
        return -1;
    nd = &b->f->nodes[b->f->n_nodes];
    nd->x = (int)(g->s[s].cell % (size_t)g->W);
    nd->y = (int)(g->s[s].cell / (size_t)g->W);
    nd->z = g->s[s].z;
    nd->degree = popcount8(g->s[s].dir);
    nd->kind = kind;
    g->s[s].node = ++b->f->n_nodes;
    return (long)b->f->n_nodes - 1;
}

/* The slot of the neighbour of slot s in direction d (an edge leads there). */
static size_t fb_step(const cellgraph *g, size_t s, int d)
{
    return cg_find(g, (size_t)((long)g->s[s].cell + DY[d] * (long)g->W + DX[d]));
}

/* Step 3: the path leaving node slot s in direction d (its edges cleared). */
static int fb_path(fbuild *b, cellgraph *g, size_t s, int d, int kind)
{
    ts_features *f = b->f;
    ts_feature_path *p;
    long na = fb_node(b, g, s, kind), nb;
    size_t cur = s, W = (size_t)g->W;
    double len = 0.0, zs = 0.0;
    size_t nz = 0;
    float zmin = NAN, zmax = NAN;
    if (na < 0 || ppa_grow((void **)&f->paths, &b->cap_p, f->n_paths + 1, sizeof *p) != 0)
        return -1;
    p = &f->paths[f->n_paths];
    memset(p, 0, sizeof *p);
    p->kind = kind;
    p->node_a = (size_t)na;
    p->first = f->n_verts;
    for (;;) {
        ts_feature_vertex *v;
        float z = g->s[cur].z;
        if (ppa_grow((void **)&f->verts, &b->cap_v, f->n_verts + 1, sizeof *v) != 0)
            return -1;
        v = &f->verts[f->n_verts++];
        v->x = (int)(g->s[cur].cell % W);
        v->y = (int)(g->s[cur].cell / W);
        v->z = z;
        if (!isnan(z)) {
            zmin = isnan(zmin) || z < zmin ? z : zmin;
            zmax = isnan(zmax) || z > zmax ? z : zmax;
            zs += z;
            nz++;
        }
        if (d < 0)
            break;
        /* step along d, clearing the edge both ways */
        g->s[cur].dir &= (unsigned char)~(1u << d);
        len += (d % 2) ? sqrt(2.0) : 1.0;
        cur = fb_step(g, cur, d);
        g->s[cur].dir &= (unsigned char)~(1u << ((d + 4) % 8));
        if (g->s[cur].node || popcount8(g->s[cur].dir) != 1) {
            d = -1; /* a node: the path ends here */
            continue;
        }
        for (d = 0; d < 8 && !(g->s[cur].dir & (1u << d)); d++)
            ;
    }
    if ((nb = fb_node(b, g, cur, kind)) < 0)
        return -1;
    p = &f->paths[f->n_paths++];
    p->node_b = (size_t)nb;
    p->count = f->n_verts - p->first;
    p->length = len;
    p->zmin = zmin;
    p->zmax = zmax;
    p->zmean = nz ? (float)(zs / (double)nz) : NAN;
    return 0;
}

typedef struct cell_slot {
    size_t cell, slot;
} cell_slot;

static int cell_slot_cmp(const void *a, const void *b)
{
    size_t x = ((const cell_slot *)a)->cell, y = ((const cell_slot *)b)->cell;
    return (x > y) - (x < y);
}

/* Step 3 for one kind: nodes (raster order), paths from them, rings. */
static int fb_kind(fbuild *b, cellgraph *g, int kind)
{
    cell_slot *ord = ts__malloc_array(g->n + 1, sizeof *ord);
    size_t i;
    int d, rc = -1;
    if (!ord)
        return -1;
    for (i = 0; i < g->n; i++) {
        ord[i].cell = g->s[i].cell;
        ord[i].slot = i;
    }
    qsort(ord, g->n, sizeof *ord, cell_slot_cmp);
    for (i = 0; i < g->n; i++) {
        size_t s = ord[i].slot;
        if (g->s[s].dir) {
            b->f->mask[g->s[s].cell] |= (unsigned char)kind;
            if (popcount8(g->s[s].dir) != 2 && fb_node(b, g, s, kind) < 0)
                goto done;
        }
    }
    for (i = 0; i < g->n; i++) {
        size_t s = ord[i].slot;
        if (g->s[s].node)
            for (d = 0; d < 8; d++)
                while (g->s[s].dir & (1u << d))
                    if (fb_path(b, g, s, d, kind) != 0)
                        goto done;
    }
    /* rings: opened at their first cell, whose first edge is cut */
    for (i = 0; i < g->n; i++) {
        size_t s = ord[i].slot, o;
        if (!g->s[s].dir)
            continue;
        for (d = 0; d < 8 && !(g->s[s].dir & (1u << d)); d++)
            ;
        o = fb_step(g, s, d);
        g->s[s].dir &= (unsigned char)~(1u << d);
        g->s[o].dir &= (unsigned char)~(1u << ((d + 4) % 8));
        if (fb_node(b, g, s, kind) < 0 || fb_node(b, g, o, kind) < 0)
            goto done;
        b->f->nodes[g->s[s].node - 1].degree = 1;
        b->f->nodes[g->s[o].node - 1].degree = 1;
        for (d = 0; d < 8 && !(g->s[s].dir & (1u << d)); d++)
            ;
        if (d < 8 && fb_path(b, g, s, d, kind) != 0)
            goto done;
    }
    rc = 0;
done:
    free(ord);
    return rc;
}

TS_API ts_status ts_features_from_lines(ts_ctx *ctx, int width, int height,
                                        const ts_sketch_line *lines, size_t n_lines, double snap,
                                        ts_features **out)
{
    size_t n = (size_t)width * (size_t)height, i, k;
    lpts *L = NULL;
    cellgraph g;
    fbuild b;
    int kinds[2] = {TS_RIDGE, TS_VALLEY}, ki, bad = 0;
    ts__clear(ctx);
    memset(&b, 0, sizeof b);
    memset(&g, 0, sizeof g);
    g.W = width;
    g.H = height;
    *out = NULL;
    if (width < 1 || height < 1 || (!lines && n_lines) || !(snap >= 0))
        return ts__fail(ctx, TS_ERR_ARG, "sketch lines", "bad grid, lines or snap distance");
    for (i = 0; i < n_lines; i++)
        if ((lines[i].kind != TS_RIDGE && lines[i].kind != TS_VALLEY) || !lines[i].x || !lines[i].y)
            return ts__fail(ctx, TS_ERR_ARG, "sketch lines", "line %zu: bad kind or points", i);
    L = ts__calloc_array(n_lines + 1, sizeof *L);
    b.f = calloc(1, sizeof *b.f);
    if (!L || !b.f || !(b.f->mask = ts__calloc_array(n, 1))) {
        bad = 1;
        goto done;
    }
    b.f->width = width;
    b.f->height = height;
    /* the points, without repeats */
    for (i = 0; i < n_lines && !bad; i++) {
        L[i].kind = lines[i].kind;
        for (k = 0; k < lines[i].n && !bad; k++) {
            double x = lines[i].x[k], y = lines[i].y[k];
            double z = lines[i].z ? lines[i].z[k] : NAN;
            if (!isfinite(x) || !isfinite(y))
                continue;
            if (L[i].n && L[i].x[L[i].n - 1] == x && L[i].y[L[i].n - 1] == y)
                continue;
            bad = lpts_insert(&L[i], L[i].n, x, y, z) != 0;
        }
    }
    /* 1. ends joined and snapped; 2. crossings made vertices */
    if (!bad)
        bad = lines_densify(L, n_lines, snap > 1.0 ? snap : 1.0) != 0;
    if (!bad) {
        buckets bk;
        insbuf ib = {NULL, 0, 0};
        lines_join_ends(L, n_lines, snap);
        bad = bk_build(&bk, L, n_lines, snap) != 0 ||
              lines_snap_ends(L, n_lines, snap, &bk, &ib) != 0 || ins_apply(L, &ib) != 0;
        bk_free(&bk);
        if (!bad)
            bad = bk_build(&bk, L, n_lines, 0.0) != 0 ||
                  (bk.start && lines_cross_vertices(L, &bk, &ib) != 0) || ins_apply(L, &ib) != 0;
        bk_free(&bk);
        free(ib.v);
    }
    for (ki = 0; ki < 2 && !bad; ki++) {
        cg_clear(&g);
        for (i = 0; i < n_lines && !bad; i++)
            if (L[i].kind == kinds[ki] && L[i].n)
                bad = lines_walk(&g, &L[i]) != 0;
        bad = bad || fb_kind(&b, &g, kinds[ki]) != 0;
    }
done:
    lpts_free(L, n_lines);
    cg_free(&g);
    if (bad) {
        ts_features_free(b.f);
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch lines", "out of memory");
    }
    *out = b.f;
    return TS_OK;
}
