/*
 * test_synth.c - non-feature patch synthesis: fills everything, never uses
 * exemplar nodata, keeps pre-filled and keep-nodata cells, deterministic,
 * clear errors.  (Visual and statistical checks on real DEMs are in
 * tests/cli/test_synth.py.)
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>

#include "harness.h"
#include "terrasynth.h"

static ts_raster make_exemplar(ts_ctx *ctx, int w, int h, uint64_t seed, int holes)
{
    ts_raster r;
    int x, y;
    uint64_t s = seed;
    double ph[6];
    for (x = 0; x < 6; x++)
        ph[x] = 6.283 * th_uniform(&s);
    ts_raster_alloc(ctx, w, h, &r);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            TS_PIX(&r, x, y) =
                (float)(1000.0 + 80.0 * sin(x / 13.0 + ph[0]) * cos(y / 17.0 + ph[1]) +
                        40.0 * sin((x + y) / 7.0 + ph[2]) +
                        15.0 * sin(x / 3.1 + ph[3]) * sin(y / 4.3 + ph[4]) + 3.0 * th_uniform(&s));
    if (holes)
        for (y = 40; y < 60; y++)
            for (x = 50; x < 75; x++)
                TS_PIX(&r, x, y) = NAN;
    return r;
}

static ts_synth_params small_params(void)
{
    ts_synth_params p = ts_synth_params_default();
    p.patch_size.value = 32;
    p.overlap.value = 8;
    p.candidates = 4;
    p.coarse_factor = 2;
    return p;
}

static size_t count_nan(const ts_raster *r)
{
    size_t n = 0;
    int x, y;
    for (y = 0; y < r->height; y++)
        for (x = 0; x < r->width; x++)
            n += isnan(TS_PIX(r, x, y)) != 0;
    return n;
}

static void test_fills_everything_without_exemplar_nodata(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_exemplar(ctx, 160, 120, 1, 1), out;
    ts_synth_params p = small_params();
    int32_t *se, *sx, *sy, *ord;
    unsigned char *seams;
    ts_synth_maps maps;
    int order;
    memset(&maps, 0, sizeof maps);
    for (order = 0; order < 2; order++) {
        int x, y, bad_source = 0;
        p.order = order;
        ts_raster_alloc(ctx, 150, 110, &out);
        se = malloc(150 * 110 * sizeof *se);
        sx = malloc(150 * 110 * sizeof *sx);
        sy = malloc(150 * 110 * sizeof *sy);
        ord = malloc(150 * 110 * sizeof *ord);
        seams = malloc(150 * 110);
        maps.source_exemplar = se;
        maps.source_x = sx;
        maps.source_y = sy;
        maps.order = ord;
        maps.seams = seams;
        CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &out, &maps) == TS_OK);
        CHECK_MSG(count_nan(&out) == 0, "%zu NaN cells (order %d)", count_nan(&out), order);
        for (y = 0; y < 110; y++)
            for (x = 0; x < 150; x++) {
                int k = y * 150 + x;
                if (se[k] != 0 || sx[k] < 0 || sy[k] < 0 || isnan(TS_PIX(&ex, sx[k], sy[k])))
                    bad_source++;
                CHECK(ord[k] >= 0);
            }
        CHECK_MSG(bad_source == 0, "%d cells without a valid exemplar source", bad_source);
        free(se);
        free(sx);
        free(sy);
        free(ord);
        free(seams);
        ts_raster_free(&out);
    }
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

static void test_deterministic_and_seeded(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_exemplar(ctx, 160, 120, 2, 0), a, b, c;
    ts_synth_params p = small_params();
    ts_raster_alloc(ctx, 120, 100, &a);
    ts_raster_alloc(ctx, 120, 100, &b);
    ts_raster_alloc(ctx, 120, 100, &c);
    ts_ctx_set_seed(ctx, 42);
    ts_ctx_set_threads(ctx, 1);
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &a, NULL) == TS_OK);
    ts_ctx_set_threads(ctx, 2);
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &b, NULL) == TS_OK);
    ts_ctx_set_seed(ctx, 43);
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &c, NULL) == TS_OK);
    CHECK(memcmp(a.data, b.data, 120 * 100 * sizeof(float)) == 0);
    CHECK(memcmp(a.data, c.data, 120 * 100 * sizeof(float)) != 0);
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_raster_free(&c);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* Half smooth, half rough: the rough half's windows match only their own
 * continuation well, so SSD alone keeps to the smooth half. */
static ts_raster make_two_halves(ts_ctx *ctx, int w, int h, uint64_t seed)
{
    ts_raster r;
    int x, y;
    uint64_t s = seed;
    ts_raster_alloc(ctx, w, h, &r);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double v = 500.0 + 30.0 * sin(x / 23.0) * cos(y / 19.0);
            if (x >= w / 2)
                v += 25.0 * sin(x / 2.3 + 3.0 * th_uniform(&s)) * sin(y / 3.1) +
                     12.0 * th_uniform(&s);
            TS_PIX(&r, x, y) = (float)v;
        }
    return r;
}

/* The usage cost (an oracle from the source maps): with it the fill draws
 * on the rough half nearly as often as windows chosen at random would, and
 * no exemplar window is used much more than the average; without it the
 * smooth half wins.  On 1 and 2 threads, the same bytes. */
