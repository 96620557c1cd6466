/*
 * cli.h - what the commands of the `terrasynth` program share: exit codes,
 * progress and the options every command takes (cli_main.c), argv and help
 * generated from the job declarations (cli_args.c), the one runner of every
 * job (cli_run.c) and the hooks each command gives it (cli_<command>.c).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_CLI_H
#define TS_CLI_H

#include <stdio.h>

#include "terrasynth.h"
#include "tsjob.h"

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
    int check; /* --check: the job built, nothing run */
} common_opts;

/* Their flags and help, NULL-ended (parsed in cli_main.c). */
typedef struct cli_common_option {
    const char *left; /* as --help shows it */
    const char *name; /* as describe names it */
    const char *kind; /* "int" (in min..max), "text" or "flag" */
    double min, max;
    const char *help;
} cli_common_option;
extern const cli_common_option cli_common_options[];

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
/* The job's option groups in their order of declaration (at most 8). */
int cli_groups(const struct tsjob_decl *job, const char *groups[8]);
/* An option as --help shows it: "--flag METAVAR", "--flag" or "METAVAR". */
struct tsjob_option;
void cli_option_left(const struct tsjob_option *o, char *left, size_t len);
/* A stage parameter as --help shows it ("--flag N") and its default. */
void cli_param_left(const ts_param_desc *d, char *left, size_t len);
void cli_param_default(const ts_param_desc *d, char *buf, size_t len);
/* The title of a stage's parameters ("PPA parameters"). */
const char *cli_stage_title(const char *stage);
/* A rule in words ("threshold excludes threshold_fraction"); 0 for a rule
 * the usage line says instead. */
struct tsjob_rule;
int cli_rule_text(const struct tsjob_rule *r, char *line, size_t len);
/* "profile_length" -> "--profile-length" */
/* The drainage stage's line of a job's summary (nothing for keep). */
void cli_drainage_report(const ts_drainage_params *p, const ts_drainage_info *d, double seconds,
                         int width, int height);

void cli_flag_of(const char *name, char *buf, size_t len);
/* One option's help: `left` (flag and value), then `text` wrapped at 50
 * columns beside it. */
void cli_help_line(FILE *out, const char *left, const char *text);
/* A stage's parameters as help lines: flag, units, default, range
 * (skipping the names in `skip`, NULL-ended, or none). */
void cli_params_help(FILE *out, const char *stage, const char *const *skip);
/* cli_describe.c: every job's options and rules as describe's "jobs". */
void cli_describe_jobs(FILE *out);

/*
 * One command that runs a declared job (cli_run.c runs it: help, argv into
 * values, the job built from them, a recipe written instead of the run, or
 * the run: inputs read and outputs checked, the work, the outputs written
 * all or none, a summary).  Each hook gets the command's own state (`size`
 * bytes, zeroed) and the run; a NULL hook is skipped.
 */
typedef struct cli_run {
    const common_opts *co;
    struct tsjob_values *values;
    tsjob_outputs outs; /* output, preview, lines, debug_dir from the values */
    ts_ctx *ctx;
    uint64_t seed; /* set by build when the job has a seed */
} cli_run;

typedef struct cli_job {
    const char *name;    /* the command and its job's declaration */
    const char *summary; /* its line in `terrasynth --help` */
    const char *usage;   /* its --help before the options: usage lines, what it does */
    const char *example; /* the example line(s) of its --help */
    int first;           /* argv index of its first option */
    size_t size;         /* its state */
    /* the values into the job (the declarations' rules checked): 0, or -1 with msg */
    int (*build)(void *st, cli_run *r, char *msg, size_t len);
    /* --recipe: the job as a recipe can hold it, and what the recipe keeps
     * beside it made (a sketch in tiles laid out) */
    int (*check_recipe)(void *st, cli_run *r, const char *path, tsio_err *err);
    /* inputs read, memory estimated, outputs checked (warnings printed) */
    int (*prepare)(void *st, cli_run *r, tsio_err *err);
    int (*compute)(void *st, cli_run *r, tsio_err *err);
    int (*write)(void *st, cli_run *r, tsio_err *err);
    /* after the outputs are in place: warnings and the summary line */
    void (*report)(void *st, cli_run *r);
    void (*free)(void *st);
} cli_job;

/* Run `job` with the command line argv (argv[1] its command): the exit code. */
int cli_run_job(const cli_job *job, int argc, char **argv);

/* A command's --help (job: a declared job's). */
void cli_command_help(FILE *out, const cli_job *job);

extern const cli_job cli_ppa_job, cli_synth_job, cli_amplify_job, cli_pixel_job, cli_dictionary_job;

/* The job command `name`, or NULL (cli_main.c). */
const cli_job *cli_job_find(const char *name);

/* A part of a job's manual in Markdown: "synopsis", "parameters",
 * "stage:NAME" or "recipe" (cli_markdown.c).  0, or -1 for an unknown job or part. */
int cli_markdown(FILE *out, const char *job, const char *part);

/* Commands of their own (dictionary info, describe) */
int cli_dictionary(int argc, char **argv);
int cli_describe(int argc, char **argv);

#endif
