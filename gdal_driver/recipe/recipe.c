/*
 * recipe.c - parse, resolve and compute TerraSynth recipes (.tsyn); read
 * any window of one (recipe_write.c writes them, recipe_tiles.c serves the
 * tiles of a tiled synth recipe).
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

/* Recipes being opened or computed on this thread: a recipe that reaches
 * itself again through its inputs is recursion. */
static _Thread_local const char *recipe_stack[RECIPE_MAX_DEPTH];
static _Thread_local int recipe_depth;

int tsrecipe_identify(const char *filename, const unsigned char *header, int n_header)
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
static const char *recipe_keep_path(tsrecipe *r, const char *value)
{
    char *dir = CPLStrdup(CPLGetPath(r->path));
    const char *resolved = value;
    if (CPLIsFilenameRelative(value) && strncmp(value, "/vsi", 4) != 0)
        resolved = CPLProjectRelativeFilename(dir, value);
    r->strings = CSLAddString(r->strings, resolved);
    CPLFree(dir);
    return r->strings[CSLCount(r->strings) - 1];
}

static int recipe_check_not_self(const tsrecipe *r, const char *input, tsio_err *err)
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
        tsio_errf(err, r->path, "the recipe refers to itself through %s (recursion)", input);
    return same ? -1 : 0;
}

/* A file name of the recipe as GDAL should open it, refused when it is the
 * recipe itself or one that is opening it (tsrecipe_values_from_xml's resolver). */
static const char *recipe_resolve(void *user, const char *name, char *msg, size_t len)
{
    tsrecipe *r = user;
    const char *path;
    tsio_err e;
    if (tsio_name_offline(name, &e) != 0) {
        snprintf(msg, len, "%s", e.msg);
        return NULL;
    }
    path = recipe_keep_path(r, name);
    if (tsio_input_offline(path, &e) != 0) {
        snprintf(msg, len, "%s", e.msg);
        return NULL;
    }
    if (recipe_check_not_self(r, path, &e) != 0) {
        /* without the recipe's own name: the caller adds it */
        const char *colon = strstr(e.msg, ": ");
        snprintf(msg, len, "%s", colon ? colon + 2 : e.msg);
        return NULL;
    }
    return path;
}

/* Open options: SEED, the stage parameters and the job's options that are
 * not files (a recipe reads only the rasters it names), any case. */
static int recipe_options(tsrecipe *r, const char *const *oo, tsio_err *err)
{
    int i;
    for (i = 0; oo && oo[i]; i++) {
        char *key = NULL;
        const char *value = CPLParseNameValue(oo[i], &key);
        const tsjob_option *o;
        char *p;
        if (!key || !value) {
            CPLFree(key);
            continue;
        }
        for (p = key; *p; p++)
            *p = (char)tolower((unsigned char)*p);
        if (!strcmp(key, "map") && r->method == TSRECIPE_SYNTH) {
            int m;
            r->map = -2;
            if (EQUAL(value, "dem"))
                r->map = -1;
            for (m = 0; m < TSJOB_N_MAPS; m++)
                if (EQUAL(value, tsjob_map_names[m]))
                    r->map = m;
            if (r->map == -2) {
                tsio_errf(err, r->path,
                          "open option MAP=%s: not one of dem, seams, source_exemplar, "
                          "source_x, source_y, order",
                          value);
                CPLFree(key);
                return -1;
            }
            CPLFree(key);
            continue;
        }
        if (!strcmp(key, "layer") && r->method == TSRECIPE_AMPLIFY) {
            size_t n = strspn(value, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                     "0123456789_-");
            if (!value[0] || value[n] || n >= TS_LAYER_NAME) {
                tsio_errf(err, r->path, "open option LAYER=%s: not a layer name", value);
                CPLFree(key);
                return -1;
            }
            snprintf(r->layer, sizeof r->layer, "%s", EQUAL(value, "dem") ? "" : value);
            CPLFree(key);
            continue;
        }
        o = tsjob_option_find(r->values.job, key);
        if (o ? (!o->xml || o->kind == TSJOB_FILE || o->kind == TSJOB_PIN ||
                 o->kind == TSJOB_RULE || o->kind == TSJOB_NAMED || o->kind == TSJOB_PAIR)
              : !tsjob_param_stage(r->values.job, key)) {
            tsio_errf(err, r->path, "open option %s: not an option of %s recipes", oo[i],
                      r->values.job->name);
            CPLFree(key);
            return -1;
        }
        tsjob_set(&r->values, key, value);
        CPLFree(key);
    }
    return 0;
}

