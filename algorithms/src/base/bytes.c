/*
 * bytes.c - the bytes of the core's file formats (a dictionary, a sketch in
 * tiles): little-endian whatever the machine, and the FNV-1a checksum they
 * end with.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <string.h>

#include "internal.h"

static int host_little(void)
{
    const uint16_t one = 1;
    unsigned char c;
    memcpy(&c, &one, 1);
    return c == 1;
}

void ts__le_copy(unsigned char *dst, const void *src, size_t n, size_t size)
{
    size_t i, k;
    if (host_little()) {
        memcpy(dst, src, n * size);
        return;
    }
    for (i = 0; i < n; i++)
        for (k = 0; k < size; k++)
            dst[i * size + k] = ((const unsigned char *)src)[i * size + size - 1 - k];
}

void ts__put_u32(unsigned char *p, uint32_t v)
{
    int k;
    for (k = 0; k < 4; k++)
        p[k] = (unsigned char)(v >> (8 * k));
}

void ts__put_u64(unsigned char *p, uint64_t v)
{
    ts__put_u32(p, (uint32_t)(v & 0xffffffffu));
    ts__put_u32(p + 4, (uint32_t)(v >> 32));
}

uint32_t ts__get_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t ts__get_u64(const unsigned char *p)
{
    return (uint64_t)ts__get_u32(p) | (uint64_t)ts__get_u32(p + 4) << 32;
}

/* FNV-1a, 64 bits (Fowler, Noll and Vo): every byte folds into the sum. */
TS_API uint64_t ts_checksum(uint64_t sum, const void *bytes, size_t n)
{
    const unsigned char *p = bytes;
    uint64_t h = sum ? sum : 0xcbf29ce484222325ull;
    size_t i;
    for (i = 0; i < n; i++)
        h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}
