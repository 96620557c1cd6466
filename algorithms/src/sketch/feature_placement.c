/*
 * feature_placement.c - feature patch matching and placement (Zhou et al.
 * 2007 section 4.1), the third step of the sketch pipeline (synth.c: PPA on
 * the sketch and the exemplars, the sites over the feature tree, these
 * feature patches, the non-feature fill, the layout).
 *
 * For each site, candidates are the exemplar sites of the same type
 *    (branch points of the same degree in each of the d cyclic alignments
 *    and mirrored; endpoints; path sites both ways round).  Their
 *    deformation cost c_d: for branch points the bending energy of the
 *    thin-plate spline taking the exemplar's control points onto the
 *    sketch's (Bookstein 1989; coordinates in units of the circle radius);
 *    for path and endpoint sites, whose three or two control points a TPS
 *    would fit affinely (zero bending), the residual of the least-squares
 *    similarity (rotation, scale, mirror) fit, which measures how
 *    differently the two chains bend.  Three rounds: (a) c_d of every
 *    alignment (in parallel chunks), the best pool_max kept; (b) for
 *    those, c_f, the path smoothness c_s, the height constraints and the
 *    relief guide estimated on the exemplar through each warp at the
 *    control points, the k best by alpha_d c_d + these going on; (c) the k
 *    are warped into the output window (bilinear, exemplar nodata
 *    respected) and cut in by graph cut, with the cells along the sketch's
 *    feature forced to the new patch; c_g is the mean seam mismatch, c_f
 *    the RMS difference of 7-point height profiles across the feature at
 *    the circle crossings against what is already placed, c_s the bend of
 *    the joined crest profile (sk_smoothness).  The lowest alpha_d c_d +
 *    alpha_g c_g + alpha_f c_f + alpha_s c_s + height and guide costs is
 *    merged (patch_merge.c), and its feature cells are fixed.
 * Cost: per site O(exemplar sites) for c_d, O(pool_max) profile estimates,
 *    k warps and graph cuts.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "feature_placement.h"
#include "feature_tree.h"
#include "layout.h"
#include "patch_merge.h"
#include "relief_guide.h"
#include "tps.h"

typedef struct candidate {
    int idx;         /* into the exemplar site list */
    int rot, mirror; /* the alignment */
    double cd;
    double pre; /* alpha_d c_d + the profile costs estimated before warping */
    ts_tps inv; /* output window coordinates -> exemplar cells */
} candidate;

typedef struct sketcher {
    ts_ctx *ctx;
    const ts_sketch_params *sp;
    const ts__fill *p; /* parameters in cells, constraints, relief guide */
    const ts_raster *ex;
    int n_ex;
    ts_raster *out;
    unsigned char *flags;  /* the caller's: feature cores get TS_CELL_FIXED */
    const ts_features *sf; /* sketch features */
    int kind;
    int P;
    double R;
    const ts__ex_site *es;
    size_t n_es;
    ts_merger merger;
    /* work buffers */
    float *old;
    /* one slot per examined candidate (k of them) */
    float *c_ring, *c_patch;
    unsigned char *c_cons, *c_labels, *c_core;
    double *c_cost;
    ts_status *c_status;
    int32_t *src_x, *src_y;
    int *near;        /* P x P: distance to the sketch's feature */
    int *fixnear;     /* P x P: distance to fixed cells (earlier feature cores, pins) */
    int core_radius;  /* feature cells and flanks within this many cells */
    candidate *cands; /* the k examined in full */
    candidate *pool;  /* the best by deformation, before the profile costs */
    double *pool_cost;
    int pool_max;
    int n_chunks;          /* the deformation scan's parallel chunks */
    candidate *chunk_pool; /* n_chunks x pool_max */
    int *chunk_n;
    ts_synth_maps *maps;
} sketcher;

/* ---- transforms ---------------------------------------------------- */

/* Least-squares similarity (optionally mirrored) taking a[i] onto b[i];
 * returns the residual sum of squares; the map in *t as an affine TPS. */
static double sk_similarity(int n, const double *ax, const double *ay, const double *bx,
                            const double *by, int mirror, ts_tps *t)
{
    double max = 0, may = 0, mbx = 0, mby = 0, sxx = 0, sxy = 0, saa = 0, c, s, res = 0;
    int i;
    for (i = 0; i < n; i++) {
        max += ax[i];
        may += mirror ? -ay[i] : ay[i];
        mbx += bx[i];
        mby += by[i];
    }
    max /= n;
    may /= n;
    mbx /= n;
    mby /= n;
    for (i = 0; i < n; i++) {
        double x = ax[i] - max, y = (mirror ? -ay[i] : ay[i]) - may;
        double u = bx[i] - mbx, v = by[i] - mby;
        sxx += x * u + y * v;
        sxy += x * v - y * u;
        saa += x * x + y * y;
    }
    c = saa > 0 ? sxx / saa : 1.0;
    s = saa > 0 ? sxy / saa : 0.0;
    memset(t, 0, sizeof *t);
    t->n = 0;
    /* b = [c -s; s c] * (a' - ma) + mb, a' = (x, mirror ? -y : y) */
    t->ax[1] = c;
    t->ax[2] = mirror ? s : -s;
    t->ax[0] = mbx - c * max + s * may;
    t->ay[1] = s;
    t->ay[2] = mirror ? -c : c;
    t->ay[0] = mby - s * max - c * may;
    for (i = 0; i < n; i++) {
        double ox, oy;
        ts__tps_map(t, ax[i], ay[i], &ox, &oy);
        res += (ox - bx[i]) * (ox - bx[i]) + (oy - by[i]) * (oy - by[i]);
    }
    return res;
}

