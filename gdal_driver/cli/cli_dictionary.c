/*
 * cli_dictionary.c - `terrasynth dictionary build|info`: an amplification
 * dictionary built once from exemplars and reused (`terrasynth amplify
 * --dictionary`).  The job "dictionary" is declared in jobs/declarations.c
 * and built by jobs/job_amplify.c; build runs through cli_run.c.
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

typedef struct dictionary_state {
    tsjob_amplify job;
    size_t n_atoms;
} dictionary_state;

static int dictionary_build(void *st, cli_run *r, char *msg, size_t len)
{
    return tsjob_build_amplify(r->values, &((dictionary_state *)st)->job, msg, len);
}

static int dictionary_compute(void *st, cli_run *r, tsio_err *err)
{
    dictionary_state *s = st;
    return tsjob_dictionary_build(r->ctx, &s->job, r->outs.output, &s->n_atoms, err);
}

static void dictionary_report(void *st, cli_run *r)
{
    dictionary_state *s = st;
    if (r->co->progress != PROGRESS_QUIET)
        printf("dictionary: %zu atoms (factor %d, patch %d, cells of %g m)\n", s->n_atoms,
               s->job.params.factor, s->job.params.patch, s->job.resolution);
}

const cli_job cli_dictionary_job = {
    "dictionary",
    "build an amplification dictionary once (build), or show one (info)",
    "Usage: terrasynth dictionary build D.tsd --exemplar EX --resolution M [options]\n"
    "       terrasynth dictionary info D.tsd\n"
    "\n"
    "Build an amplification dictionary once (the exemplars resampled to cells of M\n"
    "metres, the size of the amplified DEMs' cells, area-averaged by the factor, cut\n"
    "into atoms) and reuse it: terrasynth amplify IN OUT --dictionary D.tsd. The file\n"
    "is portable (little-endian, versioned); info prints what it holds.\n",
    "  terrasynth dictionary build alps.tsd --exemplar alps_25m.tif --resolution 25 "
    "--factor 8\n",
    3,
    sizeof(dictionary_state),
    dictionary_build,
    NULL,
    NULL,
    dictionary_compute,
    NULL,
    dictionary_report,
    NULL,
};

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
        int L, K, irr, l, version = 0;
        unsigned char h[16 + 12];
        /* read whole and verified above: its format's version from the header */
        if (tsio_read_head(path, h, sizeof h, &err) == (int)sizeof h)
            version = h[24] | h[25] << 8;
        ts_dictionary_shape(d, &factor, &patch);
        ts_dictionary_layers(d, &L, &K, &irr);
        printf("{\"file\": \"%s\", \"version\": %d, \"checksum\": \"%s\", \"factor\": %d, "
               "\"patch\": %d, \"atoms\": %zu, "
               "\"resolution_m\": %.17g, \"input_cell_m\": %.17g, \"irradiance\": %s, "
               "\"classes\": %d, \"layers\": [",
               path, version, version >= 3 ? "verified" : "none (version 2: build it again)",
               factor, patch, ts_dictionary_size(d), res, res * factor, irr ? "true" : "false", K);
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
    int i;
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            cli_command_help(stdout, &cli_dictionary_job);
            return 0;
        }
    if (argc == 4 && !strcmp(argv[2], "info"))
        return dictionary_info(argv[3]);
    if (argc < 3 || strcmp(argv[2], "build") != 0) {
        cli_usage_error("dictionary", "%s", "give build or info");
        return EXIT_USAGE;
    }
    return cli_run_job(&cli_dictionary_job, argc, argv);
}
