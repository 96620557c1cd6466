/*
 * cli_pixel.c - `terrasynth pixel`: a terrain grown cell by cell, coarse
 * to fine (Lefebvre and Hoppe 2005; Cruz et al.).  The job's options and
 * rules are declared in jobs/declarations.c, the job itself is
 * jobs/job_pixel.c; these are the command line's hooks around it
 * (cli_run.c runs them).
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

typedef struct pixel_state {
    tsjob_pixel job;
    tsjob_pixel_result res;
} pixel_state;

static int pixel_build(void *st, cli_run *r, char *msg, size_t len)
{
    pixel_state *s = st;
    if (tsjob_build_pixel(r->values, &s->job, &r->seed, msg, len) != 0)
        return -1;
    s->job.keep_sources = r->outs.debug_dir != NULL;
    return 0;
}

static int pixel_check_recipe(void *st, cli_run *r, const char *path, tsio_err *err)
{
    (void)r;
    return tsjob_pixel_check_recipe(&((pixel_state *)st)->job, path, err);
}

static int pixel_prepare(void *st, cli_run *r, tsio_err *err)
{
    pixel_state *s = st;
    return tsjob_pixel_prepare(&s->job, &s->res, err) != 0 ||
                   tsjob_pixel_check_outputs(&s->job, &s->res, &r->outs, err) != 0
               ? -1
               : 0;
}

static int pixel_compute(void *st, cli_run *r, tsio_err *err)
{
    pixel_state *s = st;
    return tsjob_pixel_compute(r->ctx, &s->job, &s->res, err);
}

static int pixel_write(void *st, cli_run *r, tsio_err *err)
{
    return tsjob_pixel_write(r->ctx, &((pixel_state *)st)->res, &r->outs, err);
}

static void pixel_report(void *st, cli_run *r)
{
    pixel_state *s = st;
    const tsjob_pixel_result *res = &s->res;
    if (res->warning.msg[0])
        fprintf(stderr, "terrasynth: warning: %s\n", res->warning.msg);
    if (res->exemplar_no_crs && r->co->progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: used cell for cell\n",
                s->job.exemplars[res->exemplar_no_crs - 1]);
    if (r->co->progress != PROGRESS_QUIET)
        printf("pixel: %d x %d cells, %d levels, window %d, %d views of each exemplar (grain "
               "%.2f), seed %llu; stacks %.2f s, synthesis %.2f s\n",
               res->geo.width, res->geo.height, ts_pixel_levels(res->stacks),
               ts_pixel_window(res->stacks), ts_pixel_variants(res->stacks),
               ts_pixel_grain(res->stacks), (unsigned long long)r->seed, res->seconds_stacks,
               res->seconds_synthesis);
    if (r->co->progress != PROGRESS_QUIET)
        cli_drainage_report(&res->drainage, &res->drainage_info, res->seconds_drainage,
                            res->geo.width, res->geo.height);
}

static void pixel_free(void *st)
{
    tsjob_pixel_result_free(&((pixel_state *)st)->res);
}

const cli_job cli_pixel_job = {
    "pixel",
    "grow a terrain cell by cell, coarse to fine (any window on its own)",
    "Usage: terrasynth pixel --exemplar EX (--like GRID | --size WxH) [options] "
    "(OUTPUT | --recipe FILE.tsyn)\n"
    "\n"
    "Grow a terrain in the style of the exemplars cell by cell, coarse to fine: the\n"
    "exemplars' Gaussian stacks give each level, every cell of the output takes an\n"
    "exemplar coordinate that is upsampled, jittered and corrected against its\n"
    "neighbours (Lefebvre and Hoppe 2005; Cruz et al.). Every cell is a function of\n"
    "the seed and its position: a recipe serves any window alone, the same as in\n"
    "the whole.\n",
    "  terrasynth pixel --exemplar mountains_30m.tif --size 1024x1024 --seed 3 new.tif\n",
    2,
    sizeof(pixel_state),
    pixel_build,
    pixel_check_recipe,
    pixel_prepare,
    pixel_compute,
    pixel_write,
    pixel_report,
    pixel_free,
};
