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
    const char *format;
    char **create_options; /* CSL list */
    progress_mode progress;
    int threads;
    double cell_size; /* > 0: ground size of a cell of a CRS-less raster, metres */
    int band;
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
    if (!strcmp(a, "-of") || !strcmp(a, "-co") || !strcmp(a, "--threads") ||
        !strcmp(a, "--cell-size") || !strcmp(a, "--band")) {
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
        } else if (!strcmp(a, "--threads")) {
            long t = strtol(value, &end, 10);
            if (*end || t < 0 || t > 256) {
                usage_error(cmd, "--threads must be 0..256, not '%s'", value);
                return -1;
            }
            o->threads = (int)t;
        } else if (!strcmp(a, "--band")) {
            long b = strtol(value, &end, 10);
            if (*end || b < 1 || b > 65535) {
                usage_error(cmd, "--band must be a band number, not '%s'", value);
                return -1;
            }
            o->band = (int)b;
        } else {
            double c = strtod(value, &end);
            if (*end || !(c > 0) || c > 1e7) {
                usage_error(cmd, "--cell-size must be a positive number of metres, not '%s'",
                            value);
                return -1;
            }
            o->cell_size = c;
        }
        return 1;
    }
    return 0;
}

static const char common_help[] =
    "  --band N                         input band (default 1)\n"
    "  --cell-size M                    ground size of a cell in metres, for a raster with\n"
    "                                   no CRS (otherwise lengths are in cells)\n"
    "  -of FORMAT                       GDAL output format (default: from the extension,\n"
    "                                   else GTiff)\n"
    "  -co KEY=VALUE                    creation option (repeatable)\n"
    "  --threads N                      worker threads (default 0 = all cores)\n"
    "  --progress-lines                 print 'PROGRESS <percent> <stage>' lines\n"
    "  -q, --quiet                      no progress bar or summary\n";

/* Ground metrics for a raster without CRS when --cell-size is given. */
static int fill_cell_size(tsio_raster *in, double cell_size)
{
    int y;
    if (in->dx_m || cell_size <= 0)
        return 0;
    in->dx_m = malloc((size_t)in->geo.height * sizeof *in->dx_m);
    in->dy_m = malloc((size_t)in->geo.height * sizeof *in->dy_m);
    if (!in->dx_m || !in->dy_m)
        return -1;
    for (y = 0; y < in->geo.height; y++)
        in->dx_m[y] = in->dy_m[y] = cell_size;
    return 0;
}

/* ------------------------------------------------------------------ */
/* terrasynth ppa                                                     */
/* ------------------------------------------------------------------ */

static void ppa_help(FILE *out)
{
    static const char *const skip[] = {"features", NULL};
    fprintf(out,
            "Usage: terrasynth ppa INPUT OUTPUT [options]\n"
            "\n"
            "Map the ridge and valley axes of a DEM with the Profile recognition and Polygon\n"
            "breaking Algorithm (Chang, Song & Hsu 1998). OUTPUT is a Byte raster on the\n"
            "input's grid: 1 ridge, 2 valley, 3 both (a saddle on both axes), 0 none,\n"
            "255 where the input is nodata.\n"
            "\n"
            "Features:\n"
            "  --ridges | --valleys | --both    which axes to map (default --ridges)\n"
            "\n"
            "PPA parameters:\n");
    cli_params_help(out, "ppa", skip);
    fprintf(out,
            "  (--threshold and --threshold-fraction exclude each other; giving one sets the\n"
            "   other to 0)\n"
            "\n"
            "Outputs:\n"
            "  --lines FILE                     vector axes: layer 'paths' (LineString per path)\n"
            "                                   and layer 'nodes' (endpoints, branch points);\n"
            "                                   format from the extension (.gpkg, .shp, .geojson)\n"
            "  --preview FILE.png               hillshade with ridges (red) and valleys (blue)\n"
            "\n"
            "Common options:\n%s"
            "\n"
            "Example:\n"
            "  terrasynth ppa dem.tif axes.tif --both --lines axes.gpkg --preview axes.png\n",
            common_help);
}

