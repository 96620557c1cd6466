/*
 * test_pixel_hash.c - the hash behind pixel synthesis's jitter and random
 * coordinates (ts__pix_hash): each of its five arguments changes it, and its
 * bits are balanced, over many random arguments.  A hash that ignored one
 * argument (y, say) would make every cell of a row share its jitter.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdint.h>
#include <stdlib.h>

#include "harness.h"
#include "pixel.h"
#include "terrasynth.h"

static void test_every_argument_counts(void)
{
    uint64_t rng = 77;
    int i, b, same[5] = {0, 0, 0, 0, 0}, ones[64] = {0};
    const int n = 20000;
    for (i = 0; i < n; i++) {
        int64_t x = (int64_t)(th_rand(&rng) % 2000001) - 1000000;
        int64_t y = (int64_t)(th_rand(&rng) % 2000001) - 1000000;
        int level = (int)(th_rand(&rng) % 20), stream = (int)(th_rand(&rng) % 4);
        uint64_t seed = th_rand(&rng), h = ts__pix_hash(x, y, level, stream, seed);
        same[0] += h == ts__pix_hash(x + 1, y, level, stream, seed);
        same[1] += h == ts__pix_hash(x, y + 1, level, stream, seed);
        same[2] += h == ts__pix_hash(x, y, level + 1, stream, seed);
        same[3] += h == ts__pix_hash(x, y, level, stream + 1, seed);
        same[4] += h == ts__pix_hash(x, y, level, stream, seed ^ 1);
        /* swapped coordinates are another cell */
        if (x != y)
            CHECK(h != ts__pix_hash(y, x, level, stream, seed));
        for (b = 0; b < 64; b++)
            ones[b] += (int)(h >> b & 1);
    }
    for (i = 0; i < 5; i++)
        CHECK_MSG(same[i] == 0, "argument %d: the hash unchanged %d times in %d", i, same[i], n);
    for (b = 0; b < 64; b++) /* each bit set about half the time (5 sigma: +-354) */
        CHECK_MSG(abs(ones[b] - n / 2) < 360, "bit %d set %d times in %d", b, ones[b], n);
    /* the same arguments, the same hash (a pure function) */
    CHECK(ts__pix_hash(12, -7, 3, 2, 99) == ts__pix_hash(12, -7, 3, 2, 99));
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"every_argument_counts", test_every_argument_counts},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
