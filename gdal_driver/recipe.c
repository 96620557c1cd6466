/*
 * recipe.c - parse, resolve, compute and write TerraSynth recipes (.tsyn).
 *
 * A recipe is XML:
 *   <TerraSynth version="1">
 *     <PPA><Input band="1">dem.tif</Input><CellSize>20</CellSize>
 *          <Param name="features">both</Param>...</PPA>
 *   or
 *     <Synth seed="7"><Exemplar>a.tif</Exemplar>...
 *            <Grid like="grid.tif"/> | <Grid width= height= [originX= originY=
 *                 resolution= crs=]/>
 *            <Param name="patch_size">64</Param>...</Synth>
 *   </TerraSynth>
 * Errors name the recipe and the element.  Recipes that refer to
 * themselves, directly or through other recipes, are refused.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cpl_conv.h>
#include <cpl_minixml.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>

#include "recipe.h"

#define RECIPE_MAX_BYTES (1 << 20)
#define RECIPE_MAX_DEPTH 8

/* Recipes being opened or computed on this thread: a recipe that reaches
 * itself again through its inputs is recursion. */
static _Thread_local const char *recipe_stack[RECIPE_MAX_DEPTH];
static _Thread_local int recipe_depth;

struct ts_recipe {
    char *path;
    int method;
    tsjob_ppa ppa;
    tsjob_synth synth;
    uint64_t seed;
    char **strings;      /* CSL list owning every path string the jobs point to */
    tsio_georef geo;     /* ppa: the input's grid */
    tsjob_ppa_result ppa_res;
    tsjob_synth_result synth_res;
    int computed;
};

