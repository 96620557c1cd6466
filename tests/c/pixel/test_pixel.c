/*
 * test_pixel.c - multiresolution pixel synthesis (algorithms/src/pixel/):
 * the stack's blur against a 2D convolution written out, the neighbourhood
 * distance against a plain sum, and the property the method is built for:
 * any window, anywhere (negative and huge coordinates too), alone equals
 * the same window of a larger run, whatever the threads; the heights within the
 * exemplar's range; seeds differ.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "pixel.h"
#include "terrasynth.h"

static ts_raster make_terrain(ts_ctx *ctx, int w, int h, uint64_t seed)
{
    ts_raster r;
    double fx[16], fy[16], ph[16], amp[16];
    int k, x, y;
    uint64_t rng = seed;
    ts_raster_alloc(ctx, w, h, &r);
    for (k = 0; k < 16; k++) {
        double f = 0.03 * pow(1.3, k), a = 6.2831853 * th_uniform(&rng);
        fx[k] = f * cos(a);
        fy[k] = f * sin(a);
        ph[k] = 6.2831853 * th_uniform(&rng);
        amp[k] = 40.0 / pow(1.3, k);
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double z = 800;
            for (k = 0; k < 16; k++)
                z += amp[k] * sin(fx[k] * x + fy[k] * y + ph[k]);
            TS_PIX(&r, x, y) = (float)z;
        }
    return r;
}

static int dbl_cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The longest run of cells along one row or column whose second difference across
 * that line is among the 1 % largest: a straight step in the terrain. */
static int longest_straight_crease(const ts_raster *r)
{
    int w = r->width, h = r->height, x, y, pass, best = 0;
    for (pass = 0; pass < 2; pass++) {
        int n1 = pass ? w : h, n2 = pass ? h : w, i, j, k = 0;
        size_t n = (size_t)(n1 - 2) * (size_t)n2;
        double *d = malloc(n * sizeof *d), *sorted = malloc(n * sizeof *sorted), thr;
        for (i = 1; i + 1 < n1; i++)
            for (j = 0; j < n2; j++) {
#define AT(a, b) (pass ? TS_PIX(r, (a), (b)) : TS_PIX(r, (b), (a)))
                d[k++] = fabs(AT(i + 1, j) - 2.0 * AT(i, j) + AT(i - 1, j));
#undef AT
            }
        memcpy(sorted, d, n * sizeof *d);
        qsort(sorted, n, sizeof *sorted, dbl_cmp);
        thr = sorted[(size_t)(0.99 * (double)(n - 1))];
        for (i = 0; i < n1 - 2; i++) {
            int run = 0;
            for (j = 0; j < n2; j++) {
                run = d[(size_t)i * n2 + j] > thr ? run + 1 : 0;
                best = run > best ? run : best;
            }
        }
        free(d);
        free(sorted);
        (void)x;
        (void)y;
    }
    return best;
}

/* An exemplar with a frame of nodata (a DEM clipped to its area): the output's bands
 * are read past usable coordinates, into the frame; dropping those reads made
 * straight steps along the frame's edges (seen in hillshades: runs of 44-78 cells on
 * St Helens 30 m, against 11 on a DEM without them).  Nodata is filled from the
 * nearest valid cell once the stacks are made; the frame's cells are never matched. */
static void test_nodata_frame(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 160, 140, 11), out;
    ts_pixel_exemplars *E = NULL;
    int x, y, seed, worst = 0;
    for (y = 0; y < ex.height; y++)
        for (x = 0; x < ex.width; x++)
            if (x < 9 + y % 3 || y < 7 || x >= ex.width - 8 || y >= ex.height - 10 + x % 2)
                TS_PIX(&ex, x, y) = NAN;
    p.levels = 4;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    ts_raster_alloc(ctx, 256, 256, &out);
    for (seed = 1; seed <= 3 && E; seed++) {
        int run;
        ts_ctx_set_seed(ctx, (uint64_t)seed);
        CHECK(ts_pixel_synthesize(ctx, E, &p, 0, 0, &out) == TS_OK);
        run = longest_straight_crease(&out);
        worst = run > worst ? run : worst;
    }
    /* measured: 5-6 cells; 5, 30 and 22 when the reads that fell on nodata were dropped */
    CHECK_MSG(worst <= 12, "a straight crease %d cells long", worst);
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

static void test_blur_against_convolution(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster r = make_terrain(ctx, 37, 29, 3);
    float *out = malloc(37 * 29 * sizeof *out);
    double sigma = 2.0;
    int x, y, bad = 0;
    TS_PIX(&r, 10, 10) = NAN;
    TS_PIX(&r, 11, 10) = NAN;
    CHECK(ts__pix_blur(r.data, 37, 29, sigma, out) == 0);
    for (y = 0; y < 29; y++)
        for (x = 0; x < 37; x++) {
            double s = 0, sw = 0;
            int i, j, rad = (int)ceil(3 * sigma);
            if (isnan(TS_PIX(&r, x, y))) {
                bad += !isnan(out[y * 37 + x]);
                continue;
            }
            for (j = -rad; j <= rad; j++)
                for (i = -rad; i <= rad; i++) {
                    int xx = x + i, yy = y + j;
                    double wgt;
                    if (xx < 0 || yy < 0 || xx >= 37 || yy >= 29 || isnan(TS_PIX(&r, xx, yy)))
                        continue;
                    wgt = exp(-0.5 * (i * i + j * j) / (sigma * sigma));
                    s += wgt * TS_PIX(&r, xx, yy);
                    sw += wgt;
                }
            bad += fabs(out[y * 37 + x] - s / sw) > 1e-3;
        }
    CHECK_MSG(bad == 0, "%d cells differ", bad);
    free(out);
    ts_raster_free(&r);
    ts_ctx_free(ctx);
}

static void test_ssd_plain(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster r = make_terrain(ctx, 60, 50, 4);
    float t[25];
    uint64_t rng = 1;
    int i, a, b;
    for (i = 0; i < 25; i++)
        t[i] = (float)(800 + 50 * th_uniform(&rng));
    for (int h = 1; h <= 4; h *= 2) {
        double want = 0;
        for (b = -2; b <= 2; b++)
            for (a = -2; a <= 2; a++) {
                double d = t[(b + 2) * 5 + a + 2] - TS_PIX(&r, 30 + a * h, 25 + b * h);
                want += d * d;
            }
        CHECK_NEAR(ts__pix_ssd(r.data, 60, 30, 25, 5, h, t), want, 1e-6 * want);
    }
    ts_raster_free(&r);
    ts_ctx_free(ctx);
}