/* The job of the recipe: its element read into values, the open options
 * over them, then the one check and conversion every front end shares. */
static int recipe_job(tsrecipe *r, CPLXMLNode *node, const char *const *oo, tsio_err *err)
{
    char msg[1024];
    tsjob_values_init(&r->values, tsjob_find(r->method == TSRECIPE_PPA     ? "ppa"
                                             : r->method == TSRECIPE_SYNTH ? "synth"
                                             : r->method == TSRECIPE_PIXEL ? "pixel"
                                                                           : "amplify"));
    if (tsrecipe_values_from_xml(&r->values, node, recipe_resolve, r, msg, sizeof msg) != 0) {
        tsio_errf(err, r->path, "%s", msg);
        return -1;
    }
    if (recipe_options(r, oo, err) != 0)
        return -1;
    if (r->method == TSRECIPE_PPA) {
        if (tsjob_build_ppa(&r->values, &r->ppa, msg, sizeof msg) != 0) {
            tsio_errf(err, r->path, "%s", msg);
            return -1;
        }
        /* the grid without reading the cells */
        if (tsio_read_georef(r->ppa.input, &r->geo, err) != 0)
            return -1;
        return tsjob_ppa_check_memory(&r->geo, r->ppa.input, err);
    }
    if (r->method == TSRECIPE_PIXEL) {
        if (tsjob_build_pixel(&r->values, &r->pixel, &r->seed, msg, sizeof msg) != 0) {
            tsio_errf(err, r->path, "%s", msg);
            return -1;
        }
        if (r->pixel.grid.crs && tsio_crs_offline(r->pixel.grid.crs, err) != 0) {
            tsio_errf(err, r->path, "%s", err->msg);
            return -1;
        }
        r->pixel.lazy = 1; /* computed block by block: tsrecipe_read_window */
        if (tsjob_pixel_prepare(&r->pixel, &r->pixel_res, err) != 0)
            return -1;
        return tsrecipe_drainage_margin(r) ? tsrecipe__raw_init(r, err) : 0;
    }
    if (r->method == TSRECIPE_AMPLIFY) {
        if (tsjob_build_amplify(&r->values, &r->amplify, msg, sizeof msg) != 0) {
            tsio_errf(err, r->path, "%s", msg);
            return -1;
        }
        r->amplify.lazy = 1; /* computed block by block: tsrecipe_read_window */
        /* a carried layer or the classes instead of the DEM (LAYER) */
        if (!strcmp(r->layer, "classes")) {
            r->amplify.want_classes = 1;
        } else if (r->layer[0]) {
            snprintf(r->amplify.out_layer_names[0], TS_LAYER_NAME, "%s", r->layer);
            r->amplify.n_out_layers = 1;
        }
        if (tsjob_amplify_adopt_dictionary(&r->amplify, err) != 0) {
            tsio_errf(err, r->path, "%s", err->msg);
            return -1;
        }
        if (tsjob_amplify_prepare(&r->amplify, &r->amplify_res, err) != 0)
            return -1;
        return tsrecipe_drainage_margin(r) ? tsrecipe__raw_init(r, err) : 0;
    }
    if (tsjob_build_synth(&r->values, &r->synth, &r->seed, msg, sizeof msg) != 0) {
        tsio_errf(err, r->path, "%s", msg);
        return -1;
    }
    if (r->synth.grid.crs && tsio_crs_offline(r->synth.grid.crs, err) != 0) {
        tsio_errf(err, r->path, "%s", err->msg);
        return -1;
    }
    if (r->synth.params.tiled > 0 && r->synth.sketch) {
        /* a sketch in tiles: laid out on the first read, then block by block */
        if (r->map >= 0) {
            tsio_errf(err, r->path, "a sketch in tiles takes no debug maps yet (MAP)");
            return -1;
        }
        r->synth.lazy = 1;
        if (ts_drainage_margin(&r->synth.drainage) && tsrecipe__raw_init(r, err) != 0)
            return -1;
    } else if (r->synth.params.tiled > 0) {
        /* tile by tile: tsrecipe_read_window makes the tiles a block needs */
        if (r->map >= 0) {
            tsio_errf(err, r->path, "tiles (tiled %d) take no debug maps yet (MAP)",
                      r->synth.params.tiled);
            return -1;
        }
        if (tsrecipe__cache_limit(r, &r->synth.tile_cache, err) != 0)
            return -1;
        r->synth.lazy = 1;
        if (pthread_mutex_init(&r->tile_lock, NULL) != 0) {
            tsio_errf(err, r->path, "out of resources for a lock");
            return -1;
        }
        r->has_tile_lock = 1;
    }
    if (tsjob_synth_prepare(&r->synth, &r->synth_res, err) != 0) {
        /* the core's words, the recipe's name */
        if (strncmp(err->msg, r->path, strlen(r->path)) != 0) {
            char msg[sizeof err->msg];
            snprintf(msg, sizeof msg, "%s", err->msg);
            tsio_errf(err, r->path, "%s", msg);
        }
        return -1;
    }
    return 0;
}

