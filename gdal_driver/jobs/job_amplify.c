/*
 * job_amplify.c - the amplify and dictionary jobs: the input and exemplars read,
 * the dictionary built or read from its file, the amplification in one piece or
 * window by window.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "job_internal.h"

/* Every cell of a class raster a code 1..TS_MAX_CLASSES, 0 or nodata. */
static int job_check_class_codes(const char *path, const ts_raster *r, tsio_err *err)
{
    int x, y;
    for (y = 0; y < r->height; y++)
        for (x = 0; x < r->width; x++) {
            float v = TS_PIX(r, x, y);
            if (!isnan(v) && v != 0.0f &&
                !(v >= 1.0f && v <= (float)TS_MAX_CLASSES && v == floorf(v))) {
                tsio_errf(err, path,
                          "%g at column %d, row %d is not a class code 1..%d (0 or nodata: "
                          "unlabelled)",
                          (double)v, x, y, TS_MAX_CLASSES);
                return -1;
            }
        }
    return 0;
}

/* The atoms an exemplar gives whose phases have n1 windows each (the
 * dictionary's rule: a lattice of the smallest step over phase 0 when it has
 * more windows than asked for, else more phases while the budget lasts). */
static uint64_t job_exemplar_atoms(uint64_t n1, uint64_t FF, uint64_t atoms)
{
    uint64_t step = 1, side;
    if (n1 * FF <= atoms)
        return n1 * FF;
    if (n1 <= atoms)
        return atoms;
    while (n1 / (step * step) > atoms)
        step++;
    side = (uint64_t)sqrt((double)n1) / step + 1; /* a square exemplar's lattice, rounded up */
    return side * side < atoms ? side * side : atoms;
}

/* The memory a dictionary takes while it is built from the job's exemplars
 * with cells of out_area square metres, added to *need: each exemplar as read
 * and at that resolution, its low-resolution sources, and the atoms (an
 * exemplar gives at most the atoms asked for and at most one per cell at the
 * output's resolution: F x F phases of (cells / F^2) windows; one phase on a
 * lattice when it alone has more windows than atoms asked for).  A warning for
 * an exemplar much coarser than the output.  *dict_bytes (may be NULL): the
 * atoms' part alone. */
static int job_dictionary_need(const tsjob_amplify *job, double out_area, uint64_t *need,
                               uint64_t *dict_bytes, tsio_err *warning, tsio_err *err)
{
    const ts_amplify_params *p = &job->params;
    uint64_t atoms_total = 0, biggest = 0, pp = (uint64_t)p->patch * p->patch;
    uint64_t FF = (uint64_t)p->factor * p->factor, atom;
    int i;
    for (i = 0; i < job->n_exemplars; i++) {
        uint64_t src, tgt;
        double ratio;
        if (tsjob__exemplar_cells(job->exemplars[i], out_area, job->cell_size, &src, &tgt, &ratio,
                                  err) != 0)
            return -1;
        atoms_total += job_exemplar_atoms(tgt / FF, FF, (uint64_t)p->atoms);
        *need += src * 4 + tgt * 16; /* as read, and at the output's resolution */
        *need += tgt * 12;           /* the phases' low-resolution sources and drainage */
        *need += (src * 4 + tgt * 8) * (uint64_t)job->n_layers; /* its layers, read one by one */
        if (job->exemplar_classes[i])
            *need += src * 4 + tgt * 8;
        if (src > biggest)
            biggest = src;
        if (ratio > 4.0 && warning && !warning->msg[0])
            tsio_errf(warning, job->exemplars[i],
                      "its cells are %.1f times the output's on the ground: its detail is "
                      "interpolated, not real (an exemplar at the output's resolution or finer "
                      "gives real detail)",
                      sqrt(ratio));
    }
    *need += biggest * JOB_MEM_EX_SOURCE_CELL;
    /* an atom: three low-resolution descriptors (and the irradiance's), its
     * detail, the layers' and classes' detail, its place and sorted keys */
    atom = pp * 4 * (3 + (p->w_l > 0 ? 1 : 0)) + pp * FF * 4 * (1 + (uint64_t)job->n_layers) +
           (job->exemplar_classes[0] ? pp * FF + 4 * TS_MAX_CLASSES : 0) + 80;
    *need += atoms_total * atom;
    if (dict_bytes)
        *dict_bytes = atoms_total * atom;
    return 0;
}