static void rerr(tsio_err *err, const char *path, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void rerr(tsio_err *err, const char *path, const char *fmt, ...)
{
    va_list ap;
    int n = snprintf(err->msg, sizeof err->msg, "%s: ", path);
    if (n < 0 || (size_t)n >= sizeof err->msg)
        return;
    va_start(ap, fmt);
    vsnprintf(err->msg + n, sizeof err->msg - (size_t)n, fmt, ap);
    va_end(ap);
}

int recipe_identify(const char *filename, const unsigned char *header, int n_header)
{
    const char *ext = CPLGetExtension(filename);
    int i = 0;
    if (EQUAL(ext, "tsyn"))
        return 1;
    if (!header || n_header < 12)
        return 0;
    while (i < n_header && isspace(header[i]))
        i++;
    if (i + 5 < n_header && !memcmp(header + i, "<?xml", 5)) {
        /* skip the declaration */
        while (i < n_header && header[i] != '>')
            i++;
        i++;
        while (i < n_header && isspace(header[i]))
            i++;
    }
    return n_header - i >= 11 && !memcmp(header + i, "<TerraSynth", 11);
}

/* Input path as GDAL should open it: relative to the recipe's folder. */
static const char *recipe_keep_path(ts_recipe *r, const char *value)
{
    char *dir = CPLStrdup(CPLGetPath(r->path));
    const char *resolved = value;
    if (CPLIsFilenameRelative(value) && strncmp(value, "/vsi", 4) != 0)
        resolved = CPLProjectRelativeFilename(dir, value);
    r->strings = CSLAddString(r->strings, resolved);
    CPLFree(dir);
    return r->strings[CSLCount(r->strings) - 1];
}

static int recipe_check_not_self(const ts_recipe *r, const char *input, tsio_err *err)
{
    int same = 0, i;
    char ra[4096], rb[4096];
    if (realpath(input, ra) && realpath(r->path, rb))
        same = strcmp(ra, rb) == 0;
    else
        same = strcmp(input, r->path) == 0;
    for (i = 0; i < recipe_depth && !same; i++)
        if (realpath(input, ra) && realpath(recipe_stack[i], rb))
            same = strcmp(ra, rb) == 0;
    if (same)
        rerr(err, r->path, "the recipe refers to itself through %s (recursion)", input);
    return same ? -1 : 0;
}

/* <Param name="x">value</Param> children of node into params of stage. */
/* Set a parameter of `stage` (a synth recipe also takes the sketch stage's
 * parameters, whether it has a sketch or not); ctx holds the message of a
 * failure. */
static ts_status recipe_set_param(ts_recipe *r, ts_ctx *ctx, const char *stage, void *params,
                                  const char *name, const char *value)
{
    size_t nd, j;
    const ts_param_desc *d;
    if (r->method == RECIPE_SYNTH) {
        d = ts_params_describe("sketch", &nd);
        for (j = 0; d && j < nd; j++)
            if (!strcmp(d[j].name, name))
                return ts_params_set(ctx, "sketch", &r->synth.sketch_params, name, value);
    }
    return ts_params_set(ctx, stage, params, name, value);
}

static int recipe_params(ts_recipe *r, CPLXMLNode *node, const char *stage, void *params,
                         tsio_err *err)
{
    CPLXMLNode *c;
    ts_ctx *ctx = ts_ctx_new();
    if (!ctx) {
        rerr(err, r->path, "out of memory");
        return -1;
    }
    for (c = node->psChild; c; c = c->psNext) {
        const char *name, *value;
        if (c->eType != CXT_Element || !EQUAL(c->pszValue, "Param"))
            continue;
        name = CPLGetXMLValue(c, "name", NULL);
        value = CPLGetXMLValue(c, NULL, "");
        if (!name) {
            rerr(err, r->path, "<Param> without a name attribute");
            ts_ctx_free(ctx);
            return -1;
        }
        if (recipe_set_param(r, ctx, stage, params, name, value) != TS_OK) {
            rerr(err, r->path, "<Param name=\"%s\">: %s", name, ts_ctx_message(ctx));
            ts_ctx_free(ctx);
            return -1;
        }
    }
    ts_ctx_free(ctx);
    return 0;
}

static int recipe_options(ts_recipe *r, const char *const *oo, const char *stage, void *params,
                          tsio_err *err)
{
    ts_ctx *ctx;
    int i;
    if (!oo)
        return 0;
    ctx = ts_ctx_new();
    if (!ctx) {
        rerr(err, r->path, "out of memory");
        return -1;
    }
    for (i = 0; oo[i]; i++) {
        char *key = NULL;
        const char *value = CPLParseNameValue(oo[i], &key);
        char *p;
        if (!key || !value) {
            CPLFree(key);
            continue;
        }
        for (p = key; *p; p++)
            *p = (char)tolower((unsigned char)*p);
        if (!strcmp(key, "seed")) {
            char *end;
            unsigned long long s = strtoull(value, &end, 10);
            if (*end || value[0] == '-' || !value[0]) {
                rerr(err, r->path, "open option SEED=%s is not a non-negative integer", value);
                CPLFree(key);
                ts_ctx_free(ctx);
                return -1;
            }
            r->seed = s;
        } else if (recipe_set_param(r, ctx, stage, params, key, value) != TS_OK) {
            rerr(err, r->path, "open option %s: %s", oo[i], ts_ctx_message(ctx));
            CPLFree(key);
            ts_ctx_free(ctx);
            return -1;
        }
        CPLFree(key);
    }
    ts_ctx_free(ctx);
    return 0;
}

static int recipe_parse_int(const char *text, long lo, long hi, long *out)
{
    char *end;
    long v;
    if (!text || !*text)
        return -1;
    v = strtol(text, &end, 10);
    if (*end || v < lo || v > hi)
        return -1;
    *out = v;
    return 0;
}

static int recipe_parse_double(const char *text, double *out)
{
    char *end;
    double v;
    if (!text || !*text)
        return -1;
    v = strtod(text, &end);
    if (*end || !isfinite(v))
        return -1;
    *out = v;
    return 0;
}

static int recipe_ppa(ts_recipe *r, CPLXMLNode *node, const char *const *oo, tsio_err *err)
{
    CPLXMLNode *in = CPLGetXMLNode(node, "Input");
    const char *v;
    long band = 1;
    r->method = RECIPE_PPA;
    r->ppa.params = ts_ppa_params_default();
    r->ppa.band = 1;
    if (!in || !CPLGetXMLValue(in, NULL, NULL) || !*CPLGetXMLValue(in, NULL, "")) {
        rerr(err, r->path, "<PPA> needs an <Input> dataset");
        return -1;
    }
    r->ppa.input = recipe_keep_path(r, CPLGetXMLValue(in, NULL, ""));
    if ((v = CPLGetXMLValue(in, "band", NULL)) && recipe_parse_int(v, 1, 65535, &band) != 0) {
        rerr(err, r->path, "<Input band=\"%s\">: not a band number", v);
        return -1;
    }
    r->ppa.band = (int)band;
    if ((v = CPLGetXMLValue(node, "CellSize", NULL)) &&
        (recipe_parse_double(v, &r->ppa.cell_size) != 0 || !(r->ppa.cell_size > 0))) {
        rerr(err, r->path, "<CellSize>%s</CellSize>: not a positive number", v);
        return -1;
    }
    if (recipe_params(r, node, "ppa", &r->ppa.params, err) ||
        recipe_options(r, oo, "ppa", &r->ppa.params, err))
        return -1;
    if (recipe_check_not_self(r, r->ppa.input, err))
        return -1;
    /* the grid without reading the cells */
    return tsio_read_georef(r->ppa.input, &r->geo, err);
}

static int recipe_synth(ts_recipe *r, CPLXMLNode *node, const char *const *oo, tsio_err *err)
{
    CPLXMLNode *c, *grid = CPLGetXMLNode(node, "Grid");
    tsjob_grid *g = &r->synth.grid;
    const char *v;
    long n;
    r->method = RECIPE_SYNTH;
    r->synth.params = ts_synth_params_default();
    r->synth.band = 1;
    if ((v = CPLGetXMLValue(node, "seed", NULL))) {
        char *end;
        r->seed = strtoull(v, &end, 10);
        if (*end || v[0] == '-' || !v[0]) {
            rerr(err, r->path, "<Synth seed=\"%s\">: not a non-negative integer", v);
            return -1;
        }
    }
    for (c = node->psChild; c; c = c->psNext) {
        if (c->eType != CXT_Element || !EQUAL(c->pszValue, "Exemplar"))
            continue;
        v = CPLGetXMLValue(c, NULL, "");
        if (!*v) {
            rerr(err, r->path, "an <Exemplar> is empty");
            return -1;
        }
        if (r->synth.n_exemplars == TSJOB_MAX_EXEMPLARS) {
            rerr(err, r->path, "more than %d <Exemplar> elements", TSJOB_MAX_EXEMPLARS);
            return -1;
        }
        r->synth.exemplars[r->synth.n_exemplars] = recipe_keep_path(r, v);
        if (recipe_check_not_self(r, r->synth.exemplars[r->synth.n_exemplars], err))
            return -1;
        r->synth.n_exemplars++;
    }
    if (!r->synth.n_exemplars) {
        rerr(err, r->path, "<Synth> needs at least one <Exemplar>");
        return -1;
    }
    if ((v = CPLGetXMLValue(node, "CellSize", NULL)) &&
        (recipe_parse_double(v, &r->synth.cell_size) != 0 || !(r->synth.cell_size > 0))) {
        rerr(err, r->path, "<CellSize>%s</CellSize>: not a positive number", v);
        return -1;
    }
    r->synth.sketch_params = ts_sketch_params_default();
    if ((v = CPLGetXMLValue(node, "Sketch", NULL))) {
        if (!*v) {
            rerr(err, r->path, "<Sketch> is empty");
            return -1;
        }
        r->synth.sketch = recipe_keep_path(r, v);
        if (recipe_check_not_self(r, r->synth.sketch, err))
            return -1;
    }
    if ((c = CPLGetXMLNode(node, "Water"))) {
        v = CPLGetXMLValue(c, NULL, "");
        if (!*v || recipe_parse_double(CPLGetXMLValue(c, "level", NULL), &r->synth.water_level)) {
            rerr(err, r->path, "<Water level=\"H\">MASK</Water> needs a mask and a numeric level");
            return -1;
        }
        r->synth.water = recipe_keep_path(r, v);
    }
    for (c = node->psChild; c; c = c->psNext) {
        static const char *const attrs[6] = {"xoff", "yoff", "width", "height", "x", "y"};
        long vals[6];
        int a;
        tsjob_pin *pin;
        if (c->eType != CXT_Element || !EQUAL(c->pszValue, "Pin"))
            continue;
        if (r->synth.n_pins == TSJOB_MAX_PINS) {
            rerr(err, r->path, "more than %d <Pin> elements", TSJOB_MAX_PINS);
            return -1;
        }
        for (a = 0; a < 6; a++)
            if (recipe_parse_int(CPLGetXMLValue(c, attrs[a], NULL), a == 2 || a == 3 ? 1 : 0,
                                 1 << 24, &vals[a]) != 0) {
                rerr(err, r->path, "<Pin %s=\"%s\">: not a cell number", attrs[a],
                     CPLGetXMLValue(c, attrs[a], ""));
                return -1;
            }
        pin = &r->synth.pins[r->synth.n_pins++];
        pin->path = recipe_keep_path(r, CPLGetXMLValue(c, NULL, ""));
        pin->xoff = (int)vals[0];
        pin->yoff = (int)vals[1];
        pin->width = (int)vals[2];
        pin->height = (int)vals[3];
        pin->x = (int)vals[4];
        pin->y = (int)vals[5];
    }
    r->synth.alpha_h = 1.0;
    if ((c = CPLGetXMLNode(node, "Heights"))) {
        v = CPLGetXMLValue(c, NULL, "");
        if (!*v || (CPLGetXMLValue(c, "alpha", NULL) &&
                    (recipe_parse_double(CPLGetXMLValue(c, "alpha", NULL), &r->synth.alpha_h) ||
                     r->synth.alpha_h < 0))) {
            rerr(err, r->path, "<Heights alpha=\"A\">FILE</Heights> needs a file and alpha >= 0");
            return -1;
        }
        r->synth.heights = recipe_keep_path(r, v);
    }
    if ((c = CPLGetXMLNode(node, "Regions"))) {
        CPLXMLNode *rule;
        v = CPLGetXMLValue(c, NULL, "");
        r->synth.regions = *v ? recipe_keep_path(r, v) : NULL;
        /* <Regions>map.tif</Regions> with <RegionExemplar id="1">ex.tif</RegionExemplar> rules */
        for (rule = node->psChild; rule && r->synth.regions; rule = rule->psNext) {
            long id;
            int kx;
            const char *file;
            if (rule->eType != CXT_Element || !EQUAL(rule->pszValue, "RegionExemplar"))
                continue;
            file = CPLGetXMLValue(rule, NULL, "");
            if (recipe_parse_int(CPLGetXMLValue(rule, "id", NULL), -2147483647L, 2147483647L,
                                 &id) != 0 || !*file ||
                r->synth.n_region_rules == TSJOB_MAX_EXEMPLARS) {
                rerr(err, r->path, "<RegionExemplar id=\"N\">FILE</RegionExemplar> is incomplete");
                return -1;
            }
            file = recipe_keep_path(r, file);
            for (kx = 0; kx < r->synth.n_exemplars; kx++)
                if (!strcmp(r->synth.exemplars[kx], file))
                    break;
            if (kx == r->synth.n_exemplars) {
                if (kx == TSJOB_MAX_EXEMPLARS) {
                    rerr(err, r->path, "more than %d exemplars", TSJOB_MAX_EXEMPLARS);
                    return -1;
                }
                r->synth.exemplars[r->synth.n_exemplars++] = file;
            }
            r->synth.region_id[r->synth.n_region_rules] = (int)id;
            r->synth.region_exemplar[r->synth.n_region_rules++] = kx;
        }
        if (!r->synth.regions || !r->synth.n_region_rules) {
            rerr(err, r->path, "<Regions> needs a map and at least one <RegionExemplar>");
            return -1;
        }
    }
    if (r->synth.sketch) {
        if (grid) {
            rerr(err, r->path, "a <Sketch> sets the output grid: give no <Grid>");
            return -1;
        }
        if (recipe_params(r, node, "synth", &r->synth.params, err) ||
            recipe_options(r, oo, "synth", &r->synth.params, err))
            return -1;
        return tsjob_synth_prepare(&r->synth, &r->synth_res, err);
    }
    if (!grid) {
        rerr(err, r->path, "<Synth> needs a <Grid like=...> or <Grid width=... height=...>");
        return -1;
    }
    if ((v = CPLGetXMLValue(grid, "like", NULL))) {
        g->like = recipe_keep_path(r, v);
        if (recipe_check_not_self(r, g->like, err))
            return -1;
    } else {
        if (recipe_parse_int(CPLGetXMLValue(grid, "width", NULL), 1, 65536, &n) != 0) {
            rerr(err, r->path, "<Grid width=\"%s\">: not a size in 1..65536",
                 CPLGetXMLValue(grid, "width", ""));
            return -1;
        }
        g->width = (int)n;
        if (recipe_parse_int(CPLGetXMLValue(grid, "height", NULL), 1, 65536, &n) != 0) {
            rerr(err, r->path, "<Grid height=\"%s\">: not a size in 1..65536",
                 CPLGetXMLValue(grid, "height", ""));
            return -1;
        }
        g->height = (int)n;
        if (CPLGetXMLValue(grid, "originX", NULL) || CPLGetXMLValue(grid, "originY", NULL)) {
            if (recipe_parse_double(CPLGetXMLValue(grid, "originX", NULL), &g->origin_x) ||
                recipe_parse_double(CPLGetXMLValue(grid, "originY", NULL), &g->origin_y)) {
                rerr(err, r->path, "<Grid originX/originY>: not numbers");
                return -1;
            }
            g->has_origin = 1;
        }
        if ((v = CPLGetXMLValue(grid, "resolution", NULL))) {
            if (recipe_parse_double(v, &g->res) || !(g->res > 0)) {
                rerr(err, r->path, "<Grid resolution=\"%s\">: not a positive number", v);
                return -1;
            }
            g->has_res = 1;
        }
        if ((v = CPLGetXMLValue(grid, "crs", NULL))) {
            r->strings = CSLAddString(r->strings, v);
            g->crs = r->strings[CSLCount(r->strings) - 1];
        }
    }
    if (recipe_params(r, node, "synth", &r->synth.params, err) ||
        recipe_options(r, oo, "synth", &r->synth.params, err))
        return -1;
    return tsjob_synth_prepare(&r->synth, &r->synth_res, err);
}

int recipe_open(const char *path, const char *const *oo, ts_recipe **out, tsio_err *err)
{
    ts_recipe *r;
    VSILFILE *fp;
    vsi_l_offset size;
    char *text = NULL;
    CPLXMLNode *root = NULL, *top, *node;
    int rc = -1;
    *out = NULL;
    if (recipe_depth >= RECIPE_MAX_DEPTH) {
        rerr(err, path, "recipes nested more than %d deep (recursion?)", RECIPE_MAX_DEPTH);
        return -1;
    }
    r = calloc(1, sizeof *r);
    if (!r) {
        rerr(err, path, "out of memory");
        return -1;
    }
    r->path = CPLStrdup(path);
    fp = VSIFOpenL(path, "rb");
    if (!fp) {
        rerr(err, path, "cannot open the recipe");
        goto done;
    }
    VSIFSeekL(fp, 0, SEEK_END);
    size = VSIFTellL(fp);
    VSIFSeekL(fp, 0, SEEK_SET);
    if (size == 0 || size > RECIPE_MAX_BYTES) {
        rerr(err, path, "a recipe must be 1 byte to 1 MB, not %llu bytes",
             (unsigned long long)size);
        VSIFCloseL(fp);
        goto done;
    }
    text = CPLMalloc((size_t)size + 1);
    if (VSIFReadL(text, 1, (size_t)size, fp) != (size_t)size) {
        rerr(err, path, "cannot read the recipe");
        VSIFCloseL(fp);
        goto done;
    }
    text[size] = '\0';
    VSIFCloseL(fp);
    CPLPushErrorHandler(CPLQuietErrorHandler);
    root = CPLParseXMLString(text);
    if (!root) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", CPLGetLastErrorMsg());
        CPLPopErrorHandler();
        rerr(err, path, "not well-formed XML (%s)", msg[0] ? msg : "parse error");
        goto done;
    }
    CPLPopErrorHandler();
    top = CPLGetXMLNode(root, "=TerraSynth");
    if (!top) {
        rerr(err, path, "the root element must be <TerraSynth>");
        goto done;
    }
    if (strcmp(CPLGetXMLValue(top, "version", "1"), "1") != 0) {
        rerr(err, path, "<TerraSynth version=\"%s\"> is not supported (only 1)",
             CPLGetXMLValue(top, "version", ""));
        goto done;
    }
    recipe_stack[recipe_depth++] = r->path;
    if ((node = CPLGetXMLNode(top, "PPA")))
        rc = recipe_ppa(r, node, oo, err);
    else if ((node = CPLGetXMLNode(top, "Synth")))
        rc = recipe_synth(r, node, oo, err);
    else
        rerr(err, path, "<TerraSynth> needs a <PPA> or a <Synth> element");
    recipe_depth--;
done:
    CPLDestroyXMLNode(root);
    CPLFree(text);
    if (rc != 0) {
        recipe_free(r);
        return -1;
    }
    *out = r;
    return 0;
}

