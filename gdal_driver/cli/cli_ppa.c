/*
 * cli_ppa.c - `terrasynth ppa`: ridge and valley axes of a DEM as a raster,
 * vector lines and a preview.  The job's options and rules are declared in
 * jobs/declarations.c, the job itself is jobs/job_ppa.c; these are the
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

typedef struct ppa_state {
    tsjob_ppa job;
    tsjob_ppa_result res;
} ppa_state;

static int ppa_build(void *st, cli_run *r, char *msg, size_t len)
{
    return tsjob_build_ppa(r->values, &((ppa_state *)st)->job, msg, len);
}

static int ppa_check_recipe(void *st, cli_run *r, const char *path, tsio_err *err)
{
    (void)r;
    return tsjob_ppa_check_recipe(&((ppa_state *)st)->job, path, err);
}

static int ppa_prepare(void *st, cli_run *r, tsio_err *err)
{
    ppa_state *s = st;
    if (tsjob_ppa_prepare(&s->job, &s->res, err) != 0 ||
        tsjob_ppa_check_outputs(&s->job, &s->res, &r->outs, err) != 0)
        return -1;
    if (s->res.warning.msg[0]) /* data read otherwise than the file says: even with -q */
        fprintf(stderr, "terrasynth: warning: %s\n", s->res.warning.msg);
    if (s->res.no_crs && r->co->progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: lengths are in cells\n", s->job.input);
    return 0;
}

static int ppa_compute(void *st, cli_run *r, tsio_err *err)
{
    ppa_state *s = st;
    return tsjob_ppa_compute(r->ctx, &s->job, &s->res, err);
}

static int ppa_write(void *st, cli_run *r, tsio_err *err)
{
    return tsjob_ppa_write(r->ctx, &((ppa_state *)st)->res, &r->outs, err);
}

static void ppa_report(void *st, cli_run *r)
{
    ppa_state *s = st;
    const ts_features *f = s->res.features;
    size_t k, nb = 0, ne = 0, np[3] = {0, 0, 0};
    if (r->co->progress == PROGRESS_QUIET)
        return;
    if (!f) {
        printf("ppa: mapped in tiles of %d cells%s (%d branch reduction passes in the tiles, "
               "%zu chains held for the rest)\n",
               s->res.tile_size,
               s->res.auto_tiles ? ", the DEM being too large for memory in one piece" : "",
               s->res.tiled.passes_in_tiles, s->res.tiled.chains_held);
        return;
    }
    for (k = 0; k < f->n_nodes; k++) {
        if (f->nodes[k].degree == 1)
            ne++;
        else
            nb++;
    }
    for (k = 0; k < f->n_paths; k++)
        np[f->paths[k].kind]++;
    printf("ppa: %zu ridge paths, %zu valley paths, %zu branch points, %zu endpoints ",
           np[TS_RIDGE], np[TS_VALLEY], nb, ne);
    if (s->job.params.features == TS_PPA_BOTH)
        printf("(thresholds: ridges %.3g m, valleys %.3g m)\n", f->threshold_used,
               f->threshold_used_valleys);
    else
        printf("(threshold %.3g m)\n", f->threshold_used);
}

static void ppa_free(void *st)
{
    tsjob_ppa_result_free(&((ppa_state *)st)->res);
}

const cli_job cli_ppa_job = {
    "ppa",
    "map ridge and valley axes of a DEM (raster, vector lines, preview)",
    "Usage: terrasynth ppa INPUT (OUTPUT | --recipe FILE.tsyn) [options]\n"
    "\n"
    "Map the ridge and valley axes of a DEM with the Profile recognition and Polygon\n"
    "breaking Algorithm (Chang, Song & Hsu 1998). OUTPUT is a Byte raster on the\n"
    "input's grid: 1 ridge, 2 valley, 3 both (a saddle on both axes), 0 none,\n"
    "255 where the input is nodata. Giving threshold sets threshold_fraction to 0\n"
    "and the other way round.\n",
    "  terrasynth ppa dem.tif axes.tif --both --lines axes.gpkg --preview axes.png\n",
    2,
    sizeof(ppa_state),
    ppa_build,
    ppa_check_recipe,
    ppa_prepare,
    ppa_compute,
    ppa_write,
    ppa_report,
    ppa_free,
};