static void test_usage(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_two_halves(ctx, 200, 120, 3), out, again;
    ts_synth_params p = small_params();
    int W = 256, H = 256, k, pass;
    int32_t *sx = malloc((size_t)W * H * sizeof *sx), *sy = malloc((size_t)W * H * sizeof *sy);
    double rough_share[2], peak[2];
    ts_synth_maps maps;
    memset(&maps, 0, sizeof maps);
    maps.source_x = sx;
    maps.source_y = sy;
    ts_raster_alloc(ctx, W, H, &out);
    ts_raster_alloc(ctx, W, H, &again);
    for (pass = 0; pass < 2; pass++) {
        /* cells per exemplar cell, and the share from the rough half */
        int *use = calloc((size_t)ex.width * ex.height, sizeof *use), n_used = 0, most = 0;
        size_t rough = 0;
        p.usage = pass ? 30.0 : 0.0;
        for (k = 0; k < W * H; k++)
            out.data[k] = again.data[k] = NAN;
        ts_ctx_set_seed(ctx, 7);
        ts_ctx_set_threads(ctx, 2);
        maps.n_patches = 0; /* (the first patch index: it seeds each placement) */
        CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &out, &maps) == TS_OK);
        for (k = 0; k < W * H; k++) {
            rough += sx[k] >= ex.width / 2;
            use[sy[k] * ex.width + sx[k]]++;
        }
        for (k = 0; k < ex.width * ex.height; k++) {
            n_used += use[k] > 0;
            most = use[k] > most ? use[k] : most;
        }
        rough_share[pass] = (double)rough / (W * H);
        /* the most-used exemplar cell against the mean over all cells */
        peak[pass] = most / ((double)W * H / (ex.width * ex.height));
        printf("  usage %g: %.2f of the cells from the rough half, the most-used exemplar cell "
               "%.1f x the mean, %d of %d exemplar cells used\n",
               p.usage, rough_share[pass], peak[pass], n_used, ex.width * ex.height);
        free(use);
        if (pass) { /* deterministic on any thread count */
            ts_ctx_set_threads(ctx, 1);
            CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &again, NULL) == TS_OK);
            CHECK(memcmp(out.data, again.data, (size_t)W * H * sizeof(float)) == 0);
        }
    }
    /* windows at random would take about half from each side */
    CHECK_MSG(rough_share[1] >= 0.35, "usage on: %.2f from the rough half", rough_share[1]);
    CHECK_MSG(rough_share[1] >= rough_share[0] + 0.1, "usage on %.2f, off %.2f from the rough half",
              rough_share[1], rough_share[0]);
    CHECK_MSG(peak[1] < peak[0], "usage on: peak use %.1f x the mean, off %.1f", peak[1], peak[0]);
    free(sx);
    free(sy);
    ts_raster_free(&out);
    ts_raster_free(&again);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

