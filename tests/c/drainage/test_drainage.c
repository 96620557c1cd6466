/*
 * test_drainage.c - the drainage stage against a slow, obviously-correct
 * oracle: the depression fill by relaxation (fill_oracle.h), which says how
 * deep every closed depression is.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "internal.h"
#include "terrasynth.h"

#include "fill_oracle.h"

/* A rough surface full of pits: a tilted plane, bumps and noise. */
static void make_surface(float *z, int w, int h, uint64_t seed)
{
    int x, y, k;
    double cx[24], cy[24], a[24], r[24];
    for (k = 0; k < 24; k++) {
        cx[k] = th_uniform(&seed) * w;
        cy[k] = th_uniform(&seed) * h;
        a[k] = (th_uniform(&seed) - 0.5) * 40.0;
        r[k] = 3.0 + th_uniform(&seed) * 12.0;
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double v = 0.2 * x + 0.1 * y;
            for (k = 0; k < 24; k++) {
                double d2 = ((x - cx[k]) * (x - cx[k]) + (y - cy[k]) * (y - cy[k])) / (r[k] * r[k]);
                v += a[k] * exp(-d2);
            }
            v += 3.0 * th_uniform(&seed);
            z[(size_t)y * (size_t)w + (size_t)x] = (float)v;
        }
}

static double g_depth = 0.0; /* max_depth of run() */
static double g_banks = 0.0; /* bank_slope of run() */

static void run(ts_ctx *ctx, float *z, int w, int h, int mode, int radius, ts_drainage_info *info)
{
    ts_raster r = ts_raster_wrap(z, w, h, w);
    ts_drainage_params p = ts_drainage_params_default();
    p.mode = mode;
    p.radius = radius;
    p.max_depth = g_depth;
    p.bank_slope = g_banks;
    CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, info) == TS_OK);
}

/* With a radius that reaches everywhere, breach leaves no depression and
 * raises no cell; fill gives the oracle's surface. */
static void test_breach_and_fill_against_oracle(void)
{
    const int w = 96, h = 80;
    size_t n = (size_t)w * h, i, over;
    float *z0 = malloc(n * sizeof *z0), *zb = malloc(n * sizeof *zb), *zf = malloc(n * sizeof *zf);
    double *wat = malloc(n * sizeof *wat), before;
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_info info;
    uint64_t seed;
    for (seed = 1; seed <= 3; seed++) {
        make_surface(z0, w, h, seed * 77);
        z0[40 * w + 50] = NAN; /* nodata drains out */
        before = deepest(z0, w, h, 1e-3, &over);
        CHECK_MSG(before > 5.0 && over > 50, "the surface has depressions (%g m, %zu)", before,
                  over);
        memcpy(zb, z0, n * sizeof *zb);
        run(ctx, zb, w, h, TS_DRAINAGE_BREACH, 200, &info);
        CHECK(info.pits > 0 && info.resolved == info.pits);
        for (i = 0; i < n; i++)
            CHECK(isnan(z0[i]) ? isnan(zb[i]) : zb[i] <= z0[i]);
        CHECK_MSG(deepest(zb, w, h, 1e-3, &over) <= 1e-3, "breached: %zu cells still in pits",
                  over);
        /* the change is a channel, not a lowering of everything */
        CHECK_MSG(info.cells_changed < n / 4, "%zu cells changed", info.cells_changed);
        memcpy(zf, z0, n * sizeof *zf);
        run(ctx, zf, w, h, TS_DRAINAGE_FILL, 200, &info);
        oracle_fill(z0, w, h, wat);
        for (i = 0; i < n; i++) {
            if (isnan(z0[i])) {
                CHECK(isnan(zf[i]));
                continue;
            }
            CHECK_MSG(fabs(zf[i] - wat[i]) <= 1e-3, "cell %zu: %g filled, %g the oracle", i,
                      (double)zf[i], wat[i]);
        }
    }
    ts_ctx_free(ctx);
    free(z0);
    free(zb);
    free(zf);
    free(wat);
}

/* A small radius drains the small pits and keeps a basin too wide for it. */
static void test_radius_keeps_wide_basins(void)
{
    const int w = 64, h = 64;
    float *z = malloc((size_t)w * h * sizeof *z);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_info info;
    size_t over;
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double r = hypot(x - 32.0, y - 32.0);
            /* a crater: a rim at r = 20, a floor 30 m below it */
            z[y * w + x] = (float)(r < 20 ? 70.0 + 1.5 * r : 100.0 - (r - 20) * 2.0);
        }
    run(ctx, z, w, h, TS_DRAINAGE_BREACH, 8, &info);
    CHECK(info.pits == 1 && info.resolved == 0 && info.cells_changed == 0);
    CHECK(deepest(z, w, h, 1.0, &over) > 25.0);
    run(ctx, z, w, h, TS_DRAINAGE_BREACH, 40, &info);
    CHECK(info.resolved == 1 && deepest(z, w, h, 1e-3, &over) <= 1e-3);
    ts_ctx_free(ctx);
    free(z);
}