/* Read and parse a recipe file; *top is its <TerraSynth> element (version
 * checked), *root the tree to free. */
static int recipe_read_xml(const char *path, CPLXMLNode **root, CPLXMLNode **top, tsio_err *err)
{
    VSILFILE *fp;
    vsi_l_offset size;
    char *text;
    *root = *top = NULL;
    fp = VSIFOpenL(path, "rb");
    if (!fp) {
        tsio_errf(err, path, "cannot open the recipe");
        return -1;
    }
    VSIFSeekL(fp, 0, SEEK_END);
    size = VSIFTellL(fp);
    VSIFSeekL(fp, 0, SEEK_SET);
    if (size == 0 || size > RECIPE_MAX_BYTES) {
        tsio_errf(err, path, "a recipe must be 1 byte to 1 MB, not %llu bytes",
                  (unsigned long long)size);
        VSIFCloseL(fp);
        return -1;
    }
    text = CPLMalloc((size_t)size + 1);
    if (VSIFReadL(text, 1, (size_t)size, fp) != (size_t)size) {
        tsio_errf(err, path, "cannot read the recipe");
        VSIFCloseL(fp);
        CPLFree(text);
        return -1;
    }
    text[size] = '\0';
    VSIFCloseL(fp);
    CPLPushErrorHandler(CPLQuietErrorHandler);
    *root = CPLParseXMLString(text);
    CPLFree(text);
    if (!*root) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", CPLGetLastErrorMsg());
        CPLPopErrorHandler();
        tsio_errf(err, path, "not well-formed XML (%s)", msg[0] ? msg : "parse error");
        return -1;
    }
    CPLPopErrorHandler();
    *top = CPLGetXMLNode(*root, "=TerraSynth");
    if (!*top) {
        tsio_errf(err, path, "the root element must be <TerraSynth>");
        return -1;
    }
    if (strcmp(CPLGetXMLValue(*top, "version", "1"), "1") != 0) {
        tsio_errf(err, path, "<TerraSynth version=\"%s\"> is not supported (only 1)",
                  CPLGetXMLValue(*top, "version", ""));
        return -1;
    }
    return 0;
}