static int cmd_ppa(int argc, char **argv)
{
    ts_ppa_params p = ts_ppa_params_default();
    common_opts co = {NULL, NULL, PROGRESS_BAR, 0, 0.0, 1};
    const char *input = NULL, *output = NULL, *lines = NULL, *preview = NULL;
    int i, rc = EXIT_RUN, seen_threshold = 0, seen_fraction = 0, progress_state = -1;
    ts_ctx *ctx = ts_ctx_new();
    tsio_raster in;
    tsio_err err;
    ts_features *f = NULL;
    unsigned char *bytes = NULL, *rgb = NULL;
    ts_grid_metrics mstore;
    const ts_grid_metrics *metrics;
    tsio_write_opts wo;
    ts_status st;
    size_t n, k;

    memset(&in, 0, sizeof in);
    if (!ctx) {
        fprintf(stderr, "terrasynth: out of memory\n");
        return EXIT_RUN;
    }
    for (i = 2; i < argc; i++) {
        const char *a = argv[i];
        int r;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            ppa_help(stdout);
            rc = 0;
            goto done;
        }
        if (!strcmp(a, "--ridges")) { p.features = TS_PPA_RIDGES; continue; }
        if (!strcmp(a, "--valleys")) { p.features = TS_PPA_VALLEYS; continue; }
        if (!strcmp(a, "--both")) { p.features = TS_PPA_BOTH; continue; }
        if (!strcmp(a, "--lines") || !strcmp(a, "--preview")) {
            if (i + 1 >= argc) {
                usage_error("ppa", "%s needs a file name", a);
                rc = EXIT_USAGE;
                goto done;
            }
            if (!strcmp(a, "--lines"))
                lines = argv[++i];
            else
                preview = argv[++i];
            continue;
        }
        if ((r = parse_common("ppa", &co, argc, argv, &i)) != 0) {
            if (r < 0) {
                rc = EXIT_USAGE;
                goto done;
            }
            continue;
        }
        if (!strncmp(a, "--threshold-fraction", 20))
            seen_fraction = 1;
        else if (!strncmp(a, "--threshold", 11))
            seen_threshold = 1;
        if ((r = cli_params_parse(ctx, "ppa", &p, argc, argv, &i)) != 0) {
            if (r < 0) {
                fprintf(stderr, "terrasynth ppa: %s\n", ts_ctx_message(ctx));
                rc = EXIT_USAGE;
                goto done;
            }
            continue;
        }
        if (a[0] == '-' && a[1] != '\0') {
            usage_error("ppa", "unknown option '%s'", a);
            rc = EXIT_USAGE;
            goto done;
        }
        if (!input)
            input = a;
        else if (!output)
            output = a;
        else {
            usage_error("ppa", "unexpected argument '%s'", a);
            rc = EXIT_USAGE;
            goto done;
        }
    }
    if (!input || !output) {
        usage_error("ppa", "%s", "needs INPUT and OUTPUT");
        rc = EXIT_USAGE;
        goto done;
    }
    if (seen_threshold && seen_fraction) {
        usage_error("ppa", "%s", "give --threshold or --threshold-fraction, not both");
        rc = EXIT_USAGE;
        goto done;
    }
    if (seen_threshold)
        p.threshold_fraction = 0.0;
    if (seen_fraction)
        p.threshold = 0.0;
    if (!strcmp(input, output) || (lines && !strcmp(lines, input)) ||
        (preview && !strcmp(preview, input))) {
        fprintf(stderr, "terrasynth: %s: an output would overwrite the input\n", input);
        goto done;
    }
    if (tsio_read_raster(input, co.band, &in, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (fill_cell_size(&in, co.cell_size) != 0) {
        fprintf(stderr, "terrasynth: out of memory\n");
        goto done;
    }
    if (!in.dx_m) {
        if (p.min_branch_length.unit == TS_UNIT_METRES) {
            fprintf(stderr,
                    "terrasynth: %s: has no CRS, so --min-branch-length must be in cells "
                    "(or give --cell-size)\n",
                    input);
            goto done;
        }
        if (co.progress != PROGRESS_QUIET)
            fprintf(stderr, "terrasynth: warning: %s has no CRS: lengths are in cells\n", input);
    }
    metrics = tsio_metrics(&in, &mstore);

    /* every output is checked before the work starts */
    memset(&wo, 0, sizeof wo);
    wo.format = co.format;
    wo.create_options = (const char *const *)co.create_options;
    wo.check_only = 1;
    {
        unsigned char probe = 0;
        tsio_write_opts png = {"PNG", NULL, 1};
        if (tsio_write_byte(output, &wo, &in.geo, &probe, 255, &err) != 0 ||
            (lines && tsio_check_vector_output(lines, &err) != 0) ||
            (preview && tsio_write_byte(preview, &png, &in.geo, &probe, -1, &err) != 0)) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            goto done;
        }
    }
    wo.check_only = 0;

    ts_ctx_set_threads(ctx, co.threads);
    set_progress(ctx, co.progress, &progress_state);
    st = ts_ppa_extract(ctx, &in.r, metrics, &p, &f);
    if (st != TS_OK) {
        fprintf(stderr, "terrasynth: %s: %s\n", input, ts_ctx_message(ctx));
        goto done;
    }

    /* the feature raster */
    n = (size_t)in.geo.width * (size_t)in.geo.height;
    bytes = malloc(n);
    if (!bytes) {
        fprintf(stderr, "terrasynth: out of memory\n");
        goto done;
    }
    for (k = 0; k < n; k++) {
        size_t y = k / (size_t)in.geo.width, x = k % (size_t)in.geo.width;
        bytes[k] = isnan(in.r.data[(ptrdiff_t)y * in.r.stride + (ptrdiff_t)x]) ? 255 : f->mask[k];
    }
    if (tsio_write_byte(output, &wo, &in.geo, bytes, 255, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (lines && tsio_write_features(lines, &in.geo, f, metrics, &err) != 0) {
        fprintf(stderr, "terrasynth: %s\n", err.msg);
        goto done;
    }
    if (preview) {
        /* a CRS-less raster is shaded with its geotransform's pixel size,
         * which is the best guess at its ground units */
        ts_grid_metrics pm;
        const ts_grid_metrics *shade_m = metrics;
        double *rowdx = NULL, *rowdy = NULL;
        int y;
        if (!shade_m && in.geo.has_gt) {
            rowdx = malloc((size_t)in.geo.height * sizeof *rowdx);
            rowdy = malloc((size_t)in.geo.height * sizeof *rowdy);
            if (rowdx && rowdy) {
                for (y = 0; y < in.geo.height; y++) {
                    rowdx[y] = fabs(in.geo.gt[1]);
                    rowdy[y] = fabs(in.geo.gt[5]);
                }
                pm.dx = rowdx;
                pm.dy = rowdy;
                shade_m = &pm;
            }
        }
        rgb = malloc(3 * n);
        st = rgb ? ts_render_preview(ctx, &in.r, shade_m, f, rgb) : TS_ERR_NOMEM;
        free(rowdx);
        free(rowdy);
        if (st != TS_OK) {
            fprintf(stderr, "terrasynth: %s: %s\n", preview,
                    rgb ? ts_ctx_message(ctx) : "out of memory");
            goto done;
        }
        if (tsio_write_png_rgb(preview, in.geo.width, in.geo.height, rgb, &err) != 0) {
            fprintf(stderr, "terrasynth: %s\n", err.msg);
            goto done;
        }
    }
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
    free(bytes);
    free(rgb);
    ts_features_free(f);
    tsio_raster_free(&in);
    CSLDestroy(co.create_options);
    ts_ctx_free(ctx);
    return rc;
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
    else {
        fprintf(stderr, "terrasynth: unknown command '%s' (see 'terrasynth --help')\n", argv[1]);
        rc = EXIT_USAGE;
    }
    GDALDestroyDriverManager();
    return rc;
}