int tsjob_amplify_prepare(const tsjob_amplify *job, tsjob_amplify_result *res, tsio_err *err)
{
    tsio_georef g;
    const ts_amplify_params *p = &job->params;
    uint64_t need, cells_out;
    double *dx = NULL, *dy = NULL, out_area = 0;
    int F = p->factor, rc;
    memset(res, 0, sizeof *res);
    if (tsio_read_georef(job->input, &g, err) != 0)
        return -1;
    cells_out = (uint64_t)g.width * F * (uint64_t)g.height * F;
    /* served window by window, the output is never whole in memory */
    need = JOB_MEM_BASE + (uint64_t)g.width * g.height * 48 + (job->lazy ? 0 : cells_out * 8);
    /* the carried layers and classes on the output (at most every layer a dictionary holds) */
    if (!job->lazy && job->n_out_layers)
        need += cells_out * 4 * (uint64_t)(job->dictionary ? TS_MAX_LAYERS : job->n_layers);
    if (!job->lazy && job->want_classes)
        need += cells_out * 5;
    need += (uint64_t)g.width * g.height * 4 * (uint64_t)job->n_biomes; /* their weights */
    if (job->n_biomes > 1 && !job->lazy) /* a reconstruction per biome */
        need += cells_out * 4 * (uint64_t)job->n_biomes;
    /* the ground size of an output cell, to count the exemplars' cells at it */
    if (tsio_georef_metrics(&g, &dx, &dy, err) == 0 && dx)
        out_area = dx[g.height / 2] * dy[g.height / 2] / ((double)F * F);
    else if (job->cell_size > 0)
        out_area = job->cell_size * job->cell_size / ((double)F * F);
    free(dx);
    free(dy);
    /* before the warning on coarse exemplars, which a cell size taken wrongly causes */
    tsjob__warn_cell_sizes(&res->warning, job->cell_size, job->input, &g,
                           (const char *const *)job->exemplars, job->n_exemplars);
    tsio_georef_free(&g);
    if (job_dictionary_need(job, out_area, &need, NULL, &res->warning, err) != 0)
        return -1;
    if (tsio_check_memory(need, "amplify",
                          "a smaller input, a smaller factor, fewer atoms or "
                          "exemplars nearer the output's resolution",
                          err) != 0)
        return -1;
    {
        tsio_err keep = res->warning;
        if (tsio_read_dem(job->input, job->band, &res->in, err) != 0)
            return -1;
        res->warning = keep;
    }
    tsjob__warn_sentinels(&res->warning, job->input, &res->in);
    if (res->in.geo.width < p->patch || res->in.geo.height < p->patch) {
        tsio_errf(err, job->input, "%d x %d cells is smaller than a patch (%d cells)",
                  res->in.geo.width, res->in.geo.height, p->patch);
        tsjob_amplify_result_free(res);
        return -1;
    }
    rc = tsio_georef_make(res->in.geo.width * F, res->in.geo.height * F, res->in.geo.gt[0],
                          res->in.geo.gt[3], fabs(res->in.geo.gt[1]) / F,
                          fabs(res->in.geo.gt[5]) / F, res->in.geo.wkt, &res->geo, err);
    if (rc != 0) {
        tsjob_amplify_result_free(res);
        return -1;
    }
    res->geo.has_gt = res->in.geo.has_gt;
    if (p->w_l > 0 && !res->in.dx_m) {
        tsio_errf(err, job->input,
                  "has no CRS: the irradiance term (w_l) needs each cell's latitude");
        tsjob_amplify_result_free(res);
        return -1;
    }
    if (job->classes) {
        if (tsio_read_raster(job->classes, 1, &res->classes, err) != 0) {
            tsjob_amplify_result_free(res);
            return -1;
        }
        if (tsio_same_grid(job->classes, "the class raster", &res->classes.geo, &res->in.geo,
                           "input", err) != 0) {
            tsjob_amplify_result_free(res);
            return -1;
        }
        if (job_check_class_codes(job->classes, &res->classes.r, err) != 0) {
            tsjob_amplify_result_free(res);
            return -1;
        }
    }
    return 0;
}

/* A dictionary file: "TSDFILE1", f64 metres per output cell (little-endian), then the
 * core's bytes (ts_dictionary_to_bytes). */
#define DICT_FILE_MAGIC "TSDFILE1"
#define DICT_FILE_HEAD 16

int tsjob_dictionary_read(ts_ctx *ctx, const char *path, ts_dictionary **dict, double *resolution,
                          tsio_err *err)
{
    unsigned char *b = NULL;
    size_t len = 0;
    uint64_t bits = 0, limit;
    int k, from_option, rc = -1;
    *dict = NULL;
    /* the file and its dictionary both in memory, at most */
    if (tsio_memory_limit(&limit, &from_option, err) != 0)
        return -1;
    if (tsio_read_bytes(path, (size_t)(limit / 2), &b, &len, err) != 0)
        return -1;
    if (len < DICT_FILE_HEAD || memcmp(b, DICT_FILE_MAGIC, 8) != 0) {
        tsio_errf(err, path, "not a TerraSynth dictionary (made by terrasynth dictionary build)");
        goto done;
    }
    for (k = 7; k >= 0; k--)
        bits = bits << 8 | b[8 + k];
    memcpy(resolution, &bits, 8);
    if (!(*resolution > 0) || *resolution > 1e7) {
        tsio_errf(err, path, "damaged: no usable resolution");
        goto done;
    }
    if (ts_dictionary_from_bytes(ctx, b + DICT_FILE_HEAD, len - DICT_FILE_HEAD, dict) != TS_OK) {
        tsio_errf(err, path, "%s", ts_ctx_message(ctx));
        goto done;
    }
    rc = 0;
done:
    free(b);
    return rc;
}