/* Windows alone equal the windows of a larger run. */
static void windows_anywhere(int coherence, int rotations)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 96, 80, 5), big, win;
    ts_pixel_exemplars *E = NULL;
    static const int64_t origins[][2] = {{0, 0},
                                         {-70, -33},
                                         {((int64_t)1 << 39) - 17, 12345},
                                         {-((int64_t)1 << 39), ((int64_t)1 << 38) + 5}};
    size_t o;
    TS_PIX(&ex, 40, 40) = NAN; /* nodata: never matched */
    p.levels = 3;
    p.coherence = coherence;
    p.rotations = rotations;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    CHECK(ts_pixel_levels(E) == 3);
    ts_ctx_set_seed(ctx, 42);
    ts_raster_alloc(ctx, 90, 70, &big);
    for (o = 0; o < sizeof origins / sizeof origins[0]; o++) {
        int64_t bx = origins[o][0], by = origins[o][1];
        int k, x, y;
        uint64_t rng = 7 + o;
        ts_ctx_set_threads(ctx, 3);
        CHECK(ts_pixel_synthesize(ctx, E, &p, bx, by, &big) == TS_OK);
        for (k = 0; k < 4; k++) {
            int w = 1 + (int)(th_uniform(&rng) * 40), h = 1 + (int)(th_uniform(&rng) * 40);
            int wx = (int)(th_uniform(&rng) * (90 - w)), wy = (int)(th_uniform(&rng) * (70 - h));
            int same = 1;
            ts_raster_alloc(ctx, w, h, &win);
            ts_ctx_set_threads(ctx, 1 + k % 2);
            CHECK(ts_pixel_synthesize(ctx, E, &p, bx + wx, by + wy, &win) == TS_OK);
            for (y = 0; y < h; y++)
                for (x = 0; x < w; x++)
                    same &= memcmp(&TS_PIX(&win, x, y), &TS_PIX(&big, wx + x, wy + y), 4) == 0;
            CHECK_MSG(same, "origin %lld,%lld window %d,%d %dx%d differs", (long long)bx,
                      (long long)by, wx, wy, w, h);
            ts_raster_free(&win);
        }
        /* the heights are sums of the exemplar's bands: within its range and a tenth of
         * its relief, never nodata */
        {
            float lo = 1e30f, hi = -1e30f;
            int bad = 0;
            for (y = 0; y < 80; y++)
                for (x = 0; x < 96; x++)
                    if (!isnan(TS_PIX(&ex, x, y))) {
                        lo = fminf(lo, TS_PIX(&ex, x, y));
                        hi = fmaxf(hi, TS_PIX(&ex, x, y));
                    }
            for (y = 0; y < 70; y++)
                for (x = 0; x < 90; x++) {
                    float v = TS_PIX(&big, x, y);
                    bad += isnan(v) || v < lo - 0.1f * (hi - lo) || v > hi + 0.1f * (hi - lo);
                }
            CHECK_MSG(bad == 0, "%d heights out of the exemplar's range", bad);
        }
    }
    /* another seed, another terrain */
    {
        ts_raster other;
        ts_raster_alloc(ctx, 90, 70, &other);
        CHECK(ts_pixel_synthesize(ctx, E, &p, 0, 0, &big) == TS_OK);
        ts_ctx_set_seed(ctx, 43);
        CHECK(ts_pixel_synthesize(ctx, E, &p, 0, 0, &other) == TS_OK);
        CHECK(memcmp(big.data, other.data, sizeof(float) * 90 * 70) != 0);
        ts_raster_free(&other);
    }
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex);
    ts_raster_free(&big);
    ts_ctx_free(ctx);
}

static void test_windows_anywhere(void)
{
    windows_anywhere(1, 4);
    windows_anywhere(3, 8); /* similarity sets, mirrored candidates */
}

/* Appearance vectors: with every direction kept their distance is the SSD
 * written out; with 95 % it is at most the SSD and at least the means' part.
 * With the roughness term (lambda > 0) each ends with sqrt(lambda) x the
 * root sum of squares of its heights about their mean (written out here),
 * and the distance gains lambda x the two roughnesses' difference squared. */
