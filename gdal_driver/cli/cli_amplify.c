/*
 * cli_amplify.c - `terrasynth amplify`: a coarse DEM made `factor` times
 * finer with the detail of real terrain (Argudo et al. 2017).  The job
 * (jobspec.c declares its options and rules) and its files (tsjob.c) are
 * shared with the driver; this is the command line around them.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_string.h>

#include "cli.h"
#include "jobspec.h"
#include "recipe.h"
#include "tsio.h"
#include "tsjob.h"

static void amplify_help(FILE *out)
{
    fprintf(
        out,
        "Usage: terrasynth amplify INPUT (OUTPUT | --recipe FILE.tsyn) --exemplar EX [options]\n"
        "\n"
        "Make a coarse DEM `factor` times finer with the detail of real terrain: a\n"
        "dictionary of atoms (windows of the exemplars, area-averaged, with the windows\n"
        "above them) is matched to the input's patches by shape, altitude, slope,\n"
        "drainage, irradiance and classes, and each patch is replaced by its atom's\n"
        "fine counterpart, its other layers with it (Argudo et al. 2017). OUTPUT covers\n"
        "the input's extent in its CRS, factor times finer, nodata where the input is\n"
        "nodata; averaged back by the factor it gives the input.\n"
        "\n");
    cli_job_help(out, tsjob_find("amplify"));
    fprintf(out,
            "\n"
            "Common options:\n%s"
            "\n"
            "Example:\n"
            "  terrasynth amplify coarse_200m.tif fine_25m.tif --exemplar alps_25m.tif "
            "--factor 8\n",
            cli_common_help);
}

int cli_amplify(int argc, char **argv)
{
    common_opts co = {"amplify", NULL, NULL, PROGRESS_BAR, 0};
    const char *recipe_path;
    tsjob_outputs outs = {0};
    const char *out_layers[TS_MAX_LAYERS + 1] = {NULL};
    int i, rc = EXIT_RUN, progress_state = -1, staged = 0;
    ts_ctx *ctx = ts_ctx_new();
    tsjob_amplify job;
    tsjob_amplify_result res;
    tsio_err err;
    tsjob_values v;
    char msg[1024] = "";

    memset(&res, 0, sizeof res);
    tsjob_values_init(&v, tsjob_find("amplify"));
    if (!ctx) {
        fprintf(stderr, "terrasynth: out of memory\n");
        return EXIT_RUN;
    }
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            amplify_help(stdout);
            rc = 0;
            goto done;
        }
    if (cli_parse_argv(&v, argc, argv, 2, cli_skip_common, &co, msg, sizeof msg) != 0) {
        if (msg[0])
            cli_usage_error("amplify", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    if (tsjob_build_amplify(&v, &job, msg, sizeof msg) != 0) {
        cli_usage_error("amplify", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    outs.output = tsjob_get(&v, "output", 0);
    outs.preview = tsjob_get(&v, "preview", 0);
    for (i = 0; i < TS_MAX_LAYERS && (out_layers[i] = tsjob_get(&v, "out_layer", i)); i++)
        ;
    outs.out_layers = out_layers;
    outs.out_classes = tsjob_get(&v, "out_classes", 0);
    outs.format = co.format;
    outs.create_options = (const char *const *)co.create_options;
    recipe_path = tsjob_get(&v, "recipe", 0);
    if (recipe_path) {
        if (tsjob_amplify_check_recipe(&job, recipe_path, &err) != 0 ||
            tsrecipe_write(recipe_path, &v, &err) != 0) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            goto done;
        }
        rc = 0;
        goto done;
    }
    /* the input read, the memory estimated and every output checked before the work;
     * the outputs are written all or none */
    tsio_stage_begin();
    staged = 1;
    if (tsjob_amplify_adopt_dictionary(&job, &err) != 0 ||
        tsjob_amplify_prepare(&job, &res, &err) != 0 ||
        tsjob_amplify_check_outputs(&job, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (res.warning.msg[0]) /* from the inputs' sizes and values: even with -q */
        fprintf(stderr, "terrasynth: warning: %s\n", res.warning.msg);
    res.warning.msg[0] = '\0';
    if (!res.in.dx_m && !(job.cell_size > 0) && co.progress != PROGRESS_QUIET)
        fprintf(stderr,
                "terrasynth: warning: %s has no CRS: the exemplars are used cell for "
                "cell (give --cell-size for their ground size)\n",
                job.input);
    ts_ctx_set_threads(ctx, co.threads);
    cli_set_progress(ctx, co.progress, &progress_state);
    if (tsjob_amplify_compute(ctx, &job, &res, &err) != 0 ||
        tsjob_amplify_write(ctx, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    staged = 0;
    if (tsio_stage_commit(&err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (res.warning.msg[0]) /* from the exemplars */
        fprintf(stderr, "terrasynth: warning: %s\n", res.warning.msg);
    if (res.exemplar_no_crs && co.progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: used cell for cell\n",
                job.exemplars[res.exemplar_no_crs - 1]);
    if (co.progress != PROGRESS_QUIET)
        printf("amplify: %d x %d -> %d x %d cells (x%d), %zu patches, %zu atoms, mean match "
               "%.3f; dictionary %.2f s, matching %.2f s, synthesis %.2f s\n",
               res.in.geo.width, res.in.geo.height, res.geo.width, res.geo.height,
               job.params.factor, res.info.n_patches, res.n_atoms, res.info.mean_score,
               res.seconds_dictionary, res.info.seconds_match, res.info.seconds_synthesis);
    rc = 0;
done:
    if (staged)
        tsio_stage_abort();
    tsjob_amplify_result_free(&res);
    tsjob_values_free(&v);
    CSLDestroy(co.create_options);
    ts_ctx_free(ctx);
    return rc;
}