int tsjob_amplify_adopt_dictionary(tsjob_amplify *job, tsio_err *err)
{
    unsigned char h[DICT_FILE_HEAD + 24];
    int got, factor, patch, b, n = job->n_biomes ? job->n_biomes : 1;
    int shape_given = job->shape_given;
    if (!job->dictionary && !job->n_biomes)
        return 0;
    for (b = 0; b < n; b++) {
        const char *path = job->n_biomes ? job->biome_dicts[b] : job->dictionary;
        got = tsio_read_head(path, h, sizeof h, err);
        if (got < 0)
            return -1;
        if (got >= 8 && !memcmp(h, DICT_FILE_MAGIC, 8) && got < (int)sizeof h) {
            tsio_errf(err, path, "damaged: cut to %d bytes (a dictionary's header alone has %d)",
                      got, (int)sizeof h);
            return -1;
        }
        if (got < (int)sizeof h || memcmp(h, DICT_FILE_MAGIC, 8) != 0 ||
            memcmp(h + DICT_FILE_HEAD, "TSDICT\r\n", 8) != 0) {
            tsio_errf(err, path,
                      "not a TerraSynth dictionary (made by terrasynth dictionary build)");
            return -1;
        }
        factor = (int)((uint32_t)h[DICT_FILE_HEAD + 12] | (uint32_t)h[DICT_FILE_HEAD + 13] << 8 |
                       (uint32_t)h[DICT_FILE_HEAD + 14] << 16 |
                       (uint32_t)(h[DICT_FILE_HEAD + 15] & 0x7f) << 24);
        patch = (int)((uint32_t)h[DICT_FILE_HEAD + 16] | (uint32_t)h[DICT_FILE_HEAD + 17] << 8 |
                      (uint32_t)h[DICT_FILE_HEAD + 18] << 16 |
                      (uint32_t)(h[DICT_FILE_HEAD + 19] & 0x7f) << 24);
        /* the ranges the format allows (ts_dictionary_from_bytes checks them again with
         * the contents), before anything is estimated from them */
        if (factor < 2 || factor > 16 || patch < 4 || patch > 64) {
            tsio_errf(err, path,
                      "damaged: its header says factor %d and patch %d (a dictionary "
                      "has factor 2..16 and patch 4..64)",
                      factor, patch);
            return -1;
        }
        if (shape_given && (factor != job->params.factor || patch != job->params.patch)) {
            tsio_errf(err, path,
                      "was built for factor %d and patch %d, not %d and %d: give %s, or "
                      "build another",
                      factor, patch, job->params.factor, job->params.patch,
                      b ? "dictionaries of one factor and patch" : "neither");
            return -1;
        }
        job->params.factor = factor;
        job->params.patch = patch;
        shape_given = 1; /* the other biomes' must be the same */
    }
    return 0;
}

/* Is `layer` on the grid of `exemplar` (as the files are, before any resampling)? */
static int job_same_grid(const char *layer, const char *exemplar, tsio_err *err)
{
    tsio_georef a, b;
    int same, k;
    if (tsio_read_georef(layer, &a, err) != 0)
        return -1;
    if (tsio_read_georef(exemplar, &b, err) != 0) {
        tsio_georef_free(&a);
        return -1;
    }
    same = a.width == b.width && a.height == b.height && a.has_gt == b.has_gt;
    for (k = 0; k < 6 && same; k++)
        same = fabs(a.gt[k] - b.gt[k]) <= 1e-9 * (fabs(b.gt[k]) + fabs(b.gt[1]) + 1e-300);
    if (!same)
        tsio_errf(err, layer, "is not on the grid of its exemplar %s (%d x %d cells)", exemplar,
                  b.width, b.height);
    tsio_georef_free(&a);
    tsio_georef_free(&b);
    return same ? 0 : -1;
}

/* One exemplar with everything the dictionary takes from it. */
typedef struct job_exemplar {
    tsio_raster dem, classes, layers[TS_MAX_LAYERS];
    ts_raster layer_views[TS_MAX_LAYERS], lat, north;
} job_exemplar;

static void job_exemplar_free(job_exemplar *e)
{
    int l;
    tsio_raster_free(&e->dem);
    tsio_raster_free(&e->classes);
    for (l = 0; l < TS_MAX_LAYERS; l++)
        tsio_raster_free(&e->layers[l]);
    ts_raster_free(&e->lat);
    ts_raster_free(&e->north);
}

/* Exemplar i of the job read at dx x dy metres per cell (0: as it is), its
 * layers and classes on the same cells, and with the irradiance term its
 * latitude and north on the grid the dictionary averages it to. */