static void test_appearance_space(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_terrain(ctx, 70, 64, 9);
    int run;
    for (run = 0; run < 4; run++) {
        int energy = run & 1;
        double lambda = run & 2 ? 8.0 : 0.0;
        ts_pixel_params p = ts_pixel_params_default();
        ts_pixel_exemplars *E = NULL;
        uint64_t rng = 11;
        int n, l, bad = 0;
        p.levels = 2;
        p.rotations = 0;
        p.pca_energy = energy ? 1.0 : 0.95;
        p.roughness_weight = lambda;
        CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
        for (l = 0; l <= 2; l++) {
            const pix_stack *s = &E->stacks[0];
            int rd = lambda > 0, dim = E->dim[l], sp = 1 << (2 - l), k = E->window;
            CHECK(dim >= 1 + rd && dim <= 1 + k * k + rd);
            if (energy)
                CHECK(dim == 1 + k * k + rd);
            for (n = 0; n < 200; n++) {
                int32_t i = s->usable_list[l][(size_t)(th_uniform(&rng) * s->n_usable[l])];
                int32_t j = s->usable_list[l][(size_t)(th_uniform(&rng) * s->n_usable[l])];
                const float *a = s->app[l] + (size_t)i * dim, *b = s->app[l] + (size_t)j * dim;
                float t[81], ti[81];
                double ssd, app = 0, mu = 0, mt = 0, mi = 0, rt = 0, ri = 0;
                int c, x, y, u = i % s->width, v = i / s->width;
                for (y = -k / 2; y <= k / 2; y++)
                    for (x = -k / 2; x <= k / 2; x++) {
                        int q = (y + k / 2) * k + x + k / 2;
                        t[q] = s->level[l][(size_t)(j / s->width + y * sp) * s->width +
                                           (size_t)(j % s->width + x * sp)];
                        ti[q] = s->level[l][(size_t)(v + y * sp) * s->width + (size_t)(u + x * sp)];
                        mu += ti[q] - t[q];
                        mt += t[q];
                        mi += ti[q];
                    }
                mt /= k * k;
                mi /= k * k;
                for (c = 0; c < k * k; c++) {
                    rt += (t[c] - mt) * (t[c] - mt);
                    ri += (ti[c] - mi) * (ti[c] - mi);
                }
                rt = sqrt(rt);
                ri = sqrt(ri);
                ssd = ts__pix_ssd(s->level[l], s->width, u, v, k, sp, t) +
                      lambda * (rt - ri) * (rt - ri);
                /* a target's vector (ts__pix_appearance) = the stored one of the same heights */
                {
                    float tv[83];
                    ts__pix_appearance(E->basis[l], dim - 1 - rd, k, t, tv);
                    for (c = 0; c < dim - rd; c++)
                        bad += fabsf(tv[c] - b[c]) > 1e-3f * (1 + fabsf(b[c]));
                    if (rd) /* the stored roughness, and ts__pix_roughness's */
                        bad += fabs(b[dim - 1] - sqrt(lambda) * rt) > 1e-3 * (1 + rt) ||
                               fabs(ts__pix_roughness(k, t) - rt) > 1e-3 * (1 + rt);
                }
                for (c = 0; c < dim; c++)
                    app += ((double)a[c] - b[c]) * ((double)a[c] - b[c]);
                mu /= k * k;
                if (energy)
                    bad += fabs(app - ssd) > 1e-3 * ssd + 1e-2;
                else
                    bad +=
                        app > ssd * (1 + 1e-3) + 1e-2 || app < k * k * mu * mu * (1 - 1e-3) - 1e-2;
            }
        }
        CHECK_MSG(bad == 0, "%d appearance distances off (energy %s, roughness weight %g)", bad,
                  energy ? "1" : "0.95", lambda);
        ts_pixel_exemplars_free(E);
    }
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* Two views: the exemplar and its half turn (read as a plain loop turns it);
 * by default (rotations -1) ridges all one way get those two, which keep
 * their direction, and a cone (no preferred direction) the quarter turns;
 * the grain against a slow sum of angles. */
static void test_half_turn_and_auto(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_terrain(ctx, 41, 30, 12), ridges, cone;
    ts_pixel_params p = ts_pixel_params_default();
    ts_pixel_exemplars *E = NULL;
    double sc = 0.0, ss = 0.0, sw = 0.0;
    int x, y, bad = 0;
    p.levels = 2;
    p.rotations = 2;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    CHECK(ts_pixel_variants(E) == 2);
    for (y = 0; y < 30; y++)
        for (x = 0; x < 41; x++)
            bad += ts__pix_candidate_height(E, 2, 1, x, y) != TS_PIX(&ex, 40 - x, 29 - y);
    CHECK_MSG(bad == 0, "%d cells of the half turn off", bad);
    ts_pixel_exemplars_free(E);
    p.rotations = -1;
    CHECK(ts_raster_alloc(ctx, 120, 100, &ridges) == TS_OK);
    CHECK(ts_raster_alloc(ctx, 100, 100, &cone) == TS_OK);
    for (y = 0; y < 100; y++)
        for (x = 0; x < 120; x++) {
            TS_PIX(&ridges, x, y) = (float)(500 + 40 * sin(6.2831853 * (x + 0.5 * y) / 20.0));
            if (x < 100) /* every direction alike: a cone on a square */
                TS_PIX(&cone, x, y) = (float)(900 - hypot(x - 49.5, y - 49.5));
        }
    for (y = 1; y < 99; y++) /* the grain written out: sum of |g|^2 e^(2 i theta) */
        for (x = 1; x < 119; x++) {
            double gx = 0.5 * (TS_PIX(&ridges, x + 1, y) - TS_PIX(&ridges, x - 1, y));
            double gy = 0.5 * (TS_PIX(&ridges, x, y + 1) - TS_PIX(&ridges, x, y - 1));
            double g2 = gx * gx + gy * gy, th = atan2(gy, gx);
            sc += g2 * cos(2 * th);
            ss += g2 * sin(2 * th);
            sw += g2;
        }
    CHECK(ts_pixel_prepare(ctx, &ridges, 1, &p, &E) == TS_OK);
    CHECK_MSG(fabs(ts_pixel_grain(E) - hypot(sc, ss) / sw) < 1e-9 && ts_pixel_grain(E) > 0.9,
              "grain %g, written out %g", ts_pixel_grain(E), hypot(sc, ss) / sw);
    CHECK(ts_pixel_variants(E) == 2);
    ts_pixel_exemplars_free(E);
    CHECK(ts_pixel_prepare(ctx, &cone, 1, &p, &E) == TS_OK);
    CHECK_MSG(ts_pixel_grain(E) < TS_PIXEL_ISOTROPIC && ts_pixel_variants(E) == 4,
              "cone: grain %g, %d views", ts_pixel_grain(E), ts_pixel_variants(E));
    ts_pixel_exemplars_free(E);
    p.rotations = 3;
    CHECK(ts_pixel_prepare(ctx, &cone, 1, &p, &E) == TS_ERR_ARG);
    ts_raster_free(&ridges);
    ts_raster_free(&cone);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* A turned or mirrored candidate reads the exemplar's stack turned: the same
 * as the stack of the exemplar turned by a plain loop (blurred on its own). */
static void test_turned_candidates(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_terrain(ctx, 41, 30, 12);
    ts_pixel_params p = ts_pixel_params_default();
    ts_pixel_exemplars *E = NULL;
    int v, bad = 0, badu = 0;
    TS_PIX(&ex, 7, 20) = NAN;
    p.levels = 2;
    p.rotations = 8;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    for (v = 0; v < 8; v++) {
        int q = v % 4, ow = q % 2 ? 30 : 41, oh = q % 2 ? 41 : 30, x, y, l;
        float *turned = malloc((size_t)ow * oh * sizeof *turned);
        float *blur = malloc((size_t)ow * oh * sizeof *blur);
        for (y = 0; y < oh; y++)
            for (x = 0; x < ow; x++) {
                /* the turn by q quarter turns counter-clockwise, written out */
                int sx = q == 0 ? x : q == 1 ? 40 - y : q == 2 ? 40 - x : y;
                int sy = q == 0 ? y : q == 1 ? x : q == 2 ? 29 - y : 29 - x;
                if (v >= 4)
                    sx = 40 - sx;
                turned[(size_t)y * ow + x] = TS_PIX(&ex, sx, sy);
            }
        for (l = 0; l <= 2; l++) {
            CHECK(ts__pix_blur(turned, ow, oh, l == 2 ? 0.0 : 0.5 * (1 << (2 - l)), blur) == 0);
            for (y = 0; y < oh; y++)
                for (x = 0; x < ow; x++) {
                    float want = blur[(size_t)y * ow + x];
                    float got = ts__pix_candidate_height(E, l, v, x, y);
                    /* nodata cells hold the nearest valid cell's value (test_nodata_frame) */
                    if (isnan(got) || (!isnan(want) && fabsf(want - got) > 1e-3f))
                        bad++;
                }
        }
        /* the usable mask: every k x k neighbourhood valid, read from the plain turn */
        for (y = 0; y < oh; y++)
            for (x = 0; x < ow; x++) {
                int r = E->window / 2, sp = 1,
                    ok = x - r * sp >= 0 && y - r * sp >= 0 && x + r * sp < ow && y + r * sp < oh;
                int a, b;
                for (b = -r; ok && b <= r; b++)
                    for (a = -r; a <= r; a++)
                        ok &= !isnan(turned[(size_t)(y + b * sp) * ow + x + a * sp]);
                badu += ok != ts__pix_candidate_usable(E, 2, v, x, y);
            }
        free(turned);
        free(blur);
    }
    CHECK_MSG(bad == 0, "%d turned heights differ", bad);
    CHECK_MSG(badu == 0, "%d turned usable cells differ", badu);
    CHECK(isnan(ts__pix_candidate_height(E, 0, 1, 30, 0)) &&
          isnan(ts__pix_candidate_height(E, 0, 1, -1, 0)));
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

typedef struct keep_test {
    int parity;
} keep_test;

static int keep_parity(void *arg, int32_t i)
{
    return (i & 1) == ((keep_test *)arg)->parity;
}

/* The kd-tree's K nearest against a plain scan: random points with ties and
 * duplicates, in 1 to 13 dimensions, with and without a filter. */
static void test_kdtree_against_scan(void)
{
    uint64_t rng = 21;
    int round, bad = 0;
    for (round = 0; round < 60; round++) {
        int dim = 1 + round % 13, K = 1 + round % 8, n = round % 5 == 0 ? 7 : 300 + 97 * round;
        float *pts = malloc((size_t)n * dim * sizeof *pts), q[13];
        int32_t got[8], want[8];
        float gd[8], wd[8];
        pix_kdtree *t;
        int i, a, qn;
        keep_test kt = {round % 2};
        for (i = 0; i < n * dim; i++) /* coarse values: many ties */
            pts[i] = round % 3 ? (float)th_uniform(&rng) : (float)(int)(th_uniform(&rng) * 4);
        if (n > 20)
            memcpy(pts + 10 * dim, pts + 3 * dim, (size_t)dim * sizeof *pts); /* a duplicate */
        t = ts__pix_kdtree_build(pts, (size_t)n, dim);
        CHECK(t != NULL);
        for (qn = 0; qn < 40; qn++) {
            int use_filter = qn % 2, found, m = 0, j;
            for (a = 0; a < dim; a++)
                q[a] = qn < 5 ? pts[(size_t)qn * dim + a] : (float)(th_uniform(&rng) * 4 - 1);
            found = ts__pix_kdtree_knn(t, q, K, use_filter ? keep_parity : NULL, &kt, got, gd);
            /* the plain scan: every point, sorted by (distance, index) */
            for (i = 0; i < n; i++) {
                float d = 0;
                if (use_filter && !keep_parity(&kt, i))
                    continue;
                for (a = 0; a < dim; a++) {
                    float e = pts[(size_t)i * dim + a] - q[a];
                    d += e * e;
                }
                for (j = m < K ? m++ : K;
                     j > 0 && (wd[j - 1] > d || (wd[j - 1] == d && want[j - 1] > i)); j--)
                    if (j < K) {
                        wd[j] = wd[j - 1];
                        want[j] = want[j - 1];
                    }
                if (j < K) {
                    wd[j] = d;
                    want[j] = i;
                }
            }
            if (found != m)
                bad++;
            else
                for (j = 0; j < m; j++)
                    bad += got[j] != want[j] || gd[j] != wd[j];
        }
        ts__pix_kdtree_free(t);
        free(pts);
    }
    CHECK_MSG(bad == 0, "%d kd-tree answers differ from the scan", bad);
}

/* Similarity sets: each usable cell's K - 1 against a plain scan of every
 * usable cell of every exemplar (its own exemplar's cells within one level
 * spacing left out). */
static void test_similarity_sets(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex[2];
    ts_pixel_params p = ts_pixel_params_default();
    ts_pixel_exemplars *E = NULL;
    int l, bad = 0, checked = 0;
    ex[0] = make_terrain(ctx, 48, 40, 13);
    ex[1] = make_terrain(ctx, 36, 44, 14);
    p.levels = 2;
    p.rotations = 4;
    p.coherence = 3;
    CHECK(ts_pixel_prepare(ctx, ex, 2, &p, &E) == TS_OK);
    for (l = 0; l <= 2; l++) {
        int dim = E->dim[l], reach = 1 << (2 - l), e;
        for (e = 0; e < 2; e++) {
            const pix_stack *s = &E->stacks[e];
            size_t c;
            for (c = 0; c < s->n_usable[l]; c += 7) {
                int32_t cell = s->usable_list[l][c], want[2] = {-1, -1};
                float wd[2] = {INFINITY, INFINITY};
                const float *q = s->app[l] + (size_t)cell * dim;
                int e2, i;
                for (e2 = 0; e2 < 2; e2++) {
                    const pix_stack *s2 = &E->stacks[e2];
                    size_t c2;
                    for (c2 = 0; c2 < s2->n_usable[l]; c2++) {
                        int32_t cell2 = s2->usable_list[l][c2];
                        int32_t id = (int32_t)(e2 ? 48 * 40 : 0) + cell2;
                        float d = 0;
                        int a;
                        if (e2 == e && abs(cell2 % s->width - cell % s->width) < reach &&
                            abs(cell2 / s->width - cell / s->width) < reach)
                            continue;
                        for (a = 0; a < dim; a++) {
                            float x = s2->app[l][(size_t)cell2 * dim + a] - q[a];
                            d += x * x;
                        }
                        if (d < wd[1] || (d == wd[1] && id < want[1])) {
                            if (d < wd[0] || (d == wd[0] && id < want[0])) {
                                wd[1] = wd[0];
                                want[1] = want[0];
                                wd[0] = d;
                                want[0] = id;
                            } else {
                                wd[1] = d;
                                want[1] = id;
                            }
                        }
                    }
                }
                for (i = 0; i < 2; i++)
                    bad += s->sim[l][(size_t)cell * 2 + i] != want[i];
                checked++;
            }
        }
    }
    CHECK(checked > 100);
    CHECK_MSG(bad == 0, "%d similarity-set members differ from the scan", bad);
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex[0]);
    ts_raster_free(&ex[1]);
    ts_ctx_free(ctx);
}

typedef struct sim_watch {
    int reports, back, notices;
    double last;
    char notice[512];
    int cancel_at; /* stop at this "similarity sets" report (0: never) */
} sim_watch;

static int sim_progress(double done, const char *msg, void *user)
{
    sim_watch *w = user;
    if (!msg || strcmp(msg, "similarity sets") != 0)
        return 1;
    w->back += done < w->last;
    w->last = done;
    return ++w->reports != w->cancel_at;
}

static void sim_notice(const char *stage, const char *msg, void *user)
{
    sim_watch *w = user;
    w->notices++;
    snprintf(w->notice, sizeof w->notice, "%s: %s", stage, msg);
}

/* The similarity sets report progress as they go (one level after another,
 * never back), can be cancelled between steps, and say how long the rest
 * takes once it is projected past the limit (0 s here: always); the sets
 * are the same with or without watching. */
static void test_similarity_progress(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_raster ex = make_terrain(ctx, 64, 56, 21);
    ts_pixel_params p = ts_pixel_params_default();
    ts_pixel_exemplars *E = NULL, *F = NULL;
    sim_watch w = {0, 0, 0, 0.0, "", 0};
    int l, same = 1;
    p.levels = 2;
    p.coherence = 4;
    ts_ctx_set_progress(ctx, sim_progress, &w);
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    CHECK_MSG(w.reports >= 3 * 32, "%d similarity-set reports", w.reports);
    CHECK(w.back == 0);
    CHECK(w.notices == 0); /* a small exemplar: far under PIX_NOTICE_SECONDS */
    /* the same sets again, with a notice at any projected time */
    p.coherence = 1;
    ts_ctx_set_notice(ctx, sim_notice, &w);
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &F) == TS_OK);
    CHECK(ts__pix_similarity_build(ctx, F, 4, 0.0) == 0);
    CHECK_MSG(w.notices == 1, "%d notices", w.notices);
    CHECK_MSG(strstr(w.notice, "pixel: ") == w.notice && strstr(w.notice, "similarity sets") &&
                  strstr(w.notice, "minute") && strstr(w.notice, "--pca-energy"),
              "notice '%s'", w.notice);
    for (l = 0; l <= 2; l++) {
        const pix_stack *a = &E->stacks[0], *b = &F->stacks[0];
        size_t c;
        CHECK(a->n_usable[l] == b->n_usable[l] && a->n_usable[l] > 0);
        for (c = 0; c < a->n_usable[l]; c++) {
            size_t at = (size_t)a->usable_list[l][c] * 3;
            same &= !memcmp(a->sim[l] + at, b->sim[l] + at, 3 * sizeof *a->sim[l]);
        }
    }
    CHECK(same);
    ts_pixel_exemplars_free(F);
    F = NULL;
    /* cancelled at the fifth step: no exemplars, a cancelled status */
    w.reports = 0;
    w.cancel_at = 5;
    p.coherence = 4;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &F) == TS_ERR_CANCELLED && F == NULL);
    CHECK(w.reports == 5);
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* Overviews: a window of the 2^k overview alone equals the same window of
 * a larger one (negative origins too, any threads); and against the block
 * means of the full-resolution terrain (the oracle: the overview is the
 * terrain without the detail finer than 2^k cells), it follows them closely
 * (correlation, RMS within a fraction of their spread). */
