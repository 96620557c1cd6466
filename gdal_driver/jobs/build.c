/*
 * build.c - a job's values into the job the jobs layer runs (tsjob_synth,
 * tsjob_ppa, tsjob_amplify, tsjob_pixel): rules, checks, defaults.
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

/* line appended to the growing text *t (n bytes, room for cap): 0, or -1
 * out of memory (*t freed). */
static int text_add(char **t, size_t *n, size_t *cap, const char *line)
{
    size_t l = strlen(line);
    if (*n + l + 1 > *cap) {
        char *g = realloc(*t, *cap = 2 * (*n + l + 1));
        if (!g) {
            free(*t);
            *t = NULL;
            return -1;
        }
        *t = g;
    }
    memcpy(*t + *n, line, l + 1);
    *n += l;
    return 0;
}

/* What a sketch in tiles laid out before must have been made with: the
 * values a recipe holds but its outputs, the coarse pass's file and the
 * drainage stage's parameters (the stage comes after), as "name=value"
 * lines in the declarations' order; an input file stands as "name=<file>"
 * (its bytes are summed by tsjob_synth_coarse_key). */
static int build_coarse_params(tsjob_values *v, tsjob_synth *job, char *msg, size_t len)
{
    size_t k, n = 0, cap = 4096;
    char *text = calloc(cap, 1);
    const char *val;
    int i, st, bad = !text;
    for (k = 0; !bad && k < v->job->n_opts; k++) {
        const tsjob_option *o = &v->job->opts[k];
        if (!o->xml || o->kind == TSJOB_OUTPUT || !strcmp(o->name, "coarse_pass"))
            continue;
        for (i = 0; !bad && (val = tsjob_get(v, o->name, i)); i++)
            bad = text_add(&text, &n, &cap,
                           CPLSPrintf("%s=%s\n", o->name, o->kind == TSJOB_FILE ? "<file>" : val));
    }
    for (st = 0; !bad && v->job->stages[st]; st++) {
        size_t np;
        const ts_param_desc *d = ts_params_describe(v->job->stages[st], &np);
        if (!strcmp(v->job->stages[st], "drainage"))
            continue;
        for (k = 0; !bad && k < np; k++)
            if ((val = tsjob_get(v, d[k].name, 0)))
                bad = text_add(&text, &n, &cap, CPLSPrintf("%s=%s\n", d[k].name, val));
    }
    if (bad) {
        tsjob__msgf(msg, len, "out of memory");
        return -1;
    }
    job->coarse_params = tsjob__keep(v, text);
    free(text);
    return 0;
}

/* A sketch in tiles: the file its coarse pass is kept in (given, or beside
 * the recipe being written), and what it must have been made with. */
static int build_coarse_pass(tsjob_values *v, tsjob_synth *job, char *msg, size_t len)
{
    const char *recipe = tsjob_get(v, "recipe", 0);
    job->coarse_pass = tsjob_get(v, "coarse_pass", 0);
    if (job->coarse_pass && !(job->params.tiled > 0)) {
        tsjob__msgf(msg, len, "coarse_pass is a sketch in tiles laid out before: give tiled > 0");
        return -1;
    }
    if (!job->sketch || !(job->params.tiled > 0))
        return 0;
    if (!job->coarse_pass && recipe) {
        tsjob_set(v, "coarse_pass", CPLSPrintf("%s.coarse", recipe));
        job->coarse_pass = tsjob_get(v, "coarse_pass", 0);
    }
    return job->coarse_pass ? build_coarse_params(v, job, msg, len) : 0;
}

