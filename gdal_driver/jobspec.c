/*
 * jobspec.c - one declaration per job: the options and rules of `ppa` and
 * `synth`, and everything generated from them (see jobspec.h).
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

#include "cli_params.h"
#include "jobspec.h"

/* ------------------------------------------------------------------ */
/* The declarations                                                    */
/* ------------------------------------------------------------------ */

#define G_IN "Inputs"
#define G_GRID "Target grid"
#define G_CONS "Constraints"
#define G_RUN "Run"
#define G_OUT "Outputs"

/* Options and rules several jobs declare alike. */
#define OPT_BAND_EVERY                                                                             \
    {                                                                                              \
        "band", TSJ_INT, 1, 1, 65535, "N", G_IN, "band read from every input (default 1)", "Band", \
            0, NULL                                                                                \
    }
#define OPT_CELL_SIZE_GRID                                                                         \
    {                                                                                              \
        "cell_size", TSJ_NUMBER, 1, 1e-6, 1e7, "M", G_IN,                                          \
            "ground size of a cell in metres of every raster without a CRS (a target grid "        \
            "without "                                                                             \
            "one too); without it such rasters are used cell for cell",                            \
            "CellSize", 0, NULL                                                                    \
    }
/* the target grid: like a raster, or a size (at most size_max cells a side) */
#define OPT_GRID(size_max)                                                                         \
    {                                                                                              \
        "like",      TSJ_FILE,   1,      0,                                                        \
        0,           "GRID.tif", G_GRID, "size, geotransform and CRS of a raster",                 \
        "Grid@like", 0,          NULL},                                                            \
        {"size",                                                                                   \
         TSJ_SIZE,                                                                                 \
         1,                                                                                        \
         1,                                                                                        \
         size_max,                                                                                 \
         "WxH",                                                                                    \
         G_GRID,                                                                                   \
         "size in cells; the grid takes the first exemplar's CRS, resolution and origin "          \
         "unless origin, resolution and crs are given",                                            \
         "Grid@width@height",                                                                      \
         0,                                                                                        \
         NULL},                                                                                    \
        {"origin",                                                                                 \
         TSJ_XY,                                                                                   \
         1,                                                                                        \
         0,                                                                                        \
         0,                                                                                        \
         "X,Y",                                                                                    \
         G_GRID,                                                                                   \
         "top-left corner in CRS units (with size)",                                               \
         "Grid@originX@originY",                                                                   \
         0,                                                                                        \
         NULL},                                                                                    \
        {"resolution",                                                                             \
         TSJ_NUMBER,                                                                               \
         1,                                                                                        \
         1e-12,                                                                                    \
         1e12,                                                                                     \
         "R",                                                                                      \
         G_GRID,                                                                                   \
         "cell size in CRS units (with size)",                                                     \
         "Grid@resolution",                                                                        \
         0,                                                                                        \
         NULL},                                                                                    \
    {                                                                                              \
        "crs", TSJ_TEXT, 1, 0, 0, "CRS", G_GRID,                                                   \
            "EPSG:code, WKT or PROJ string (with size, origin and resolution)", "Grid@crs", 0,     \
            NULL                                                                                   \
    }
#define OPT_SEED                                                                                   \
    {                                                                                              \
        "seed", TSJ_SEED, 1, 0, 0, "S", G_RUN,                                                     \
            "random seed (default 0); same inputs and seed give the same bytes", "@seed", 0, NULL  \
    }
#define OPT_PREVIEW                                                                                \
    {                                                                                              \
        "preview", TSJ_OUTPUT, 1, 0, 0, "FILE.png", G_OUT, "hillshade of the result", NULL, 0,     \
            NULL                                                                                   \
    }
#define OPT_RECIPE                                                                                 \
    {                                                                                              \
        "recipe", TSJ_OUTPUT, 1, 0, 0, "FILE.tsyn", G_OUT,                                         \
            "write a recipe for this job instead of running it: gdal_translate FILE.tsyn out.tif", \
            NULL, 0, NULL                                                                          \
    }
/* what a grid given by its size needs */
#define RULES_GRID_SIZE                                                                            \
    {TSJ_REQUIRES,                                                                                 \
     "crs",                                                                                        \
     {"origin", "resolution", NULL},                                                               \
     "a CRS needs an origin and a resolution"},                                                    \
        {TSJ_REQUIRES, "origin", {"size", NULL}, "origin goes with size"},                         \
    {                                                                                              \
        TSJ_REQUIRES, "resolution", {"size", NULL}, "resolution goes with size"                    \
    }

static const tsj_option synth_opts[] = {
    {"exemplar", TSJ_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "EX.tif", G_IN,
     "a real DEM (any GDAL raster) whose style the terrain takes; repeatable", "Exemplar", 0, NULL},
    OPT_BAND_EVERY,
    OPT_CELL_SIZE_GRID,
    {"sketch", TSJ_FILE, 1, 0, 0, "SK", G_GRID,
     "a sketch the terrain follows: a raster (bright strokes are ridges, dark strokes valleys; "
     "on a grey ground, brighter and darker) on whose grid the output is, nodata where it is "
     "nodata; or a layer of lines (GeoPackage, Shapefile, GeoJSON, KML, FlatGeobuf...) whose "
     "field kind says ridge, valley or river, on the grid of like or of resolution",
     "Sketch", 0, NULL},
    {"sketch_layer", TSJ_TEXT, 1, 0, 0, "NAME", G_GRID,
     "the layer of a sketch of lines (default: its first layer of lines)", "Sketch@layer", 0,
     NULL},
    {"kind_field", TSJ_TEXT, 1, 0, 0, "FIELD", G_GRID,
     "the field of a sketch of lines that says ridge, valley or river (default kind)",
     "Sketch@kindField", 0, NULL},
    {"height_field", TSJ_TEXT, 1, 0, 0, "FIELD", G_CONS,
     "a numeric field of a sketch of lines: the height wanted along each line (the lines' Z "
     "values are used without it)",
     "Sketch@heightField", 0, NULL},
    {"snap", TSJ_NUMBER, 1, 0, 1000, "CELLS", G_GRID,
     "a line end this close to another line of its kind joins it (cells, default 2)",
     "Sketch@snap", 0, NULL},
    {"extent", TSJ_TEXT, 1, 0, 0, "XMIN,YMIN,XMAX,YMAX", G_GRID,
     "with a sketch of lines and resolution: the output's extent in its CRS (default: the "
     "lines' bounding box grown by a patch on each side)",
     "Grid@extent", 0, NULL},
    OPT_GRID(65536),
    {"pin", TSJ_PIN, TSJOB_MAX_PINS, 0, 0, "FILE:XOFF,YOFF,W,H@X,Y", G_CONS,
     "keep a window of a DEM (its own cells) unchanged with its top-left at output cell X,Y; "
     "repeatable",
     "Pin", 0, NULL},
    {"water", TSJ_FILE, 1, 0, 0, "MASK", G_CONS,
     "cells where MASK (a raster on the output grid) is non-zero keep water_level", "Water", 0,
     NULL},
    {"water_level", TSJ_NUMBER, 1, -1e7, 1e7, "H", G_CONS, "the level of the water cells",
     "Water@level", 0, NULL},
    {"heights", TSJ_FILE, 1, 0, 0, "H.tif", G_CONS,
     "wanted elevations (a raster on the output grid, nodata = free)", "Heights", 0, NULL},
    {"alpha_h", TSJ_NUMBER, 1, 0, 1e9, "A", G_CONS,
     "weight of the wanted elevations: each candidate pays A x RMS difference (default 1)",
     "Heights@alpha", 0, NULL},
    {"regions", TSJ_FILE, 1, 0, 0, "R", G_CONS,
     "several styles: an integer raster on the output grid or a polygon layer with an "
     "integer field 'region'",
     "Regions", 0, NULL},
    {"region_exemplar", TSJ_RULE, TSJOB_MAX_EXEMPLARS, 0, 0, "ID=EX", G_CONS,
     "region ID takes exemplar EX (repeatable; other regions take any exemplar)", "RegionExemplar",
     0, NULL},
    OPT_SEED,
    {"output", TSJ_OUTPUT, 1, 0, 0, "OUTPUT", G_OUT,
     "the terrain: a Float32 DEM on the target grid, nodata -9999", NULL, 1, NULL},
    OPT_PREVIEW,
    {"debug_dir", TSJ_OUTPUT, 1, 0, 0, "DIR", G_OUT,
     "seams.tif, source_exemplar.tif, source_x.tif, source_y.tif, order.tif (georeferenced); "
     "with a sketch also its features and the output's (GeoPackage)",
     NULL, 0, NULL},
    OPT_RECIPE,
};

