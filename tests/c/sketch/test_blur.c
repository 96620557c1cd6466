/*
 * test_blur.c - the NaN-aware blur the sketch stages share
 * (algorithms/src/sketch/blur.c): the three-box blur against a direct
 * NaN-aware convolution with the same kernel (and its spread against the
 * Gaussian it stands for), and the wide blur through a coarser grid against
 * a direct NaN-aware Gaussian convolution, on land with a cliff, on values
 * known only along lines and on land known unevenly, mirrored input giving
 * the mirrored output, the same bytes on any thread count.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "layout.h"
#include "terrasynth.h"

/* ---- blur == direct convolution with the three-box kernel ---- */

/* The 1-D kernel of three boxes of radius r (length 6r + 1). */
static void three_box_kernel(int r, double *k)
{
    int n = 2 * r + 1, i, j, len = 6 * r + 1;
    double a[1024], b[1024];
    for (i = 0; i < len; i++)
        a[i] = b[i] = 0.0;
    for (i = 0; i < n; i++)
        a[i] = 1.0;
    for (i = 0; i < len; i++) /* box * box */
        for (j = 0; j < n && j <= i; j++)
            b[i] += a[i - j];
    for (i = 0; i < len; i++) {
        k[i] = 0.0;
        for (j = 0; j < n && j <= i; j++)
            k[i] += b[i - j];
    }
}

static void test_blur_direct(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t s = 3;
    int rep;
    for (rep = 0; rep < 12; rep++) {
        int w = 40 + (int)(th_uniform(&s) * 40), h = 40 + (int)(th_uniform(&s) * 30), x, y, u, v;
        double sigma = 1.0 + th_uniform(&s) * 5.0, k[1024], var = 0.0, sum = 0.0;
        int r = ts__blur_radius(sigma), half = 3 * r;
        float *in = malloc((size_t)w * h * sizeof(float)),
              *out = malloc((size_t)w * h * sizeof(float));
        for (x = 0; x < w * h; x++)
            in[x] = th_uniform(&s) < (rep % 3 == 2 ? 0.0 : 0.15) /* no NaN: the weights' shortcut */
                        ? NAN
                        : (float)(100.0 * th_uniform(&s));
        ts_ctx_set_threads(ctx, 1 + rep % 2);
        CHECK(ts__blur_nan(ctx, in, w, w, h, sigma, out) == TS_OK);
        three_box_kernel(r, k);
        for (x = -half; x <= half; x++) {
            sum += k[x + half];
            var += k[x + half] * x * x;
        }
        /* three boxes stand for a Gaussian of sigma (rounded to whole boxes) */
        CHECK_NEAR(sqrt(var / sum), sigma, 0.6);
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                double num = 0.0, den = 0.0, want;
                for (v = -half; v <= half; v++)
                    for (u = -half; u <= half; u++) {
                        int xx = x + u, yy = y + v;
                        double wt;
                        if (xx < 0 || yy < 0 || xx >= w || yy >= h || isnan(in[yy * w + xx]))
                            continue;
                        wt = k[u + half] * k[v + half];
                        num += wt * in[yy * w + xx];
                        den += wt;
                    }
                want = den > 0 ? num / den : NAN;
                if (x < half || y < half || x >= w - half || y >= h - half) {
                    /* near the edges the passes are clipped one by one: a
                     * weighted mean of the valid input all the same */
                    CHECK(!(out[y * w + x] < -1e-3) && !(out[y * w + x] > 100.001));
                    continue;
                }
                if (isnan(want))
                    CHECK(isnan(out[y * w + x]));
                else
                    CHECK_NEAR(out[y * w + x], want, 1e-3);
            }
        free(in);
        free(out);
    }
    ts_ctx_free(ctx);
}

/* ---- the blur through a coarser grid == a direct Gaussian ---- */

/* Land with a cliff, slopes and bumps from 0 to about 100 (kind 0), the
 * same known only along three lines, NaN elsewhere (kind 1: the layout's
 * blurs of the output along the sketch's features), or known on every cell
 * above the cliff and on one in twelve below it (kind 2: a block's cells
 * weigh as many cells, not as one). */
static void coarse_field(float *in, int w, int h, int kind, uint64_t *s)
{
    double a = th_uniform(s) * 6.3, b = th_uniform(s) * 6.3;
    int x, y, k;
    unsigned char *on;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            in[y * w + x] = (float)((x > w / 3 + y / 4 ? 50.0 : 0.0) + 20.0 * sin(a + x / 37.0) +
                                    15.0 * cos(b + y / 23.0) + 10.0 * th_uniform(s) + 15.0);
    if (kind == 0)
        return;
    if (kind == 2) {
        for (x = 0; x < w * h; x++)
            if (in[x] < 50.0f && th_uniform(s) > 1.0 / 12.0)
                in[x] = NAN;
        return;
    }
    on = calloc((size_t)w * h, 1);
    for (k = 0; k < 3; k++) { /* a line from one random point to another */
        double x0 = th_uniform(s) * w, y0 = th_uniform(s) * h;
        double x1 = th_uniform(s) * w, y1 = th_uniform(s) * h, t;
        for (t = 0.0; t <= 1.0; t += 0.25 / (w + h))
            on[(int)(y0 + t * (y1 - y0)) * w + (int)(x0 + t * (x1 - x0))] = 1;
    }
    for (x = 0; x < w * h; x++)
        if (!on[x])
            in[x] = NAN;
    free(on);
}

