/*
 * recipe_write.c - a job written as a recipe (inputs relative to it when they lie
 * under its folder), and the open options the driver lists.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <ctype.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cpl_conv.h>
#include <cpl_minixml.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>

#include "recipe_internal.h"

/* ------------------------------------------------------------------ */
/* Writing                                                             */
/* ------------------------------------------------------------------ */

/* An input path as the recipe at `recipe` should store it. */
static const char *recipe_rel(const char *recipe, const char *input)
{
    static _Thread_local char buf[4096];
    char dir[4096], abs_in[4096];
    const char *rel;
    int ok = 0;
    if (!strncmp(input, "/vsi", 4))
        return input;
    if (!realpath(input, abs_in))
        snprintf(abs_in, sizeof abs_in, "%s", input);
    snprintf(dir, sizeof dir, "%s", CPLGetPath(recipe));
    if (!dir[0])
        snprintf(dir, sizeof dir, ".");
    {
        char absdir[4096];
        if (realpath(dir, absdir))
            snprintf(dir, sizeof dir, "%s", absdir);
    }
    rel = CPLExtractRelativePath(dir, abs_in, &ok);
    snprintf(buf, sizeof buf, "%s", ok ? rel : abs_in);
    return buf;
}

static int recipe_save(const char *path, CPLXMLNode *root, tsio_err *err)
{
    char *xml = CPLSerializeXMLTree(root);
    char *tmp = CPLStrdup(CPLSPrintf("%s.tmp%ld", path, (long)getpid()));
    VSILFILE *fp = VSIFOpenL(tmp, "wb");
    int rc = -1;
    if (!fp) {
        tsio_errf(err, path, "cannot create the recipe (does the folder exist?)");
    } else {
        size_t len = strlen(xml);
        int ok = VSIFWriteL(xml, 1, len, fp) == len;
        ok = (VSIFCloseL(fp) == 0) && ok;
        if (ok && VSIRename(tmp, path) == 0)
            rc = 0;
        else {
            VSIUnlink(tmp);
            tsio_errf(err, path, "cannot write the recipe");
        }
    }
    CPLFree(tmp);
    CPLFree(xml);
    return rc;
}

/* tsrecipe_values_to_xml's file names: relative to the recipe's folder */
static const char *recipe_rel_cb(void *user, const char *name)
{
    return recipe_rel(user, name);
}

int tsrecipe_write(const char *path, const tsjob_values *values, tsio_err *err)
{
    CPLXMLNode *root = CPLCreateXMLNode(NULL, CXT_Element, "TerraSynth");
    int rc;
    CPLAddXMLAttributeAndValue(root, "version", "1");
    tsrecipe_values_to_xml(values, root, recipe_rel_cb, (void *)path);
    rc = recipe_save(path, root, err);
    CPLDestroyXMLNode(root);
    return rc;
}

/* One <Option> of the list, unless one of that name is there already. */
static CPLXMLNode *option_add(CPLXMLNode *list, const char *name, const char *type,
                              const char *description)
{
    CPLXMLNode *c, *o;
    char upper[64];
    size_t i;
    for (i = 0; name[i] && i + 1 < sizeof upper; i++)
        upper[i] = (char)toupper((unsigned char)name[i]);
    upper[i] = '\0';
    for (c = list->psChild; c; c = c->psNext)
        if (c->eType == CXT_Element && EQUAL(CPLGetXMLValue(c, "name", ""), upper))
            return NULL; /* shared by two jobs or stages */
    o = CPLCreateXMLNode(list, CXT_Element, "Option");
    CPLAddXMLAttributeAndValue(o, "name", upper);
    CPLAddXMLAttributeAndValue(o, "type", type);
    CPLAddXMLAttributeAndValue(o, "description", description);
    return o;
}

