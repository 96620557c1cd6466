/*
 * test_sketch_tiles_fixed.c - pinned windows and water in a sketch in tiles
 * (algorithms/src/sketch/sketch_tiles_fixed.c), against oracles written
 * here: the pins' blend against direct sums over every pinned cell and a
 * brute-force distance; the water's banks leave no free cell touching water
 * below it, lower nothing and change nothing beyond their reach; a sketch in
 * tiles keeps its pinned cells and water exactly, its shore at or above the
 * water, its pins' borders without a step above the land's own, and every
 * window made grown by ts_sketch_tiles_margin equals that window of the
 * whole; fixed cells without values are refused.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "internal.h"
#include "sketch_amplify.h"

#define W 190
#define H 171

static ts_raster exemplar(ts_ctx *ctx, int w, int h, uint64_t seed)
{
    ts_raster r;
    int x, y;
    uint64_t s = seed;
    ts_raster_alloc(ctx, w, h, &r);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            TS_PIX(&r, x, y) =
                (float)(1000.0 + 80.0 * sin(x / 13.0) * cos(y / 17.0) + 40.0 * sin((x + y) / 7.0) +
                        15.0 * sin(x / 3.1) * sin(y / 4.3) + 6.0 * th_uniform(&s));
    return r;
}

/* The slow reference of the pins' blend: for each free cell, the Gaussian
 * sums written out over every pinned cell in its square, the distance to the
 * nearest pinned cell by brute force. */
static void blend_reference(ts_raster *z, const unsigned char *flags, const float *values, int R)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster c;
    int x, y, u, v, w = z->width, h = z->height;
    double sg = R / 3.0;
    ts_raster_alloc(ctx, w, h, &c);
    memcpy(c.data, z->data, (size_t)w * h * sizeof(float));
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double num = 0, den = 0, fnum = 0, fden = 0, best = INFINITY, s, t, l;
            if (flags[y * w + x] & TS_CELL_FIXED)
                continue;
            for (v = 0; v < h; v++)
                for (u = 0; u < w; u++) {
                    int i = v * w + u, dx = u - x, dy = v - y;
                    double d;
                    if ((flags[i] & (TS_CELL_FIXED | TS_CELL_WATER)) != TS_CELL_FIXED)
                        continue;
                    d = values[i] - (double)TS_PIX(&c, u, v);
                    if (sqrt((double)dx * dx + dy * dy) < best)
                        best = sqrt((double)dx * dx + dy * dy);
                    if (abs(dx) <= R && abs(dy) <= R) {
                        double g = exp(-0.5 * (dx * dx + dy * dy) / (sg * sg));
                        num += g * d;
                        den += g;
                    }
                    if (abs(dx) <= 3 && abs(dy) <= 3) {
                        double g = exp(-0.5 * (dx * dx + dy * dy));
                        fnum += g * d;
                        fden += g;
                    }
                }
            t = (R - best) / (R - 1.0);
            if (!(t > 0) || !(den > 0))
                continue;
            t = t >= 1 ? 1 : t * t * (3 - 2 * t);
            s = num / den;
            if (fden > 0) {
                l = exp(-(best - 1.0) / 3.0);
                s = l * fnum / fden + (1 - l) * s;
            }
            TS_PIX(z, x, y) = (float)(TS_PIX(&c, x, y) + t * s);
        }
    ts_raster_free(&c);
    ts_ctx_free(ctx);
}

/* A pinned L-shaped window and, apart from it, a water disc of a 60 x 50 grid. */
static void small_fixed(unsigned char *flags, float *values, const ts_raster *z, double level)
{
    int x, y;
    for (y = 0; y < 50; y++)
        for (x = 0; x < 60; x++) {
            int i = y * 60 + x;
            values[i] = NAN;
            flags[i] = 0;
            if ((x >= 10 && x < 22 && y >= 12 && y < 36) ||
                (x >= 10 && x < 30 && y >= 28 && y < 36)) {
                flags[i] = TS_CELL_FIXED;
                values[i] =
                    TS_PIX(z, x, y) + 25.0f + (float)(x % 3); /* off by a step and a grain */
            } else if ((x - 46) * (x - 46) + (y - 14) * (y - 14) < 36) {
                flags[i] = TS_CELL_FIXED | TS_CELL_WATER;
                values[i] = (float)level;
            }
        }
}