/* Deformation cost of exemplar site e onto sketch site s with arm rotation
 * `rot` and `mirror` (c_d, on coordinates in units of R so it does not
 * depend on the patch size; skipped when cd is NULL), and the inverse map
 * (skipped when inv is NULL) from the output window's continuous
 * coordinates (window cell (x, y) has its centre at x + 0.5, y + 0.5; the
 * site's centre cell is at (cx - wx, cy - wy)) to the exemplar's. */
static int sk_align(const sketcher *k, ts_ctx *ctx, const ts_feature_site *s,
                    const ts_feature_site *e, int rot, int mirror, double wcx, double wcy,
                    double *cd, ts_tps *inv)
{
    double ex[TS_SITE_MAX_ARMS + 1], ey[TS_SITE_MAX_ARMS + 1];
    double sx[TS_SITE_MAX_ARMS + 1], sy[TS_SITE_MAX_ARMS + 1];
    double wx_[TS_SITE_MAX_ARMS + 1], wy_[TS_SITE_MAX_ARMS + 1];
    double gx[TS_SITE_MAX_ARMS + 1], gy[TS_SITE_MAX_ARMS + 1];
    int n = s->n_ctrl, i, arms = n - 1;
    ts_tps fwd;
    for (i = 0; i < n; i++) {
        /* arm i of the sketch takes arm j of the exemplar; mirrored
         * exemplars (y flipped) run their arms the other way round */
        int j = ts__feature_arm(arms, i, rot, mirror);
        double epx = e->px[j], epy = mirror ? -e->py[j] : e->py[j];
        ex[i] = epx / k->R;
        ey[i] = epy / k->R;
        sx[i] = s->px[i] / k->R;
        sy[i] = s->py[i] / k->R;
        wx_[i] = wcx + s->px[i] + 0.5;
        wy_[i] = wcy + s->py[i] + 0.5;
        /* the exemplar cell itself (the mirror only pairs the points) */
        gx[i] = e->cx + e->px[j] + 0.5;
        gy[i] = e->cy + e->py[j] + 0.5;
    }
    if (s->type == TS_SITE_BRANCH) {
        if (cd && ts__tps_fit(ctx, n, ex, ey, sx, sy, 0.0, &fwd) != TS_OK)
            return -1;
        if (cd)
            *cd = fwd.bending;
        if (inv && ts__tps_fit(ctx, n, wx_, wy_, gx, gy, 0.0, inv) != TS_OK)
            return -1;
    } else {
        if (cd)
            *cd = sk_similarity(n, ex, ey, sx, sy, 0, &fwd) / n;
        /* a mirrored pairing needs a reflecting map */
        if (inv)
            sk_similarity(n, wx_, wy_, gx, gy, mirror, inv);
    }
    return 0;
}

/* ---- helpers ------------------------------------------------------- */

static int sk_cand_cmp(const void *a, const void *b)
{
    const candidate *p = a, *q = b;
    if (p->cd != q->cd)
        return p->cd < q->cd ? -1 : 1;
    if (p->idx != q->idx)
        return p->idx < q->idx ? -1 : 1;
    if (p->mirror != q->mirror)
        return p->mirror < q->mirror ? -1 : 1;
    return (p->rot > q->rot) - (p->rot < q->rot);
}

/* Same order by the pre-warp cost; ties fall back on the deformation order,
 * a total order (exemplar site, then alignment), so sorting is
 * deterministic. */
static int sk_pre_cmp(const void *a, const void *b)
{
    const candidate *p = a, *q = b;
    if (p->pre != q->pre)
        return p->pre < q->pre ? -1 : 1;
    return sk_cand_cmp(a, b);
}

/* Bilinear sample of the output (NaN where any corner is empty). */
static double sk_sample(const ts_raster *r, double x, double y)
{
    int x0 = (int)floor(x), y0 = (int)floor(y);
    double fx = x - x0, fy = y - y0, v;
    if (x0 < 0 || y0 < 0 || x0 + 1 >= r->width || y0 + 1 >= r->height)
        return NAN;
    v = (1 - fy) * ((1 - fx) * TS_PIX(r, x0, y0) + fx * TS_PIX(r, x0 + 1, y0)) +
        fy * ((1 - fx) * TS_PIX(r, x0, y0 + 1) + fx * TS_PIX(r, x0 + 1, y0 + 1));
    return v;
}

