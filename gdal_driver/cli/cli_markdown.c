/*
 * cli_markdown.c - `terrasynth describe --markdown JOB PART`: the parts of
 * a job's manual generated from its declarations, so the manuals say what
 * the program takes: the SYNOPSIS (the command's usage lines), the
 * PARAMETERS (the options by group, each stage's parameters with default
 * and range, the rules between them, the common options), or one stage's
 * parameters alone (stage:NAME), or how each option is written in a
 * recipe (recipe).  tools/manuals.py writes them into the
 * manuals; tests/cli/test_manuals.py fails when a manual differs.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "jobspec.h"

/* Text in a table cell: '|' escaped. */
static void md_cell(FILE *out, const char *s)
{
    for (; *s; s++) {
        if (*s == '|')
            fputs("\\|", out);
        else
            fputc(*s, out);
    }
}

/* "a|b|c" as "a, b, c" */
static void md_choices(FILE *out, const char *s)
{
    for (; *s; s++) {
        if (*s == '|')
            fputs(", ", out);
        else
            fputc(*s, out);
    }
}

/* What values an option takes. */
static void md_values(FILE *out, const tsjob_option *o)
{
    switch (o->kind) {
    case TSJOB_NUMBER:
    case TSJOB_INT:
        fprintf(out, "%g..%g", o->min, o->max);
        break;
    case TSJOB_SIZE:
        fprintf(out, "%g..%g cells", o->min, o->max);
        break;
    case TSJOB_SEED:
        fputs("0..18446744073709551615", out);
        break;
    case TSJOB_CHOICE:
        fputs("(a flag)", out);
        break;
    case TSJOB_OUTPUT:
        fputs("a new file", out);
        break;
    case TSJOB_FILE:
    case TSJOB_NAMED:
    case TSJOB_PAIR:
    case TSJOB_RULE:
    case TSJOB_PIN:
        fputs("files GDAL reads", out);
        break;
    default:
        fputs("text", out);
    }
    if (o->max_count > 1)
        fprintf(out, "; up to %d times", o->max_count);
}

static void md_stage(FILE *out, const char *stage)
{
    size_t n, k;
    const ts_param_desc *d = ts_params_describe(stage, &n);
    fprintf(out, "| parameter | default | range | meaning |\n|---|---|---|---|\n");
    for (k = 0; k < n; k++) {
        char left[200], def[128];
        cli_param_left(&d[k], left, sizeof left);
        cli_param_default(&d[k], def, sizeof def);
        fputs("| `", out);
        md_cell(out, left);
        fprintf(out, "` | %s | ", def);
        if (d[k].type == TS_PARAM_ENUM)
            md_choices(out, d[k].choices);
        else
            fprintf(out, "%g..%g%s%s", d[k].min, d[k].max,
                    d[k].type == TS_PARAM_LENGTH || !d[k].units[0] ? "" : " ",
                    d[k].type == TS_PARAM_LENGTH ? "" : d[k].units);
        fputs(" | ", out);
        md_cell(out, d[k].help);
        fputs(" |\n", out);
    }
}

static void md_synopsis(FILE *out, const cli_job *job)
{
    const char *p = job->usage, *end = strstr(p, "\n\n");
    size_t n = end ? (size_t)(end - p) : strlen(p);
    fputs("```\n", out);
    /* "Usage: " and the lines aligned under it, without the indent */
    while (n > 0) {
        const char *nl = memchr(p, '\n', n);
        size_t len = nl ? (size_t)(nl - p) : n;
        size_t skip = !strncmp(p, "Usage: ", 7) ? 7 : (len >= 7 ? 7 : 0);
        fprintf(out, "%.*s\n", (int)(len - skip), p + skip);
        if (!nl)
            break;
        n -= len + 1;
        p = nl + 1;
    }
    fputs("```\n", out);
}