/* Any window grown by the margin gives the whole's cells; any thread count
 * the same bytes. */
static void test_windows_and_threads(void)
{
    const int w = 150, h = 120, R = 6;
    /* breach (one-cell channels), breach with banks, fill; breach with banks beside a
     * fixed floor (a line across the grid, the cells within 5 of it shallow) */
    static const int modes[4] = {TS_DRAINAGE_BREACH, TS_DRAINAGE_BREACH, TS_DRAINAGE_FILL,
                                 TS_DRAINAGE_BREACH};
    static const double banks[4] = {0.0, 1.5, 0.0, 1.5}, shallow[4] = {0, 0, 0, 2.0};
    static const int margins[4] = {2 * R + 2, 2 * R + R / 2 + 2, 2 * R + 2,
                                   2 * R + R / 2 + 2 + R / 2 + 2};
    size_t n = (size_t)w * h;
    float *z0 = malloc(n * sizeof *z0), *whole = malloc(n * sizeof *whole), *win;
    unsigned char *fl = calloc(n, 1), *wfl = malloc(n), *use;
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_params p = ts_drainage_params_default();
    ts_raster r;
    uint64_t s = 99;
    int c, k, t, M;
    make_surface(z0, w, h, 5);
    for (k = 0; k < (int)n; k++) /* rough: pits everywhere, lakes beside lakes */
        z0[k] += (float)(12.0 * th_uniform(&s));
    p.radius = R;
    for (k = 0; k < (int)n; k++) {
        int dy = k / w - (40 + (k % w) / 5);
        fl[k] = dy == 0 ? TS_CELL_FIXED : abs(dy) <= 5 ? TS_CELL_SHALLOW : 0;
    }
    win = malloc(n * sizeof *win);
    for (c = 0; c < 4; c++) {
        use = shallow[c] > 0 ? fl : NULL;
        for (k = 0; use && k < (int)n; k++) /* the floor below the land beside it: gullies */
            if (fl[k] & TS_CELL_FIXED)
                z0[k] -= 25.0f;
        p.mode = modes[c];
        p.bank_slope = banks[c];
        p.shallow_depth = shallow[c];
        M = ts_drainage_margin(&p);
        CHECK(M == margins[c]);
        memcpy(whole, z0, n * sizeof *whole);
        r = ts_raster_wrap(whole, w, h, w);
        ts_ctx_set_threads(ctx, 1);
        CHECK(ts_drainage_apply(ctx, &r, use, 0, 0, w, h, &p, NULL) == TS_OK);
        CHECK(memcmp(whole, z0, n * sizeof *z0) != 0);
        for (t = 2; t <= 5; t += 3) {
            memcpy(win, z0, n * sizeof *win);
            r = ts_raster_wrap(win, w, h, w);
            ts_ctx_set_threads(ctx, t);
            CHECK(ts_drainage_apply(ctx, &r, use, 0, 0, w, h, &p, NULL) == TS_OK);
            CHECK_MSG(memcmp(win, whole, n * sizeof *win) == 0, "threads %d", t);
        }
        for (k = 0; k < 150; k++) {
            int x0 = (int)(th_uniform(&s) * (w - 10)), y0 = (int)(th_uniform(&s) * (h - 10));
            int ww = 1 + (int)(th_uniform(&s) * (w - x0)),
                hh = 1 + (int)(th_uniform(&s) * (h - y0));
            int ex0 = x0 - M < 0 ? 0 : x0 - M, ey0 = y0 - M < 0 ? 0 : y0 - M;
            int ex1 = x0 + ww + M > w ? w : x0 + ww + M, ey1 = y0 + hh + M > h ? h : y0 + hh + M;
            int ew = ex1 - ex0, eh = ey1 - ey0, x, y, same = 1;
            for (y = 0; y < eh; y++) {
                memcpy(win + (size_t)y * ew, z0 + (size_t)(ey0 + y) * w + ex0, (size_t)ew * 4);
                memcpy(wfl + (size_t)y * ew, fl + (size_t)(ey0 + y) * w + ex0, (size_t)ew);
            }
            r = ts_raster_wrap(win, ew, eh, ew);
            CHECK(ts_drainage_apply(ctx, &r, use ? wfl : NULL, ex0, ey0, w, h, &p, NULL) == TS_OK);
            for (y = y0; y < y0 + hh; y++)
                for (x = x0; x < x0 + ww; x++)
                    if (memcmp(&win[(size_t)(y - ey0) * ew + (x - ex0)], &whole[(size_t)y * w + x],
                               4) != 0)
                        same = 0;
            CHECK_MSG(same, "case %d window %d,%d %dx%d", c, x0, y0, ww, hh);
        }
    }
    ts_ctx_free(ctx);
    free(z0);
    free(whole);
    free(win);
    free(fl);
    free(wfl);
}

