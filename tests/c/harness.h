/*
 * harness.h - a tiny test harness: CHECK macros, tolerance helpers, a
 * deterministic RNG, and a closing line "N passed, N failed" that CI reads.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_TEST_HARNESS_H
#define TS_TEST_HARNESS_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int th_checks_failed;
static int th_case_failed;

#define CHECK(cond)                                                                     \
    do {                                                                                \
        if (!(cond)) {                                                                  \
            fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);   \
            th_checks_failed++;                                                         \
            th_case_failed = 1;                                                         \
        }                                                                               \
    } while (0)

#define CHECK_MSG(cond, ...)                                                            \
    do {                                                                                \
        if (!(cond)) {                                                                  \
            fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__, #cond);   \
            fprintf(stderr, __VA_ARGS__);                                               \
            fputc('\n', stderr);                                                        \
            th_checks_failed++;                                                         \
            th_case_failed = 1;                                                         \
        }                                                                               \
    } while (0)

#define CHECK_NEAR(a, b, tol)                                                           \
    CHECK_MSG(fabs((double)(a) - (double)(b)) <= (tol), "%.9g vs %.9g (tol %g)",        \
              (double)(a), (double)(b), (double)(tol))

typedef struct th_case {
    const char *name;
    void (*fn)(void);
} th_case;

/* Run the cases (all, or only those named on the command line). */
static int th_run(const th_case *cases, size_t n, int argc, char **argv)
{
    size_t i;
    int passed = 0, failed = 0, a;
    for (i = 0; i < n; i++) {
        int wanted = argc <= 1;
        for (a = 1; a < argc; a++)
            if (strcmp(argv[a], cases[i].name) == 0)
                wanted = 1;
        if (!wanted)
            continue;
        th_case_failed = 0;
        cases[i].fn();
        printf("%s %s\n", th_case_failed ? "FAIL" : "ok  ", cases[i].name);
        if (th_case_failed)
            failed++;
        else
            passed++;
    }
    printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}

/* splitmix64: a deterministic RNG for test data. */
static inline uint64_t th_rand(uint64_t *s)
{
    uint64_t z = (*s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static inline double th_uniform(uint64_t *s)
{
    return (double)(th_rand(s) >> 11) / 9007199254740992.0;
}

#endif
