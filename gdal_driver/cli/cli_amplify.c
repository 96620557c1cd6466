/*
 * cli_amplify.c - `terrasynth amplify`: a coarse DEM made `factor` times
 * finer with the detail of real terrain (Argudo et al. 2017).  The job's
 * options and rules are declared in jobs/declarations.c, the job itself is
 * jobs/job_amplify.c; these are the command line's hooks around it
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

typedef struct amplify_state {
    tsjob_amplify job;
    tsjob_amplify_result res;
    const char *out_layers[TS_MAX_LAYERS + 1];
} amplify_state;

static int amplify_build(void *st, cli_run *r, char *msg, size_t len)
{
    amplify_state *s = st;
    int i;
    for (i = 0; i < TS_MAX_LAYERS && (s->out_layers[i] = tsjob_get(r->values, "out_layer", i)); i++)
        ;
    r->outs.out_layers = s->out_layers;
    r->outs.out_classes = tsjob_get(r->values, "out_classes", 0);
    return tsjob_build_amplify(r->values, &s->job, msg, len);
}

static int amplify_check_recipe(void *st, cli_run *r, const char *path, tsio_err *err)
{
    (void)r;
    return tsjob_amplify_check_recipe(&((amplify_state *)st)->job, path, err);
}

static int amplify_prepare(void *st, cli_run *r, tsio_err *err)
{
    amplify_state *s = st;
    if (tsjob_amplify_adopt_dictionary(&s->job, err) != 0 ||
        tsjob_amplify_prepare(&s->job, &s->res, err) != 0 ||
        tsjob_amplify_check_outputs(&s->job, &s->res, &r->outs, err) != 0)
        return -1;
    if (s->res.warning.msg[0]) /* from the inputs' sizes and values: even with -q */
        fprintf(stderr, "terrasynth: warning: %s\n", s->res.warning.msg);
    s->res.warning.msg[0] = '\0';
    if (!s->res.in.dx_m && !(s->job.cell_size > 0) && r->co->progress != PROGRESS_QUIET)
        fprintf(stderr,
                "terrasynth: warning: %s has no CRS: the exemplars are used cell for "
                "cell (give --cell-size for their ground size)\n",
                s->job.input);
    return 0;
}

static int amplify_compute(void *st, cli_run *r, tsio_err *err)
{
    amplify_state *s = st;
    return tsjob_amplify_compute(r->ctx, &s->job, &s->res, err);
}

static int amplify_write(void *st, cli_run *r, tsio_err *err)
{
    return tsjob_amplify_write(r->ctx, &((amplify_state *)st)->res, &r->outs, err);
}

static void amplify_report(void *st, cli_run *r)
{
    amplify_state *s = st;
    const tsjob_amplify_result *res = &s->res;
    if (res->warning.msg[0]) /* from the exemplars */
        fprintf(stderr, "terrasynth: warning: %s\n", res->warning.msg);
    if (res->exemplar_no_crs && r->co->progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: used cell for cell\n",
                s->job.exemplars[res->exemplar_no_crs - 1]);
    if (r->co->progress != PROGRESS_QUIET)
        printf("amplify: %d x %d -> %d x %d cells (x%d), %zu patches, %zu atoms, mean match "
               "%.3f; dictionary %.2f s, matching %.2f s, synthesis %.2f s\n",
               res->in.geo.width, res->in.geo.height, res->geo.width, res->geo.height,
               s->job.params.factor, res->info.n_patches, res->n_atoms, res->info.mean_score,
               res->seconds_dictionary, res->info.seconds_match, res->info.seconds_synthesis);
    if (r->co->progress != PROGRESS_QUIET)
        cli_drainage_report(&res->drainage, &res->drainage_info, res->seconds_drainage,
                            res->geo.width, res->geo.height);
}

static void amplify_free(void *st)
{
    tsjob_amplify_result_free(&((amplify_state *)st)->res);
}

const cli_job cli_amplify_job = {
    "amplify",
    "make a coarse DEM finer with the detail of real terrain",
    "Usage: terrasynth amplify INPUT (OUTPUT | --recipe FILE.tsyn) --exemplar EX [options]\n"
    "\n"
    "Make a coarse DEM `factor` times finer with the detail of real terrain: a\n"
    "dictionary of atoms (windows of the exemplars, area-averaged, with the windows\n"
    "above them) is matched to the input's patches by shape, altitude, slope,\n"
    "drainage, irradiance and classes, and each patch is replaced by its atom's\n"
    "fine counterpart, its other layers with it (Argudo et al. 2017). OUTPUT covers\n"
    "the input's extent in its CRS, factor times finer, nodata where the input is\n"
    "nodata; averaged back by the factor it gives the input.\n",
    "  terrasynth amplify coarse_200m.tif fine_25m.tif --exemplar alps_25m.tif "
    "--factor 8\n",
    2,
    sizeof(amplify_state),
    amplify_build,
    amplify_check_recipe,
    amplify_prepare,
    amplify_compute,
    amplify_write,
    amplify_report,
    amplify_free,
};
