/*
 * cli_synth.c - `terrasynth synth`: a new terrain from real DEMs, free or
 * following a sketch.  The job (jobspec.c) and its files (tsjob.c) are
 * shared with the driver and QGIS; this is the command line around them.
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

static void synth_help(FILE *out)
{
    fprintf(
        out,
        "Usage: terrasynth synth --exemplar EX.tif [--exemplar EX2.tif ...]\n"
        "                        (--sketch SK.tif | --like GRID.tif | --size WxH [--origin X,Y]\n"
        "                         [--resolution R] [--crs CRS]) [options] OUTPUT\n"
        "\n"
        "Grow a new terrain of any size from real DEMs by non-feature patch synthesis\n"
        "(Zhou et al. 2007 section 4.2 and 5): patches matched by FFT masked SSD, cut in\n"
        "with graph-cut seams and smoothed with Poisson seam removal. OUTPUT is a Float32\n"
        "DEM on the target grid with its CRS, geotransform and nodata (-9999).\n"
        "Exemplars are resampled to the target's ground resolution when it differs.\n"
        "\n"
        "With --sketch, the terrain follows a drawing: bright strokes are ridges, dark\n"
        "strokes valleys (Zhou et al. 2007 sections 3-4: feature patches matched along the\n"
        "sketch's feature tree with thin-plate-spline warps, then the fill above, then\n"
        "the layout stage, a TerraSynth addition).\n"
        "\n");
    cli_job_help(out, tsjob_find("synth"));
    fprintf(out,
            "\n"
            "Common options:\n%s"
            "\n"
            "Example:\n"
            "  terrasynth synth --exemplar dem.tif --size 1024x1024 --seed 7 new.tif "
            "--preview new.png\n",
            cli_common_help);
}

int cli_synth(int argc, char **argv)
{
    common_opts co = {"synth", NULL, NULL, PROGRESS_BAR, 0};
    const char *recipe_path = NULL;
    tsjob_outputs outs = {0};
    int i, rc = EXIT_RUN, progress_state = -1, staged = 0;
    uint64_t seed = 0;
    tsjob_synth job;
    tsjob_synth_result res;
    tsio_err err;
    ts_ctx *ctx = ts_ctx_new();
    tsjob_values v;
    char msg[1024] = "";

    tsjob_values_init(&v, tsjob_find("synth"));
    memset(&job, 0, sizeof job);
    memset(&res, 0, sizeof res);
    if (!ctx) {
        fprintf(stderr, "terrasynth: out of memory\n");
        return EXIT_RUN;
    }
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            synth_help(stdout);
            rc = 0;
            goto done;
        }
    if (cli_parse_argv(&v, argc, argv, 2, cli_skip_common, &co, msg, sizeof msg) != 0) {
        if (msg[0])
            cli_usage_error("synth", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    if (tsjob_build_synth(&v, &job, &seed, msg, sizeof msg) != 0) {
        cli_usage_error("synth", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    outs.output = tsjob_get(&v, "output", 0);
    outs.preview = tsjob_get(&v, "preview", 0);
    outs.debug_dir = tsjob_get(&v, "debug_dir", 0);
    outs.format = co.format;
    outs.create_options = (const char *const *)co.create_options;
    recipe_path = tsjob_get(&v, "recipe", 0);
    if (recipe_path) {
        if (tsjob_synth_check_recipe(&job, recipe_path, &err) != 0 ||
            tsrecipe_write(recipe_path, &v, &err) != 0) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            goto done;
        }
        rc = 0;
        goto done;
    }
    /* the grid is resolved and every output checked before the work; the
     * outputs are written all or none (a stage) */
    tsio_stage_begin();
    staged = 1;
    if (tsjob_synth_prepare(&job, &res, &err) != 0 ||
        tsjob_synth_check_outputs(&job, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (!res.dx_m && co.progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: the target grid has no CRS: exemplars are used "
                        "cell for cell\n");
    ts_ctx_set_seed(ctx, seed);
    ts_ctx_set_threads(ctx, co.threads);
    cli_set_progress(ctx, co.progress, &progress_state);
    if (tsjob_synth_compute(ctx, &job, &res, outs.debug_dir != NULL, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (res.warning.msg[0]) /* data read otherwise than the file says: even with -q */
        fprintf(stderr, "terrasynth: warning: %s\n", res.warning.msg);
    if (job.sketch && co.progress != PROGRESS_QUIET)
        printf("sketch: %s, %zu feature sites, %zu feature patches placed (from %zu exemplar "
               "sites)\n",
               res.sketch_info.mode == TS_SKETCH_BOTH      ? "ridges and valleys"
               : res.sketch_info.mode == TS_SKETCH_VALLEYS ? "valleys"
                                                           : "ridges",
               res.sketch_info.n_sites, res.sketch_info.n_feature_patches,
               res.sketch_info.n_exemplar_sites);
    if (job.sketch && res.sketch_info.n_sites > 0 && res.sketch_info.n_exemplar_sites == 0)
        fprintf(stderr,
                "terrasynth: warning: the exemplars have no main %s to draw the sketch "
                "with: the output does not follow it\n",
                res.sketch_info.mode == TS_SKETCH_BOTH      ? "ridges or valleys"
                : res.sketch_info.mode == TS_SKETCH_VALLEYS ? "valleys"
                                                            : "ridges");
    ts_ctx_set_progress(ctx, NULL, NULL);
    if (res.exemplar_no_crs && co.progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: used cell for cell\n",
                job.exemplars[res.exemplar_no_crs - 1]);
    if (tsjob_synth_write(ctx, &job, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    staged = 0;
    if (tsio_stage_commit(&err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    rc = 0;
done:
    if (staged)
        tsio_stage_abort();
    tsjob_synth_result_free(&res);
    tsjob_values_free(&v);
    CSLDestroy(co.create_options);
    ts_ctx_free(ctx);
    return rc;
}