int tsjob_build_synth(tsjob_values *v, tsjob_synth *job, uint64_t *seed, char *msg, size_t len)
{
    const char *s;
    double x, y;
    int i, k, cli = v->cli;
    memset(job, 0, sizeof *job);
    job->params = ts_synth_params_default();
    job->sketch_params = ts_sketch_params_default();
    job->drainage = ts_drainage_params_default();
    job->alpha_h = 1.0;
    job->band = 1;
    *seed = 0;
    if (tsjob__check_values(v, msg, len) || tsjob__check_rules(v, cli, msg, len) ||
        tsjob__apply_params(v, "synth", &job->params, msg, len) ||
        tsjob__apply_params(v, "sketch", &job->sketch_params, msg, len) ||
        tsjob__apply_params(v, "drainage", &job->drainage, msg, len))
        return -1;
    for (i = 0; (s = tsjob_get(v, "exemplar", i)); i++)
        job->exemplars[job->n_exemplars++] = s;
    /* a region's exemplar joins the exemplars when it is not one yet */
    for (i = 0; (s = tsjob_get(v, "region_exemplar", i)); i++) {
        char *end;
        long id = strtol(s, &end, 10);
        const char *file = end + 1;
        for (k = 0; k < job->n_region_rules; k++)
            if (job->region_id[k] == (int)id) {
                tsjob__msgf(msg, len, "region_exemplar: region %ld is given twice", id);
                return -1;
            }
        for (k = 0; k < job->n_exemplars; k++)
            if (!strcmp(job->exemplars[k], file))
                break;
        if (k == job->n_exemplars) {
            if (job->n_exemplars == TSJOB_MAX_EXEMPLARS) {
                tsjob__msgf(msg, len, "exemplar: at most %d", TSJOB_MAX_EXEMPLARS);
                return -1;
            }
            job->exemplars[job->n_exemplars++] = file;
        }
        job->region_id[job->n_region_rules] = (int)id;
        job->region_exemplar[job->n_region_rules++] = k;
    }
    if (!job->n_exemplars) {
        tsjob__msgf(msg, len, "needs at least one exemplar");
        return -1;
    }
    if ((s = tsjob_get(v, "band", 0)))
        job->band = atoi(s);
    if ((s = tsjob_get(v, "cell_size", 0)))
        job->cell_size = atof(s);
    job->sketch = tsjob_get(v, "sketch", 0);
    job->sketch_layer = tsjob_get(v, "sketch_layer", 0);
    job->kind_field = tsjob_get(v, "kind_field", 0);
    job->height_field = tsjob_get(v, "height_field", 0);
    job->snap = (s = tsjob_get(v, "snap", 0)) ? atof(s) : -1.0;
    if ((s = tsjob_get(v, "extent", 0))) {
        double *e = job->extent;
        char tail;
        if (sscanf(s, "%lf,%lf,%lf,%lf%c", &e[0], &e[1], &e[2], &e[3], &tail) != 4 ||
            !isfinite(e[0]) || !isfinite(e[1]) || !isfinite(e[2]) || !isfinite(e[3]) ||
            !(e[2] > e[0]) || !(e[3] > e[1])) {
            tsjob__msgf(msg, len,
                        "extent takes XMIN,YMIN,XMAX,YMAX with XMIN < XMAX and YMIN < YMAX, "
                        "not '%s'",
                        s);
            return -1;
        }
        job->has_extent = 1;
    }
    job->grid.like = tsjob_get(v, "like", 0);
    if ((s = tsjob_get(v, "size", 0)) && !tsjob__parse_pair(s, 'x', &x, &y)) {
        job->grid.width = (int)x;
        job->grid.height = (int)y;
    }
    if ((s = tsjob_get(v, "origin", 0)) && !tsjob__parse_pair(s, ',', &x, &y)) {
        job->grid.origin_x = x;
        job->grid.origin_y = y;
        job->grid.has_origin = 1;
    }
    if ((s = tsjob_get(v, "resolution", 0))) {
        job->grid.res = atof(s);
        job->grid.has_res = 1;
    }
    job->grid.crs = tsjob_get(v, "crs", 0);
    for (i = 0; (s = tsjob_get(v, "pin", i)); i++) {
        char path[1024];
        tsjob_pin *pin = &job->pins[job->n_pins];
        tsjob_parse_pin(s, pin, path, sizeof path); /* checked above */
        pin->path = tsjob__keep(v, path);
        job->n_pins++;
    }
    job->water = tsjob_get(v, "water", 0);
    if ((s = tsjob_get(v, "water_level", 0)))
        job->water_level = atof(s);
    job->heights = tsjob_get(v, "heights", 0);
    if ((s = tsjob_get(v, "alpha_h", 0)))
        job->alpha_h = atof(s);
    job->regions = tsjob_get(v, "regions", 0);
    if ((s = tsjob_get(v, "seed", 0)))
        *seed = strtoull(s, NULL, 10);
    return build_coarse_pass(v, job, msg, len);
}