/* The ring of a drawn ridge with the plane tilting down towards x = 0 and a
 * pit just outside it uphill (hole_in 0) or inside it (hole_in 1). */
static void ring_surface(float *z, unsigned char *fl, int w, int h, int hole_in)
{
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double d = hypot(x - 20.0, y - 20.0);
            double hx = hole_in ? 20.0 : 29.0, dh = hypot(x - hx, y - 20.0);
            z[y * w + x] = (float)(50.0 + 0.5 * x + (dh < 2.5 ? -6.0 + dh : 0.0) +
                                   (d > 5.5 && d < 6.5 ? 1.0 : 0.0));
            fl[y * w + x] = fabs(d - 6.0) < 0.5 ? TS_CELL_BARRIER : 0;
        }
}

static size_t barrier_cells_changed(const float *z, const float *z0, const unsigned char *fl,
                                    size_t n)
{
    size_t i, k = 0;
    for (i = 0; i < n; i++)
        k += (fl[i] & TS_CELL_BARRIER) && z[i] != z0[i];
    return k;
}

/* A channel goes round a drawn ridge when it can, and crosses a ring drawn
 * closed once, where the land inside has no other way out; fixed cells
 * never change; keep changes nothing. */
static void test_fixed_and_barriers(void)
{
    const int w = 48, h = 40;
    size_t n = (size_t)w * h, i, over;
    float *z = malloc(n * sizeof *z), *z0 = malloc(n * sizeof *z0);
    unsigned char *fl = calloc(n, 1), *none = calloc(n, 1);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_params p = ts_drainage_params_default();
    ts_drainage_info info;
    ts_raster r = ts_raster_wrap(z, w, h, w);
    int x, y;
    p.radius = 30;
    /* outside, uphill: the straight way down crosses the ring twice */
    ring_surface(z0, fl, w, h, 0);
    memcpy(z, z0, n * sizeof *z);
    CHECK(ts_drainage_apply(ctx, &r, none, 0, 0, w, h, &p, &info) == TS_OK);
    CHECK(info.resolved == info.pits && barrier_cells_changed(z, z0, fl, n) > 0);
    memcpy(z, z0, n * sizeof *z);
    CHECK(ts_drainage_apply(ctx, &r, fl, 0, 0, w, h, &p, &info) == TS_OK);
    CHECK(info.resolved == info.pits && deepest(z, w, h, 1e-3, &over) <= 1e-3);
    CHECK_MSG(barrier_cells_changed(z, z0, fl, n) == 0, "%zu ridge cells carved",
              barrier_cells_changed(z, z0, fl, n));
    /* inside a closed ring: out over it, at one place (or between two of its cells) */
    ring_surface(z0, fl, w, h, 1);
    memcpy(z, z0, n * sizeof *z);
    CHECK(ts_drainage_apply(ctx, &r, fl, 0, 0, w, h, &p, &info) == TS_OK);
    CHECK(info.resolved == info.pits && deepest(z, w, h, 1e-3, &over) <= 1e-3);
    CHECK_MSG(barrier_cells_changed(z, z0, fl, n) <= 2, "%zu ridge cells carved",
              barrier_cells_changed(z, z0, fl, n));
    /* fixed cells: a band across the slope, the pit below it */
    memcpy(z, z0, n * sizeof *z);
    for (y = 0; y < h; y++)
        for (x = 8; x < 12; x++)
            fl[y * w + x] = TS_CELL_FIXED;
    CHECK(ts_drainage_apply(ctx, &r, fl, 0, 0, w, h, &p, &info) == TS_OK);
    for (i = 0; i < n; i++)
        if (fl[i] & TS_CELL_FIXED)
            CHECK(z[i] == z0[i]);
    p.mode = TS_DRAINAGE_KEEP;
    memcpy(z, z0, n * sizeof *z);
    CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, &info) == TS_OK);
    CHECK(memcmp(z, z0, n * sizeof *z) == 0 && ts_drainage_margin(&p) == 0);
    /* bad arguments: a message, no change */
    p.mode = TS_DRAINAGE_BREACH;
    p.radius = 0;
    CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, NULL) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "radius") != NULL);
    p.radius = 30;
    p.bank_slope = -2.0;
    CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, NULL) == TS_ERR_ARG);
    CHECK(strstr(ts_ctx_message(ctx), "bank") != NULL);
    ts_ctx_free(ctx);
    free(z);
    free(z0);
    free(fl);
    free(none);
}

/* With a deepest cut, breach cuts no deeper: a depression that needs more
 * is kept; without a limit none is. */