static const tsj_rule synth_rules[] = {
    {TSJ_EXCLUDES, "sketch", {"size", "origin", NULL}, "a sketch sets the output grid: give no %s"},
    {TSJ_EXCLUDES,
     "like",
     {"size", "origin", "resolution", "crs", "extent", NULL},
     "like sets the output grid: give no %s"},
    {TSJ_ANY_OF, "sketch", {"like", "size", NULL}, "give the target grid: a sketch, like or size"},
    {TSJ_NEEDS_ANY,
     "crs",
     {"origin", "sketch", NULL},
     "a CRS needs an origin and a resolution (or a sketch of lines and a resolution)"},
    {TSJ_REQUIRES,
     "crs",
     {"resolution", NULL},
     "a CRS needs an origin and a resolution (or a sketch of lines and a resolution)"},
    {TSJ_REQUIRES, "origin", {"size", NULL}, "origin goes with size"},
    {TSJ_NEEDS_ANY,
     "resolution",
     {"size", "sketch", NULL},
     "resolution goes with size (or a sketch of lines)"},
    {TSJ_REQUIRES, "extent", {"sketch", "resolution", NULL},
     "extent goes with a sketch of lines and resolution"},
    {TSJ_REQUIRES, "sketch_layer", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJ_REQUIRES, "kind_field", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJ_REQUIRES, "height_field", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJ_REQUIRES, "snap", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJ_TOGETHER, "water", {"water_level", NULL}, "water and water_level go together"},
    {TSJ_TOGETHER, "regions", {"region_exemplar", NULL}, "regions and region_exemplar go together"},
    {TSJ_REQUIRES, "alpha_h", {"heights", NULL}, "alpha_h weighs heights: give heights"},
    {TSJ_REQUIRES, "@sketch", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJ_EXCLUDES,
     "recipe",
     {"output", "preview", "debug_dir", NULL},
     "recipe writes the recipe instead of running the job: give no %s"},
    {TSJ_ONE_OF, "output", {"recipe", NULL}, "give OUTPUT (or recipe)"},
};

static const tsj_option ppa_opts[] = {
    {"input", TSJ_FILE, 1, 0, 0, "INPUT", G_IN, "the DEM (any GDAL raster)", "Input", 1, NULL},
    {"band", TSJ_INT, 1, 1, 65535, "N", G_IN, "band read (default 1)", "Input@band", 0, NULL},
    {"cell_size", TSJ_NUMBER, 1, 1e-6, 1e7, "M", G_IN,
     "ground size of a cell in metres, for a raster without a CRS (otherwise lengths are in "
     "cells)",
     "CellSize", 0, NULL},
    {"ridges", TSJ_CHOICE, 1, 0, 0, NULL, G_IN, "map ridges (features ridges)", NULL, 0,
     "features=ridges"},
    {"valleys", TSJ_CHOICE, 1, 0, 0, NULL, G_IN, "map valleys (features valleys)", NULL, 0,
     "features=valleys"},
    {"both", TSJ_CHOICE, 1, 0, 0, NULL, G_IN, "map both (features both)", NULL, 0, "features=both"},
    {"output", TSJ_OUTPUT, 1, 0, 0, "OUTPUT", G_OUT,
     "Byte raster on the input's grid: 1 ridge, 2 valley, 3 both, 0 none, 255 nodata", NULL, 2,
     NULL},
    {"lines", TSJ_OUTPUT, 1, 0, 0, "FILE", G_OUT,
     "vector axes: layer 'paths' (LineString per path) and layer 'nodes' (endpoints, branch "
     "points); format from the extension (.gpkg, .shp, .geojson)",
     NULL, 0, NULL},
    {"preview", TSJ_OUTPUT, 1, 0, 0, "FILE.png", G_OUT,
     "hillshade with ridges (red) and valleys (blue)", NULL, 0, NULL},
    {"tile_size", TSJ_INT, 1, 0, 16384, "N", G_RUN,
     "map the DEM in tiles of N x N cells (16..16384), read window by window three times: the "
     "same raster as in one piece, in the memory of three rows of tiles and the axes' chains "
     "(DEMs larger than memory; not with lines or preview). 0 (default): in one piece, or, when "
     "it does not fit in memory, in the largest tiles (8192 .. 64) that do",
     "TileSize", 0, NULL},
    OPT_RECIPE,
};

static const tsj_rule ppa_rules[] = {
    {TSJ_EXCLUDES, "threshold", {"threshold_fraction", NULL},
     "give threshold or threshold_fraction, not both"},
    {TSJ_EXCLUDES, "ridges", {"valleys", "both", "features", NULL},
     "give one of ridges, valleys, both (or features), not %s too"},
    {TSJ_EXCLUDES, "valleys", {"both", "features", NULL},
     "give one of ridges, valleys, both (or features), not %s too"},
    {TSJ_EXCLUDES, "both", {"features", NULL},
     "give one of ridges, valleys, both (or features), not %s too"},
    {TSJ_EXCLUDES, "recipe", {"output", "lines", "preview", NULL},
     "recipe writes the recipe instead of running the job: give no %s"},
    {TSJ_ONE_OF, "output", {"recipe", NULL}, "give OUTPUT (or recipe)"},
};

static const tsj_option amplify_opts[] = {
    {"input", TSJ_FILE, 1, 0, 0, "INPUT", G_IN,
     "the coarse DEM (any GDAL raster): the output is `factor` times finer on its extent", "Input",
     1, NULL},
    {"exemplar", TSJ_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "EX.tif", G_IN,
     "a real DEM whose detail the output takes (resampled to the output's ground "
     "resolution); repeatable",
     "Exemplar", 0, NULL},
    {"exemplar_layer", TSJ_NAMED, TSJOB_MAX_EXEMPLARS *TS_MAX_LAYERS, 0, 0, "NAME=FILE", G_IN,
     "an extra layer of an exemplar (vegetation, soil, ...: any raster on its grid) that the "
     "atoms carry to the output; the k-th FILE given for a NAME belongs to the k-th exemplar, "
     "and every exemplar gives every NAME",
     "ExemplarLayer", 0, NULL},
    {"exemplar_classes", TSJ_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "CL.tif", G_IN,
     "class codes 1..64 of an exemplar (a raster on its grid; 0 or nodata: unlabelled), one "
     "per exemplar in order: the atoms' classes (section 5.4)",
     "ExemplarClasses", 0, NULL},
    {"dictionary", TSJ_FILE, 1, 0, 0, "D.tsd", G_IN,
     "a dictionary built once by `terrasynth dictionary build` (instead of exemplars): "
     "its factor, patch and cell size are the job's",
     "Dictionary", 0, NULL},
    {"weights", TSJ_TEXT, 1, 0, 0, "h=W,a=W,s=W,u=W,l=W,c=W,x=W", G_IN,
     "the matching weights in one option (any of them; the others keep their values): the same "
     "as --w-h, --w-a, ... (not both)",
     NULL, 0, NULL},
    {"biome", TSJ_PAIR, TSJOB_MAX_BIOMES, 0, 0, "W.tif=D.tsd", G_IN,
     "a biome (section 5.5): dictionary D (terrasynth dictionary build) weighs W, a raster "
     "on the input's grid painted by the user (shares: each biome's weight over their sum); "
     "repeatable, instead of exemplars or a dictionary",
     "Biome", 0, "weights"},
    OPT_BAND_EVERY,
    {"cell_size", TSJ_NUMBER, 1, 1e-6, 1e7, "M", G_IN,
     "ground size of a cell in metres of every raster without a CRS (without it such "
     "rasters are used cell for cell)",
     "CellSize", 0, NULL},
    {"classes", TSJ_FILE, 1, 0, 0, "WANT.tif", G_CONS,
     "wanted classes on the input's grid (codes of the exemplars' classes; 0 or nodata: any): "
     "each patch prefers atoms of its classes, weighed by w_c",
     "Classes", 0, NULL},
    {"output", TSJ_OUTPUT, 1, 0, 0, "OUTPUT", G_OUT,
     "the amplified DEM: Float32 on the input's extent and CRS, factor times finer, "
     "nodata -9999 where the input is nodata",
     NULL, 2, NULL},
    {"out_layer", TSJ_OUTPUT, TS_MAX_LAYERS, 0, 0, "NAME=FILE", G_OUT,
     "an extra layer the atoms carry (exemplar_layer NAME), on the output's grid (Float32, "
     "nodata -9999); repeatable",
     NULL, 0, NULL},
    {"out_classes", TSJ_OUTPUT, 1, 0, 0, "FILE", G_OUT,
     "the atoms' classes on the output's grid (Byte, 0 = unlabelled)", NULL, 0, NULL},
    OPT_PREVIEW,
    OPT_RECIPE,
};