static void test_overviews(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 128, 112, 31), full, ov, win;
    ts_pixel_exemplars *E = NULL;
    int k, x, y;
    p.levels = 4;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    ts_ctx_set_seed(ctx, 9);
    ts_raster_alloc(ctx, 256, 192, &full);
    CHECK(ts_pixel_synthesize(ctx, E, &p, -64, 32, &full) == TS_OK);
    CHECK(ts_pixel_synthesize_overview(ctx, E, NULL, &p, 0, 0, 0, &full) == TS_ERR_ARG);
    CHECK(ts_pixel_synthesize_overview(ctx, E, NULL, &p, 5, 0, 0, &full) == TS_ERR_ARG);
    for (k = 1; k <= 3; k++) {
        int b = 1 << k, W = 256 / b, H = 192 / b, same = 1;
        double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, n = (double)W * H, corr, rms, sd;
        ts_raster_alloc(ctx, W, H, &ov);
        ts_ctx_set_threads(ctx, 2);
        CHECK(ts_pixel_synthesize_overview(ctx, E, NULL, &p, k, -64 / b, 32 / b, &ov) == TS_OK);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                double m = 0, o = TS_PIX(&ov, x, y);
                int i, j;
                for (j = 0; j < b; j++)
                    for (i = 0; i < b; i++)
                        m += TS_PIX(&full, x * b + i, y * b + j);
                m /= (double)b * b;
                sa += o;
                sb += m;
                saa += o * o;
                sbb += m * m;
                sab += o * m;
            }
        sd = sqrt(sbb / n - (sb / n) * (sb / n));
        corr = (sab / n - sa / n * sb / n) / (sqrt(saa / n - (sa / n) * (sa / n)) * sd);
        rms = sqrt((saa - 2 * sab + sbb) / n);
        CHECK_MSG(corr > 0.95 && rms < 0.35 * sd, "2^%d: correlation %.3f, rms %.2f (sd %.2f)", k,
                  corr, rms, sd);
        /* a window of it alone */
        ts_raster_alloc(ctx, 7, 5, &win);
        ts_ctx_set_threads(ctx, 1);
        CHECK(ts_pixel_synthesize_overview(ctx, E, NULL, &p, k, -64 / b + 3, 32 / b + 2, &win) ==
              TS_OK);
        for (y = 0; y < 5; y++)
            for (x = 0; x < 7; x++)
                same &= memcmp(&TS_PIX(&win, x, y), &TS_PIX(&ov, 3 + x, 2 + y), 4) == 0;
        CHECK_MSG(same, "2^%d: a window differs from the same cells of a larger overview", k);
        ts_raster_free(&win);
        ts_raster_free(&ov);
    }
    ts_pixel_exemplars_free(E);
    ts_raster_free(&full);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