static void test_deepest_cut_keeps(void)
{
    const int w = 96, h = 80;
    size_t n = (size_t)w * h, i, over;
    float *z0 = malloc(n * sizeof *z0), *z = malloc(n * sizeof *z);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_info info;
    uint64_t seed;
    double depth;
    for (seed = 1; seed <= 3; seed++)
        for (depth = 1.0; depth <= 8.0; depth *= 2.0) {
            size_t kept = 0;
            make_surface(z0, w, h, seed * 31);
            memcpy(z, z0, n * sizeof *z);
            g_depth = depth;
            run(ctx, z, w, h, TS_DRAINAGE_BREACH, 200, &info);
            g_depth = 0.0;
            for (i = 0; i < n; i++) {
                CHECK(z[i] <= z0[i]);
                /* the channel's own fall below the pit: a millimetre a cell at most */
                CHECK_MSG(z[i] >= z0[i] - depth - 0.2, "depth %g: cell %zu cut %g", depth, i,
                          (double)(z0[i] - z[i]));
            }
            kept = info.pits - info.resolved;
            if (depth == 1.0)
                CHECK_MSG(kept > 0 && deepest(z, w, h, 1.0, &over) > 1.0,
                          "seed %d: a 1 m cut drains everything", (int)seed);
        }
    ts_ctx_free(ctx);
    free(z0);
    free(z);
}

/* TS_CELL_SHALLOW: a pit on such a cell is cut at most shallow_depth deep.
 * Every cell flagged with shallow_depth d gives the bytes of max_depth d;
 * with shallow_depth 0 the flag changes nothing; half the cells flagged
 * keep more pits than none and fewer than all (each pit on its own). */
static void test_shallow_beside(void)
{
    const int w = 96, h = 80;
    size_t n = (size_t)w * h, i, kept[3];
    float *z0 = malloc(n * sizeof *z0), *za = malloc(n * sizeof *za), *zb = malloc(n * sizeof *zb);
    unsigned char *flags = malloc(n);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_params p = ts_drainage_params_default();
    ts_drainage_info info;
    ts_raster ra = ts_raster_wrap(za, w, h, w), rb = ts_raster_wrap(zb, w, h, w);
    make_surface(z0, w, h, 4242);
    p.radius = 200;
    p.bank_slope = 0;
    /* all flagged, shallow 1 m == a 1 m limit everywhere */
    memcpy(za, z0, n * sizeof *za);
    memcpy(zb, z0, n * sizeof *zb);
    memset(flags, TS_CELL_SHALLOW, n);
    p.max_depth = 0;
    p.shallow_depth = 1.0;
    CHECK(ts_drainage_apply(ctx, &ra, flags, 0, 0, w, h, &p, &info) == TS_OK);
    kept[2] = info.pits - info.resolved;
    p.max_depth = 1.0;
    p.shallow_depth = 0;
    CHECK(ts_drainage_apply(ctx, &rb, NULL, 0, 0, w, h, &p, &info) == TS_OK);
    CHECK(!memcmp(za, zb, n * sizeof *za));
    /* shallow 0: the flag changes nothing */
    memcpy(za, z0, n * sizeof *za);
    memcpy(zb, z0, n * sizeof *zb);
    p.max_depth = 0;
    CHECK(ts_drainage_apply(ctx, &ra, flags, 0, 0, w, h, &p, &info) == TS_OK);
    kept[0] = info.pits - info.resolved;
    CHECK(ts_drainage_apply(ctx, &rb, NULL, 0, 0, w, h, &p, &info) == TS_OK);
    CHECK(!memcmp(za, zb, n * sizeof *za));
    /* the left half flagged */
    for (i = 0; i < n; i++)
        flags[i] = (int)(i % (size_t)w) < w / 2 ? TS_CELL_SHALLOW : 0;
    memcpy(za, z0, n * sizeof *za);
    p.shallow_depth = 1.0;
    CHECK(ts_drainage_apply(ctx, &ra, flags, 0, 0, w, h, &p, &info) == TS_OK);
    kept[1] = info.pits - info.resolved;
    CHECK_MSG(kept[0] < kept[1] && kept[1] < kept[2], "kept %zu, %zu, %zu", kept[0], kept[1],
              kept[2]);
    for (i = 0; i < n; i++)
        CHECK(za[i] <= z0[i]);
    ts_ctx_free(ctx);
    free(z0);
    free(za);
    free(zb);
    free(flags);
}

/* A valley dammed by a ridge 40 m high across it: breached without banks,
 * a slot one cell wide with creases as sharp as the cut; with banks, the
 * same drainage (no pit left, no cell raised) through a gorge as wide as
 * the cut over the slope, whose creases are those of the slope. */
static void dam_surface(float *z, int w, int h)
{
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double dam = fabs(x - 32.0) < 4.0 ? 40.0 * (1.0 - fabs(x - 32.0) / 4.0) : 0.0;
            z[y * w + x] = (float)(160.0 - 2.0 * x + 2.0 * fabs(y - 24.0) + dam);
        }
}

static double sharpest_crease(const float *z, int w, int h)
{
    double m = 0.0;
    int x, y;
    for (y = 1; y < h - 1; y++)
        for (x = 1; x < w - 1; x++) {
            double l = fabs((double)z[y * w + x - 1] + z[y * w + x + 1] + z[(y - 1) * w + x] +
                            z[(y + 1) * w + x] - 4.0 * z[y * w + x]);
            if (l > m)
                m = l;
        }
    return m;
}

