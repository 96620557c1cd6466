/*
 * job_synth_write.c - what the synth job writes: the DEM, its preview, the debug maps
 * and, with a sketch, its feature graph and the output's axes as lines.
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

/* Every file a synth job reads. */
int tsjob_synth_inputs(const tsjob_synth *job, const char **in)
{
    int n = 0, i;
    for (i = 0; i < job->n_exemplars; i++)
        in[n++] = job->exemplars[i];
    in[n++] = job->sketch;
    in[n++] = job->grid.like;
    in[n++] = job->water;
    in[n++] = job->regions;
    in[n++] = job->heights;
    for (i = 0; i < job->n_pins; i++)
        in[n++] = job->pins[i].path;
    return n;
}

int tsjob_synth_check_recipe(const tsjob_synth *job, const char *recipe, tsio_err *err)
{
    const char *in[TSJOB_MAX_INPUTS];
    int n = tsjob_synth_inputs(job, in);
    if (job->coarse_pass && !strcmp(job->coarse_pass, recipe)) {
        tsio_errf(err, recipe,
                  "is the recipe and its coarse pass (coarse_pass): give another name");
        return -1;
    }
    return tsjob__not_an_input(recipe, in, n, err) || tsio_check_output_file(recipe, err) ||
                   (job->coarse_pass && (tsjob__not_an_input(job->coarse_pass, in, n, err) ||
                                         tsio_check_output_file(job->coarse_pass, err)))
               ? -1
               : 0;
}

/* With a sketch, debug_dir also holds these (name, extension). */
enum { JOB_SKETCH_FEATURES, JOB_OUTPUT_FEATURES, JOB_VALLEY_FLOOR, JOB_N_SKETCH_DEBUG };
static const char *const job_sketch_debug[JOB_N_SKETCH_DEBUG][2] = {
    {"sketch_features", "gpkg"}, {"output_features", "gpkg"}, {"valley_floor", "tif"}};

/* The names of the debug maps (debug_dir/<name>.tif, the driver's MAP). */
const char *const tsjob_map_names[TSJOB_N_MAPS] = {"seams", "source_exemplar", "source_x",
                                                   "source_y", "order"};

const int32_t *tsjob_synth_int_map(const tsjob_synth_result *res, int map)
{
    if (!res->has_maps)
        return NULL;
    switch (map) {
    case TSJOB_MAP_SOURCE_EXEMPLAR:
        return res->maps.source_exemplar;
    case TSJOB_MAP_SOURCE_X:
        return res->maps.source_x;
    case TSJOB_MAP_SOURCE_Y:
        return res->maps.source_y;
    case TSJOB_MAP_ORDER:
        return res->maps.order;
    default:
        return NULL;
    }
}

int tsjob_synth_check_outputs(const tsjob_synth *job, const tsjob_synth_result *res,
                              const tsjob_outputs *o, tsio_err *err)
{
    const char *in[TSJOB_MAX_INPUTS];
    int n = tsjob_synth_inputs(job, in), i;
    float probe = 0;
    ts_raster pr = ts_raster_wrap(&probe, 1, 1, 1);
    unsigned char bp = 0;
    tsio_write_opts wo = {o->format, o->create_options, 1};
    tsio_write_opts png = {"PNG", NULL, 1};
    tsio_georef g1 = res->geo;
    g1.width = g1.height = 1;
    if (tsjob__not_an_input(o->output, in, n, err) || tsjob__not_an_input(o->preview, in, n, err))
        return -1;
    if (tsio_write_float(o->output, &wo, &g1, &pr, TSIO_NODATA, err) != 0 ||
        (o->preview && tsio_write_byte(o->preview, &png, &g1, &bp, -1, err) != 0))
        return -1;
    if (o->debug_dir && job->sketch && res->params.tiled > 0) {
        tsio_errf(err, o->debug_dir,
                  "a sketch in tiles makes no debug maps yet: make it in one piece (no tiled)");
        return -1;
    }
    if (o->debug_dir) {
        char paths[TSJOB_N_MAPS + JOB_N_SKETCH_DEBUG][4096];
        const char *outs[TSJOB_N_MAPS + JOB_N_SKETCH_DEBUG + 2];
        int k = 0;
        outs[k++] = o->output;
        outs[k++] = o->preview;
        if (tsio_make_dir(o->debug_dir, err) != 0)
            return -1;
        for (i = 0; i < TSJOB_N_MAPS + JOB_N_SKETCH_DEBUG; i++) {
            const char *const *sk = i < TSJOB_N_MAPS ? NULL : job_sketch_debug[i - TSJOB_N_MAPS];
            if (sk && !job->sketch)
                break;
            if (tsio_path(paths[i], sizeof paths[i], o->debug_dir, sk ? sk[0] : tsjob_map_names[i],
                          sk ? sk[1] : "tif", err) != 0 ||
                tsjob__not_an_input(paths[i], in, n, err) != 0)
                return -1;
            outs[k++] = paths[i];
        }
        if (tsjob__distinct(outs, k, err) != 0)
            return -1;
        for (i = 2; i < k; i++)
            if (tsio_check_output_file(outs[i], err) != 0)
                return -1;
    } else {
        const char *outs[2] = {o->output, o->preview};
        if (tsjob__distinct(outs, 2, err) != 0)
            return -1;
    }
    {
        const char *outs[2] = {o->output, o->preview};
        if (tsjob__flow_check(o, in, n, outs, 2, &res->geo, res->metrics, err) != 0)
            return -1;
    }
    return tsjob__preview_name(o->preview, err);
}

