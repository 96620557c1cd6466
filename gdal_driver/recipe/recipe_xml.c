/*
 * recipe_xml.c - a job's values read from a recipe's XML and written to it, by the
 * recipe names the declarations give each option ("Element@attribute").
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

#include "recipe_xml.h"

/* ------------------------------------------------------------------ */
/* Recipes                                                             */
/* ------------------------------------------------------------------ */

/* Split "Element@a@b" into its parts (element may be empty: the job's
 * own element). */
static int xml_split(const char *xml, char *elem, char *a, char *b, size_t len)
{
    const char *at = strchr(xml, '@'), *at2;
    elem[0] = a[0] = b[0] = '\0';
    if (!at) {
        snprintf(elem, len, "%s", xml);
        return 0;
    }
    snprintf(elem, len, "%.*s", (int)(at - xml), xml);
    at2 = strchr(at + 1, '@');
    if (!at2) {
        snprintf(a, len, "%s", at + 1);
        return 1;
    }
    snprintf(a, len, "%.*s", (int)(at2 - at - 1), at + 1);
    snprintf(b, len, "%s", at2 + 1);
    return 2;
}

static const char *pin_attrs[6] = {"xoff", "yoff", "width", "height", "x", "y"};

int tsrecipe_values_from_xml(tsjob_values *v, const CPLXMLNode *node,
                             const char *(*resolve)(void *user, const char *name, char *msg,
                                                    size_t len),
                             void *user, char *msg, size_t len)
{
    const CPLXMLNode *c;
    size_t k;
    for (k = 0; k < v->job->n_opts; k++) {
        const tsjob_option *o = &v->job->opts[k];
        char elem[64], a[64], b[64];
        int parts;
        if (!o->xml)
            continue;
        parts = xml_split(o->xml, elem, a, b, sizeof elem);
        for (c = elem[0] ? node->psChild : node; c; c = elem[0] ? c->psNext : NULL) {
            const char *val = NULL;
            char buf[2048];
            if (elem[0] && (c->eType != CXT_Element || !EQUAL(c->pszValue, elem)))
                continue;
            if (o->kind == TSJOB_PIN) {
                long n[6];
                int i;
                for (i = 0; i < 6; i++) {
                    const char *s = CPLGetXMLValue(c, pin_attrs[i], NULL);
                    char *end;
                    n[i] = s ? strtol(s, &end, 10) : -1;
                    if (!s || *end || n[i] < 0) {
                        snprintf(msg, len, "<%s %s=\"%s\">: not a cell number", elem, pin_attrs[i],
                                 s ? s : "");
                        return -1;
                    }
                }
                snprintf(buf, sizeof buf, "%s:%ld,%ld,%ld,%ld@%ld,%ld", CPLGetXMLValue(c, NULL, ""),
                         n[0], n[1], n[2], n[3], n[4], n[5]);
                val = buf;
            } else if (o->kind == TSJOB_RULE || o->kind == TSJOB_NAMED) {
                snprintf(buf, sizeof buf, "%s=%s",
                         CPLGetXMLValue(c, o->kind == TSJOB_RULE ? "id" : "name", ""),
                         CPLGetXMLValue(c, NULL, ""));
                val = buf;
            } else if (o->kind == TSJOB_PAIR) {
                /* both files relative to the recipe */
                const char *first = CPLGetXMLValue(c, o->choices, ""), *res;
                char a_abs[1024];
                if (!*first || !*CPLGetXMLValue(c, NULL, "")) {
                    snprintf(msg, len, "<%s %s=\"FILE\">FILE</%s> needs both files", elem,
                             o->choices, elem);
                    return -1;
                }
                if (strchr(first, '=')) {
                    snprintf(msg, len, "<%s %s=\"%s\">: a name with '='", elem, o->choices, first);
                    return -1;
                }
                if (!(res = resolve(user, first, msg, len)))
                    return -1;
                snprintf(a_abs, sizeof a_abs, "%s", res);
                if (!(res = resolve(user, CPLGetXMLValue(c, NULL, ""), msg, len)))
                    return -1;
                snprintf(buf, sizeof buf, "%s=%s", a_abs, res);
                if (o->max_count > 1 && tsjob_count(v, o->name) >= o->max_count) {
                    snprintf(msg, len, "more than %d <%s> elements", o->max_count, elem);
                    return -1;
                }
                tsjob_set(v, o->name, buf);
                continue;
            } else if (parts == 0) {
                val = CPLGetXMLValue(c, NULL, "");
            } else if (parts == 1) {
                val = CPLGetXMLValue(c, a, NULL);
            } else {
                const char *x = CPLGetXMLValue(c, a, NULL), *y = CPLGetXMLValue(c, b, NULL);
                if (!x && !y)
                    continue;
                snprintf(buf, sizeof buf, "%s%c%s", x ? x : "", o->kind == TSJOB_SIZE ? 'x' : ',',
                         y ? y : "");
                val = buf;
            }
            if (!val)
                continue;
            if (o->kind == TSJOB_FILE || o->kind == TSJOB_PIN || o->kind == TSJOB_RULE ||
                o->kind == TSJOB_NAMED) {
                /* the file names relative to the recipe, and never the recipe itself */
                const char *file = val, *sep = NULL;
                char head[64] = "";
                if (o->kind == TSJOB_RULE || o->kind == TSJOB_NAMED) {
                    sep = strchr(val, '=');
                    snprintf(head, sizeof head, "%.*s=", sep ? (int)(sep - val) : 0, val);
                    file = sep ? sep + 1 : "";
                }
                if (o->kind == TSJOB_PIN) {
                    const char *colon = strrchr(val, ':');
                    char path[1024], tail[128];
                    const char *res;
                    snprintf(path, sizeof path, "%.*s", colon ? (int)(colon - val) : 0, val);
                    snprintf(tail, sizeof tail, "%s", colon ? colon : "");
                    if (!*path) {
                        snprintf(msg, len, "<%s> is empty", elem);
                        return -1;
                    }
                    if (!(res = resolve(user, path, msg, len)))
                        return -1;
                    snprintf(buf, sizeof buf, "%s%s", res, tail);
                    tsjob_set(v, o->name, buf);
                    continue;
                }
                if (!*file) {
                    if (o->kind == TSJOB_RULE || o->kind == TSJOB_NAMED) {
                        snprintf(msg, len, "<%s %s>FILE</%s> has no file", elem,
                                 o->kind == TSJOB_RULE ? "id=\"N\"" : "name=\"NAME\"", elem);
                        return -1;
                    }
                    continue; /* an empty element names nothing */
                }
                if (!(file = resolve(user, file, msg, len)))
                    return -1;
                snprintf(buf, sizeof buf, "%s%s", head, file);
                val = buf;
            }
            if (o->max_count > 1 && tsjob_count(v, o->name) >= o->max_count) {
                snprintf(msg, len, "more than %d <%s> elements", o->max_count, elem);
                return -1;
            }
            tsjob_set(v, o->name, val);
        }
    }
    /* the stage parameters */
    for (c = node->psChild; c; c = c->psNext) {
        const char *name;
        if (c->eType != CXT_Element || !EQUAL(c->pszValue, "Param"))
            continue;
        name = CPLGetXMLValue(c, "name", NULL);
        if (!name) {
            snprintf(msg, len, "<Param> without a name attribute");
            return -1;
        }
        if (!tsjob_param_stage(v->job, name)) {
            snprintf(msg, len, "<Param name=\"%s\">: unknown parameter", name);
            return -1;
        }
        tsjob_set(v, name, CPLGetXMLValue(c, NULL, ""));
    }
    return 0;
}

