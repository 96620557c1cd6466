/*
 * terrasynth.c - the `terrasynth` command-line program.
 *
 *   terrasynth ppa INPUT OUTPUT [options]    ridge and valley axes (PPA)
 *
 * A thin front end: read with tsio, call the core, write with tsio.  Stage
 * parameters come from the core's descriptor tables (cli_params.c).
 * Errors are one line on stderr ("terrasynth: <file>: <problem>") and a
 * non-zero exit: 1 for a failed run, 2 for a usage error.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal.h>

#include "cli_params.h"
#include "jobspec.h"
#include "recipe.h"
#include "tsjob.h"
#include "terrasynth.h"
#include "tsio.h"

#define EXIT_RUN 1
#define EXIT_USAGE 2

/* ------------------------------------------------------------------ */
/* Progress: GDAL's terminal bar, machine-readable lines, or nothing  */
/* ------------------------------------------------------------------ */

typedef enum { PROGRESS_BAR, PROGRESS_LINES, PROGRESS_QUIET } progress_mode;

static int progress_lines(double done, const char *msg, void *user)
{
    int *last = user;
    int pct = (int)(done * 100.0);
    if (pct != *last) {
        *last = pct;
        printf("PROGRESS %d %s\n", pct, msg ? msg : "");
        fflush(stdout);
    }
    return 1;
}

static int progress_bar(double done, const char *msg, void *user)
{
    (void)user;
    (void)msg;
    return GDALTermProgress(done, NULL, NULL);
}

static void set_progress(ts_ctx *ctx, progress_mode mode, int *state)
{
    if (mode == PROGRESS_BAR)
        ts_ctx_set_progress(ctx, progress_bar, NULL);
    else if (mode == PROGRESS_LINES)
        ts_ctx_set_progress(ctx, progress_lines, state);
}

/* ------------------------------------------------------------------ */
/* Shared option handling                                             */
/* ------------------------------------------------------------------ */

typedef struct common_opts {
    const char *cmd;
    const char *format;
    char **create_options; /* CSL list */
    progress_mode progress;
    int threads;
} common_opts;

static void usage_error(const char *cmd, const char *fmt, const char *arg)
{
    fprintf(stderr, "terrasynth %s: ", cmd);
    fprintf(stderr, fmt, arg);
    fprintf(stderr, " (see 'terrasynth %s --help')\n", cmd);
}

/* Parse an option shared by every command; returns 1 if consumed, 0 if
 * not ours, -1 on error (message printed). */
static int parse_common(const char *cmd, common_opts *o, int argc, char **argv, int *i)
{
    const char *a = argv[*i];
    const char *value = *i + 1 < argc ? argv[*i + 1] : NULL;
    char *end;
    if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
        o->progress = PROGRESS_QUIET;
        return 1;
    }
    if (!strcmp(a, "--progress-lines")) {
        o->progress = PROGRESS_LINES;
        return 1;
    }
    if (!strcmp(a, "-of") || !strcmp(a, "-co") || !strcmp(a, "--threads")) {
        if (!value) {
            usage_error(cmd, "%s needs a value", a);
            return -1;
        }
        ++*i;
        if (!strcmp(a, "-of")) {
            o->format = value;
        } else if (!strcmp(a, "-co")) {
            if (!strchr(value, '=')) {
                usage_error(cmd, "-co takes KEY=VALUE, not '%s'", value);
                return -1;
            }
            o->create_options = CSLAddString(o->create_options, value);
        } else {
            long t = strtol(value, &end, 10);
            if (*end || t < 0 || t > 256) {
                usage_error(cmd, "--threads must be 0..256, not '%s'", value);
                return -1;
            }
            o->threads = (int)t;
        }
        return 1;
    }
    return 0;
}

/* tsj_parse_argv's hook for the options every command shares (they are the
 * command line's own: formats, threads, progress) */
static int skip_common(int argc, char **argv, int *i, void *user)
{
    common_opts *co = user;
    return parse_common(co->cmd, co, argc, argv, i);
}

static const char common_help[] =
    "  -of FORMAT                       GDAL output format (default: from the extension,\n"
    "                                   else GTiff)\n"
    "  -co KEY=VALUE                    creation option (repeatable)\n"
    "  --threads N                      worker threads (default 0 = all cores)\n"
    "  --progress-lines                 print 'PROGRESS <percent> <stage>' lines\n"
    "  -q, --quiet                      no progress bar or summary\n";

/* ------------------------------------------------------------------ */
/* terrasynth ppa                                                     */
/* ------------------------------------------------------------------ */

