/*
 * bench_common.h - small helpers shared by the benchmarks: wall clock, peak
 * resident memory, reflect tiling.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_BENCH_COMMON_H
#define TS_BENCH_COMMON_H

#include <stdio.h>
#include <sys/resource.h>
#include <time.h>

static inline double bench_now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Peak resident set size of the process so far, MB. */
static inline double bench_peak_rss_mb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_maxrss / 1024.0;
}

/* Source index of mosaic coordinate i for n source cells, tiles mirrored
 * when odd, so a mosaic has no seams. */
static inline int bench_reflect(int i, int n)
{
    int t = i / n, r = i % n;
    return (t % 2) ? n - 1 - r : r;
}

/* The goal line every benchmark ends with (missing it is a figure, not an error). */
static inline void bench_goal_line(double seconds, double goal_s, double goal_mb)
{
    printf("goal: < %.0f s and < %.0f MB: %s\n", goal_s, goal_mb,
           (seconds < goal_s && bench_peak_rss_mb() < goal_mb) ? "PASS" : "FAIL");
}

#endif
