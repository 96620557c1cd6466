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
 * nodata; a factor that leaves patches under 8 cells is refused (pins and water:
 * test_sketch_tiles_fixed.c).
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
        CHECK(ts_sketch_tiles_window(ctx, t, win[k][0], win[k][1], &w, NULL) == TS_OK);
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
        CHECK(ts_sketch_tiles_window(ctx, t, W - 5, 0, &w, NULL) == TS_ERR_ARG); /* off the grid */
        ts_raster_free(&w);
    }
    ts_sketch_tiles_free(t);
    ts_raster_free(&out);
    ts_raster_free(&sk);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* The u64 at p, little-endian. */
static uint64_t get_u64(const unsigned char *p)
{
    uint64_t v = 0;
    int k;
    for (k = 7; k >= 0; k--)
        v = v << 8 | p[k];
    return v;
}

/* b (len bytes) with its closing checksum made right again. */
static void resum(unsigned char *b, size_t len)
{
    uint64_t sum = ts_checksum(0, b, len - 8);
    int k;
    for (k = 0; k < 8; k++)
        b[len - 8 + k] = (unsigned char)(sum >> (8 * k));
}

/* Whether window (x0, y0, w, h) of a and b are the same bytes. */
static int same_window(ts_ctx *ctx, const ts_sketch_tiles *a, const ts_sketch_tiles *b, int x0,
                       int y0, int w, int h)
{
    ts_raster ra, rb;
    int same;
    ts_raster_alloc(ctx, w, h, &ra);
    ts_raster_alloc(ctx, w, h, &rb);
    same = ts_sketch_tiles_window(ctx, a, x0, y0, &ra, NULL) == TS_OK &&
           ts_sketch_tiles_window(ctx, b, x0, y0, &rb, NULL) == TS_OK &&
           memcmp(ra.data, rb.data, (size_t)w * h * sizeof(float)) == 0;
    ts_raster_free(&ra);
    ts_raster_free(&rb);
    return same;
}