/* What a candidate (or the output) holds at output cell coordinates
 * (x, y) (cell centres at integers): the warped window with its ring
 * (inv NULL: value at (x + ox, y + oy) of r), or the exemplar itself through
 * the window's inverse warp (before any warping is done). */
typedef struct sk_view {
    const ts_raster *r;
    const ts_tps *inv;
    double ox, oy; /* ring offsets, or the window's corner for inv */
} sk_view;

static double sk_value(const sk_view *v, double x, double y)
{
    if (v->inv) {
        double ex, ey;
        ts__tps_map(v->inv, x - v->ox + 0.5, y - v->oy + 0.5, &ex, &ey);
        return sk_sample(v->r, ex - 0.5, ey - 0.5);
    }
    return sk_sample(v->r, x + v->ox, y + v->oy);
}

/* The crest (valleys: the thalweg) near (x, y): the extreme of five values
 * across the feature, a quarter radius either side; NaN if none is known. */
static double sk_crest(const sketcher *k, const sk_view *v, double x, double y, double nx,
                       double ny)
{
    double best = NAN, step = k->R / 8.0;
    int j;
    for (j = -2; j <= 2; j++) {
        double z = sk_value(v, x + j * step * nx, y + j * step * ny);
        if (isnan(z))
            continue;
        if (isnan(best) || (k->kind == TS_VALLEY ? z < best : z > best))
            best = z;
    }
    return best;
}

/* RMS of the second differences of a height sequence (NaN = gap). */
static void sk_bend_add(const double *z, int n, double *sum, int *cnt)
{
    int i;
    for (i = 1; i + 1 < n; i++)
        if (!isnan(z[i - 1]) && !isnan(z[i]) && !isnan(z[i + 1])) {
            double b = z[i - 1] - 2.0 * z[i] + z[i + 1];
            *sum += b * b;
            (*cnt)++;
        }
}

/* c_s, the path smoothness constraint (Zhou et al. name it among the user
 * constraints c_i without defining it; this is TerraSynth's reading): along
 * each arm of the site, the crest heights every half radius out to twice
 * the radius, where the candidate holds the inner three (to the circle) and
 * the output what is already placed.  Where both are known the output
 * wins, as in the merge; the candidate elsewhere, raised by the mean
 * difference to the output where both are known (what the Poisson seam
 * removal does to it).  c_s is the RMS second difference of that joined
 * profile (metres): it grows with a crest that bends in height inside the
 * patch, and with a crest whose trend breaks where it meets the placed
 * one.  A path site's two arms make one profile through the centre. */
static double sk_smoothness(const sketcher *k, const ts_feature_site *s, const sk_view *cand)
{
    const sk_view outv = {k->out, NULL, 0.0, 0.0};
    double c[TS_SITE_MAX_ARMS][5], o[TS_SITE_MAX_ARMS][5], delta = 0.0, sum = 0.0;
    int arms = s->n_ctrl - 1, i, m, nd = 0, cnt = 0;
    if (arms < 1)
        return 0.0;
    for (i = 0; i < arms; i++) {
        double dx = s->px[i + 1], dy = s->py[i + 1], len = hypot(dx, dy), ux, uy;
        if (len <= 0)
            len = 1.0, dx = 1.0, dy = 0.0;
        ux = dx / len;
        uy = dy / len;
        for (m = 0; m < 5; m++) {
            double t = 0.5 * m * k->R, x = s->cx + t * ux, y = s->cy + t * uy;
            c[i][m] = m <= 2 ? sk_crest(k, cand, x, y, -uy, ux) : NAN;
            o[i][m] = sk_crest(k, &outv, x, y, -uy, ux);
            if (!isnan(c[i][m]) && !isnan(o[i][m])) {
                delta += o[i][m] - c[i][m];
                nd++;
            }
        }
    }
    if (nd)
        delta /= nd;
    for (i = 0; i < arms; i++)
        for (m = 0; m < 5; m++)
            if (isnan(o[i][m]))
                o[i][m] = isnan(c[i][m]) ? NAN : c[i][m] + delta;
    if (s->type == TS_SITE_PATH && arms == 2) {
        double z[9];
        for (m = 0; m < 5; m++) {
            z[4 - m] = o[0][m];
            z[4 + m] = o[1][m];
        }
        sk_bend_add(z, 9, &sum, &cnt);
    } else {
        for (i = 0; i < arms; i++)
            sk_bend_add(o[i], 5, &sum, &cnt);
    }
    return cnt ? sqrt(sum / cnt) : 0.0;
}

/* c_f: RMS difference of 7-point profiles across the feature at the
 * control points, between the candidate and the output; with `wanted`,
 * also alpha_h RMS(candidate - heights) + alpha_r RMS(candidate - guide)
 * at the same points (the estimate used before warping). */
