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

static void json_string(FILE *out, const char *s)
{
    fputc('"', out);
    for (; s && *s; s++) {
        if (*s == '"' || *s == '\\')
            fprintf(out, "\\%c", *s);
        else if ((unsigned char)*s < 0x20)
            fprintf(out, "\\u%04x", (unsigned char)*s);
        else
            fputc(*s, out);
    }
    fputc('"', out);
}

int cli_describe(int argc, char **argv)
{
    const char *const *stages = ts_params_stages();
    int i, first = 1;
    if (argc > 2 && (!strcmp(argv[2], "-h") || !strcmp(argv[2], "--help"))) {
        printf("Usage: terrasynth describe [STAGE]\n\n"
               "Print the parameters of every stage (or one) as JSON: name, CLI flag, type,\n"
               "default, range, units, choices and help; and every job's options (inputs,\n"
               "target grid, constraints, outputs) and the rules between them. Front ends\n"
               "(QGIS) read it.\n");
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
    tsj_describe(stdout);
    printf("\n}\n");
    return 0;
}
