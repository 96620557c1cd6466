/*
 * crest_profile.c - peaks and saddles along a sketch's ridges (a TerraSynth
 * addition to Zhou et al. 2007, in the spirit of their feature patches:
 * the profile comes from the exemplars, not from a formula).
 *
 * Feature patches give a sketched ridge the exemplars' crests up to about
 * a patch long; the layout (layout.c) then sets the ridge's large-scale
 * height to one level, so a drawn crest kept its small bumps but no peaks
 * and saddles a patch or more apart: a long even embankment.  Here every
 * exemplar's main ridge paths give their heights along the crest, a cell
 * of arc length apart, band-passed between P/4 and 2P (P the patch): the
 * peaks and saddles the layout would level, without the path's overall
 * rise or fall.  Along every ridge path of the sketch these pieces are laid
 * end to end, each from a seeded piece and position, joined by equal-power
 * cross-fades over P/4 (sin/cos weights: two unrelated pieces keep their
 * variance through the join); every node (branch point, end) takes a value
 * of its own from the same pieces and the paths meeting there are bent
 * linearly to it, so the crest is continuous through junctions.  The
 * layout adds the offsets to its level along the ridges, fading with the
 * distance from them (layout.c): a peak over a quarter patch, so it stands
 * out above its flanks; a saddle over a patch, so the land around a pass
 * is low too and the ridge stays convex across it; with valleys drawn too,
 * both fade out over two patches towards them, so valley walls are no
 * steeper.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "crest_profile.h"
#include "layout.h"
#include "relief_guide.h"

void ts__crest_library_free(ts__crest_library *lib)
{
    if (!lib)
        return;
    free(lib->z);
    free(lib->start);
    memset(lib, 0, sizeof *lib);
}

/* Arc length of the path's vertices v[0..n) (cells): s[k], s[0] = 0. */
static void crest_arc(const ts_feature_vertex *v, size_t n, double *s)
{
    size_t k;
    s[0] = 0.0;
    for (k = 1; k < n; k++)
        s[k] = s[k - 1] + hypot((double)(v[k].x - v[k - 1].x), (double)(v[k].y - v[k - 1].y));
}

/* Heights of the path every cell of arc length (*m of them, into z):
 * linear between its vertices; 0 when a vertex has no height. */
static int crest_resample(const ts_feature_vertex *v, const double *s, size_t n, double *z,
                          size_t *m)
{
    size_t k, j = 0, cnt = (size_t)floor(s[n - 1]) + 1;
    for (k = 0; k < n; k++)
        if (!isfinite(v[k].z))
            return 0;
    for (k = 0; k < cnt; k++) {
        double t = (double)k, f;
        while (j + 2 < n && s[j + 1] < t)
            j++;
        f = s[j + 1] > s[j] ? (t - s[j]) / (s[j + 1] - s[j]) : 0.0;
        f = f < 0.0 ? 0.0 : f > 1.0 ? 1.0 : f;
        z[k] = (1.0 - f) * v[j].z + f * v[j + 1].z;
    }
    *m = cnt;
    return 1;
}

/* A Gaussian of sigma cut at 3 sigma: w[d] = exp(-(d / sigma)^2 / 2) for
 * d = 0..r (library-allocated, free(); NULL when out of memory). */
static double *crest_kernel(double sigma, long *r)
{
    long d;
    double *w;
    *r = (long)ceil(3.0 * sigma);
    w = ts__malloc_array((size_t)*r + 1, sizeof(double));
    for (d = 0; w && d <= *r; d++) {
        double u = (double)d / sigma;
        w[d] = exp(-0.5 * u * u);
    }
    return w;
}

/* The Gaussian (kernel w, radius r) of z[0..m) at k, its weights
 * renormalised over the piece. */
static double crest_gauss(const double *z, size_t m, size_t k, const double *w, long r)
{
    long a = (long)k - r, b = (long)k + r, i;
    double sw = 0.0, sz = 0.0;
    a = a < 0 ? 0 : a;
    b = b >= (long)m ? (long)m - 1 : b;
    for (i = a; i <= b; i++) {
        double wi = w[labs(i - (long)k)];
        sw += wi;
        sz += wi * z[i];
    }
    return sz / sw;
}