char *tsrecipe_open_option_list(void)
{
    CPLXMLNode *list = CPLCreateXMLNode(NULL, CXT_Element, "OpenOptionList");
    const char *jobs[4] = {"ppa", "synth", "amplify", "pixel"};
    char *out, *xml;
    int j, s;
    for (j = 0; j < 4; j++) {
        const tsjob_decl *job = tsjob_find(jobs[j]);
        size_t k;
        /* the stages' parameters, as GDAL drivers declare them */
        for (s = 0; job->stages[s]; s++) {
            size_t n;
            const ts_param_desc *d = ts_params_describe(job->stages[s], &n);
            for (k = 0; k < n; k++) {
                const char *type = d[k].type == TS_PARAM_INT      ? "int"
                                   : d[k].type == TS_PARAM_DOUBLE ? "float"
                                   : d[k].type == TS_PARAM_ENUM   ? "string-select"
                                                                  : "string";
                CPLXMLNode *o = option_add(list, d[k].name, type,
                                           CPLSPrintf("%s (%s)", d[k].help, job->stages[s]));
                if (!o)
                    continue;
                if (d[k].type == TS_PARAM_ENUM) {
                    char **choices = CSLTokenizeString2(d[k].choices, "|", 0);
                    int c;
                    for (c = 0; choices && choices[c]; c++)
                        CPLCreateXMLElementAndValue(o, "Value", choices[c]);
                    CPLAddXMLAttributeAndValue(
                        o, "default",
                        choices && (int)d[k].def < CSLCount(choices) ? choices[(int)d[k].def] : "");
                    CSLDestroy(choices);
                } else {
                    CPLAddXMLAttributeAndValue(o, "default", CPLSPrintf("%.15g", d[k].def));
                    if (d[k].type != TS_PARAM_LENGTH) {
                        CPLAddXMLAttributeAndValue(o, "min", CPLSPrintf("%.15g", d[k].min));
                        CPLAddXMLAttributeAndValue(o, "max", CPLSPrintf("%.15g", d[k].max));
                    }
                }
            }
        }
        /* the job's options that name no file */
        for (k = 0; k < job->n_opts; k++) {
            const tsjob_option *op = &job->opts[k];
            CPLXMLNode *o;
            if (!op->xml || op->kind == TSJOB_FILE || op->kind == TSJOB_PIN ||
                op->kind == TSJOB_RULE || op->kind == TSJOB_NAMED || op->kind == TSJOB_PAIR)
                continue;
            o = option_add(list, op->name,
                           op->kind == TSJOB_INT      ? "int"
                           : op->kind == TSJOB_NUMBER ? "float"
                                                      : "string", /* a seed: 64 bits, checked by
                                                                     the job */
                           CPLSPrintf("%s (%s)", op->help, job->name));
            if (o && (op->kind == TSJOB_INT || op->kind == TSJOB_NUMBER)) {
                CPLAddXMLAttributeAndValue(o, "min", CPLSPrintf("%.15g", op->min));
                CPLAddXMLAttributeAndValue(o, "max", CPLSPrintf("%.15g", op->max));
            }
        }
    }
    option_add(list, "LAYER", "string",
               "what an amplify recipe serves: the DEM (dem, the default), a layer the atoms "
               "carry (its name), or their classes (classes)");
    {
        /* what a synth recipe serves: the terrain, or one of its synthesis maps */
        CPLXMLNode *o = option_add(list, "MAP", "string-select",
                                   "what to serve: the terrain (dem), or where its cells came "
                                   "from (seams, source_exemplar, source_x, source_y, order; "
                                   "synth)");
        if (o) {
            CPLCreateXMLElementAndValue(o, "Value", "dem");
            for (j = 0; j < TSJOB_N_MAPS; j++)
                CPLCreateXMLElementAndValue(o, "Value", tsjob_map_names[j]);
            CPLAddXMLAttributeAndValue(o, "default", "dem");
        }
    }
    xml = CPLSerializeXMLTree(list);
    CPLDestroyXMLNode(list);
    out = xml ? strdup(xml) : NULL;
    CPLFree(xml);
    return out;
}
