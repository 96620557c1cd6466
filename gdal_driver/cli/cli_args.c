/*
 * cli_args.c - a job's values from the command line (flags generated from the
 * declarations) and its --help.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_conv.h>
#include <cpl_string.h>

#include "cli.h"
#include "jobspec.h"

/* "profile_length" -> "--profile-length" */
void cli_flag_of(const char *name, char *buf, size_t len)
{
    size_t i = 2;
    buf[0] = buf[1] = '-';
    for (; *name && i + 1 < len; name++)
        buf[i++] = *name == '_' ? '-' : *name;
    buf[i] = '\0';
}

/* ------------------------------------------------------------------ */
/* Command line                                                        */
/* ------------------------------------------------------------------ */

/* "--alpha-h" (or "--alpha-h=..."): the name "alpha_h" into buf; 0 if arg
 * is not a long flag. */
static int flag_to_name(const char *arg, char *buf, size_t len, const char **inline_value)
{
    size_t i = 0;
    const char *p;
    *inline_value = NULL;
    if (strncmp(arg, "--", 2) != 0 || !arg[2])
        return 0;
    for (p = arg + 2; *p && *p != '=' && i + 1 < len; p++)
        buf[i++] = *p == '-' ? '_' : *p;
    buf[i] = '\0';
    if (*p == '=')
        *inline_value = p + 1;
    return 1;
}

int cli_parse_argv(tsjob_values *v, int argc, char **argv, int first,
                   int (*skip)(int argc, char **argv, int *i, void *user), void *user, char *msg,
                   size_t len)
{
    int i, positional = 0;
    v->cli = 1;
    for (i = first; i < argc; i++) {
        const char *a = argv[i], *inl;
        char name[128];
        const tsjob_option *o;
        if (skip) {
            int r = skip(argc, argv, &i, user);
            if (r < 0)
                return -1;
            if (r > 0)
                continue;
        }
        if (flag_to_name(a, name, sizeof name, &inl)) {
            o = tsjob_option_find(v->job, name);
            if (!o && !tsjob_param_stage(v->job, name)) {
                snprintf(msg, len, "unknown option '%s'", a);
                return -1;
            }
            if (o && o->kind == TSJOB_CHOICE) {
                if (inl) {
                    snprintf(msg, len, "%s takes no value", a);
                    return -1;
                }
                tsjob_set(v, name, "1");
                continue;
            }
            if (!inl) {
                if (i + 1 >= argc) {
                    snprintf(msg, len, "%s needs a value", a);
                    return -1;
                }
                inl = argv[++i];
            }
            if (o && o->max_count > 1 && tsjob_count(v, name) >= o->max_count) {
                snprintf(msg, len, "%s: at most %d", name, o->max_count);
                return -1;
            }
            tsjob_set(v, name, inl);
            continue;
        }
        if (a[0] == '-' && a[1] != '\0') {
            snprintf(msg, len, "unknown option '%s'", a);
            return -1;
        }
        /* a plain argument: the next positional option */
        positional++;
        {
            size_t k;
            o = NULL;
            for (k = 0; k < v->job->n_opts; k++)
                if (v->job->opts[k].positional == positional)
                    o = &v->job->opts[k];
            if (!o) {
                snprintf(msg, len, "unexpected argument '%s'", a);
                return -1;
            }
            tsjob_set(v, o->name, a);
        }
    }
    return 0;
}