static void md_parameters(FILE *out, const cli_job *cj)
{
    const tsjob_decl *job = tsjob_find(cj->name);
    const cli_common_option *c;
    const char *groups[8];
    int n_groups = cli_groups(job, groups), g, s;
    size_t k;
    for (g = 0; g < n_groups; g++) {
        fprintf(out, "%s### %s\n\n| option | takes | meaning |\n|---|---|---|\n", g ? "\n" : "",
                groups[g]);
        for (k = 0; k < job->n_opts; k++) {
            const tsjob_option *o = &job->opts[k];
            char left[160];
            if (strcmp(o->group, groups[g]) != 0)
                continue;
            cli_option_left(o, left, sizeof left);
            fputs("| `", out);
            md_cell(out, left);
            fputs("` | ", out);
            md_values(out, o);
            fputs(" | ", out);
            md_cell(out, o->help);
            fputs(" |\n", out);
        }
    }
    for (s = 0; job->stages[s]; s++) {
        fprintf(out, "\n### %s\n\n", cli_stage_title(job->stages[s]));
        md_stage(out, job->stages[s]);
    }
    fprintf(out, "\n### Rules\n\n");
    for (k = 0; k < job->n_rules; k++) {
        char line[256];
        if (cli_rule_text(&job->rules[k], line, sizeof line))
            fprintf(out, "- %s\n", line);
    }
    fprintf(out, "\n### Common options\n\n| option | meaning |\n|---|---|\n");
    for (c = cli_common_options; c->left; c++) {
        fprintf(out, "| `%s` | ", c->left);
        md_cell(out, c->help);
        fputs(" |\n", out);
    }
}

/* How each option of the job is written in a recipe (jobspec.h: the
 * element's text, an attribute, a stage parameter as <Param>). */
static void md_recipe(FILE *out, const cli_job *cj)
{
    const tsjob_decl *job = tsjob_find(cj->name);
    size_t k;
    int s;
    fprintf(out, "| option | in a recipe (inside <%s>) |\n|---|---|\n", job->element);
    for (k = 0; k < job->n_opts; k++) {
        const tsjob_option *o = &job->opts[k];
        char flag[64];
        const char *at;
        if (!o->xml)
            continue;
        cli_flag_of(o->name, flag, sizeof flag);
        fprintf(out, "| `%s` | ", o->positional ? o->metavar : flag);
        at = strchr(o->xml, '@');
        if (o->max_count > 1 && (o->kind == TSJOB_PIN || o->kind == TSJOB_RULE ||
                                 o->kind == TSJOB_NAMED || o->kind == TSJOB_PAIR))
            fputs("repeatable: ", out);
        if (o->kind == TSJOB_PIN)
            fprintf(out, "`<%s xoff=\"\" yoff=\"\" width=\"\" height=\"\" x=\"\" y=\"\">FILE</%s>`",
                    o->xml, o->xml);
        else if (o->kind == TSJOB_RULE)
            fprintf(out, "`<%s id=\"ID\">FILE</%s>`", o->xml, o->xml);
        else if (o->kind == TSJOB_NAMED)
            fprintf(out, "`<%s name=\"NAME\">FILE</%s>`", o->xml, o->xml);
        else if (o->kind == TSJOB_PAIR) /* the attribute is named in `choices` */
            fprintf(out, "`<%s %s=\"FILE\">FILE</%s>`", o->xml, o->choices, o->xml);
        else if (o->xml[0] == '@')
            fprintf(out, "attribute `%s` of `<%s>`", o->xml + 1, job->element);
        else if (!at)
            fprintf(out, "`<%s>` text%s", o->xml, o->max_count > 1 ? ", repeatable" : "");
        else if (strchr(at + 1, '@'))
            fprintf(out, "attributes `%.*s` and `%s` of `<%.*s>`",
                    (int)(strchr(at + 1, '@') - at - 1), at + 1, strchr(at + 1, '@') + 1,
                    (int)(at - o->xml), o->xml);
        else
            fprintf(out, "attribute `%s` of `<%.*s>`", at + 1, (int)(at - o->xml), o->xml);
        fputs(" |\n", out);
    }
    for (s = 0; job->stages[s]; s++)
        fprintf(out, "| %s | `<Param name=\"NAME\">VALUE</Param>` |\n",
                cli_stage_title(job->stages[s]));
}

int cli_markdown(FILE *out, const char *name, const char *part)
{
    const cli_job *job = cli_job_find(name);
    size_t n;
    if (!job)
        return -1;
    if (!strcmp(part, "synopsis"))
        md_synopsis(out, job);
    else if (!strcmp(part, "parameters"))
        md_parameters(out, job);
    else if (!strcmp(part, "recipe"))
        md_recipe(out, job);
    else if (!strncmp(part, "stage:", 6) && ts_params_describe(part + 6, &n))
        md_stage(out, part + 6);
    else
        return -1;
    return 0;
}