void recipe_free(ts_recipe *r)
{
    if (!r)
        return;
    tsjob_ppa_result_free(&r->ppa_res);
    tsjob_synth_result_free(&r->synth_res);
    tsio_georef_free(&r->geo);
    CSLDestroy(r->strings);
    CPLFree(r->path);
    free(r);
}

const tsio_georef *recipe_georef(const ts_recipe *r)
{
    return r->method == RECIPE_PPA ? &r->geo : &r->synth_res.geo;
}

int recipe_gdal_type(const ts_recipe *r)
{
    return r->method == RECIPE_PPA ? GDT_Byte : GDT_Float32;
}

double recipe_nodata(const ts_recipe *r)
{
    return r->method == RECIPE_PPA ? 255.0 : -9999.0;
}

int recipe_compute(ts_recipe *r, tsio_err *err)
{
    ts_ctx *ctx;
    int rc;
    size_t i, n;
    if (r->computed)
        return 0;
    if (recipe_depth >= RECIPE_MAX_DEPTH) {
        rerr(err, r->path, "recipes nested more than %d deep (recursion?)", RECIPE_MAX_DEPTH);
        return -1;
    }
    ctx = ts_ctx_new();
    if (!ctx) {
        rerr(err, r->path, "out of memory");
        return -1;
    }
    ts_ctx_set_seed(ctx, r->seed);
    recipe_stack[recipe_depth++] = r->path;
    if (r->method == RECIPE_PPA) {
        rc = tsjob_ppa_prepare(&r->ppa, &r->ppa_res, err);
        if (rc == 0 && (r->ppa_res.in.geo.width != r->geo.width ||
                        r->ppa_res.in.geo.height != r->geo.height)) {
            rerr(err, r->path, "the input changed size since the recipe was opened");
            rc = -1;
        }
        if (rc == 0)
            rc = tsjob_ppa_compute(ctx, &r->ppa, &r->ppa_res, err);
    } else {
        rc = tsjob_synth_compute(ctx, &r->synth, &r->synth_res, NULL, err);
        if (rc == 0) {
            /* nodata as the driver declares it */
            n = (size_t)r->synth_res.out.width * (size_t)r->synth_res.out.height;
            for (i = 0; i < n; i++)
                if (isnan(r->synth_res.out.data[i]))
                    r->synth_res.out.data[i] = -9999.0f;
        }
    }
    recipe_depth--;
    ts_ctx_free(ctx);
    r->computed = rc == 0;
    return rc;
}

