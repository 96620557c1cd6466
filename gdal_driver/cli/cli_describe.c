/*
 * cli_describe.c - `terrasynth describe`: every stage's parameters and every
 * job's options and rules as JSON, what QGIS builds its dialogs from.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "jobspec.h"

/* s as a JSON string, or null */
static void json_str(FILE *out, const char *s)
{
    if (!s) {
        fputs("null", out);
        return;
    }
    fputc('"', out);
    for (; *s; s++) {
        if (*s == '"' || *s == '\\')
            fprintf(out, "\\%c", *s);
        else if ((unsigned char)*s < 0x20)
            fprintf(out, "\\u%04x", (unsigned char)*s);
        else
            fputc(*s, out);
    }
    fputc('"', out);
}

/* s as a JSON string ("" for NULL) */
static void json_string(FILE *out, const char *s)
{
    json_str(out, s ? s : "");
}

void cli_describe_jobs(FILE *out)
{
    static const char *const kinds[] = {"file",   "output", "number", "int", "seed",
                                        "text",   "size",   "xy",     "pin", "rule",
                                        "choice", "named",  "pair"};
    /* one name per kind: a kind added without its name does not compile */
    _Static_assert(sizeof kinds / sizeof kinds[0] == TSJOB_PAIR + 1, "a name for every tsjob_kind");
    static const char *const rkinds[] = {"requires", "excludes",  "together",
                                         "one_of",   "needs_any", "any_of"};
    _Static_assert(sizeof rkinds / sizeof rkinds[0] == TSJOB_ANY_OF + 1, "a name for every rule");
    size_t j, k;
    int i;
    fprintf(out, "  \"jobs\": {");
    for (j = 0; tsjob_at(j); j++) {
        const tsjob_decl *job = tsjob_at(j);
        fprintf(out, "%s\n    \"%s\": {\n      \"stages\": [", j ? "," : "", job->name);
        for (i = 0; job->stages[i]; i++)
            fprintf(out, "%s\"%s\"", i ? ", " : "", job->stages[i]);
        fprintf(out, "],\n      \"options\": [");
        for (k = 0; k < job->n_opts; k++) {
            const tsjob_option *o = &job->opts[k];
            char flag[64];
            cli_flag_of(o->name, flag, sizeof flag);
            fprintf(out,
                    "%s\n        {\"name\": \"%s\", \"flag\": \"%s\", \"kind\": \"%s\", "
                    "\"max_count\": %d, \"min\": %.17g, \"max\": %.17g, \"metavar\": ",
                    k ? "," : "", o->name, flag, kinds[o->kind], o->max_count, o->min, o->max);
            json_str(out, o->metavar);
            fprintf(out, ", \"group\": ");
            json_str(out, o->group);
            fprintf(out, ", \"recipe\": ");
            json_str(out, o->xml);
            fprintf(out, ", \"positional\": %d, \"sets\": ", o->positional);
            json_str(out, o->choices);
            fprintf(out, ", \"help\": ");
            json_str(out, o->help);
            fputc('}', out);
        }
        fprintf(out, "\n      ],\n      \"rules\": [");
        for (k = 0; k < job->n_rules; k++) {
            const tsjob_rule *r = &job->rules[k];
            fprintf(out, "%s\n        {\"kind\": \"%s\", \"a\": \"%s\", \"b\": [", k ? "," : "",
                    rkinds[r->kind], r->a);
            for (i = 0; r->b[i]; i++)
                fprintf(out, "%s\"%s\"", i ? ", " : "", r->b[i]);
            fprintf(out, "], \"message\": ");
            json_str(out, r->message);
            fputc('}', out);
        }
        fprintf(out, "\n      ]\n    }");
    }
    fprintf(out, "\n  }");
}