static double sk_profile_cost(const sketcher *k, const ts_feature_site *s, const sk_view *cand,
                              double *wanted)
{
    int i, j, n = 0, nh = 0, ng = 0, W = k->out->width;
    double sum = 0.0, sh = 0.0, sg = 0.0, step = k->R / 4.0;
    for (i = 1; i < s->n_ctrl; i++) {
        double dx = s->px[i], dy = s->py[i], len = hypot(dx, dy), nx, ny;
        if (len <= 0)
            continue;
        nx = -dy / len;
        ny = dx / len;
        for (j = -3; j <= 3; j++) {
            double x = s->cx + dx + j * step * nx, y = s->cy + dy + j * step * ny;
            double a = sk_sample(k->out, x, y);
            double b = sk_value(cand, x, y);
            if (isnan(b))
                continue;
            if (!isnan(a)) {
                sum += (a - b) * (a - b);
                n++;
            }
            if (wanted) {
                long ix = lround(x), iy = lround(y);
                if (ix >= 0 && iy >= 0 && ix < W && iy < k->out->height) {
                    size_t at = (size_t)iy * (size_t)W + (size_t)ix;
                    if (k->p->heights && k->p->alpha_h > 0 && !isnan(k->p->heights[at])) {
                        sh += (b - k->p->heights[at]) * (b - k->p->heights[at]);
                        nh++;
                    }
                    if (k->p->guide && k->p->alpha_r > 0 && !isnan(k->p->guide[at])) {
                        sg += (b - k->p->guide[at]) * (b - k->p->guide[at]);
                        ng++;
                    }
                }
            }
        }
    }
    if (wanted)
        *wanted =
            (nh ? k->p->alpha_h * sqrt(sh / nh) : 0.0) + (ng ? k->p->alpha_r * sqrt(sg / ng) : 0.0);
    return n ? sqrt(sum / n) : 0.0;
}

/* c_p, crest prominence (a TerraSynth addition): how far the candidate's
 * crest (valleys: thalweg) stands out across the feature at a scale of an
 * eighth of a patch, at the control points and half-way to them: the
 * extreme near the point against the mean of the land P/8 cells off on
 * both sides, in metres, negated (the more prominent, the cheaper).  A
 * stroke stands for a main ridge: among candidates that fit, the sharpest
 * make it read as one. */
static double sk_prominence(const sketcher *k, const ts_feature_site *s, const sk_view *cand)
{
    double sum = 0.0, off = k->P / 8.0;
    int i, m, n = 0;
    for (i = 1; i < s->n_ctrl; i++) {
        double dx = s->px[i], dy = s->py[i], len = hypot(dx, dy), nx, ny;
        if (len <= 0)
            continue;
        nx = -dy / len;
        ny = dx / len;
        for (m = 1; m <= 2; m++) {
            double x = s->cx + 0.5 * m * dx, y = s->cy + 0.5 * m * dy;
            double c = sk_crest(k, cand, x, y, nx, ny);
            double a = sk_value(cand, x + off * nx, y + off * ny);
            double b = sk_value(cand, x - off * nx, y - off * ny);
            if (isnan(c) || isnan(a) || isnan(b))
                continue;
            sum += k->kind == TS_VALLEY ? 0.5 * (a + b) - c : c - 0.5 * (a + b);
            n++;
        }
    }
    return n ? -sum / n : 0.0;
}

/* ---- one site ------------------------------------------------------ */

/* Insert c into the sorted pool[0..*n) holding at most max. */
static void sk_pool_insert(candidate *pool, int *n, int max, const candidate *c)
{
    int at;
    if (*n >= max && sk_cand_cmp(c, &pool[*n - 1]) >= 0)
        return;
    at = *n < max ? (*n)++ : max - 1;
    while (at > 0 && sk_cand_cmp(c, &pool[at - 1]) < 0) {
        pool[at] = pool[at - 1];
        at--;
    }
    pool[at] = *c;
}

/* The deformation scan over the exemplar sites, in chunks that run in
 * parallel, each keeping its own best pool_max. */
typedef struct scan_job {
    sketcher *k;
    const ts_feature_site *s;
    int only;
    double wcx, wcy;
    int n_chunks;
} scan_job;