const void *recipe_data(const ts_recipe *r)
{
    if (!r->computed)
        return NULL;
    return r->method == RECIPE_PPA ? (const void *)r->ppa_res.codes
                                   : (const void *)r->synth_res.out.data;
}

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

static void recipe_add_params(CPLXMLNode *node, const char *stage, const void *params)
{
    size_t n, k;
    const ts_param_desc *d = ts_params_describe(stage, &n);
    ts_ctx *ctx = ts_ctx_new();
    for (k = 0; k < n && ctx; k++) {
        char value[128];
        CPLXMLNode *p;
        if (ts_params_get(ctx, stage, params, d[k].name, value, sizeof value) != TS_OK)
            continue;
        p = CPLCreateXMLElementAndValue(node, "Param", value);
        CPLAddXMLAttributeAndValue(p, "name", d[k].name);
    }
    ts_ctx_free(ctx);
}

static int recipe_save(const char *path, CPLXMLNode *root, tsio_err *err)
{
    char *xml = CPLSerializeXMLTree(root);
    char *tmp = CPLStrdup(CPLSPrintf("%s.tmp%ld", path, (long)getpid()));
    VSILFILE *fp = VSIFOpenL(tmp, "wb");
    int rc = -1;
    if (!fp) {
        rerr(err, path, "cannot create the recipe (does the folder exist?)");
    } else {
        size_t len = strlen(xml);
        int ok = VSIFWriteL(xml, 1, len, fp) == len;
        ok = (VSIFCloseL(fp) == 0) && ok;
        if (ok && VSIRename(tmp, path) == 0)
            rc = 0;
        else {
            VSIUnlink(tmp);
            rerr(err, path, "cannot write the recipe");
        }
    }
    CPLFree(tmp);
    CPLFree(xml);
    return rc;
}