static void test_errors(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 20, 20, 6);
    ts_pixel_exemplars *E = NULL;
    p.levels = 5; /* a 5 x 5 neighbourhood at spacing 32 does not fit in 20 cells */
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_ERR_SIZE && !E);
    CHECK(strstr(ts_ctx_message(ctx), "no valid 5 x 5 neighbourhood") != NULL);
    p = ts_pixel_params_default();
    p.window = 4;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_ERR_ARG && !E);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* --guide-heights quantile: each guide value goes to the exemplars' height of
 * its rank, so the mapped guide has the exemplars' distribution (its 1st and
 * 99th percentiles are theirs, by ts_pixel_guide_ranges on the mapped
 * values), the mapping keeps the order, and equal values (a drawing's
 * ground) map to one height: for a ground of 3/4 of the cells, the
 * exemplars' height at rank 3/8. */
static void test_guide_quantile(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 120, 110, 9), guide, mapped;
    ts_pixel_exemplars *E = NULL;
    ts_pixel_guide *g = NULL;
    uint64_t s = 31;
    int x, y, trial;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    ts_raster_alloc(ctx, 90, 70, &guide);
    for (trial = 0; trial < 2 && E; trial++) {
        double er[2], gr[2];
        size_t i, n = 90 * 70, bad = 0;
        for (y = 0; y < 70; y++)
            for (x = 0; x < 90; x++)
                TS_PIX(&guide, x, y) = trial == 0 ? (float)(-log(1.0 - th_uniform(&s)) * 40.0)
                                       : (float)((x + y) % 4 == 0 ? 230 : 30); /* a drawing */
        p.guide_heights = TS_GUIDE_QUANTILE;
        CHECK(ts_pixel_guide_prepare(ctx, &guide, E, &p, &g) == TS_OK);
        if (!g)
            break;
        mapped = ts_raster_wrap(g->level[g->levels], 90, 70, 90);
        CHECK(ts_pixel_guide_ranges(&mapped, E, er, gr) == 0);
        for (i = 0; i < n; i++)
            for (x = 0; x < 8; x++) { /* the order kept (a few pairs per cell) */
                size_t j = (size_t)(th_uniform(&s) * (double)n) % n;
                if ((guide.data[i] < guide.data[j] && mapped.data[i] > mapped.data[j]) ||
                    (guide.data[i] == guide.data[j] && mapped.data[i] != mapped.data[j]))
                    bad++;
            }
        CHECK_MSG(bad == 0, "trial %d: %zu pairs out of order", trial, bad);
        if (trial == 0) {
            double tol = 0.02 * (er[1] - er[0]);
            CHECK_MSG(fabs(gr[0] - er[0]) <= tol && fabs(gr[1] - er[1]) <= tol,
                      "mapped 1st..99th %g..%g, the exemplars' %g..%g", gr[0], gr[1], er[0],
                      er[1]);
        } else {
            /* the ground (3/4) at rank 3/8, the lines (1/4) at rank 7/8: strictly between
             * the exemplars' 1st and 99th percentiles, the lines above */
            float ground = mapped.data[1], line = mapped.data[0];
            CHECK(guide.data[1] == 30 && guide.data[0] == 230);
            CHECK_MSG(ground > er[0] && line < er[1] && line > ground, "%g %g (%g..%g)", ground,
                      line, er[0], er[1]);
        }
        ts_pixel_guide_free(g);
        g = NULL;
    }
    ts_raster_free(&guide);
    ts_raster_free(&ex);
    ts_pixel_exemplars_free(E);
    ts_ctx_free(ctx);
}