static void test_keep_nodata_and_prefilled(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_exemplar(ctx, 160, 120, 3, 0), out;
    ts_synth_params p = small_params();
    unsigned char *keep = calloc(100 * 90, 1);
    int x, y, kept_nan = 1, far_kept = 1;
    ts_raster_alloc(ctx, 100, 90, &out);
    for (y = 0; y < 90; y++)
        for (x = 0; x < 100; x++) {
            if (x < 10)
                keep[y * 100 + x] = TS_CELL_NODATA; /* a nodata strip */
            if (x >= 60 && y >= 50) {
                TS_PIX(&out, x, y) = 1000.0f + (float)(x - y); /* a fixed pre-filled block */
                keep[y * 100 + x] = TS_CELL_FIXED;
            }
        }
    {
        ts_synth_constraints c = ts_synth_constraints_default();
        c.cell_flags = keep;
        CHECK(ts_synth_patches(ctx, &ex, 1, &p, &c, &out, NULL) == TS_OK);
    }
    for (y = 0; y < 90; y++)
        for (x = 0; x < 100; x++) {
            if (x < 10 && !isnan(TS_PIX(&out, x, y)))
                kept_nan = 0;
            if (x >= 10 && isnan(TS_PIX(&out, x, y)))
                kept_nan = 0;
            if (x >= 60 && y >= 50 && TS_PIX(&out, x, y) != 1000.0f + (float)(x - y))
                far_kept = 0;
        }
    CHECK(kept_nan);
    CHECK(far_kept);
    free(keep);
    ts_raster_free(&out);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* The sketch pipeline takes the same constraints: flagged nodata stays
 * NaN, a flagged fixed block is kept to the bit, the rest is made. */
/* Water: the land touching it ends at or above its level (water_banks.c).  The same
 * run with the water flagged as plain fixed cells is the reference: the fill does not
 * look at the water bit, so the banks alone make the difference, which is never
 * negative, nil past a patch from the water, and lifts every shore cell to the level. */
static void test_water_banks(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_exemplar(ctx, 160, 160, 21, 0), a, b;
    ts_synth_params p = small_params();
    ts_synth_constraints c = ts_synth_constraints_default();
    int W = 180, H = 150, x, y, below_ref = 0, below = 0, far_changed = 0, lowered = 0;
    unsigned char *fw = calloc((size_t)W * H, 1), *ff = calloc((size_t)W * H, 1);
    float level = 0;
    double sum = 0;
    size_t n = 0;
    for (y = 0; y < ex.height; y++)
        for (x = 0; x < ex.width; x++, n++)
            sum += TS_PIX(&ex, x, y);
    level = (float)(sum / (double)n); /* the exemplar's mean: much land below it */
    ts_raster_alloc(ctx, W, H, &a);
    ts_raster_alloc(ctx, W, H, &b);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int water = (x - 90) * (x - 90) / 900.0 + (y - 75) * (y - 75) / 400.0 < 1.0;
            size_t i = (size_t)y * W + (size_t)x;
            TS_PIX(&a, x, y) = TS_PIX(&b, x, y) = water ? level : NAN;
            fw[i] = water ? TS_CELL_FIXED | TS_CELL_WATER : 0;
            ff[i] = water ? TS_CELL_FIXED : 0;
        }
    ts_ctx_set_seed(ctx, 5);
    c.cell_flags = fw;
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, &c, &a, NULL) == TS_OK);
    c.cell_flags = ff;
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, &c, &b, NULL) == TS_OK);
    for (y = 1; y + 1 < H; y++)
        for (x = 1; x + 1 < W; x++) {
            size_t i = (size_t)y * W + (size_t)x;
            int dx, dy, shore = 0, near = 0;
            if (fw[i])
                continue;
            for (dy = -32; dy <= 32 && !near; dy++)
                for (dx = -32; dx <= 32; dx++) {
                    int u = x + dx, v = y + dy;
                    if (u >= 0 && v >= 0 && u < W && v < H && fw[(size_t)v * W + (size_t)u] &&
                        dx * dx + dy * dy < 32 * 32) {
                        near = 1;
                        break;
                    }
                }
            for (dy = -1; dy <= 1; dy++)
                for (dx = -1; dx <= 1; dx++)
                    shore |= fw[(size_t)(y + dy) * W + (size_t)(x + dx)] != 0;
            below_ref += shore && TS_PIX(&b, x, y) < level;
            below += shore && TS_PIX(&a, x, y) < level;
            lowered += TS_PIX(&a, x, y) < TS_PIX(&b, x, y);
            far_changed += !near && TS_PIX(&a, x, y) != TS_PIX(&b, x, y);
        }
    CHECK_MSG(below_ref > 0, "the reference has no shore below the water: the test shows nothing");
    CHECK_MSG(below == 0, "%d shore cells below the water (%d without the banks)", below,
              below_ref);
    CHECK_MSG(lowered == 0 && far_changed == 0, "%d cells lowered, %d changed past a patch",
              lowered, far_changed);
    free(fw);
    free(ff);
    ts_raster_free(&ex);
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_ctx_free(ctx);
}