static void ppa_help(FILE *out)
{
    fprintf(out,
            "Usage: terrasynth ppa INPUT (OUTPUT | --recipe FILE.tsyn) [options]\n"
            "\n"
            "Map the ridge and valley axes of a DEM with the Profile recognition and Polygon\n"
            "breaking Algorithm (Chang, Song & Hsu 1998). OUTPUT is a Byte raster on the\n"
            "input's grid: 1 ridge, 2 valley, 3 both (a saddle on both axes), 0 none,\n"
            "255 where the input is nodata. Giving threshold sets threshold_fraction to 0\n"
            "and the other way round.\n"
            "\n");
    tsj_help(out, tsj_find("ppa"));
    fprintf(out,
            "\n"
            "Common options:\n%s"
            "\n"
            "Example:\n"
            "  terrasynth ppa dem.tif axes.tif --both --lines axes.gpkg --preview axes.png\n",
            common_help);
}

static int cmd_ppa(int argc, char **argv)
{
    common_opts co = {"ppa", NULL, NULL, PROGRESS_BAR, 0};
    const char *input = NULL, *recipe_path = NULL;
    tsjob_outputs outs = {NULL, NULL, NULL, NULL, NULL, NULL};
    int i, rc = EXIT_RUN, progress_state = -1;
    ts_ctx *ctx = ts_ctx_new();
    tsjob_ppa job;
    tsjob_ppa_result res;
    tsio_err err;
    ts_features *f = NULL;
    size_t k;
    tsj_values v;
    char msg[1024] = "";

    memset(&res, 0, sizeof res);
    tsj_values_init(&v, tsj_find("ppa"));
    if (!ctx) {
        fprintf(stderr, "terrasynth: out of memory\n");
        return EXIT_RUN;
    }
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            ppa_help(stdout);
            rc = 0;
            goto done;
        }
    if (tsj_parse_argv(&v, argc, argv, 2, skip_common, &co, msg, sizeof msg) != 0) {
        if (msg[0])
            usage_error("ppa", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    if (tsj_build_ppa(&v, &job, msg, sizeof msg) != 0) {
        usage_error("ppa", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    input = job.input;
    outs.output = tsj_get(&v, "output", 0);
    outs.lines = tsj_get(&v, "lines", 0);
    outs.preview = tsj_get(&v, "preview", 0);
    outs.format = co.format;
    outs.create_options = (const char *const *)co.create_options;
    recipe_path = tsj_get(&v, "recipe", 0);
    if (recipe_path) {
        if (recipe_write(recipe_path, &v, &err) != 0) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            goto done;
        }
        rc = 0;
        goto done;
    }
    /* the input is read and every output checked before the work starts */
    if (tsjob_ppa_prepare(&job, &res, &err) != 0 ||
        tsjob_ppa_check_outputs(&job, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (res.no_crs && co.progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: lengths are in cells\n", input);
    ts_ctx_set_threads(ctx, co.threads);
    set_progress(ctx, co.progress, &progress_state);
    if (tsjob_ppa_compute(ctx, &job, &res, &err) != 0 ||
        tsjob_ppa_write(ctx, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    f = res.features;
    if (co.progress != PROGRESS_QUIET) {
        size_t nb = 0, ne = 0, np[3] = {0, 0, 0};
        for (k = 0; k < f->n_nodes; k++) {
            if (f->nodes[k].degree == 1) ne++;
            else nb++;
        }
        for (k = 0; k < f->n_paths; k++)
            np[f->paths[k].kind]++;
        printf("ppa: %zu ridge paths, %zu valley paths, %zu branch points, %zu endpoints "
               "(threshold %.3g m)\n",
               np[TS_RIDGE], np[TS_VALLEY], nb, ne, f->threshold_used);
    }
    rc = 0;
done:
    tsjob_ppa_result_free(&res);
    tsj_values_free(&v);
    CSLDestroy(co.create_options);
    ts_ctx_free(ctx);
    return rc;
}


/* ------------------------------------------------------------------ */
/* terrasynth synth                                                   */
/* ------------------------------------------------------------------ */

static void synth_help(FILE *out)
{
    fprintf(out,
            "Usage: terrasynth synth --exemplar EX.tif [--exemplar EX2.tif ...]\n"
            "                        (--sketch SK.tif | --like GRID.tif | --size WxH [--origin X,Y]\n"
            "                         [--resolution R] [--crs CRS]) [options] OUTPUT\n"
            "\n"
            "Grow a new terrain of any size from real DEMs by non-feature patch synthesis\n"
            "(Zhou et al. 2007 section 4.2 and 5): patches matched by FFT masked SSD, cut in\n"
            "with graph-cut seams and smoothed with Poisson seam removal. OUTPUT is a Float32\n"
            "DEM on the target grid with its CRS, geotransform and nodata (-9999).\n"
            "Exemplars are resampled to the target's ground resolution when it differs.\n"
            "\n"
            "With --sketch, the terrain follows a drawing: bright strokes are ridges, dark\n"
            "strokes valleys (Zhou et al. 2007 sections 3-4: feature patches matched along the\n"
            "sketch's feature tree with thin-plate-spline warps, then the fill above, then\n"
            "the layout stage, a TerraSynth addition).\n"
            "\n");
    tsj_help(out, tsj_find("synth"));
    fprintf(out,
            "\n"
            "Common options:\n%s"
            "\n"
            "Example:\n"
            "  terrasynth synth --exemplar dem.tif --size 1024x1024 --seed 7 new.tif "
            "--preview new.png\n",
            common_help);
}

static int cmd_synth(int argc, char **argv)
{
    common_opts co = {"synth", NULL, NULL, PROGRESS_BAR, 0};
    const char *recipe_path = NULL;
    tsjob_outputs outs = {NULL, NULL, NULL, NULL, NULL, NULL};
    int i, rc = EXIT_RUN, progress_state = -1;
    uint64_t seed = 0;
    tsjob_synth job;
    tsjob_synth_result res;
    tsio_err err;
    ts_ctx *ctx = ts_ctx_new();
    tsj_values v;
    char msg[1024] = "";

    tsj_values_init(&v, tsj_find("synth"));
    memset(&job, 0, sizeof job);
    memset(&res, 0, sizeof res);
    if (!ctx) {
        fprintf(stderr, "terrasynth: out of memory\n");
        return EXIT_RUN;
    }
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            synth_help(stdout);
            rc = 0;
            goto done;
        }
    if (tsj_parse_argv(&v, argc, argv, 2, skip_common, &co, msg, sizeof msg) != 0) {
        if (msg[0])
            usage_error("synth", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    if (tsj_build_synth(&v, &job, &seed, msg, sizeof msg) != 0) {
        usage_error("synth", "%s", msg);
        rc = EXIT_USAGE;
        goto done;
    }
    outs.output = tsj_get(&v, "output", 0);
    outs.preview = tsj_get(&v, "preview", 0);
    outs.debug_dir = tsj_get(&v, "debug_dir", 0);
    outs.format = co.format;
    outs.create_options = (const char *const *)co.create_options;
    recipe_path = tsj_get(&v, "recipe", 0);
    if (recipe_path) {
        if (recipe_write(recipe_path, &v, &err) != 0) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            goto done;
        }
        rc = 0;
        goto done;
    }
    /* the grid is resolved and every output checked before the work */
    if (tsjob_synth_prepare(&job, &res, &err) != 0 ||
        tsjob_synth_check_outputs(&job, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (!res.dx_m && co.progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: the target grid has no CRS: exemplars are used "
                        "cell for cell\n");
    ts_ctx_set_seed(ctx, seed);
    ts_ctx_set_threads(ctx, co.threads);
    set_progress(ctx, co.progress, &progress_state);
    if (tsjob_synth_compute(ctx, &job, &res, outs.debug_dir != NULL, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (job.sketch && co.progress != PROGRESS_QUIET)
        printf("sketch: %s, %zu feature sites, %zu feature patches placed (from %zu exemplar "
               "sites)\n",
               res.sketch_info.mode == TS_SKETCH_VALLEYS ? "valleys" : "ridges",
               res.sketch_info.n_sites, res.sketch_info.n_feature_patches,
               res.sketch_info.n_exemplar_sites);
    if (job.sketch && res.sketch_info.n_sites > 0 && res.sketch_info.n_exemplar_sites == 0)
        fprintf(stderr, "terrasynth: warning: the exemplars have no main %s to draw the sketch "
                        "with: the output does not follow it\n",
                res.sketch_info.mode == TS_SKETCH_VALLEYS ? "valleys" : "ridges");
    ts_ctx_set_progress(ctx, NULL, NULL);
    if (res.exemplar_no_crs && co.progress != PROGRESS_QUIET)
        fprintf(stderr, "terrasynth: warning: %s has no CRS: used cell for cell\n",
                job.exemplars[res.exemplar_no_crs - 1]);
    if (tsjob_synth_write(ctx, &job, &res, &outs, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    rc = 0;
done:
    tsjob_synth_result_free(&res);
    tsj_values_free(&v);
    CSLDestroy(co.create_options);
    ts_ctx_free(ctx);
    return rc;
}


/* ------------------------------------------------------------------ */
/* terrasynth describe: the descriptor tables as JSON, for front ends  */
/* ------------------------------------------------------------------ */

static void json_string(FILE *out, const char *s)
{
    fputc('"', out);
    for (; s && *s; s++) {
        if (*s == '"' || *s == '\\')
            fprintf(out, "\\%c", *s);
        else if ((unsigned char)*s < 0x20)
            fprintf(out, "\\u%04x", (unsigned char)*s);
        else
            fputc(*s, out);
    }
    fputc('"', out);
}

static int cmd_describe(int argc, char **argv)
{
    const char *const *stages = ts_params_stages();
    int i, first = 1;
    if (argc > 2 && (!strcmp(argv[2], "-h") || !strcmp(argv[2], "--help"))) {
        printf("Usage: terrasynth describe [STAGE]\n\n"
               "Print the parameters of every stage (or one) as JSON: name, CLI flag, type,\n"
               "default, range, units, choices and help; and every job's options (inputs,\n"
               "target grid, constraints, outputs) and the rules between them. Front ends\n"
               "(QGIS) read it.\n");
        return 0;
    }
    if (argc > 2) {
        size_t n;
        if (!ts_params_describe(argv[2], &n)) {
            fprintf(stderr, "terrasynth describe: unknown stage '%s'\n", argv[2]);
            return EXIT_USAGE;
        }
    }
    printf("{\n  \"version\": \"%s\",\n  \"stages\": {", ts_version());
    for (i = 0; stages[i]; i++) {
        size_t n, k;
        const ts_param_desc *d = ts_params_describe(stages[i], &n);
        if (argc > 2 && strcmp(argv[2], stages[i]) != 0)
            continue;
        printf("%s\n    \"%s\": [", first ? "" : ",", stages[i]);
        first = 0;
        for (k = 0; k < n; k++) {
            static const char *const types[] = {"int", "double", "enum", "length"};
            char flag[128];
            size_t j = 2;
            const char *c;
            flag[0] = flag[1] = '-';
            for (c = d[k].name; *c && j + 1 < sizeof flag; c++)
                flag[j++] = *c == '_' ? '-' : *c;
            flag[j] = '\0';
            printf("%s\n      {\"name\": \"%s\", \"flag\": \"%s\", \"type\": \"%s\", ", k ? "," : "",
                   d[k].name, flag, types[d[k].type]);
            printf("\"default\": %.17g, \"min\": %.17g, \"max\": %.17g, ", d[k].def, d[k].min,
                   d[k].max);
            if (d[k].type == TS_PARAM_LENGTH)
                printf("\"default_unit\": \"%s\", ", d[k].def_unit ? "m" : "cells");
            printf("\"units\": ");
            json_string(stdout, d[k].units);
            printf(", \"choices\": ");
            if (d[k].choices) {
                const char *w = d[k].choices;
                printf("[");
                while (*w) {
                    const char *bar = strchr(w, '|');
                    size_t len = bar ? (size_t)(bar - w) : strlen(w);
                    printf("\"%.*s\"%s", (int)len, w, bar ? ", " : "");
                    if (!bar)
                        break;
                    w = bar + 1;
                }
                printf("]");
            } else {
                printf("null");
            }
            printf(", \"help\": ");
            json_string(stdout, d[k].help);
            printf("}");
        }
        printf("\n    ]");
    }
    printf("\n  },\n");
    tsj_describe(stdout);
    printf("\n}\n");
    return 0;
}

/* ------------------------------------------------------------------ */

static void main_help(FILE *out)
{
    fprintf(out,
            "Usage: terrasynth COMMAND [options]\n"
            "\n"
            "TerraSynth %s: terrain synthesis from real DEMs.\n"
            "\n"
            "Commands:\n"
            "  ppa        map ridge and valley axes of a DEM (raster, vector lines, preview)\n"
            "  synth      grow a new terrain from real DEMs, free or following a sketch\n"
            "  describe   print every stage's parameters as JSON (for front ends)\n"
            "\n"
            "'terrasynth COMMAND --help' lists a command's options with defaults and units.\n"
            "  --version  print the version\n",
            ts_version());
}

int main(int argc, char **argv)
{
    int rc;
    if (argc < 2) {
        main_help(stderr);
        return EXIT_USAGE;
    }
    if (!strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) {
        main_help(stdout);
        return 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("terrasynth %s (GDAL %s)\n", ts_version(), GDALVersionInfo("RELEASE_NAME"));
        return 0;
    }
    GDALAllRegister();
    if (!strcmp(argv[1], "ppa"))
        rc = cmd_ppa(argc, argv);
    else if (!strcmp(argv[1], "synth"))
        rc = cmd_synth(argc, argv);
    else if (!strcmp(argv[1], "describe"))
        rc = cmd_describe(argc, argv);
    else {
        fprintf(stderr, "terrasynth: unknown command '%s' (see 'terrasynth --help')\n", argv[1]);
        rc = EXIT_USAGE;
    }
    GDALDestroyDriverManager();
    return rc;
}