static void test_as_bytes(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = exemplar(ctx, 256, 224, 5);
    ts_synth_params p = params(32, 8, 64);
    ts_sketch_params sp = ts_sketch_params_default();
    ts_synth_constraints c = ts_synth_constraints_default();
    unsigned char *flags = calloc((size_t)W * H, 1), *got = calloc((size_t)W * H, 1), *b = NULL;
    double lx[3] = {20.5, 170.5, 100.5}, ly[3] = {150.5, 30.5, 5.5};
    ts_sketch_line line = {TS_RIDGE, 3, lx, ly, NULL};
    ts_features *f = NULL;
    ts_sketch_tiles *t = NULL, *u = NULL;
    uint64_t key = 0, n_runs, n_ridges;
    size_t len = 0, i, k, bad_ok = 1;
    int x, y, same = 1;
    for (y = 0; y < H; y++)
        for (x = 0; x < 6; x++)
            flags[(size_t)y * W + x] = TS_CELL_NODATA;
    c.cell_flags = flags;
    CHECK(ts_features_from_lines(ctx, W, H, &line, 1, 2.0, &f) == TS_OK);
    ts_ctx_set_seed(ctx, 11);
    CHECK_MSG(ts_sketch_tiles_new(ctx, NULL, f, &ex, 1, &sp, &p, &c, W, H, &t, NULL, NULL) == TS_OK,
              "%s", ts_ctx_message(ctx));
    /* the drawn ridges: the graph's ridge cells, over the grid and a window */
    ts_sketch_tiles_ridges(t, 0, 0, W, H, got, 4);
    for (i = 0; i < (size_t)W * H; i++)
        same &= (got[i] == 4) == ((f->mask[i] & TS_RIDGE) != 0);
    CHECK_MSG(same, "the ridge cells are not the graph's");
    memset(got, 0, (size_t)W * H);
    ts_sketch_tiles_ridges(t, 101, 7, 50, 70, got, 1);
    for (y = 0, same = 1; y < 70; y++)
        for (x = 0; x < 50; x++)
            same &= got[y * 50 + x] == ((f->mask[(size_t)(y + 7) * W + x + 101] & TS_RIDGE) != 0);
    CHECK_MSG(same, "the ridge cells of a window are not the graph's");
    /* as bytes and back: the key, and every window the same bytes */
    CHECK(ts_sketch_tiles_to_bytes(ctx, t, 0x0123456789abcdefull, &b, &len) == TS_OK);
    CHECK_MSG(ts_sketch_tiles_from_bytes(ctx, b, len, &key, &u) == TS_OK, "%s",
              ts_ctx_message(ctx));
    CHECK(key == 0x0123456789abcdefull && ts_sketch_tiles_factor(u) == K);
    CHECK(same_window(ctx, t, u, 0, 0, W, H) && same_window(ctx, t, u, 3, 40, 61, 33));
    memset(got, 0, (size_t)W * H);
    ts_sketch_tiles_ridges(u, 0, 0, W, H, got, 4);
    for (i = 0, same = 1; i < (size_t)W * H; i++)
        same &= (got[i] == 4) == ((f->mask[i] & TS_RIDGE) != 0);
    CHECK(same);
    ts_sketch_tiles_free(u);
    u = NULL;
    /* damaged: any byte changed, or the bytes cut, is refused */
    for (k = 0; k < len; k += (k < 64 || k + 16 > len) ? 1 : len / 300 + 1) {
        b[k] ^= 0x20;
        bad_ok &= ts_sketch_tiles_from_bytes(ctx, b, len, NULL, &u) == TS_ERR_ARG && !u;
        b[k] ^= 0x20;
    }
    for (k = 0; k < len; k += len / 13 + 1)
        bad_ok &= ts_sketch_tiles_from_bytes(ctx, b, k, NULL, &u) == TS_ERR_ARG && !u;
    CHECK_MSG(bad_ok, "a damaged sketch in tiles was read");
    /* with the checksum made right: sizes that do not add up, ridge cells out of order, a
     * coarse cell that is no height */
    n_runs = get_u64(b + 32);
    n_ridges = get_u64(b + 40);
    CHECK(n_runs == H && n_ridges > 10); /* a run of 6 cells a row */
    b[16] += 1;                          /* W */
    resum(b, len);
    CHECK(ts_sketch_tiles_from_bytes(ctx, b, len, NULL, &u) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "sizes") != NULL);
    b[16] -= 1;
    {
        unsigned char tmp[8], *r = b + 56 + 16 * n_runs;
        memcpy(tmp, r, 8);
        memcpy(r, r + 8, 8);
        memcpy(r + 8, tmp, 8);
        resum(b, len);
        CHECK(ts_sketch_tiles_from_bytes(ctx, b, len, NULL, &u) == TS_ERR_ARG);
        CHECK(strstr(ts_ctx_message(ctx), "ridge") != NULL);
        memcpy(r + 8, r, 8);
        memcpy(r, tmp, 8);
    }
    {
        unsigned char *z = b + 56 + 16 * n_runs + 8 * n_ridges + 4 * 40;
        union {
            float f;
            uint32_t u;
        } inf = {INFINITY};
        for (k = 0; k < 4; k++) /* little-endian, as the format is */
            z[k] = (unsigned char)(inf.u >> (8 * k));
        resum(b, len);
        CHECK(ts_sketch_tiles_from_bytes(ctx, b, len, NULL, &u) == TS_ERR_ARG);
        CHECK(strstr(ts_ctx_message(ctx), "coarse cell") != NULL);
    }
    free(b);
    ts_sketch_tiles_free(t);
    ts_features_free(f);
    free(flags);
    free(got);
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
        {"as_bytes", test_as_bytes},
        {"refusals", test_refusals},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
