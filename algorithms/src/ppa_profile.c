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
 * Cost: O(cells x profile_length) at worst; a scan stops as soon as it has
 * seen a deep enough dip (rise), rows split over the context's threads.
 * Deterministic: every cell is decided independently.
 */
#include <string.h>

#include "internal.h"

typedef struct profile_job {
    const ts_raster *dem;
    int half;
    float threshold;
    int kinds;
    unsigned char *targets;
} profile_job;

static const int profile_dir[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};

/* Walk `half` steps from (x, y) along (dx, dy), stopping at the edge or at
 * nodata, and as soon as every kind in `want` is seen: TS_RIDGE when a
 * value lies more than `threshold` below z (z - v > threshold, the same
 * float arithmetic as comparing with the lowest value), TS_VALLEY when one
 * lies more than `threshold` above it.  Returns the kinds seen, or -1 if
 * no step was possible (the profile does not count). */
static int profile_side(const ts_raster *dem, int x, int y, int dx, int dy, int half, float z,
                        float threshold, int want)
{
    int i, found = 0;
    for (i = 1; i <= half; i++) {
        int xx = x + i * dx, yy = y + i * dy;
        float v;
        if (xx < 0 || yy < 0 || xx >= dem->width || yy >= dem->height)
            break;
        v = TS_PIX(dem, xx, yy);
        if (isnan(v))
            break;
        if (z - v > threshold)
            found |= TS_RIDGE;
        if (v - z > threshold)
            found |= TS_VALLEY;
        if ((found & want) == want)
            return found & want;
    }
    return i == 1 ? -1 : found & want;
}

static void profile_rows(void *arg, size_t y0, size_t y1)
{
    const profile_job *job = arg;
    const ts_raster *dem = job->dem;
    int want = job->kinds & (TS_RIDGE | TS_VALLEY);
    size_t y;
    for (y = y0; y < y1; y++) {
        int x;
        unsigned char *out = job->targets + y * (size_t)dem->width;
        for (x = 0; x < dem->width; x++) {
            float z = TS_PIX(dem, x, (int)y);
            int bits = 0, d;
            if (!isnan(z)) {
                for (d = 0; d < 4 && bits != want; d++) {
                    int dx = profile_dir[d][0], dy = profile_dir[d][1], s1, s2;
                    /* only the kinds not yet decided */
                    s1 = profile_side(dem, x, (int)y, dx, dy, job->half, z, job->threshold,
                                      want & ~bits);
                    if (s1 <= 0)
                        continue;
                    s2 = profile_side(dem, x, (int)y, -dx, -dy, job->half, z, job->threshold,
                                      s1);
                    if (s2 > 0)
                        bits |= s1 & s2;
                }
            }
            out[x] = (unsigned char)bits;
        }
    }
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
    ts_parallel_for(ctx, (size_t)dem->height, profile_rows, &job);
    return ts_progress(ctx, 1.0, "profile recognition");
}
