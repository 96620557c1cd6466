/*
 * patch_merge.c - patch merging (Zhou et al. 2007 section 5, appendix B):
 * the cells a graph cut gave to the new patch are written, then the seam
 * is removed by a Poisson solve on the new cells and the old cells within
 * `band` cells of them, with the cells around as Dirichlet boundary.
 * Across the seam the wanted gradient is the mean of the two sources'
 * gradients (Zhou et al. set it to zero, which flattens the slope along
 * every seam and shows as lines in a hillshade).
 * Cost: O(P^2) plus one Poisson solve per merged patch.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "patch_merge.h"

ts_status ts__merger_init(ts_ctx *ctx, ts_merger *m, int P, int band)
{
    size_t M2 = (size_t)(P + 2) * (size_t)(P + 2);
    memset(m, 0, sizeof *m);
    m->P = P;
    m->band = band;
    m->merged = ts__malloc_array(M2, sizeof(float));
    m->old_m = ts__malloc_array(M2, sizeof(float));
    m->new_m = ts__malloc_array(M2, sizeof(float));
    m->sgx = ts__malloc_array(M2, sizeof(float));
    m->sgy = ts__malloc_array(M2, sizeof(float));
    m->mlabels = ts__malloc_array(M2, 1);
    m->region = ts__malloc_array(M2, 1);
    m->dist = ts__malloc_array((size_t)P * (size_t)P, sizeof(int));
    if (!m->merged || !m->old_m || !m->new_m || !m->sgx || !m->sgy || !m->mlabels || !m->region ||
        !m->dist) {
        ts__merger_free(m);
        return ts__fail(ctx, TS_ERR_NOMEM, "merge", "out of memory");
    }
    return TS_OK;
}

void ts__merger_free(ts_merger *m)
{
    free(m->merged);
    free(m->old_m);
    free(m->new_m);
    free(m->sgx);
    free(m->sgy);
    free(m->mlabels);
    free(m->region);
    free(m->dist);
    memset(m, 0, sizeof *m);
}

/* Count 4-adjacent label changes inside the window. */
int ts__label_cut_edges(const unsigned char *labels, int P)
{
    int x, y, n = 0;
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++) {
            if (x + 1 < P && labels[y * P + x] != labels[y * P + x + 1])
                n++;
            if (y + 1 < P && labels[y * P + x] != labels[(y + 1) * P + x])
                n++;
        }
    return n;
}

/* Keep in the Poisson region only the new cells and the old cells within
 * `overlap` cells (Chebyshev) of new ones: the seam is smoothed in a band,
 * old content farther away stays as it was. */
void ts__chamfer_chebyshev(int *d, int P)
{
    int x, y;
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++) {
            int v = d[y * P + x];
            if (x > 0)
                v = TS_MIN(v, d[y * P + x - 1] + 1);
            if (y > 0)
                v = TS_MIN(v, d[(y - 1) * P + x] + 1);
            if (x > 0 && y > 0)
                v = TS_MIN(v, d[(y - 1) * P + x - 1] + 1);
            if (x + 1 < P && y > 0)
                v = TS_MIN(v, d[(y - 1) * P + x + 1] + 1);
            d[y * P + x] = v;
        }
    for (y = P - 1; y >= 0; y--)
        for (x = P - 1; x >= 0; x--) {
            int v = d[y * P + x];
            if (x + 1 < P)
                v = TS_MIN(v, d[y * P + x + 1] + 1);
            if (y + 1 < P)
                v = TS_MIN(v, d[(y + 1) * P + x] + 1);
            if (x + 1 < P && y + 1 < P)
                v = TS_MIN(v, d[(y + 1) * P + x + 1] + 1);
            if (x > 0 && y + 1 < P)
                v = TS_MIN(v, d[(y + 1) * P + x - 1] + 1);
            d[y * P + x] = v;
        }
}

int ts__border_keeps_old(const ts_raster *out, int wx, int wy, int P, int x, int y)
{
    int ox = wx + x, oy = wy + y;
    return (x == 0 && ox > 0 && !isnan(TS_PIX(out, ox - 1, oy))) ||
           (y == 0 && oy > 0 && !isnan(TS_PIX(out, ox, oy - 1))) ||
           (x == P - 1 && ox + 1 < out->width && !isnan(TS_PIX(out, ox + 1, oy))) ||
           (y == P - 1 && oy + 1 < out->height && !isnan(TS_PIX(out, ox, oy + 1)));
}

static void merge_limit_region(ts_merger *m, const unsigned char *labels)
{
    int P = m->P, M = P + 2, r = m->band, x, y;
    int *dist = m->dist; /* distance to the nearest new cell */
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++)
            dist[y * P + x] = labels[y * P + x] ? 0 : P + r + 1;
    ts__chamfer_chebyshev(dist, P);
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++)
            if (dist[y * P + x] > r)
                m->region[(y + 1) * M + x + 1] = 0;
}

/* Mean of the available differences a(q) - a(p) of the two sources. */
static float merge_mean_diff(const float *o, const float *n, int p, int q)
{
    double s = 0.0;
    int k = 0;
    if (!isnan(o[p]) && !isnan(o[q])) {
        s += (double)o[q] - (double)o[p];
        k++;
    }
    if (!isnan(n[p]) && !isnan(n[q])) {
        s += (double)n[q] - (double)n[p];
        k++;
    }
    return k ? (float)(s / k) : NAN;
}

/* Guidance across the seam: the mean of the old and new gradients there
 * (Zhou et al. use zero, which flattens the slope along every seam and
 * shows as lines in a hillshade). */
