/*
 * cli_dictionary.c - `terrasynth dictionary build|info`: an amplification
 * dictionary built once from exemplars and reused (`terrasynth amplify
 * --dictionary`).  The job "dictionary" is declared in jobspec.c.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_string.h>

#include "cli.h"
#include "jobspec.h"
#include "tsio.h"
#include "tsjob.h"

static void dictionary_help(FILE *out)
{
    fprintf(out,
            "Usage: terrasynth dictionary build D.tsd --exemplar EX --resolution M [options]\n"
            "       terrasynth dictionary info D.tsd\n"
            "\n"
            "Build an amplification dictionary once (the exemplars resampled to cells of M\n"
            "metres, the size of the amplified DEMs' cells, area-averaged by the factor, cut\n"
            "into atoms) and reuse it: terrasynth amplify IN OUT --dictionary D.tsd. The file\n"
            "is portable (little-endian, versioned); info prints what it holds.\n"
            "\n");
    cli_job_help(out, tsjob_find("dictionary"));
    fprintf(out,
            "\n"
            "Common options:\n%s"
            "\n"
            "Example:\n"
            "  terrasynth dictionary build alps.tsd --exemplar alps_25m.tif --resolution 25 "
            "--factor 8\n",
            cli_common_help);
}

static int dictionary_info(const char *path)
{
    ts_ctx *ctx = ts_ctx_new();
    ts_dictionary *d = NULL;
    double res = 0;
    tsio_err err;
    int factor, patch, rc = EXIT_RUN;
    if (!ctx)
        return EXIT_RUN;
    if (tsjob_dictionary_read(ctx, path, &d, &res, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
    } else {
        int L, K, irr, l;
        ts_dictionary_shape(d, &factor, &patch);
        ts_dictionary_layers(d, &L, &K, &irr);
        printf("{\"file\": \"%s\", \"version\": 2, \"factor\": %d, \"patch\": %d, \"atoms\": %zu, "
               "\"resolution_m\": %.17g, \"input_cell_m\": %.17g, \"irradiance\": %s, "
               "\"classes\": %d, \"layers\": [",
               path, factor, patch, ts_dictionary_size(d), res, res * factor,
               irr ? "true" : "false", K);
        for (l = 0; l < L; l++) /* names of letters, digits, _ and - */
            printf("%s\"%s\"", l ? ", " : "", ts_dictionary_layer_name(d, l));
        printf("]}\n");
        rc = 0;
    }
    ts_dictionary_free(d);
    ts_ctx_free(ctx);
    return rc;
}

int cli_dictionary(int argc, char **argv)
{
    common_opts co = {"dictionary", NULL, NULL, PROGRESS_BAR, 0};
    int i, rc = EXIT_RUN, progress_state = -1, staged = 0;
    ts_ctx *ctx;
    tsjob_amplify job;
    tsio_err err;
    tsjob_values v;
    size_t n_atoms = 0;
    char msg[1024] = "";
    const char *out;
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            dictionary_help(stdout);
            return 0;
        }
    if (argc >= 4 && !strcmp(argv[2], "info") && argc == 4)
        return dictionary_info(argv[3]);
    if (argc < 3 || strcmp(argv[2], "build") != 0) {
        cli_usage_error("dictionary", "%s", "give build or info");
        return EXIT_USAGE;
    }
    ctx = ts_ctx_new();
    if (!ctx)
        return EXIT_RUN;
    tsjob_values_init(&v, tsjob_find("dictionary"));
    if (cli_parse_argv(&v, argc, argv, 3, cli_skip_common, &co, msg, sizeof msg) != 0) {
        if (msg[0])
            cli_usage_error("dictionary", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    if (tsjob_build_amplify(&v, &job, msg, sizeof msg) != 0) {
        cli_usage_error("dictionary", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    out = tsjob_get(&v, "output", 0);
    ts_ctx_set_threads(ctx, co.threads);
    cli_set_progress(ctx, co.progress, &progress_state);
    tsio_stage_begin();
    staged = 1;
    if (tsjob_dictionary_build(ctx, &job, out, &n_atoms, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    staged = 0;
    if (tsio_stage_commit(&err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (co.progress != PROGRESS_QUIET)
        printf("dictionary: %zu atoms (factor %d, patch %d, cells of %g m)\n", n_atoms,
               job.params.factor, job.params.patch, job.resolution);
    rc = 0;
done:
    if (staged)
        tsio_stage_abort();
    tsjob_values_free(&v);
    CSLDestroy(co.create_options);
    ts_ctx_free(ctx);
    return rc;
}