static void sk_scan_chunks(void *arg, size_t b, size_t e)
{
    scan_job *j = arg;
    sketcher *k = j->k;
    const ts_feature_site *s = j->s;
    ts_ctx *c = ts__ctx_child(k->ctx); /* a failed fit only skips that alignment */
    size_t t;
    for (t = b; t < e; t++) {
        candidate *pool = k->chunk_pool + t * (size_t)k->pool_max;
        size_t lo = t * k->n_es / (size_t)j->n_chunks;
        size_t hi = (t + 1) * k->n_es / (size_t)j->n_chunks;
        size_t i;
        int n = 0;
        if (!c) {
            k->chunk_n[t] = -1; /* out of memory, reported by the caller */
            continue;
        }
        if (ts__cancelled(c)) {
            k->chunk_n[t] = 0; /* the caller reports it */
            continue;
        }
        for (i = lo; i < hi; i++) {
            const ts_feature_site *es = &k->es[i].site;
            int rot, mirror, rots, mirrors;
            if (es->type != s->type || es->kind != s->kind || es->n_ctrl != s->n_ctrl ||
                (j->only >= 0 && k->es[i].ex != j->only))
                continue;
            rots = s->type == TS_SITE_BRANCH ? s->degree : s->type == TS_SITE_PATH ? 2 : 1;
            mirrors = s->type == TS_SITE_BRANCH ? 2 : 1;
            for (mirror = 0; mirror < mirrors; mirror++)
                for (rot = 0; rot < rots; rot++) {
                    candidate cand;
                    cand.idx = (int)i;
                    cand.rot = rot;
                    cand.mirror = mirror;
                    /* the deformation first; the inverse map only for a pool member */
                    if (sk_align(k, c, s, es, rot, mirror, j->wcx, j->wcy, &cand.cd, NULL) != 0)
                        continue;
                    if (n >= k->pool_max && sk_cand_cmp(&cand, &pool[n - 1]) >= 0)
                        continue;
                    if (sk_align(k, c, s, es, rot, mirror, j->wcx, j->wcy, NULL, &cand.inv) != 0)
                        continue;
                    cand.pre = cand.cd;
                    sk_pool_insert(pool, &n, k->pool_max, &cand);
                }
        }
        k->chunk_n[t] = n;
    }
    ts_ctx_free(c);
}

/* Distance from (x, y) (relative to the site's centre) to the site's arms,
 * the segments from the centre to each control point. */
static double sk_arms_distance(const ts_feature_site *s, double x, double y)
{
    double best = INFINITY;
    int i;
    for (i = 1; i < s->n_ctrl; i++) {
        double ax = s->px[i], ay = s->py[i], l2 = ax * ax + ay * ay, t, d;
        t = l2 > 0 ? (x * ax + y * ay) / l2 : 0.0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        d = hypot(x - t * ax, y - t * ay);
        best = d < best ? d : best;
    }
    return best;
}

/* What the candidates' rounds on the thread pool read (sk_pre_range,
 * sk_eval_range): the site and its window's corner. */
typedef struct eval_job {
    sketcher *k;
    const ts_feature_site *s;
    int wx, wy;
} eval_job;

/* Round (c) for candidates [b, e): the warp, the graph cut and the costs,
 * each in its own slot with a private context, so they run in parallel
 * (the output is only read). */
static void sk_eval_range(void *arg, size_t b, size_t e)
{
    eval_job *j = arg;
    sketcher *k = j->k;
    const ts_feature_site *s = j->s;
    int P = k->P, M = P + 2, W = k->out->width, wx = j->wx, wy = j->wy, x, y;
    size_t P2 = (size_t)P * (size_t)P, M2 = (size_t)M * (size_t)M, i;
    ts_ctx *c = ts__ctx_child(k->ctx);
    for (i = b; i < e; i++) {
        const ts_raster *exr = &k->ex[k->es[k->cands[i].idx].ex];
        float *rd = k->c_ring + i * M2, *patch = k->c_patch + i * P2;
        unsigned char *cons = k->c_cons + i * P2, *lab = k->c_labels + i * P2;
        unsigned char *core = k->c_core + i * P2;
        ts_raster ring = ts_raster_wrap(rd, M, M, M);
        ts_raster oldr = ts_raster_wrap(k->old, P, P, P);
        ts_raster pr = ts_raster_wrap(patch, P, P, P);
        double cg = 0.0, cf, cs, cp;
        int cuts, core_n = 0;
        ts_status st;
        k->c_cost[i] = INFINITY;
        k->c_status[i] = TS_OK;
        if (!c) {
            k->c_status[i] = TS_ERR_NOMEM;
            continue;
        }
        if (ts__cancelled(c))
            continue; /* the caller reports it */
        /* the warped window with its ring: window cell (x - 1, y - 1) */
        if ((st = ts__tps_warp(c, &k->cands[i].inv, exr, -1.0, -1.0, &ring)) != TS_OK) {
            k->c_status[i] = st;
            continue;
        }
        for (y = 0; y < P; y++)
            for (x = 0; x < P; x++)
                patch[y * P + x] = rd[(y + 1) * M + x + 1];
        /* constraints: the sketch's feature cells near the centre come from
         * the patch; filled border cells next to filled outside cells stay */
        for (y = 0; y < P; y++)
            for (x = 0; x < P; x++) {
                int ox = wx + x, oy = wy + y;
                unsigned char cc = TS_SEAM_FREE;
                int feature = k->near[y * P + x] <= k->core_radius &&
                              k->fixnear[y * P + x] > k->core_radius &&
                              hypot(ox - s->cx, oy - s->cy) <= k->R &&
                              (s->type != TS_SITE_PATH ||
                               sk_arms_distance(s, ox - s->cx, oy - s->cy) <= 2 * k->core_radius);
                core[y * P + x] = 0;
                if (!isnan(k->old[y * P + x])) {
                    if (ts__border_keeps_old(k->out, wx, wy, P, x, y))
                        cc = TS_SEAM_OLD;
                    if (k->flags[(size_t)oy * (size_t)W + (size_t)ox] & TS_CELL_FIXED)
                        cc = TS_SEAM_OLD;
                }
                if (feature && cc == TS_SEAM_FREE && !isnan(patch[y * P + x])) {
                    cc = TS_SEAM_NEW;
                    core[y * P + x] = 1;
                    core_n++;
                }
                if (k->flags[(size_t)oy * (size_t)W + (size_t)ox] & TS_CELL_NODATA)
                    cc = TS_SEAM_FREE;
                cons[y * P + x] = cc;
            }
        if (core_n == 0)
            continue; /* the warp left the feature empty */
        if ((st = ts_seam_graphcut(c, &oldr, &pr, cons, lab, &cg)) != TS_OK) {
            k->c_status[i] = st;
            continue;
        }
        cuts = ts__label_cut_edges(lab, P);
        {
            sk_view v = {&ring, NULL, 1.0 - wx, 1.0 - wy};
            cf = sk_profile_cost(k, s, &v, NULL);
            cs = k->sp->alpha_s > 0 ? sk_smoothness(k, s, &v) : 0.0;
            cp = k->sp->alpha_p > 0 ? sk_prominence(k, s, &v) : 0.0;
        }
        k->c_cost[i] = k->sp->alpha_d * k->cands[i].cd +
                       k->p->s.alpha_g * cg / (2.0 * TS_MAX(1, cuts)) + k->sp->alpha_f * cf +
                       k->sp->alpha_s * cs + k->sp->alpha_p * cp +
                       ts__height_cost(k->p, W, wx, wy, P, patch, P);
    }
    ts_ctx_free(c);
}