static void test_sketch_keeps_constraints(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_exemplar(ctx, 220, 200, 5, 0), sk, out;
    ts_synth_params p = small_params();
    ts_sketch_params sp = ts_sketch_params_default();
    ts_synth_constraints c = ts_synth_constraints_default();
    unsigned char *flags = calloc(120 * 110, 1);
    int x, y, ok_nan = 1, ok_fixed = 1, ok_made = 1;
    ts_raster_alloc(ctx, 120, 110, &sk);
    ts_raster_alloc(ctx, 120, 110, &out);
    for (y = 0; y < 110; y++)
        for (x = 0; x < 120; x++) {
            /* a bright diagonal stroke on a dark ground */
            TS_PIX(&sk, x, y) = abs(x - y) < 3 ? 255.0f : 0.0f;
            if (x < 8)
                flags[y * 120 + x] = TS_CELL_NODATA;
            if (x >= 90 && y >= 85) {
                flags[y * 120 + x] = TS_CELL_FIXED;
                TS_PIX(&out, x, y) = 1000.0f + (float)(x - y);
            }
        }
    c.cell_flags = flags;
    sp.mode = TS_SKETCH_RIDGES;
    CHECK(ts_synth_sketch(ctx, &sk, &ex, 1, &sp, &p, &c, &out, NULL, NULL, NULL) == TS_OK);
    for (y = 0; y < 110; y++)
        for (x = 0; x < 120; x++) {
            float v = TS_PIX(&out, x, y);
            if (x < 8)
                ok_nan &= isnan(v) != 0;
            else if (x >= 90 && y >= 85)
                ok_fixed &= v == 1000.0f + (float)(x - y);
            else
                ok_made &= isfinite(v) != 0;
        }
    CHECK(ok_nan);
    CHECK(ok_fixed);
    CHECK(ok_made);
    /* alpha_h out of range is refused */
    c.heights = out.data;
    c.alpha_h = -1.0;
    CHECK(ts_synth_sketch(ctx, &sk, &ex, 1, &sp, &p, &c, &out, NULL, NULL, NULL) == TS_ERR_ARG);
    free(flags);
    ts_raster_free(&sk);
    ts_raster_free(&out);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

static void test_several_exemplars(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex[2], out;
    ts_synth_params p = small_params();
    int32_t *se = malloc(128 * 128 * sizeof *se);
    ts_synth_maps maps;
    int used[2] = {0, 0}, i;
    memset(&maps, 0, sizeof maps);
    maps.source_exemplar = se;
    ex[0] = make_exemplar(ctx, 100, 100, 4, 0);
    ex[1] = make_exemplar(ctx, 90, 110, 5, 0);
    ts_raster_alloc(ctx, 128, 128, &out);
    ts_ctx_set_seed(ctx, 9);
    CHECK(ts_synth_patches(ctx, ex, 2, &p, NULL, &out, &maps) == TS_OK);
    for (i = 0; i < 128 * 128; i++)
        if (se[i] == 0 || se[i] == 1)
            used[se[i]]++;
    CHECK(used[0] + used[1] == 128 * 128);
    CHECK(count_nan(&out) == 0);
    free(se);
    ts_raster_free(&out);
    ts_raster_free(&ex[0]);
    ts_raster_free(&ex[1]);
    ts_ctx_free(ctx);
}

static int cancel_soon(double done, const char *msg, void *user)
{
    (void)msg;
    (void)user;
    return done < 0.4;
}

/* Lengths in metres become whole cells of the grid, then are checked. */
static void test_resolve_metres(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_synth_params p = ts_synth_params_default();
    CHECK(ts_params_set(ctx, "synth", &p, "patch_size", "3000m") == TS_OK);
    CHECK(ts_params_set(ctx, "synth", &p, "overlap", "700m") == TS_OK);
    CHECK(p.patch_size.unit == TS_UNIT_METRES && p.patch_size.value == 3000.0);
    CHECK(ts_synth_params_resolve(ctx, &p, 30.0) == TS_OK);
    CHECK(p.patch_size.unit == TS_UNIT_CELLS && p.patch_size.value == 100.0);
    CHECK(p.overlap.unit == TS_UNIT_CELLS && p.overlap.value == 23.0); /* 23.3 rounds down */
    /* cells stay as they are */
    CHECK(ts_synth_params_resolve(ctx, &p, 10.0) == TS_OK && p.patch_size.value == 100.0);
    /* no ground size: metres cannot be turned into cells */
    p = ts_synth_params_default();
    CHECK(ts_params_set(ctx, "synth", &p, "patch_size", "3000m") == TS_OK);
    CHECK(ts_synth_params_resolve(ctx, &p, 0.0) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "no ground size") != NULL);
    /* too many or too few cells, and an overlap as wide as the patch */
    CHECK(ts_synth_params_resolve(ctx, &p, 1.0) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "3000 cells") != NULL);
    CHECK(ts_synth_params_resolve(ctx, &p, 1000.0) == TS_ERR_ARG);
    p = ts_synth_params_default();
    CHECK(ts_params_set(ctx, "synth", &p, "overlap", "2000m") == TS_OK);
    CHECK(ts_synth_params_resolve(ctx, &p, 30.0) == TS_ERR_ARG); /* 67 cells >= 64 */
    CHECK(strstr(ts_ctx_message(ctx), "at most half of patch_size") != NULL);
    /* the bound: half the patch is the most (31 of 32 took 86x the default's time) */
    p = ts_synth_params_default();
    p.patch_size.value = 32;
    p.overlap.value = 16;
    CHECK(ts_synth_params_resolve(ctx, &p, 30.0) == TS_OK);
    p.overlap.value = 17;
    CHECK(ts_synth_params_resolve(ctx, &p, 30.0) == TS_ERR_ARG);
    p.overlap.value = 31;
    CHECK(ts_synth_params_resolve(ctx, &p, 30.0) == TS_ERR_ARG);
    /* negative or unknown units are refused when set */
    CHECK(ts_params_set(ctx, "synth", &p, "patch_size", "-5m") == TS_ERR_ARG);
    CHECK(ts_params_set(ctx, "synth", &p, "patch_size", "5km") == TS_ERR_ARG);
    CHECK(ts_params_set(ctx, "synth", &p, "patch_size", "2000") == TS_ERR_ARG);
    ts_ctx_free(ctx);
}

static void test_errors_and_cancel(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_exemplar(ctx, 160, 120, 6, 0), small = make_exemplar(ctx, 20, 20, 7, 0),
              out;
    ts_synth_params p = small_params();
    ts_raster_alloc(ctx, 100, 100, &out);
    CHECK(ts_synth_patches(ctx, &small, 1, &p, NULL, &out, NULL) == TS_ERR_SIZE);
    CHECK(strstr(ts_ctx_message(ctx), "smaller than a patch") != NULL);
    p.overlap.value = 40;
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &out, NULL) == TS_ERR_ARG);
    p = small_params();
    p.patch_size.value = 5000;
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &out, NULL) == TS_ERR_ARG);
    /* lengths in cells must be whole; metres must be resolved first */
    p = small_params();
    p.patch_size.value = 32.5;
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &out, NULL) == TS_ERR_ARG);
    p = small_params();
    p.patch_size.unit = TS_UNIT_METRES;
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &out, NULL) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "ts_synth_params_resolve") != NULL);
    p = small_params();
    {
        ts_raster tiny;
        ts_raster_alloc(ctx, 10, 10, &tiny);
        CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &tiny, NULL) == TS_ERR_SIZE);
        ts_raster_free(&tiny);
    }
    {
        ts_raster allnan;
        ts_raster_alloc(ctx, 64, 64, &allnan);
        CHECK(ts_synth_patches(ctx, &allnan, 1, &p, NULL, &out, NULL) == TS_ERR_NUMERIC);
        ts_raster_free(&allnan);
    }
    ts_ctx_set_progress(ctx, cancel_soon, NULL);
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &out, NULL) == TS_ERR_CANCELLED);
    ts_raster_free(&out);
    ts_raster_free(&ex);
    ts_raster_free(&small);
    ts_ctx_free(ctx);
}