/* A shallow cell is cut no deeper than shallow_depth by any pit's channel:
 * the dam's cells flagged (the pit above it is not), its 40 m breached with
 * no flags; with them every flagged cell is lowered at most 5 m (the pit
 * drains another way, over the valley's side to the grid's edge). */
static void test_shallow_cells_any_channel(void)
{
    const int w = 64, h = 48;
    size_t n = (size_t)w * h, i;
    float *z0 = malloc(n * sizeof *z0), *z = malloc(n * sizeof *z);
    unsigned char *flags = calloc(n, 1);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_params p = ts_drainage_params_default();
    ts_drainage_info info;
    ts_raster r = ts_raster_wrap(z, w, h, w);
    double cut = 0;
    dam_surface(z0, w, h);
    p.radius = 64;
    p.bank_slope = 0;
    p.max_depth = 0;
    p.shallow_depth = 5.0;
    memcpy(z, z0, n * sizeof *z);
    CHECK(ts_drainage_apply(ctx, &r, flags, 0, 0, w, h, &p, &info) == TS_OK);
    for (i = 0; i < n; i++)
        if (z0[i] - z[i] > cut)
            cut = z0[i] - z[i];
    CHECK_MSG(cut > 30 && info.pits == info.resolved, "unflagged: deepest cut %.1f", cut);
    for (i = 0; i < n; i++) /* the dam */
        flags[i] = fabs((double)(i % (size_t)w) - 32.0) < 4.0 ? TS_CELL_SHALLOW : 0;
    memcpy(z, z0, n * sizeof *z);
    CHECK(ts_drainage_apply(ctx, &r, flags, 0, 0, w, h, &p, &info) == TS_OK);
    cut = 0;
    for (i = 0; i < n; i++) {
        CHECK(z[i] <= z0[i]);
        if (flags[i] && z0[i] - z[i] > cut)
            cut = z0[i] - z[i];
    }
    CHECK_MSG(cut <= 5.0 + 1e-3, "a flagged cell cut %.2f deep by a channel from elsewhere", cut);
    ts_ctx_free(ctx);
    free(z0);
    free(z);
    free(flags);
}

static void test_banks(void)
{
    const int w = 64, h = 48;
    const double s = 4.0;
    size_t n = (size_t)w * h, i, over;
    float *z0 = malloc(n * sizeof *z0), *slot = malloc(n * sizeof *slot),
          *gorge = malloc(n * sizeof *gorge);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_info info;
    int y, wide = 0;
    double c0, c1, c2;
    dam_surface(z0, w, h);
    CHECK(deepest(z0, w, h, 1.0, &over) > 30.0);
    memcpy(slot, z0, n * sizeof *slot);
    run(ctx, slot, w, h, TS_DRAINAGE_BREACH, 60, &info);
    memcpy(gorge, z0, n * sizeof *gorge);
    g_banks = s;
    run(ctx, gorge, w, h, TS_DRAINAGE_BREACH, 60, &info);
    g_banks = 0.0;
    CHECK(info.pits == 1 && info.resolved == 1);
    CHECK_MSG(deepest(gorge, w, h, 1e-3, &over) <= 1e-3, "%zu cells still in pits", over);
    for (i = 0; i < n; i++)
        CHECK(gorge[i] <= z0[i]);
    for (y = 0; y < h; y++)
        wide += gorge[y * w + 32] < z0[y * w + 32];
    /* the cut at the crest, ~32 m, over the slope: ~8 cells each side */
    CHECK_MSG(wide >= 12, "the gorge is %d cells wide at the crest", wide);
    c0 = sharpest_crease(z0, w, h);
    c1 = sharpest_crease(slot, w, h);
    c2 = sharpest_crease(gorge, w, h);
    CHECK_MSG(c1 > 3.0 * c0 && c2 < c0 + 3.0 * s, "creases: %g as given, %g slot, %g gorge", c0, c1,
              c2);
    /* the automatic deepest cut: the slope times an eighth of the radius; the dam
     * needs ~32 m: kept with 4 x 60 / 8 = 30, drained with 4 x 72 / 8 = 36 */
    {
        ts_drainage_params p = ts_drainage_params_default();
        ts_raster r = ts_raster_wrap(gorge, w, h, w);
        p.bank_slope = s;
        p.radius = 60;
        CHECK(p.max_depth == -1 && ts_drainage_depth_of(&p) == 30.0);
        memcpy(gorge, z0, n * sizeof *gorge);
        CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, &info) == TS_OK);
        CHECK(info.pits == 1 && info.resolved == 0 && memcmp(gorge, z0, n * sizeof *z0) == 0);
        p.radius = 72;
        memcpy(gorge, z0, n * sizeof *gorge);
        CHECK(ts_drainage_apply(ctx, &r, NULL, 0, 0, w, h, &p, &info) == TS_OK);
        CHECK(info.resolved == 1 && deepest(gorge, w, h, 1e-3, &over) <= 1e-3);
        p.bank_slope = 0.0;
        CHECK(ts_drainage_depth_of(&p) == 0.0);
    }
    ts_ctx_free(ctx);
    free(z0);
    free(slot);
    free(gorge);
}