/* Is the file at path a recipe (by its name or its first bytes)? */
static int recipe_is_recipe(const char *path)
{
    unsigned char head[64];
    size_t n = 0;
    VSILFILE *fp;
    if (EQUAL(CPLGetExtension(path), "tsyn"))
        return 1;
    fp = VSIFOpenL(path, "rb");
    if (!fp)
        return 0;
    n = VSIFReadL(head, 1, sizeof head, fp);
    VSIFCloseL(fp);
    return tsrecipe_identify(path, head, (int)n);
}

/* The files a recipe names (tsrecipe_values_from_xml's resolver: every file option the
 * jobs declare), relative to its folder. */
typedef struct recipe_names {
    char *dir;
    char **names;
} recipe_names;

static const char *recipe_collect(void *user, const char *name, char *msg, size_t len)
{
    recipe_names *n = user;
    const char *resolved = name;
    tsio_err e;
    if (tsio_name_offline(name, &e) != 0) {
        snprintf(msg, len, "%s", e.msg); /* never followed; the open refuses it */
        return NULL;
    }
    if (CPLIsFilenameRelative(name) && strncmp(name, "/vsi", 4) != 0)
        resolved = CPLProjectRelativeFilename(n->dir, name);
    if (tsio_name_plain(resolved, &e) != 0) {
        snprintf(msg, len, "%s", e.msg); /* never read; the open refuses it */
        return NULL;
    }
    n->names = CSLAddString(n->names, resolved);
    return n->names[CSLCount(n->names) - 1];
}

/* The same file, as far as a loop goes (links and spellings resolved). */
static int recipe_same(const char *a, const char *b)
{
    char ra[4096], rb[4096];
    if (realpath(a, ra) && realpath(b, rb))
        return strcmp(ra, rb) == 0;
    return strcmp(a, b) == 0;
}

/* "a.tsyn -> b.tsyn -> ..." of the chain, and `last` after it. */
static void recipe_chain_text(char *buf, size_t len, char **chain, const char *last)
{
    size_t used = 0;
    int i;
    buf[0] = '\0';
    for (i = 0; chain && chain[i] && used < len; i++)
        used += (size_t)snprintf(buf + used, len - used, "%s -> ", CPLGetFilename(chain[i]));
    if (used < len)
        snprintf(buf + used, len - used, "%s", CPLGetFilename(last));
}

/* Follow every recipe that `path` names, and those they name: a recipe met
 * again is a loop, refused at open with the chain; so is nesting past
 * RECIPE_MAX_DEPTH.  Recipes that cannot be read are left to their own
 * open to report. */
static int recipe_scan(const char *path, char ***chain, tsio_err *err)
{
    CPLXMLNode *root = NULL, *top = NULL, *node;
    recipe_names n = {NULL, NULL};
    tsio_err ignored;
    char msg[1024];
    int rc = 0, i, j, depth = CSLCount(*chain);
    if (recipe_read_xml(path, &root, &top, &ignored) != 0) {
        CPLDestroyXMLNode(root);
        return 0;
    }
    {
        const CPLXMLNode *cn = NULL;
        const tsjob_decl *job = tsjob_find_element(top, &cn);
        node = (CPLXMLNode *)cn;
        if (!job)
            node = NULL;
    }
    if (node) {
        tsjob_values v;
        tsjob_values_init(&v, tsjob_find_element(top, NULL));
        n.dir = CPLStrdup(CPLGetPath(path));
        tsrecipe_values_from_xml(&v, node, recipe_collect, &n, msg,
                                 sizeof msg); /* names, not checks */
        tsjob_values_free(&v);
    }
    CPLDestroyXMLNode(root);
    for (i = 0; n.names && n.names[i] && rc == 0; i++) {
        const char *name = n.names[i];
        if (!recipe_is_recipe(name))
            continue;
        for (j = 0; j < depth; j++)
            if (recipe_same(name, (*chain)[j])) {
                recipe_chain_text(msg, sizeof msg, *chain, name);
                tsio_errf(err, (*chain)[0],
                          "recipes that name each other in a loop (recursion): %s", msg);
                rc = -1;
                break;
            }
        if (rc == 0 && depth + 1 >= RECIPE_MAX_DEPTH) {
            recipe_chain_text(msg, sizeof msg, *chain, name);
            tsio_errf(err, (*chain)[0], "recipes nested more than %d deep: %s", RECIPE_MAX_DEPTH,
                      msg);
            rc = -1;
        }
        if (rc == 0) {
            *chain = CSLAddString(*chain, name);
            rc = recipe_scan(name, chain, err);
            CPLFree((*chain)[depth]);
            (*chain)[depth] = NULL;
        }
    }
    CSLDestroy(n.names);
    CPLFree(n.dir);
    return rc;
}

