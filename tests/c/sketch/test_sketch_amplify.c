/*
 * test_sketch_amplify.c - a sketch in tiles (algorithms/src/sketch/
 * sketch_amplify.c: laid out K times coarser, then amplified), against
 * oracles written here: the output averaged over K x K blocks is the
 * one-piece sketch synthesis of the block-averaged sketch and exemplar with
 * patches K times smaller (amplification gives back its input when
 * averaged), for drawn valleys with the cells within a cell of the floors
 * that run carved (its valley floor map) replaced by their 3 x 3 means; a ridge drawn as a line
 * stands above the land beside it; the same bytes on 1 and 3 threads; windows made alone
 * (ts_sketch_tiles_window) equal to the same windows of the whole; the sketch's nodata stays
 * nodata; pins and a factor that leaves patches under 8 cells are refused.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "internal.h"

#define W 190 /* not a multiple of K: the last coarse column is half a block */
#define H 171
#define K 2

static ts_raster exemplar(ts_ctx *ctx, int w, int h, uint64_t seed)
{
    ts_raster r;
    int x, y;
    uint64_t s = seed;
    double ph[5];
    for (x = 0; x < 5; x++)
        ph[x] = 6.283 * th_uniform(&s);
    ts_raster_alloc(ctx, w, h, &r);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            TS_PIX(&r, x, y) =
                (float)(1000.0 + 80.0 * sin(x / 13.0 + ph[0]) * cos(y / 17.0 + ph[1]) +
                        40.0 * sin((x + y) / 7.0 + ph[2]) +
                        15.0 * sin(x / 3.1 + ph[3]) * sin(y / 4.3 + ph[4]) + 3.0 * th_uniform(&s));
    return r;
}

static ts_synth_params params(int patch, int overlap, int tiled)
{
    ts_synth_params p = ts_synth_params_default();
    p.patch_size.value = patch;
    p.overlap.value = overlap;
    p.candidates = 4;
    p.coarse_factor = 2;
    p.tiled = tiled;
    return p;
}

/* The slow reference: the mean of the valid cells of each k x k block (the
 * part inside the grid); with strict, NaN when any cell is NaN. */
static ts_raster block_mean(ts_ctx *ctx, const ts_raster *in, int k, int strict)
{
    ts_raster r;
    int x, y, u, v;
    ts_raster_alloc(ctx, (in->width + k - 1) / k, (in->height + k - 1) / k, &r);
    for (y = 0; y < r.height; y++)
        for (x = 0; x < r.width; x++) {
            double s = 0;
            int n = 0, nan = 0;
            for (v = 0; v < k; v++)
                for (u = 0; u < k; u++) {
                    int fx = x * k + u, fy = y * k + v;
                    if (fx >= in->width || fy >= in->height)
                        continue;
                    if (isnan(TS_PIX(in, fx, fy)))
                        nan++;
                    else {
                        s += TS_PIX(in, fx, fy);
                        n++;
                    }
                }
            TS_PIX(&r, x, y) = n == 0 || (strict && nan) ? NAN : (float)(s / n);
        }
    return r;
}

static ts_raster diagonal_sketch(ts_ctx *ctx)
{
    ts_raster sk;
    int x, y;
    ts_raster_alloc(ctx, W, H, &sk);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&sk, x, y) = abs(x - y) < 4 ? 255.0f : 0.0f;
    return sk;
}

static ts_raster empty(ts_ctx *ctx, int w, int h)
{
    ts_raster r;
    ts_raster_alloc(ctx, w, h, &r); /* NaN everywhere */
    return r;
}