/* A path site through the two arms of branch site s that make the
 * straightest line (the pair whose directions are most nearly opposite);
 * 0 when s has fewer than two arms. */
static int sk_straightest_path(const ts_feature_site *s, ts_feature_site *ps)
{
    int a, b, ba = -1, bb = -1, arms = s->n_ctrl - 1;
    double best = INFINITY;
    for (a = 1; a <= arms; a++)
        for (b = a + 1; b <= arms; b++) {
            double la = hypot(s->px[a], s->py[a]), lb = hypot(s->px[b], s->py[b]), c;
            if (la <= 0 || lb <= 0)
                continue;
            c = (s->px[a] * s->px[b] + s->py[a] * s->py[b]) / (la * lb); /* -1: opposite */
            if (c < best) {
                best = c;
                ba = a;
                bb = b;
            }
        }
    if (ba < 0)
        return 0;
    *ps = *s;
    ps->type = TS_SITE_PATH;
    ps->degree = 2;
    ps->n_ctrl = 3;
    ps->px[1] = s->px[ba];
    ps->py[1] = s->py[ba];
    ps->px[2] = s->px[bb];
    ps->py[2] = s->py[bb];
    return 1;
}

/* Candidates [b, e) of the pool: their profile costs estimated on the
 * exemplar through each warp (c->pre), INFINITY for a warp that folds
 * anywhere over the window with its ring or squeezes or stretches areas
 * more than 2.5 times. */
static void sk_pre_range(void *arg, size_t b, size_t e)
{
    const eval_job *j = arg;
    const sketcher *k = j->k;
    const ts_feature_site *s = j->s;
    size_t i;
    for (i = b; i < e; i++) {
        candidate *c = &k->pool[i];
        sk_view v = {&k->ex[k->es[c->idx].ex], &c->inv, j->wx, j->wy};
        double want = 0.0, cf, cs, cp;
        if (ts__tps_folds(&c->inv, s->cx - j->wx + 0.5, s->cy - j->wy + 0.5, 0.5 * k->P + 1.0, 13,
                          2.5)) {
            c->pre = INFINITY;
            continue;
        }
        cf = sk_profile_cost(k, s, &v, &want);
        cs = k->sp->alpha_s > 0 ? sk_smoothness(k, s, &v) : 0.0;
        cp = k->sp->alpha_p > 0 ? sk_prominence(k, s, &v) : 0.0;
        c->pre = k->sp->alpha_d * c->cd + k->sp->alpha_f * cf + k->sp->alpha_s * cs +
                 k->sp->alpha_p * cp + want;
    }
}

static ts_status sk_place_site(sketcher *k, const ts_feature_site *s, int index, int *placed);

