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
 * lowest and highest values on either side come from monotonic queues over
 * each nodata-free run (sliding-window extremes); lines are split over the
 * context's threads, one direction at a time.
 * Deterministic: every cell is decided independently.
 */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

typedef struct profile_job {
    const ts_raster *dem;
    int half;
    float threshold;
    int kinds;
    int dir;             /* the direction of this pass, index into profile_dir */
    unsigned char *targets;
    atomic_int failed;   /* a worker could not get its buffers */
} profile_job;

static const int profile_dir[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};

/* Lines of direction d: their count, and the start and length of line l. */
static size_t profile_lines(const ts_raster *dem, int d)
{
    size_t w = (size_t)dem->width, h = (size_t)dem->height;
    return d == 0 ? h : d == 1 ? w : w + h - 1;
}

static void profile_line(const ts_raster *dem, int d, size_t l, int *x0, int *y0, int *n)
{
    int W = dem->width, H = dem->height, li = (int)l;
    switch (d) {
    case 0: *x0 = 0; *y0 = li; *n = W; break;
    case 1: *x0 = li; *y0 = 0; *n = H; break;
    case 2:
        if (li < W) { *x0 = li; *y0 = 0; } else { *x0 = 0; *y0 = li - W + 1; }
        *n = TS_MIN(W - *x0, H - *y0);
        break;
    default:
        if (li < W) { *x0 = li; *y0 = H - 1; } else { *x0 = 0; *y0 = li - W; }
        *n = TS_MIN(W - *x0, *y0 + 1);
        break;
    }
}

/* Sliding extremes over one nodata-free run v[s..e]: for each i the lowest
 * and highest value among v[i+1 .. i+half] (fwd) and v[i-half .. i-1]
 * (bwd), cut at the run's ends (+-INFINITY where that side is empty).
 * Monotonic queues q (n ints each): O(run length). */
static void profile_run(const float *v, int s, int e, int half, int want_min, int want_max,
                        float *fmin, float *fmax, float *bmin, float *bmax, int *qa, int *qb)
{
    int i, ha, ta, hb, tb;
    /* forward: i from e down to s, the window (i, i + half] */
    ha = ta = hb = tb = 0;
    for (i = e; i >= s; i--) {
        int j = i + 1;
        if (j <= e) {
            if (want_min) {
                while (ta > ha && v[qa[ta - 1]] >= v[j])
                    ta--;
                qa[ta++] = j;
            }
            if (want_max) {
                while (tb > hb && v[qb[tb - 1]] <= v[j])
                    tb--;
                qb[tb++] = j;
            }
        }
        while (ta > ha && qa[ha] > i + half)
            ha++;
        while (tb > hb && qb[hb] > i + half)
            hb++;
        fmin[i] = ta > ha ? v[qa[ha]] : INFINITY;
        fmax[i] = tb > hb ? v[qb[hb]] : -INFINITY;
    }
    /* backward: i from s up to e, the window [i - half, i) */
    ha = ta = hb = tb = 0;
    for (i = s; i <= e; i++) {
        int j = i - 1;
        if (j >= s) {
            if (want_min) {
                while (ta > ha && v[qa[ta - 1]] >= v[j])
                    ta--;
                qa[ta++] = j;
            }
            if (want_max) {
                while (tb > hb && v[qb[tb - 1]] <= v[j])
                    tb--;
                qb[tb++] = j;
            }
        }
        while (ta > ha && qa[ha] < i - half)
            ha++;
        while (tb > hb && qb[hb] < i - half)
            hb++;
        bmin[i] = ta > ha ? v[qa[ha]] : INFINITY;
        bmax[i] = tb > hb ? v[qb[hb]] : -INFINITY;
    }
}