static void test_averages_to_the_coarse_pass(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = exemplar(ctx, 256, 224, 3), sk = diagonal_sketch(ctx), out = empty(ctx, W, H);
    ts_raster skc = block_mean(ctx, &sk, K, 0), exc = block_mean(ctx, &ex, K, 1);
    ts_raster ref = empty(ctx, skc.width, skc.height), avg;
    ts_synth_params p = params(32, 8, 64), pc = params(32 / K, 8 / K, 0);
    ts_sketch_params sp = ts_sketch_params_default();
    double d = 0, s = 0, s2 = 0;
    int x, y, n = 0;
    sp.mode = TS_SKETCH_RIDGES;
    ts_ctx_set_seed(ctx, 7);
    CHECK(ts_sketch_amplify_factor(&sp, 32, W, H) == K);
    CHECK(ts_sketch_amplify_factor(&sp, 64, 4096, 4096) == 2);   /* patches of 32 */
    CHECK(ts_sketch_amplify_factor(&sp, 64, 16384, 16384) == 8); /* a coarse grid of 2048^2 */
    CHECK(ts_sketch_amplify_factor(&sp, 128, 1000, 1000) == 4);  /* patches of 32 */
    CHECK_MSG(ts_synth_sketch(ctx, &sk, &ex, 1, &sp, &p, NULL, &out, NULL, NULL, NULL) == TS_OK,
              "%s", ts_ctx_message(ctx));
    CHECK_MSG(ts_synth_sketch(ctx, &skc, &exc, 1, &sp, &pc, NULL, &ref, NULL, NULL, NULL) == TS_OK,
              "%s", ts_ctx_message(ctx));
    avg = block_mean(ctx, &out, K, 1);
    for (y = 0; y < H / K; y++) /* whole blocks only */
        for (x = 0; x < W / K; x++) {
            double r = TS_PIX(&ref, x, y);
            d += fabs(TS_PIX(&avg, x, y) - r);
            s += r;
            s2 += r * r;
            n++;
        }
    d /= n;
    s = sqrt(s2 / n - (s / n) * (s / n));
    printf("     averaged by %d: mean |difference| to the coarse pass %.3f m (its spread %.1f m)\n",
           K, d, s);
    CHECK_MSG(s > 10.0 && d < 0.02 * s, "mean difference %.3f, spread %.3f", d, s);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            CHECK(isfinite(TS_PIX(&out, x, y)));
    ts_raster_free(&avg);
    ts_raster_free(&ref);
    ts_raster_free(&skc);
    ts_raster_free(&exc);
    ts_raster_free(&out);
    ts_raster_free(&sk);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* The slow reference of the floors' softening: every cell with a floor cell
 * in its 3 x 3 takes the mean of its valid 3 x 3 cells, from a copy. */
static void soften_reference(ts_raster *z, const unsigned char *floor)
{
    ts_raster c;
    int x, y, u, v;
    ts_ctx *ctx = ts_ctx_new();
    ts_raster_alloc(ctx, z->width, z->height, &c);
    memcpy(c.data, z->data, (size_t)z->width * z->height * sizeof(float));
    for (y = 0; y < z->height; y++)
        for (x = 0; x < z->width; x++) {
            int touch = 0, n = 0;
            double sum = 0;
            for (v = -1; v <= 1; v++)
                for (u = -1; u <= 1; u++) {
                    int px = x + u, py = y + v;
                    if (px < 0 || py < 0 || px >= z->width || py >= z->height)
                        continue;
                    if (floor[py * z->width + px])
                        touch = 1;
                    if (!isnan(TS_PIX(&c, px, py))) {
                        sum += TS_PIX(&c, px, py);
                        n++;
                    }
                }
            if (touch && !isnan(TS_PIX(&c, x, y)))
                TS_PIX(z, x, y) = (float)(sum / n);
        }
    ts_raster_free(&c);
    ts_ctx_free(ctx);
}

static void test_valleys_average_to_the_softened_coarse_pass(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = exemplar(ctx, 256, 224, 4), sk, out = empty(ctx, W, H), skc, exc, ref, avg;
    ts_synth_params p = params(32, 8, 64), pc = params(32 / K, 8 / K, 0);
    ts_sketch_params sp = ts_sketch_params_default();
    ts_synth_maps maps;
    double d = 0, dmax = 0;
    int x, y, n = 0, floors = 0;
    ts_raster_alloc(ctx, W, H, &sk);
    for (y = 0; y < H; y++) /* a dark valley stroke down the middle, on to the bottom edge */
        for (x = 0; x < W; x++)
            TS_PIX(&sk, x, y) = abs(x - W / 2 - (y - H / 2) / 4) < 4 ? 0.0f : 255.0f;
    sp.mode = TS_SKETCH_VALLEYS;
    skc = block_mean(ctx, &sk, K, 0);
    exc = block_mean(ctx, &ex, K, 1);
    ref = empty(ctx, skc.width, skc.height);
    memset(&maps, 0, sizeof maps);
    maps.valley_floor = calloc((size_t)skc.width * skc.height, 1);
    ts_ctx_set_seed(ctx, 9);
    CHECK_MSG(ts_synth_sketch(ctx, &sk, &ex, 1, &sp, &p, NULL, &out, NULL, NULL, NULL) == TS_OK,
              "%s", ts_ctx_message(ctx));
    CHECK(ts_synth_sketch(ctx, &skc, &exc, 1, &sp, &pc, NULL, &ref, &maps, NULL, NULL) == TS_OK);
    for (x = 0; x < skc.width * skc.height; x++)
        floors += maps.valley_floor[x];
    soften_reference(&ref, maps.valley_floor);
    avg = block_mean(ctx, &out, K, 1);
    for (y = 0; y < H / K; y++)
        for (x = 0; x < W / K; x++) {
            double e = fabs(TS_PIX(&avg, x, y) - TS_PIX(&ref, x, y));
            d += e;
            dmax = e > dmax ? e : dmax;
            n++;
        }
    printf("     valleys averaged by %d: mean |difference| to the softened coarse pass %.3f m, "
           "largest %.2f m (%d floor cells)\n",
           K, d / n, dmax, floors);
    /* unsoftened, the floors' cells differ by up to 8.8 m here */
    CHECK_MSG(floors > 50 && d / n < 0.1 && dmax < 2.0, "mean %.3f, largest %.2f", d / n, dmax);
    free(maps.valley_floor);
    ts_raster_free(&avg);
    ts_raster_free(&ref);
    ts_raster_free(&skc);
    ts_raster_free(&exc);
    ts_raster_free(&out);
    ts_raster_free(&sk);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

static void test_lines_threads_nodata(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = exemplar(ctx, 256, 224, 5), a = empty(ctx, W, H), b = empty(ctx, W, H);
    ts_synth_params p = params(32, 8, 64);
    ts_sketch_params sp = ts_sketch_params_default();
    ts_synth_constraints c = ts_synth_constraints_default();
    unsigned char *flags = calloc((size_t)W * H, 1);
    double lx[2] = {20.5, 170.5}, ly[2] = {150.5, 30.5}, near = 0, far = 0;
    ts_sketch_line line = {TS_RIDGE, 2, lx, ly, NULL};
    ts_features *f = NULL;
    int x, y, nn = 0, nf = 0, ok_nan = 1;
    size_t i;
    for (y = 0; y < H; y++)
        for (x = 0; x < 6; x++)
            flags[(size_t)y * W + x] = TS_CELL_NODATA;
    c.cell_flags = flags;
    CHECK(ts_features_from_lines(ctx, W, H, &line, 1, 2.0, &f) == TS_OK);
    ts_ctx_set_seed(ctx, 11);
    ts_ctx_set_threads(ctx, 1);
    CHECK_MSG(ts_synth_sketch_features(ctx, f, &ex, 1, &sp, &p, &c, &a, NULL, NULL) == TS_OK, "%s",
              ts_ctx_message(ctx));
    ts_ctx_set_threads(ctx, 3);
    CHECK(ts_synth_sketch_features(ctx, f, &ex, 1, &sp, &p, &c, &b, NULL, NULL) == TS_OK);
    CHECK(memcmp(a.data, b.data, (size_t)W * H * sizeof(float)) == 0);
    /* the drawn ridge stands above the land a patch away from it */
    for (y = 0; y < H; y++)
        for (x = 6; x < W; x++) {
            double t = ((x + 0.5 - lx[0]) * (lx[1] - lx[0]) + (y + 0.5 - ly[0]) * (ly[1] - ly[0])) /
                       ((lx[1] - lx[0]) * (lx[1] - lx[0]) + (ly[1] - ly[0]) * (ly[1] - ly[0]));
            double px = lx[0] + t * (lx[1] - lx[0]), py = ly[0] + t * (ly[1] - ly[0]);
            double dd = hypot(x + 0.5 - px, y + 0.5 - py);
            if (t < 0.1 || t > 0.9)
                continue;
            if (dd < 2.0) {
                near += TS_PIX(&a, x, y);
                nn++;
            } else if (dd > 32.0) {
                far += TS_PIX(&a, x, y);
                nf++;
            }
        }
    printf("     drawn ridge %.1f m above the land a patch off\n", near / nn - far / nf);
    CHECK(nn > 100 && nf > 1000 && near / nn > far / nf + 20.0);
    for (i = 0; i < (size_t)W * H; i++)
        ok_nan &= (flags[i] & TS_CELL_NODATA) ? isnan(a.data[i]) != 0 : isfinite(a.data[i]) != 0;
    CHECK(ok_nan);
    ts_features_free(f);
    free(flags);
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

static void test_windows_equal_the_whole(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = exemplar(ctx, 256, 224, 3), sk = diagonal_sketch(ctx), out = empty(ctx, W, H);
    ts_synth_params p = params(32, 8, 64);
    ts_sketch_params sp = ts_sketch_params_default();
    ts_sketch_tiles *t = NULL;
    static const int win[4][4] = {
        {0, 0, 64, 64}, {101, 37, 50, 70}, {W - 33, H - 20, 33, 20}, {0, 0, W, H}};
    int k, x, y, same;
    sp.mode = TS_SKETCH_RIDGES;
    ts_ctx_set_seed(ctx, 7);
    CHECK(ts_synth_sketch(ctx, &sk, &ex, 1, &sp, &p, NULL, &out, NULL, NULL, NULL) == TS_OK);
    CHECK(ts_sketch_tiles_new(ctx, &sk, NULL, &ex, 1, &sp, &p, NULL, W, H, &t, NULL, NULL) ==
          TS_OK);
    CHECK(ts_sketch_tiles_factor(t) == K);
    for (k = 3; k >= 0; k--) { /* the whole last: windows in any order */
        ts_raster w;
        ts_raster_alloc(ctx, win[k][2], win[k][3], &w);
        CHECK(ts_sketch_tiles_window(ctx, t, win[k][0], win[k][1], &w) == TS_OK);
        same = 1;
        for (y = 0; y < w.height; y++)
            for (x = 0; x < w.width; x++)
                same &= memcmp(&TS_PIX(&w, x, y), &TS_PIX(&out, win[k][0] + x, win[k][1] + y),
                               sizeof(float)) == 0;
        CHECK_MSG(same, "window %d differs from the whole", k);
        ts_raster_free(&w);
    }
    {
        ts_raster w;
        ts_raster_alloc(ctx, 10, 10, &w);
        CHECK(ts_sketch_tiles_window(ctx, t, W - 5, 0, &w) == TS_ERR_ARG); /* off the grid */
        ts_raster_free(&w);
    }
    ts_sketch_tiles_free(t);
    ts_raster_free(&out);
    ts_raster_free(&sk);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

static void test_refusals(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = exemplar(ctx, 256, 224, 3), sk = diagonal_sketch(ctx), out = empty(ctx, W, H);
    ts_synth_params p = params(32, 8, 64);
    ts_sketch_params sp = ts_sketch_params_default();
    sp.mode = TS_SKETCH_RIDGES;
    sp.amplify_factor = 8; /* patches of 4 cells */
    CHECK(ts_synth_sketch(ctx, &sk, &ex, 1, &sp, &p, NULL, &out, NULL, NULL, NULL) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "amplify_factor") != NULL);
    sp.amplify_factor = 0;
    TS_PIX(&out, 50, 50) = 1000.0f; /* a pinned cell */
    CHECK(ts_synth_sketch(ctx, &sk, &ex, 1, &sp, &p, NULL, &out, NULL, NULL, NULL) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "pinned") != NULL);
    ts_raster_free(&out);
    ts_raster_free(&sk);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"averages_to_the_coarse_pass", test_averages_to_the_coarse_pass},
        {"valleys_average_to_the_softened_coarse_pass",
         test_valleys_average_to_the_softened_coarse_pass},
        {"lines_threads_nodata", test_lines_threads_nodata},
        {"windows_equal_the_whole", test_windows_equal_the_whole},
        {"refusals", test_refusals},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