/* ts__nearest_fixed_levels against the obvious search: every fixed cell's
 * chamfer distance (7 a diagonal step, 5 a straight one) to every cell, the
 * nearest within 5 reach, ties to the first in raster order; and a window
 * with a margin of reach gives the whole's values inside it. */
static void test_nearest_fixed_levels(void)
{
    const int w = 61, h = 47, reach = 7;
    size_t n = (size_t)w * h, i;
    float *z = malloc(n * sizeof *z), *lv, *wl;
    unsigned char *fl = malloc(n), *wfl = malloc(n);
    uint64_t s = 17;
    int x, y, k, bad = 0;
    for (i = 0; i < n; i++) {
        z[i] = (float)(1000.0 * th_uniform(&s));
        fl[i] = th_uniform(&s) < 0.015 ? TS_CELL_FIXED : th_uniform(&s) < 0.3 ? TS_CELL_SHALLOW : 0;
    }
    z[5 * w + 5] = NAN; /* a fixed cell without data is no floor */
    fl[5 * w + 5] = TS_CELL_FIXED;
    lv = ts__nearest_fixed_levels(z, fl, w, h, reach);
    CHECK(lv != NULL);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            long best = -1, bd = 0;
            float want;
            for (i = 0; i < n; i++) {
                long ax = labs((long)(i % (size_t)w) - x), ay = labs((long)(i / (size_t)w) - y);
                long d = 7 * (ax < ay ? ax : ay) + 5 * (labs(ax - ay));
                if (!(fl[i] & TS_CELL_FIXED) || isnan(z[i]) || d > 5 * reach)
                    continue;
                if (best < 0 || d < bd) { /* raster order: the first of equals kept */
                    best = (long)i;
                    bd = d;
                }
            }
            want = best < 0 ? NAN : z[best];
            i = (size_t)y * (size_t)w + (size_t)x;
            if (!(lv[i] == want || (isnan(lv[i]) && isnan(want))))
                bad++;
        }
    CHECK_MSG(bad == 0, "%d cells differ from the search", bad);
    for (k = 0; k < 40; k++) {
        int x0 = (int)(th_uniform(&s) * (w - 1)), y0 = (int)(th_uniform(&s) * (h - 1));
        int ww = 1 + (int)(th_uniform(&s) * (w - x0)), hh = 1 + (int)(th_uniform(&s) * (h - y0));
        int ex0 = x0 - reach < 0 ? 0 : x0 - reach, ey0 = y0 - reach < 0 ? 0 : y0 - reach;
        int ex1 = x0 + ww + reach > w ? w : x0 + ww + reach;
        int ey1 = y0 + hh + reach > h ? h : y0 + hh + reach, ew = ex1 - ex0, eh = ey1 - ey0;
        float *wz = malloc((size_t)ew * (size_t)eh * sizeof *wz);
        for (y = 0; y < eh; y++) {
            memcpy(wz + (size_t)y * ew, z + (size_t)(ey0 + y) * w + ex0, (size_t)ew * 4);
            memcpy(wfl + (size_t)y * ew, fl + (size_t)(ey0 + y) * w + ex0, (size_t)ew);
        }
        wl = ts__nearest_fixed_levels(wz, wfl, ew, eh, reach);
        CHECK(wl != NULL);
        for (y = y0; y < y0 + hh; y++)
            for (x = x0; x < x0 + ww; x++)
                if (memcmp(&wl[(size_t)(y - ey0) * ew + (x - ex0)], &lv[(size_t)y * w + x], 4))
                    bad++;
        CHECK_MSG(bad == 0, "window %d,%d %dx%d", x0, y0, ww, hh);
        free(wl);
        free(wz);
    }
    free(lv);
    free(z);
    free(fl);
    free(wfl);
}

/* Beside a drawn valley's floor (a fixed row falling to the grid's left
 * edge, the land rising 1 a cell from it, the rows within 25 shallow), two
 * bowls dug into the valley's side: one whose bottom stands above the floor
 * beside it is drained by a side gully cut deeper than the shallow depth;
 * one whose bottom is below the floor is cut no deeper than it; no cell is
 * cut deeper than the shallow depth below the floor nearest it. */
/* An 80 x 60 valley whose floor (row 30, fixed, falling to x = 79) has shallow banks 25 rows
 * each side, and two bowls on its bank: one (x = 40) above the floor beside it, one (x = 20)
 * below it; the breach the case is made for (one-cell channels, no depth limit, shallow depth 3
 * beside the floor). */