/* Lines [b, e) of the job's direction. */
static void profile_lines_range(void *arg, size_t b, size_t e)
{
    profile_job *job = arg;
    const ts_raster *dem = job->dem;
    int n_max = TS_MAX(dem->width, dem->height), dx = profile_dir[job->dir][0],
        dy = profile_dir[job->dir][1];
    int want_min = (job->kinds & TS_RIDGE) != 0, want_max = (job->kinds & TS_VALLEY) != 0;
    float *buf = ts_malloc_array((size_t)n_max * 5, sizeof(float));
    int *q = ts_malloc_array((size_t)n_max * 2, sizeof(int));
    size_t l;
    if (!buf || !q) {
        atomic_store(&job->failed, 1);
        free(buf);
        free(q);
        return;
    }
    for (l = b; l < e; l++) {
        float *v = buf, *fmin = buf + n_max, *fmax = buf + 2 * n_max, *bmin = buf + 3 * n_max,
              *bmax = buf + 4 * n_max;
        int x0, y0, n, i, s;
        profile_line(dem, job->dir, l, &x0, &y0, &n);
        for (i = 0; i < n; i++)
            v[i] = TS_PIX(dem, x0 + i * dx, y0 + i * dy);
        for (s = 0; s < n;) {
            int end;
            if (isnan(v[s])) {
                s++;
                continue;
            }
            for (end = s; end + 1 < n && !isnan(v[end + 1]); end++)
                ;
            profile_run(v, s, end, job->half, want_min, want_max, fmin, fmax, bmin, bmax, q,
                        q + n_max);
            for (i = s; i <= end; i++) {
                float z = v[i];
                unsigned char bits = 0;
                /* a profile needs a step on both sides */
                if (i == s || i == end)
                    continue;
                if (want_min && z - fmin[i] > job->threshold && z - bmin[i] > job->threshold)
                    bits |= TS_RIDGE;
                if (want_max && fmax[i] - z > job->threshold && bmax[i] - z > job->threshold)
                    bits |= TS_VALLEY;
                if (bits)
                    job->targets[(size_t)(y0 + i * dy) * (size_t)dem->width +
                                 (size_t)(x0 + i * dx)] |= bits;
            }
            s = end + 1;
        }
    }
    free(buf);
    free(q);
}

TS_API ts_status ts_ppa_profile_recognition(ts_ctx *ctx, const ts_raster *dem,
                                            int profile_length, double threshold, int kinds,
                                            unsigned char *targets)
{
    profile_job job;
    ts_clear(ctx);
    if (!dem || !dem->data || !targets)
        return ts_fail(ctx, TS_ERR_ARG, "ppa profile recognition", "missing raster or output");
    if (dem->width <= 0 || dem->height <= 0)
        return ts_fail(ctx, TS_ERR_SIZE, "ppa profile recognition", "empty raster");
    if (profile_length < 3 || profile_length % 2 == 0)
        return ts_fail(ctx, TS_ERR_ARG, "ppa profile recognition",
                       "profile length %d must be odd and at least 3", profile_length);
    if (!(threshold >= 0.0) || !isfinite(threshold))
        return ts_fail(ctx, TS_ERR_ARG, "ppa profile recognition",
                       "threshold %g must be a non-negative number", threshold);
    job.dem = dem;
    job.half = profile_length / 2;
    job.threshold = (float)threshold;
    job.kinds = kinds & (TS_RIDGE | TS_VALLEY);
    job.targets = targets;
    atomic_init(&job.failed, 0);
    memset(targets, 0, (size_t)dem->width * (size_t)dem->height);
    /* one direction at a time: its lines are disjoint, so workers never
     * write the same cell */
    for (job.dir = 0; job.dir < 4; job.dir++)
        ts_parallel_for(ctx, profile_lines(dem, job.dir), profile_lines_range, &job);
    if (atomic_load(&job.failed))
        return ts_fail(ctx, TS_ERR_NOMEM, "ppa profile recognition", "out of memory");
    return ts_progress(ctx, 1.0, "profile recognition");
}
