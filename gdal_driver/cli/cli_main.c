/*
 * cli_main.c - the `terrasynth` command-line program: the table of
 * commands, the options every command shares, progress.
 *
 * A thin front end: the jobs (gdal_driver/jobs/) read with tsio, call the
 * core and write with tsio; options and rules come from the job
 * declarations and the core's parameter tables; cli_run.c runs any job.  Errors are one line on
 * stderr ("terrasynth: <file>: <problem>") and a non-zero exit: 1 for a
 * failed run, 2 for a usage error.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal.h>

#include "cli.h"
#include "tsio.h"

/* ------------------------------------------------------------------ */
/* Progress: GDAL's terminal bar, machine-readable lines, or nothing  */
/* ------------------------------------------------------------------ */

static int progress_lines(double done, const char *msg, void *user)
{
    int *last = user;
    int pct = (int)(done * 100.0);
    if (pct != *last) {
        *last = pct;
        printf("PROGRESS %d %s\n", pct, msg ? msg : "");
        fflush(stdout);
    }
    return 1;
}

static int progress_bar(double done, const char *msg, void *user)
{
    (void)user;
    (void)msg;
    return GDALTermProgress(done, NULL, NULL);
}

/* A note from the core while it works: a warning line (after the bar's dots). */
static void notice_line(const char *stage, const char *msg, void *user)
{
    if (user)
        fputc('\n', stderr);
    fprintf(stderr, "terrasynth: warning: %s: %s\n", stage, msg);
}

void cli_set_progress(ts_ctx *ctx, progress_mode mode, int *state)
{
    static int bar = 1;
    fflush(stdout);
    ts_ctx_set_notice(ctx, notice_line, mode == PROGRESS_BAR ? &bar : NULL);
    if (mode == PROGRESS_BAR)
        ts_ctx_set_progress(ctx, progress_bar, NULL);
    else if (mode == PROGRESS_LINES)
        ts_ctx_set_progress(ctx, progress_lines, state);
}

/* ------------------------------------------------------------------ */
/* Shared option handling                                             */
/* ------------------------------------------------------------------ */

void cli_usage_error(const char *cmd, const char *fmt, const char *arg)
{
    size_t n = strlen(cmd);
    fprintf(stderr, "terrasynth %s: ", cmd);
    /* a message of the core that names the command already ("synth: ...") */
    if (arg && !strcmp(fmt, "%s") && !strncmp(arg, cmd, n) && arg[n] == ':' && arg[n + 1] == ' ')
        arg += n + 2;
    fprintf(stderr, fmt, arg);
    fprintf(stderr, " (see 'terrasynth %s --help')\n", cmd);
}

/* Parse an option shared by every command; returns 1 if consumed, 0 if
 * not ours, -1 on error (message printed). */
static int parse_common(const char *cmd, common_opts *o, int argc, char **argv, int *i)
{
    const char *a = argv[*i];
    const char *value = *i + 1 < argc ? argv[*i + 1] : NULL;
    char *end;
    if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
        o->progress = PROGRESS_QUIET;
        return 1;
    }
    if (!strcmp(a, "--progress-lines")) {
        o->progress = PROGRESS_LINES;
        return 1;
    }
    if (!strcmp(a, "--check")) {
        o->check = 1;
        return 1;
    }
    if (!strcmp(a, "-of") || !strcmp(a, "-co") || !strcmp(a, "--threads") ||
        !strcmp(a, "--max-memory")) {
        if (!value) {
            cli_usage_error(cmd, "%s needs a value", a);
            return -1;
        }
        ++*i;
        if (!strcmp(a, "-of")) {
            o->format = value;
        } else if (!strcmp(a, "-co")) {
            if (!strchr(value, '=')) {
                cli_usage_error(cmd, "-co takes KEY=VALUE, not '%s'", value);
                return -1;
            }
            o->create_options = CSLAddString(o->create_options, value);
        } else if (!strcmp(a, "--max-memory")) {
            uint64_t bytes;
            if (tsio_parse_memory(value, &bytes) != 0) {
                cli_usage_error(cmd,
                                "--max-memory takes an amount of memory (2G, 500M, 512 = MB, "
                                "50%%), not '%s'",
                                value);
                return -1;
            }
            /* the same option the GDAL driver reads (--config TSYN_MAX_MEMORY) */
            CPLSetConfigOption("TSYN_MAX_MEMORY", value);
        } else {
            const cli_common_option *th = &cli_common_options[2];
            long t = strtol(value, &end, 10);
            if (*end || !*value || t < th->min || t > th->max) {
                char msg[96];
                snprintf(msg, sizeof msg, "--threads must be %g..%g, not '%%s'", th->min, th->max);
                cli_usage_error(cmd, msg, value);
                return -1;
            }
            o->threads = (int)t;
        }
        return 1;
    }
    return 0;
}