void cli_job_help(FILE *out, const tsjob_decl *job)
{
    const char *groups[8];
    int n_groups = 0, g, s;
    size_t k;
    for (k = 0; k < job->n_opts; k++) {
        int seen = 0;
        for (g = 0; g < n_groups; g++)
            seen |= !strcmp(groups[g], job->opts[k].group);
        if (!seen && n_groups < 8)
            groups[n_groups++] = job->opts[k].group;
    }
    for (g = 0; g < n_groups; g++) {
        fprintf(out, "%s:\n", groups[g]);
        for (k = 0; k < job->n_opts; k++) {
            const tsjob_option *o = &job->opts[k];
            char flag[64], left[160];
            if (strcmp(o->group, groups[g]) != 0)
                continue;
            cli_flag_of(o->name, flag, sizeof flag);
            if (o->positional)
                snprintf(left, sizeof left, "%s", o->metavar);
            else if (o->kind == TSJOB_CHOICE)
                snprintf(left, sizeof left, "%s", flag);
            else
                snprintf(left, sizeof left, "%s %s", flag, o->metavar);
            cli_help_line(out, left, o->help);
        }
        fputc('\n', out);
    }
    for (s = 0; job->stages[s]; s++) {
        if (!strcmp(job->stages[s], "sketch"))
            fprintf(out, "Sketch parameters (with --sketch):\n");
        else
            fprintf(out, "%s parameters:\n",
                    !strcmp(job->stages[s], "ppa")       ? "PPA"
                    : !strcmp(job->stages[s], "amplify") ? "Amplification"
                                                         : "Synthesis");
        cli_params_help(out, job->stages[s], NULL);
        fputc('\n', out);
    }
    fprintf(out, "Rules:\n");
    for (k = 0; k < job->n_rules; k++) {
        const tsjob_rule *r = &job->rules[k];
        char line[256];
        int i;
        size_t n = 0;
        static const char *const kinds[] = {"needs", "excludes",     "goes with",
                                            "or",    "needs one of", "or"};
        if (!strcmp(r->a, "output"))
            continue; /* the usage line says it */
        n += (size_t)snprintf(
            line + n, sizeof line - n, "%s %s", r->a[0] == '@' ? "the sketch parameters" : r->a,
            r->kind == TSJOB_ONE_OF || r->kind == TSJOB_ANY_OF ? "," : kinds[r->kind]);
        for (i = 0; r->b[i] && n < sizeof line; i++)
            n += (size_t)snprintf(line + n, sizeof line - n, "%s %s",
                                  i ? (r->kind == TSJOB_ONE_OF || r->kind == TSJOB_ANY_OF ||
                                               r->kind == TSJOB_NEEDS_ANY
                                           ? " or"
                                           : ",")
                                    : "",
                                  r->b[i]);
        if (r->kind == TSJOB_ONE_OF && n < sizeof line)
            snprintf(line + n, sizeof line - n, ": exactly one");
        if (r->kind == TSJOB_ANY_OF && n < sizeof line)
            snprintf(line + n, sizeof line - n, ": at least one");
        fprintf(out, "  %s\n", line);
    }
}

void cli_help_line(FILE *out, const char *left, const char *text)
{
    const char *p = text;
    int first = 1;
    while (*p || first) {
        size_t n = strlen(p), cut = n;
        if (n > 50) {
            cut = 50;
            while (cut > 0 && p[cut] != ' ')
                cut--;
            if (cut == 0)
                cut = 50;
        }
        fprintf(out, "  %-32s %.*s\n", first ? left : "", (int)cut, p);
        p += cut;
        while (*p == ' ')
            p++;
        first = 0;
    }
}

void cli_params_help(FILE *out, const char *stage, const char *const *skip)
{
    size_t n, k;
    const ts_param_desc *d = ts_params_describe(stage, &n);
    for (k = 0; k < n; k++) {
        char flag[128], left[200];
        const char *const *s;
        int skipped = 0;
        for (s = skip; s && *s; s++)
            if (strcmp(*s, d[k].name) == 0)
                skipped = 1;
        if (skipped)
            continue;
        cli_flag_of(d[k].name, flag, sizeof flag);
        switch (d[k].type) {
        case TS_PARAM_ENUM:
            snprintf(left, sizeof left, "%s %s", flag, d[k].choices);
            break;
        case TS_PARAM_LENGTH:
            snprintf(left, sizeof left, "%s L[m]", flag);
            break;
        default:
            snprintf(left, sizeof left, "%s %s", flag, d[k].type == TS_PARAM_INT ? "N" : "X");
        }
        cli_help_line(out, left, d[k].help);
        if (d[k].type == TS_PARAM_ENUM) {
            const char *w = d[k].choices, *bar;
            int idx;
            for (idx = 0; idx < (int)d[k].def && (bar = strchr(w, '|')); idx++)
                w = bar + 1;
            bar = strchr(w, '|');
            fprintf(out, "  %-32s default %.*s\n", "", bar ? (int)(bar - w) : (int)strlen(w), w);
        } else {
            fprintf(out, "  %-32s default %g%s, range %g..%g %s\n", "", d[k].def,
                    d[k].type == TS_PARAM_LENGTH ? (d[k].def_unit ? " m" : " cells") : "", d[k].min,
                    d[k].max, d[k].type == TS_PARAM_LENGTH ? "" : d[k].units);
        }
    }
}
