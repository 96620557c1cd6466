/*
 * jobspec.h - one declaration per job (ppa, synth, amplify, dictionary,
 * pixel): every option a job takes
 * besides the core's stage parameters (inputs, the target grid,
 * constraints, outputs), with its command-line flag, its form in a recipe,
 * its help, and the rules between options (GRASS's G_option_requires /
 * exclusive / collective, libvips's argument introspection).  Every front
 * end goes through it:
 *
 *   the CLI      parses argv into values (cli_parse_argv), prints --help
 *                (cli_job_help);
 *   recipes      read their XML into values (tsrecipe_values_from_xml) and are written
 *                from values (tsrecipe_values_to_xml);
 *   describe     prints the options and rules as JSON (cli_describe_jobs), which
 *                the QGIS provider builds its dialogs from;
 *
 * and one function turns values into the job, checking every rule
 * (tsjob_build_synth, tsjob_build_ppa), so every front end rejects the same
 * bad combinations with the same message.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_JOBSPEC_H
#define TS_JOBSPEC_H

#include <cpl_minixml.h>
#include <stdint.h>

#include "tsjob.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum tsjob_kind {
    TSJOB_FILE,   /* an input dataset name */
    TSJOB_OUTPUT, /* an output file or folder (command line only) */
    TSJOB_NUMBER, /* a real number in [min, max] */
    TSJOB_INT,    /* a whole number in [min, max] */
    TSJOB_SEED,   /* a non-negative 64-bit integer */
    TSJOB_TEXT,   /* free text (a CRS) */
    TSJOB_SIZE,   /* WxH in cells */
    TSJOB_XY,     /* X,Y */
    TSJOB_PIN,    /* FILE:XOFF,YOFF,W,H@X,Y */
    TSJOB_RULE,   /* ID=FILE */
    TSJOB_CHOICE, /* one of `choices` ("ridges|valleys|both") */
    TSJOB_NAMED,  /* NAME=FILE: an input file under a name (letters, digits, _ and -) */
    TSJOB_PAIR    /* FILE=FILE: two input files (the first without '='); in recipes the
                   * element's text is the second, attribute `choices` the first */
} tsjob_kind;

typedef struct tsjob_option {
    const char *name; /* snake_case; flag --name-with-dashes */
    tsjob_kind kind;
    int max_count;       /* how often it may be given (1: once) */
    double min, max;     /* TSJOB_NUMBER, TSJOB_INT, TSJOB_SIZE */
    const char *metavar; /* in --help */
    const char *group;   /* the --help section */
    const char *help;
    /* the recipe form: "Element" (its text), "Element@attr", "@attr" (of
     * the job's element), "Element@a@b" (TSJOB_SIZE, TSJOB_XY: two attributes);
     * NULL: not in recipes.  TSJOB_PIN, TSJOB_RULE (id="N") and TSJOB_NAMED
     * (name="NAME") use the element's text and attributes of their own. */
    const char *xml;
    int positional;      /* > 0: also the n-th plain argument of the command line */
    const char *choices; /* TSJOB_CHOICE */
} tsjob_option;

typedef enum tsjob_rule_kind {
    TSJOB_REQUIRES,  /* a needs every b */
    TSJOB_EXCLUDES,  /* a forbids every b */
    TSJOB_TOGETHER,  /* all or none of a and b */
    TSJOB_ONE_OF,    /* exactly one of a and b */
    TSJOB_NEEDS_ANY, /* a needs at least one of b */
    TSJOB_ANY_OF     /* at least one of a and b */
} tsjob_rule_kind;

typedef struct tsjob_rule {
    tsjob_rule_kind kind;
    const char *a;       /* an option, or "@STAGE": any parameter of that stage */
    const char *b[6];    /* NULL-terminated */
    const char *message; /* "%s" stands for the offending option */
} tsjob_rule;

typedef struct tsjob_decl {
    const char *name; /* "ppa", "synth": also the recipe's element and the command */
    const tsjob_option *opts;
    size_t n_opts;
    const tsjob_rule *rules;
    size_t n_rules;
    const char *stages[4]; /* the core stages whose parameters the job takes (NULL-ended) */
    const char *element;   /* its element in a recipe ("PPA", "Synth", "Amplify") */
} tsjob_decl;
/* The job whose recipe element `node` is (a child of <TerraSynth>), or NULL. */
const tsjob_decl *tsjob_find_element(const CPLXMLNode *top, const CPLXMLNode **node);

/* The job declared as `name`, or NULL. */
const tsjob_decl *tsjob_find(const char *name);
/* The option `name` of a job, or NULL. */
const tsjob_option *tsjob_option_find(const tsjob_decl *job, const char *name);
/* The core stage a parameter `name` of the job belongs to, or NULL. */
const char *tsjob_param_stage(const tsjob_decl *job, const char *name);

/*
 * What a front end was given: "name=value" in the order given (options and
 * stage parameters alike; repeatable options appear once per value).  Owned
 * strings; tsjob_values_free frees them.
 */
typedef struct tsjob_values {
    const tsjob_decl *job;
    char **kv;   /* CSL list */
    char **keep; /* strings the built job points into */
    int cli;     /* from a command line: its rules about outputs apply */
} tsjob_values;

void tsjob_values_init(tsjob_values *v, const tsjob_decl *job);
void tsjob_values_free(tsjob_values *v);
/* Add (append) a value; a non-repeatable option or a parameter given again
 * replaces the earlier value. */
void tsjob_set(tsjob_values *v, const char *name, const char *value);
int tsjob_count(const tsjob_values *v, const char *name);
/* The k-th value of `name` (0-based), or NULL. */
const char *tsjob_get(const tsjob_values *v, const char *name, int k);

/*
 * Check the rules and turn the values into the job (synth: the job, its
 * seed; ppa: the job).  0, or -1 with one line in msg (no file name: the
 * front end adds its own context).  The job points into v, which must
 * outlive it.
 */
int tsjob_build_synth(tsjob_values *v, tsjob_synth *job, uint64_t *seed, char *msg, size_t len);
int tsjob_build_ppa(tsjob_values *v, tsjob_ppa *job, char *msg, size_t len);
int tsjob_build_amplify(tsjob_values *v, tsjob_amplify *job, char *msg, size_t len);
int tsjob_build_pixel(tsjob_values *v, tsjob_pixel *job, uint64_t *seed, char *msg, size_t len);

/* Every declared job in turn (i from 0), NULL past the last. */
const tsjob_decl *tsjob_at(size_t i);

#ifdef __cplusplus
}
#endif
#endif
