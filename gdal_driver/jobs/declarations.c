/*
 * declarations.c - one declaration per job: the options, groups, stages and rules of
 * ppa, synth, amplify, dictionary and pixel, and the lookups into them.
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

#include "jobspec.h"

/* ------------------------------------------------------------------ */
/* The declarations                                                    */
/* ------------------------------------------------------------------ */

#define TS_STR_(x) #x
#define TS_STR(x) TS_STR_(x) /* a number as text */
#define G_IN "Inputs"
#define G_GRID "Target grid"
#define G_CONS "Constraints"
#define G_RUN "Run"
#define G_OUT "Outputs"

/* Options and rules several jobs declare alike. */
#define OPT_BAND_EVERY                                                                             \
    {                                                                                              \
        "band", TSJOB_INT, 1, 1, 65535, "N", G_IN, "band read from every input (default 1)",       \
            "Band", 0, NULL                                                                        \
    }
#define OPT_CELL_SIZE_GRID                                                                         \
    {                                                                                              \
        "cell_size", TSJOB_NUMBER, 1, 1e-6, 1e7, "M", G_IN,                                        \
            "ground size of a cell in metres of every raster without a CRS (a target grid "        \
            "without "                                                                             \
            "one too); without it such rasters are used cell for cell",                            \
            "CellSize", 0, NULL                                                                    \
    }
/* the target grid: like a raster, or a size (at most size_max cells a side) */
#define OPT_GRID(size_max)                                                                         \
    {"like",      TSJOB_FILE, 1,      0,                                                           \
     0,           "GRID.tif", G_GRID, "size, geotransform and CRS of a raster",                    \
     "Grid@like", 0,          NULL},                                                               \
        {"size",                                                                                   \
         TSJOB_SIZE,                                                                               \
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
         TSJOB_XY,                                                                                 \
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
         TSJOB_NUMBER,                                                                             \
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
        "crs", TSJOB_TEXT, 1, 0, 0, "CRS", G_GRID,                                                 \
            "EPSG:code, WKT or PROJ string (with size, origin and resolution)", "Grid@crs", 0,     \
            NULL                                                                                   \
    }
#define OPT_SEED                                                                                   \
    {                                                                                              \
        "seed", TSJOB_SEED, 1, 0, 0, "S", G_RUN,                                                   \
            "random seed (default 0); same inputs and seed give the same bytes", "@seed", 0, NULL  \
    }
#define OPT_PREVIEW                                                                                \
    {                                                                                              \
        "preview", TSJOB_OUTPUT, 1, 0, 0, "FILE.png", G_OUT, "hillshade of the result", NULL, 0,   \
            NULL                                                                                   \
    }
/* the output's streams, on every job that writes a DEM (and ppa, of its input) */
#define OPT_FLOW                                                                                   \
    {"flow_lines",                                                                                 \
     TSJOB_OUTPUT,                                                                                 \
     1,                                                                                            \
     0,                                                                                            \
     0,                                                                                            \
     "FILE.gpkg",                                                                                  \
     G_OUT,                                                                                        \
     "the DEM's streams as vector lines: layer 'streams', a line per link with its Strahler "      \
     "order, drainage area and the link it flows into; format from the extension (.gpkg, "         \
     ".shp, .geojson)",                                                                            \
     NULL,                                                                                         \
     0,                                                                                            \
     NULL},                                                                                        \
        {"flow_cells",                                                                             \
         TSJOB_NUMBER,                                                                             \
         1,                                                                                        \
         2,                                                                                        \
         1e12,                                                                                     \
         "CELLS",                                                                                  \
         G_OUT,                                                                                    \
         "with flow_lines: a stream drains at least this many cells (default 1000)",               \
         NULL,                                                                                     \
         0,                                                                                        \
         NULL},                                                                                    \
    {                                                                                              \
        "flow_km2", TSJOB_NUMBER, 1, 1e-9, 1e9, "KM2", G_OUT,                                      \
            "with flow_lines: a stream drains at least this many square kilometres (instead of "   \
            "flow_cells; needs a CRS or cell_size)",                                               \
            NULL, 0, NULL                                                                          \
    }
