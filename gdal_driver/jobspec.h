/*
 * jobspec.h - one declaration per job (ppa, synth): every option a job takes
 * besides the core's stage parameters (inputs, the target grid,
 * constraints, outputs), with its command-line flag, its form in a recipe,
 * its help, and the rules between options (GRASS's G_option_requires /
 * exclusive / collective, libvips's argument introspection).  Every front
 * end goes through it:
 *
 *   the CLI      parses argv into values (tsj_parse_argv), prints --help
 *                (tsj_help);
 *   recipes      read their XML into values (tsj_from_xml) and are written
 *                from values (tsj_to_xml);
 *   describe     prints the options and rules as JSON (tsj_describe), which
 *                the QGIS provider builds its dialogs from;
 *
 * and one function turns values into the job, checking every rule
 * (tsj_build_synth, tsj_build_ppa), so every front end rejects the same
 * bad combinations with the same message.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_JOBSPEC_H
#define TS_JOBSPEC_H

#include <stdint.h>
#include <stdio.h>

#include <cpl_minixml.h>

#include "tsjob.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum tsj_kind {
    TSJ_FILE,   /* an input dataset name */
    TSJ_OUTPUT, /* an output file or folder (command line only) */
    TSJ_NUMBER, /* a real number in [min, max] */
    TSJ_INT,    /* a whole number in [min, max] */
    TSJ_SEED,   /* a non-negative 64-bit integer */
    TSJ_TEXT,   /* free text (a CRS) */
    TSJ_SIZE,   /* WxH in cells */
    TSJ_XY,     /* X,Y */
    TSJ_PIN,    /* FILE:XOFF,YOFF,W,H@X,Y */
    TSJ_RULE,   /* ID=FILE */
    TSJ_CHOICE, /* one of `choices` ("ridges|valleys|both") */
    TSJ_NAMED,  /* NAME=FILE: an input file under a name (letters, digits, _ and -) */
    TSJ_PAIR    /* FILE=FILE: two input files (the first without '='); in recipes the
                 * element's text is the second, attribute `choices` the first */
} tsj_kind;

typedef struct tsj_option {
    const char *name;     /* snake_case; flag --name-with-dashes */
    tsj_kind kind;
    int max_count;        /* how often it may be given (1: once) */
    double min, max;      /* TSJ_NUMBER, TSJ_INT, TSJ_SIZE */
    const char *metavar;  /* in --help */
    const char *group;    /* the --help section */
    const char *help;
    /* the recipe form: "Element" (its text), "Element@attr", "@attr" (of
     * the job's element), "Element@a@b" (TSJ_SIZE, TSJ_XY: two attributes);
     * NULL: not in recipes.  TSJ_PIN, TSJ_RULE (id="N") and TSJ_NAMED
     * (name="NAME") use the element's text and attributes of their own. */
    const char *xml;
    int positional;       /* > 0: also the n-th plain argument of the command line */
    const char *choices;  /* TSJ_CHOICE */
} tsj_option;

typedef enum tsj_rule_kind {
    TSJ_REQUIRES, /* a needs every b */
    TSJ_EXCLUDES, /* a forbids every b */
    TSJ_TOGETHER, /* all or none of a and b */
    TSJ_ONE_OF,   /* exactly one of a and b */
    TSJ_NEEDS_ANY, /* a needs at least one of b */
    TSJ_ANY_OF    /* at least one of a and b */
} tsj_rule_kind;

typedef struct tsj_rule {
    tsj_rule_kind kind;
    const char *a;         /* an option, or "@STAGE": any parameter of that stage */
    const char *b[6];      /* NULL-terminated */
    const char *message;   /* "%s" stands for the offending option */
} tsj_rule;

typedef struct tsj_job {
    const char *name;      /* "ppa", "synth": also the recipe's element and the command */
    const tsj_option *opts;
    size_t n_opts;
    const tsj_rule *rules;
    size_t n_rules;
    const char *stages[3]; /* the core stages whose parameters the job takes (NULL-ended) */
    const char *element;   /* its element in a recipe ("PPA", "Synth", "Amplify") */
} tsj_job;
/* The job whose recipe element `node` is (a child of <TerraSynth>), or NULL. */
const tsj_job *tsj_find_element(const CPLXMLNode *top, const CPLXMLNode **node);

/* The job declared as `name`, or NULL. */
const tsj_job *tsj_find(const char *name);
/* The option `name` of a job, or NULL. */
const tsj_option *tsj_option_find(const tsj_job *job, const char *name);
/* The core stage a parameter `name` of the job belongs to, or NULL. */
const char *tsj_param_stage(const tsj_job *job, const char *name);

/*
 * What a front end was given: "name=value" in the order given (options and
 * stage parameters alike; repeatable options appear once per value).  Owned
 * strings; tsj_values_free frees them.
 */
typedef struct tsj_values {
    const tsj_job *job;
    char **kv;    /* CSL list */
    char **keep;  /* strings the built job points into */
    int cli;      /* from a command line: its rules about outputs apply */
} tsj_values;

void tsj_values_init(tsj_values *v, const tsj_job *job);
void tsj_values_free(tsj_values *v);
/* Add (append) a value; a non-repeatable option or a parameter given again
 * replaces the earlier value. */
void tsj_set(tsj_values *v, const char *name, const char *value);
int tsj_count(const tsj_values *v, const char *name);
/* The k-th value of `name` (0-based), or NULL. */
const char *tsj_get(const tsj_values *v, const char *name, int k);

/*
 * Check the rules and turn the values into the job (synth: the job, its
 * seed; ppa: the job).  0, or -1 with one line in msg (no file name: the
 * front end adds its own context).  The job points into v, which must
 * outlive it.
 */
int tsj_build_synth(tsj_values *v, tsjob_synth *job, uint64_t *seed, char *msg, size_t len);
int tsj_build_ppa(tsj_values *v, tsjob_ppa *job, char *msg, size_t len);
int tsj_build_amplify(tsj_values *v, tsjob_amplify *job, char *msg, size_t len);
int tsj_build_pixel(tsj_values *v, tsjob_pixel *job, uint64_t *seed, char *msg, size_t len);

/* Command line.  Parse argv[first..argc) into v: flags of the options
 * (--name VALUE or --name=VALUE), of the stage parameters, and positional
 * arguments.  Flags the caller handles itself (common output options) are
 * skipped when `skip` (argv index -> nonzero) says so.  0, or -1 with the
 * message in msg. */
int tsj_parse_argv(tsj_values *v, int argc, char **argv, int first,
                   int (*skip)(int argc, char **argv, int *i, void *user), void *user, char *msg,
                   size_t len);
/* The options, the stage parameters and the rules of the job as help
 * lines, by group. */
void tsj_help(FILE *out, const tsj_job *job);

/* Recipes.  Read the job's element into v: `resolve` turns a file name of
 * the recipe into the one to open (relative to the recipe) and may refuse
 * it (returning NULL with msg set).  0, or -1 with msg. */
int tsj_from_xml(tsj_values *v, const CPLXMLNode *node,
                 const char *(*resolve)(void *user, const char *name, char *msg, size_t len),
                 void *user, char *msg, size_t len);
/* Write v as the job's element under root; `rel` turns a file name into its
 * form in the recipe (relative to it). */
void tsj_to_xml(const tsj_values *v, CPLXMLNode *root,
                const char *(*rel)(void *user, const char *name), void *user);

/* Every job's options and rules as the "jobs" member of describe's JSON. */
void tsj_describe(FILE *out);

#ifdef __cplusplus
}
#endif
#endif
