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

#include "jobspec.h"
#include "recipe.h"

#define RECIPE_MAX_BYTES (1 << 20)
#define RECIPE_MAX_DEPTH 8

/* Recipes being opened or computed on this thread: a recipe that reaches
 * itself again through its inputs is recursion. */
static _Thread_local const char *recipe_stack[RECIPE_MAX_DEPTH];
static _Thread_local int recipe_depth;

/* A tile of a tiled synth recipe: its window's cells (ts_synth_tile_window). */
typedef struct recipe_tile {
    int ti, tj;
    int x0, y0, w, h; /* the window */
    float *cells;
    uint64_t used; /* the last request that needed it */
} recipe_tile;

struct ts_recipe {
    char *path;
    int method;
    tsjob_ppa ppa;
    tsjob_synth synth;
    uint64_t seed;
    tsj_values values;   /* what the recipe (and the open options) give: the jobs point in */
    char **strings;      /* CSL list owning every path string the jobs point to */
    tsio_georef geo;     /* ppa: the input's grid */
    tsjob_ppa_result ppa_res;
    tsjob_synth_result synth_res;
    tsjob_amplify amplify;
    tsjob_amplify_result amplify_res;
    tsjob_pixel pixel;
    tsjob_pixel_result pixel_res;
    int map; /* synth: -1 the terrain, else the TSJOB_MAP_* served (open option MAP) */
    char layer[TS_LAYER_NAME]; /* amplify: the carried layer or "classes" served (LAYER), or "" */
    int computed;
    /* a tiled synth recipe: the tiles made so far, at most tile_limit bytes
     * of them between requests (least recently used go first) */
    pthread_mutex_t tile_lock;
    int has_tile_lock;
    recipe_tile *tiles;
    size_t n_tiles, cap_tiles, tile_bytes;
    uint64_t tile_clock; /* the request being served */
};

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
        tsio_errf(err, r->path, "the recipe refers to itself through %s (recursion)", input);
    return same ? -1 : 0;
}

/* A file name of the recipe as GDAL should open it, refused when it is the
 * recipe itself or one that is opening it (tsj_from_xml's resolver). */