static int recipe_open_offline(const char *path, const char *const *oo, tsrecipe **out,
                               tsio_err *err)
{
    tsrecipe *r;
    CPLXMLNode *root = NULL, *top, *node;
    int rc = -1;
    *out = NULL;
    if (recipe_depth >= RECIPE_MAX_DEPTH) {
        tsio_errf(err, path, "recipes nested more than %d deep (recursion?)", RECIPE_MAX_DEPTH);
        return -1;
    }
    r = calloc(1, sizeof *r);
    if (!r) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    r->map = -1;
    r->path = CPLStrdup(path);
    if (recipe_read_xml(path, &root, &top, err) != 0)
        goto done;
    if (recipe_depth == 0) {
        /* the outermost recipe: every loop through any input, before any is opened */
        char **chain = CSLAddString(NULL, path);
        int bad = recipe_scan(path, &chain, err);
        CSLDestroy(chain);
        if (bad)
            goto done;
    }
    recipe_stack[recipe_depth++] = r->path;
    {
        const CPLXMLNode *cn = NULL;
        const tsjob_decl *job = tsjob_find_element(top, &cn);
        node = (CPLXMLNode *)cn;
        char msg[512];
        if (job && tsrecipe_check_schema(job, top, node, msg, sizeof msg) != 0) {
            tsio_errf(err, path, "%s", msg);
        } else if (job) {
            r->method = !strcmp(job->name, "ppa")       ? TSRECIPE_PPA
                        : !strcmp(job->name, "synth")   ? TSRECIPE_SYNTH
                        : !strcmp(job->name, "pixel")   ? TSRECIPE_PIXEL
                        : !strcmp(job->name, "amplify") ? TSRECIPE_AMPLIFY
                                                        : 0;
            if (r->method)
                rc = recipe_job(r, node, oo, err);
            else
                tsio_errf(err, path, "<%s> is not a job a recipe runs", job->element);
        } else {
            tsio_errf(err, path,
                      "<TerraSynth> needs a <PPA>, a <Synth>, an <Amplify> or a <Pixel> element");
        }
    }
    recipe_depth--;
done:
    CPLDestroyXMLNode(root);
    if (rc != 0) {
        tsrecipe_free(r);
        return -1;
    }
    *out = r;
    return 0;
}

int tsrecipe_open(const char *path, const char *const *oo, tsrecipe **out, tsio_err *err)
{
    tsio_offline g;
    int rc;
    tsio_offline_begin(&g);
    rc = recipe_open_offline(path, oo, out, err);
    tsio_offline_end(&g);
    return rc;
}

void tsrecipe_free(tsrecipe *r)
{
    if (!r)
        return;
    tsjob_ppa_result_free(&r->ppa_res);
    tsjob_synth_result_free(&r->synth_res);
    tsjob_amplify_result_free(&r->amplify_res);
    tsjob_pixel_result_free(&r->pixel_res);
    for (size_t i = 0; i < r->n_tiles; i++)
        free(r->tiles[i].cells);
    free(r->tiles);
    if (r->has_tile_lock)
        pthread_mutex_destroy(&r->tile_lock);
    tsrecipe__raw_free(r);
    tsio_georef_free(&r->geo);
    tsjob_values_free(&r->values);
    CSLDestroy(r->strings);
    CPLFree(r->path);
    free(r);
}