/* The relief start (relief_start.c): the field's ranks are uniform, every
 * 8S x 8S window holds the low and the high ranks (the strata), its lattice
 * spacing gives the exemplar's mean height difference at the coarsest
 * spacing (both written out here with a plain loop and a plain sort), and
 * plains among massifs keep both in the output, where the random start
 * leaves more middle heights. */
static void test_relief_start(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 160, 150, 21), out;
    ts_pixel_exemplars *E = NULL;
    int x, y, i, L, D, bins[10] = {0}, n = 0;
    double S;
    p.levels = 3;
    CHECK(p.start == TS_PIXEL_START_RELIEF);
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    if (!E)
        goto done;
    S = E->relief.scale;
    L = E->levels;
    D = 1 << L;
    CHECK_MSG(S >= D / 4.0 && S <= D * 256.0, "lattice spacing %g", S);
    /* ranks: uniform over 32 x 32 lattice cells far from the origin */
    for (y = 0; y < 224; y++)
        for (x = 0; x < 224; x++) {
            double q = ts__pix_relief_rank(&E->relief, S, 1e9 + (x + 0.5) * S / 7,
                                           -3e8 + (y + 0.5) * S / 7, 5);
            CHECK(q >= 0 && q <= 1);
            bins[q >= 1 ? 9 : (int)(q * 10)]++;
            n++;
        }
    for (i = 0; i < 10; i++)
        CHECK_MSG(fabs(bins[i] / (double)n - 0.1) <= 0.03, "rank bin %d holds %.3f", i,
                  bins[i] / (double)n);
    /* every 8S x 8S window: the low and the high ranks */
    {
        int wx, wy, worst_ok = 1;
        double worst_lo = 0, worst_hi = 1;
        for (wy = 0; wy < 6; wy++)
            for (wx = 0; wx < 6; wx++) {
                double lo = 1, hi = 0;
                for (y = 0; y < 32; y++)
                    for (x = 0; x < 32; x++) {
                        double q = ts__pix_relief_rank(&E->relief, S, (wx * 5.3 + x / 4.0) * S,
                                                       (wy * 4.7 + y / 4.0) * S, 11);
                        lo = fmin(lo, q);
                        hi = fmax(hi, q);
                    }
                worst_lo = fmax(worst_lo, lo);
                worst_hi = fmin(worst_hi, hi);
                worst_ok &= lo < 0.1 && hi > 0.9;
            }
        CHECK_MSG(worst_ok, "a window's ranks span only %.3f..%.3f", worst_lo, worst_hi);
    }
    /* the calibration: the exemplar's mean |h(p) - h(p + D)| at level 0 over every pair
     * of usable cells, against the field's mapped to the same heights (a plain sort) on a
     * grid of its own */
    {
        const pix_stack *st = &E->stacks[0];
        const float *h0 = st->level[0];
        size_t nu = 0, c, pairs = 0;
        float *sorted = malloc(sizeof(float) * (size_t)st->width * (size_t)st->height);
        double sum = 0, fsum = 0, want, got;
        for (y = 0; y < st->height; y++)
            for (x = 0; x < st->width; x++) {
                c = (size_t)y * (size_t)st->width + (size_t)x;
                if (!st->usable[0][c])
                    continue;
                sorted[nu++] = h0[c];
                if (x + D < st->width && st->usable[0][c + (size_t)D]) {
                    sum += fabs((double)h0[c + (size_t)D] - h0[c]);
                    pairs++;
                }
                if (y + D < st->height && st->usable[0][c + (size_t)D * (size_t)st->width]) {
                    sum += fabs((double)h0[c + (size_t)D * (size_t)st->width] - h0[c]);
                    pairs++;
                }
            }
        qsort(sorted, nu, sizeof *sorted, ts__float_cmp);
        want = sum / (double)pairs;
        for (y = 0; y < 200; y++)
            for (x = 0; x < 200; x++) {
                double px = 7777 + x * S / 5, py = -999 + y * S / 5;
                double q0 = ts__pix_relief_rank(&E->relief, S, px, py, 3);
                double qx = ts__pix_relief_rank(&E->relief, S, px + D, py, 3);
                double qy = ts__pix_relief_rank(&E->relief, S, px, py + D, 3);
#define H_OF(q) sorted[(size_t)fmin((q) * (double)nu, (double)nu - 1)]
                fsum += fabs(H_OF(qx) - H_OF(q0)) + fabs(H_OF(qy) - H_OF(q0));
#undef H_OF
            }
        got = fsum / (2.0 * 200 * 200);
        CHECK_MSG(fabs(got - want) <= 0.15 * want,
                  "mean height difference at %d cells: field %.2f, exemplar %.2f (S %.1f)", D,
                  got, want, S);
        free(sorted);
    }
    /* a plain beside a range: the lowest and the highest quarters of the exemplar's
     * heights in the output, relief against random start */
    {
        ts_raster two = make_terrain(ctx, 240, 240, 23);
        ts_pixel_exemplars *E2 = NULL;
        float *hs = malloc(sizeof(float) * 240 * 240);
        double share[2][2];
        int st;
        for (y = 0; y < 240; y++)
            for (x = 0; x < 240; x++) {
                /* plains and massifs in a pattern of about 60 cells */
                double t = 1 / (1 + exp(-8 * sin(x / 19.0) * sin(y / 19.0 + 1)));
                TS_PIX(&two, x, y) = (float)(100 + t * 900 + (0.1 + 0.9 * t) *
                                                                 (TS_PIX(&two, x, y) - 800));
                hs[y * 240 + x] = TS_PIX(&two, x, y);
            }
        qsort(hs, 240 * 240, sizeof *hs, ts__float_cmp);
        CHECK(ts_pixel_prepare(ctx, &two, 1, &p, &E2) == TS_OK);
        ts_raster_alloc(ctx, 256, 256, &out);
        ts_ctx_set_seed(ctx, 7);
        for (st = 0; st < 2 && E2; st++) {
            int lo = 0, hi = 0;
            p.start = st ? TS_PIXEL_START_RANDOM : TS_PIXEL_START_RELIEF;
            CHECK(ts_pixel_synthesize(ctx, E2, &p, 0, 0, &out) == TS_OK);
            for (i = 0; i < 256 * 256; i++) {
                lo += out.data[i] < hs[240 * 240 / 4];
                hi += out.data[i] > hs[240 * 240 * 3 / 4];
            }
            share[st][0] = lo / 65536.0;
            share[st][1] = hi / 65536.0;
        }
        /* seeds 1, 2, 3, 7: relief 0.28-0.39 below, 0.26-0.34 above; random 0.07-0.19,
         * 0.14-0.34 */
        CHECK_MSG(share[0][0] >= 0.2 && share[0][1] >= 0.2 &&
                      fmin(share[0][0], share[0][1]) > fmin(share[1][0], share[1][1]) + 0.05,
                  "relief start: %.3f below the exemplar's 1st quartile, %.3f above the 3rd "
                  "(random start: %.3f, %.3f)",
                  share[0][0], share[0][1], share[1][0], share[1][1]);
        p.start = TS_PIXEL_START_RELIEF;
        ts_pixel_exemplars_free(E2);
        ts_raster_free(&two);
        ts_raster_free(&out);
        free(hs);
    }