ts_status ts__crest_library_measure(ts_ctx *ctx, const ts_features *ef, int patch,
                                    ts__crest_library *lib)
{
    size_t p, total = 0, used = 0, np = 0, k, longest = 0;
    double *s = NULL, *z = NULL, *w_lo = NULL, *w_hi = NULL;
    long r_lo, r_hi;
    ts_status st = TS_OK;
    memset(lib, 0, sizeof *lib);
    if (!ef || patch < 8)
        return TS_OK;
    for (p = 0; p < ef->n_paths; p++)
        if (ef->paths[p].kind == TS_RIDGE && ef->paths[p].count >= 2) {
            total += ef->paths[p].count * 2; /* arc length <= sqrt(2) a step */
            longest = TS_MAX(longest, ef->paths[p].count * 2);
            np++;
        }
    if (!np)
        return TS_OK;
    lib->z = ts__malloc_array(total, sizeof(float));
    lib->start = ts__malloc_array(np + 1, sizeof(size_t));
    s = ts__malloc_array(longest, sizeof(double));
    z = ts__malloc_array(longest, sizeof(double));
    w_lo = crest_kernel(patch / 4.0, &r_lo);
    w_hi = crest_kernel(2.0 * patch, &r_hi);
    if (!lib->z || !lib->start || !s || !z || !w_lo || !w_hi) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "crest profile", "out of memory");
        goto done;
    }
    lib->start[0] = 0;
    for (p = 0; p < ef->n_paths; p++) {
        const ts_feature_path *fp = &ef->paths[p];
        const ts_feature_vertex *v = ef->verts + fp->first;
        size_t m;
        if (fp->kind != TS_RIDGE || fp->count < 2)
            continue;
        crest_arc(v, fp->count, s);
        if (s[fp->count - 1] + 1.0 < patch || !crest_resample(v, s, fp->count, z, &m))
            continue;
        for (k = 0; k < m; k++)
            lib->z[used + k] =
                (float)(crest_gauss(z, m, k, w_lo, r_lo) - crest_gauss(z, m, k, w_hi, r_hi));
        used += m;
        lib->start[++lib->n_pieces] = used;
        if ((st = ts__progress(ctx, 0.0, "crest profile")) != TS_OK)
            goto done;
    }
done:
    free(s);
    free(z);
    free(w_lo);
    free(w_hi);
    if (st != TS_OK || !lib->n_pieces)
        ts__crest_library_free(lib);
    return st;
}

/* The library a sketch path takes: its middle cell's region's exemplar
 * when that one has pieces, else a seeded pick among those that have. */
static const ts__crest_library *crest_pick_library(const ts__crest_library *libs, int n_libs,
                                                   const int32_t *cell_exemplar, size_t mid,
                                                   uint64_t h)
{
    int e, n = 0;
    if (cell_exemplar) {
        int ce = cell_exemplar[mid];
        if (ce >= 0 && ce < n_libs && libs[ce].n_pieces)
            return &libs[ce];
    }
    for (e = 0; e < n_libs; e++)
        n += libs[e].n_pieces > 0;
    if (!n)
        return NULL;
    n = (int)(h % (uint64_t)n);
    for (e = 0; e < n_libs; e++)
        if (libs[e].n_pieces > 0 && n-- == 0)
            return &libs[e];
    return NULL;
}

/* A node's own offset: one height of a seeded piece at a seeded place. */
static double crest_node_value(const ts__crest_library *lib, uint64_t h1, uint64_t h2)
{
    size_t k = (size_t)(h1 % lib->n_pieces), len = lib->start[k + 1] - lib->start[k];
    return lib->z[lib->start[k] + (size_t)(h2 % len)];
}

/* The profile of a path m cells of arc long into prof[0..m): pieces from
 * seeded places chained with cross-fades over B cells. */
static void crest_chain(const ts__crest_library *lib, uint64_t seed, size_t path, size_t m, int B,
                        double *prof)
{
    size_t pos = 0, j = 0;
    memset(prof, 0, m * sizeof *prof);
    for (;;) {
        uint64_t w[3] = {(uint64_t)path, (uint64_t)j, 1}, h1, h2;
        size_t k, len, u, avail, t;
        h1 = ts__hash_words(seed, w, 3);
        w[2] = 2;
        h2 = ts__hash_words(seed, w, 3);
        k = (size_t)(h1 % lib->n_pieces);
        len = lib->start[k + 1] - lib->start[k];
        /* a start that leaves more than 2B cells of the piece (every piece
         * is a patch = 4B long or more) */
        u = len > (size_t)(2 * B + 1) ? (size_t)(h2 % (len - (size_t)(2 * B + 1))) : 0;
        avail = len - u;
        for (t = 0; t < avail && pos + t < m; t++) {
            double v = lib->z[lib->start[k] + u + t];
            if (pos > 0 && t < (size_t)B) {
                double a = 0.5 * TS_PI * ((double)t + 0.5) / B;
                prof[pos + t] = cos(a) * prof[pos + t] + sin(a) * v;
            } else
                prof[pos + t] = v;
        }
        if (pos + avail >= m || avail <= (size_t)B)
            break;
        pos += avail - (size_t)B;
        j++;
    }
}