int recipe_write_ppa(const char *path, const tsjob_ppa *job, tsio_err *err)
{
    CPLXMLNode *root = CPLCreateXMLNode(NULL, CXT_Element, "TerraSynth"), *node, *in;
    int rc;
    CPLAddXMLAttributeAndValue(root, "version", "1");
    node = CPLCreateXMLNode(root, CXT_Element, "PPA");
    in = CPLCreateXMLElementAndValue(node, "Input", recipe_rel(path, job->input));
    CPLAddXMLAttributeAndValue(in, "band", CPLSPrintf("%d", job->band));
    if (job->cell_size > 0)
        CPLCreateXMLElementAndValue(node, "CellSize", CPLSPrintf("%.17g", job->cell_size));
    recipe_add_params(node, "ppa", &job->params);
    rc = recipe_save(path, root, err);
    CPLDestroyXMLNode(root);
    return rc;
}

int recipe_write_synth(const char *path, const tsjob_synth *job, uint64_t seed, tsio_err *err)
{
    CPLXMLNode *root = CPLCreateXMLNode(NULL, CXT_Element, "TerraSynth"), *node, *grid;
    const tsjob_grid *g = &job->grid;
    int i, rc;
    CPLAddXMLAttributeAndValue(root, "version", "1");
    node = CPLCreateXMLNode(root, CXT_Element, "Synth");
    CPLAddXMLAttributeAndValue(node, "seed", CPLSPrintf("%llu", (unsigned long long)seed));
    for (i = 0; i < job->n_exemplars; i++)
        CPLCreateXMLElementAndValue(node, "Exemplar", recipe_rel(path, job->exemplars[i]));
    if (job->sketch)
        CPLCreateXMLElementAndValue(node, "Sketch", recipe_rel(path, job->sketch));
    if (job->cell_size > 0)
        CPLCreateXMLElementAndValue(node, "CellSize", CPLSPrintf("%.17g", job->cell_size));
    for (i = 0; i < job->n_pins; i++) {
        const tsjob_pin *p = &job->pins[i];
        CPLXMLNode *pn = CPLCreateXMLElementAndValue(node, "Pin", recipe_rel(path, p->path));
        CPLAddXMLAttributeAndValue(pn, "xoff", CPLSPrintf("%d", p->xoff));
        CPLAddXMLAttributeAndValue(pn, "yoff", CPLSPrintf("%d", p->yoff));
        CPLAddXMLAttributeAndValue(pn, "width", CPLSPrintf("%d", p->width));
        CPLAddXMLAttributeAndValue(pn, "height", CPLSPrintf("%d", p->height));
        CPLAddXMLAttributeAndValue(pn, "x", CPLSPrintf("%d", p->x));
        CPLAddXMLAttributeAndValue(pn, "y", CPLSPrintf("%d", p->y));
    }
    if (job->heights) {
        CPLXMLNode *hn = CPLCreateXMLElementAndValue(node, "Heights", recipe_rel(path, job->heights));
        CPLAddXMLAttributeAndValue(hn, "alpha", CPLSPrintf("%.17g", job->alpha_h));
    }
    if (job->regions) {
        CPLCreateXMLElementAndValue(node, "Regions", recipe_rel(path, job->regions));
        for (i = 0; i < job->n_region_rules; i++) {
            CPLXMLNode *rn = CPLCreateXMLElementAndValue(
                node, "RegionExemplar", recipe_rel(path, job->exemplars[job->region_exemplar[i]]));
            CPLAddXMLAttributeAndValue(rn, "id", CPLSPrintf("%d", job->region_id[i]));
        }
    }
    if (job->water) {
        CPLXMLNode *wn = CPLCreateXMLElementAndValue(node, "Water", recipe_rel(path, job->water));
        CPLAddXMLAttributeAndValue(wn, "level", CPLSPrintf("%.17g", job->water_level));
    }
    grid = job->sketch ? NULL : CPLCreateXMLNode(node, CXT_Element, "Grid");
    if (!grid) {
        /* the sketch's grid */
    } else if (g->like) {
        CPLAddXMLAttributeAndValue(grid, "like", recipe_rel(path, g->like));
    } else {
        CPLAddXMLAttributeAndValue(grid, "width", CPLSPrintf("%d", g->width));
        CPLAddXMLAttributeAndValue(grid, "height", CPLSPrintf("%d", g->height));
        if (g->has_origin) {
            CPLAddXMLAttributeAndValue(grid, "originX", CPLSPrintf("%.17g", g->origin_x));
            CPLAddXMLAttributeAndValue(grid, "originY", CPLSPrintf("%.17g", g->origin_y));
        }
        if (g->has_res)
            CPLAddXMLAttributeAndValue(grid, "resolution", CPLSPrintf("%.17g", g->res));
        if (g->crs)
            CPLAddXMLAttributeAndValue(grid, "crs", g->crs);
    }
    recipe_add_params(node, "synth", &job->params);
    if (job->sketch)
        recipe_add_params(node, "sketch", &job->sketch_params);
    rc = recipe_save(path, root, err);
    CPLDestroyXMLNode(root);
    return rc;
}

