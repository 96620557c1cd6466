/*
 * ppa_profile.c - PPA step 1, profile recognition (Chang, Song & Hsu 1998;
 * Zhou et al. 2007 section 3, Fig. 4a).
 *
 * A cell is a ridge target when, along at least one of the four profile
 * directions (E-W, N-S and the two diagonals), the terrain dips below it by
 * more than `threshold` on both sides within half the profile length; a
 * valley target when it rises above it likewise.  A profile stops at the
 * raster edge and at nodata: nothing is seen across a hole, and nodata
 * cells are never targets.
 * Cost: O(cells), whatever the profile length: along each direction the
 * lowest and highest values on either side are sliding-window extremes
 * over each nodata-free run (van Herk / Gil-Werman); lines are split over
 * the context's threads, one direction at a time.
 * Deterministic: every cell is decided independently.
 */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

typedef struct profile_job {
    const ts_raster *dem;
    int half;
    float threshold[2]; /* ridges, valleys */
    int kinds;
    int dir; /* the direction of this pass (see profile_lines) */
    unsigned char *targets;
    atomic_int failed; /* a worker could not get its buffers */
} profile_job;

/* Lines of direction d (0 rows, 1 columns, 2 diagonals x - y = const,
 * 3 anti-diagonals x + y = const), all walked by increasing row: line t
 * has its cell of row y at x = line_x(d, t, y), for rows ya..yb.  (A line
 * walked backwards gives the same targets: both sides are tested.)  Lines
 * t and t + 1 of directions 1-3 sit side by side on every row, so a block
 * of them is gathered and scattered row by row, along memory. */
static size_t profile_lines(const ts_raster *dem, int d)
{
    size_t w = (size_t)dem->width, h = (size_t)dem->height;
    return d == 0 ? h : d == 1 ? w : w + h - 1;
}

static int line_x(int d, int t, int y, int H)
{
    return d == 1 ? t : d == 2 ? y + t - (H - 1) : t - y;
}

static void line_rows(int d, int t, int W, int H, int *ya, int *yb)
{
    if (d == 1) {
        *ya = 0;
        *yb = H - 1;
    } else if (d == 2) { /* x = y + c, c = t - (H - 1) */
        int c = t - (H - 1);
        *ya = TS_MAX(0, -c);
        *yb = TS_MIN(H - 1, W - 1 - c);
    } else { /* x = t - y */
        *ya = TS_MAX(0, t - W + 1);
        *yb = TS_MIN(H - 1, t);
    }
}

/* Window extremes of one nodata-free run by van Herk / Gil-Werman: the run
 * padded with `half` cells of `pad` (+INFINITY for minima, -INFINITY for
 * maxima) at each end is cut into blocks of `half`; pre[j] is the extreme
 * from the start of j's block to j, suf[j] from j to the end of its block;
 * the extreme of the window p[a .. a + half - 1] is then
 * ext(suf[a], pre[a + half - 1]).  Branch-free, O(run length) whatever the
 * profile length; the same multiset of values as a direct scan, so the
 * same extreme.  No NaN reaches PPA_MIN/MAX (runs are nodata-free, pads
 * infinite): plain comparisons compile to min/max instructions, fminf to
 * library calls. */
#define PPA_MIN(a, b) ((a) < (b) ? (a) : (b))
#define PPA_MAX(a, b) ((a) > (b) ? (a) : (b))

static void vhgw(const float *v, int n, int half, int is_max, float *p, float *pre, float *suf)
{
    float pad = is_max ? -INFINITY : INFINITY;
    int m = n + 2 * half, j, j0;
    for (j = 0; j < half; j++) {
        p[j] = pad;
        p[half + n + j] = pad;
    }
    memcpy(p + half, v, (size_t)n * sizeof(float));
    for (j0 = 0; j0 < m; j0 += half) {
        int j1 = TS_MIN(m, j0 + half);
        pre[j0] = p[j0];
        suf[j1 - 1] = p[j1 - 1];
        if (is_max) {
            for (j = j0 + 1; j < j1; j++)
                pre[j] = PPA_MAX(pre[j - 1], p[j]);
            for (j = j1 - 2; j >= j0; j--)
                suf[j] = PPA_MAX(suf[j + 1], p[j]);
        } else {
            for (j = j0 + 1; j < j1; j++)
                pre[j] = PPA_MIN(pre[j - 1], p[j]);
            for (j = j1 - 2; j >= j0; j--)
                suf[j] = PPA_MIN(suf[j + 1], p[j]);
        }
    }
}

