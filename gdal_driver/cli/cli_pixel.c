/*
 * cli_pixel.c - `terrasynth pixel`: multiresolution pixel synthesis
 * (Lefebvre and Hoppe 2005; Cruz et al.): a terrain of any size in the style
 * of the exemplars, every cell a function of the seed and its position.  The
 * job (jobspec.c declares its options and rules) and its files (tsjob.c) are
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

static void pixel_help(FILE *out)
{
    fprintf(out, "Usage: terrasynth pixel --exemplar EX (--like GRID | --size WxH) [options] "
                 "(OUTPUT | --recipe FILE.tsyn)\n"
                 "\n"
                 "Grow a terrain in the style of the exemplars cell by cell, coarse to fine: the\n"
                 "exemplars' Gaussian stacks give each level, every cell of the output takes an\n"
                 "exemplar coordinate that is upsampled, jittered and corrected against its\n"
                 "neighbours (Lefebvre and Hoppe 2005; Cruz et al.). Every cell is a function of\n"
                 "the seed and its position: a recipe serves any window alone, the same as in\n"
                 "the whole.\n"
                 "\n");
    cli_job_help(out, tsjob_find("pixel"));
    fprintf(out,
            "\n"
            "Common options:\n%s"
            "\n"
            "Example:\n"
            "  terrasynth pixel --exemplar mountains_30m.tif --size 1024x1024 --seed 3 new.tif\n",
            cli_common_help);
}

int cli_pixel(int argc, char **argv)
{
    common_opts co = {"pixel", NULL, NULL, PROGRESS_BAR, 0};
    const char *recipe_path;
    tsjob_outputs outs = {0};
    int i, rc = EXIT_RUN, progress_state = -1, staged = 0;
    ts_ctx *ctx = ts_ctx_new();
    tsjob_pixel job;
    tsjob_pixel_result res;
    tsio_err err;
    tsjob_values v;
    uint64_t seed = 0;
    char msg[1024] = "";

    memset(&res, 0, sizeof res);
    tsjob_values_init(&v, tsjob_find("pixel"));
    if (!ctx) {
        fprintf(stderr, "terrasynth: out of memory\n");
        return EXIT_RUN;
    }
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            pixel_help(stdout);
            rc = 0;
            goto done;
        }
    if (cli_parse_argv(&v, argc, argv, 2, cli_skip_common, &co, msg, sizeof msg) != 0) {
        if (msg[0])
            cli_usage_error("pixel", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    if (tsjob_build_pixel(&v, &job, &seed, msg, sizeof msg) != 0) {
        cli_usage_error("pixel", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    outs.output = tsjob_get(&v, "output", 0);
    outs.preview = tsjob_get(&v, "preview", 0);
    outs.debug_dir = tsjob_get(&v, "debug_dir", 0);
    job.keep_sources = outs.debug_dir != NULL;
    outs.format = co.format;
    outs.create_options = (const char *const *)co.create_options;
    recipe_path = tsjob_get(&v, "recipe", 0);
    if (recipe_path) {
        if (tsjob_pixel_check_recipe(&job, recipe_path, &err) != 0 ||
            tsrecipe_write(recipe_path, &v, &err) != 0) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            goto done;
        }
        rc = 0;
        goto done;
    }
    /* the grid resolved, the memory estimated and every output checked before the
     * work; the outputs are written all or none */
    tsio_stage_begin();
    staged = 1;
    if (tsjob_pixel_prepare(&job, &res, &err) != 0 ||
        tsjob_pixel_check_outputs(&job, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    ts_ctx_set_threads(ctx, co.threads);
    ts_ctx_set_seed(ctx, seed);
    cli_set_progress(ctx, co.progress, &progress_state);
    if (tsjob_pixel_compute(ctx, &job, &res, &err) != 0 ||
        tsjob_pixel_write(ctx, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    staged = 0;
    if (tsio_stage_commit(&err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (res.warning.msg[0])
        fprintf(stderr, "terrasynth: warning: %s\n", res.warning.msg);
    if (res.exemplar_no_crs && co.progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: used cell for cell\n",
                job.exemplars[res.exemplar_no_crs - 1]);
    if (co.progress != PROGRESS_QUIET)
        printf("pixel: %d x %d cells, %d levels, window %d, seed %llu; stacks %.2f s, synthesis "
               "%.2f s\n",
               res.geo.width, res.geo.height, ts_pixel_levels(res.stacks),
               ts_pixel_window(res.stacks), (unsigned long long)seed, res.seconds_stacks,
               res.seconds_synthesis);
    rc = 0;
done:
    if (staged)
        tsio_stage_abort();
    tsjob_pixel_result_free(&res);
    tsjob_values_free(&v);
    CSLDestroy(co.create_options);
    ts_ctx_free(ctx);
    return rc;
}