char *recipe_open_option_list(void)
{
    const char *const *stages = ts_params_stages();
    size_t cap = 8192, len = 0;
    char *s = malloc(cap);
    int i;
    if (!s)
        return NULL;
    len += (size_t)snprintf(s + len, cap - len,
                            "<OpenOptionList>"
                            "<Option name='SEED' type='int' description='random seed'/>");
    for (i = 0; stages[i]; i++) {
        size_t n, k;
        const ts_param_desc *d = ts_params_describe(stages[i], &n);
        for (k = 0; k < n; k++) {
            char name[64];
            size_t j;
            int w;
            for (j = 0; d[k].name[j] && j + 1 < sizeof name; j++)
                name[j] = (char)toupper((unsigned char)d[k].name[j]);
            name[j] = '\0';
            char *help;
            if (strstr(s, CPLSPrintf("name='%s'", name)))
                continue; /* shared by two stages */
            help = CPLEscapeString(d[k].help, -1, CPLES_XML);
            {
                /* the list quotes attributes with ' */
                char *q = help, *e;
                while ((e = strchr(q, '\''))) {
                    char *nh = CPLStrdup(CPLSPrintf("%.*s&apos;%s", (int)(e - help), help, e + 1));
                    q = nh + (e - help) + 6;
                    CPLFree(help);
                    help = nh;
                }
            }
            w = snprintf(s + len, cap - len,
                         "<Option name='%s' type='%s' description='%s (%s)'/>", name,
                         d[k].type == TS_PARAM_INT      ? "int"
                         : d[k].type == TS_PARAM_DOUBLE ? "float"
                                                        : "string",
                         help, stages[i]);
            CPLFree(help);
            if (w < 0 || (size_t)w >= cap - len) {
                char *ns;
                cap *= 2;
                ns = realloc(s, cap);
                if (!ns) {
                    free(s);
                    return NULL;
                }
                s = ns;
                k--;
                continue;
            }
            len += (size_t)w;
        }
    }
    if (len + 32 >= cap) {
        char *ns = realloc(s, cap + 64);
        if (!ns) {
            free(s);
            return NULL;
        }
        s = ns;
    }
    snprintf(s + len, 32, "</OpenOptionList>");
    return s;
}