#define RULES_FLOW                                                                                 \
    {TSJOB_REQUIRES, "flow_cells", {"flow_lines", NULL}, "flow_cells goes with flow_lines"},       \
        {TSJOB_REQUIRES, "flow_km2", {"flow_lines", NULL}, "flow_km2 goes with flow_lines"},       \
    {                                                                                              \
        TSJOB_EXCLUDES, "flow_cells", {"flow_km2", NULL}, "give flow_cells or flow_km2, not both"  \
    }
#define OPT_RECIPE                                                                                 \
    {                                                                                              \
        "recipe", TSJOB_OUTPUT, 1, 0, 0, "FILE.tsyn", G_OUT,                                       \
            "write a recipe for this job instead of running it: gdal_translate FILE.tsyn out.tif", \
            NULL, 0, NULL                                                                          \
    }
/* what a grid given by its size needs */
#define RULES_GRID_SIZE                                                                            \
    {TSJOB_REQUIRES,                                                                               \
     "crs",                                                                                        \
     {"origin", "resolution", NULL},                                                               \
     "a CRS needs an origin and a resolution"},                                                    \
        {TSJOB_REQUIRES, "origin", {"size", NULL}, "origin goes with size"},                       \
    {                                                                                              \
        TSJOB_REQUIRES, "resolution", {"size", NULL}, "resolution goes with size"                  \
    }