/* Tiles in four waves (tiled_synthesis.c): every cell filled from the
 * exemplar's range; the same bytes on 1, 2 and 3 threads (the tiles of a
 * wave run side by side, in any order); no step across a tile border
 * steeper than the exemplar's steepest steps (the later tile cut and
 * smoothed it); the cores of the first wave are what a synthesis of the
 * grown tile alone gives (an oracle: the public call on that window with
 * the tile's seed); refusals. */
static uint64_t tile_seed_of(uint64_t seed, int i, int j)
{
    uint64_t z = seed ^ (0x9e3779b97f4a7c15ull * ((uint64_t)(uint32_t)i + 1)) ^
                 (0xc2b2ae3d27d4eb4full * ((uint64_t)(uint32_t)j + 1));
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static void test_tiles(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_exemplar(ctx, 160, 120, 8, 0), a, b, c, lone;
    ts_synth_params p = small_params();
    const int W = 230, H = 170, T = 64;
    double lo = 1e30, hi = -1e30, ex_step = 0.0, worst = 0.0;
    int x, y, P = (int)p.patch_size.value;
    ts_raster_alloc(ctx, W, H, &a);
    ts_raster_alloc(ctx, W, H, &b);
    ts_raster_alloc(ctx, W, H, &c);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&a, x, y) = TS_PIX(&b, x, y) = TS_PIX(&c, x, y) = NAN;
    p.tiled = T;
    ts_ctx_set_seed(ctx, 77);
    ts_ctx_set_threads(ctx, 1);
    CHECK_MSG(ts_synth_patches(ctx, &ex, 1, &p, NULL, &a, NULL) == TS_OK, "%s",
              ts_ctx_message(ctx));
    ts_ctx_set_threads(ctx, 2);
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &b, NULL) == TS_OK);
    ts_ctx_set_threads(ctx, 3);
    CHECK(ts_synth_tiled(ctx, &ex, 1, &p, NULL, T, &c) == TS_OK);
    CHECK(memcmp(a.data, b.data, sizeof(float) * W * H) == 0);
    CHECK(memcmp(a.data, c.data, sizeof(float) * W * H) == 0);
    /* with the debug maps the tiles run wave by wave, without them row by row
     * (three rows of windows alive): two orders, the same heights */
    {
        ts_synth_maps maps;
        int32_t *se = malloc(sizeof(int32_t) * W * H);
        memset(&maps, 0, sizeof maps);
        maps.source_exemplar = se;
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++)
                TS_PIX(&b, x, y) = NAN;
        p.tiled = T;
        ts_ctx_set_threads(ctx, 2);
        CHECK(se && ts_synth_patches(ctx, &ex, 1, &p, NULL, &b, &maps) == TS_OK);
        CHECK_MSG(memcmp(a.data, b.data, sizeof(float) * W * H) == 0,
                  "tiles in rows and in waves differ");
        free(se);
    }
    /* bands of rows of two sizes, the same bytes: 32 tiles a row, 7 rows; 1 thread takes
     * bands of 2 odd rows (a step of 32 tiles at least, tiles of 64: 2048 / 64 a thread),
     * so the first band's windows are freed before the second runs; 5 threads one band of
     * every row */
    {
        ts_raster t1, t5;
        const int W2 = 32 * T, H2 = 7 * T - 20;
        int ok = ts_raster_alloc(ctx, W2, H2, &t1) == TS_OK &&
                 ts_raster_alloc(ctx, W2, H2, &t5) == TS_OK;
        CHECK(ok && ts_synth_tiled_band(1, W2, T) == 2 && ts_synth_tiled_band(5, W2, T) >= 4);
        for (y = 0; ok && y < H2; y++)
            for (x = 0; x < W2; x++)
                TS_PIX(&t1, x, y) = TS_PIX(&t5, x, y) = NAN;
        ts_ctx_set_threads(ctx, 1);
        CHECK(ok && ts_synth_tiled(ctx, &ex, 1, &p, NULL, T, &t1) == TS_OK);
        ts_ctx_set_threads(ctx, 5);
        CHECK(ok && ts_synth_tiled(ctx, &ex, 1, &p, NULL, T, &t5) == TS_OK);
        CHECK_MSG(ok && memcmp(t1.data, t5.data, sizeof(float) * (size_t)W2 * (size_t)H2) == 0,
                  "tiles in bands of two sizes differ");
        ts_raster_free(&t1);
        ts_raster_free(&t5);
    }
    for (y = 0; y < 120; y++)
        for (x = 0; x < 160; x++) {
            lo = fmin(lo, TS_PIX(&ex, x, y));
            hi = fmax(hi, TS_PIX(&ex, x, y));
            if (x > 0)
                ex_step = fmax(ex_step, fabs(TS_PIX(&ex, x, y) - TS_PIX(&ex, x - 1, y)));
            if (y > 0)
                ex_step = fmax(ex_step, fabs(TS_PIX(&ex, x, y) - TS_PIX(&ex, x, y - 1)));
        }
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            float v = TS_PIX(&a, x, y);
            CHECK(!isnan(v) && v > lo - 0.2 * (hi - lo) && v < hi + 0.2 * (hi - lo));
            if (x > 0 && x % T == 0) /* across a vertical tile border */
                worst = fmax(worst, fabs(v - TS_PIX(&a, x - 1, y)));
            if (y > 0 && y % T == 0)
                worst = fmax(worst, fabs(v - TS_PIX(&a, x, y - 1)));
        }
    printf("     tiles: worst step across a tile border %.1f, the exemplar's %.1f\n", worst,
           ex_step);
    CHECK_MSG(worst <= 1.5 * ex_step, "worst step %g against %g", worst, ex_step);
    /* wave 0's tile (2, 0): the public call alone on its grown window, its seed */
    {
        int x0 = 2 * T - P, x1 = 3 * T + P, y1 = T + P, same = 1;
        ts_raster_alloc(ctx, x1 - x0, y1, &lone);
        for (y = 0; y < y1; y++)
            for (x = 0; x < x1 - x0; x++)
                TS_PIX(&lone, x, y) = NAN;
        p.tiled = 0;
        ts_ctx_set_seed(ctx, tile_seed_of(77, 2, 0));
        CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &lone, NULL) == TS_OK);
        for (y = 0; y < T; y++)
            for (x = 2 * T; x < 3 * T; x++)
                same &= memcmp(&TS_PIX(&lone, x - x0, y), &TS_PIX(&a, x, y), sizeof(float)) == 0;
        CHECK_MSG(same, "wave 0's core differs from its tile made alone");
        ts_raster_free(&lone);
    }
    /* tile (3, 1) of wave 3 made alone through ts_synth_tiles from only the
     * tiles it needs (its cone), each made alone in wave order, one call per
     * tile, in reverse order within a wave: the same bytes as the whole run */
    {
        enum { NTI = 4, NTJ = 3 };
        ts_raster wins[NTJ][NTI];
        int need[NTJ][NTI], i, j, w, di, dj, changed = 1, same = 1, n_need = 0, win[4], core[4];
        memset(need, 0, sizeof need);
        need[1][3] = 1;
        while (changed) { /* the cone: earlier-wave neighbours of needed tiles */
            changed = 0;
            for (j = 0; j < NTJ; j++)
                for (i = 0; i < NTI; i++)
                    for (dj = -1; dj <= 1 && need[j][i]; dj++)
                        for (di = -1; di <= 1; di++)
                            if (i + di >= 0 && j + dj >= 0 && i + di < NTI && j + dj < NTJ &&
                                ts_synth_tile_wave(i + di, j + dj) < ts_synth_tile_wave(i, j) &&
                                !need[j + dj][i + di])
                                need[j + dj][i + di] = changed = 1;
        }
        p.tiled = 0;
        for (j = 0; j < NTJ; j++)
            for (i = 0; i < NTI; i++) {
                CHECK(ts_synth_tile_window(ctx, &p, T, W, H, i, j, win, core) == TS_OK);
                CHECK(core[0] == i * T && core[1] == j * T && core[2] == (i < 3 ? T : W - 3 * T));
                CHECK(win[0] == (i ? i * T - P : 0) && win[2] >= core[2]);
                ts_raster_alloc(ctx, win[2], win[3], &wins[j][i]);
                n_need += need[j][i];
            }
        CHECK(n_need < NTI * NTJ); /* the cone is not everything */
        ts_ctx_set_seed(ctx, 77);
        ts_ctx_set_threads(ctx, 1);
        for (w = 0; w < 4; w++)
            for (j = NTJ - 1; j >= 0; j--)
                for (i = NTI - 1; i >= 0; i--) {
                    ts_synth_tile t;
                    if (!need[j][i] || ts_synth_tile_wave(i, j) != w)
                        continue;
                    memset(&t, 0, sizeof t);
                    t.ti = i;
                    t.tj = j;
                    t.window = wins[j][i];
                    for (dj = -1; dj <= 1; dj++)
                        for (di = -1; di <= 1; di++)
                            if (i + di >= 0 && j + dj >= 0 && i + di < NTI && j + dj < NTJ &&
                                need[j + dj][i + di])
                                t.neighbours[(dj + 1) * 3 + di + 1] = &wins[j + dj][i + di];
                    CHECK_MSG(ts_synth_tiles(ctx, &ex, 1, &p, T, W, H, &t, 1) == TS_OK, "%s",
                              ts_ctx_message(ctx));
                }
        CHECK(ts_synth_tile_window(ctx, &p, T, W, H, 3, 1, win, core) == TS_OK);
        for (y = 0; y < T; y++)
            same &= memcmp(&TS_PIX(&wins[1][3], 3 * T - win[0], T + y - win[1]),
                           &TS_PIX(&a, 3 * T, T + y), sizeof(float) * (size_t)(W - 3 * T)) == 0;
        CHECK_MSG(same, "tile (3, 1) made from its cone differs from the whole run");
        printf("     tiles: tile (3, 1) from %d of %d tiles, as in the whole run\n", n_need,
               NTI * NTJ);
        /* refusals: a needed neighbour missing; two waves' neighbours in one call;
         * a tile off the grid */
        {
            ts_synth_tile two[2];
            memset(two, 0, sizeof two);
            two[0].ti = 3;
            two[0].tj = 1;
            two[0].window = wins[1][3];
            CHECK(ts_synth_tiles(ctx, &ex, 1, &p, T, W, H, two, 1) == TS_ERR_ARG);
            CHECK(strstr(ts_ctx_message(ctx), "needs") != NULL);
            two[0].ti = 0;
            two[0].tj = 0;
            two[0].window = wins[0][0];
            two[1].ti = 1;
            two[1].tj = 0;
            two[1].window = wins[0][1];
            two[1].neighbours[3] = &wins[0][0];
            two[1].neighbours[5] = &wins[0][2];
            CHECK(ts_synth_tiles(ctx, &ex, 1, &p, T, W, H, two, 2) == TS_ERR_ARG);
            CHECK(strstr(ts_ctx_message(ctx), "two waves") != NULL);
            CHECK(ts_synth_tile_window(ctx, &p, T, W, H, 4, 0, win, core) == TS_ERR_ARG);
        }
        for (j = 0; j < NTJ; j++)
            for (i = 0; i < NTI; i++)
                ts_raster_free(&wins[j][i]);
    }
    /* another seed, another terrain; refusals */
    p.tiled = T;
    ts_ctx_set_seed(ctx, 78);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&b, x, y) = NAN;
    CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &b, NULL) == TS_OK);
    CHECK(memcmp(a.data, b.data, sizeof(float) * W * H) != 0);
    CHECK(ts_synth_tiled(ctx, &ex, 1, &p, NULL, P, &b) == TS_ERR_ARG); /* under 2 patches */
    CHECK(strstr(ts_ctx_message(ctx), "tiles") != NULL);
    {
        ts_synth_maps maps;
        int32_t *order = malloc(sizeof(int32_t) * (size_t)W * H);
        memset(&maps, 0, sizeof maps);
        size_t k, unset = 0;
        maps.order = order;
        /* debug maps in tiles: the same terrain as without, every cell from a patch */
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++)
                TS_PIX(&c, x, y) = NAN;
        ts_ctx_set_seed(ctx, 78);
        CHECK(ts_synth_patches(ctx, &ex, 1, &p, NULL, &c, &maps) == TS_OK);
        CHECK(memcmp(b.data, c.data, sizeof(float) * W * H) == 0);
        for (k = 0; k < (size_t)W * H; k++)
            unset += order[k] < 0 || order[k] >= maps.n_patches;
        CHECK_MSG(unset == 0, "%zu cells without a patch index (%d patches)", unset,
                  maps.n_patches);
        free(order);
    }
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_raster_free(&c);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* Tiles with the whole grid's constraints: pinned cells keep their values
 * exactly, nodata cells stay empty, each region takes its exemplar (a
 * smooth one on the left, a rough one on the right: the right third's mean
 * |Laplacian| several times the left third's, as in one piece), the same
 * bytes on 1 and 3 threads. */
static double mean_abs_lap(const ts_raster *r, const unsigned char *fl, int x0, int x1)
{
    double s = 0.0;
    int x, y, n = 0;
    for (y = 1; y < r->height - 1; y++)
        for (x = x0 > 1 ? x0 : 1; x < (x1 < r->width - 1 ? x1 : r->width - 1); x++) {
            double l = TS_PIX(r, x - 1, y) + TS_PIX(r, x + 1, y) + TS_PIX(r, x, y - 1) +
                       TS_PIX(r, x, y + 1) - 4.0 * TS_PIX(r, x, y);
            if (fl[(size_t)y * (size_t)r->width + (size_t)x] || isnan(l))
                continue;
            s += fabs(l);
            n++;
        }
    return n ? s / n : 0.0;
}

static void test_tiles_constraints(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex[2], out[3];
    ts_synth_params p = small_params();
    const int W = 300, H = 200, T = 64;
    unsigned char *fl = calloc((size_t)W * H, 1);
    int32_t *reg = malloc(sizeof(int32_t) * (size_t)W * H);
    ts_synth_constraints cons = ts_synth_constraints_default();
    int x, y, k, pins_ok = 1, holes_ok = 1, filled_ok = 1;
    double ratio[3];
    ex[0] = make_exemplar(ctx, 160, 120, 8, 0);
    ex[1] = make_exemplar(ctx, 160, 120, 9, 0);
    for (y = 0; y < 120; y++)
        for (x = 0; x < 160; x++)
            TS_PIX(&ex[1], x, y) += (float)(60.0 * sin(x / 1.7) * sin(y / 2.1));
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            size_t c = (size_t)y * W + (size_t)x;
            reg[c] = x < W / 2 ? 0 : 1;
            if (x >= 100 && x < 140 && y >= 60 && y < 100)
                fl[c] = TS_CELL_FIXED; /* across tile borders (64, 128) */
            if (x >= 220 && x < 240 && y >= 20 && y < 40)
                fl[c] = TS_CELL_NODATA;
        }
    cons.cell_flags = fl;
    cons.cell_exemplar = reg;
    for (k = 0; k < 3; k++) { /* tiles on 1 and 3 threads, one piece */
        ts_raster_alloc(ctx, W, H, &out[k]);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++)
                TS_PIX(&out[k], x, y) =
                    fl[(size_t)y * W + (size_t)x] & TS_CELL_FIXED ? 1000.0f : NAN;
        p.tiled = k < 2 ? T : 0;
        ts_ctx_set_seed(ctx, 31);
        ts_ctx_set_threads(ctx, k == 1 ? 3 : 1);
        CHECK_MSG(ts_synth_patches(ctx, ex, 2, &p, &cons, &out[k], NULL) == TS_OK, "%s",
                  ts_ctx_message(ctx));
        ratio[k] = mean_abs_lap(&out[k], fl, 2 * W / 3, W) / mean_abs_lap(&out[k], fl, 0, W / 3);
    }
    CHECK(memcmp(out[0].data, out[1].data, sizeof(float) * (size_t)W * H) == 0);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            unsigned char f = fl[(size_t)y * W + (size_t)x];
            float v = TS_PIX(&out[0], x, y);
            if (f & TS_CELL_FIXED)
                pins_ok &= v == 1000.0f;
            else if (f & TS_CELL_NODATA)
                holes_ok &= isnan(v);
            else
                filled_ok &= !isnan(v);
        }
    CHECK(pins_ok);
    CHECK(holes_ok);
    CHECK(filled_ok);
    /* tile by tile (ts_synth_tiles, as the driver serves a recipe), each with its
     * window's part of the constraints: the same bytes as the whole run */
    {
        int nti = (W + T - 1) / T, ntj = (H + T - 1) / T, wave, ti, tj, di, dj, same = 1;
        ts_raster *win = calloc((size_t)nti * ntj, sizeof *win);
        for (wave = 0; wave < 4; wave++)
            for (tj = 0; tj < ntj; tj++)
                for (ti = 0; ti < nti; ti++) {
                    int w[4], c[4], at = tj * nti + ti;
                    size_t n, i;
                    unsigned char *wf;
                    int32_t *wr;
                    ts_synth_tile t;
                    ts_synth_constraints wc = ts_synth_constraints_default();
                    if (ts_synth_tile_wave(ti, tj) != wave)
                        continue;
                    p.tiled = T;
                    CHECK(ts_synth_tile_window(ctx, &p, T, W, H, ti, tj, w, c) == TS_OK);
                    ts_raster_alloc(ctx, w[2], w[3], &win[at]);
                    n = (size_t)w[2] * w[3];
                    wf = malloc(n);
                    wr = malloc(n * sizeof *wr);
                    for (i = 0; i < n; i++) {
                        size_t g = (size_t)(w[1] + (int)(i / (size_t)w[2])) * W +
                                   (size_t)(w[0] + (int)(i % (size_t)w[2]));
                        wf[i] = fl[g];
                        wr[i] = reg[g];
                        win[at]
                            .data[(i / (size_t)w[2]) * (size_t)win[at].stride + i % (size_t)w[2]] =
                            fl[g] & TS_CELL_FIXED ? 1000.0f : NAN;
                    }
                    wc.cell_flags = wf;
                    wc.cell_exemplar = wr;
                    memset(&t, 0, sizeof t);
                    t.ti = ti;
                    t.tj = tj;
                    t.window = win[at];
                    t.constraints = &wc;
                    for (dj = -1; dj <= 1; dj++)
                        for (di = -1; di <= 1; di++)
                            if ((di || dj) && ti + di >= 0 && tj + dj >= 0 && ti + di < nti &&
                                tj + dj < ntj && ts_synth_tile_wave(ti + di, tj + dj) < wave)
                                t.neighbours[(dj + 1) * 3 + di + 1] = &win[at + dj * nti + di];
                    ts_ctx_set_seed(ctx, 31);
                    CHECK_MSG(ts_synth_tiles(ctx, ex, 2, &p, T, W, H, &t, 1) == TS_OK, "%s",
                              ts_ctx_message(ctx));
                    for (y = c[1]; y < c[1] + c[3]; y++)
                        for (x = c[0]; x < c[0] + c[2]; x++) {
                            float a = TS_PIX(&win[at], x - w[0], y - w[1]),
                                  b = TS_PIX(&out[0], x, y);
                            same &= (isnan(a) && isnan(b)) || a == b;
                        }
                    free(wf);
                    free(wr);
                }
        CHECK_MSG(same, "tiles made one by one with their windows' constraints differ from "
                        "the whole run");
        for (k = 0; k < nti * ntj; k++)
            ts_raster_free(&win[k]);
        free(win);
    }
    printf("     tiles with regions: right third / left third mean |Laplacian| %.2f "
           "(one piece %.2f)\n",
           ratio[0], ratio[2]);
    CHECK(ratio[0] > 2.0 && ratio[0] > 0.7 * ratio[2]);
    for (k = 0; k < 3; k++)
        ts_raster_free(&out[k]);
    ts_raster_free(&ex[0]);
    ts_raster_free(&ex[1]);
    free(fl);
    free(reg);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"fills_everything_without_exemplar_nodata", test_fills_everything_without_exemplar_nodata},
        {"deterministic_and_seeded", test_deterministic_and_seeded},
        {"usage", test_usage},
        {"keep_nodata_and_prefilled", test_keep_nodata_and_prefilled},
        {"water_banks", test_water_banks},
        {"several_exemplars", test_several_exemplars},
        {"sketch_keeps_constraints", test_sketch_keeps_constraints},
        {"resolve_metres", test_resolve_metres},
        {"errors_and_cancel", test_errors_and_cancel},
        {"tiles", test_tiles},
        {"tiles_constraints", test_tiles_constraints},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