static ts_drainage_params floor_surface(float *z0, unsigned char *fl, int w, int h)
{
    ts_drainage_params p = ts_drainage_params_default();
    int x, y;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double floor_ = 40.0 - 0.2 * x, v = floor_ + fabs(y - 30.0);
            double ra = hypot(x - 40.0, y - 8.0), rb = hypot(x - 20.0, y - 8.0);
            v -= 20.0 * exp(-ra * ra / 25.0) + 30.0 * exp(-rb * rb / 25.0);
            z0[y * w + x] = (float)v;
            fl[y * w + x] = y == 30 ? TS_CELL_FIXED : abs(y - 30) <= 25 ? TS_CELL_SHALLOW : 0;
        }
    p.radius = 64;
    p.bank_slope = 0;
    p.max_depth = 0;
    p.shallow_depth = 3.0;
    return p;
}

static void test_gully_to_the_floor(void)
{
    const int w = 80, h = 60;
    size_t n = (size_t)w * h, i;
    float *z0 = malloc(n * sizeof *z0), *z = malloc(n * sizeof *z), *lv;
    unsigned char *fl = malloc(n);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_params p;
    ts_raster r = ts_raster_wrap(z, w, h, w);
    double cut_a = 0, cut_b = 0;
    size_t left;
    int x, y;
    p = floor_surface(z0, fl, w, h);
    CHECK(z0[8 * w + 40] > z0[30 * w + 40] && z0[8 * w + 20] < z0[30 * w + 20]);
    memcpy(z, z0, n * sizeof *z);
    CHECK(ts_drainage_apply(ctx, &r, fl, 0, 0, w, h, &p, NULL) == TS_OK);
    lv = ts__nearest_fixed_levels(z0, fl, w, h, p.radius / 2 + 2);
    CHECK(lv != NULL);
    for (i = 0; i < n; i++) {
        double c = (double)z0[i] - z[i];
        CHECK(c >= 0);
        if ((int)(i % (size_t)w) < 30 && c > cut_b)
            cut_b = c;
        if ((int)(i % (size_t)w) >= 30 && c > cut_a)
            cut_a = c;
        CHECK_MSG(c <= 3.0 + 1e-3 || z[i] >= lv[i] - 1.0,
                  "cell %zu cut %.1f to %.1f below its floor %.1f", i, c, z[i], lv[i]);
    }
    CHECK_MSG(cut_a > 3.5 && cut_b <= 3.0 + 1e-3, "above the floor cut %.1f, below it %.1f", cut_a,
              cut_b);
    deepest(z, w, h, 0.5, &left);
    CHECK_MSG(left > 0, "the bowl below the floor drained");
    /* the lower bowl away: no pit left once the upper one drains */
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double rb = hypot(x - 20.0, y - 8.0);
            z[y * w + x] = (float)(z0[y * w + x] + 30.0 * exp(-rb * rb / 25.0));
        }
    CHECK(ts_drainage_apply(ctx, &r, fl, 0, 0, w, h, &p, NULL) == TS_OK);
    deepest(z, w, h, 0.5, &left);
    CHECK_MSG(left == 0, "%zu cells in pits with the upper bowl alone", left);
    free(lv);
    ts_ctx_free(ctx);
    free(z0);
    free(z);
    free(fl);
}

/* The spill levels (a priority flood) against the fill by relaxation, with nodata holes and
 * with flats (heights in whole units: cells reached out of height order beside equal ones). */
static void test_spill_levels(void)
{
    const int w = 70, h = 50;
    size_t n = (size_t)w * h, i, bad = 0;
    float *z = malloc(n * sizeof *z), *lv = malloc(n * sizeof *lv);
    double *wat = malloc(n * sizeof *wat);
    uint64_t seed;
    for (seed = 1; seed <= 6; seed++) {
        make_surface(z, w, h, seed * 31);
        for (i = 0; seed > 2 && i < n; i += 37) /* nodata drains out */
            z[i] = NAN;
        for (i = 0; seed > 4 && i < n; i++) /* whole units: ties and flats */
            z[i] = floorf(z[i] / 4.0f);
        CHECK(ts__spill_levels(z, w, h, lv) == 0);
        oracle_fill(z, w, h, wat);
        for (i = 0; i < n; i++)
            if (isnan(z[i]) ? !isnan(lv[i]) : lv[i] != (float)wat[i])
                bad++;
        CHECK_MSG(bad == 0, "seed %d: %zu cells' levels differ from the relaxation's", (int)seed,
                  bad);
    }
    free(z);
    free(lv);
    free(wat);
}

/* floodplain_relief: the bowl below the floor, which a breach keeps (test_gully_to_the_floor),
 * is raised to a plain no higher than its spill plus the relief and drained: no pit left, fixed
 * cells as they were, no cell raised outside the kept basins, the same bytes on 1 and 3
 * threads; kept with a pinned cell in it; refused on a window; a basin beside no floor or bank
 * left as the breach leaves it. */