static const tsjob_option synth_opts[] = {
    {"exemplar", TSJOB_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "EX.tif", G_IN,
     "a real DEM (any GDAL raster) whose style the terrain takes; repeatable", "Exemplar", 0, NULL},
    OPT_BAND_EVERY,
    OPT_CELL_SIZE_GRID,
    {"sketch", TSJOB_FILE, 1, 0, 0, "SK", G_GRID,
     "a sketch the terrain follows: a raster (bright strokes are ridges, dark strokes valleys; "
     "on a grey ground, brighter and darker) on whose grid the output is, nodata where it is "
     "nodata; or a layer of lines (GeoPackage, Shapefile, GeoJSON, KML, FlatGeobuf...) whose "
     "field kind says ridge, valley or river, on the grid of like or of resolution",
     "Sketch", 0, NULL},
    {"sketch_layer", TSJOB_TEXT, 1, 0, 0, "NAME", G_GRID,
     "the layer of a sketch of lines (default: its first layer of lines)", "Sketch@layer", 0, NULL},
    {"kind_field", TSJOB_TEXT, 1, 0, 0, "FIELD", G_GRID,
     "the field of a sketch of lines that says ridge, valley or river (default kind)",
     "Sketch@kindField", 0, NULL},
    {"height_field", TSJOB_TEXT, 1, 0, 0, "FIELD", G_CONS,
     "a numeric field of a sketch of lines: the height wanted along each line (the lines' Z "
     "values are used without it)",
     "Sketch@heightField", 0, NULL},
    {"snap", TSJOB_NUMBER, 1, 0, 1000, "CELLS", G_GRID,
     "a line end this close to another line of its kind joins it (cells, default 2)", "Sketch@snap",
     0, NULL},
    {"extent", TSJOB_TEXT, 1, 0, 0, "XMIN,YMIN,XMAX,YMAX", G_GRID,
     "with a sketch of lines and resolution: the output's extent in its CRS (default: the "
     "lines' bounding box grown by a patch on each side)",
     "Grid@extent", 0, NULL},
    OPT_GRID(65536),
    {"coarse_pass", TSJOB_FILE, 1, 0, 0, "FILE", G_GRID,
     "a sketch in tiles laid out before (its coarse pass): read instead of laying the sketch out "
     "when it was made from the same inputs, parameters and seed (else laid out again, with a "
     "warning); recipe writes it (default: the recipe's name with .coarse added)",
     "CoarsePass", 0, NULL},
    {"pin", TSJOB_PIN, TSJOB_MAX_PINS, 0, 0, "FILE:XOFF,YOFF,W,H@X,Y", G_CONS,
     "keep a window of a DEM (its own cells) unchanged with its top-left at output cell X,Y; "
     "repeatable",
     "Pin", 0, NULL},
    {"water", TSJOB_FILE, 1, 0, 0, "MASK", G_CONS,
     "cells where MASK (a raster on the output grid) is non-zero keep water_level", "Water", 0,
     NULL},
    {"water_level", TSJOB_NUMBER, 1, -1e7, 1e7, "H", G_CONS, "the level of the water cells",
     "Water@level", 0, NULL},
    {"heights", TSJOB_FILE, 1, 0, 0, "H.tif", G_CONS,
     "wanted elevations (a raster on the output grid, nodata = free)", "Heights", 0, NULL},
    {"alpha_h", TSJOB_NUMBER, 1, 0, 1e9, "A", G_CONS,
     "weight of the wanted elevations: each candidate pays A x RMS difference (default 1)",
     "Heights@alpha", 0, NULL},
    {"regions", TSJOB_FILE, 1, 0, 0, "R", G_CONS,
     "several styles: an integer raster on the output grid or a polygon layer with an "
     "integer field 'region'",
     "Regions", 0, NULL},
    {"region_exemplar", TSJOB_RULE, TSJOB_MAX_EXEMPLARS, 0, 0, "ID=EX", G_CONS,
     "region ID takes exemplar EX (repeatable; other regions take any exemplar)", "RegionExemplar",
     0, NULL},
    OPT_SEED,
    {"output", TSJOB_OUTPUT, 1, 0, 0, "OUTPUT", G_OUT,
     "the terrain: a Float32 DEM on the target grid, nodata " TSIO_NODATA_TEXT, NULL, 1, NULL},
    OPT_PREVIEW,
    OPT_FLOW,
    {"debug_dir", TSJOB_OUTPUT, 1, 0, 0, "DIR", G_OUT,
     "seams.tif, source_exemplar.tif, source_x.tif, source_y.tif, order.tif (georeferenced); "
     "with a sketch also its features and the output's (GeoPackage) and valley_floor.tif "
     "(1 on the drawn valleys' floors)",
     NULL, 0, NULL},
    OPT_RECIPE,
};

static const tsjob_rule synth_rules[] = {
    {TSJOB_EXCLUDES,
     "sketch",
     {"size", "origin", NULL},
     "a sketch sets the output grid: give no %s"},
    {TSJOB_EXCLUDES,
     "like",
     {"size", "origin", "resolution", "crs", "extent", NULL},
     "like sets the output grid: give no %s"},
    {TSJOB_ANY_OF,
     "sketch",
     {"like", "size", NULL},
     "give the target grid: a sketch, like or size"},
    {TSJOB_NEEDS_ANY,
     "crs",
     {"origin", "sketch", NULL},
     "a CRS needs an origin and a resolution (or a sketch of lines and a resolution)"},
    {TSJOB_REQUIRES,
     "crs",
     {"resolution", NULL},
     "a CRS needs an origin and a resolution (or a sketch of lines and a resolution)"},
    {TSJOB_REQUIRES, "origin", {"size", NULL}, "origin goes with size"},
    {TSJOB_NEEDS_ANY,
     "resolution",
     {"size", "sketch", NULL},
     "resolution goes with size (or a sketch of lines)"},
    {TSJOB_REQUIRES,
     "extent",
     {"sketch", "resolution", NULL},
     "extent goes with a sketch of lines and resolution"},
    {TSJOB_REQUIRES, "sketch_layer", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJOB_REQUIRES, "kind_field", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJOB_REQUIRES, "height_field", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJOB_REQUIRES, "snap", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJOB_REQUIRES,
     "coarse_pass",
     {"sketch", "tiled", NULL},
     "%s is a sketch in tiles laid out before: give sketch and tiled"},
    {TSJOB_TOGETHER, "water", {"water_level", NULL}, "water and water_level go together"},
    {TSJOB_TOGETHER,
     "regions",
     {"region_exemplar", NULL},
     "regions and region_exemplar go together"},
    {TSJOB_REQUIRES, "alpha_h", {"heights", NULL}, "alpha_h weighs heights: give heights"},
    {TSJOB_REQUIRES, "@sketch", {"sketch", NULL}, "%s applies to a sketch: give sketch"},
    {TSJOB_EXCLUDES,
     "recipe",
     {"output", "preview", "debug_dir", "flow_lines", NULL},
     "recipe writes the recipe instead of running the job: give no %s"},
    RULES_FLOW,
    {TSJOB_ONE_OF, "output", {"recipe", NULL}, "give OUTPUT (or recipe)"},
};