const tsio_georef *tsrecipe_georef(const tsrecipe *r)
{
    if (r->method == TSRECIPE_AMPLIFY)
        return &r->amplify_res.geo;
    if (r->method == TSRECIPE_PIXEL)
        return &r->pixel_res.geo;
    return r->method == TSRECIPE_PPA ? &r->geo : &r->synth_res.geo;
}

int tsrecipe_gdal_type(const tsrecipe *r)
{
    if (r->method == TSRECIPE_PPA || r->map == TSJOB_MAP_SEAMS)
        return GDT_Byte;
    return r->map < 0 ? GDT_Float32 : GDT_Int32;
}

double tsrecipe_nodata(const tsrecipe *r)
{
    if (r->method == TSRECIPE_PPA || r->map == TSJOB_MAP_SEAMS)
        return 255.0;
    return r->map < 0 ? TSIO_NODATA : -1.0;
}

/* A note from the core while a recipe is computed: a GDAL warning. */
static void recipe_notice(const char *stage, const char *msg, void *user)
{
    CPLError(CE_Warning, CPLE_AppDefined, "%s: %s: %s", (const char *)user, stage, msg);
}

static int recipe_compute_offline(tsrecipe *r, tsio_err *err)
{
    ts_ctx *ctx;
    int rc;
    size_t i, n;
    if (r->computed)
        return 0;
    if (recipe_depth >= RECIPE_MAX_DEPTH) {
        tsio_errf(err, r->path, "recipes nested more than %d deep (recursion?)", RECIPE_MAX_DEPTH);
        return -1;
    }
    ctx = ts_ctx_new();
    if (!ctx) {
        tsio_errf(err, r->path, "out of memory");
        return -1;
    }
    ts_ctx_set_seed(ctx, r->seed);
    ts_ctx_set_notice(ctx, recipe_notice, r->path);
    recipe_stack[recipe_depth++] = r->path;
    if (r->method == TSRECIPE_PPA) {
        rc = tsjob_ppa_prepare(&r->ppa, &r->ppa_res, err);
        if (rc == 0 && (r->ppa_res.in.geo.width != r->geo.width ||
                        r->ppa_res.in.geo.height != r->geo.height)) {
            tsio_errf(err, r->path, "the input changed size since the recipe was opened");
            rc = -1;
        }
        if (rc == 0 && r->ppa_res.warning.msg[0])
            CPLError(CE_Warning, CPLE_AppDefined, "%s", r->ppa_res.warning.msg);
        if (rc == 0)
            rc = tsjob_ppa_compute(ctx, &r->ppa, &r->ppa_res, err);
    } else if (r->method == TSRECIPE_PIXEL) {
        /* the stacks every block shares; the blocks themselves: tsrecipe_read_window */
        rc = tsjob_pixel_setup(ctx, &r->pixel, &r->pixel_res, err);
        if (rc == 0 && r->pixel_res.warning.msg[0])
            CPLError(CE_Warning, CPLE_AppDefined, "%s", r->pixel_res.warning.msg);
    } else if (r->method == TSRECIPE_AMPLIFY) {
        /* what every block shares; the blocks themselves: tsrecipe_read_window */
        rc = tsjob_amplify_setup(ctx, &r->amplify, &r->amplify_res, err);
        if (rc == 0 && r->amplify_res.warning.msg[0])
            CPLError(CE_Warning, CPLE_AppDefined, "%s", r->amplify_res.warning.msg);
    } else if (r->synth.lazy && r->synth.sketch) {
        /* the coarse pass and the dictionary every block shares (no whole output) */
        rc = tsjob_synth_compute(ctx, &r->synth, &r->synth_res, 0, err);
        if (rc == 0 && r->synth_res.warning.msg[0])
            CPLError(CE_Warning, CPLE_AppDefined, "%s", r->synth_res.warning.msg);
    } else if (r->synth.lazy) {
        /* the exemplars every tile shares; the tiles: tsrecipe_read_window */
        rc = tsjob_synth_setup(ctx, &r->synth, &r->synth_res, err);
        if (rc == 0 && r->synth_res.warning.msg[0])
            CPLError(CE_Warning, CPLE_AppDefined, "%s", r->synth_res.warning.msg);
    } else {
        rc = tsjob_synth_compute(ctx, &r->synth, &r->synth_res, r->map >= 0, err);
        if (rc == 0 && r->synth_res.warning.msg[0])
            CPLError(CE_Warning, CPLE_AppDefined, "%s", r->synth_res.warning.msg);
        if (rc == 0) {
            /* nodata as the driver declares it */
            n = (size_t)r->synth_res.out.width * (size_t)r->synth_res.out.height;
            for (i = 0; i < n; i++)
                if (isnan(r->synth_res.out.data[i]))
                    r->synth_res.out.data[i] = (float)TSIO_NODATA;
        }
    }
    recipe_depth--;
    ts_ctx_free(ctx);
    r->computed = rc == 0;
    return rc;
}