static const tsj_rule amplify_rules[] = {
    {TSJ_ONE_OF,
     "exemplar",
     {"dictionary", "biome", NULL},
     "give at least one exemplar, or a dictionary, or biomes"},
    {TSJ_EXCLUDES,
     "biome",
     {"classes", "out_layer", "out_classes", NULL},
     "biomes blend dictionaries: give no %s"},
    {TSJ_EXCLUDES,
     "recipe",
     {"output", "preview", "out_layer", "out_classes", NULL},
     "recipe writes the recipe instead of running the job: give no %s"},
    {TSJ_EXCLUDES,
     "dictionary",
     {"exemplar_layer", "exemplar_classes", NULL},
     "the dictionary holds the exemplars' layers and classes: give no %s"},
    {TSJ_REQUIRES, "exemplar_layer", {"exemplar", NULL}, "exemplar_layer needs exemplars"},
    {TSJ_REQUIRES, "exemplar_classes", {"exemplar", NULL}, "exemplar_classes needs exemplars"},
    {TSJ_ONE_OF, "output", {"recipe", NULL}, "give OUTPUT (or recipe)"},
};

static const tsj_option dictionary_opts[] = {
    {"exemplar", TSJ_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "EX.tif", G_IN,
     "a real DEM whose detail the atoms hold (resampled to the resolution); repeatable", "Exemplar",
     0, NULL},
    {"band", TSJ_INT, 1, 1, 65535, "N", G_IN, "band read from every exemplar (default 1)", "Band",
     0, NULL},
    {"cell_size", TSJ_NUMBER, 1, 1e-6, 1e7, "M", G_IN,
     "ground size of a cell in metres of every exemplar without a CRS", "CellSize", 0, NULL},
    {"exemplar_layer", TSJ_NAMED, TSJOB_MAX_EXEMPLARS *TS_MAX_LAYERS, 0, 0, "NAME=FILE", G_IN,
     "an extra layer of an exemplar (vegetation, soil, ...: any raster on its grid) that the "
     "atoms carry to the output; the k-th FILE given for a NAME belongs to the k-th exemplar, "
     "and every exemplar gives every NAME",
     "ExemplarLayer", 0, NULL},
    {"exemplar_classes", TSJ_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "CL.tif", G_IN,
     "class codes 1..64 of an exemplar (a raster on its grid; 0 or nodata: unlabelled), one "
     "per exemplar in order: the atoms' classes (section 5.4)",
     "ExemplarClasses", 0, NULL},
    {"resolution", TSJ_NUMBER, 1, 1e-6, 1e7, "M", G_IN,
     "ground size in metres of the cells of the amplified DEMs the dictionary is for (the "
     "input's cell divided by the factor); required",
     "Resolution", 0, NULL},
    {"output", TSJ_OUTPUT, 1, 0, 0, "D.tsd", G_OUT, "the dictionary file", NULL, 1, NULL},
};

static const tsj_rule dictionary_rules[] = {
    {TSJ_REQUIRES,
     "output",
     {"exemplar", "resolution", NULL},
     "a dictionary needs exemplars and the resolution"},
};

static const tsj_option pixel_opts[] = {
    {"exemplar", TSJ_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "EX.tif", G_IN,
     "a real DEM (any GDAL raster) whose style the terrain takes, resampled to the output's "
     "ground resolution; repeatable",
     "Exemplar", 0, NULL},
    OPT_BAND_EVERY,
    OPT_CELL_SIZE_GRID,
    {"guide", TSJ_FILE, 1, 0, 0, "G.tif", G_GRID,
     "a DEM in the exemplars' units (a sketch, a synth output, a coarse real DEM) that the "
     "terrain follows at every level; its grid is the output's",
     "Guide", 0, NULL},
    OPT_GRID(1048576),
    OPT_SEED,
    {"jitter_levels", TSJ_TEXT, 1, 0, 0, "J1,J2,...", G_RUN,
     "jitter per level, coarse to fine, from level 1 (levels past the list take its last "
     "value), in spacings 0..2; instead of the one jitter",
     "JitterLevels", 0, NULL},
    {"output", TSJ_OUTPUT, 1, 0, 0, "OUTPUT", G_OUT,
     "the terrain: a Float32 DEM on the target grid, nodata -9999", NULL, 1, NULL},
    OPT_PREVIEW,
    {"debug_dir", TSJ_OUTPUT, 1, 0, 0, "DIR", G_OUT,
     "source_exemplar.tif, source_x.tif, source_y.tif: where each cell's finest coordinate "
     "points (the candidate exemplar: index x rotations + turn; the cell in it)",
     NULL, 0, NULL},
    OPT_RECIPE,
};

static const tsj_rule pixel_rules[] = {
    {TSJ_EXCLUDES,
     "guide",
     {"like", "size", "origin", "resolution", "crs", NULL},
     "a guide sets the output grid: give no %s"},
    {TSJ_EXCLUDES,
     "like",
     {"size", "origin", "resolution", "crs", NULL},
     "like sets the output grid: give no %s"},
    {TSJ_ONE_OF, "guide", {"like", "size", NULL}, "give the target grid: a guide, like or size"},
    {TSJ_REQUIRES, "guide_weight", {"guide", NULL}, "guide_weight weighs a guide: give guide"},
    {TSJ_EXCLUDES, "jitter_levels", {"jitter", NULL}, "give jitter or jitter_levels, not both"},
    RULES_GRID_SIZE,
    {TSJ_EXCLUDES,
     "recipe",
     {"output", "preview", "debug_dir", NULL},
     "recipe writes the recipe instead of running the job: give no %s"},
    {TSJ_ONE_OF, "output", {"recipe", NULL}, "give OUTPUT (or recipe)"},
};

static const tsj_job jobs[] = {
    {"ppa",
     ppa_opts,
     sizeof ppa_opts / sizeof ppa_opts[0],
     ppa_rules,
     sizeof ppa_rules / sizeof ppa_rules[0],
     {"ppa", NULL, NULL},
     "PPA"},
    {"synth",
     synth_opts,
     sizeof synth_opts / sizeof synth_opts[0],
     synth_rules,
     sizeof synth_rules / sizeof synth_rules[0],
     {"synth", "sketch", NULL},
     "Synth"},
    {"amplify",
     amplify_opts,
     sizeof amplify_opts / sizeof amplify_opts[0],
     amplify_rules,
     sizeof amplify_rules / sizeof amplify_rules[0],
     {"amplify", NULL, NULL},
     "Amplify"},
    {"dictionary",
     dictionary_opts,
     sizeof dictionary_opts / sizeof dictionary_opts[0],
     dictionary_rules,
     sizeof dictionary_rules / sizeof dictionary_rules[0],
     {"amplify", NULL, NULL},
     "Dictionary"},
    {"pixel",
     pixel_opts,
     sizeof pixel_opts / sizeof pixel_opts[0],
     pixel_rules,
     sizeof pixel_rules / sizeof pixel_rules[0],
     {"pixel", NULL, NULL},
     "Pixel"},
};

const tsj_job *tsj_find(const char *name)
{
    size_t i;
    for (i = 0; name && i < sizeof jobs / sizeof jobs[0]; i++)
        if (!strcmp(jobs[i].name, name))
            return &jobs[i];
    return NULL;
}

const tsj_job *tsj_find_element(const CPLXMLNode *top, const CPLXMLNode **node)
{
    size_t i;
    for (i = 0; top && i < sizeof jobs / sizeof jobs[0]; i++) {
        const CPLXMLNode *n = CPLGetXMLNode((CPLXMLNode *)top, jobs[i].element);
        if (n) {
            if (node)
                *node = n;
            return &jobs[i];
        }
    }
    return NULL;
}