static void test_pin_blend_against_direct_sums(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster z = exemplar(ctx, 60, 50, 5), ref;
    unsigned char flags[60 * 50];
    float values[60 * 50];
    double worst = 0;
    int x, y, R = 10, same_far = 1;
    small_fixed(flags, values, &z, 900.0);
    ts_raster_alloc(ctx, 60, 50, &ref);
    memcpy(ref.data, z.data, sizeof values);
    blend_reference(&ref, flags, values, R);
    {
        ts_raster orig;
        ts_raster_alloc(ctx, 60, 50, &orig);
        memcpy(orig.data, z.data, sizeof values);
        CHECK(ts__pin_blend(ctx, &z, flags, values, R) == TS_OK);
        for (y = 0; y < 50; y++)
            for (x = 0; x < 60; x++) {
                double d = fabs(TS_PIX(&z, x, y) - TS_PIX(&ref, x, y));
                worst = d > worst ? d : worst;
                /* beyond R of the pin (x >= 40 or y >= 46 is at least 10 cells off it) */
                if ((x >= 40 || y >= 46) && !(flags[y * 60 + x] & TS_CELL_FIXED))
                    same_far &= TS_PIX(&z, x, y) == TS_PIX(&orig, x, y);
            }
        ts_raster_free(&orig);
    }
    printf("     pins' blend against direct sums: worst difference %.2e m\n", worst);
    CHECK_MSG(worst < 1e-3, "worst %.3g", worst);
    CHECK(same_far);
    CHECK(ts__pin_blend(ctx, &z, flags, values, 1) == TS_ERR_ARG);
    ts_raster_free(&ref);
    ts_raster_free(&z);
    ts_ctx_free(ctx);
}

static void test_water_banks(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster z = exemplar(ctx, 60, 50, 6), orig;
    unsigned char flags[60 * 50];
    float values[60 * 50];
    double level = 1010.0; /* the exemplar's middle: part of the shore lies below it */
    int x, y, u, v, R = 10, below_before = 0, ok_shore = 1, lowered = 0, far_same = 1;
    small_fixed(flags, values, &z, level);
    ts_raster_alloc(ctx, 60, 50, &orig);
    memcpy(orig.data, z.data, sizeof values);
    CHECK(ts__water_banks_window(ctx, &z, flags, values, 3.0, R) == TS_OK);
    for (y = 0; y < 50; y++)
        for (x = 0; x < 60; x++) {
            int touch = 0, near = 0, i = y * 60 + x;
            if (flags[i] & TS_CELL_FIXED) {
                far_same &= TS_PIX(&z, x, y) == TS_PIX(&orig, x, y); /* water untouched */
                continue;
            }
            for (v = -R; v <= R; v++)
                for (u = -R; u <= R; u++) {
                    int px = x + u, py = y + v;
                    if (px < 0 || py < 0 || px >= 60 || py >= 50 ||
                        !(flags[py * 60 + px] & TS_CELL_WATER))
                        continue;
                    touch |= abs(u) <= 1 && abs(v) <= 1;
                    near |= u * u + v * v < R * R;
                }
            below_before += touch && TS_PIX(&orig, x, y) < level;
            ok_shore &= !touch || TS_PIX(&z, x, y) >= level;
            lowered += TS_PIX(&z, x, y) < TS_PIX(&orig, x, y);
            if (!near)
                far_same &= TS_PIX(&z, x, y) == TS_PIX(&orig, x, y);
        }
    printf("     water's banks: %d shore cells below the level before, none after\n", below_before);
    CHECK(below_before > 0); /* the test can fail */
    CHECK(ok_shore);
    CHECK(lowered == 0);
    CHECK(far_same);
    ts_raster_free(&orig);
    ts_raster_free(&z);
    ts_ctx_free(ctx);
}

static ts_synth_params params(void)
{
    ts_synth_params p = ts_synth_params_default();
    p.patch_size.value = 32;
    p.overlap.value = 8;
    p.candidates = 4;
    p.coarse_factor = 2;
    p.tiled = 64;
    return p;
}

/* The whole grid's pins (a window of the exemplar, 40 x 30 at (120, 20))
 * and water (a disc at level 1000 round (50, 120)). */
static void grid_fixed(const ts_raster *ex, unsigned char *flags, float *values)
{
    int x, y;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int i = y * W + x;
            flags[i] = 0;
            values[i] = NAN;
            if (x >= 120 && x < 160 && y >= 20 && y < 50) {
                flags[i] = TS_CELL_FIXED;
                values[i] = TS_PIX(ex, x + 30, y + 100);
            } else if ((x - 50) * (x - 50) + (y - 120) * (y - 120) < 400) {
                flags[i] = TS_CELL_FIXED | TS_CELL_WATER;
                values[i] = 1000.0f;
            }
        }
}

/* The mean |step| between 4-neighbours one inside the pin, one not, over the
 * mean of those 3 to 20 cells outside it (Chebyshev). */
static double border_step_ratio(const ts_raster *z)
{
    double across = 0, near = 0;
    int na = 0, nn = 0, x, y;
    for (y = 0; y + 1 < H; y++)
        for (x = 0; x + 1 < W; x++) {
            int in = x >= 120 && x < 160 && y >= 20 && y < 50;
            int inr = x + 1 >= 120 && x + 1 < 160 && y >= 20 && y < 50;
            int ind = x >= 120 && x < 160 && y + 1 >= 20 && y + 1 < 50;
            int dx = x < 120 ? 120 - x : x >= 160 ? x - 159 : 0;
            int dy = y < 20 ? 20 - y : y >= 50 ? y - 49 : 0;
            int d = dx > dy ? dx : dy;
            double sx = fabs(TS_PIX(z, x + 1, y) - TS_PIX(z, x, y));
            double sy = fabs(TS_PIX(z, x, y + 1) - TS_PIX(z, x, y));
            if (in != inr) {
                across += sx;
                na++;
            }
            if (in != ind) {
                across += sy;
                na++;
            }
            if (d >= 3 && d <= 20 && x + 1 < 120 - 2) {
                near += sx + sy;
                nn += 2;
            }
        }
    return (across / na) / (near / nn);
}