/* ---- the schema: what the declarations give each element ---- */

/* Does option o's recipe name (or its kind's own attributes) give element `elem` ("" for
 * the job's element) the attribute `attr`? */
static int option_has_attr(const tsjob_option *o, const char *elem, const char *attr)
{
    char e[64], a[64], b[64];
    int parts, i;
    if (!o->xml)
        return 0;
    parts = xml_split(o->xml, e, a, b, sizeof e);
    if (!EQUAL(e, elem))
        return 0;
    if ((parts >= 1 && EQUAL(a, attr)) || (parts == 2 && EQUAL(b, attr)))
        return 1;
    if (o->kind == TSJOB_PIN)
        for (i = 0; i < 6; i++)
            if (EQUAL(pin_attrs[i], attr))
                return 1;
    return (o->kind == TSJOB_RULE && EQUAL(attr, "id")) ||
           (o->kind == TSJOB_NAMED && EQUAL(attr, "name")) ||
           (o->kind == TSJOB_PAIR && o->choices && EQUAL(attr, o->choices));
}

/* Does one of the job's options name element `elem` (attr NULL), or give it attribute
 * `attr`? */
static int job_has(const tsjob_decl *job, const char *elem, const char *attr)
{
    size_t k;
    for (k = 0; k < job->n_opts; k++) {
        const tsjob_option *o = &job->opts[k];
        char e[64], a[64], b[64];
        if (attr && option_has_attr(o, elem, attr))
            return 1;
        if (!attr && o->xml) {
            xml_split(o->xml, e, a, b, sizeof e);
            if (e[0] && EQUAL(e, elem))
                return 1;
        }
    }
    return 0;
}

