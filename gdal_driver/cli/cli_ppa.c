/*
 * cli_ppa.c - `terrasynth ppa`: ridge and valley axes of a DEM as a raster,
 * vector lines and a preview.  The job (gdal_driver/jobspec.c declares
 * its options and rules) and its files (tsjob.c) are shared with the
 * driver and QGIS; this is the command line around them.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal.h>

#include "cli.h"
#include "jobspec.h"
#include "recipe.h"
#include "tsio.h"
#include "tsjob.h"

static void ppa_help(FILE *out)
{
    fprintf(out, "Usage: terrasynth ppa INPUT (OUTPUT | --recipe FILE.tsyn) [options]\n"
                 "\n"
                 "Map the ridge and valley axes of a DEM with the Profile recognition and Polygon\n"
                 "breaking Algorithm (Chang, Song & Hsu 1998). OUTPUT is a Byte raster on the\n"
                 "input's grid: 1 ridge, 2 valley, 3 both (a saddle on both axes), 0 none,\n"
                 "255 where the input is nodata. Giving threshold sets threshold_fraction to 0\n"
                 "and the other way round.\n"
                 "\n");
    cli_job_help(out, tsjob_find("ppa"));
    fprintf(out,
            "\n"
            "Common options:\n%s"
            "\n"
            "Example:\n"
            "  terrasynth ppa dem.tif axes.tif --both --lines axes.gpkg --preview axes.png\n",
            cli_common_help);
}

int cli_ppa(int argc, char **argv)
{
    common_opts co = {"ppa", NULL, NULL, PROGRESS_BAR, 0};
    const char *input = NULL, *recipe_path = NULL;
    tsjob_outputs outs = {0};
    int i, rc = EXIT_RUN, progress_state = -1, staged = 0;
    ts_ctx *ctx = ts_ctx_new();
    tsjob_ppa job;
    tsjob_ppa_result res;
    tsio_err err;
    ts_features *f = NULL;
    size_t k;
    tsjob_values v;
    char msg[1024] = "";

    memset(&res, 0, sizeof res);
    tsjob_values_init(&v, tsjob_find("ppa"));
    if (!ctx) {
        fprintf(stderr, "terrasynth: out of memory\n");
        return EXIT_RUN;
    }
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            ppa_help(stdout);
            rc = 0;
            goto done;
        }
    if (cli_parse_argv(&v, argc, argv, 2, cli_skip_common, &co, msg, sizeof msg) != 0) {
        if (msg[0])
            cli_usage_error("ppa", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    if (tsjob_build_ppa(&v, &job, msg, sizeof msg) != 0) {
        cli_usage_error("ppa", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    input = job.input;
    outs.output = tsjob_get(&v, "output", 0);
    outs.lines = tsjob_get(&v, "lines", 0);
    outs.preview = tsjob_get(&v, "preview", 0);
    outs.format = co.format;
    outs.create_options = (const char *const *)co.create_options;
    recipe_path = tsjob_get(&v, "recipe", 0);
    if (recipe_path) {
        if (tsjob_ppa_check_recipe(&job, recipe_path, &err) != 0 ||
            tsrecipe_write(recipe_path, &v, &err) != 0) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            goto done;
        }
        rc = 0;
        goto done;
    }
    /* the input is read and every output checked before the work starts; the
     * outputs are written all or none (a stage) */
    tsio_stage_begin();
    staged = 1;
    if (tsjob_ppa_prepare(&job, &res, &err) != 0 ||
        tsjob_ppa_check_outputs(&job, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (res.warning.msg[0]) /* data read otherwise than the file says: even with -q */
        fprintf(stderr, "terrasynth: warning: %s\n", res.warning.msg);
    if (res.no_crs && co.progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: lengths are in cells\n", input);
    ts_ctx_set_threads(ctx, co.threads);
    cli_set_progress(ctx, co.progress, &progress_state);
    if (tsjob_ppa_compute(ctx, &job, &res, &err) != 0 ||
        tsjob_ppa_write(ctx, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    staged = 0; /* a failed commit cleans up itself */
    if (tsio_stage_commit(&err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    f = res.features;
    if (co.progress != PROGRESS_QUIET && !f)
        printf("ppa: mapped in tiles of %d cells%s (%d branch reduction passes in the tiles, "
               "%zu chains held for the rest)\n",
               res.tile_size,
               res.auto_tiles ? ", the DEM being too large for memory in one piece" : "",
               res.tiled.passes_in_tiles, res.tiled.chains_held);
    if (co.progress != PROGRESS_QUIET && f) {
        size_t nb = 0, ne = 0, np[3] = {0, 0, 0};
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
        if (job.params.features == TS_PPA_BOTH)
            printf("(thresholds: ridges %.3g m, valleys %.3g m)\n", f->threshold_used,
                   f->threshold_used_valleys);
        else
            printf("(threshold %.3g m)\n", f->threshold_used);
    }
    rc = 0;
done:
    if (staged)
        tsio_stage_abort();
    tsjob_ppa_result_free(&res);
    tsjob_values_free(&v);
    CSLDestroy(co.create_options);
    ts_ctx_free(ctx);
    return rc;
}
