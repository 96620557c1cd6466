/*
 * test_crest_profile.c - peaks and saddles along a sketch's ridges
 * (algorithms/src/sketch/crest_profile.c): the pieces of an exemplar's
 * crest against the Gaussian band-pass in closed form (a diagonal path, so
 * arc length is measured, not counted), short paths left out; the offsets
 * chained from a constant piece (exactly the constant outside the
 * cross-fades, within the equal-power bound inside), a node's value the
 * same whichever path reaches it, the same bytes for a seed; and the
 * layout carrying the offsets to the output: a drawn crest on flat land
 * rises and falls with them, the land five patches off and a pinned window
 * do not.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "harness.h"
#include "crest_profile.h"
#include "layout.h"
#include "terrasynth.h"

#define PI 3.14159265358979323846

/* ---- the pieces: the band-pass of the crest's heights by arc length ---- */
static void test_library_band_pass(void)
{
    ts_ctx *ctx = ts_ctx_new();
    enum { N = 700, SHORT = 20 };
    static ts_feature_vertex vv[N + SHORT];
    ts_feature_node nn[4] = {{0, 0, 0, 1, TS_RIDGE}, {N - 1, N - 1, 0, 1, TS_RIDGE},
                             {0, 5, 0, 1, TS_RIDGE}, {SHORT - 1, 5, 0, 1, TS_RIDGE}};
    ts_feature_path pp[2] = {{TS_RIDGE, 0, 1, 0, N, 0, 0, 0, 0},
                             {TS_RIDGE, 2, 3, N, SHORT, 0, 0, 0, 0}};
    ts_features ef;
    ts__crest_library lib;
    int P = 32, k;
    double lambda = 48.0, A = 100.0, gain, s1 = P / 4.0, s2 = 2.0 * P, worst = 0.0;
    size_t m;
    /* a diagonal ridge: a cell of the path is sqrt(2) of arc; its height a
     * steady rise (the path's fall to the plain) plus peaks and saddles */
    for (k = 0; k < N; k++) {
        double s = k * sqrt(2.0);
        vv[k] = (ts_feature_vertex){k, k, (float)(1000.0 + 0.8 * s + A * sin(2.0 * PI * s / lambda))};
    }
    for (k = 0; k < SHORT; k++) /* shorter than a patch: no piece */
        vv[N + k] = (ts_feature_vertex){k, 5, 900.0f};
    memset(&ef, 0, sizeof ef);
    ef.width = ef.height = N;
    ef.nodes = nn;
    ef.n_nodes = 4;
    ef.paths = pp;
    ef.n_paths = 2;
    ef.verts = vv;
    ef.n_verts = N + SHORT;
    CHECK(ts__crest_library_measure(ctx, &ef, P, &lib) == TS_OK);
    CHECK(lib.n_pieces == 1);
    m = lib.start[1] - lib.start[0];
    CHECK(m == (size_t)floor((N - 1) * sqrt(2.0)) + 1);
    /* the Gaussians' transfer at the sine's wavelength; the rise is a line,
     * which both Gaussians keep, so it cancels away from the ends */
    gain = exp(-2.0 * PI * PI * s1 * s1 / (lambda * lambda)) -
           exp(-2.0 * PI * PI * s2 * s2 / (lambda * lambda));
    for (k = (int)(3 * s2) + 2; k + (int)(3 * s2) + 2 < (int)m; k++) {
        double want = gain * A * sin(2.0 * PI * k / lambda);
        worst = fmax(worst, fabs(lib.z[lib.start[0] + (size_t)k] - want));
    }
    CHECK_MSG(worst < 0.03 * A, "band-pass off by %.2f m", worst);
    ts__crest_library_free(&lib);
    /* no ridge path a patch long: no library */
    ef.paths = pp + 1;
    ef.n_paths = 1;
    CHECK(ts__crest_library_measure(ctx, &ef, P, &lib) == TS_OK);
    CHECK(lib.n_pieces == 0 && lib.z == NULL);
    ts_ctx_free(ctx);
}

/* A star of three ridge paths from the node at (cx, cy) (index 0) to ends
 * 1..3, each straight along a direction; verts: 3 * len. */