static int job_read_exemplar(ts_ctx *ctx, const tsjob_amplify *job, int i, double dx, double dy,
                             job_exemplar *je, ts_exemplar *te, tsio_err *err)
{
    const char *path = job->exemplars[i];
    int l, F = job->params.factor;
    double f = 1.0;
    memset(te, 0, sizeof *te);
    if (tsio_read_raster_resampled(path, job->band, dx, dy, job->cell_size, &je->dem, &f, err) != 0)
        return -1;
    te->dem = je->dem.r;
    if (je->dem.dx_m) {
        te->dx = je->dem.dx_m[je->dem.geo.height / 2];
        te->dy = je->dem.dy_m[je->dem.geo.height / 2];
    }
    for (l = 0; l < job->n_layers; l++) {
        const char *lp = job->layer_files[i][l];
        if (job_same_grid(lp, path, err) != 0 ||
            tsio_read_raster_resampled(lp, 1, dx, dy, job->cell_size, &je->layers[l], &f, err) != 0)
            return -1;
        if (je->layers[l].geo.width != je->dem.geo.width ||
            je->layers[l].geo.height != je->dem.geo.height) {
            tsio_errf(err, lp, "is not on the grid of its exemplar %s", path);
            return -1;
        }
        je->layer_views[l] = je->layers[l].r;
    }
    if (job->n_layers)
        te->layers = je->layer_views;
    if (job->exemplar_classes[i]) {
        const char *cp = job->exemplar_classes[i];
        if (job_same_grid(cp, path, err) != 0 ||
            tsio_read_classes_resampled(cp, 1, dx, dy, job->cell_size, &je->classes, err) != 0)
            return -1;
        if (je->classes.geo.width != je->dem.geo.width ||
            je->classes.geo.height != je->dem.geo.height) {
            tsio_errf(err, cp, "is not on the grid of its exemplar %s", path);
            return -1;
        }
        if (job_check_class_codes(cp, &je->classes.r, err) != 0)
            return -1;
        te->classes = &je->classes.r;
    }
    if (job->params.w_l > 0 && je->dem.dx_m) {
        int lw = je->dem.geo.width / F, lh = je->dem.geo.height / F, rc;
        if (lw < 1 || lh < 1)
            return 0; /* too small: the core says so */
        if (ts_raster_alloc(ctx, lw, lh, &je->lat) != TS_OK ||
            ts_raster_alloc(ctx, lw, lh, &je->north) != TS_OK) {
            tsio_errf(err, path, "%s", ts_ctx_message(ctx));
            return -1;
        }
        rc = tsio_georef_sun_frame(&je->dem.geo, F, &je->lat, &je->north, err);
        if (rc < 0) {
            tsio_errf(err, path, "%s", err->msg);
            return -1;
        }
        if (rc == 0) {
            te->lat = &je->lat;
            te->north = &je->north;
        }
    }
    return 0;
}

/* The exemplars read at dx x dy metres per cell (0: as they are), and the
 * dictionary built from them.  With `warning`, sentinel cells are reported
 * there and *no_crs gets the index+1 of an exemplar used cell for cell. */