/* cli_parse_argv's hook for the options every command shares (they are the
 * command line's own: formats, threads, progress) */
int cli_skip_common(int argc, char **argv, int *i, void *user)
{
    common_opts *co = user;
    return parse_common(co->cmd, co, argc, argv, i);
}

const cli_common_option cli_common_options[] = {
    {"-of FORMAT", "format", "text", 0, 0,
     "GDAL output format (default: from the extension, else GTiff)"},
    {"-co KEY=VALUE", "co", "text", 0, 0, "creation option (repeatable)"},
    {"--threads N", "threads", "int", 0, 256, "worker threads (default 0 = all cores)"},
    {"--max-memory M", "max_memory", "text", 0, 0,
     "refuse a job that needs more (2G, 500M, 50%; default the machine's memory; "
     "TSYN_MAX_MEMORY)"},
    {"--progress-lines", "progress_lines", "flag", 0, 0,
     "print 'PROGRESS <percent> <stage>' lines"},
    {"-q, --quiet", "quiet", "flag", 0, 0, "no progress bar or summary"},
    {"--check", "check", "flag", 0, 0,
     "check the options and the rules between them, then exit: nothing is read or written"},
    {NULL, NULL, NULL, 0, 0, NULL},
};

/* ------------------------------------------------------------------ */
/* The commands                                                        */
/* ------------------------------------------------------------------ */

typedef struct command {
    const char *name;
    const cli_job *job;                /* a job run by cli_run_job ... */
    int (*own)(int argc, char **argv); /* ... or a command of its own */
    const char *summary;               /* (then its line in the help) */
} command;

static const command commands[] = {
    {"ppa", &cli_ppa_job, NULL, NULL},
    {"synth", &cli_synth_job, NULL, NULL},
    {"amplify", &cli_amplify_job, NULL, NULL},
    {"dictionary", &cli_dictionary_job, cli_dictionary, NULL},
    {"pixel", &cli_pixel_job, NULL, NULL},
    {"describe", NULL, cli_describe, "print every stage's parameters as JSON (for front ends)"},
};

const cli_job *cli_job_find(const char *name)
{
    size_t k;
    for (k = 0; k < sizeof commands / sizeof commands[0]; k++)
        if (commands[k].job && !strcmp(commands[k].job->name, name))
            return commands[k].job;
    return NULL;
}

static void main_help(FILE *out)
{
    size_t k;
    fprintf(out,
            "Usage: terrasynth COMMAND [options]\n"
            "\n"
            "TerraSynth %s: terrain synthesis from real DEMs.\n"
            "\n"
            "Commands:\n",
            ts_version());
    for (k = 0; k < sizeof commands / sizeof commands[0]; k++)
        fprintf(out, "  %-10s %s\n", commands[k].name,
                commands[k].summary ? commands[k].summary : commands[k].job->summary);
    fprintf(out, "\n"
                 "'terrasynth COMMAND --help' lists a command's options with defaults and units.\n"
                 "  --version  print the version\n");
}

int main(int argc, char **argv)
{
    int rc = -1;
    size_t k;
    if (argc < 2) {
        main_help(stderr);
        return EXIT_USAGE;
    }
    if (!strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) {
        main_help(stdout);
        return 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("terrasynth %s (GDAL %s)\n", ts_version(), GDALVersionInfo("RELEASE_NAME"));
        return 0;
    }
    GDALAllRegister();
    /* Ctrl-C, kill, a closed terminal: no unfinished output is left behind */
    tsio_cleanup_on_signals("terrasynth");
    for (k = 0; k < sizeof commands / sizeof commands[0] && rc < 0; k++)
        if (!strcmp(argv[1], commands[k].name))
            rc = commands[k].own ? commands[k].own(argc, argv)
                                 : cli_run_job(commands[k].job, argc, argv);
    if (rc < 0) {
        fprintf(stderr, "terrasynth: unknown command '%s' (see 'terrasynth --help')\n", argv[1]);
        rc = EXIT_USAGE;
    }
    GDALDestroyDriverManager();
    return rc;
}