static void test_pins_and_water_in_tiles(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = exemplar(ctx, 256, 224, 3), sk, out;
    ts_synth_params p = params();
    ts_sketch_params sp = ts_sketch_params_default();
    ts_synth_constraints c = ts_synth_constraints_default();
    ts_sketch_tiles *t = NULL;
    unsigned char *flags = malloc(W * H);
    float *values = malloc(W * H * sizeof(float));
    static const int win[3][4] = {{100, 0, 64, 64}, {20, 90, 70, 60}, {130, 40, 60, 131}};
    int x, y, k, m, exact = 1, shore = 1, same;
    double ratio;
    sp.mode = TS_SKETCH_RIDGES;
    ts_raster_alloc(ctx, W, H, &sk);
    ts_raster_alloc(ctx, W, H, &out);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&sk, x, y) = abs(x - y) < 4 ? 255.0f : 0.0f;
    grid_fixed(&ex, flags, values);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&out, x, y) = values[y * W + x];
    c.cell_flags = flags;
    ts_ctx_set_seed(ctx, 7);
    CHECK_MSG(ts_synth_sketch(ctx, &sk, &ex, 1, &sp, &p, &c, &out, NULL, NULL, NULL) == TS_OK, "%s",
              ts_ctx_message(ctx));
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int i = y * W + x, u, v, touch = 0;
            if (flags[i] & TS_CELL_FIXED) {
                exact &= TS_PIX(&out, x, y) == values[i];
                continue;
            }
            for (v = -1; v <= 1; v++)
                for (u = -1; u <= 1; u++)
                    touch |= x + u >= 0 && x + u < W && y + v >= 0 && y + v < H &&
                             (flags[(y + v) * W + x + u] & TS_CELL_WATER);
            shore &= !touch || TS_PIX(&out, x, y) >= 1000.0f;
        }
    CHECK(exact);
    CHECK(shore);
    ratio = border_step_ratio(&out);
    printf("     mean step across the pin's border / beside it: %.2f\n", ratio);
    CHECK_MSG(ratio < 2.0, "%.2f", ratio);
    /* windows grown by the margin, in any order, give the whole's cells */
    c.values = values;
    CHECK(ts_sketch_tiles_new(ctx, &sk, NULL, &ex, 1, &sp, &p, &c, W, H, &t, NULL, NULL) == TS_OK);
    m = ts_sketch_tiles_margin(t);
    CHECK(m == 8 * ts_sketch_tiles_factor(t) + 1);
    for (k = 0; k < 3; k++) {
        int x0 = win[k][0] > m ? win[k][0] - m : 0, y0 = win[k][1] > m ? win[k][1] - m : 0;
        int x1 = win[k][0] + win[k][2] + m < W ? win[k][0] + win[k][2] + m : W;
        int y1 = win[k][1] + win[k][3] + m < H ? win[k][1] + win[k][3] + m : H;
        ts_raster g;
        unsigned char *gf = calloc((size_t)(x1 - x0) * (y1 - y0), 1);
        ts_raster_alloc(ctx, x1 - x0, y1 - y0, &g);
        for (y = y0; y < y1; y++)
            for (x = x0; x < x1; x++) {
                gf[(y - y0) * (x1 - x0) + x - x0] = flags[y * W + x];
                TS_PIX(&g, x - x0, y - y0) = values[y * W + x];
            }
        CHECK(ts_sketch_tiles_window(ctx, t, x0, y0, &g, gf) == TS_OK);
        same = 1;
        for (y = win[k][1]; y < win[k][1] + win[k][3]; y++)
            for (x = win[k][0]; x < win[k][0] + win[k][2]; x++)
                same &=
                    memcmp(&TS_PIX(&g, x - x0, y - y0), &TS_PIX(&out, x, y), sizeof(float)) == 0;
        CHECK_MSG(same, "window %d differs from the whole", k);
        ts_raster_free(&g);
        free(gf);
    }
    ts_sketch_tiles_free(t);
    /* fixed cells need their values */
    c.values = NULL;
    CHECK(ts_sketch_tiles_new(ctx, &sk, NULL, &ex, 1, &sp, &p, &c, W, H, &t, NULL, NULL) ==
          TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "values") != NULL);
    free(flags);
    free(values);
    ts_raster_free(&out);
    ts_raster_free(&sk);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"pin_blend_against_direct_sums", test_pin_blend_against_direct_sums},
        {"water_banks", test_water_banks},
        {"pins_and_water_in_tiles", test_pins_and_water_in_tiles},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
