/*
 * job_synth_drain.c - the synth job's drainage stage on the whole output: the
 * constraints and the sketch's features as the stage's cell flags (water and
 * pins fixed, drawn valley floors fixed, drawn ridges barriers, the land beside
 * drawn valleys shallow), then the stage and its time.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <time.h>

#include "job_internal.h"

/* TS_CELL_SHALLOW on the cells within r (Chebyshev) of a drawn valley's floor (floor's
 * non-zero cells): a running window along the rows, then along the
 * columns; -1 out of memory. */
static int mark_beside_valleys(unsigned char *flags, const unsigned char *floor, int w, int h,
                               int r)
{
    unsigned char *row = malloc((size_t)w * (size_t)h);
    int x, y;
    if (!row)
        return -1;
    for (y = 0; y < h; y++) {
        const unsigned char *f = floor + (size_t)y * (size_t)w;
        unsigned char *o = row + (size_t)y * (size_t)w;
        int last = -1 - r;
        for (x = 0; x < w; x++) {
            if (f[x])
                last = x;
            o[x] = x - last <= r;
        }
        last = w + r + 1;
        for (x = w - 1; x >= 0; x--) {
            if (f[x])
                last = x;
            o[x] |= last - x <= r;
        }
    }
    for (x = 0; x < w; x++) {
        int last = -1 - r;
        for (y = 0; y < h; y++) {
            if (row[(size_t)y * (size_t)w + (size_t)x])
                last = y;
            if (y - last <= r)
                flags[(size_t)y * (size_t)w + (size_t)x] |= TS_CELL_SHALLOW;
        }
        last = h + r + 1;
        for (y = h - 1; y >= 0; y--) {
            if (row[(size_t)y * (size_t)w + (size_t)x])
                last = y;
            if (last - y <= r)
                flags[(size_t)y * (size_t)w + (size_t)x] |= TS_CELL_SHALLOW;
        }
    }
    free(row);
    return 0;
}

/* The drainage stage on the whole output: the water, the pins and the
 * sketch's valley floors fixed, its ridges barriers a channel crosses only
 * where it must. */
int tsjob__synth_drain_whole(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res,
                             unsigned char *flags, job_progress *jp, tsio_err *err)
{
    size_t i, n = (size_t)res->geo.width * (size_t)res->geo.height;
    struct timespec t0, t1;
    int rc;
    if (job->drainage.mode == TS_DRAINAGE_KEEP)
        return 0;
    tsjob__progress_range(ctx, jp, 0.95, 1.0);
    tsjob_synth_sketch_barriers(res, 0, 0, res->geo.width, res->geo.height, flags);
    /* a drawn valley's floor, made to descend to its outlet, is kept as it is */
    for (i = 0; res->maps.valley_floor && i < n; i++)
        if (res->maps.valley_floor[i])
            flags[i] |= TS_CELL_FIXED;
    /* with a sketch, the land beside a drawn valley's floor (within a quarter of the
     * radius) is cut at most the banks' slope deep by default, by its own pits and by
     * channels from farther off: a deeper channel runs beside the fixed floor as a trench
     * and leaves the floor standing as a wall (the sketch matrices' seams); pits farther
     * off are cut as after any method */
    if (job->sketch && res->drainage.max_depth == -1 && res->drainage.bank_slope > 0 &&
        res->maps.valley_floor &&
        mark_beside_valleys(flags, res->maps.valley_floor, res->geo.width, res->geo.height,
                            res->drainage.radius >= 8 ? res->drainage.radius / 4 : 2) == 0)
        res->drainage.shallow_depth = 1.0 * res->drainage.bank_slope;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    rc = tsjob_drain(ctx, &res->drainage, &res->out, flags, 0, 0, res->geo.width, res->geo.height,
                     &res->drainage_info, job->sketch ? job->sketch : "synth", err);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    res->seconds_drainage =
        (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    return rc;
}