ts_status ts__crest_offsets(ts_ctx *ctx, const ts_features *sf, const ts__crest_library *libs,
                            int n_libs, const int32_t *cell_exemplar, int patch, uint64_t seed,
                            float *off, int *any)
{
    size_t n = (size_t)sf->width * (size_t)sf->height, i, p, longest = 2, k;
    double *s, *prof;
    int B = TS_MAX(1, patch / 4);
    *any = 0;
    for (i = 0; i < n; i++)
        off[i] = NAN;
    for (p = 0; p < sf->n_paths; p++)
        longest = TS_MAX(longest, sf->paths[p].count * 2 + 2);
    s = ts__malloc_array(longest, sizeof(double));
    prof = ts__malloc_array(longest, sizeof(double));
    if (!s || !prof) {
        free(s);
        free(prof);
        return ts__fail(ctx, TS_ERR_NOMEM, "crest profile", "out of memory");
    }
    for (p = 0; p < sf->n_paths; p++) {
        const ts_feature_path *fp = &sf->paths[p];
        const ts_feature_vertex *v = sf->verts + fp->first;
        const ts__crest_library *lib;
        uint64_t wa[2] = {(uint64_t)fp->node_a, 7}, wb[2] = {(uint64_t)fp->node_b, 7};
        size_t m, mid;
        double za, zb, a0, b0;
        if (fp->kind != TS_RIDGE || fp->count < 1)
            continue;
        mid = (size_t)v[fp->count / 2].y * (size_t)sf->width + (size_t)v[fp->count / 2].x;
        {
            uint64_t w[2] = {(uint64_t)p, 5};
            lib = crest_pick_library(libs, n_libs, cell_exemplar, mid, ts__hash_words(seed, w, 2));
        }
        if (!lib)
            continue;
        crest_arc(v, fp->count, s);
        m = (size_t)floor(s[fp->count - 1]) + 1;
        crest_chain(lib, seed, p, m, B, prof);
        /* the ends bent linearly to their nodes' own values */
        za = crest_node_value(lib, ts__hash_words(seed, wa, 2), ts__hash_words(seed ^ 1u, wa, 2));
        zb = crest_node_value(lib, ts__hash_words(seed, wb, 2), ts__hash_words(seed ^ 1u, wb, 2));
        a0 = za - prof[0];
        b0 = zb - prof[m - 1];
        for (k = 0; k < fp->count; k++) {
            double t = m > 1 ? s[k] / s[fp->count - 1] : 0.0, q = s[k], f;
            size_t q0 = (size_t)floor(q);
            f = q - (double)q0;
            q = q0 + 1 < m ? (1.0 - f) * prof[q0] + f * prof[q0 + 1] : prof[m - 1];
            if (v[k].x < 0 || v[k].y < 0 || v[k].x >= sf->width || v[k].y >= sf->height)
                continue;
            off[(size_t)v[k].y * (size_t)sf->width + (size_t)v[k].x] =
                (float)(q + (1.0 - t) * a0 + t * b0);
        }
        *any = 1;
    }
    free(s);
    free(prof);
    return TS_OK;
}

ts_status ts__crest_field(ts_ctx *ctx, const ts_features *sf, const ts__crest_library *libs,
                          int n_libs, const int32_t *cell_exemplar, int patch,
                          const float *valley_dist, double reach, double sigma, double gain,
                          float **add, float **add_hp)
{
    size_t n, i;
    float *off = NULL, *dist = NULL;
    int32_t *near = NULL;
    unsigned char *m = NULL;
    int any = 0;
    ts_status st = TS_OK;
    *add = *add_hp = NULL;
    if (!libs || !sf)
        return TS_OK;
    n = (size_t)sf->width * (size_t)sf->height;
    off = ts__malloc_array(n, sizeof(float));
    dist = ts__malloc_array(n, sizeof(float));
    near = ts__malloc_array(n, sizeof(int32_t));
    m = ts__malloc_array(n, 1);
    if (!off || !dist || !near || !m) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "crest profile", "out of memory");
        goto done;
    }
    st =
        ts__crest_offsets(ctx, sf, libs, n_libs, cell_exemplar, patch, ts_ctx_seed(ctx), off, &any);
    if (st != TS_OK || !any)
        goto done;
    for (i = 0; i < n; i++)
        m[i] = !isnan(off[i]);
    if ((st = ts__distance_transform_nearest(ctx, m, sf->width, sf->height, dist, near)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++) {
        double o = near[i] >= 0 ? off[near[i]] : 0.0;
        double w = gain * exp(-dist[i] / (o < 0.0 ? 4.0 * reach : reach));
        if (valley_dist) {
            double t = valley_dist[i] / (2.0 * patch);
            t = t > 1.0 ? 1.0 : t;
            w *= t * t * (3.0 - 2.0 * t);
        }
        dist[i] = (float)(w * o);
    }
    /* the nearest path cell's offset is constant over a fan of cells
     * behind every corner of the path's staircase: smoothed over a
     * sixteenth of a patch, the fans' steps (metres a cell along a steep
     * crest) do not draw lines across the flanks */
    if ((st = ts__blur_nan(ctx, dist, sf->width, sf->width, sf->height, patch / 16.0, off)) !=
        TS_OK)
        goto done;
    memcpy(dist, off, n * sizeof(float));
    /* off is free from here: the blur of the field (as the layout blurs),
     * then the rest */
    if ((st = ts__blur_nan_coarse(ctx, dist, sf->width, sf->width, sf->height, sigma, off)) !=
        TS_OK)
        goto done;
    for (i = 0; i < n; i++)
        off[i] = dist[i] - off[i];
    *add = dist;
    *add_hp = off;
    dist = off = NULL;
done:
    free(off);
    free(dist);
    free(near);
    free(m);
    return st;
}