static const char *recipe_resolve(void *user, const char *name, char *msg, size_t len)
{
    ts_recipe *r = user;
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
static int recipe_options(ts_recipe *r, const char *const *oo, tsio_err *err)
{
    int i;
    for (i = 0; oo && oo[i]; i++) {
        char *key = NULL;
        const char *value = CPLParseNameValue(oo[i], &key);
        const tsj_option *o;
        char *p;
        if (!key || !value) {
            CPLFree(key);
            continue;
        }
        for (p = key; *p; p++)
            *p = (char)tolower((unsigned char)*p);
        if (!strcmp(key, "map") && r->method == RECIPE_SYNTH) {
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
        if (!strcmp(key, "layer") && r->method == RECIPE_AMPLIFY) {
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
        o = tsj_option_find(r->values.job, key);
        if (o ? (!o->xml || o->kind == TSJ_FILE || o->kind == TSJ_PIN || o->kind == TSJ_RULE ||
                 o->kind == TSJ_NAMED || o->kind == TSJ_PAIR)
              : !tsj_param_stage(r->values.job, key)) {
            tsio_errf(err, r->path, "open option %s: not an option of %s recipes", oo[i],
                      r->values.job->name);
            CPLFree(key);
            return -1;
        }
        tsj_set(&r->values, key, value);
        CPLFree(key);
    }
    return 0;
}

/* The job of the recipe: its element read into values, the open options
 * over them, then the one check and conversion every front end shares. */
static int recipe_job(ts_recipe *r, CPLXMLNode *node, const char *const *oo, tsio_err *err)
{
    char msg[1024];
    tsj_values_init(&r->values, tsj_find(r->method == RECIPE_PPA     ? "ppa"
                                         : r->method == RECIPE_SYNTH ? "synth"
                                         : r->method == RECIPE_PIXEL ? "pixel"
                                                                     : "amplify"));
    if (tsj_from_xml(&r->values, node, recipe_resolve, r, msg, sizeof msg) != 0) {
        tsio_errf(err, r->path, "%s", msg);
        return -1;
    }
    if (recipe_options(r, oo, err) != 0)
        return -1;
    if (r->method == RECIPE_PPA) {
        if (tsj_build_ppa(&r->values, &r->ppa, msg, sizeof msg) != 0) {
            tsio_errf(err, r->path, "%s", msg);
            return -1;
        }
        /* the grid without reading the cells */
        if (tsio_read_georef(r->ppa.input, &r->geo, err) != 0)
            return -1;
        return tsjob_ppa_check_memory(&r->geo, r->ppa.input, err);
    }
    if (r->method == RECIPE_PIXEL) {
        if (tsj_build_pixel(&r->values, &r->pixel, &r->seed, msg, sizeof msg) != 0) {
            tsio_errf(err, r->path, "%s", msg);
            return -1;
        }
        if (r->pixel.grid.crs && tsio_crs_offline(r->pixel.grid.crs, err) != 0) {
            tsio_errf(err, r->path, "%s", err->msg);
            return -1;
        }
        r->pixel.lazy = 1; /* computed block by block: recipe_read_window */
        return tsjob_pixel_prepare(&r->pixel, &r->pixel_res, err);
    }
    if (r->method == RECIPE_AMPLIFY) {
        if (tsj_build_amplify(&r->values, &r->amplify, msg, sizeof msg) != 0) {
            tsio_errf(err, r->path, "%s", msg);
            return -1;
        }
        r->amplify.lazy = 1; /* computed block by block: recipe_read_window */
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
        return tsjob_amplify_prepare(&r->amplify, &r->amplify_res, err);
    }
    if (tsj_build_synth(&r->values, &r->synth, &r->seed, msg, sizeof msg) != 0) {
        tsio_errf(err, r->path, "%s", msg);
        return -1;
    }
    if (r->synth.grid.crs && tsio_crs_offline(r->synth.grid.crs, err) != 0) {
        tsio_errf(err, r->path, "%s", err->msg);
        return -1;
    }
    if (r->synth.params.tiled > 0) {
        /* tile by tile: recipe_read_window makes the tiles a block needs */
        const char *mb = CPLGetConfigOption("TSYN_TILE_CACHE_MB", "256");
        char *end = NULL;
        double v = strtod(mb, &end);
        if (r->map >= 0) {
            tsio_errf(err, r->path, "tiles (tiled %d) take no debug maps yet (MAP)",
                      r->synth.params.tiled);
            return -1;
        }
        if (end == mb || *end || !(v >= 0 && v <= 1e6)) {
            tsio_errf(err, r->path, "TSYN_TILE_CACHE_MB=%s: give megabytes, 0 to 1000000", mb);
            return -1;
        }
        r->synth.lazy = 1;
        r->synth.tile_cache = (size_t)(v * 1048576.0);
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
    return recipe_identify(path, head, (int)n);
}

/* The files a recipe names (tsj_from_xml's resolver: every file option the
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
        const tsj_job *job = tsj_find_element(top, &cn);
        node = (CPLXMLNode *)cn;
        if (!job)
            node = NULL;
    }
    if (node) {
        tsj_values v;
        tsj_values_init(&v, tsj_find_element(top, NULL));
        n.dir = CPLStrdup(CPLGetPath(path));
        tsj_from_xml(&v, node, recipe_collect, &n, msg, sizeof msg); /* names, not checks */
        tsj_values_free(&v);
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

static int recipe_open_offline(const char *path, const char *const *oo, ts_recipe **out, tsio_err *err)
{
    ts_recipe *r;
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
        const tsj_job *job = tsj_find_element(top, &cn);
        node = (CPLXMLNode *)cn;
        if (job) {
            r->method = !strcmp(job->name, "ppa")       ? RECIPE_PPA
                        : !strcmp(job->name, "synth")   ? RECIPE_SYNTH
                        : !strcmp(job->name, "pixel")   ? RECIPE_PIXEL
                        : !strcmp(job->name, "amplify") ? RECIPE_AMPLIFY
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
        recipe_free(r);
        return -1;
    }
    *out = r;
    return 0;
}

int recipe_open(const char *path, const char *const *oo, ts_recipe **out, tsio_err *err)
{
    tsio_offline g;
    int rc;
    tsio_offline_begin(&g);
    rc = recipe_open_offline(path, oo, out, err);
    tsio_offline_end(&g);
    return rc;
}

void recipe_free(ts_recipe *r)
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
    tsio_georef_free(&r->geo);
    tsj_values_free(&r->values);
    CSLDestroy(r->strings);
    CPLFree(r->path);
    free(r);
}

const tsio_georef *recipe_georef(const ts_recipe *r)
{
    if (r->method == RECIPE_AMPLIFY)
        return &r->amplify_res.geo;
    if (r->method == RECIPE_PIXEL)
        return &r->pixel_res.geo;
    return r->method == RECIPE_PPA ? &r->geo : &r->synth_res.geo;
}

int recipe_gdal_type(const ts_recipe *r)
{
    if (r->method == RECIPE_PPA || r->map == TSJOB_MAP_SEAMS)
        return GDT_Byte;
    return r->map < 0 ? GDT_Float32 : GDT_Int32;
}

double recipe_nodata(const ts_recipe *r)
{
    if (r->method == RECIPE_PPA || r->map == TSJOB_MAP_SEAMS)
        return 255.0;
    return r->map < 0 ? -9999.0 : -1.0;
}

static int recipe_compute_offline(ts_recipe *r, tsio_err *err)
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
    recipe_stack[recipe_depth++] = r->path;
    if (r->method == RECIPE_PPA) {
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
    } else if (r->method == RECIPE_PIXEL) {
        /* the stacks every block shares; the blocks themselves: recipe_read_window */
        rc = tsjob_pixel_setup(ctx, &r->pixel, &r->pixel_res, err);
        if (rc == 0 && r->pixel_res.warning.msg[0])
            CPLError(CE_Warning, CPLE_AppDefined, "%s", r->pixel_res.warning.msg);
    } else if (r->method == RECIPE_AMPLIFY) {
        /* what every block shares; the blocks themselves: recipe_read_window */
        rc = tsjob_amplify_setup(ctx, &r->amplify, &r->amplify_res, err);
        if (rc == 0 && r->amplify_res.warning.msg[0])
            CPLError(CE_Warning, CPLE_AppDefined, "%s", r->amplify_res.warning.msg);
    } else if (r->synth.lazy) {
        /* the exemplars every tile shares; the tiles: recipe_read_window */
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
                    r->synth_res.out.data[i] = -9999.0f;
        }
    }
    recipe_depth--;
    ts_ctx_free(ctx);
    r->computed = rc == 0;
    return rc;
}

int recipe_compute(ts_recipe *r, tsio_err *err)
{
    tsio_offline g;
    int rc;
    tsio_offline_begin(&g);
    rc = recipe_compute_offline(r, err);
    tsio_offline_end(&g);
    return rc;
}

const void *recipe_data(const ts_recipe *r)
{
    if (!r->computed)
        return NULL;
    if (r->method == RECIPE_PPA)
        return r->ppa_res.codes;
    if (r->method == RECIPE_AMPLIFY || r->method == RECIPE_PIXEL || r->synth.lazy)
        return NULL; /* lazy: recipe_read_window */
    if (r->map == TSJOB_MAP_SEAMS)
        return r->synth_res.maps.seams;
    if (r->map >= 0)
        return tsjob_synth_int_map(&r->synth_res, r->map);
    return r->synth_res.out.data;
}

int recipe_block_size(const ts_recipe *r)
{
    if (r->method == RECIPE_SYNTH && r->synth.lazy && r->synth_res.params.tiled < 256)
        return r->synth_res.params.tiled; /* a block inside one tile */
    return r->method == RECIPE_PIXEL ? 512 : 256;
}

int recipe_lazy(const ts_recipe *r)
{
    return r->method == RECIPE_AMPLIFY || r->method == RECIPE_PIXEL ||
           (r->method == RECIPE_SYNTH && r->synth.lazy);
}

/* ---- a tiled synth recipe, tile by tile ---------------------------- */

static recipe_tile *tile_find(const ts_recipe *r, int ti, int tj)
{
    size_t k;
    for (k = 0; k < r->n_tiles; k++)
        if (r->tiles[k].ti == ti && r->tiles[k].tj == tj)
            return &r->tiles[k];
    return NULL;
}

/* Add (ti, tj) to the list of wanted tiles unless there. */
static int want_add(int **list, size_t *n, size_t *cap, int ti, int tj)
{
    size_t k;
    for (k = 0; k < *n; k++)
        if ((*list)[2 * k] == ti && (*list)[2 * k + 1] == tj)
            return 0;
    if (*n == *cap) {
        size_t c = *cap ? 2 * *cap : 32;
        int *l = realloc(*list, c * 2 * sizeof **list);
        if (!l)
            return -1;
        *list = l;
        *cap = c;
    }
    (*list)[2 * *n] = ti;
    (*list)[2 * *n + 1] = tj;
    (*n)++;
    return 0;
}

/* Drop the least recently used tiles not needed by the request being
 * served until the cache is within its limit. */
static void tiles_evict(ts_recipe *r)
{
    while (r->tile_bytes > r->synth.tile_cache) {
        size_t k, old = r->n_tiles;
        for (k = 0; k < r->n_tiles; k++)
            if (r->tiles[k].used != r->tile_clock &&
                (old == r->n_tiles || r->tiles[k].used < r->tiles[old].used))
                old = k;
        if (old == r->n_tiles)
            return;
        r->tile_bytes -= (size_t)r->tiles[old].w * (size_t)r->tiles[old].h * sizeof(float);
        free(r->tiles[old].cells);
        r->tiles[old] = r->tiles[--r->n_tiles];
    }
}

/* Where tile (ti, tj) lies: win and core = {x, y, w, h} (ts_synth_tile_window;
 * ctx for errors). */
static int tile_rect(const ts_recipe *r, ts_ctx *ctx, int ti, int tj, int win[4], int core[4])
{
    const tsjob_synth_result *res = &r->synth_res;
    return ts_synth_tile_window(ctx, &res->params, res->params.tiled, res->geo.width,
                                res->geo.height, ti, tj, win, core) == TS_OK
               ? 0
               : -1;
}

/* Make n (<= 64) tiles of one wave side by side and put them in the cache
 * (their earlier-wave neighbours are there). */
static int tiles_make(ts_recipe *r, ts_ctx *ctx, ts_synth_tile *batch, size_t n, tsio_err *err)
{
    const tsjob_synth_result *res = &r->synth_res;
    int di, dj, nv = 0;
    ts_raster views[9 * 64];
    int win[64][4];
    size_t g;
    for (g = 0; g < n; g++) {
        ts_synth_tile *t = &batch[g];
        float *cells;
        if (tile_rect(r, ctx, t->ti, t->tj, win[g], NULL) != 0) {
            tsio_errf(err, r->path, "%s", ts_ctx_message(ctx));
            goto fail;
        }
        cells = malloc((size_t)win[g][2] * (size_t)win[g][3] * sizeof(float));
        if (!cells)
            goto oom;
        t->window = ts_raster_wrap(cells, win[g][2], win[g][3], win[g][2]);
        for (dj = -1; dj <= 1; dj++)
            for (di = -1; di <= 1; di++) {
                recipe_tile *nb = tile_find(r, t->ti + di, t->tj + dj);
                if (nb) {
                    views[nv] = ts_raster_wrap(nb->cells, nb->w, nb->h, nb->w);
                    t->neighbours[(dj + 1) * 3 + di + 1] = &views[nv++];
                }
            }
    }
    if (r->n_tiles + n > r->cap_tiles) {
        size_t c = 2 * (r->n_tiles + n);
        recipe_tile *l = realloc(r->tiles, c * sizeof *l);
        if (!l)
            goto oom;
        r->tiles = l;
        r->cap_tiles = c;
    }
    if (tsjob_synth_tiles(ctx, &r->synth, res, batch, (int)n, err) != 0)
        goto fail;
    for (g = 0; g < n; g++) { /* into the cache */
        recipe_tile *e = &r->tiles[r->n_tiles++];
        e->ti = batch[g].ti;
        e->tj = batch[g].tj;
        e->x0 = win[g][0];
        e->y0 = win[g][1];
        e->w = batch[g].window.width;
        e->h = batch[g].window.height;
        e->cells = batch[g].window.data;
        e->used = r->tile_clock;
        r->tile_bytes += (size_t)e->w * (size_t)e->h * sizeof(float);
    }
    return 0;
oom:
    tsio_errf(err, r->path, "out of memory for the tiles");
fail:
    for (g = 0; g < n; g++)
        free(batch[g].window.data);
    return -1;
}

/* Cells [x0, x0+w) x [y0, y0+h) of a tiled synth recipe: the tiles under the
 * window, and before them the tiles of earlier waves they need (their cone),
 * made wave by wave (a wave's tiles side by side), kept for later requests. */
static int tiles_window(ts_recipe *r, ts_ctx *ctx, int x0, int y0, int w, int h, float *out,
                        tsio_err *err)
{
    const tsjob_synth_result *res = &r->synth_res;
    int T = res->params.tiled, W = res->geo.width, H = res->geo.height;
    int nti = (W + T - 1) / T, ntj = (H + T - 1) / T, wave, ti, tj, di, dj, rc = -1;
    int *want = NULL;
    size_t n_want = 0, cap_want = 0, k, m;
    ts_synth_tile *batch = NULL;
    pthread_mutex_lock(&r->tile_lock);
    r->tile_clock++;
    for (tj = y0 / T; tj <= (y0 + h - 1) / T; tj++)
        for (ti = x0 / T; ti <= (x0 + w - 1) / T; ti++)
            if (want_add(&want, &n_want, &cap_want, ti, tj) != 0)
                goto oom;
    /* the cone: dependencies go to earlier waves only, so one pass from
     * the last wave down finds them all */
    for (wave = 3; wave > 0; wave--)
        for (k = 0; k < n_want; k++) {
            int i = want[2 * k], j = want[2 * k + 1];
            if (ts_synth_tile_wave(i, j) != wave)
                continue;
            for (dj = -1; dj <= 1; dj++)
                for (di = -1; di <= 1; di++)
                    if (i + di >= 0 && j + dj >= 0 && i + di < nti && j + dj < ntj &&
                        ts_synth_tile_wave(i + di, j + dj) < wave &&
                        want_add(&want, &n_want, &cap_want, i + di, j + dj) != 0)
                        goto oom;
        }
    for (k = 0; k < n_want; k++) {
        recipe_tile *t = tile_find(r, want[2 * k], want[2 * k + 1]);
        if (t)
            t->used = r->tile_clock;
    }
    batch = calloc(n_want ? n_want : 1, sizeof *batch);
    if (!batch)
        goto oom;
    for (wave = 0; wave < 4; wave++) {
        m = 0;
        for (k = 0; k < n_want; k++) {
            int i = want[2 * k], j = want[2 * k + 1];
            if (ts_synth_tile_wave(i, j) == wave && !tile_find(r, i, j)) {
                memset(&batch[m], 0, sizeof batch[m]);
                batch[m].ti = i;
                batch[m].tj = j;
                m++;
            }
        }
        for (k = 0; k < m; k += 64)
            if (tiles_make(r, ctx, &batch[k], m - k < 64 ? m - k : 64, err) != 0)
                goto done;
    }
    { /* the window out of its tiles */
        int y;
        for (y = y0; y < y0 + h; y++) {
            int x = x0;
            while (x < x0 + w) {
                const recipe_tile *t = tile_find(r, x / T, y / T);
                int end = (x / T + 1) * T < x0 + w ? (x / T + 1) * T : x0 + w;
                memcpy(out + (size_t)(y - y0) * (size_t)w + (size_t)(x - x0),
                       t->cells + (size_t)(y - t->y0) * (size_t)t->w + (size_t)(x - t->x0),
                       (size_t)(end - x) * sizeof(float));
                x = end;
            }
        }
    }
    rc = 0;
    goto done;
oom:
    tsio_errf(err, r->path, "out of memory for the tiles");
done:
    tiles_evict(r);
    pthread_mutex_unlock(&r->tile_lock);
    free(batch);
    free(want);
    return rc;
}

static int recipe_read_window_offline(ts_recipe *r, int x0, int y0, int w, int h, float *out, tsio_err *err)
{
    ts_ctx *ctx;
    size_t i, n = (size_t)w * (size_t)h;
    int rc;
    if (!r->computed || !recipe_lazy(r)) {
        tsio_errf(err, r->path, "not computed");
        return -1;
    }
    if (x0 < 0 || y0 < 0 || w < 1 || h < 1 || x0 > recipe_georef(r)->width - w ||
        y0 > recipe_georef(r)->height - h) {
        tsio_errf(err, r->path, "window %d,%d %dx%d is off the grid", x0, y0, w, h);
        return -1;
    }
    ctx = ts_ctx_new();
    if (!ctx) {
        tsio_errf(err, r->path, "out of memory");
        return -1;
    }
    if (r->method == RECIPE_SYNTH) {
        ts_ctx_set_seed(ctx, r->seed);
        rc = tiles_window(r, ctx, x0, y0, w, h, out, err);
        ts_ctx_free(ctx);
        for (i = 0; rc == 0 && i < n; i++)
            if (isnan(out[i]))
                out[i] = -9999.0f; /* nodata as the driver declares it */
        return rc;
    }
    if (r->method == RECIPE_PIXEL) {
        ts_ctx_set_seed(ctx, r->seed);
        rc = tsjob_pixel_window(ctx, &r->pixel, &r->pixel_res, x0, y0, w, h, out, err);
        ts_ctx_free(ctx);
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
            out[i] = -9999.0f; /* nodata as the driver declares it */
    return rc;
}

int recipe_read_window(ts_recipe *r, int x0, int y0, int w, int h, float *out, tsio_err *err)
{
    tsio_offline g;
    int rc;
    tsio_offline_begin(&g);
    rc = recipe_read_window_offline(r, x0, y0, w, h, out, err);
    tsio_offline_end(&g);
    return rc;
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

/* tsj_to_xml's file names: relative to the recipe's folder */
static const char *recipe_rel_cb(void *user, const char *name)
{
    return recipe_rel(user, name);
}

int recipe_write(const char *path, const tsj_values *values, tsio_err *err)
{
    CPLXMLNode *root = CPLCreateXMLNode(NULL, CXT_Element, "TerraSynth");
    int rc;
    CPLAddXMLAttributeAndValue(root, "version", "1");
    tsj_to_xml(values, root, recipe_rel_cb, (void *)path);
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

char *recipe_open_option_list(void)
{
    CPLXMLNode *list = CPLCreateXMLNode(NULL, CXT_Element, "OpenOptionList");
    const char *jobs[4] = {"ppa", "synth", "amplify", "pixel"};
    char *out, *xml;
    int j, s;
    for (j = 0; j < 4; j++) {
        const tsj_job *job = tsj_find(jobs[j]);
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
                    CPLAddXMLAttributeAndValue(o, "default",
                                               choices && (int)d[k].def < CSLCount(choices)
                                                   ? choices[(int)d[k].def]
                                                   : "");
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
            const tsj_option *op = &job->opts[k];
            CPLXMLNode *o;
            if (!op->xml || op->kind == TSJ_FILE || op->kind == TSJ_PIN || op->kind == TSJ_RULE ||
                op->kind == TSJ_NAMED || op->kind == TSJ_PAIR)
                continue;
            o = option_add(list, op->name,
                           op->kind == TSJ_INT                             ? "int"
                           : op->kind == TSJ_NUMBER                        ? "float"
                           : op->kind == TSJ_SEED                          ? "unsignedint"
                                                                           : "string",
                           CPLSPrintf("%s (%s)", op->help, job->name));
            if (o && (op->kind == TSJ_INT || op->kind == TSJ_NUMBER)) {
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

/* ------------------------------------------------------------------ */
/* Tiles for the Dask runner                                           */
/* ------------------------------------------------------------------ */

#define TSYN_EXPORT __attribute__((visibility("default")))

static void copy_err(const tsio_err *e, char *msg, int n)
{
    if (msg && n > 0)
        snprintf(msg, (size_t)n, "%s", e->msg);
}

TSYN_EXPORT int tsyn_tiles_open(const char *path, void **handle, int *width, int *height,
                                int *tile, char *msg, int n)
{
    ts_recipe *r = NULL;
    tsio_err err;
    *handle = NULL;
    if (recipe_open(path, NULL, &r, &err) != 0) {
        copy_err(&err, msg, n);
        return -1;
    }
    if (r->method != RECIPE_SYNTH || !r->synth.lazy) {
        tsio_errf(&err, path, "not a tiled synth recipe (give it <Param name=\"tiled\">)");
        recipe_free(r);
        copy_err(&err, msg, n);
        return -1;
    }
    if (recipe_compute(r, &err) != 0) {
        recipe_free(r);
        copy_err(&err, msg, n);
        return -1;
    }
    *width = r->synth_res.geo.width;
    *height = r->synth_res.geo.height;
    *tile = r->synth_res.params.tiled;
    *handle = r;
    return 0;
}

TSYN_EXPORT int tsyn_tile_rect(void *handle, int ti, int tj, int win[4], int core[4], char *msg,
                               int n)
{
    ts_recipe *r = handle;
    ts_ctx *ctx = ts_ctx_new();
    int rc = ctx ? tile_rect(r, ctx, ti, tj, win, core) : -1;
    if (rc != 0 && msg && n > 0)
        snprintf(msg, (size_t)n, "%s: %s", r->path, ctx ? ts_ctx_message(ctx) : "out of memory");
    ts_ctx_free(ctx);
    return rc;
}

/* Tile (ti, tj)'s window into window (row by row, its own width: see
 * tsyn_tile_rect), from the windows of its neighbours, nb[(dj + 1) * 3 + di
 * + 1] (each row by row, its own width), NULL where not needed. */
TSYN_EXPORT int tsyn_tile_make(void *handle, int ti, int tj, const float *const nb[9],
                               float *window, char *msg, int n)
{
    ts_recipe *r = handle;
    int k, rc, win[4];
    ts_raster views[9];
    ts_synth_tile t;
    ts_ctx *ctx = ts_ctx_new();
    tsio_err err;
    memset(&t, 0, sizeof t);
    if (!ctx) {
        tsio_errf(&err, r->path, "out of memory");
        copy_err(&err, msg, n);
        return -1;
    }
    if (tile_rect(r, ctx, ti, tj, win, NULL) != 0) {
        tsio_errf(&err, r->path, "%s", ts_ctx_message(ctx));
        copy_err(&err, msg, n);
        ts_ctx_free(ctx);
        return -1;
    }
    t.ti = ti;
    t.tj = tj;
    t.window = ts_raster_wrap(window, win[2], win[3], win[2]);
    for (k = 0; k < 9; k++) {
        int nw[4];
        if (!nb[k] || tile_rect(r, ctx, ti + k % 3 - 1, tj + k / 3 - 1, nw, NULL) != 0)
            continue;
        views[k] = ts_raster_wrap((float *)(uintptr_t)nb[k], nw[2], nw[3], nw[2]);
        t.neighbours[k] = &views[k];
    }
    ts_ctx_set_seed(ctx, r->seed);
    ts_ctx_set_threads(ctx, 1);
    {
        tsio_offline g;
        tsio_offline_begin(&g);
        rc = tsjob_synth_tiles(ctx, &r->synth, &r->synth_res, &t, 1, &err);
        tsio_offline_end(&g);
    }
    ts_ctx_free(ctx);
    if (rc != 0) {
        copy_err(&err, msg, n);
        return -1;
    }
    return 0;
}

TSYN_EXPORT void tsyn_tiles_close(void *handle)
{
    recipe_free(handle);
}