static const tsjob_option ppa_opts[] = {
    {"input", TSJOB_FILE, 1, 0, 0, "INPUT", G_IN, "the DEM (any GDAL raster)", "Input", 1, NULL},
    {"band", TSJOB_INT, 1, 1, 65535, "N", G_IN, "band read (default 1)", "Input@band", 0, NULL},
    {"cell_size", TSJOB_NUMBER, 1, 1e-6, 1e7, "M", G_IN,
     "ground size of a cell in metres, for a raster without a CRS (otherwise lengths are in "
     "cells)",
     "CellSize", 0, NULL},
    {"ridges", TSJOB_CHOICE, 1, 0, 0, NULL, G_IN, "map ridges (features ridges)", NULL, 0,
     "features=ridges"},
    {"valleys", TSJOB_CHOICE, 1, 0, 0, NULL, G_IN, "map valleys (features valleys)", NULL, 0,
     "features=valleys"},
    {"both", TSJOB_CHOICE, 1, 0, 0, NULL, G_IN, "map both (features both)", NULL, 0,
     "features=both"},
    {"output", TSJOB_OUTPUT, 1, 0, 0, "OUTPUT", G_OUT,
     "Byte raster on the input's grid: 1 ridge, 2 valley, 3 both, 0 none, 255 nodata", NULL, 2,
     NULL},
    {"lines", TSJOB_OUTPUT, 1, 0, 0, "FILE", G_OUT,
     "vector axes: layer 'paths' (LineString per path) and layer 'nodes' (endpoints, branch "
     "points); format from the extension (.gpkg, .shp, .geojson)",
     NULL, 0, NULL},
    {"preview", TSJOB_OUTPUT, 1, 0, 0, "FILE.png", G_OUT,
     "hillshade with ridges (red) and valleys (blue)", NULL, 0, NULL},
    OPT_FLOW,
    {"tile_size", TSJOB_INT, 1, 0, TS_PPA_TILE_MAX, "N", G_RUN,
     "map the DEM in tiles of N x N cells (" TS_STR(TS_PPA_TILE_MIN) ".." TS_STR(
         TS_PPA_TILE_MAX) "), read window by window three times: the "
                          "same raster as in one piece, in the memory of three rows of tiles and "
                          "the axes' chains "
                          "(DEMs larger than memory; not with lines, preview or flow_lines). 0 "
                          "(default): in one piece, or, when "
                          "it does not fit in memory, in the largest tiles (8192 .. 64) that do",
     "TileSize", 0, NULL},
    OPT_RECIPE,
};