/* The path of a sketch debug file (job_sketch_debug[which]) in dir. */
static int job_sketch_path(char path[4096], const char *dir, int which, tsio_err *err)
{
    return tsio_path(path, 4096, dir, job_sketch_debug[which][0], job_sketch_debug[which][1], err);
}

/* With a sketch: its feature graph and the output's PPA axes as lines. */
static int job_debug_features(ts_ctx *ctx, const char *dir, const tsjob_synth_result *res,
                              tsio_err *err)
{
    ts_ppa_params pp = ts_ppa_params_default();
    ts_features *of = NULL;
    pp.min_drainage = 0; /* the axes as the synthesis sees them: by profile */
    char a[4096], b[4096];
    int rc = -1;
    if (job_sketch_path(a, dir, JOB_SKETCH_FEATURES, err) != 0 ||
        job_sketch_path(b, dir, JOB_OUTPUT_FEATURES, err) != 0)
        return -1;
    pp.features = res->sketch_info.mode == TS_SKETCH_BOTH      ? TS_PPA_BOTH
                  : res->sketch_info.mode == TS_SKETCH_VALLEYS ? TS_PPA_VALLEYS
                                                               : TS_PPA_RIDGES;
    if (res->sketch_features &&
        tsio_write_features(a, &res->geo, res->sketch_features, NULL, err) != 0)
        goto out;
    if (ts_ppa_extract(ctx, &res->out, res->metrics, &pp, &of) != TS_OK) {
        tsio_errf(err, b, "%s", ts_ctx_message(ctx));
        goto out;
    }
    if (tsio_write_features(b, &res->geo, of, res->metrics, err) != 0)
        goto out;
    rc = 0;
out:
    ts_features_free(of);
    return rc;
}

int tsjob_synth_write(ts_ctx *ctx, const tsjob_synth *job, const tsjob_synth_result *res,
                      const tsjob_outputs *o, tsio_err *err)
{
    tsio_write_opts wo = {o->format, o->create_options, 0};
    if (tsio_write_float(o->output, &wo, &res->geo, &res->out, TSIO_NODATA, err) != 0)
        return -1;
    if (o->preview &&
        tsjob__preview(ctx, o->preview, &res->out, &res->geo, res->metrics, NULL, err) != 0)
        return -1;
    if (tsjob__flow_write(ctx, o, &res->out, &res->geo, res->metrics, err) != 0)
        return -1;
    if (o->debug_dir && res->has_maps) {
        const ts_synth_maps *m = &res->maps;
        size_t n = (size_t)res->geo.width * (size_t)res->geo.height;
        float *tmp = malloc(n * sizeof *tmp);
        char path[4096];
        int bad;
        if (!tmp) {
            tsio_errf(err, o->debug_dir, "out of memory");
            return -1;
        }
        int i;
        bad = tsio_path(path, sizeof path, o->debug_dir, tsjob_map_names[TSJOB_MAP_SEAMS], "tif",
                        err) != 0 ||
              tsio_write_byte(path, NULL, &res->geo, m->seams, -1, err) != 0;
        for (i = TSJOB_MAP_SOURCE_EXEMPLAR; i < TSJOB_N_MAPS && !bad; i++)
            bad = tsjob__int_map(o->debug_dir, tsjob_map_names[i], &res->geo,
                                 tsjob_synth_int_map(res, i), tmp, err) != 0;
        free(tmp);
        if (bad)
            return -1;
        if (job->sketch && job_debug_features(ctx, o->debug_dir, res, err) != 0)
            return -1;
        if (job->sketch && m->valley_floor &&
            (job_sketch_path(path, o->debug_dir, JOB_VALLEY_FLOOR, err) != 0 ||
             tsio_write_byte(path, NULL, &res->geo, m->valley_floor, -1, err) != 0))
            return -1;
    }
    return 0;
}