int tsjob_build_ppa(tsjob_values *v, tsjob_ppa *job, char *msg, size_t len)
{
    const char *s;
    int cli = v->cli;
    memset(job, 0, sizeof *job);
    job->params = ts_ppa_params_default();
    job->band = 1;
    if (tsjob__check_values(v, msg, len) || tsjob__check_rules(v, cli, msg, len))
        return -1;
    tsjob__expand_choices(v);
    if (tsjob__apply_params(v, "ppa", &job->params, msg, len))
        return -1;
    /* the larger of the two thresholds applies: giving one sets the other to 0 */
    if (tsjob_count(v, "threshold"))
        job->params.threshold_fraction = 0.0;
    if (tsjob_count(v, "threshold_fraction"))
        job->params.threshold = 0.0;
    job->input = tsjob_get(v, "input", 0);
    if (!job->input) {
        tsjob__msgf(msg, len, "needs an input DEM");
        return -1;
    }
    if ((s = tsjob_get(v, "band", 0)))
        job->band = atoi(s);
    if ((s = tsjob_get(v, "cell_size", 0)))
        job->cell_size = atof(s);
    if ((s = tsjob_get(v, "tile_size", 0)))
        job->tile_size = atoi(s);
    return 0;
}

/* --weights h=0.4,a=0.2,...: into the parameters w_h, w_a, ... */
static int expand_weights(tsjob_values *v, char *msg, size_t len)
{
    const char *s = tsjob_get(v, "weights", 0);
    char **items;
    int i, rc = 0;
    if (!s)
        return 0;
    items = CSLTokenizeString2(s, ",", 0);
    for (i = 0; items && items[i] && rc == 0; i++) {
        const char *eq = strchr(items[i], '=');
        char name[8];
        if (!eq || eq - items[i] != 1 || !strchr("haculsx", items[i][0]) || !eq[1]) {
            tsjob__msgf(msg, len, "weights takes h=W,a=W,s=W,u=W,l=W,c=W,x=W, not '%s'", items[i]);
            rc = -1;
            break;
        }
        snprintf(name, sizeof name, "w_%c", items[i][0]);
        if (tsjob_count(v, name)) {
            tsjob__msgf(msg, len, "give weights or %s, not both", name);
            rc = -1;
            break;
        }
        tsjob_set(v, name, eq + 1);
    }
    if (!items || !items[0]) {
        tsjob__msgf(msg, len, "weights is empty");
        rc = -1;
    }
    CSLDestroy(items);
    return rc;
}