static void test_dammed_basins_raised(void)
{
    const int w = 80, h = 60;
    size_t n = (size_t)w * h, i, left, raised = 0;
    float *z0 = malloc(n * sizeof *z0), *zb = malloc(n * sizeof *zb), *z = malloc(n * sizeof *z),
          *z3 = malloc(n * sizeof *z3);
    double *spill = malloc(n * sizeof *spill);
    unsigned char *fl = malloc(n), *none = calloc(n, 1);
    ts_ctx *ctx = ts_ctx_new();
    ts_drainage_params p;
    ts_raster rb = ts_raster_wrap(zb, w, h, w), r = ts_raster_wrap(z, w, h, w),
              r3 = ts_raster_wrap(z3, w, h, w);
    ts_drainage_info info;
    p = floor_surface(z0, fl, w, h);
    memcpy(zb, z0, n * sizeof *zb);
    CHECK(ts_drainage_apply(ctx, &rb, fl, 0, 0, w, h, &p, NULL) == TS_OK);
    oracle_fill(zb, w, h, spill); /* the basins the breach keeps */
    p.floodplain_relief = 4.0;
    memcpy(z, z0, n * sizeof *z);
    memcpy(z3, z0, n * sizeof *z3);
    ts_ctx_set_threads(ctx, 1);
    CHECK(ts_drainage_apply(ctx, &r, fl, 0, 0, w, h, &p, &info) == TS_OK);
    ts_ctx_set_threads(ctx, 3);
    CHECK(ts_drainage_apply(ctx, &r3, fl, 0, 0, w, h, &p, NULL) == TS_OK);
    CHECK(memcmp(z, z3, n * sizeof *z) == 0);
    CHECK_MSG(info.basins_raised == 1, "%zu basins raised", info.basins_raised);
    deepest(z, w, h, 0.01, &left);
    CHECK_MSG(left == 0, "%zu cells in pits after the plain", left);
    for (i = 0; i < n; i++) {
        if (fl[i] & TS_CELL_FIXED)
            CHECK(z[i] == z0[i]);
        if (z[i] > zb[i]) {
            raised++;
            CHECK_MSG(spill[i] > zb[i] && z[i] <= spill[i] + 4.0 + 1e-3,
                      "cell %zu raised from %.2f to %.2f, its spill %.2f", i, zb[i], z[i],
                      spill[i]);
        }
    }
    CHECK_MSG(raised > 20 && info.cells_raised >= raised, "%zu cells raised", raised);
    /* a pinned cell (fixed, not water) below the bowl's spill: the bowl is kept (land raised
     * round the pin would stand as a step against it) */
    memcpy(z, z0, n * sizeof *z);
    fl[8 * w + 20] |= TS_CELL_FIXED;
    CHECK(ts_drainage_apply(ctx, &r, fl, 0, 0, w, h, &p, &info) == TS_OK);
    CHECK_MSG(info.basins_raised == 0, "%zu basins raised round a pin", info.basins_raised);
    fl[8 * w + 20] &= (unsigned char)~TS_CELL_FIXED;
    r = ts_raster_wrap(z + w, w, h - 1, w);
    CHECK(ts_drainage_apply(ctx, &r, fl + w, 0, 1, w, h, &p, NULL) == TS_ERR_ARG);
    /* no floor, no banks: the plain's pass changes nothing */
    p.radius = 4;
    make_surface(z0, w, h, 5);
    memcpy(z, z0, n * sizeof *z);
    memcpy(zb, z0, n * sizeof *zb);
    r = ts_raster_wrap(z, w, h, w);
    CHECK(ts_drainage_apply(ctx, &r, none, 0, 0, w, h, &p, &info) == TS_OK);
    p.floodplain_relief = 0;
    CHECK(ts_drainage_apply(ctx, &rb, none, 0, 0, w, h, &p, NULL) == TS_OK);
    CHECK(memcmp(z, zb, n * sizeof *z) == 0 && info.basins_raised == 0);
    deepest(z, w, h, 0.5, &left);
    CHECK_MSG(left > 0, "a radius of 4 drained every basin: the case tests nothing");
    ts_ctx_free(ctx);
    free(z0);
    free(zb);
    free(z);
    free(z3);
    free(spill);
    free(fl);
    free(none);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"breach_and_fill_against_oracle", test_breach_and_fill_against_oracle},
        {"radius_keeps_wide_basins", test_radius_keeps_wide_basins},
        {"deepest_cut_keeps", test_deepest_cut_keeps},
        {"shallow_beside", test_shallow_beside},
        {"shallow_cells_any_channel", test_shallow_cells_any_channel},
        {"nearest_fixed_levels", test_nearest_fixed_levels},
        {"gully_to_the_floor", test_gully_to_the_floor},
        {"spill_levels", test_spill_levels},
        {"dammed_basins_raised", test_dammed_basins_raised},
        {"banks", test_banks},
        {"windows_and_threads", test_windows_and_threads},
        {"fixed_and_barriers", test_fixed_and_barriers},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