const tsj_option *tsj_option_find(const tsj_job *job, const char *name)
{
    size_t i;
    for (i = 0; job && name && i < job->n_opts; i++)
        if (!strcmp(job->opts[i].name, name))
            return &job->opts[i];
    return NULL;
}

const char *tsj_param_stage(const tsj_job *job, const char *name)
{
    int s;
    for (s = 0; job && name && job->stages[s]; s++) {
        size_t n, k;
        const ts_param_desc *d = ts_params_describe(job->stages[s], &n);
        for (k = 0; k < n; k++)
            if (!strcmp(d[k].name, name))
                return job->stages[s];
    }
    return NULL;
}

/* ------------------------------------------------------------------ */
/* Values                                                              */
/* ------------------------------------------------------------------ */

void tsj_values_init(tsj_values *v, const tsj_job *job)
{
    v->job = job;
    v->kv = NULL;
    v->keep = NULL;
    v->cli = 0;
}

void tsj_values_free(tsj_values *v)
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

void tsj_set(tsj_values *v, const char *name, const char *value)
{
    const tsj_option *o = tsj_option_find(v->job, name);
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

int tsj_count(const tsj_values *v, const char *name)
{
    int i, n = 0;
    for (i = 0; v->kv && v->kv[i]; i++)
        n += key_is(v->kv[i], name);
    return n;
}

const char *tsj_get(const tsj_values *v, const char *name, int k)
{
    int i;
    for (i = 0; v->kv && v->kv[i]; i++)
        if (key_is(v->kv[i], name) && k-- == 0)
            return v->kv[i] + strlen(name) + 1;
    return NULL;
}

/* A string the job may point into, owned by v. */
static const char *keep(tsj_values *v, const char *s)
{
    v->keep = CSLAddString(v->keep, s);
    return v->keep[CSLCount(v->keep) - 1];
}

static void msgf(char *msg, size_t len, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static void msgf(char *msg, size_t len, const char *fmt, ...)
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
static const char *given(const tsj_values *v, const char *name)
{
    if (name[0] == '@') {
        size_t n, k;
        const ts_param_desc *d = ts_params_describe(name + 1, &n);
        for (k = 0; k < n; k++)
            if (tsj_count(v, d[k].name))
                return d[k].name;
        return NULL;
    }
    return tsj_count(v, name) ? name : NULL;
}

/* Does a rule apply to this front end?  Rules about options that only the
 * command line has (outputs) do not apply to recipes. */
static int rule_applies(const tsj_job *job, const tsj_rule *r, int cli)
{
    const tsj_option *o = tsj_option_find(job, r->a);
    int i;
    if (cli)
        return 1;
    if (o && !o->xml && o->kind != TSJ_CHOICE)
        return 0;
    for (i = 0; r->b[i]; i++) {
        o = tsj_option_find(job, r->b[i]);
        if (o && !o->xml && o->kind != TSJ_CHOICE)
            return 0;
    }
    return 1;
}

static int check_rules(const tsj_values *v, int cli, char *msg, size_t len)
{
    const tsj_job *job = v->job;
    size_t r;
    for (r = 0; r < job->n_rules; r++) {
        const tsj_rule *ru = &job->rules[r];
        const char *a = given(v, ru->a), *bad = NULL;
        int i, n_given = a ? 1 : 0, n_all = 1;
        if (!rule_applies(job, ru, cli))
            continue;
        for (i = 0; ru->b[i]; i++) {
            const char *b = given(v, ru->b[i]);
            n_all++;
            n_given += b != NULL;
            switch (ru->kind) {
            case TSJ_REQUIRES:
                if (a && !b && !bad)
                    bad = a;
                break;
            case TSJ_EXCLUDES:
                if (a && b && !bad)
                    bad = b;
                break;
            default:
                break;
            }
        }
        if (ru->kind == TSJ_TOGETHER && n_given && n_given != n_all)
            bad = ru->a;
        if (ru->kind == TSJ_ONE_OF && n_given != 1)
            bad = ru->a;
        if (ru->kind == TSJ_NEEDS_ANY && a && n_given == 1)
            bad = a;
        if (ru->kind == TSJ_ANY_OF && n_given == 0)
            bad = ru->a;
        if (bad) {
            msgf(msg, len, ru->message, bad);
            return -1;
        }
    }
    return 0;
}

/* ------------------------------------------------------------------ */
/* Values -> jobs                                                      */
/* ------------------------------------------------------------------ */

static int parse_number(const char *s, double *out)
{
    char *end;
    if (!s || !*s)
        return -1;
    errno = 0;
    *out = strtod(s, &end);
    return (*end || errno || !isfinite(*out)) ? -1 : 0;
}

static int parse_pair(const char *s, char sep, double *a, double *b)
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
static int check_value(const tsj_option *o, const char *s, char *msg, size_t len)
{
    double x, y;
    switch (o->kind) {
    case TSJ_FILE:
    case TSJ_OUTPUT:
    case TSJ_TEXT:
        if (!s || !*s) {
            msgf(msg, len, "%s is empty", o->name);
            return -1;
        }
        return 0;
    case TSJ_NUMBER:
        if (parse_number(s, &x) || x < o->min || x > o->max) {
            msgf(msg, len, "%s must be a number in %g..%g, not '%s'", o->name, o->min, o->max,
                 s ? s : "");
            return -1;
        }
        return 0;
    case TSJ_INT:
        if (parse_number(s, &x) || x != floor(x) || x < o->min || x > o->max) {
            msgf(msg, len, "%s must be a whole number in %g..%g, not '%s'", o->name, o->min,
                 o->max, s ? s : "");
            return -1;
        }
        return 0;
    case TSJ_SEED: {
        char *end = NULL;
        int bad;
        errno = 0;
        bad = !s || !*s || !isdigit((unsigned char)s[0]) || (strtoull(s, &end, 10), *end);
        if (bad || errno == ERANGE) {
            msgf(msg, len, "%s must be a whole number in 0..18446744073709551615, not '%s'",
                 o->name, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJ_SIZE:
        if (parse_pair(s, 'x', &x, &y) || x != floor(x) || y != floor(y) || x < o->min ||
            y < o->min || x > o->max || y > o->max) {
            msgf(msg, len, "%s takes WxH in cells (%g..%g), not '%s'", o->name, o->min, o->max,
                 s ? s : "");
            return -1;
        }
        return 0;
    case TSJ_XY:
        if (parse_pair(s, ',', &x, &y)) {
            msgf(msg, len, "%s takes X,Y, not '%s'", o->name, s ? s : "");
            return -1;
        }
        return 0;
    case TSJ_PIN: {
        tsjob_pin pin;
        char path[1024];
        if (tsjob_parse_pin(s ? s : "", &pin, path, sizeof path) != 0) {
            msgf(msg, len, "%s takes FILE:XOFF,YOFF,W,H@X,Y, not '%s'", o->name, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJ_RULE: {
        char *end;
        if (!s || (strtol(s, &end, 10), end == s) || *end != '=' || !end[1]) {
            msgf(msg, len, "%s takes ID=FILE, not '%s'", o->name, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJ_NAMED: {
        size_t n =
            s ? strspn(s, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-") : 0;
        if (!s || n == 0 || n >= TS_LAYER_NAME || s[n] != '=' || !s[n + 1]) {
            msgf(msg, len, "%s takes NAME=FILE (NAME: 1 to %d letters, digits, _ or -), not '%s'",
                 o->name, TS_LAYER_NAME - 1, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJ_PAIR: {
        const char *eq = s ? strchr(s, '=') : NULL;
        if (!eq || eq == s || !eq[1]) {
            msgf(msg, len, "%s takes FILE=FILE, not '%s'", o->name, s ? s : "");
            return -1;
        }
        return 0;
    }
    case TSJ_CHOICE:
        return 0;
    }
    return 0;
}

/* Every value: known names, counts, kinds, ranges; choices become their
 * parameter. */
static int check_values(tsj_values *v, char *msg, size_t len)
{
    int i;
    for (i = 0; v->kv && v->kv[i]; i++) {
        char name[128];
        size_t kl = key_len(v->kv[i]);
        const tsj_option *o;
        if (kl >= sizeof name) {
            msgf(msg, len, "unknown option '%.40s...'", v->kv[i]);
            return -1;
        }
        memcpy(name, v->kv[i], kl);
        name[kl] = '\0';
        o = tsj_option_find(v->job, name);
        if (!o) {
            if (!tsj_param_stage(v->job, name)) {
                msgf(msg, len, "unknown option '%s'", name);
                return -1;
            }
            continue;
        }
        if (tsj_count(v, name) > o->max_count) {
            msgf(msg, len, "%s: at most %d", name, o->max_count);
            return -1;
        }
        if (check_value(o, v->kv[i] + kl + 1, msg, len) != 0)
            return -1;
    }
    return 0;
}

/* The stage parameters among the values into params of `stage`. */
static int apply_params(const tsj_values *v, const char *stage, void *params, char *msg,
                        size_t len)
{
    ts_ctx *ctx = ts_ctx_new();
    int i, rc = 0;
    if (!ctx) {
        msgf(msg, len, "out of memory");
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
        st = tsj_param_stage(v->job, name);
        if (!st || strcmp(st, stage) != 0)
            continue;
        if (ts_params_set(ctx, stage, params, name, v->kv[i] + kl + 1) != TS_OK) {
            msgf(msg, len, "%s", ts_ctx_message(ctx));
            rc = -1;
        }
    }
    if (!rc && ts_params_validate(ctx, stage, params) != TS_OK) {
        msgf(msg, len, "%s", ts_ctx_message(ctx));
        rc = -1;
    }
    ts_ctx_free(ctx);
    return rc;
}

/* TSJ_CHOICE options set their parameter ("features=ridges"). */
static void expand_choices(tsj_values *v)
{
    size_t k;
    for (k = 0; k < v->job->n_opts; k++) {
        const tsj_option *o = &v->job->opts[k];
        char name[64];
        const char *eq;
        if (o->kind != TSJ_CHOICE || !tsj_count(v, o->name) || !(eq = strchr(o->choices, '=')))
            continue;
        snprintf(name, sizeof name, "%.*s", (int)(eq - o->choices), o->choices);
        if (!tsj_count(v, name))
            tsj_set(v, name, eq + 1);
    }
}

int tsj_build_synth(tsj_values *v, tsjob_synth *job, uint64_t *seed, char *msg, size_t len)
{
    const char *s;
    double x, y;
    int i, k, cli = v->cli;
    memset(job, 0, sizeof *job);
    job->params = ts_synth_params_default();
    job->sketch_params = ts_sketch_params_default();
    job->alpha_h = 1.0;
    job->band = 1;
    *seed = 0;
    if (check_values(v, msg, len) || check_rules(v, cli, msg, len) ||
        apply_params(v, "synth", &job->params, msg, len) ||
        apply_params(v, "sketch", &job->sketch_params, msg, len))
        return -1;
    for (i = 0; (s = tsj_get(v, "exemplar", i)); i++)
        job->exemplars[job->n_exemplars++] = s;
    /* a region's exemplar joins the exemplars when it is not one yet */
    for (i = 0; (s = tsj_get(v, "region_exemplar", i)); i++) {
        char *end;
        long id = strtol(s, &end, 10);
        const char *file = end + 1;
        for (k = 0; k < job->n_exemplars; k++)
            if (!strcmp(job->exemplars[k], file))
                break;
        if (k == job->n_exemplars) {
            if (job->n_exemplars == TSJOB_MAX_EXEMPLARS) {
                msgf(msg, len, "exemplar: at most %d", TSJOB_MAX_EXEMPLARS);
                return -1;
            }
            job->exemplars[job->n_exemplars++] = file;
        }
        job->region_id[job->n_region_rules] = (int)id;
        job->region_exemplar[job->n_region_rules++] = k;
    }
    if (!job->n_exemplars) {
        msgf(msg, len, "needs at least one exemplar");
        return -1;
    }
    if ((s = tsj_get(v, "band", 0)))
        job->band = atoi(s);
    if ((s = tsj_get(v, "cell_size", 0)))
        job->cell_size = atof(s);
    job->sketch = tsj_get(v, "sketch", 0);
    job->sketch_layer = tsj_get(v, "sketch_layer", 0);
    job->kind_field = tsj_get(v, "kind_field", 0);
    job->height_field = tsj_get(v, "height_field", 0);
    job->snap = (s = tsj_get(v, "snap", 0)) ? atof(s) : -1.0;
    if ((s = tsj_get(v, "extent", 0))) {
        double *e = job->extent;
        char tail;
        if (sscanf(s, "%lf,%lf,%lf,%lf%c", &e[0], &e[1], &e[2], &e[3], &tail) != 4 ||
            !isfinite(e[0]) || !isfinite(e[1]) || !isfinite(e[2]) || !isfinite(e[3]) ||
            !(e[2] > e[0]) || !(e[3] > e[1])) {
            msgf(msg, len, "extent takes XMIN,YMIN,XMAX,YMAX with XMIN < XMAX and YMIN < YMAX, "
                           "not '%s'",
                 s);
            return -1;
        }
        job->has_extent = 1;
    }
    job->grid.like = tsj_get(v, "like", 0);
    if ((s = tsj_get(v, "size", 0)) && !parse_pair(s, 'x', &x, &y)) {
        job->grid.width = (int)x;
        job->grid.height = (int)y;
    }
    if ((s = tsj_get(v, "origin", 0)) && !parse_pair(s, ',', &x, &y)) {
        job->grid.origin_x = x;
        job->grid.origin_y = y;
        job->grid.has_origin = 1;
    }
    if ((s = tsj_get(v, "resolution", 0))) {
        job->grid.res = atof(s);
        job->grid.has_res = 1;
    }
    job->grid.crs = tsj_get(v, "crs", 0);
    for (i = 0; (s = tsj_get(v, "pin", i)); i++) {
        char path[1024];
        tsjob_pin *pin = &job->pins[job->n_pins];
        tsjob_parse_pin(s, pin, path, sizeof path); /* checked above */
        pin->path = keep(v, path);
        job->n_pins++;
    }
    job->water = tsj_get(v, "water", 0);
    if ((s = tsj_get(v, "water_level", 0)))
        job->water_level = atof(s);
    job->heights = tsj_get(v, "heights", 0);
    if ((s = tsj_get(v, "alpha_h", 0)))
        job->alpha_h = atof(s);
    job->regions = tsj_get(v, "regions", 0);
    if ((s = tsj_get(v, "seed", 0)))
        *seed = strtoull(s, NULL, 10);
    return 0;
}

int tsj_build_ppa(tsj_values *v, tsjob_ppa *job, char *msg, size_t len)
{
    const char *s;
    int cli = v->cli;
    memset(job, 0, sizeof *job);
    job->params = ts_ppa_params_default();
    job->band = 1;
    if (check_values(v, msg, len) || check_rules(v, cli, msg, len))
        return -1;
    expand_choices(v);
    if (apply_params(v, "ppa", &job->params, msg, len))
        return -1;
    /* the larger of the two thresholds applies: giving one sets the other to 0 */
    if (tsj_count(v, "threshold"))
        job->params.threshold_fraction = 0.0;
    if (tsj_count(v, "threshold_fraction"))
        job->params.threshold = 0.0;
    job->input = tsj_get(v, "input", 0);
    if (!job->input) {
        msgf(msg, len, "needs an input DEM");
        return -1;
    }
    if ((s = tsj_get(v, "band", 0)))
        job->band = atoi(s);
    if ((s = tsj_get(v, "cell_size", 0)))
        job->cell_size = atof(s);
    if ((s = tsj_get(v, "tile_size", 0)))
        job->tile_size = atoi(s);
    return 0;
}

/* --weights h=0.4,a=0.2,...: into the parameters w_h, w_a, ... */
static int expand_weights(tsj_values *v, char *msg, size_t len)
{
    const char *s = tsj_get(v, "weights", 0);
    char **items;
    int i, rc = 0;
    if (!s)
        return 0;
    items = CSLTokenizeString2(s, ",", 0);
    for (i = 0; items && items[i] && rc == 0; i++) {
        const char *eq = strchr(items[i], '=');
        char name[8];
        if (!eq || eq - items[i] != 1 || !strchr("haculsx", items[i][0]) || !eq[1]) {
            msgf(msg, len, "weights takes h=W,a=W,s=W,u=W,l=W,c=W,x=W, not '%s'", items[i]);
            rc = -1;
            break;
        }
        snprintf(name, sizeof name, "w_%c", items[i][0]);
        if (tsj_count(v, name)) {
            msgf(msg, len, "give weights or %s, not both", name);
            rc = -1;
            break;
        }
        tsj_set(v, name, eq + 1);
    }
    if (!items || !items[0]) {
        msgf(msg, len, "weights is empty");
        rc = -1;
    }
    CSLDestroy(items);
    return rc;
}

int tsj_build_amplify(tsj_values *v, tsjob_amplify *job, char *msg, size_t len)
{
    const char *s;
    int i;
    memset(job, 0, sizeof *job);
    job->params = ts_amplify_params_default();
    job->band = 1;
    if (expand_weights(v, msg, len) || check_values(v, msg, len) ||
        check_rules(v, v->cli, msg, len))
        return -1;
    if (apply_params(v, "amplify", &job->params, msg, len))
        return -1;
    job->input = tsj_get(v, "input", 0);
    if (!job->input && strcmp(v->job->name, "dictionary") != 0) {
        msgf(msg, len, "needs an input DEM");
        return -1;
    }
    for (i = 0; (s = tsj_get(v, "exemplar", i)); i++) {
        if (job->n_exemplars == TSJOB_MAX_EXEMPLARS) {
            msgf(msg, len, "exemplar: at most %d", TSJOB_MAX_EXEMPLARS);
            return -1;
        }
        job->exemplars[job->n_exemplars++] = s;
    }
    /* the exemplars' layers: the k-th FILE of a NAME is the k-th exemplar's */
    for (i = 0; (s = tsj_get(v, "exemplar_layer", i)); i++) {
        const char *eq = strchr(s, '=');
        int l, k;
        for (l = 0; l < job->n_layers; l++)
            if (strlen(job->layer_names[l]) == (size_t)(eq - s) &&
                !strncmp(job->layer_names[l], s, (size_t)(eq - s)))
                break;
        if (l == job->n_layers) {
            if (l == TS_MAX_LAYERS) {
                msgf(msg, len, "exemplar_layer: at most %d names", TS_MAX_LAYERS);
                return -1;
            }
            snprintf(job->layer_names[l], TS_LAYER_NAME, "%.*s", (int)(eq - s), s);
            job->n_layers++;
        }
        for (k = 0; k < TSJOB_MAX_EXEMPLARS && job->layer_files[k][l]; k++)
            ;
        if (k >= job->n_exemplars) {
            msgf(msg, len, "exemplar_layer %s: more files than the %d exemplars",
                 job->layer_names[l], job->n_exemplars);
            return -1;
        }
        job->layer_files[k][l] = eq + 1;
    }
    for (i = 0; i < job->n_layers; i++)
        if (!job->layer_files[job->n_exemplars - 1][i]) {
            msgf(msg, len, "exemplar_layer %s: one file for each of the %d exemplars",
                 job->layer_names[i], job->n_exemplars);
            return -1;
        }
    for (i = 0; (s = tsj_get(v, "exemplar_classes", i)); i++) {
        if (i >= job->n_exemplars) {
            msgf(msg, len, "exemplar_classes: more files than the %d exemplars", job->n_exemplars);
            return -1;
        }
        job->exemplar_classes[i] = s;
    }
    if (i && i != job->n_exemplars) {
        msgf(msg, len, "exemplar_classes: one file for each of the %d exemplars", job->n_exemplars);
        return -1;
    }
    job->classes = tsj_get(v, "classes", 0);
    for (i = 0; (s = tsj_get(v, "biome", i)); i++) {
        const char *eq = strchr(s, '=');
        char *w;
        if (i == TSJOB_MAX_BIOMES) {
            msgf(msg, len, "biome: at most %d", TSJOB_MAX_BIOMES);
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
    for (i = 0; (s = tsj_get(v, "out_layer", i)); i++) {
        size_t n = strspn(s, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-");
        int l;
        if (n == 0 || n >= TS_LAYER_NAME || s[n] != '=' || !s[n + 1]) {
            msgf(msg, len, "out_layer takes NAME=FILE, not '%s'", s);
            return -1;
        }
        snprintf(job->out_layer_names[i], TS_LAYER_NAME, "%.*s", (int)n, s);
        for (l = 0; l < i; l++)
            if (!strcmp(job->out_layer_names[l], job->out_layer_names[i])) {
                msgf(msg, len, "out_layer %s is given twice", job->out_layer_names[i]);
                return -1;
            }
        job->n_out_layers++;
    }
    job->want_classes = tsj_count(v, "out_classes") > 0;
    job->dictionary = tsj_get(v, "dictionary", 0);
    job->shape_given = tsj_count(v, "factor") || tsj_count(v, "patch");
    if (!job->n_exemplars && !job->dictionary && !job->n_biomes) {
        msgf(msg, len, "give at least one exemplar, or a dictionary, or biomes");
        return -1;
    }
    if ((s = tsj_get(v, "resolution", 0)))
        job->resolution = atof(s);
    if (!strcmp(v->job->name, "dictionary") && !(job->resolution > 0)) {
        msgf(msg, len, "a dictionary needs the resolution of the cells it is for");
        return -1;
    }
    if ((s = tsj_get(v, "band", 0)))
        job->band = atoi(s);
    if ((s = tsj_get(v, "cell_size", 0)))
        job->cell_size = atof(s);
    return 0;
}

/* The target grid options (like, size, origin, resolution, crs). */
static void build_grid(tsj_values *v, tsjob_grid *g)
{
    const char *s;
    double x, y;
    g->like = tsj_get(v, "like", 0);
    if ((s = tsj_get(v, "size", 0)) && !parse_pair(s, 'x', &x, &y)) {
        g->width = (int)x;
        g->height = (int)y;
    }
    if ((s = tsj_get(v, "origin", 0)) && !parse_pair(s, ',', &x, &y)) {
        g->origin_x = x;
        g->origin_y = y;
        g->has_origin = 1;
    }
    if ((s = tsj_get(v, "resolution", 0))) {
        g->res = atof(s);
        g->has_res = 1;
    }
    g->crs = tsj_get(v, "crs", 0);
}

int tsj_build_pixel(tsj_values *v, tsjob_pixel *job, uint64_t *seed, char *msg, size_t len)
{
    const char *s;
    int i;
    memset(job, 0, sizeof *job);
    job->params = ts_pixel_params_default();
    job->band = 1;
    *seed = 0;
    if (check_values(v, msg, len) || check_rules(v, v->cli, msg, len) ||
        apply_params(v, "pixel", &job->params, msg, len))
        return -1;
    for (i = 0; (s = tsj_get(v, "exemplar", i)); i++)
        job->exemplars[job->n_exemplars++] = s;
    if (!job->n_exemplars) {
        msgf(msg, len, "needs at least one exemplar");
        return -1;
    }
    if (job->params.window && job->params.window % 2 == 0) {
        msgf(msg, len, "window must be odd, not %d", job->params.window);
        return -1;
    }
    if (job->params.rotations != 0 && job->params.rotations != 4 && job->params.rotations != 8) {
        msgf(msg, len, "rotations must be 0, 4 or 8, not %d", job->params.rotations);
        return -1;
    }
    if ((s = tsj_get(v, "band", 0)))
        job->band = atoi(s);
    if ((s = tsj_get(v, "cell_size", 0)))
        job->cell_size = atof(s);
    build_grid(v, &job->grid);
    job->guide = tsj_get(v, "guide", 0);
    if ((s = tsj_get(v, "jitter_levels", 0))) {
        char **items = CSLTokenizeString2(s, ",", 0);
        int n = CSLCount(items), bad = n < 1 || n > 10;
        for (i = 0; !bad && i < n; i++) {
            double j = -1;
            bad = parse_number(items[i], &j) || j < 0 || j > 2;
            job->params.jitter_levels[i] = j;
        }
        CSLDestroy(items);
        if (bad) {
            msgf(msg, len, "jitter_levels takes 1 to 10 numbers in 0..2, not '%s'", s);
            return -1;
        }
        job->params.n_jitter_levels = n;
    }
    if ((s = tsj_get(v, "seed", 0)))
        *seed = strtoull(s, NULL, 10);
    return 0;
}

/* ------------------------------------------------------------------ */
/* Command line                                                        */
/* ------------------------------------------------------------------ */

/* "--alpha-h" (or "--alpha-h=..."): the name "alpha_h" into buf; 0 if arg
 * is not a long flag. */
static int flag_to_name(const char *arg, char *buf, size_t len, const char **inline_value)
{
    size_t i = 0;
    const char *p;
    *inline_value = NULL;
    if (strncmp(arg, "--", 2) != 0 || !arg[2])
        return 0;
    for (p = arg + 2; *p && *p != '=' && i + 1 < len; p++)
        buf[i++] = *p == '-' ? '_' : *p;
    buf[i] = '\0';
    if (*p == '=')
        *inline_value = p + 1;
    return 1;
}

int tsj_parse_argv(tsj_values *v, int argc, char **argv, int first,
                   int (*skip)(int argc, char **argv, int *i, void *user), void *user, char *msg,
                   size_t len)
{
    int i, positional = 0;
    v->cli = 1;
    for (i = first; i < argc; i++) {
        const char *a = argv[i], *inl;
        char name[128];
        const tsj_option *o;
        if (skip) {
            int r = skip(argc, argv, &i, user);
            if (r < 0)
                return -1;
            if (r > 0)
                continue;
        }
        if (flag_to_name(a, name, sizeof name, &inl)) {
            o = tsj_option_find(v->job, name);
            if (!o && !tsj_param_stage(v->job, name)) {
                msgf(msg, len, "unknown option '%s'", a);
                return -1;
            }
            if (o && o->kind == TSJ_CHOICE) {
                if (inl) {
                    msgf(msg, len, "%s takes no value", a);
                    return -1;
                }
                tsj_set(v, name, "1");
                continue;
            }
            if (!inl) {
                if (i + 1 >= argc) {
                    msgf(msg, len, "%s needs a value", a);
                    return -1;
                }
                inl = argv[++i];
            }
            if (o && o->max_count > 1 && tsj_count(v, name) >= o->max_count) {
                msgf(msg, len, "%s: at most %d", name, o->max_count);
                return -1;
            }
            tsj_set(v, name, inl);
            continue;
        }
        if (a[0] == '-' && a[1] != '\0') {
            msgf(msg, len, "unknown option '%s'", a);
            return -1;
        }
        /* a plain argument: the next positional option */
        positional++;
        {
            size_t k;
            o = NULL;
            for (k = 0; k < v->job->n_opts; k++)
                if (v->job->opts[k].positional == positional)
                    o = &v->job->opts[k];
            if (!o) {
                msgf(msg, len, "unexpected argument '%s'", a);
                return -1;
            }
            tsj_set(v, o->name, a);
        }
    }
    return 0;
}

static void name_to_flag(const char *name, char *buf, size_t len)
{
    size_t i = 2;
    buf[0] = buf[1] = '-';
    for (; *name && i + 1 < len; name++)
        buf[i++] = *name == '_' ? '-' : *name;
    buf[i] = '\0';
}

void tsj_help(FILE *out, const tsj_job *job)
{
    const char *groups[8];
    int n_groups = 0, g, s;
    size_t k;
    for (k = 0; k < job->n_opts; k++) {
        int seen = 0;
        for (g = 0; g < n_groups; g++)
            seen |= !strcmp(groups[g], job->opts[k].group);
        if (!seen && n_groups < 8)
            groups[n_groups++] = job->opts[k].group;
    }
    for (g = 0; g < n_groups; g++) {
        fprintf(out, "%s:\n", groups[g]);
        for (k = 0; k < job->n_opts; k++) {
            const tsj_option *o = &job->opts[k];
            char flag[64], left[160];
            if (strcmp(o->group, groups[g]) != 0)
                continue;
            name_to_flag(o->name, flag, sizeof flag);
            if (o->positional)
                snprintf(left, sizeof left, "%s", o->metavar);
            else if (o->kind == TSJ_CHOICE)
                snprintf(left, sizeof left, "%s", flag);
            else
                snprintf(left, sizeof left, "%s %s", flag, o->metavar);
            cli_help_line(out, left, o->help);
        }
        fputc('\n', out);
    }
    for (s = 0; job->stages[s]; s++) {
        if (!strcmp(job->stages[s], "sketch"))
            fprintf(out, "Sketch parameters (with --sketch):\n");
        else
            fprintf(out, "%s parameters:\n",
                    !strcmp(job->stages[s], "ppa")       ? "PPA"
                    : !strcmp(job->stages[s], "amplify") ? "Amplification"
                                                         : "Synthesis");
        cli_params_help(out, job->stages[s], NULL);
        fputc('\n', out);
    }
    fprintf(out, "Rules:\n");
    for (k = 0; k < job->n_rules; k++) {
        const tsj_rule *r = &job->rules[k];
        char line[256];
        int i;
        size_t n = 0;
        static const char *const kinds[] = {"needs",    "excludes", "goes with",
                                            "or",       "needs one of", "or"};
        if (!strcmp(r->a, "output"))
            continue; /* the usage line says it */
        n += (size_t)snprintf(line + n, sizeof line - n, "%s %s",
                              r->a[0] == '@' ? "the sketch parameters" : r->a,
                              r->kind == TSJ_ONE_OF || r->kind == TSJ_ANY_OF ? ","
                                                                             : kinds[r->kind]);
        for (i = 0; r->b[i] && n < sizeof line; i++)
            n += (size_t)snprintf(
                line + n, sizeof line - n, "%s %s",
                i ? (r->kind == TSJ_ONE_OF || r->kind == TSJ_ANY_OF || r->kind == TSJ_NEEDS_ANY
                         ? " or"
                         : ",")
                  : "",
                r->b[i]);
        if (r->kind == TSJ_ONE_OF && n < sizeof line)
            snprintf(line + n, sizeof line - n, ": exactly one");
        if (r->kind == TSJ_ANY_OF && n < sizeof line)
            snprintf(line + n, sizeof line - n, ": at least one");
        fprintf(out, "  %s\n", line);
    }
}

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

int tsj_from_xml(tsj_values *v, const CPLXMLNode *node,
                 const char *(*resolve)(void *user, const char *name, char *msg, size_t len),
                 void *user, char *msg, size_t len)
{
    const CPLXMLNode *c;
    size_t k;
    for (k = 0; k < v->job->n_opts; k++) {
        const tsj_option *o = &v->job->opts[k];
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
            if (o->kind == TSJ_PIN) {
                long n[6];
                int i;
                for (i = 0; i < 6; i++) {
                    const char *s = CPLGetXMLValue(c, pin_attrs[i], NULL);
                    char *end;
                    n[i] = s ? strtol(s, &end, 10) : -1;
                    if (!s || *end || n[i] < 0) {
                        msgf(msg, len, "<%s %s=\"%s\">: not a cell number", elem, pin_attrs[i],
                             s ? s : "");
                        return -1;
                    }
                }
                snprintf(buf, sizeof buf, "%s:%ld,%ld,%ld,%ld@%ld,%ld",
                         CPLGetXMLValue(c, NULL, ""), n[0], n[1], n[2], n[3], n[4], n[5]);
                val = buf;
            } else if (o->kind == TSJ_RULE || o->kind == TSJ_NAMED) {
                snprintf(buf, sizeof buf, "%s=%s",
                         CPLGetXMLValue(c, o->kind == TSJ_RULE ? "id" : "name", ""),
                         CPLGetXMLValue(c, NULL, ""));
                val = buf;
            } else if (o->kind == TSJ_PAIR) {
                /* both files relative to the recipe */
                const char *first = CPLGetXMLValue(c, o->choices, ""), *res;
                char a_abs[1024];
                if (!*first || !*CPLGetXMLValue(c, NULL, "")) {
                    msgf(msg, len, "<%s %s=\"FILE\">FILE</%s> needs both files", elem, o->choices,
                         elem);
                    return -1;
                }
                if (strchr(first, '=')) {
                    msgf(msg, len, "<%s %s=\"%s\">: a name with '='", elem, o->choices, first);
                    return -1;
                }
                if (!(res = resolve(user, first, msg, len)))
                    return -1;
                snprintf(a_abs, sizeof a_abs, "%s", res);
                if (!(res = resolve(user, CPLGetXMLValue(c, NULL, ""), msg, len)))
                    return -1;
                snprintf(buf, sizeof buf, "%s=%s", a_abs, res);
                if (o->max_count > 1 && tsj_count(v, o->name) >= o->max_count) {
                    msgf(msg, len, "more than %d <%s> elements", o->max_count, elem);
                    return -1;
                }
                tsj_set(v, o->name, buf);
                continue;
            } else if (parts == 0) {
                val = CPLGetXMLValue(c, NULL, "");
            } else if (parts == 1) {
                val = CPLGetXMLValue(c, a, NULL);
            } else {
                const char *x = CPLGetXMLValue(c, a, NULL), *y = CPLGetXMLValue(c, b, NULL);
                if (!x && !y)
                    continue;
                snprintf(buf, sizeof buf, "%s%c%s", x ? x : "", o->kind == TSJ_SIZE ? 'x' : ',',
                         y ? y : "");
                val = buf;
            }
            if (!val)
                continue;
            if (o->kind == TSJ_FILE || o->kind == TSJ_PIN || o->kind == TSJ_RULE ||
                o->kind == TSJ_NAMED) {
                /* the file names relative to the recipe, and never the recipe itself */
                const char *file = val, *sep = NULL;
                char head[64] = "";
                if (o->kind == TSJ_RULE || o->kind == TSJ_NAMED) {
                    sep = strchr(val, '=');
                    snprintf(head, sizeof head, "%.*s=", sep ? (int)(sep - val) : 0, val);
                    file = sep ? sep + 1 : "";
                }
                if (o->kind == TSJ_PIN) {
                    const char *colon = strrchr(val, ':');
                    char path[1024], tail[128];
                    const char *res;
                    snprintf(path, sizeof path, "%.*s", colon ? (int)(colon - val) : 0, val);
                    snprintf(tail, sizeof tail, "%s", colon ? colon : "");
                    if (!*path) {
                        msgf(msg, len, "<%s> is empty", elem);
                        return -1;
                    }
                    if (!(res = resolve(user, path, msg, len)))
                        return -1;
                    snprintf(buf, sizeof buf, "%s%s", res, tail);
                    tsj_set(v, o->name, buf);
                    continue;
                }
                if (!*file) {
                    if (o->kind == TSJ_RULE || o->kind == TSJ_NAMED) {
                        msgf(msg, len, "<%s %s>FILE</%s> has no file", elem,
                             o->kind == TSJ_RULE ? "id=\"N\"" : "name=\"NAME\"", elem);
                        return -1;
                    }
                    continue; /* an empty element names nothing */
                }
                if (!(file = resolve(user, file, msg, len)))
                    return -1;
                snprintf(buf, sizeof buf, "%s%s", head, file);
                val = buf;
            }
            if (o->max_count > 1 && tsj_count(v, o->name) >= o->max_count) {
                msgf(msg, len, "more than %d <%s> elements", o->max_count, elem);
                return -1;
            }
            tsj_set(v, o->name, val);
        }
    }
    /* the stage parameters */
    for (c = node->psChild; c; c = c->psNext) {
        const char *name;
        if (c->eType != CXT_Element || !EQUAL(c->pszValue, "Param"))
            continue;
        name = CPLGetXMLValue(c, "name", NULL);
        if (!name) {
            msgf(msg, len, "<Param> without a name attribute");
            return -1;
        }
        if (!tsj_param_stage(v->job, name)) {
            msgf(msg, len, "<Param name=\"%s\">: unknown parameter", name);
            return -1;
        }
        tsj_set(v, name, CPLGetXMLValue(c, NULL, ""));
    }
    return 0;
}

/* The child element `name` of node, created when missing. */
static CPLXMLNode *xml_child(CPLXMLNode *node, const char *name)
{
    CPLXMLNode *c = CPLGetXMLNode(node, name);
    return c ? c : CPLCreateXMLNode(node, CXT_Element, name);
}

void tsj_to_xml(const tsj_values *v, CPLXMLNode *root,
                const char *(*rel)(void *user, const char *name), void *user)
{
    CPLXMLNode *node = CPLCreateXMLNode(root, CXT_Element, v->job->element);
    size_t k;
    int i, s;
    /* attributes of the job's element first (XML puts them before children) */
    for (k = 0; k < v->job->n_opts; k++) {
        const tsj_option *o = &v->job->opts[k];
        if (o->xml && o->xml[0] == '@' && tsj_count(v, o->name))
            CPLAddXMLAttributeAndValue(node, o->xml + 1, tsj_get(v, o->name, 0));
    }
    for (k = 0; k < v->job->n_opts; k++) {
        const tsj_option *o = &v->job->opts[k];
        char elem[64], a[64], b[64];
        int parts;
        const char *val;
        if (!o->xml || o->xml[0] == '@')
            continue;
        parts = xml_split(o->xml, elem, a, b, sizeof elem);
        for (i = 0; (val = tsj_get(v, o->name, i)); i++) {
            CPLXMLNode *e;
            if (o->kind == TSJ_PIN) {
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
            } else if (o->kind == TSJ_RULE || o->kind == TSJ_NAMED) {
                const char *eq = strchr(val, '=');
                if (!eq)
                    continue;
                e = CPLCreateXMLElementAndValue(node, elem, rel(user, eq + 1));
                CPLAddXMLAttributeAndValue(e, o->kind == TSJ_RULE ? "id" : "name",
                                           CPLSPrintf("%.*s", (int)(eq - val), val));
            } else if (o->kind == TSJ_PAIR) {
                const char *eq = strchr(val, '=');
                char first[1024];
                if (!eq)
                    continue;
                snprintf(first, sizeof first, "%.*s", (int)(eq - val), val);
                e = CPLCreateXMLElementAndValue(node, elem, rel(user, eq + 1));
                CPLAddXMLAttributeAndValue(e, o->choices, rel(user, first));
            } else if (parts == 0) {
                CPLCreateXMLElementAndValue(node, elem,
                                            o->kind == TSJ_FILE ? rel(user, val) : val);
            } else if (parts == 1) {
                e = xml_child(node, elem);
                CPLAddXMLAttributeAndValue(e, a, o->kind == TSJ_FILE ? rel(user, val) : val);
            } else {
                char sep = o->kind == TSJ_SIZE ? 'x' : ',';
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
            const char *val = tsj_get(v, d[k].name, 0);
            CPLXMLNode *p;
            if (!val)
                continue;
            p = CPLCreateXMLElementAndValue(node, "Param", val);
            CPLAddXMLAttributeAndValue(p, "name", d[k].name);
        }
    }
}

/* ------------------------------------------------------------------ */
/* describe                                                            */
/* ------------------------------------------------------------------ */

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

void tsj_describe(FILE *out)
{
    static const char *const kinds[] = {"file", "output", "number", "int",    "seed",
                                        "text", "size",   "xy",     "pin",    "rule",
                                        "choice", "named", "pair"};
    /* one name per kind: a kind added without its name does not compile */
    _Static_assert(sizeof kinds / sizeof kinds[0] == TSJ_PAIR + 1, "a name for every tsj_kind");
    static const char *const rkinds[] = {"requires", "excludes", "together",
                                         "one_of",   "needs_any", "any_of"};
    _Static_assert(sizeof rkinds / sizeof rkinds[0] == TSJ_ANY_OF + 1, "a name for every rule");
    size_t j, k;
    int i;
    fprintf(out, "  \"jobs\": {");
    for (j = 0; j < sizeof jobs / sizeof jobs[0]; j++) {
        const tsj_job *job = &jobs[j];
        fprintf(out, "%s\n    \"%s\": {\n      \"stages\": [", j ? "," : "", job->name);
        for (i = 0; job->stages[i]; i++)
            fprintf(out, "%s\"%s\"", i ? ", " : "", job->stages[i]);
        fprintf(out, "],\n      \"options\": [");
        for (k = 0; k < job->n_opts; k++) {
            const tsj_option *o = &job->opts[k];
            char flag[64];
            name_to_flag(o->name, flag, sizeof flag);
            fprintf(out, "%s\n        {\"name\": \"%s\", \"flag\": \"%s\", \"kind\": \"%s\", "
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
            const tsj_rule *r = &job->rules[k];
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
