/*
 * cli_params.h - the command line generated from the core's parameter
 * descriptor tables (ts_params_describe): flags, parsing and help text.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_CLI_PARAMS_H
#define TS_CLI_PARAMS_H

#include <stdio.h>

#include "terrasynth.h"

/* If argv[*i] is a flag of `stage` ("--profile-length 11" or
 * "--profile-length=11"), parse it into params, advance *i past its value
 * and return 1; return 0 if it is not one of the stage's flags; return -1
 * (message in ctx) on a bad value or a missing one. */
int cli_params_parse(ts_ctx *ctx, const char *stage, void *params, int argc, char **argv, int *i);

/* One option's help: `left` (flag and value), then `text` wrapped at 50
 * columns beside it. */
void cli_help_line(FILE *out, const char *left, const char *text);

/* Print the stage's parameters as help lines: flag, units, default, help. */
void cli_params_help(FILE *out, const char *stage, const char *const *skip);

#endif