/* The NaN-aware Gaussian-weighted mean at (x, y) out to 3 sigma; NAN where
 * the known cells within sigma carry less than 0.35 of the weight (0.39 with
 * every cell known; farther
 * out the Gaussian's tail and the boxes' differ). */
static double gauss_at(const float *in, int w, int x, int y, double sigma)
{
    double num = 0.0, den = 0.0, near = 0.0;
    int half = (int)ceil(3.0 * sigma), u, v;
    for (v = -half; v <= half; v++)
        for (u = -half; u <= half; u++) {
            float z = in[(y + v) * w + x + u];
            double wt;
            if (isnan(z))
                continue;
            wt = exp(-(u * u + v * v) / (2.0 * sigma * sigma));
            num += wt * z;
            den += wt;
            if (u * u + v * v <= sigma * sigma)
                near += wt;
        }
    return near > 0.35 * den && den > 0 ? num / den : NAN;
}

static void test_blur_coarse(void)
{
    ts_ctx *ctx = ts_ctx_new();
    uint64_t s = 11;
    int rep;
    CHECK(ts__blur_coarse_factor(15.9, 1000, 1000) == 1);
    CHECK(ts__blur_coarse_factor(16.0, 1000, 1000) == 2);
    CHECK(ts__blur_coarse_factor(64.0, 1000, 1000) == 8);
    CHECK(ts__blur_coarse_factor(64.0, 60, 1000) == 4); /* 8 x 8 coarse cells at least */
    for (rep = 0; rep < 9; rep++) {
        int w = 8 * (38 + (int)(th_uniform(&s) * 10)), h = 8 * (35 + (int)(th_uniform(&s) * 8));
        int kind = rep % 3, x, y, checked = 0, half;
        double sigma = rep < 6 ? 16.0 + th_uniform(&s) * 15.0 : 33.0 + th_uniform(&s) * 10.0;
        double worst = 0.0, worst_exact = 0.0;
        size_t n = (size_t)w * h;
        float *in = malloc(n * sizeof(float)), *out = malloc(n * sizeof(float));
        float *out2 = malloc(n * sizeof(float)), *exact = malloc(n * sizeof(float));
        coarse_field(in, w, h, kind, &s);
        ts_ctx_set_threads(ctx, 1);
        CHECK(ts__blur_nan_coarse(ctx, in, w, w, h, sigma, out) == TS_OK);
        ts_ctx_set_threads(ctx, 3);
        CHECK(ts__blur_nan_coarse(ctx, in, w, w, h, sigma, out2) == TS_OK);
        CHECK(memcmp(out, out2, n * sizeof(float)) == 0);
        /* the input mirrored left to right blurs to the output mirrored
         * (w a multiple of every factor: the blocks mirror too) */
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++)
                exact[y * w + x] = in[y * w + (w - 1 - x)];
        CHECK(ts__blur_nan_coarse(ctx, exact, w, w, h, sigma, out2) == TS_OK);
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                float a = out[y * w + x], b = out2[y * w + (w - 1 - x)];
                CHECK((isnan(a) && isnan(b)) || fabsf(a - b) < 1e-3f);
            }
        CHECK(ts__blur_nan(ctx, in, w, w, h, sigma, exact) == TS_OK);
        half = (int)ceil(3.0 * sigma);
        /* every 7th cell in both directions, away from the edges */
        for (y = half; y < h - half; y += 7)
            for (x = half; x < w - half; x += 7) {
                double want = gauss_at(in, w, x, y, sigma);
                if (isnan(want))
                    continue;
                CHECK(!isnan(out[y * w + x]));
                worst = fmax(worst, fabs(out[y * w + x] - want));
                worst_exact = fmax(worst_exact, fabs(exact[y * w + x] - want));
                checked++;
            }
        /* about as close to the Gaussian as the full three-box blur: within
         * 4 m over land 0..100 m (a block's cells weighed as one: 8-20 m) */
        CHECK(checked > 10);
        printf("  sigma %.1f kind %d: %d cells, coarse %.3f, full %.3f off the Gaussian\n", sigma,
               kind, checked, worst, worst_exact);
        CHECK(worst < 4.0 && worst < 2.0 * worst_exact + 1.0);
        free(in);
        free(out);
        free(out2);
        free(exact);
    }
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"blur_direct", test_blur_direct},
        {"blur_coarse", test_blur_coarse},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