static void merge_seam_guidance(ts_merger *m)
{
    int M = m->P + 2, x, y;
    for (y = 0; y < M; y++)
        for (x = 0; x < M; x++) {
            int c = y * M + x;
            m->sgx[c] = x + 1 < M ? merge_mean_diff(m->old_m, m->new_m, c, c + 1) : NAN;
            m->sgy[c] = y + 1 < M ? merge_mean_diff(m->old_m, m->new_m, c, c + M) : NAN;
        }
}

static int merge_flag(const unsigned char *flags, const ts_raster *out, int x, int y, int bit)
{
    return flags && (flags[(size_t)y * (size_t)out->width + (size_t)x] & bit);
}

ts_status ts__merger_apply(ts_ctx *ctx, ts_merger *m, ts_raster *out, const unsigned char *flags,
                           int wx, int wy, const float *old, const unsigned char *labels,
                           ts_synth_maps *maps, int ex_index, const int32_t *src_x,
                           const int32_t *src_y, int patch_index)
{
    int P = m->P, M = P + 2, x, y, W = out->width, H = out->height, any_seam = 0;
    ts_raster mr;
    ts_status st;
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++) {
            int ox = wx + x, oy = wy + y;
            size_t o = (size_t)oy * (size_t)W + (size_t)ox;
            float v = m->new_m[(y + 1) * M + x + 1];
            if (!labels[y * P + x] || isnan(v) || merge_flag(flags, out, ox, oy, TS_CELL_NODATA))
                continue;
            TS_PIX(out, ox, oy) = v;
            if (maps) {
                if (maps->source_exemplar)
                    maps->source_exemplar[o] = ex_index;
                if (maps->source_x && src_x)
                    maps->source_x[o] = src_x[y * P + x];
                if (maps->source_y && src_y)
                    maps->source_y[o] = src_y[y * P + x];
                if (maps->order)
                    maps->order[o] = patch_index;
                if (maps->seams) /* a seam the new patch covers is gone */
                    maps->seams[o] = 0;
            }
        }
    /* the window with its ring */
    for (y = 0; y < M; y++)
        for (x = 0; x < M; x++) {
            int ox = wx + x - 1, oy = wy + y - 1, inside = x > 0 && y > 0 && x <= P && y <= P;
            float v = (ox >= 0 && oy >= 0 && ox < W && oy < H) ? TS_PIX(out, ox, oy) : NAN;
            m->old_m[y * M + x] = inside ? old[(y - 1) * P + (x - 1)] : v;
            m->merged[y * M + x] = v;
            m->mlabels[y * M + x] = inside ? labels[(y - 1) * P + (x - 1)] : 0;
            m->region[y * M + x] =
                inside && !isnan(v) && !merge_flag(flags, out, ox, oy, TS_CELL_FIXED);
        }
    for (y = 0; y < M && !any_seam; y++)
        for (x = 0; x + 1 < M; x++)
            if (!isnan(m->merged[y * M + x]) && !isnan(m->merged[y * M + x + 1]) &&
                m->mlabels[y * M + x] != m->mlabels[y * M + x + 1]) {
                any_seam = 1;
                break;
            }
    for (y = 0; y + 1 < M && !any_seam; y++)
        for (x = 0; x < M; x++)
            if (!isnan(m->merged[y * M + x]) && !isnan(m->merged[(y + 1) * M + x]) &&
                m->mlabels[y * M + x] != m->mlabels[(y + 1) * M + x]) {
                any_seam = 1;
                break;
            }
    if (!any_seam)
        return TS_OK;
    if (maps && maps->seams)
        for (y = 1; y <= P; y++)
            for (x = 1; x <= P; x++) {
                unsigned char l = m->mlabels[y * M + x];
                int ox = wx + x - 1, oy = wy + y - 1;
                if (isnan(m->merged[y * M + x]))
                    continue;
                if ((!isnan(m->merged[y * M + x - 1]) && m->mlabels[y * M + x - 1] != l) ||
                    (!isnan(m->merged[y * M + x + 1]) && m->mlabels[y * M + x + 1] != l) ||
                    (!isnan(m->merged[(y - 1) * M + x]) && m->mlabels[(y - 1) * M + x] != l) ||
                    (!isnan(m->merged[(y + 1) * M + x]) && m->mlabels[(y + 1) * M + x] != l))
                    maps->seams[(size_t)oy * (size_t)W + (size_t)ox] = 1;
            }
    merge_limit_region(m, labels);
    merge_seam_guidance(m);
    mr = ts_raster_wrap(m->merged, M, M, M);
    st = ts_poisson_seam_remove_guided(ctx, &mr, m->mlabels, m->region, m->sgx, m->sgy);
    if (st != TS_OK)
        return st;
    for (y = 1; y <= P; y++)
        for (x = 1; x <= P; x++)
            if (m->region[y * M + x])
                TS_PIX(out, wx + x - 1, wy + y - 1) = m->merged[y * M + x];
    return TS_OK;
}

/* alpha * RMS(patch - want) over the window cells where both are set. */
static double rms_to(const float *want, double alpha, int width, int wx, int wy, int P,
                     const float *patch, int stride)
{
    double sum = 0.0;
    int x, y, n = 0;
    if (!want || !(alpha > 0))
        return 0.0;
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++) {
            float h = want[(size_t)(wy + y) * (size_t)width + (size_t)(wx + x)];
            float v = patch[(ptrdiff_t)y * stride + x];
            if (isnan(h) || isnan(v))
                continue;
            sum += ((double)v - h) * ((double)v - h);
            n++;
        }
    return n ? alpha * sqrt(sum / n) : 0.0;
}

double ts__height_cost(const ts__fill *p, int width, int wx, int wy, int P, const float *patch,
                       int stride)
{
    return rms_to(p->heights, p->alpha_h, width, wx, wy, P, patch, stride) +
           rms_to(p->guide, p->alpha_r, width, wx, wy, P, patch, stride);
}