int tsjob_build_amplify(tsjob_values *v, tsjob_amplify *job, char *msg, size_t len)
{
    const char *s;
    int i;
    memset(job, 0, sizeof *job);
    job->params = ts_amplify_params_default();
    job->drainage = ts_drainage_params_default();
    job->band = 1;
    if (expand_weights(v, msg, len) || tsjob__check_values(v, msg, len) ||
        tsjob__check_rules(v, v->cli, msg, len))
        return -1;
    if (tsjob__apply_params(v, "amplify", &job->params, msg, len) ||
        tsjob__apply_params(v, "drainage", &job->drainage, msg, len))
        return -1;
    job->input = tsjob_get(v, "input", 0);
    if (!job->input && strcmp(v->job->name, "dictionary") != 0) {
        tsjob__msgf(msg, len, "needs an input DEM");
        return -1;
    }
    for (i = 0; (s = tsjob_get(v, "exemplar", i)); i++) {
        if (job->n_exemplars == TSJOB_MAX_EXEMPLARS) {
            tsjob__msgf(msg, len, "exemplar: at most %d", TSJOB_MAX_EXEMPLARS);
            return -1;
        }
        job->exemplars[job->n_exemplars++] = s;
    }
    /* the exemplars' layers: the k-th FILE of a NAME is the k-th exemplar's */
    for (i = 0; (s = tsjob_get(v, "exemplar_layer", i)); i++) {
        const char *eq = strchr(s, '=');
        int l, k;
        for (l = 0; l < job->n_layers; l++)
            if (strlen(job->layer_names[l]) == (size_t)(eq - s) &&
                !strncmp(job->layer_names[l], s, (size_t)(eq - s)))
                break;
        if (l == job->n_layers) {
            if (l == TS_MAX_LAYERS) {
                tsjob__msgf(msg, len, "exemplar_layer: at most %d names", TS_MAX_LAYERS);
                return -1;
            }
            snprintf(job->layer_names[l], TS_LAYER_NAME, "%.*s", (int)(eq - s), s);
            job->n_layers++;
        }
        for (k = 0; k < TSJOB_MAX_EXEMPLARS && job->layer_files[k][l]; k++)
            ;
        if (k >= job->n_exemplars) {
            tsjob__msgf(msg, len, "exemplar_layer %s: more files than the %d exemplars",
                        job->layer_names[l], job->n_exemplars);
            return -1;
        }
        job->layer_files[k][l] = eq + 1;
    }
    for (i = 0; i < job->n_layers; i++)
        if (!job->layer_files[job->n_exemplars - 1][i]) {
            tsjob__msgf(msg, len, "exemplar_layer %s: one file for each of the %d exemplars",
                        job->layer_names[i], job->n_exemplars);
            return -1;
        }
    for (i = 0; (s = tsjob_get(v, "exemplar_classes", i)); i++) {
        if (i >= job->n_exemplars) {
            tsjob__msgf(msg, len, "exemplar_classes: more files than the %d exemplars",
                        job->n_exemplars);
            return -1;
        }
        job->exemplar_classes[i] = s;
    }
    if (i && i != job->n_exemplars) {
        tsjob__msgf(msg, len, "exemplar_classes: one file for each of the %d exemplars",
                    job->n_exemplars);
        return -1;
    }
    job->classes = tsjob_get(v, "classes", 0);
    for (i = 0; (s = tsjob_get(v, "biome", i)); i++) {
        const char *eq = strchr(s, '=');
        char *w;
        if (i == TSJOB_MAX_BIOMES) {
            tsjob__msgf(msg, len, "biome: at most %d", TSJOB_MAX_BIOMES);
            return -1;
        }
        w = CPLStrdup(s);
        w[eq - s] = '\0';
        v->keep = CSLAddString(v->keep, w);
        CPLFree(w);
        job->biome_weights[i] = v->keep[CSLCount(v->keep) - 1];
        job->biome_dicts[i] = eq + 1;
        job->n_biomes++;
    }
    for (i = 0; (s = tsjob_get(v, "out_layer", i)); i++) {
        size_t n = strspn(s, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-");
        int l;
        if (n == 0 || n >= TS_LAYER_NAME || s[n] != '=' || !s[n + 1]) {
            tsjob__msgf(msg, len, "out_layer takes NAME=FILE, not '%s'", s);
            return -1;
        }
        snprintf(job->out_layer_names[i], TS_LAYER_NAME, "%.*s", (int)n, s);
        for (l = 0; l < i; l++)
            if (!strcmp(job->out_layer_names[l], job->out_layer_names[i])) {
                tsjob__msgf(msg, len, "out_layer %s is given twice", job->out_layer_names[i]);
                return -1;
            }
        job->n_out_layers++;
    }
    job->want_classes = tsjob_count(v, "out_classes") > 0;
    job->dictionary = tsjob_get(v, "dictionary", 0);
    job->shape_given = tsjob_count(v, "factor") || tsjob_count(v, "patch");
    if (!job->n_exemplars && !job->dictionary && !job->n_biomes) {
        tsjob__msgf(msg, len, "give at least one exemplar, or a dictionary, or biomes");
        return -1;
    }
    if ((s = tsjob_get(v, "resolution", 0)))
        job->resolution = atof(s);
    if (!strcmp(v->job->name, "dictionary") && !(job->resolution > 0)) {
        tsjob__msgf(msg, len, "a dictionary needs the resolution of the cells it is for");
        return -1;
    }
    if ((s = tsjob_get(v, "band", 0)))
        job->band = atoi(s);
    if ((s = tsjob_get(v, "cell_size", 0)))
        job->cell_size = atof(s);
    return 0;
}

/* The target grid options (like, size, origin, resolution, crs). */
static void build_grid(tsjob_values *v, tsjob_grid *g)
{
    const char *s;
    double x, y;
    g->like = tsjob_get(v, "like", 0);
    if ((s = tsjob_get(v, "size", 0)) && !tsjob__parse_pair(s, 'x', &x, &y)) {
        g->width = (int)x;
        g->height = (int)y;
    }
    if ((s = tsjob_get(v, "origin", 0)) && !tsjob__parse_pair(s, ',', &x, &y)) {
        g->origin_x = x;
        g->origin_y = y;
        g->has_origin = 1;
    }
    if ((s = tsjob_get(v, "resolution", 0))) {
        g->res = atof(s);
        g->has_res = 1;
    }
    g->crs = tsjob_get(v, "crs", 0);
}

int tsjob_build_pixel(tsjob_values *v, tsjob_pixel *job, uint64_t *seed, char *msg, size_t len)
{
    const char *s;
    int i;
    memset(job, 0, sizeof *job);
    job->params = ts_pixel_params_default();
    job->drainage = ts_drainage_params_default();
    job->band = 1;
    *seed = 0;
    if (tsjob__check_values(v, msg, len) || tsjob__check_rules(v, v->cli, msg, len) ||
        tsjob__apply_params(v, "pixel", &job->params, msg, len) ||
        tsjob__apply_params(v, "drainage", &job->drainage, msg, len))
        return -1;
    for (i = 0; (s = tsjob_get(v, "exemplar", i)); i++)
        job->exemplars[job->n_exemplars++] = s;
    if (!job->n_exemplars) {
        tsjob__msgf(msg, len, "needs at least one exemplar");
        return -1;
    }
    if (job->params.window && job->params.window % 2 == 0) {
        tsjob__msgf(msg, len, "window must be odd, not %d", job->params.window);
        return -1;
    }
    if (!ts_pixel_rotations_valid(job->params.rotations)) {
        tsjob__msgf(msg, len, "rotations must be -1, 0, 2, 4 or 8, not %d", job->params.rotations);
        return -1;
    }
    if ((s = tsjob_get(v, "band", 0)))
        job->band = atoi(s);
    if ((s = tsjob_get(v, "cell_size", 0)))
        job->cell_size = atof(s);
    build_grid(v, &job->grid);
    job->guide = tsjob_get(v, "guide", 0);
    if ((s = tsjob_get(v, "jitter_levels", 0))) {
        char **items = CSLTokenizeString2(s, ",", 0);
        int n = CSLCount(items), bad = n < 1 || n > 10;
        for (i = 0; !bad && i < n; i++) {
            double j = -1;
            bad = tsjob__parse_number(items[i], &j) || j < 0 || j > 2;
            job->params.jitter_levels[i] = j;
        }
        CSLDestroy(items);
        if (bad) {
            tsjob__msgf(msg, len, "jitter_levels takes 1 to 10 numbers in 0..2, not '%s'", s);
            return -1;
        }
        job->params.n_jitter_levels = n;
    }
    if ((s = tsjob_get(v, "seed", 0)))
        *seed = strtoull(s, NULL, 10);
    return 0;
}