int tsrecipe_compute(tsrecipe *r, tsio_err *err)
{
    tsio_offline g;
    int rc;
    tsio_offline_begin(&g);
    rc = recipe_compute_offline(r, err);
    tsio_offline_end(&g);
    return rc;
}

const void *tsrecipe_data(const tsrecipe *r)
{
    if (!r->computed)
        return NULL;
    if (r->method == TSRECIPE_PPA)
        return r->ppa_res.codes;
    if (r->method == TSRECIPE_AMPLIFY || r->method == TSRECIPE_PIXEL || r->synth.lazy)
        return NULL; /* lazy: tsrecipe_read_window */
    if (r->map == TSJOB_MAP_SEAMS)
        return r->synth_res.maps.seams;
    if (r->map >= 0)
        return tsjob_synth_int_map(&r->synth_res, r->map);
    return r->synth_res.out.data;
}

int tsrecipe_block_size(const tsrecipe *r)
{
    if (r->method == TSRECIPE_SYNTH && r->synth.lazy && !r->synth.sketch &&
        r->synth_res.params.tiled < 256)
        return r->synth_res.params.tiled; /* a block inside one tile */
    return r->method == TSRECIPE_PIXEL ? 512 : 256;
}

const char *tsrecipe_job_name(const tsrecipe *r)
{
    return r->values.job ? r->values.job->element : "";
}

const char *tsrecipe_schedule(const tsrecipe *r)
{
    if (r->method == TSRECIPE_SYNTH && r->synth.lazy && !r->synth.sketch)
        return "tiles";
    return tsrecipe_lazy(r) ? "any" : "whole";
}

int tsrecipe_tile_size(const tsrecipe *r)
{
    return r->method == TSRECIPE_SYNTH && r->synth.lazy && !r->synth.sketch ? r->synth.params.tiled
                                                                            : 0;
}

int tsrecipe_drainage_margin(const tsrecipe *r)
{
    switch (r->method) {
    case TSRECIPE_SYNTH: /* (the automatic bank slope, -1, takes the margin of banks) */
        return ts_drainage_margin(&r->synth.drainage);
    case TSRECIPE_PIXEL:
        return ts_drainage_margin(&r->pixel.drainage);
    case TSRECIPE_AMPLIFY:
        return r->layer[0] ? 0 : ts_drainage_margin(&r->amplify.drainage);
    default:
        return 0;
    }
}

const char *const *tsrecipe_inputs(const tsrecipe *r)
{
    return (const char *const *)r->strings;
}

int tsrecipe_lazy(const tsrecipe *r)
{
    return r->method == TSRECIPE_AMPLIFY || r->method == TSRECIPE_PIXEL ||
           (r->method == TSRECIPE_SYNTH && r->synth.lazy);
}

/* A window of a tiled synth recipe's tiles before the drainage stage, with
 * the water and pins over it (a tsjob_raw_fn). */
static int recipe_tiles_raw(void *arg, ts_ctx *ctx, int x0, int y0, int w, int h, float *cells,
                            unsigned char *flags, tsio_err *err)
{
    tsrecipe *r = arg;
    if (tsrecipe__tiles_window(r, ctx, x0, y0, w, h, cells, err) != 0)
        return -1;
    return flags
               ? tsjob_synth_window_flags(&r->synth, &r->synth_res, x0, y0, w, h, flags, NULL, err)
               : 0;
}