static ts_status sk_place_site(sketcher *k, const ts_feature_site *s, int index, int *placed)
{
    ts_ctx *ctx = k->ctx;
    int P = k->P, W = k->out->width, H = k->out->height;
    size_t P2 = (size_t)P * (size_t)P, M2 = (size_t)(P + 2) * (size_t)(P + 2);
    int wx = (int)lround(s->cx) - P / 2, wy = (int)lround(s->cy) - P / 2, x, y;
    int n_c = 0, n_pool = 0, kmax = k->p->s.candidates, i, best = -1;
    double best_cost = INFINITY;
    eval_job ej; /* the candidates' rounds on the pool: the site and its window's corner */
    ts_status st;
    *placed = 0;
    k->kind = s->kind; /* the feature the site stands on: its crest or thalweg */
    wx = TS_MAX(0, TS_MIN(W - P, wx));
    wy = TS_MAX(0, TS_MIN(H - P, wy));
    /* candidates by deformation */
    int only = -1;
    if (k->p->cell_exemplar) {
        int c = k->p->cell_exemplar[(size_t)lround(s->cy) * (size_t)W + (size_t)lround(s->cx)];
        only = (c >= 0 && c < k->n_ex) ? c : -1;
    }
    {
        scan_job j;
        int t;
        j.k = k;
        j.s = s;
        j.only = only;
        j.wcx = s->cx - wx;
        j.wcy = s->cy - wy;
        j.n_chunks = k->n_chunks;
        ts__parallel_for(ctx, (size_t)j.n_chunks, sk_scan_chunks, &j);
        if (ts__check_cancel(ctx) != TS_OK)
            return ctx->status;
        /* merge the chunks' pools: the best pool_max overall, in a total
         * order, so the result does not depend on the split */
        for (t = 0; t < j.n_chunks; t++) {
            const candidate *cp = k->chunk_pool + (size_t)t * (size_t)k->pool_max;
            if (k->chunk_n[t] < 0)
                return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
            for (i = 0; i < k->chunk_n[t]; i++)
                sk_pool_insert(k->pool, &n_pool, k->pool_max, &cp[i]);
        }
    }
    /* the profile costs, estimated on the exemplar through each warp, pick
     * the k that are warped and cut; a warp that folds anywhere over the
     * window with its ring, or squeezes or stretches areas more than 2.5
     * times, is never used */
    ej.k = k;
    ej.s = s;
    ej.wx = wx;
    ej.wy = wy;
    ts__parallel_for(ctx, (size_t)n_pool, sk_pre_range, &ej);
    qsort(k->pool, (size_t)n_pool, sizeof *k->pool, sk_pre_cmp);
    while (n_pool > 0 && !isfinite(k->pool[n_pool - 1].pre))
        n_pool--;
    if (n_pool == 0) {
        /* no exemplar junction of this degree, or every warp folds: compose
         * it, a path patch through its two straightest-joined arms (the
         * other arms get their own path patches along their chains) */
        ts_feature_site ps;
        if (s->type != TS_SITE_BRANCH || !sk_straightest_path(s, &ps))
            return TS_OK; /* no such feature in the exemplars: left to the fill */
        return sk_place_site(k, &ps, index, placed);
    }
    n_c = TS_MIN(n_pool, kmax);
    memcpy(k->cands, k->pool, (size_t)n_c * sizeof *k->cands);
    /* the old window */
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++)
            k->old[y * P + x] = TS_PIX(k->out, wx + x, wy + y);
    /* distance of each window cell to the sketch's feature (the core of a
     * feature patch is the feature with its flanks) */
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++)
            k->near[y * P + x] =
                (k->sf->mask[(size_t)(wy + y) * (size_t)W + (size_t)(wx + x)] & k->kind) ? 0
                                                                                         : 2 * P;
    ts__chamfer_chebyshev(k->near, P);
    /* and to the cells fixed before: a new core keeps its distance, so the
     * cut finds a seam between two cores that the seam removal can smooth */
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++)
            k->fixnear[y * P + x] =
                (k->flags[(size_t)(wy + y) * (size_t)W + (size_t)(wx + x)] & TS_CELL_FIXED) ? 0
                                                                                            : 2 * P;
    ts__chamfer_chebyshev(k->fixnear, P);
    /* round (c): warps and graph cuts, in parallel */
    {
        ts__parallel_for(ctx, (size_t)n_c, sk_eval_range, &ej);
        if (ts__check_cancel(ctx) != TS_OK)
            return ctx->status;
        for (i = 0; i < n_c; i++) {
            if (k->c_status[i] != TS_OK)
                return ts__fail(ctx, k->c_status[i], "sketch",
                                "a feature patch candidate failed: %s",
                                ts_status_str(k->c_status[i]));
            if (k->c_cost[i] < best_cost) {
                best_cost = k->c_cost[i];
                best = i;
            }
        }
    }
    if (best < 0)
        return TS_OK;
    memcpy(k->merger.new_m, k->c_ring + (size_t)best * M2, M2 * sizeof(float));
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++) {
            double ex_x, ex_y;
            ts__tps_map(&k->cands[best].inv, x + 0.5, y + 0.5, &ex_x, &ex_y);
            k->src_x[y * P + x] = (int32_t)floor(ex_x);
            k->src_y[y * P + x] = (int32_t)floor(ex_y);
        }
    st = ts__merger_apply(ctx, &k->merger, k->out, k->flags, wx, wy, k->old,
                          k->c_labels + (size_t)best * P2, k->maps, k->es[k->cands[best].idx].ex,
                          k->src_x, k->src_y, index);
    if (st != TS_OK)
        return st;
    /* the feature cells stay as placed */
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++)
            if (k->c_core[(size_t)best * P2 + (size_t)(y * P + x)] &&
                k->c_labels[(size_t)best * P2 + (size_t)(y * P + x)])
                k->flags[(size_t)(wy + y) * (size_t)W + (size_t)(wx + x)] |= TS_CELL_FIXED;
    *placed = 1;
    return TS_OK;
}

