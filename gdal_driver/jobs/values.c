/*
 * values.c - a job's values (name=value pairs from argv, a recipe or open
 * options): storing them, the rules between them and the checks of each value.
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

#include "jobspec_internal.h"

/* ------------------------------------------------------------------ */
/* Values                                                              */
/* ------------------------------------------------------------------ */

void tsjob_values_init(tsjob_values *v, const tsjob_decl *job)
{
    v->job = job;
    v->kv = NULL;
    v->keep = NULL;
    v->cli = 0;
}

void tsjob_values_free(tsjob_values *v)
{
    CSLDestroy(v->kv);
    CSLDestroy(v->keep);
    v->kv = v->keep = NULL;
}

static size_t key_len(const char *kv)
{
    const char *eq = strchr(kv, '=');
    return eq ? (size_t)(eq - kv) : strlen(kv);
}

static int key_is(const char *kv, const char *name)
{
    size_t n = strlen(name);
    return key_len(kv) == n && !strncmp(kv, name, n);
}

void tsjob_set(tsjob_values *v, const char *name, const char *value)
{
    const tsjob_option *o = tsjob_option_find(v->job, name);
    char *item = CPLStrdup(CPLSPrintf("%s=%s", name, value));
    int i;
    if (!o || o->max_count <= 1)
        for (i = 0; v->kv && v->kv[i]; i++)
            if (key_is(v->kv[i], name)) {
                CPLFree(v->kv[i]);
                v->kv[i] = item;
                return;
            }
    v->kv = CSLAddString(v->kv, item);
    CPLFree(item);
}

int tsjob_count(const tsjob_values *v, const char *name)
{
    int i, n = 0;
    for (i = 0; v->kv && v->kv[i]; i++)
        n += key_is(v->kv[i], name);
    return n;
}

const char *tsjob_get(const tsjob_values *v, const char *name, int k)
{
    int i;
    for (i = 0; v->kv && v->kv[i]; i++)
        if (key_is(v->kv[i], name) && k-- == 0)
            return v->kv[i] + strlen(name) + 1;
    return NULL;
}

/* A string the job may point into, owned by v. */
const char *tsjob__keep(tsjob_values *v, const char *s)
{
    v->keep = CSLAddString(v->keep, s);
    return v->keep[CSLCount(v->keep) - 1];
}

void tsjob__msgf(char *msg, size_t len, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, len, fmt, ap);
    va_end(ap);
}

/* ------------------------------------------------------------------ */
/* Rules                                                               */
/* ------------------------------------------------------------------ */

/* Is `name` given?  "@stage": the first parameter of that stage given, or
 * NULL; otherwise the name itself, or NULL. */
const char *tsjob__given(const tsjob_values *v, const char *name)
{
    if (name[0] == '@') {
        size_t n, k;
        const ts_param_desc *d = ts_params_describe(name + 1, &n);
        for (k = 0; k < n; k++)
            if (tsjob_count(v, d[k].name))
                return d[k].name;
        return NULL;
    }
    return tsjob_count(v, name) ? name : NULL;
}

/* Does a rule apply to this front end?  Rules about options that only the
 * command line has (outputs) do not apply to recipes. */
static int rule_applies(const tsjob_decl *job, const tsjob_rule *r, int cli)
{
    const tsjob_option *o = tsjob_option_find(job, r->a);
    int i;
    if (cli)
        return 1;
    if (o && !o->xml && o->kind != TSJOB_CHOICE)
        return 0;
    for (i = 0; r->b[i]; i++) {
        o = tsjob_option_find(job, r->b[i]);
        if (o && !o->xml && o->kind != TSJOB_CHOICE)
            return 0;
    }
    return 1;
}

