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

int cli_groups(const tsjob_decl *job, const char *groups[8])
{
    int n_groups = 0, g;
    size_t k;
    for (k = 0; k < job->n_opts; k++) {
        int seen = 0;
        for (g = 0; g < n_groups; g++)
            seen |= !strcmp(groups[g], job->opts[k].group);
        if (!seen && n_groups < 8)
            groups[n_groups++] = job->opts[k].group;
    }
    return n_groups;
}

void cli_option_left(const tsjob_option *o, char *left, size_t len)
{
    char flag[64];
    cli_flag_of(o->name, flag, sizeof flag);
    if (o->positional)
        snprintf(left, len, "%s", o->metavar);
    else if (o->kind == TSJOB_CHOICE)
        snprintf(left, len, "%s", flag);
    else
        snprintf(left, len, "%s %s", flag, o->metavar);
}

const char *cli_stage_title(const char *stage)
{
    return !strcmp(stage, "sketch")     ? "Sketch parameters (with --sketch)"
           : !strcmp(stage, "ppa")      ? "PPA parameters"
           : !strcmp(stage, "amplify")  ? "Amplification parameters"
           : !strcmp(stage, "drainage") ? "Drainage parameters (after the method)"
                                        : "Synthesis parameters";
}

int cli_rule_text(const tsjob_rule *r, char *line, size_t len)
{
    static const char *const kinds[] = {"needs", "excludes",     "goes with",
                                        "or",    "needs one of", "or"};
    int i, any = r->kind == TSJOB_ONE_OF || r->kind == TSJOB_ANY_OF;
    size_t n = 0;
    if (!strcmp(r->a, "output"))
        return 0; /* the usage line says it */
    n += (size_t)snprintf(line + n, len - n, "%s %s",
                          r->a[0] == '@' ? "the sketch parameters" : r->a,
                          any ? "," : kinds[r->kind]);
    for (i = 0; r->b[i] && n < len; i++)
        n += (size_t)snprintf(line + n, len - n, "%s %s",
                              i ? (any || r->kind == TSJOB_NEEDS_ANY ? " or" : ",") : "", r->b[i]);
    if (r->kind == TSJOB_ONE_OF && n < len)
        snprintf(line + n, len - n, ": exactly one");
    if (r->kind == TSJOB_ANY_OF && n < len)
        snprintf(line + n, len - n, ": at least one");
    return 1;
}

void cli_job_help(FILE *out, const tsjob_decl *job)
{
    const char *groups[8];
    int n_groups = cli_groups(job, groups), g, s;
    size_t k;
    for (g = 0; g < n_groups; g++) {
        fprintf(out, "%s:\n", groups[g]);
        for (k = 0; k < job->n_opts; k++) {
            char left[160];
            if (strcmp(job->opts[k].group, groups[g]) != 0)
                continue;
            cli_option_left(&job->opts[k], left, sizeof left);
            cli_help_line(out, left, job->opts[k].help);
        }
        fputc('\n', out);
    }
    for (s = 0; job->stages[s]; s++) {
        fprintf(out, "%s:\n", cli_stage_title(job->stages[s]));
        cli_params_help(out, job->stages[s], NULL);
        fputc('\n', out);
    }
    fprintf(out, "Rules:\n");
    for (k = 0; k < job->n_rules; k++) {
        char line[256];
        if (cli_rule_text(&job->rules[k], line, sizeof line))
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

void cli_param_left(const ts_param_desc *d, char *left, size_t len)
{
    char flag[128];
    cli_flag_of(d->name, flag, sizeof flag);
    switch (d->type) {
    case TS_PARAM_ENUM:
        snprintf(left, len, "%s %s", flag, d->choices);
        break;
    case TS_PARAM_LENGTH:
        snprintf(left, len, "%s L[m]", flag);
        break;
    default:
        snprintf(left, len, "%s %s", flag, d->type == TS_PARAM_INT ? "N" : "X");
    }
}

void cli_param_default(const ts_param_desc *d, char *buf, size_t len)
{
    if (d->type == TS_PARAM_ENUM) {
        const char *w = d->choices, *bar;
        int idx;
        for (idx = 0; idx < (int)d->def && (bar = strchr(w, '|')); idx++)
            w = bar + 1;
        bar = strchr(w, '|');
        snprintf(buf, len, "%.*s", bar ? (int)(bar - w) : (int)strlen(w), w);
    } else {
        snprintf(buf, len, "%g%s", d->def,
                 d->type == TS_PARAM_LENGTH ? (d->def_unit ? " m" : " cells") : "");
    }
}

void cli_params_help(FILE *out, const char *stage, const char *const *skip)
{
    size_t n, k;
    const ts_param_desc *d = ts_params_describe(stage, &n);
    for (k = 0; k < n; k++) {
        char left[200], def[128];
        const char *const *s;
        int skipped = 0;
        for (s = skip; s && *s; s++)
            if (strcmp(*s, d[k].name) == 0)
                skipped = 1;
        if (skipped)
            continue;
        cli_param_left(&d[k], left, sizeof left);
        cli_help_line(out, left, d[k].help);
        cli_param_default(&d[k], def, sizeof def);
        if (d[k].type == TS_PARAM_ENUM)
            fprintf(out, "  %-32s default %s\n", "", def);
        else
            fprintf(out, "  %-32s default %s, range %g..%g %s\n", "", def, d[k].min, d[k].max,
                    d[k].type == TS_PARAM_LENGTH ? "" : d[k].units);
    }
}

void cli_drainage_report(const ts_drainage_params *p, const ts_drainage_info *d, double seconds,
                         int width, int height)
{
    static const char *const modes[] = {"keep", "breach", "fill"};
    double cells = (double)width * (double)height;
    char depth[256] = "";
    if (p->mode == TS_DRAINAGE_KEEP)
        return;
    if (p->mode == TS_DRAINAGE_BREACH && p->bank_slope > 0)
        snprintf(depth, sizeof depth, ", banks %.3g per cell", p->bank_slope);
    if (p->mode == TS_DRAINAGE_BREACH && ts_drainage_depth_of(p) > 0)
        snprintf(depth + strlen(depth), sizeof depth - strlen(depth), ", cuts at most %.3g deep",
                 ts_drainage_depth_of(p));
    if (p->mode == TS_DRAINAGE_BREACH && p->shallow_depth > 0)
        snprintf(depth + strlen(depth), sizeof depth - strlen(depth),
                 " (%.3g beside drawn valleys)", p->shallow_depth);
    if (d->cells_lifted)
        snprintf(depth + strlen(depth), sizeof depth - strlen(depth),
                 "; basins wider than the radius lifted (%zu cells)", d->cells_lifted);
    if (d->basins_raised)
        snprintf(depth + strlen(depth), sizeof depth - strlen(depth),
                 "; %zu dammed basins raised to plains (%zu cells)", d->basins_raised,
                 d->cells_raised);
    printf("drainage: %s%s, %zu pits, %zu drained within %d cells; %zu cells changed (%.2f %%), "
           "mean %.2f; %.2f s\n",
           modes[p->mode], depth, d->pits, d->resolved, p->radius, d->cells_changed,
           cells > 0 ? 100.0 * (double)d->cells_changed / cells : 0.0, d->mean_change, seconds);
}