done:
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex);
    ts_ctx_free(ctx);
}

/* The guide steers the levels down to guide_spacing: under a flat guide (a
 * drawing's ground) the finest levels keep the exemplar's detail with the
 * default 8, and lose it when every level is steered (1). */
static double roughness(const ts_raster *r)
{
    double s = 0;
    int x, y;
    for (y = 0; y < r->height; y++)
        for (x = 0; x + 1 < r->width; x++)
            s += fabs(TS_PIX(r, x + 1, y) - TS_PIX(r, x, y));
    return s / ((double)r->height * (r->width - 1));
}

static void test_guide_spacing(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 160, 150, 13), guide, out;
    ts_pixel_exemplars *E = NULL;
    ts_pixel_guide *g = NULL;
    double free_r, r8, r1;
    size_t i;
    CHECK(p.guide_spacing == 8);
    p.levels = 4;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    ts_raster_alloc(ctx, 128, 128, &guide);
    ts_raster_alloc(ctx, 128, 128, &out);
    for (i = 0; i < 128 * 128; i++)
        guide.data[i] = 800; /* the exemplar's middle, flat */
    ts_ctx_set_seed(ctx, 3);
    if (E) {
        CHECK(ts_pixel_synthesize(ctx, E, &p, 0, 0, &out) == TS_OK);
        free_r = roughness(&out);
        CHECK(ts_pixel_guide_prepare(ctx, &guide, E, &p, &g) == TS_OK);
        CHECK(ts_pixel_synthesize_guided(ctx, E, g, &p, 0, 0, &out) == TS_OK);
        r8 = roughness(&out);
        p.guide_spacing = 1;
        CHECK(ts_pixel_synthesize_guided(ctx, E, g, &p, 0, 0, &out) == TS_OK);
        r1 = roughness(&out);
        /* seeds 1-6: r1 / r8 0.89-0.94, r8 / unguided 0.78-0.90 (the guided start, all at
         * the guide's height, smooths a little too) */
        CHECK_MSG(r8 >= 0.7 * free_r && r1 < 0.96 * r8,
                  "cell-to-cell relief: unguided %.3f, steered to 8 cells %.3f, every level %.3f",
                  free_r, r8, r1);
        ts_pixel_guide_free(g);
    }
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex);
    ts_raster_free(&guide);
    ts_raster_free(&out);
    ts_ctx_free(ctx);
}

/* The roughness term is off where the guide steers: with every level
 * steered (guide spacing 1) stacks prepared with and without it give the
 * same bytes (their vectors differ only in the roughness value, not
 * compared there); steered to 8 cells, or unguided, the finer levels compare
 * it and the outputs differ. */
static void test_roughness_steered(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 160, 150, 13), guide, a, b;
    ts_pixel_exemplars *E0 = NULL, *E8 = NULL;
    ts_pixel_guide *g0 = NULL, *g8 = NULL;
    size_t i, n = 96 * 96;
    int x, y, sp, same;
    p.levels = 4;
    CHECK(p.roughness_weight == 8);
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E8) == TS_OK);
    p.roughness_weight = 0;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E0) == TS_OK);
    ts_raster_alloc(ctx, 96, 96, &guide);
    ts_raster_alloc(ctx, 96, 96, &a);
    ts_raster_alloc(ctx, 96, 96, &b);
    for (y = 0; y < 96; y++)
        for (x = 0; x < 96; x++)
            TS_PIX(&guide, x, y) = (float)(800 + 60 * sin(6.2831853 * (x + 0.5 * y) / 32.0));
    if (!E0 || !E8)
        goto done;
    ts_ctx_set_seed(ctx, 5);
    CHECK(ts_pixel_guide_prepare(ctx, &guide, E0, &p, &g0) == TS_OK);
    CHECK(ts_pixel_guide_prepare(ctx, &guide, E8, &p, &g8) == TS_OK);
    for (sp = 1; sp <= 8 && g0 && g8; sp += 7) {
        p.guide_spacing = sp;
        CHECK(ts_pixel_synthesize_guided(ctx, E0, g0, &p, 0, 0, &a) == TS_OK);
        CHECK(ts_pixel_synthesize_guided(ctx, E8, g8, &p, 0, 0, &b) == TS_OK);
        for (i = 0; i < n && a.data[i] == b.data[i]; i++)
            ;
        same = i == n;
        CHECK_MSG(same == (sp == 1), "guide spacing %d: with and without the roughness term %s",
                  sp, same ? "the same" : "differ");
    }
    CHECK(ts_pixel_synthesize(ctx, E0, &p, 0, 0, &a) == TS_OK);
    CHECK(ts_pixel_synthesize(ctx, E8, &p, 0, 0, &b) == TS_OK);
    for (i = 0; i < n && a.data[i] == b.data[i]; i++)
        ;
    CHECK_MSG(i < n, "unguided: the roughness term changed nothing");
done:
    ts_pixel_guide_free(g0);
    ts_pixel_guide_free(g8);
    ts_pixel_exemplars_free(E0);
    ts_pixel_exemplars_free(E8);
    ts_raster_free(&ex);
    ts_raster_free(&guide);
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_ctx_free(ctx);
}

/* The paper's guide (--guide-mode add, Cruz et al. II.B): each level gets
 * the guide's Laplacian band of that level.  A flat guide has none past the
 * coarsest level, so steering every level changes nothing (pull, ours, pulls
 * the finer levels flat: test_guide_spacing); a guide of ridges at a
 * period of 32 cells shows in the output's band at that scale when the finer
 * levels get their bands, more than from the guided start alone (correlation
 * by a plain loop: box means of 9 and 33 cells differenced); the unguided
 * output is unrelated to it. */
static double band_corr(const ts_raster *a, const ts_raster *b)
{
    /* (box 9 - box 33) of each, correlated over the cells 16 from the edges */
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, n = 0;
    int x, y, i, j;
    for (y = 16; y < a->height - 16; y += 2)
        for (x = 16; x < a->width - 16; x += 2) {
            double m9[2] = {0, 0}, m33[2] = {0, 0}, u, v;
            for (j = -16; j <= 16; j++)
                for (i = -16; i <= 16; i++) {
                    m33[0] += TS_PIX(a, x + i, y + j);
                    m33[1] += TS_PIX(b, x + i, y + j);
                    if (abs(i) <= 4 && abs(j) <= 4) {
                        m9[0] += TS_PIX(a, x + i, y + j);
                        m9[1] += TS_PIX(b, x + i, y + j);
                    }
                }
            u = m9[0] / 81 - m33[0] / 1089;
            v = m9[1] / 81 - m33[1] / 1089;
            sa += u;
            sb += v;
            saa += u * u;
            sbb += v * v;
            sab += u * v;
            n++;
        }
    return (sab - sa * sb / n) / sqrt((saa - sa * sa / n) * (sbb - sb * sb / n) + 1e-30);
}