int tsjob__check_rules(const tsjob_values *v, int cli, char *msg, size_t len)
{
    const tsjob_decl *job = v->job;
    size_t r;
    for (r = 0; r < job->n_rules; r++) {
        const tsjob_rule *ru = &job->rules[r];
        const char *a = tsjob__given(v, ru->a), *bad = NULL;
        int i, n_given = a ? 1 : 0, n_all = 1;
        if (!rule_applies(job, ru, cli))
            continue;
        for (i = 0; ru->b[i]; i++) {
            const char *b = tsjob__given(v, ru->b[i]);
            n_all++;
            n_given += b != NULL;
            switch (ru->kind) {
            case TSJOB_REQUIRES:
                if (a && !b && !bad)
                    bad = a;
                break;
            case TSJOB_EXCLUDES:
                if (a && b && !bad)
                    bad = b;
                break;
            default:
                break;
            }
        }
        if (ru->kind == TSJOB_TOGETHER && n_given && n_given != n_all)
            bad = ru->a;
        if (ru->kind == TSJOB_ONE_OF && n_given != 1)
            bad = ru->a;
        if (ru->kind == TSJOB_NEEDS_ANY && a && n_given == 1)
            bad = a;
        if (ru->kind == TSJOB_ANY_OF && n_given == 0)
            bad = ru->a;
        if (bad) {
            tsjob__msgf(msg, len, ru->message, bad);
            return -1;
        }
    }
    return 0;
}

/* ------------------------------------------------------------------ */
/* Values -> jobs                                                      */
/* ------------------------------------------------------------------ */

int tsjob__parse_number(const char *s, double *out)
{
    char *end;
    if (!s || !*s)
        return -1;
    errno = 0;
    *out = strtod(s, &end);
    return (*end || errno || !isfinite(*out)) ? -1 : 0;
}

int tsjob__parse_pair(const char *s, char sep, double *a, double *b)
{
    char *end;
    if (!s)
        return -1;
    *a = strtod(s, &end);
    if (end == s || *end != sep)
        return -1;
    s = end + 1;
    *b = strtod(s, &end);
    return (end == s || *end || !isfinite(*a) || !isfinite(*b)) ? -1 : 0;
}