#define PROFILE_BLOCK 16

/* Work buffers of one worker. */
typedef struct profile_work {
    float *v;               /* PROFILE_BLOCK lines of n_max values */
    unsigned char *bits;    /* PROFILE_BLOCK lines of n_max target bits */
    float *pad, *pre, *suf; /* n_max + 2 half each: vhgw's arrays */
    int n_max;
} profile_work;

/* The target bits of one line of n values (NaN = nodata). */
static void profile_line_bits(const profile_job *job, profile_work *w, const float *v, int n,
                              unsigned char *bits)
{
    int h = job->half, s, i, kind;
    memset(bits, 0, (size_t)n);
    for (s = 0; s < n;) {
        int end, len;
        if (isnan(v[s])) {
            s++;
            continue;
        }
        for (end = s; end + 1 < n && !isnan(v[end + 1]); end++)
            ;
        len = end - s + 1;
        for (kind = TS_RIDGE; kind <= TS_VALLEY; kind <<= 1) {
            int is_max = kind == TS_VALLEY;
            if (!(job->kinds & kind) || len < 3)
                continue;
            vhgw(v + s, len, h, is_max, w->pad, w->pre, w->suf);
            /* run cell i is padded cell i + h; its backward window starts
             * at padded i, its forward window at padded i + h + 1; a
             * profile needs a step on both sides: not the run's ends */
            for (i = 1; i + 1 < len; i++) {
                float z = v[s + i];
                int a = i, f = i + h + 1;
                if (is_max) {
                    float bw = PPA_MAX(w->suf[a], w->pre[a + h - 1]);
                    float fw = PPA_MAX(w->suf[f], w->pre[f + h - 1]);
                    if (fw - z > job->threshold[1] && bw - z > job->threshold[1])
                        bits[s + i] |= TS_VALLEY;
                } else {
                    float bw = PPA_MIN(w->suf[a], w->pre[a + h - 1]);
                    float fw = PPA_MIN(w->suf[f], w->pre[f + h - 1]);
                    if (z - fw > job->threshold[0] && z - bw > job->threshold[0])
                        bits[s + i] |= TS_RIDGE;
                }
            }
        }
        s = end + 1;
    }
}

/* Items [b, e) of the job's direction: rows for direction 0, blocks of
 * PROFILE_BLOCK lines for the others. */