static const tsjob_rule ppa_rules[] = {
    {TSJOB_EXCLUDES,
     "threshold",
     {"threshold_fraction", NULL},
     "give threshold or threshold_fraction, not both"},
    {TSJOB_EXCLUDES,
     "ridges",
     {"valleys", "both", "features", NULL},
     "give one of ridges, valleys, both (or features), not %s too"},
    {TSJOB_EXCLUDES,
     "valleys",
     {"both", "features", NULL},
     "give one of ridges, valleys, both (or features), not %s too"},
    {TSJOB_EXCLUDES,
     "both",
     {"features", NULL},
     "give one of ridges, valleys, both (or features), not %s too"},
    {TSJOB_EXCLUDES,
     "recipe",
     {"output", "lines", "preview", "flow_lines", NULL},
     "recipe writes the recipe instead of running the job: give no %s"},
    RULES_FLOW,
    {TSJOB_ONE_OF, "output", {"recipe", NULL}, "give OUTPUT (or recipe)"},
};

static const tsjob_option amplify_opts[] = {
    {"input", TSJOB_FILE, 1, 0, 0, "INPUT", G_IN,
     "the coarse DEM (any GDAL raster): the output is `factor` times finer on its extent", "Input",
     1, NULL},
    {"exemplar", TSJOB_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "EX.tif", G_IN,
     "a real DEM whose detail the output takes (resampled to the output's ground "
     "resolution); repeatable",
     "Exemplar", 0, NULL},
    {"exemplar_layer", TSJOB_NAMED, TSJOB_MAX_EXEMPLARS *TS_MAX_LAYERS, 0, 0, "NAME=FILE", G_IN,
     "an extra layer of an exemplar (vegetation, soil, ...: any raster on its grid) that the "
     "atoms carry to the output; the k-th FILE given for a NAME belongs to the k-th exemplar, "
     "and every exemplar gives every NAME",
     "ExemplarLayer", 0, NULL},
    {"exemplar_classes", TSJOB_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "CL.tif", G_IN,
     "class codes 1..64 of an exemplar (a raster on its grid; 0 or nodata: unlabelled), one "
     "per exemplar in order: the atoms' classes (section 5.4)",
     "ExemplarClasses", 0, NULL},
    {"dictionary", TSJOB_FILE, 1, 0, 0, "D.tsd", G_IN,
     "a dictionary built once by `terrasynth dictionary build` (instead of exemplars): "
     "its factor, patch and cell size are the job's",
     "Dictionary", 0, NULL},
    {"weights", TSJOB_TEXT, 1, 0, 0, "h=W,a=W,s=W,u=W,l=W,c=W,x=W", G_IN,
     "the matching weights in one option (any of them; the others keep their values): the same "
     "as --w-h, --w-a, ... (not both)",
     NULL, 0, NULL},
    {"biome", TSJOB_PAIR, TSJOB_MAX_BIOMES, 0, 0, "W.tif=D.tsd", G_IN,
     "a biome (section 5.5): dictionary D (terrasynth dictionary build) weighs W, a raster "
     "on the input's grid painted by the user (shares: each biome's weight over their sum); "
     "repeatable, instead of exemplars or a dictionary",
     "Biome", 0, "weights"},
    OPT_BAND_EVERY,
    {"cell_size", TSJOB_NUMBER, 1, 1e-6, 1e7, "M", G_IN,
     "ground size of a cell in metres of every raster without a CRS (without it such "
     "rasters are used cell for cell)",
     "CellSize", 0, NULL},
    {"classes", TSJOB_FILE, 1, 0, 0, "WANT.tif", G_CONS,
     "wanted classes on the input's grid (codes of the exemplars' classes; 0 or nodata: any): "
     "each patch prefers atoms of its classes, weighed by w_c",
     "Classes", 0, NULL},
    {"output", TSJOB_OUTPUT, 1, 0, 0, "OUTPUT", G_OUT,
     "the amplified DEM: Float32 on the input's extent and CRS, factor times finer, "
     "nodata " TSIO_NODATA_TEXT " where the input is nodata",
     NULL, 2, NULL},
    {"out_layer", TSJOB_OUTPUT, TS_MAX_LAYERS, 0, 0, "NAME=FILE", G_OUT,
     "an extra layer the atoms carry (exemplar_layer NAME), on the output's grid (Float32, "
     "nodata " TSIO_NODATA_TEXT "); repeatable",
     NULL, 0, NULL},
    {"out_classes", TSJOB_OUTPUT, 1, 0, 0, "FILE", G_OUT,
     "the atoms' classes on the output's grid (Byte, 0 = unlabelled)", NULL, 0, NULL},
    OPT_PREVIEW,
    OPT_FLOW,
    OPT_RECIPE,
};

