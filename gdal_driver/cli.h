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

/* tsj_parse_argv's hook for the common options (user: a common_opts). */
int cli_skip_common(int argc, char **argv, int *i, void *user);

/* The progress display of `mode` on ctx (state: an int set to -1). */
void cli_set_progress(ts_ctx *ctx, progress_mode mode, int *state);

int cli_ppa(int argc, char **argv);
int cli_synth(int argc, char **argv);
int cli_amplify(int argc, char **argv);
int cli_pixel(int argc, char **argv);
int cli_dictionary(int argc, char **argv);
int cli_describe(int argc, char **argv);

#endif