static void test_guide_add(void)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_pixel_params p = ts_pixel_params_default();
    ts_raster ex = make_terrain(ctx, 160, 150, 13), flat, ridges, a, b, free_out;
    ts_pixel_exemplars *E = NULL;
    ts_pixel_guide *g = NULL;
    size_t i;
    int x, y, seed;
    p.levels = 4;
    p.guide_mode = TS_GUIDE_ADD;
    p.rotations = 4; /* a guide across the exemplar's grain needs the turned views */
    /* the guide's bands alone: the roughness term is off at steered levels, so with it the
     * steered levels would differ whatever the guide */
    p.roughness_weight = 0;
    CHECK(ts_pixel_prepare(ctx, &ex, 1, &p, &E) == TS_OK);
    ts_raster_alloc(ctx, 128, 128, &flat);
    ts_raster_alloc(ctx, 128, 128, &ridges);
    ts_raster_alloc(ctx, 128, 128, &a);
    ts_raster_alloc(ctx, 128, 128, &b);
    ts_raster_alloc(ctx, 128, 128, &free_out);
    for (y = 0; y < 128; y++)
        for (x = 0; x < 128; x++) {
            TS_PIX(&flat, x, y) = 800;
            TS_PIX(&ridges, x, y) = (float)(800 + 60 * sin(6.2831853 * (x + 0.5 * y) / 32.0));
        }
    if (!E)
        goto done;
    ts_ctx_set_seed(ctx, 3);
    CHECK(ts_pixel_guide_prepare(ctx, &flat, E, &p, &g) == TS_OK);
    if (g) {
        p.guide_spacing = 8;
        CHECK(ts_pixel_synthesize_guided(ctx, E, g, &p, 0, 0, &a) == TS_OK);
        p.guide_spacing = 1;
        CHECK(ts_pixel_synthesize_guided(ctx, E, g, &p, 0, 0, &b) == TS_OK);
        for (i = 0; i < 128 * 128 && a.data[i] == b.data[i]; i++)
            ;
        CHECK_MSG(i == 128 * 128, "a flat guide added at every level changed cell %zu", i);
        ts_pixel_guide_free(g);
        g = NULL;
    }
    CHECK(ts_pixel_guide_prepare(ctx, &ridges, E, &p, &g) == TS_OK);
    for (seed = 1; seed <= 3 && g; seed++) {
        double r_all, r_start, r_free;
        ts_ctx_set_seed(ctx, (uint64_t)seed);
        p.guide_spacing = 1; /* every level gets its band */
        CHECK(ts_pixel_synthesize_guided(ctx, E, g, &p, 0, 0, &a) == TS_OK);
        p.guide_spacing = 16; /* the coarsest level alone (spacing 16): the start */
        CHECK(ts_pixel_synthesize_guided(ctx, E, g, &p, 0, 0, &b) == TS_OK);
        CHECK(ts_pixel_synthesize(ctx, E, &p, 0, 0, &free_out) == TS_OK);
        r_all = band_corr(&a, &ridges);
        r_start = band_corr(&b, &ridges);
        r_free = band_corr(&free_out, &ridges);
        /* seeds 1-3: 0.31, 0.18, 0.31 against 0.09, -0.06, 0.02 and unguided -0.09..-0.02 */
        CHECK_MSG(r_all >= 0.15 && r_all >= r_start + 0.12 && fabs(r_free) < 0.15,
                  "seed %d: the 32-cell band's correlation with the guide's: bands added %.3f, "
                  "the start alone %.3f, unguided %.3f",
                  seed, r_all, r_start, r_free);
    }
    ts_pixel_guide_free(g);
done:
    ts_pixel_exemplars_free(E);
    ts_raster_free(&ex);
    ts_raster_free(&flat);
    ts_raster_free(&ridges);
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_raster_free(&free_out);
    ts_ctx_free(ctx);
}

/* The Jacobi eigenvalues keep the matrix's invariants (trace, Frobenius
 * norm) and give a 2 x 2 matrix's by the formula; the window choice takes 3
 * for white noise (every direction carries variance) and 9 for a smooth
 * wave (a few components hold it all). */
static void test_window_choice(void)
{
    ts_ctx *ctx = ts_ctx_new();
    double a[25 * 25], b[25 * 25], ev[25], tr = 0, fro = 0, s1 = 0, s2 = 0;
    double m2[4] = {2, 1, 1, 3}, e2[2];
    uint64_t rng = 11;
    ts_raster noise, wave;
    int i, j;
    for (i = 0; i < 25; i++)
        for (j = 0; j <= i; j++)
            a[i * 25 + j] = a[j * 25 + i] = th_uniform(&rng) - 0.5;
    memcpy(b, a, sizeof a);
    for (i = 0; i < 25; i++) {
        tr += a[i * 25 + i];
        for (j = 0; j < 25; j++)
            fro += a[i * 25 + j] * a[i * 25 + j];
    }
    CHECK(ts__pix_eigenvalues(b, 25, ev) == 0);
    for (i = 0; i < 25; i++) {
        s1 += ev[i];
        s2 += ev[i] * ev[i];
    }
    CHECK_NEAR(s1, tr, 1e-9);
    CHECK_NEAR(s2, fro, 1e-9);
    CHECK(ts__pix_eigenvalues(m2, 2, e2) == 0);
    CHECK_NEAR(fmin(e2[0], e2[1]), 2.5 - sqrt(1.25), 1e-12);
    CHECK_NEAR(fmax(e2[0], e2[1]), 2.5 + sqrt(1.25), 1e-12);
    ts_raster_alloc(ctx, 120, 100, &noise);
    ts_raster_alloc(ctx, 120, 100, &wave);
    for (j = 0; j < 100; j++)
        for (i = 0; i < 120; i++) {
            TS_PIX(&noise, i, j) = (float)th_uniform(&rng);
            TS_PIX(&wave, i, j) = (float)(100 * sin(0.05 * i + 0.03 * j));
        }
    CHECK(ts__pix_choose_window(&noise, 1) == 3);
    CHECK(ts__pix_choose_window(&wave, 1) == 9);
    ts_raster_free(&noise);
    ts_raster_free(&wave);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"blur_against_convolution", test_blur_against_convolution},
        {"ssd_plain", test_ssd_plain},
        {"windows_anywhere", test_windows_anywhere},
        {"appearance_space", test_appearance_space},
        {"turned_candidates", test_turned_candidates},
        {"half_turn_and_auto", test_half_turn_and_auto},
        {"kdtree_against_scan", test_kdtree_against_scan},
        {"similarity_sets", test_similarity_sets},
        {"similarity_progress", test_similarity_progress},
        {"overviews", test_overviews},
        {"errors", test_errors},
        {"nodata_frame", test_nodata_frame},
        {"window_choice", test_window_choice},
        {"guide_quantile", test_guide_quantile},
        {"relief_start", test_relief_start},
        {"guide_spacing", test_guide_spacing},
        {"guide_add", test_guide_add},
        {"roughness_steered", test_roughness_steered},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