static const tsjob_rule amplify_rules[] = {
    {TSJOB_ONE_OF,
     "exemplar",
     {"dictionary", "biome", NULL},
     "give at least one exemplar, or a dictionary, or biomes"},
    {TSJOB_EXCLUDES,
     "biome",
     {"classes", "out_layer", "out_classes", NULL},
     "biomes blend dictionaries: give no %s"},
    {TSJOB_EXCLUDES,
     "recipe",
     {"output", "preview", "out_layer", "out_classes", "flow_lines", NULL},
     "recipe writes the recipe instead of running the job: give no %s"},
    RULES_FLOW,
    {TSJOB_EXCLUDES,
     "dictionary",
     {"exemplar_layer", "exemplar_classes", NULL},
     "the dictionary holds the exemplars' layers and classes: give no %s"},
    {TSJOB_REQUIRES, "exemplar_layer", {"exemplar", NULL}, "exemplar_layer needs exemplars"},
    {TSJOB_REQUIRES, "exemplar_classes", {"exemplar", NULL}, "exemplar_classes needs exemplars"},
    {TSJOB_ONE_OF, "output", {"recipe", NULL}, "give OUTPUT (or recipe)"},
};

static const tsjob_option dictionary_opts[] = {
    {"exemplar", TSJOB_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "EX.tif", G_IN,
     "a real DEM whose detail the atoms hold (resampled to the resolution); repeatable", "Exemplar",
     0, NULL},
    {"band", TSJOB_INT, 1, 1, 65535, "N", G_IN, "band read from every exemplar (default 1)", "Band",
     0, NULL},
    {"cell_size", TSJOB_NUMBER, 1, 1e-6, 1e7, "M", G_IN,
     "ground size of a cell in metres of every exemplar without a CRS", "CellSize", 0, NULL},
    {"exemplar_layer", TSJOB_NAMED, TSJOB_MAX_EXEMPLARS *TS_MAX_LAYERS, 0, 0, "NAME=FILE", G_IN,
     "an extra layer of an exemplar (vegetation, soil, ...: any raster on its grid) that the "
     "atoms carry to the output; the k-th FILE given for a NAME belongs to the k-th exemplar, "
     "and every exemplar gives every NAME",
     "ExemplarLayer", 0, NULL},
    {"exemplar_classes", TSJOB_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "CL.tif", G_IN,
     "class codes 1..64 of an exemplar (a raster on its grid; 0 or nodata: unlabelled), one "
     "per exemplar in order: the atoms' classes (section 5.4)",
     "ExemplarClasses", 0, NULL},
    {"resolution", TSJOB_NUMBER, 1, 1e-6, 1e7, "M", G_IN,
     "ground size in metres of the cells of the amplified DEMs the dictionary is for (the "
     "input's cell divided by the factor); required",
     "Resolution", 0, NULL},
    {"output", TSJOB_OUTPUT, 1, 0, 0, "D.tsd", G_OUT, "the dictionary file", NULL, 1, NULL},
};

static const tsjob_rule dictionary_rules[] = {
    {TSJOB_REQUIRES,
     "output",
     {"exemplar", "resolution", NULL},
     "a dictionary needs exemplars and the resolution"},
};