static void star(ts_features *f, ts_feature_node nn[4], ts_feature_path pp[3],
                 ts_feature_vertex *vv, int W, int H, int len, int only)
{
    static const int dx[3] = {1, -1, 0}, dy[3] = {0, 0, 1};
    int cx = W / 2, cy = H / 3, a, k;
    size_t nv = 0, np = 0;
    nn[0] = (ts_feature_node){cx, cy, 0, 3, TS_RIDGE};
    for (a = 0; a < 3; a++) {
        nn[a + 1] = (ts_feature_node){cx + dx[a] * (len - 1), cy + dy[a] * (len - 1), 0, 1, TS_RIDGE};
        if (only >= 0 && a != only)
            continue;
        pp[np++] = (ts_feature_path){TS_RIDGE, 0, (size_t)a + 1, nv, (size_t)len, 0, 0, 0, 0};
        for (k = 0; k < len; k++)
            vv[nv++] = (ts_feature_vertex){cx + dx[a] * k, cy + dy[a] * k, 0};
    }
    memset(f, 0, sizeof *f);
    f->width = W;
    f->height = H;
    f->nodes = nn;
    f->n_nodes = 4;
    f->paths = pp;
    f->n_paths = np;
    f->verts = vv;
    f->n_verts = nv;
}

/* ---- the offsets: chained pieces, nodes shared, seeded ---- */
static void test_offsets(void)
{
    ts_ctx *ctx = ts_ctx_new();
    enum { W = 300, H = 300, LEN = 140 };
    static ts_feature_vertex vv[3 * LEN];
    static float off[W * H], off2[W * H], offa[W * H], offb[W * H];
    ts_feature_node nn[4];
    ts_feature_path pp[3];
    ts_features f;
    ts__crest_library lib;
    float z[100];
    size_t start[2] = {0, 100}, i, exact = 0, on = 0;
    int any, k, P = 32, node = (H / 3) * W + W / 2;
    for (k = 0; k < 100; k++)
        z[k] = 50.0f;
    lib.z = z;
    lib.start = start;
    lib.n_pieces = 1;
    star(&f, nn, pp, vv, W, H, LEN, -1);
    CHECK(ts__crest_offsets(ctx, &f, &lib, 1, NULL, P, 7, off, &any) == TS_OK && any);
    /* a constant piece: the constant wherever one piece speaks, between it
     * and sqrt(2) times it where two cross-fade (cos a + sin a) */
    for (i = 0; i < (size_t)W * H; i++) {
        int is_path = 0, a;
        for (a = 0; a < 3; a++) {
            int x = (int)(i % W) - W / 2, y = (int)(i / W) - H / 3;
            is_path |= (a == 0 && y == 0 && x >= 0 && x < LEN) ||
                       (a == 1 && y == 0 && x <= 0 && x > -LEN) ||
                       (a == 2 && x == 0 && y >= 0 && y < LEN);
        }
        if (!is_path) {
            CHECK(isnan(off[i]));
            continue;
        }
        on++;
        CHECK(off[i] >= 50.0f - 1e-3f && off[i] <= 50.0f * sqrt(2.0) + 1e-3);
        exact += fabsf(off[i] - 50.0f) < 1e-3f;
    }
    CHECK(on == 3 * LEN - 2);
    CHECK_MSG(exact * 2 > on, "%zu of %zu cells are the piece's own value", exact, on);
    /* the same seed: the same offsets */
    CHECK(ts__crest_offsets(ctx, &f, &lib, 1, NULL, P, 7, off2, &any) == TS_OK);
    CHECK(memcmp(off, off2, sizeof off) == 0);
    /* a varied piece: another seed gives another profile; a node takes its
     * own value whichever path reaches it */
    for (k = 0; k < 100; k++)
        z[k] = (float)(80.0 * sin(2.0 * PI * k / 37.0) + 30.0 * cos(2.0 * PI * k / 11.0));
    CHECK(ts__crest_offsets(ctx, &f, &lib, 1, NULL, P, 7, off, &any) == TS_OK);
    CHECK(ts__crest_offsets(ctx, &f, &lib, 1, NULL, P, 8, off2, &any) == TS_OK);
    CHECK(memcmp(off, off2, sizeof off) != 0);
    star(&f, nn, pp, vv, W, H, LEN, 0);
    CHECK(ts__crest_offsets(ctx, &f, &lib, 1, NULL, P, 7, offa, &any) == TS_OK);
    star(&f, nn, pp, vv, W, H, LEN, 2);
    CHECK(ts__crest_offsets(ctx, &f, &lib, 1, NULL, P, 7, offb, &any) == TS_OK);
    CHECK(!isnan(offa[node]) && offa[node] == offb[node] && offa[node] == off[node]);
    /* no library: nothing laid */
    CHECK(ts__crest_offsets(ctx, &f, &lib, 0, NULL, P, 7, off, &any) == TS_OK && !any);
    ts_ctx_free(ctx);
}