static int job_build_dictionary(ts_ctx *ctx, const tsjob_amplify *job, double dx, double dy,
                                const char *what, ts_dictionary **dict, tsio_err *warning,
                                int *no_crs, double *seconds, tsio_err *err)
{
    job_exemplar *ex = calloc(TSJOB_MAX_EXEMPLARS, sizeof *ex);
    ts_exemplar te[TSJOB_MAX_EXEMPLARS];
    const char *names[TS_MAX_LAYERS];
    struct timespec t0, t1;
    int i, rc = -1;
    if (!ex) {
        tsio_errf(err, what, "out of memory");
        return -1;
    }
    for (i = 0; i < job->n_layers; i++)
        names[i] = job->layer_names[i];
    for (i = 0; i < job->n_exemplars; i++) {
        if (job_read_exemplar(ctx, job, i, dx, dy, &ex[i], &te[i], err) != 0)
            goto done;
        if (warning)
            tsjob__warn_sentinels(warning, job->exemplars[i], &ex[i].dem);
        if (no_crs && dx > 0 && !ex[i].dem.dx_m && !*no_crs)
            *no_crs = i + 1;
    }
    clock_gettime(CLOCK_MONOTONIC, &t0);
    ts_status bst =
        ts_dictionary_build(ctx, te, job->n_exemplars, names, job->n_layers, &job->params, dict);
    if (bst != TS_OK) {
        int bad = ts_ctx_failed_input(ctx);
        if (bad < 0 && job->n_exemplars == 1 && bst == TS_ERR_NUMERIC)
            bad = 0; /* no atom from one exemplar: that file is at fault */
        tsio_errf(err, bad >= 0 && bad < job->n_exemplars ? job->exemplars[bad] : what, "%s",
                  ts_ctx_message(ctx));
        goto done;
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (seconds)
        *seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    rc = 0;
done:
    for (i = 0; i < job->n_exemplars; i++)
        job_exemplar_free(&ex[i]);
    free(ex);
    return rc;
}

/* Every file an amplify (or dictionary) job reads; returns the count. */
#define JOB_AMP_MAX_INPUTS (TSJOB_MAX_EXEMPLARS * (2 + TS_MAX_LAYERS) + 2 * TSJOB_MAX_BIOMES + 3)
static int job_amplify_inputs(const tsjob_amplify *job, const char **in)
{
    int n = 0, i, l;
    in[n++] = job->input;
    in[n++] = job->dictionary;
    in[n++] = job->classes;
    for (i = 0; i < job->n_biomes; i++) {
        in[n++] = job->biome_dicts[i];
        in[n++] = job->biome_weights[i];
    }
    for (i = 0; i < job->n_exemplars; i++) {
        in[n++] = job->exemplars[i];
        in[n++] = job->exemplar_classes[i];
        for (l = 0; l < job->n_layers; l++)
            in[n++] = job->layer_files[i][l];
    }
    return n;
}

int tsjob_dictionary_build(ts_ctx *ctx, const tsjob_amplify *job, const char *path, size_t *n_atoms,
                           tsio_err *err)
{
    const char *in[JOB_AMP_MAX_INPUTS];
    int n = job_amplify_inputs(job, in), k, rc = -1;
    ts_dictionary *dict = NULL;
    unsigned char head[DICT_FILE_HEAD], *bytes = NULL;
    size_t len = 0;
    uint64_t bits, need = 0, dict_need;
    /* the destination and the memory, before the work: the dictionary and its
     * file's bytes are both held while it is written */
    if (tsjob__not_an_input(path, in, n, err) ||
        tsio_write_bytes(path, NULL, 0, NULL, 0, 1, err) != 0 ||
        job_dictionary_need(job, job->resolution * job->resolution, &need, &dict_need, NULL,
                            err) != 0)
        return -1;
    if (tsio_check_memory(JOB_MEM_BASE + need + dict_need, "dictionary",
                          "a coarser resolution, fewer atoms (--atoms), fewer exemplars or a "
                          "smaller factor",
                          err) != 0)
        return -1;
    if (job_build_dictionary(ctx, job, job->resolution, job->resolution, "dictionary", &dict, NULL,
                             NULL, NULL, err) != 0)
        goto done;
    if (ts_dictionary_to_bytes(ctx, dict, &bytes, &len) != TS_OK) {
        tsio_errf(err, path, "%s", ts_ctx_message(ctx));
        goto done;
    }
    memcpy(head, DICT_FILE_MAGIC, 8);
    memcpy(&bits, &job->resolution, 8);
    for (k = 0; k < 8; k++)
        head[8 + k] = (unsigned char)(bits >> (8 * k));
    if (tsio_write_bytes(path, head, sizeof head, bytes, len, 0, err) != 0)
        goto done;
    *n_atoms = ts_dictionary_size(dict);
    rc = 0;
done:
    free(bytes);
    ts_dictionary_free(dict);
    return rc;
}

/* A warning for the wanted class codes no atom holds: their cells are matched
 * as unlabelled, which the user would not guess. */
static void job_warn_missing_classes(const tsjob_amplify *job, tsjob_amplify_result *res)
{
    unsigned char seen[TS_MAX_CLASSES + 1] = {0};
    char list[256] = "";
    const ts_raster *c = &res->classes.r;
    int x, y, k, n = 0;
    for (y = 0; y < c->height; y++)
        for (x = 0; x < c->width; x++) {
            float v = TS_PIX(c, x, y);
            if (v >= 1.0f && v <= (float)TS_MAX_CLASSES)
                seen[(int)v] = 1;
        }
    for (k = 1; k <= TS_MAX_CLASSES; k++)
        if (seen[k] && ts_dictionary_class_atoms(res->dict, k) == 0) {
            if (strlen(list) < sizeof list - 16)
                snprintf(list + strlen(list), sizeof list - strlen(list), "%s%d", n ? ", " : "", k);
            n++;
        }
    if (n && !res->warning.msg[0])
        tsio_errf(&res->warning, job->classes,
                  "no atom holds class%s %s: %s cells are matched as unlabelled (label those "
                  "classes in exemplar_classes)",
                  n > 1 ? "es" : "", list, n > 1 ? "their" : "its");
}

/* After the dictionary: the input's irradiance (with w_l), the layers and
 * classes asked for found in the dictionary. */
static int job_amplify_frame(ts_ctx *ctx, const tsjob_amplify *job, tsjob_amplify_result *res,
                             tsio_err *err)
{
    int L, K, has_l, i, l;
    ts_dictionary_layers(res->dict, &L, &K, &has_l);
    if (job->params.w_l > 0) {
        ts_raster lat = {0, 0, 0, NULL}, north = {0, 0, 0, NULL};
        ts_grid_metrics m;
        int rc = -1;
        if (!has_l) {
            tsio_errf(err, job->dictionary ? job->dictionary : job->input,
                      "the dictionary was built without the irradiance: build it with w_l > 0");
            return -1;
        }
        if (ts_raster_alloc(ctx, res->in.r.width, res->in.r.height, &lat) != TS_OK ||
            ts_raster_alloc(ctx, res->in.r.width, res->in.r.height, &north) != TS_OK ||
            ts_raster_alloc(ctx, res->in.r.width, res->in.r.height, &res->irr) != TS_OK)
            tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        else if (tsio_georef_sun_frame(&res->in.geo, 1, &lat, &north, err) != 0)
            tsio_errf(err, job->input, "%s", err->msg[0] ? err->msg : "has no CRS: no latitude");
        else if (ts_irradiance(ctx, &res->in.r, tsio_metrics(&res->in, &m), &lat, &north,
                               &res->irr) != TS_OK)
            tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        else
            rc = 0;
        ts_raster_free(&lat);
        ts_raster_free(&north);
        if (rc != 0)
            return -1;
    }
    for (i = 0; i < job->n_out_layers; i++) {
        for (l = 0; l < L; l++)
            if (!strcmp(ts_dictionary_layer_name(res->dict, l), job->out_layer_names[i]))
                break;
        if (l == L) {
            char have[TS_MAX_LAYERS * (TS_LAYER_NAME + 2) + 8] = "";
            for (l = 0; l < L; l++)
                snprintf(have + strlen(have), sizeof have - strlen(have), "%s%s", l ? ", " : "",
                         ts_dictionary_layer_name(res->dict, l));
            tsio_errf(err, job->dictionary ? job->dictionary : job->exemplars[0],
                      "out_layer %s: the atoms carry no layer %s (they carry: %s)",
                      job->out_layer_names[i], job->out_layer_names[i], L ? have : "none");
            return -1;
        }
        res->layer_of[i] = l;
    }
    if (job->want_classes && K == 0) {
        tsio_errf(err, job->dictionary ? job->dictionary : job->exemplars[0],
                  "out_classes: the atoms have no classes (give exemplar_classes)");
        return -1;
    }
    if (job->classes && K == 0) {
        tsio_errf(err, job->classes,
                  "wanted classes, but the atoms have none (give exemplar_classes)");
        return -1;
    }
    if (job->classes)
        job_warn_missing_classes(job, res);
    return 0;
}

int tsjob_amplify_setup(ts_ctx *ctx, const tsjob_amplify *job, tsjob_amplify_result *res,
                        tsio_err *err)
{
    int cy = res->in.geo.height / 2, F = job->params.factor;
    double in_dx = res->in.dx_m ? res->in.dx_m[cy] : job->cell_size;
    double in_dy = res->in.dy_m ? res->in.dy_m[cy] : job->cell_size;
    res->drainage = job->drainage;
    if (job->n_biomes) {
        int b;
        for (b = 0; b < job->n_biomes; b++) {
            double dres;
            if (tsjob_dictionary_read(ctx, job->biome_dicts[b], &res->biome_dicts[b], &dres, err) !=
                0)
                return -1;
            if (in_dx > 0 && fabs(sqrt(in_dx * in_dy) / F / dres - 1.0) > 0.02) {
                tsio_errf(err, job->biome_dicts[b],
                          "was built for cells of %.6g m; this input at factor %d gives cells "
                          "of %.6g m: build one for them (terrasynth dictionary build "
                          "--resolution)",
                          dres, F, sqrt(in_dx * in_dy) / F);
                return -1;
            }
            res->n_atoms += ts_dictionary_size(res->biome_dicts[b]);
            if (tsio_read_raster(job->biome_weights[b], 1, &res->biome_w[b], err) != 0)
                return -1;
            if (res->biome_w[b].geo.width != res->in.geo.width ||
                res->biome_w[b].geo.height != res->in.geo.height) {
                tsio_errf(err, job->biome_weights[b],
                          "the weights are %d x %d cells, the input %d x %d",
                          res->biome_w[b].geo.width, res->biome_w[b].geo.height, res->in.geo.width,
                          res->in.geo.height);
                return -1;
            }
            {
                size_t k, n = (size_t)res->in.geo.width * (size_t)res->in.geo.height;
                for (k = 0; k < n; k++) /* nodata: no weight */
                    if (isnan(res->biome_w[b].r.data[k]))
                        res->biome_w[b].r.data[k] = 0.0f;
            }
        }
        res->dict = res->biome_dicts[0];
        goto drainage;
    }
    if (job->dictionary) {
        double dres;
        if (tsjob_dictionary_read(ctx, job->dictionary, &res->dict, &dres, err) != 0)
            return -1;
        if (in_dx > 0 && fabs(sqrt(in_dx * in_dy) / F / dres - 1.0) > 0.02) {
            tsio_errf(err, job->dictionary,
                      "was built for cells of %.6g m; this input at factor %d gives cells of "
                      "%.6g m: build one for them (terrasynth dictionary build --resolution)",
                      dres, F, sqrt(in_dx * in_dy) / F);
            return -1;
        }
        res->n_atoms = ts_dictionary_size(res->dict);
        goto drainage;
    }
    if (job_build_dictionary(ctx, job, in_dx > 0 ? in_dx / F : 0, in_dy > 0 ? in_dy / F : 0,
                             "amplify", &res->dict, &res->warning, &res->exemplar_no_crs,
                             &res->seconds_dictionary, err) != 0)
        return -1;
    res->n_atoms = ts_dictionary_size(res->dict);
    if (res->n_atoms < 256 && !res->warning.msg[0])
        tsio_errf(&res->warning, job->exemplars[0],
                  "only %zu atoms: the exemplars cover little ground at the output's resolution "
                  "(%.3g m), so their patterns repeat; give larger exemplars",
                  res->n_atoms, in_dx > 0 ? in_dx / F : 0.0);
drainage:
    /* the automatic bank slope from the input (what exemplars, a dictionary and biomes
     * share), its gradients per the factor's finer cells */
    if (res->drainage.bank_slope == -1)
        res->drainage.bank_slope = ts_drainage_bank_slope_auto(&res->in.r, 1) / F;
    if (ts_raster_alloc(ctx, res->in.r.width, res->in.r.height, &res->drain) != TS_OK ||
        ts_drainage_area(ctx, &res->in.r, &res->drain) != TS_OK) {
        tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        return -1;
    }
    return job_amplify_frame(ctx, job, res, err);
}

static ts_amplify_guide job_amplify_guide(const tsjob_amplify *job, const tsjob_amplify_result *res)
{
    ts_amplify_guide g;
    g.drainage = &res->drain;
    g.irradiance = job->params.w_l > 0 ? &res->irr : NULL;
    g.classes = res->classes.r.data ? &res->classes.r : NULL;
    return g;
}

/* The biomes' amplification of the window at x0, y0 (NaN in weights: 0). */
static ts_status job_amplify_biomes(ts_ctx *ctx, const tsjob_amplify *job,
                                    const tsjob_amplify_result *res, int x0, int y0, ts_raster *out,
                                    ts_amplify_info *info)
{
    ts_raster w[TSJOB_MAX_BIOMES];
    const ts_dictionary *d[TSJOB_MAX_BIOMES];
    ts_amplify_guide g = job_amplify_guide(job, res);
    int b;
    for (b = 0; b < job->n_biomes; b++) {
        w[b] = res->biome_w[b].r;
        d[b] = res->biome_dicts[b];
    }
    return ts_amplify_biomes(ctx, &res->in.r, &g, d, w, job->n_biomes, &job->params, x0, y0, out,
                             info);
}

static int amplify_raw_window(ts_ctx *ctx, const tsjob_amplify *job,
                              const tsjob_amplify_result *res, int x0, int y0, int w, int h,
                              int serve, float *out, tsio_err *err)
{
    ts_raster o = ts_raster_wrap(out, w, h, w), dem = {0, 0, 0, NULL}, cls = {0, 0, 0, NULL};
    ts_raster layers[TS_MAX_LAYERS];
    ts_amplify_guide g = job_amplify_guide(job, res);
    ts_amplify_layers lay = {NULL, NULL};
    int L = 0, l, rc = -1;
    memset(layers, 0, sizeof layers);
    if (serve != TSJOB_SERVE_DEM) {
        /* the DEM computed aside, the layers (every one the atoms carry) or classes kept */
        ts_dictionary_layers(res->dict, &L, NULL, NULL);
        if (ts_raster_alloc(ctx, w, h, &dem) != TS_OK)
            goto done;
        if (serve == TSJOB_SERVE_CLASSES) {
            cls = o;
            lay.classes = &cls;
        } else {
            for (l = 0; l < L; l++)
                if (l == res->layer_of[serve])
                    layers[l] = o;
                else if (ts_raster_alloc(ctx, w, h, &layers[l]) != TS_OK)
                    goto done;
            lay.layers = layers;
        }
    }
    if (job->n_biomes ? job_amplify_biomes(ctx, job, res, x0, y0, &o, NULL)
                      : ts_amplify_window(ctx, &res->in.r, &g, res->dict, &job->params, x0, y0,
                                          serve == TSJOB_SERVE_DEM ? &o : &dem, &lay, NULL))
        goto done;
    rc = 0;
done:
    if (rc != 0)
        tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
    ts_raster_free(&dem);
    for (l = 0; l < L; l++)
        if (serve < 0 || l != res->layer_of[serve])
            ts_raster_free(&layers[l]);
    return rc;
}

typedef struct amplify_raw_arg {
    const tsjob_amplify *job;
    const tsjob_amplify_result *res;
} amplify_raw_arg;

/* The DEM's window before the drainage stage (a tsjob_raw_fn). */
static int amplify_raw(void *arg, ts_ctx *ctx, int x0, int y0, int w, int h, float *out,
                       unsigned char *flags, tsio_err *err)
{
    const amplify_raw_arg *a = arg;
    (void)flags;
    return amplify_raw_window(ctx, a->job, a->res, x0, y0, w, h, TSJOB_SERVE_DEM, out, err);
}

int tsjob_amplify_window_raw(ts_ctx *ctx, const tsjob_amplify *job, const tsjob_amplify_result *res,
                             int x0, int y0, int w, int h, float *out, tsio_err *err)
{
    return amplify_raw_window(ctx, job, res, x0, y0, w, h, TSJOB_SERVE_DEM, out, err);
}

int tsjob_amplify_window(ts_ctx *ctx, const tsjob_amplify *job, const tsjob_amplify_result *res,
                         int x0, int y0, int w, int h, int serve, float *out, tsio_err *err)
{
    amplify_raw_arg a;
    if (serve != TSJOB_SERVE_DEM) /* the layers and classes as the atoms carry them */
        return amplify_raw_window(ctx, job, res, x0, y0, w, h, serve, out, err);
    a.job = job;
    a.res = res;
    return tsjob_drained_window(ctx, &res->drainage, res->geo.width, res->geo.height, x0, y0, w, h,
                                amplify_raw, &a, out, job->input, err);
}

int tsjob_amplify_compute(ts_ctx *ctx, const tsjob_amplify *job, tsjob_amplify_result *res,
                          tsio_err *err)
{
    job_progress jp;
    ts_amplify_layers lay = {NULL, NULL};
    ts_amplify_guide g;
    int rc = -1;
    ts_ctx_get_progress(ctx, &jp.fn, &jp.user);
    tsjob__progress_range(ctx, &jp, 0.0, 0.2);
    if (tsjob_amplify_setup(ctx, job, res, err) != 0)
        goto done;
    if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out) != TS_OK) {
        tsio_errf(err, "amplify", "%s", ts_ctx_message(ctx));
        goto done;
    }
    if (job->n_out_layers) {
        int L, l;
        ts_dictionary_layers(res->dict, &L, NULL, NULL);
        for (l = 0; l < L; l++)
            if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->layers[l]) != TS_OK) {
                tsio_errf(err, "amplify", "%s", ts_ctx_message(ctx));
                goto done;
            }
        lay.layers = res->layers;
    }
    if (job->want_classes) {
        if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out_classes) != TS_OK) {
            tsio_errf(err, "amplify", "%s", ts_ctx_message(ctx));
            goto done;
        }
        lay.classes = &res->out_classes;
    }
    g = job_amplify_guide(job, res);
    tsjob__progress_range(ctx, &jp, 0.2, 0.95);
    if ((job->n_biomes ? job_amplify_biomes(ctx, job, res, 0, 0, &res->out, &res->info)
                       : ts_amplify_window(ctx, &res->in.r, &g, res->dict, &job->params, 0, 0,
                                           &res->out, &lay, &res->info)) != TS_OK) {
        tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        goto done;
    }
    /* the drainage stage on the whole DEM: the bytes of every drained window */
    tsjob__progress_range(ctx, &jp, 0.95, 1.0);
    {
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        if (tsjob_drain(ctx, &res->drainage, &res->out, NULL, 0, 0, res->geo.width, res->geo.height,
                        &res->drainage_info, job->input, err) != 0)
            goto done;
        clock_gettime(CLOCK_MONOTONIC, &t1);
        res->seconds_drainage =
            (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    }
    rc = 0;
done:
    ts_ctx_set_progress(ctx, jp.fn, jp.user);
    return rc;
}