static const tsjob_option pixel_opts[] = {
    {"exemplar", TSJOB_FILE, TSJOB_MAX_EXEMPLARS, 0, 0, "EX.tif", G_IN,
     "a real DEM (any GDAL raster) whose style the terrain takes, resampled to the output's "
     "ground resolution; repeatable",
     "Exemplar", 0, NULL},
    OPT_BAND_EVERY,
    OPT_CELL_SIZE_GRID,
    {"guide", TSJOB_FILE, 1, 0, 0, "G.tif", G_GRID,
     "a DEM in the exemplars' units (a sketch, a synth output, a coarse real DEM) that the "
     "terrain follows at every level; its grid is the output's",
     "Guide", 0, NULL},
    OPT_GRID(1048576),
    OPT_SEED,
    {"jitter_levels", TSJOB_TEXT, 1, 0, 0, "J1,J2,...", G_RUN,
     "jitter per level, coarse to fine, from level 1 (levels past the list take its last "
     "value), in spacings 0..2; instead of the one jitter",
     "JitterLevels", 0, NULL},
    {"output", TSJOB_OUTPUT, 1, 0, 0, "OUTPUT", G_OUT,
     "the terrain: a Float32 DEM on the target grid, nodata " TSIO_NODATA_TEXT, NULL, 1, NULL},
    OPT_PREVIEW,
    OPT_FLOW,
    {"debug_dir", TSJOB_OUTPUT, 1, 0, 0, "DIR", G_OUT,
     "source_exemplar.tif, source_x.tif, source_y.tif: where each cell's finest coordinate "
     "points (the candidate exemplar: index x variants + the variant; the cell in it)",
     NULL, 0, NULL},
    OPT_RECIPE,
};

static const tsjob_rule pixel_rules[] = {
    {TSJOB_EXCLUDES,
     "guide",
     {"like", "size", "origin", "resolution", "crs", NULL},
     "a guide sets the output grid: give no %s"},
    {TSJOB_EXCLUDES,
     "like",
     {"size", "origin", "resolution", "crs", NULL},
     "like sets the output grid: give no %s"},
    {TSJOB_ONE_OF, "guide", {"like", "size", NULL}, "give the target grid: a guide, like or size"},
    {TSJOB_REQUIRES, "guide_weight", {"guide", NULL}, "guide_weight weighs a guide: give guide"},
    {TSJOB_EXCLUDES, "jitter_levels", {"jitter", NULL}, "give jitter or jitter_levels, not both"},
    RULES_GRID_SIZE,
    {TSJOB_EXCLUDES,
     "recipe",
     {"output", "preview", "debug_dir", "flow_lines", NULL},
     "recipe writes the recipe instead of running the job: give no %s"},
    RULES_FLOW,
    {TSJOB_ONE_OF, "output", {"recipe", NULL}, "give OUTPUT (or recipe)"},
};

static const tsjob_decl jobs[] = {
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
     {"synth", "sketch", "drainage", NULL},
     "Synth"},
    {"amplify",
     amplify_opts,
     sizeof amplify_opts / sizeof amplify_opts[0],
     amplify_rules,
     sizeof amplify_rules / sizeof amplify_rules[0],
     {"amplify", "drainage", NULL},
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
     {"pixel", "drainage", NULL},
     "Pixel"},
};

const tsjob_decl *tsjob_at(size_t i)
{
    return i < sizeof jobs / sizeof jobs[0] ? &jobs[i] : NULL;
}

const tsjob_decl *tsjob_find(const char *name)
{
    size_t i;
    for (i = 0; name && i < sizeof jobs / sizeof jobs[0]; i++)
        if (!strcmp(jobs[i].name, name))
            return &jobs[i];
    return NULL;
}

const tsjob_decl *tsjob_find_element(const CPLXMLNode *top, const CPLXMLNode **node)
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

const tsjob_option *tsjob_option_find(const tsjob_decl *job, const char *name)
{
    size_t i;
    for (i = 0; job && name && i < job->n_opts; i++)
        if (!strcmp(job->opts[i].name, name))
            return &job->opts[i];
    return NULL;
}

const char *tsjob_param_stage(const tsjob_decl *job, const char *name)
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