static void profile_lines_range(void *arg, size_t b, size_t e)
{
    profile_job *job = arg;
    const ts_raster *dem = job->dem;
    int W = dem->width, H = dem->height, d = job->dir;
    profile_work w;
    size_t item;
    w.n_max = TS_MAX(W, H);
    w.v = ts__malloc_array((size_t)w.n_max * PROFILE_BLOCK, sizeof(float));
    w.bits = ts__malloc_array((size_t)w.n_max * PROFILE_BLOCK, 1);
    w.pad = ts__malloc_array((size_t)w.n_max + 2 * (size_t)job->half, sizeof(float));
    w.pre = ts__malloc_array((size_t)w.n_max + 2 * (size_t)job->half, sizeof(float));
    w.suf = ts__malloc_array((size_t)w.n_max + 2 * (size_t)job->half, sizeof(float));
    if (!w.v || !w.bits || !w.pad || !w.pre || !w.suf) {
        atomic_store(&job->failed, 1);
        goto done;
    }
    for (item = b; item < e; item++) {
        if (d == 0) {
            int y = (int)item, x;
            unsigned char *out = job->targets + (size_t)y * (size_t)W;
            for (x = 0; x < W; x++)
                w.v[x] = TS_PIX(dem, x, y);
            profile_line_bits(job, &w, w.v, W, w.bits);
            for (x = 0; x < W; x++)
                out[x] |= w.bits[x];
        } else {
            int t0 = (int)item * PROFILE_BLOCK, nl, k, y, ylo = H, yhi = -1;
            int ya[PROFILE_BLOCK], yb[PROFILE_BLOCK];
            nl = (int)TS_MIN((size_t)PROFILE_BLOCK, profile_lines(dem, d) - (size_t)t0);
            for (k = 0; k < nl; k++) {
                line_rows(d, t0 + k, W, H, &ya[k], &yb[k]);
                ylo = TS_MIN(ylo, ya[k]);
                yhi = TS_MAX(yhi, yb[k]);
            }
            /* gather row by row: line t0 + k has its cell of row y at x0 + k,
             * so the block's cells of a row are side by side */
            for (y = ylo; y <= yhi; y++) {
                int x0 = line_x(d, t0, y, H), k0 = TS_MAX(0, -x0), k1 = TS_MIN(nl, W - x0);
                const float *row = &TS_PIX(dem, 0, y);
                for (k = k0; k < k1; k++)
                    w.v[(size_t)k * (size_t)w.n_max + (size_t)(y - ya[k])] = row[x0 + k];
            }
            for (k = 0; k < nl; k++)
                if (yb[k] >= ya[k])
                    profile_line_bits(job, &w, w.v + (size_t)k * (size_t)w.n_max, yb[k] - ya[k] + 1,
                                      w.bits + (size_t)k * (size_t)w.n_max);
            for (y = ylo; y <= yhi; y++) {
                int x0 = line_x(d, t0, y, H), k0 = TS_MAX(0, -x0), k1 = TS_MIN(nl, W - x0);
                unsigned char *out = job->targets + (size_t)y * (size_t)W;
                for (k = k0; k < k1; k++)
                    out[x0 + k] |= w.bits[(size_t)k * (size_t)w.n_max + (size_t)(y - ya[k])];
            }
        }
    }
done:
    free(w.v);
    free(w.bits);
    free(w.pad);
    free(w.pre);
    free(w.suf);
}

ts_status ppa_profile_targets(ts_ctx *ctx, const ts_raster *dem, int profile_length,
                              double threshold_ridges, double threshold_valleys, int kinds,
                              unsigned char *targets)
{
    profile_job job;
    ts__clear(ctx);
    if (!dem || !dem->data || !targets)
        return ts__fail(ctx, TS_ERR_ARG, "ppa profile recognition", "missing raster or output");
    if (dem->width <= 0 || dem->height <= 0)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa profile recognition", "empty raster");
    if (profile_length < 3 || profile_length % 2 == 0)
        return ts__fail(ctx, TS_ERR_ARG, "ppa profile recognition",
                        "profile length %d must be odd and at least 3", profile_length);
    if (!(threshold_ridges >= 0.0) || !isfinite(threshold_ridges) ||
        !(threshold_valleys >= 0.0) || !isfinite(threshold_valleys))
        return ts__fail(ctx, TS_ERR_ARG, "ppa profile recognition",
                        "threshold %g must be a non-negative number",
                        !(threshold_ridges >= 0.0) || !isfinite(threshold_ridges)
                            ? threshold_ridges
                            : threshold_valleys);
    job.dem = dem;
    job.half = profile_length / 2;
    job.threshold[0] = (float)threshold_ridges;
    job.threshold[1] = (float)threshold_valleys;
    job.kinds = kinds & (TS_RIDGE | TS_VALLEY);
    job.targets = targets;
    atomic_init(&job.failed, 0);
    memset(targets, 0, (size_t)dem->width * (size_t)dem->height);
    /* one direction at a time: its lines are disjoint, so workers never
     * write the same cell */
    for (job.dir = 0; job.dir < 4; job.dir++) {
        size_t n = profile_lines(dem, job.dir);
        ts__parallel_for(ctx, job.dir == 0 ? n : (n + PROFILE_BLOCK - 1) / PROFILE_BLOCK,
                         profile_lines_range, &job);
    }
    if (atomic_load(&job.failed))
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa profile recognition", "out of memory");
    return ts__progress(ctx, 1.0, "profile recognition");
}

TS_API ts_status ts_ppa_profile_recognition(ts_ctx *ctx, const ts_raster *dem, int profile_length,
                                            double threshold, int kinds, unsigned char *targets)
{
    return ppa_profile_targets(ctx, dem, profile_length, threshold, threshold, kinds, targets);
}