void tsjob_amplify_result_free(tsjob_amplify_result *res)
{
    int l;
    for (l = 0; l < TS_MAX_LAYERS; l++)
        ts_raster_free(&res->layers[l]);
    ts_raster_free(&res->out_classes);
    ts_raster_free(&res->irr);
    tsio_raster_free(&res->classes);
    for (l = 0; l < TSJOB_MAX_BIOMES; l++) {
        if (res->biome_dicts[l] == res->dict)
            res->dict = NULL;
        ts_dictionary_free(res->biome_dicts[l]);
        tsio_raster_free(&res->biome_w[l]);
    }
    ts_dictionary_free(res->dict);
    ts_raster_free(&res->drain);
    tsio_raster_free(&res->in);
    tsio_georef_free(&res->geo);
    ts_raster_free(&res->out);
    memset(res, 0, sizeof *res);
}

int tsjob_amplify_check_recipe(const tsjob_amplify *job, const char *recipe, tsio_err *err)
{
    const char *in[JOB_AMP_MAX_INPUTS];
    int n = job_amplify_inputs(job, in);
    return tsjob__not_an_input(recipe, in, n, err) || tsio_check_output_file(recipe, err) ? -1 : 0;
}

int tsjob_amplify_check_outputs(const tsjob_amplify *job, const tsjob_amplify_result *res,
                                const tsjob_outputs *o, tsio_err *err)
{
    const char *in[JOB_AMP_MAX_INPUTS],
        *outs[3 + TS_MAX_LAYERS] = {o->output, o->preview, o->out_classes};
    int n = job_amplify_inputs(job, in), n_out = 3, l;
    float probe = 0;
    ts_raster pr = ts_raster_wrap(&probe, 1, 1, 1);
    unsigned char bp = 0;
    tsio_write_opts wo = {o->format, o->create_options, 1};
    tsio_write_opts png = {"PNG", NULL, 1};
    tsio_georef g1 = res->geo;
    g1.width = g1.height = 1;
    for (l = 0; o->out_layers && o->out_layers[l] && l < TS_MAX_LAYERS; l++)
        outs[n_out++] = strchr(o->out_layers[l], '=') + 1;
    for (l = 0; l < n_out; l++)
        if (tsjob__not_an_input(outs[l], in, n, err))
            return -1;
    if (tsjob__distinct(outs, n_out, err))
        return -1;
    if (tsio_write_float(o->output, &wo, &g1, &pr, TSIO_NODATA, err) != 0 ||
        (o->preview && tsio_write_byte(o->preview, &png, &g1, &bp, -1, err) != 0) ||
        (o->out_classes && tsio_write_byte(o->out_classes, &wo, &g1, &bp, -1, err) != 0))
        return -1;
    for (l = 3; l < n_out; l++)
        if (tsio_write_float(outs[l], &wo, &g1, &pr, TSIO_NODATA, err) != 0)
            return -1;
    if (tsjob__flow_check(o, in, n, outs, n_out, &res->geo, NULL, err) != 0)
        return -1;
    return tsjob__preview_name(o->preview, err);
}