int tsrecipe_check_schema(const tsjob_decl *job, const CPLXMLNode *top, const CPLXMLNode *node,
                          char *msg, size_t len)
{
    const CPLXMLNode *c, *d;
    for (c = top->psChild; c; c = c->psNext) {
        if (c->eType == CXT_Attribute && !EQUAL(c->pszValue, "version")) {
            snprintf(msg, len, "<TerraSynth %s=...>: unknown attribute", c->pszValue);
            return -1;
        }
        if (c->eType == CXT_Element && c != node) {
            snprintf(msg, len, "<TerraSynth> holds <%s> besides <%s>: a recipe runs one job",
                     c->pszValue, node->pszValue);
            return -1;
        }
    }
    for (c = node->psChild; c; c = c->psNext) {
        int param = c->eType == CXT_Element && EQUAL(c->pszValue, "Param");
        if (c->eType == CXT_Attribute && !job_has(job, "", c->pszValue)) {
            snprintf(msg, len, "<%s %s=...>: unknown attribute", node->pszValue, c->pszValue);
            return -1;
        }
        if (c->eType != CXT_Element)
            continue;
        if (!param && !job_has(job, c->pszValue, NULL)) {
            snprintf(msg, len, "<%s> has no element <%s>", node->pszValue, c->pszValue);
            return -1;
        }
        for (d = c->psChild; d; d = d->psNext) {
            if (d->eType == CXT_Element) {
                snprintf(msg, len, "<%s> holds <%s>: it takes no elements", c->pszValue,
                         d->pszValue);
                return -1;
            }
            if (d->eType == CXT_Attribute &&
                !(param ? EQUAL(d->pszValue, "name") : job_has(job, c->pszValue, d->pszValue))) {
                snprintf(msg, len, "<%s %s=...>: unknown attribute", c->pszValue, d->pszValue);
                return -1;
            }
        }
    }
    return 0;
}

/* The child element `name` of node, created when missing. */
static CPLXMLNode *xml_child(CPLXMLNode *node, const char *name)
{
    CPLXMLNode *c = CPLGetXMLNode(node, name);
    return c ? c : CPLCreateXMLNode(node, CXT_Element, name);
}

