/*
 * cli.h - what the commands of the `terrasynth` program share (cli_main.c):
 * exit codes, progress, the options every command takes.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_CLI_H
#define TS_CLI_H

#include <stdio.h>

#include "terrasynth.h"

#define EXIT_RUN 1
#define EXIT_USAGE 2

typedef enum { PROGRESS_BAR, PROGRESS_LINES, PROGRESS_QUIET } progress_mode;

/* The options every command takes (the command line's own: formats,
 * threads, progress). */
typedef struct common_opts {
    const char *cmd;
    const char *format;
    char **create_options; /* CSL list */
    progress_mode progress;
    int threads;
} common_opts;

/* Their help lines. */
extern const char cli_common_help[];

/* "terrasynth CMD: <fmt with arg> (see 'terrasynth CMD --help')" on stderr. */
void cli_usage_error(const char *cmd, const char *fmt, const char *arg);

/* cli_parse_argv's hook for the common options (user: a common_opts). */
int cli_skip_common(int argc, char **argv, int *i, void *user);

/* The progress display of `mode` on ctx (state: an int set to -1). */
void cli_set_progress(ts_ctx *ctx, progress_mode mode, int *state);

/* cli_args.c: a job's values from argv[first..argc) (flags of its options,
 * --name VALUE or --name=VALUE, of its stages' parameters, and positional
 * arguments); flags the caller handles itself (the common options) are
 * consumed by `skip` (1 taken, 0 not its own, -1 an error it printed).
 * 0, or -1 with the message in msg. */
struct tsjob_values;
struct tsjob_decl;
int cli_parse_argv(struct tsjob_values *v, int argc, char **argv, int first,
                   int (*skip)(int argc, char **argv, int *i, void *user), void *user, char *msg,
                   size_t len);
/* The job's options by group, its stages' parameters and its rules as help
 * lines. */
void cli_job_help(FILE *out, const struct tsjob_decl *job);
/* "profile_length" -> "--profile-length" */
void cli_flag_of(const char *name, char *buf, size_t len);
/* One option's help: `left` (flag and value), then `text` wrapped at 50
 * columns beside it. */
void cli_help_line(FILE *out, const char *left, const char *text);
/* A stage's parameters as help lines: flag, units, default, range
 * (skipping the names in `skip`, NULL-ended, or none). */
void cli_params_help(FILE *out, const char *stage, const char *const *skip);
/* cli_describe.c: every job's options and rules as describe's "jobs". */
void cli_describe_jobs(FILE *out);

int cli_ppa(int argc, char **argv);
int cli_synth(int argc, char **argv);
int cli_amplify(int argc, char **argv);
int cli_pixel(int argc, char **argv);
int cli_dictionary(int argc, char **argv);
int cli_describe(int argc, char **argv);

#endif
