/*
 * cli_synth.c - `terrasynth synth`: a new terrain from real DEMs, free or
 * following a sketch.  The job's options and rules are declared in
 * jobs/declarations.c, the job itself is jobs/job_synth.c; these are the
 * command line's hooks around it (cli_run.c runs them).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "jobspec.h"
#include "tsio.h"
#include "tsjob.h"

typedef struct synth_state {
    tsjob_synth job;
    tsjob_synth_result res;
} synth_state;

static int synth_build(void *st, cli_run *r, char *msg, size_t len)
{
    return tsjob_build_synth(r->values, &((synth_state *)st)->job, &r->seed, msg, len);
}

/* A sketch in tiles is laid out now and kept beside the recipe (coarse_pass). */
static int synth_check_recipe(void *st, cli_run *r, const char *path, tsio_err *err)
{
    synth_state *s = st;
    if (tsjob_synth_check_recipe(&s->job, path, err) != 0)
        return -1;
    if (!s->job.coarse_pass)
        return 0;
    s->job.lazy = 1;
    s->job.write_coarse = 1;
    if (tsjob_synth_prepare(&s->job, &s->res, err) != 0 ||
        tsjob_synth_compute(r->ctx, &s->job, &s->res, 0, err) != 0)
        return -1;
    ts_ctx_set_progress(r->ctx, NULL, NULL);
    return tsjob_synth_write_coarse(r->ctx, &s->job, &s->res, err);
}

static int synth_prepare(void *st, cli_run *r, tsio_err *err)
{
    synth_state *s = st;
    if (tsjob_synth_prepare(&s->job, &s->res, err) != 0 ||
        tsjob_synth_check_outputs(&s->job, &s->res, &r->outs, err) != 0)
        return -1;
    if (!s->res.dx_m && r->co->progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: the target grid has no CRS: exemplars are used "
                        "cell for cell\n");
    return 0;
}

/* What the sketch was read as. */
static const char *sketch_kinds(int mode, const char *both)
{
    return mode == TS_SKETCH_BOTH ? both : mode == TS_SKETCH_VALLEYS ? "valleys" : "ridges";
}

static int synth_compute(void *st, cli_run *r, tsio_err *err)
{
    synth_state *s = st;
    const ts_sketch_info *si = &s->res.sketch_info;
    if (tsjob_synth_compute(r->ctx, &s->job, &s->res, r->outs.debug_dir != NULL, err) != 0)
        return -1;
    if (s->res.warning.msg[0]) /* data read otherwise than the file says: even with -q */
        fprintf(stderr, "terrasynth: warning: %s\n", s->res.warning.msg);
    if (s->job.sketch && r->co->progress != PROGRESS_QUIET)
        printf("sketch: %s, %zu feature sites, %zu feature patches placed (from %zu exemplar "
               "sites)\n",
               sketch_kinds(si->mode, "ridges and valleys"), si->n_sites, si->n_feature_patches,
               si->n_exemplar_sites);
    if (s->job.sketch && si->n_sites > 0 && si->n_exemplar_sites == 0)
        fprintf(stderr,
                "terrasynth: warning: the exemplars have no main %s to draw the sketch "
                "with: the output does not follow it\n",
                sketch_kinds(si->mode, "ridges or valleys"));
    ts_ctx_set_progress(r->ctx, NULL, NULL);
    if (r->co->progress != PROGRESS_QUIET)
        cli_drainage_report(&s->res.drainage, &s->res.drainage_info, s->res.seconds_drainage,
                            s->res.geo.width, s->res.geo.height);
    if (s->res.exemplar_no_crs && r->co->progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: used cell for cell\n",
                s->job.exemplars[s->res.exemplar_no_crs - 1]);
    return 0;
}

static int synth_write(void *st, cli_run *r, tsio_err *err)
{
    synth_state *s = st;
    return tsjob_synth_write(r->ctx, &s->job, &s->res, &r->outs, err);
}

static void synth_free(void *st)
{
    tsjob_synth_result_free(&((synth_state *)st)->res);
}

const cli_job cli_synth_job = {
    "synth",
    "grow a new terrain from real DEMs, free or following a sketch",
    "Usage: terrasynth synth --exemplar EX.tif [--exemplar EX2.tif ...]\n"
    "                        (--sketch SK.tif | --like GRID.tif | --size WxH [--origin X,Y]\n"
    "                         [--resolution R] [--crs CRS]) [options] OUTPUT\n"
    "\n"
    "Grow a new terrain of any size from real DEMs by non-feature patch synthesis\n"
    "(Zhou et al. 2007 section 4.2 and 5): patches matched by FFT masked SSD, cut in\n"
    "with graph-cut seams and smoothed with Poisson seam removal. OUTPUT is a Float32\n"
    "DEM on the target grid with its CRS, geotransform and nodata (" TSIO_NODATA_TEXT ").\n"
    "Exemplars are resampled to the target's ground resolution when it differs.\n"
    "\n"
    "With --sketch, the terrain follows a drawing: bright strokes are ridges, dark\n"
    "strokes valleys (Zhou et al. 2007 sections 3-4: feature patches matched along the\n"
    "sketch's feature tree with thin-plate-spline warps, then the fill above, then\n"
    "the layout stage, a TerraSynth addition).\n",
    "  terrasynth synth --exemplar dem.tif --size 1024x1024 --seed 7 new.tif "
    "--preview new.png\n",
    2,
    sizeof(synth_state),
    synth_build,
    synth_check_recipe,
    synth_prepare,
    synth_compute,
    synth_write,
    NULL,
    synth_free,
};