static int recipe_read_window_offline(tsrecipe *r, int x0, int y0, int w, int h, float *out,
                                      tsio_err *err)
{
    ts_ctx *ctx;
    size_t i, n = (size_t)w * (size_t)h;
    int rc;
    if (!r->computed || !tsrecipe_lazy(r)) {
        tsio_errf(err, r->path, "not computed");
        return -1;
    }
    if (x0 < 0 || y0 < 0 || w < 1 || h < 1 || x0 > tsrecipe_georef(r)->width - w ||
        y0 > tsrecipe_georef(r)->height - h) {
        tsio_errf(err, r->path, "window %d,%d %dx%d is off the grid", x0, y0, w, h);
        return -1;
    }
    ctx = ts_ctx_new();
    if (!ctx) {
        tsio_errf(err, r->path, "out of memory");
        return -1;
    }
    if (r->method == TSRECIPE_SYNTH && r->synth.sketch) { /* a sketch in tiles */
        rc = r->has_raw_lock ? tsrecipe__raw_drained(r, ctx, x0, y0, w, h, out, err)
                             : tsjob_synth_sketch_window_raw(ctx, &r->synth, &r->synth_res, x0, y0,
                                                             w, h, out, err);
        ts_ctx_free(ctx);
        for (i = 0; rc == 0 && i < n; i++)
            if (isnan(out[i]))
                out[i] = (float)TSIO_NODATA; /* nodata as the driver declares it */
        return rc;
    }
    if (r->method == TSRECIPE_SYNTH) {
        ts_ctx_set_seed(ctx, r->seed);
        rc = tsjob_drained_window(ctx, &r->synth_res.drainage, tsrecipe_georef(r)->width,
                                  tsrecipe_georef(r)->height, x0, y0, w, h, recipe_tiles_raw, r,
                                  out, r->path, err);
        ts_ctx_free(ctx);
        for (i = 0; rc == 0 && i < n; i++)
            if (isnan(out[i]))
                out[i] = (float)TSIO_NODATA; /* nodata as the driver declares it */
        return rc;
    }
    if (r->method == TSRECIPE_PIXEL) {
        ts_ctx_set_seed(ctx, r->seed);
        rc = r->has_raw_lock
                 ? tsrecipe__raw_drained(r, ctx, x0, y0, w, h, out, err)
                 : tsjob_pixel_window(ctx, &r->pixel, &r->pixel_res, x0, y0, w, h, out, err);
        ts_ctx_free(ctx);
        return rc;
    }
    if (r->has_raw_lock && !r->layer[0]) { /* the amplified DEM, drained */
        rc = tsrecipe__raw_drained(r, ctx, x0, y0, w, h, out, err);
        ts_ctx_free(ctx);
        for (i = 0; rc == 0 && i < n; i++)
            if (isnan(out[i]))
                out[i] = (float)TSIO_NODATA; /* nodata as the driver declares it */
        return rc;
    }
    rc = tsjob_amplify_window(ctx, &r->amplify, &r->amplify_res, x0, y0, w, h,
                              !strcmp(r->layer, "classes") ? TSJOB_SERVE_CLASSES
                              : r->layer[0]                ? 0
                                                           : TSJOB_SERVE_DEM,
                              out, err);
    ts_ctx_free(ctx);
    for (i = 0; rc == 0 && i < n; i++)
        if (isnan(out[i]))
            out[i] = (float)TSIO_NODATA; /* nodata as the driver declares it */
    return rc;
}

int tsrecipe_read_window(tsrecipe *r, int x0, int y0, int w, int h, float *out, tsio_err *err)
{
    tsio_offline g;
    int rc;
    tsio_offline_begin(&g);
    rc = recipe_read_window_offline(r, x0, y0, w, h, out, err);
    tsio_offline_end(&g);
    return rc;
}
