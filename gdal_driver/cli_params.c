/*
 * cli_params.c - command-line flags generated from the descriptor tables.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <string.h>

#include "cli_params.h"

/* "profile_length" -> "--profile-length" */
static void flag_name(const char *name, char *buf, size_t len)
{
    size_t i = 2;
    buf[0] = buf[1] = '-';
    for (; *name && i + 1 < len; name++)
        buf[i++] = *name == '_' ? '-' : *name;
    buf[i] = '\0';
}

int cli_params_parse(ts_ctx *ctx, const char *stage, void *params, int argc, char **argv, int *i)
{
    size_t n, k;
    const ts_param_desc *d = ts_params_describe(stage, &n);
    const char *arg = argv[*i];
    for (k = 0; k < n; k++) {
        char flag[128];
        size_t fl;
        const char *value = NULL;
        flag_name(d[k].name, flag, sizeof flag);
        fl = strlen(flag);
        if (strncmp(arg, flag, fl) != 0)
            continue;
        if (arg[fl] == '=') {
            value = arg + fl + 1;
        } else if (arg[fl] == '\0') {
            if (*i + 1 >= argc) {
                ts_params_set(ctx, stage, params, d[k].name, "");
                return -1;
            }
            value = argv[++*i];
        } else {
            continue;
        }
        return ts_params_set(ctx, stage, params, d[k].name, value) == TS_OK ? 1 : -1;
    }
    return 0;
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
        flag_name(d[k].name, flag, sizeof flag);
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
                    d[k].type == TS_PARAM_LENGTH ? (d[k].def_unit ? " m" : " cells") : "",
                    d[k].min, d[k].max, d[k].type == TS_PARAM_LENGTH ? "" : d[k].units);
        }
    }
}