int tsjob_amplify_write(ts_ctx *ctx, const tsjob_amplify_result *res, const tsjob_outputs *o,
                        tsio_err *err)
{
    tsio_write_opts wo = {o->format, o->create_options, 0};
    int l;
    if (tsio_write_float(o->output, &wo, &res->geo, &res->out, TSIO_NODATA, err) != 0)
        return -1;
    for (l = 0; o->out_layers && o->out_layers[l] && l < TS_MAX_LAYERS; l++)
        if (tsio_write_float(strchr(o->out_layers[l], '=') + 1, &wo, &res->geo,
                             &res->layers[res->layer_of[l]], TSIO_NODATA, err) != 0)
            return -1;
    if (o->out_classes) {
        size_t n = (size_t)res->geo.width * (size_t)res->geo.height, k;
        unsigned char *b = malloc(n ? n : 1);
        int rc;
        if (!b) {
            tsio_errf(err, o->out_classes, "out of memory");
            return -1;
        }
        for (k = 0; k < n; k++)
            b[k] = (unsigned char)res->out_classes.data[k];
        rc = tsio_write_byte(o->out_classes, &wo, &res->geo, b, -1, err);
        free(b);
        if (rc != 0)
            return -1;
    }
    if (o->preview) {
        /* the hillshade on the ground: cell sizes in metres (a geographic grid's too) */
        double *dx = NULL, *dy = NULL;
        ts_grid_metrics m;
        int rc;
        if (tsio_georef_metrics(&res->geo, &dx, &dy, err) != 0)
            return -1;
        m.dx = dx;
        m.dy = dy;
        rc = tsjob__preview(ctx, o->preview, &res->out, &res->geo, dx ? &m : NULL, NULL, err);
        free(dx);
        free(dy);
        if (rc != 0)
            return -1;
    }
    return tsjob__flow_write(ctx, o, &res->out, &res->geo, NULL, err);
}