void tsrecipe_values_to_xml(const tsjob_values *v, CPLXMLNode *root,
                            const char *(*rel)(void *user, const char *name), void *user)
{
    CPLXMLNode *node = CPLCreateXMLNode(root, CXT_Element, v->job->element);
    size_t k;
    int i, s;
    /* attributes of the job's element first (XML puts them before children) */
    for (k = 0; k < v->job->n_opts; k++) {
        const tsjob_option *o = &v->job->opts[k];
        if (o->xml && o->xml[0] == '@' && tsjob_count(v, o->name))
            CPLAddXMLAttributeAndValue(node, o->xml + 1, tsjob_get(v, o->name, 0));
    }
    for (k = 0; k < v->job->n_opts; k++) {
        const tsjob_option *o = &v->job->opts[k];
        char elem[64], a[64], b[64];
        int parts;
        const char *val;
        if (!o->xml || o->xml[0] == '@')
            continue;
        parts = xml_split(o->xml, elem, a, b, sizeof elem);
        for (i = 0; (val = tsjob_get(v, o->name, i)); i++) {
            CPLXMLNode *e;
            if (o->kind == TSJOB_PIN) {
                tsjob_pin pin;
                char path[1024];
                if (tsjob_parse_pin(val, &pin, path, sizeof path) != 0)
                    continue;
                e = CPLCreateXMLElementAndValue(node, elem, rel(user, path));
                CPLAddXMLAttributeAndValue(e, "xoff", CPLSPrintf("%d", pin.xoff));
                CPLAddXMLAttributeAndValue(e, "yoff", CPLSPrintf("%d", pin.yoff));
                CPLAddXMLAttributeAndValue(e, "width", CPLSPrintf("%d", pin.width));
                CPLAddXMLAttributeAndValue(e, "height", CPLSPrintf("%d", pin.height));
                CPLAddXMLAttributeAndValue(e, "x", CPLSPrintf("%d", pin.x));
                CPLAddXMLAttributeAndValue(e, "y", CPLSPrintf("%d", pin.y));
            } else if (o->kind == TSJOB_RULE || o->kind == TSJOB_NAMED) {
                const char *eq = strchr(val, '=');
                if (!eq)
                    continue;
                e = CPLCreateXMLElementAndValue(node, elem, rel(user, eq + 1));
                CPLAddXMLAttributeAndValue(e, o->kind == TSJOB_RULE ? "id" : "name",
                                           CPLSPrintf("%.*s", (int)(eq - val), val));
            } else if (o->kind == TSJOB_PAIR) {
                const char *eq = strchr(val, '=');
                char first[1024];
                if (!eq)
                    continue;
                snprintf(first, sizeof first, "%.*s", (int)(eq - val), val);
                e = CPLCreateXMLElementAndValue(node, elem, rel(user, eq + 1));
                CPLAddXMLAttributeAndValue(e, o->choices, rel(user, first));
            } else if (parts == 0) {
                CPLCreateXMLElementAndValue(node, elem,
                                            o->kind == TSJOB_FILE ? rel(user, val) : val);
            } else if (parts == 1) {
                e = xml_child(node, elem);
                CPLAddXMLAttributeAndValue(e, a, o->kind == TSJOB_FILE ? rel(user, val) : val);
            } else {
                char sep = o->kind == TSJOB_SIZE ? 'x' : ',';
                const char *p = strchr(val, sep);
                e = xml_child(node, elem);
                if (!p)
                    continue;
                CPLAddXMLAttributeAndValue(e, a, CPLSPrintf("%.*s", (int)(p - val), val));
                CPLAddXMLAttributeAndValue(e, b, p + 1);
            }
        }
    }
    /* the stage parameters, in the order of the descriptor tables */
    for (s = 0; v->job->stages[s]; s++) {
        size_t n;
        const ts_param_desc *d = ts_params_describe(v->job->stages[s], &n);
        for (k = 0; k < n; k++) {
            const char *val = tsjob_get(v, d[k].name, 0);
            CPLXMLNode *p;
            if (!val)
                continue;
            p = CPLCreateXMLElementAndValue(node, "Param", val);
            CPLAddXMLAttributeAndValue(p, "name", d[k].name);
        }
    }
}