/* ---- the entry point ----------------------------------------------- */

static void sk_free(sketcher *k)
{
    ts__merger_free(&k->merger);
    free(k->old);
    free(k->c_ring);
    free(k->c_patch);
    free(k->c_cons);
    free(k->c_labels);
    free(k->c_core);
    free(k->c_cost);
    free(k->c_status);
    free(k->src_x);
    free(k->src_y);
    free(k->near);
    free(k->fixnear);
    free(k->cands);
    free(k->pool);
    free(k->chunk_pool);
    free(k->chunk_n);
}

ts_status ts__place_features(ts_ctx *ctx, const ts__feature_job *j, ts_raster *out,
                             unsigned char *flags, ts_synth_maps *maps, size_t *n_placed)
{
    sketcher k;
    size_t P2, M2, i;
    int first_index = maps ? maps->n_patches : 0, n = 0;
    ts_status st = TS_OK;
    *n_placed = 0;
    memset(&k, 0, sizeof k);
    k.ctx = ctx;
    k.sp = j->sp;
    k.p = j->fill;
    k.ex = j->exemplars;
    k.n_ex = j->n_exemplars;
    k.out = out;
    k.flags = flags;
    k.sf = j->sketch_features;
    k.kind = j->kind;
    k.es = j->exemplar_sites;
    k.n_es = j->n_exemplar_sites;
    k.maps = maps;
    k.P = (int)j->fill->s.patch_size.value;
    k.R = 0.5 * k.P - 1.0;
    P2 = (size_t)k.P * (size_t)k.P;
    M2 = (size_t)(k.P + 2) * (size_t)(k.P + 2);
    k.old = ts__malloc_array(P2, sizeof(float));
    {
        size_t kc = (size_t)k.p->s.candidates;
        k.c_ring = ts__malloc_array(kc * M2, sizeof(float));
        k.c_patch = ts__malloc_array(kc * P2, sizeof(float));
        k.c_cons = ts__malloc_array(kc * P2, 1);
        k.c_labels = ts__malloc_array(kc * P2, 1);
        k.c_core = ts__malloc_array(kc * P2, 1);
        k.c_cost = ts__malloc_array(kc, sizeof(double));
        k.c_status = ts__malloc_array(kc, sizeof(ts_status));
    }
    k.src_x = ts__malloc_array(P2, sizeof(int32_t));
    k.src_y = ts__malloc_array(P2, sizeof(int32_t));
    k.cands = ts__malloc_array((size_t)k.p->s.candidates, sizeof *k.cands);
    k.pool_max = TS_MAX(64, 8 * k.p->s.candidates);
    k.pool = ts__malloc_array((size_t)k.pool_max, sizeof *k.pool);
    k.n_chunks = 4 * ts__thread_count(ctx, 1u << 20);
    k.chunk_pool = ts__malloc_array((size_t)k.n_chunks * (size_t)k.pool_max, sizeof *k.chunk_pool);
    k.chunk_n = ts__calloc_array((size_t)k.n_chunks, sizeof *k.chunk_n);
    k.near = ts__malloc_array(P2, sizeof(int));
    k.fixnear = ts__malloc_array(P2, sizeof(int));
    k.core_radius = TS_MAX(1, k.P / 8);
    if (!k.old || !k.c_ring || !k.c_patch || !k.c_cons || !k.c_labels || !k.c_core || !k.c_cost ||
        !k.c_status || !k.src_x || !k.src_y || !k.cands || !k.pool || !k.chunk_pool || !k.chunk_n ||
        !k.near || !k.fixnear ||
        ts__merger_init(ctx, &k.merger, k.P, (int)k.p->s.overlap.value) != TS_OK) {
        sk_free(&k);
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    }
    for (i = 0; i < j->n_sites; i++) {
        int placed;
        double f = (double)i / (double)j->n_sites;
        ts_progress_saved sv = ts__progress_push(ctx, f, f);
        st = sk_place_site(&k, &j->sites[i], first_index + n, &placed);
        if (st == TS_OK)
            st = ts__progress(ctx, 0.0, "feature patches");
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            break;
        n += placed;
    }
    if (maps)
        maps->n_patches = first_index + n;
    *n_placed = (size_t)n;
    sk_free(&k);
    return st;
}