/* RMS about the mean of the heights on row y, x in [x0, x1). */
static double row_spread(const ts_raster *r, int y, int x0, int x1)
{
    double s = 0.0, s2 = 0.0;
    int x;
    for (x = x0; x < x1; x++) {
        s += TS_PIX(r, x, y);
        s2 += (double)TS_PIX(r, x, y) * TS_PIX(r, x, y);
    }
    s /= x1 - x0;
    return sqrt(fmax(0.0, s2 / (x1 - x0) - s * s));
}

/* ---- the layout carries the offsets to the drawn crest ---- */
static void test_layout_crest(void)
{
    ts_ctx *ctx = ts_ctx_new();
    enum { W = 400, H = 320 };
    static ts_feature_vertex vv[W];
    static unsigned char mask[W * H], flags[W * H];
    ts_feature_node nn[2] = {{10, 160, 0, 1, TS_RIDGE}, {W - 11, 160, 0, 1, TS_RIDGE}};
    ts_feature_path pp[1] = {{TS_RIDGE, 0, 1, 0, W - 20, 0, 0, 0, 0}};
    ts_features f;
    ts__crest_library lib;
    ts_raster ex, a, b;
    ts_relief_profile prof;
    ts_layout_spec sp;
    float z[600];
    size_t start[2] = {0, 600};
    int x, y, k, P = 32;
    double flat, crest, far;
    CHECK(ts_raster_alloc(ctx, 200, 200, &ex) == TS_OK);
    CHECK(ts_raster_alloc(ctx, W, H, &a) == TS_OK);
    CHECK(ts_raster_alloc(ctx, W, H, &b) == TS_OK);
    for (y = 0; y < 200; y++) /* an exemplar of ridges: rows of a sine */
        for (x = 0; x < 200; x++)
            TS_PIX(&ex, x, y) = (float)(500.0 + 200.0 * sin(2.0 * PI * x / 60.0));
    for (k = 0; k < 600; k++) /* its crest: peaks and saddles 2 patches apart */
        z[k] = (float)(120.0 * sin(2.0 * PI * k / 64.0));
    lib.z = z;
    lib.start = start;
    lib.n_pieces = 1;
    for (x = 10; x < W - 10; x++) {
        mask[160 * W + x] = TS_RIDGE;
        vv[x - 10] = (ts_feature_vertex){x, 160, 0};
    }
    memset(&f, 0, sizeof f);
    f.width = W;
    f.height = H;
    f.nodes = nn;
    f.n_nodes = 2;
    f.paths = pp;
    f.n_paths = 1;
    f.verts = vv;
    f.n_verts = W - 20;
    memset(&prof, 0, sizeof prof);
    prof.valid = 1;
    prof.level = 700.0;
    memset(&sp, 0, sizeof sp);
    sp.sketch_mask = mask;
    sp.kind = TS_RIDGE;
    sp.width = W;
    sp.height = H;
    sp.exemplars = &ex;
    sp.n_exemplars = 1;
    sp.profs = &prof;
    sp.patch = P;
    sp.features = &f;
    for (y = 5; y < 25; y++) /* a pinned window */
        for (x = 5; x < 25; x++)
            flags[y * W + x] = TS_CELL_FIXED;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TS_PIX(&a, x, y) = TS_PIX(&b, x, y) = 400.0f;
    CHECK(ts__layout_apply(ctx, &sp, &a, flags, 1.0) == TS_OK); /* one level */
    sp.crest = &lib;
    sp.crest_relief = 1.0;
    CHECK(ts__layout_apply(ctx, &sp, &b, flags, 1.0) == TS_OK); /* peaks and saddles */
    flat = row_spread(&a, 160, 3 * P, W - 3 * P);
    crest = row_spread(&b, 160, 3 * P, W - 3 * P);
    far = fabs(TS_PIX(&b, W / 2, 2) - TS_PIX(&a, W / 2, 2)) +
          fabs(TS_PIX(&b, W / 2, H - 3) - TS_PIX(&a, W / 2, H - 3));
    CHECK_MSG(flat < 5.0, "a crest at one level varies by %.1f m", flat);
    CHECK_MSG(crest > 40.0, "the crest's peaks and saddles vary by %.1f m only", crest);
    CHECK_MSG(far < 0.1 * crest, "the land 5 patches off moved by %.1f m", far);
    for (y = 5; y < 25; y++)
        for (x = 5; x < 25; x++)
            CHECK(TS_PIX(&b, x, y) == 400.0f);
    ts_raster_free(&ex);
    ts_raster_free(&a);
    ts_raster_free(&b);
    ts_ctx_free(ctx);
}

int main(int argc, char **argv)
{
    static const th_case cases[] = {
        {"library_band_pass", test_library_band_pass},
        {"offsets", test_offsets},
        {"layout_crest", test_layout_crest},
    };
    return th_run(cases, sizeof cases / sizeof cases[0], argc, argv);
}
