/*
 * cli_run.c - the one runner of every job command: help, argv into the
 * job's values, the job built from them (every rule checked), then either
 * a recipe written or the run: a stage opened, inputs read and outputs
 * checked before the work, the work, the outputs written and committed all
 * together, a summary.  The commands give their hooks (cli.h).
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

void cli_command_help(FILE *out, const cli_job *job)
{
    const cli_common_option *c;
    fputs(job->usage, out);
    fputc('\n', out);
    cli_job_help(out, tsjob_find(job->name));
    fprintf(out, "\nCommon options:\n");
    for (c = cli_common_options; c->left; c++)
        cli_help_line(out, c->left, c->help);
    fprintf(out, "\nExample:\n%s", job->example);
}

/* The run after the job is built: recipe, or stage, prepare, compute, write,
 * commit, report.  0, or -1 after printing the error. */
static int run_built(const cli_job *job, void *st, cli_run *r)
{
    const char *recipe_path = tsjob_get(r->values, "recipe", 0);
    int progress_state = -1;
    tsio_err err;
    if (recipe_path && job->check_recipe) {
        ts_ctx_set_seed(r->ctx, r->seed);
        ts_ctx_set_threads(r->ctx, r->co->threads);
        cli_set_progress(r->ctx, r->co->progress, &progress_state);
        if (job->check_recipe(st, r, recipe_path, &err) != 0 ||
            tsrecipe_write(recipe_path, r->values, &err) != 0) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            return -1;
        }
        return 0;
    }
    /* the inputs read, the memory estimated and every output checked before
     * the work; the outputs are written all or none (a stage) */
    tsio_stage_begin();
    if ((job->prepare && job->prepare(st, r, &err) != 0)) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        tsio_stage_abort();
        return -1;
    }
    ts_ctx_set_seed(r->ctx, r->seed);
    ts_ctx_set_threads(r->ctx, r->co->threads);
    cli_set_progress(r->ctx, r->co->progress, &progress_state);
    if (job->compute(st, r, &err) != 0 || (job->write && job->write(st, r, &err) != 0)) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        tsio_stage_abort();
        return -1;
    }
    /* a failed commit cleans up itself */
    if (tsio_stage_commit(&err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        return -1;
    }
    if (job->report)
        job->report(st, r);
    return 0;
}

int cli_run_job(const cli_job *job, int argc, char **argv)
{
    common_opts co = {job->name, NULL, NULL, PROGRESS_BAR, 0, 0};
    cli_run r;
    tsjob_values v;
    char msg[1024] = "";
    void *st;
    int i, rc = EXIT_RUN;

    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            cli_command_help(stdout, job);
            return 0;
        }
    memset(&r, 0, sizeof r);
    r.ctx = ts_ctx_new();
    st = calloc(1, job->size);
    if (!r.ctx || !st) {
        fprintf(stderr, "terrasynth: out of memory\n");
        ts_ctx_free(r.ctx);
        free(st);
        return EXIT_RUN;
    }
    tsjob_values_init(&v, tsjob_find(job->name));
    r.co = &co;
    r.values = &v;
    if (cli_parse_argv(&v, argc, argv, job->first, cli_skip_common, &co, msg, sizeof msg) != 0) {
        if (msg[0])
            cli_usage_error(job->name, "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    r.outs.output = tsjob_get(&v, "output", 0);
    r.outs.lines = tsjob_get(&v, "lines", 0);
    r.outs.preview = tsjob_get(&v, "preview", 0);
    r.outs.debug_dir = tsjob_get(&v, "debug_dir", 0);
    r.outs.flow_lines = tsjob_get(&v, "flow_lines", 0);
    if (tsjob_get(&v, "flow_cells", 0))
        r.outs.flow_cells = atof(tsjob_get(&v, "flow_cells", 0));
    if (tsjob_get(&v, "flow_km2", 0))
        r.outs.flow_km2 = atof(tsjob_get(&v, "flow_km2", 0));
    r.outs.format = co.format;
    r.outs.create_options = (const char *const *)co.create_options;
    if (job->build(st, &r, msg, sizeof msg) != 0) {
        cli_usage_error(job->name, "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    rc = co.check ? 0 : run_built(job, st, &r) == 0 ? 0 : EXIT_RUN;
done:
    if (job->free)
        job->free(st);
    free(st);
    tsjob_values_free(&v);
    CSLDestroy(co.create_options);
    ts_ctx_free(r.ctx);
    return rc;
}