/* Check one value of an option against its kind and range. */
static int check_value(const tsjob_option *o, const char *s, char *msg, size_t len)
{
    double x, y;
    switch (o->kind) {
    case TSJOB_FILE:
    case TSJOB_OUTPUT:
    case TSJOB_TEXT:
        if (!s || !*s) {
            tsjob__msgf(msg, len, "%s is empty", o->name);
            return -1;
        }
        return 0;
    case TSJOB_NUMBER:
        if (tsjob__parse_number(s, &x) || x < o->min || x > o->max) {
            tsjob__msgf(msg, len, "%s must be a number in %g..%g, not '%s'", o->name, o->min,
                        o->max, s ? s : "");
            return -1;
        }
        return 0;
    case TSJOB_INT:
        if (tsjob__parse_number(s, &x) || x != floor(x) || x < o->min || x > o->max) {
            tsjob__msgf(msg, len, "%s must be a whole number in %g..%g, not '%s'", o->name, o->min,
                        o->max, s ? s : "");
            return -1;
        }
        return 0;
    case TSJOB_SEED: {
        char *end = NULL;
        int bad;
        errno = 0;
        bad = !s || !*s || !isdigit((unsigned char)s[0]) || (strtoull(s, &end, 10), *end);
        if (bad || errno == ERANGE) {
            tsjob__msgf(msg, len, "%s must be a whole number in 0..18446744073709551615, not '%s'",
                        o->name, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJOB_SIZE:
        if (tsjob__parse_pair(s, 'x', &x, &y) || x != floor(x) || y != floor(y) || x < o->min ||
            y < o->min || x > o->max || y > o->max) {
            tsjob__msgf(msg, len, "%s takes WxH in cells (%g..%g), not '%s'", o->name, o->min,
                        o->max, s ? s : "");
            return -1;
        }
        return 0;
    case TSJOB_XY:
        if (tsjob__parse_pair(s, ',', &x, &y)) {
            tsjob__msgf(msg, len, "%s takes X,Y, not '%s'", o->name, s ? s : "");
            return -1;
        }
        return 0;
    case TSJOB_PIN: {
        tsjob_pin pin;
        char path[1024];
        if (tsjob_parse_pin(s ? s : "", &pin, path, sizeof path) != 0) {
            tsjob__msgf(msg, len, "%s takes FILE:XOFF,YOFF,W,H@X,Y, not '%s'", o->name, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJOB_RULE: {
        char *end;
        if (!s || (strtol(s, &end, 10), end == s) || *end != '=' || !end[1]) {
            tsjob__msgf(msg, len, "%s takes ID=FILE, not '%s'", o->name, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJOB_NAMED: {
        size_t n =
            s ? strspn(s, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-") : 0;
        if (!s || n == 0 || n >= TS_LAYER_NAME || s[n] != '=' || !s[n + 1]) {
            tsjob__msgf(msg, len,
                        "%s takes NAME=FILE (NAME: 1 to %d letters, digits, _ or -), not '%s'",
                        o->name, TS_LAYER_NAME - 1, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJOB_PAIR: {
        const char *eq = s ? strchr(s, '=') : NULL;
        if (!eq || eq == s || !eq[1]) {
            tsjob__msgf(msg, len, "%s takes FILE=FILE, not '%s'", o->name, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJOB_CHOICE:
        return 0;
    }
    return 0;
}

/* Every value: known names, counts, kinds, ranges; choices become their
 * parameter. */
int tsjob__check_values(tsjob_values *v, char *msg, size_t len)
{
    int i;
    for (i = 0; v->kv && v->kv[i]; i++) {
        char name[128];
        size_t kl = key_len(v->kv[i]);
        const tsjob_option *o;
        if (kl >= sizeof name) {
            tsjob__msgf(msg, len, "unknown option '%.40s...'", v->kv[i]);
            return -1;
        }
        memcpy(name, v->kv[i], kl);
        name[kl] = '\0';
        o = tsjob_option_find(v->job, name);
        if (!o) {
            if (!tsjob_param_stage(v->job, name)) {
                tsjob__msgf(msg, len, "unknown option '%s'", name);
                return -1;
            }
            continue;
        }
        if (tsjob_count(v, name) > o->max_count) {
            tsjob__msgf(msg, len, "%s: at most %d", name, o->max_count);
            return -1;
        }
        if (check_value(o, v->kv[i] + kl + 1, msg, len) != 0)
            return -1;
    }
    return 0;
}

/* The stage parameters among the values into params of `stage`. */
int tsjob__apply_params(const tsjob_values *v, const char *stage, void *params, char *msg,
                        size_t len)
{
    ts_ctx *ctx = ts_ctx_new();
    int i, rc = 0;
    if (!ctx) {
        tsjob__msgf(msg, len, "out of memory");
        return -1;
    }
    for (i = 0; v->kv && v->kv[i] && !rc; i++) {
        char name[128];
        size_t kl = key_len(v->kv[i]);
        const char *st;
        if (kl >= sizeof name)
            continue;
        memcpy(name, v->kv[i], kl);
        name[kl] = '\0';
        st = tsjob_param_stage(v->job, name);
        if (!st || strcmp(st, stage) != 0)
            continue;
        if (ts_params_set(ctx, stage, params, name, v->kv[i] + kl + 1) != TS_OK) {
            tsjob__msgf(msg, len, "%s", ts_ctx_message(ctx));
            rc = -1;
        }
    }
    if (!rc && ts_params_validate(ctx, stage, params) != TS_OK) {
        tsjob__msgf(msg, len, "%s", ts_ctx_message(ctx));
        rc = -1;
    }
    ts_ctx_free(ctx);
    return rc;
}

/* TSJOB_CHOICE options set their parameter ("features=ridges"). */
void tsjob__expand_choices(tsjob_values *v)
{
    size_t k;
    for (k = 0; k < v->job->n_opts; k++) {
        const tsjob_option *o = &v->job->opts[k];
        char name[64];
        const char *eq;
        if (o->kind != TSJOB_CHOICE || !tsjob_count(v, o->name) || !(eq = strchr(o->choices, '=')))
            continue;
        snprintf(name, sizeof name, "%.*s", (int)(eq - o->choices), o->choices);
        if (!tsjob_count(v, name))
            tsjob_set(v, name, eq + 1);
    }
}