int cli_describe(int argc, char **argv)
{
    const char *const *stages = ts_params_stages();
    int i, first = 1;
    if (argc > 2 && (!strcmp(argv[2], "-h") || !strcmp(argv[2], "--help"))) {
        printf("Usage: terrasynth describe [STAGE]\n"
               "       terrasynth describe --markdown JOB (synopsis | parameters | stage:NAME | "
               "recipe)\n"
               "\n"
               "Print the parameters of every stage (or one) as JSON: name, CLI flag, type,\n"
               "default, range, units, choices and help; and every job's options (inputs,\n"
               "target grid, constraints, outputs) and the rules between them. Front ends\n"
               "(QGIS) read it, and the options every command takes (common). --markdown\n"
               "prints a part of a job's manual: its synopsis, its parameters, one stage's\n"
               "parameters, or its options' forms in a recipe.\n");
        return 0;
    }
    if (argc > 2 && !strcmp(argv[2], "--markdown")) {
        if (argc != 5 || cli_markdown(stdout, argv[3], argv[4]) != 0) {
            fprintf(stderr,
                    "terrasynth describe: --markdown takes a job (ppa, synth, amplify, "
                    "dictionary, pixel) and a part (synopsis, parameters, stage:NAME, recipe)\n");
            return EXIT_USAGE;
        }
        return 0;
    }
    if (argc > 2) {
        size_t n;
        if (!ts_params_describe(argv[2], &n)) {
            fprintf(stderr, "terrasynth describe: unknown stage '%s'\n", argv[2]);
            return EXIT_USAGE;
        }
    }
    printf("{\n  \"version\": \"%s\",\n  \"stages\": {", ts_version());
    for (i = 0; stages[i]; i++) {
        size_t n, k;
        const ts_param_desc *d = ts_params_describe(stages[i], &n);
        if (argc > 2 && strcmp(argv[2], stages[i]) != 0)
            continue;
        printf("%s\n    \"%s\": [", first ? "" : ",", stages[i]);
        first = 0;
        for (k = 0; k < n; k++) {
            static const char *const types[] = {"int", "double", "enum", "length"};
            char flag[128];
            size_t j = 2;
            const char *c;
            flag[0] = flag[1] = '-';
            for (c = d[k].name; *c && j + 1 < sizeof flag; c++)
                flag[j++] = *c == '_' ? '-' : *c;
            flag[j] = '\0';
            printf("%s\n      {\"name\": \"%s\", \"flag\": \"%s\", \"type\": \"%s\", ",
                   k ? "," : "", d[k].name, flag, types[d[k].type]);
            printf("\"default\": %.17g, \"min\": %.17g, \"max\": %.17g, ", d[k].def, d[k].min,
                   d[k].max);
            if (d[k].type == TS_PARAM_LENGTH)
                printf("\"default_unit\": \"%s\", ", d[k].def_unit ? "m" : "cells");
            printf("\"units\": ");
            json_string(stdout, d[k].units);
            printf(", \"choices\": ");
            if (d[k].choices) {
                const char *w = d[k].choices;
                printf("[");
                while (*w) {
                    const char *bar = strchr(w, '|');
                    size_t len = bar ? (size_t)(bar - w) : strlen(w);
                    printf("\"%.*s\"%s", (int)len, w, bar ? ", " : "");
                    if (!bar)
                        break;
                    w = bar + 1;
                }
                printf("]");
            } else {
                printf("null");
            }
            printf(", \"help\": ");
            json_string(stdout, d[k].help);
            printf("}");
        }
        printf("\n    ]");
    }
    printf("\n  },\n");
    cli_describe_jobs(stdout);
    printf(",\n  \"common\": [");
    for (i = 0; cli_common_options[i].left; i++) {
        const cli_common_option *c = &cli_common_options[i];
        printf("%s\n    {\"name\": \"%s\", \"usage\": ", i ? "," : "", c->name);
        json_string(stdout, c->left);
        printf(", \"kind\": \"%s\", \"min\": %.17g, \"max\": %.17g, \"help\": ", c->kind, c->min,
               c->max);
        json_string(stdout, c->help);
        printf("}");
    }
    printf("\n  ]\n}\n");
    return 0;
}
