/*
 * pixfun.c - VRT pixel functions of the TSYN plugin.  Each one converts
 * GDAL's buffers to float (source nodata -> NaN), calls a kernel of the
 * core (pixel_ops.c) and writes back (NaN -> nodata).  GDAL 3.6 enforces
 * neither `mandatory` nor `default`, so every function checks its own
 * arguments and fails with a message naming the function.
 *
 *   tsyn_blend    sources t1..tn, w1..wn: weighted mean of the terrains
 *   tsyn_rescale  from_min, from_max, to_min, to_max: linear map
 *   tsyn_units    from, to in m | ft | ftUS: unit conversion
 *   tsyn_water    level, mode = fill | depth | mask
 * All take an optional nodata argument (the sources' nodata and the value
 * written for NaN results).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_string.h>
#include <gdal.h>

#include "pixfun.h"
#include "terrasynth.h"

typedef struct pix_buf {
    size_t n;
    int has_nodata;
    double nodata;
} pix_buf;

/* Source k of the call as floats; NaN where nodata.  Caller frees. */
static float *pix_source(void **sources, int k, GDALDataType type, const pix_buf *b)
{
    float *f = malloc(b->n * sizeof *f);
    size_t i;
    if (!f)
        return NULL;
    GDALCopyWords64(sources[k], type, GDALGetDataTypeSizeBytes(type), f, GDT_Float32,
                    (int)sizeof(float), (GPtrDiff_t)b->n);
    if (b->has_nodata)
        for (i = 0; i < b->n; i++)
            if (f[i] == (float)b->nodata)
                f[i] = NAN;
    return f;
}

static void pix_write(const float *f, const pix_buf *b, void *data, int width, int height,
                      GDALDataType buf_type, int pixel_space, int line_space)
{
    int x, y;
    for (y = 0; y < height; y++)
        for (x = 0; x < width; x++) {
            double v = f[(size_t)y * (size_t)width + (size_t)x];
            if (isnan(v) && b->has_nodata)
                v = b->nodata;
            GDALCopyWords(&v, GDT_Float64, 0,
                          (GByte *)data + (GPtrDiff_t)line_space * y + (GPtrDiff_t)pixel_space * x,
                          buf_type, pixel_space, 1);
        }
}

static int pix_number(CSLConstList args, const char *fn, const char *name, int mandatory,
                      double *out)
{
    const char *v = CSLFetchNameValue(args, name);
    char *end;
    if (!v) {
        if (mandatory)
            CPLError(CE_Failure, CPLE_AppDefined, "%s: the argument %s is missing", fn, name);
        return mandatory ? -1 : 0;
    }
    *out = CPLStrtod(v, &end);
    if (end == v || *end || !isfinite(*out)) {
        CPLError(CE_Failure, CPLE_AppDefined, "%s: %s='%s' is not a number", fn, name, v);
        return -1;
    }
    return 1;
}

static int pix_common(CSLConstList args, const char *fn, int width, int height, pix_buf *b)
{
    int r;
    b->n = (size_t)width * (size_t)height;
    b->has_nodata = 0;
    b->nodata = 0.0;
    r = pix_number(args, fn, "nodata", 0, &b->nodata);
    if (r < 0)
        return -1;
    b->has_nodata = r == 1;
    return 0;
}

static CPLErr pix_blend(void **sources, int n_sources, void *data, int width, int height,
                        GDALDataType src_type, GDALDataType buf_type, int pixel_space,
                        int line_space, CSLConstList args)
{
    pix_buf b;
    float **t = NULL, *out = NULL;
    int k, terms = n_sources / 2;
    CPLErr rc = CE_Failure;
    if (pix_common(args, "tsyn_blend", width, height, &b) != 0)
        return CE_Failure;
    if (n_sources < 2 || n_sources % 2) {
        CPLError(CE_Failure, CPLE_AppDefined,
                 "tsyn_blend: needs terrains then as many weight bands (an even number of "
                 "sources), got %d",
                 n_sources);
        return CE_Failure;
    }
    t = calloc((size_t)n_sources, sizeof *t);
    out = malloc(b.n * sizeof *out);
    if (!t || !out)
        goto done;
    for (k = 0; k < n_sources; k++) {
        /* weights have no nodata */
        pix_buf wb = b;
        if (k >= terms)
            wb.has_nodata = 0;
        if (!(t[k] = pix_source(sources, k, src_type, &wb)))
            goto done;
    }
    ts_blend_weighted(b.n, terms, (const float *const *)t, (const float *const *)(t + terms), out);
    pix_write(out, &b, data, width, height, buf_type, pixel_space, line_space);
    rc = CE_None;
done:
    if (rc != CE_None)
        CPLError(CE_Failure, CPLE_OutOfMemory, "tsyn_blend: out of memory");
    for (k = 0; t && k < n_sources; k++)
        free(t[k]);
    free(t);
    free(out);
    return rc;
}

/* One source through a unary kernel. */
typedef void (*pix_unary)(size_t n, const float *in, const double *a, float *out);

static CPLErr pix_run_unary(const char *fn, void **sources, int n_sources, void *data, int width,
                            int height, GDALDataType src_type, GDALDataType buf_type,
                            int pixel_space, int line_space, const pix_buf *b, pix_unary op,
                            const double *a)
{
    float *in, *out;
    if (n_sources != 1) {
        CPLError(CE_Failure, CPLE_AppDefined, "%s: needs exactly 1 source, got %d", fn, n_sources);
        return CE_Failure;
    }
    in = pix_source(sources, 0, src_type, b);
    out = malloc(b->n * sizeof *out);
    if (!in || !out) {
        free(in);
        free(out);
        CPLError(CE_Failure, CPLE_OutOfMemory, "%s: out of memory", fn);
        return CE_Failure;
    }
    op(b->n, in, a, out);
    pix_write(out, b, data, width, height, buf_type, pixel_space, line_space);
    free(in);
    free(out);
    return CE_None;
}

static void op_rescale(size_t n, const float *in, const double *a, float *out)
{
    ts_rescale_linear(n, in, a[0], a[1], a[2], a[3], out);
}

static void op_water(size_t n, const float *in, const double *a, float *out)
{
    ts_water_level(n, in, a[0], (int)a[1], out);
}

static CPLErr pix_rescale(void **sources, int n_sources, void *data, int width, int height,
                          GDALDataType src_type, GDALDataType buf_type, int pixel_space,
                          int line_space, CSLConstList args)
{
    static const char *const names[4] = {"from_min", "from_max", "to_min", "to_max"};
    double a[4];
    pix_buf b;
    int i;
    if (pix_common(args, "tsyn_rescale", width, height, &b) != 0)
        return CE_Failure;
    for (i = 0; i < 4; i++)
        if (pix_number(args, "tsyn_rescale", names[i], 1, &a[i]) < 0)
            return CE_Failure;
    if (a[0] == a[1]) {
        CPLError(CE_Failure, CPLE_AppDefined, "tsyn_rescale: from_min equals from_max");
        return CE_Failure;
    }
    return pix_run_unary("tsyn_rescale", sources, n_sources, data, width, height, src_type,
                         buf_type, pixel_space, line_space, &b, op_rescale, a);
}

static int pix_unit(const char *v, double *metres)
{
    if (!v)
        return -1;
    if (!strcmp(v, "m"))
        *metres = 1.0;
    else if (!strcmp(v, "ft"))
        *metres = 0.3048;
    else if (!strcmp(v, "ftUS"))
        *metres = 1200.0 / 3937.0;
    else
        return -1;
    return 0;
}

static CPLErr pix_units(void **sources, int n_sources, void *data, int width, int height,
                        GDALDataType src_type, GDALDataType buf_type, int pixel_space,
                        int line_space, CSLConstList args)
{
    const char *from = CSLFetchNameValue(args, "from"), *to = CSLFetchNameValue(args, "to");
    double mf, mt, a[4];
    pix_buf b;
    if (pix_common(args, "tsyn_units", width, height, &b) != 0)
        return CE_Failure;
    if (pix_unit(from, &mf) || pix_unit(to, &mt)) {
        CPLError(CE_Failure, CPLE_AppDefined,
                 "tsyn_units: from and to must each be m, ft or ftUS (got from='%s' to='%s')",
                 from ? from : "", to ? to : "");
        return CE_Failure;
    }
    a[0] = 0.0;
    a[1] = 1.0;
    a[2] = 0.0;
    a[3] = mf / mt;
    return pix_run_unary("tsyn_units", sources, n_sources, data, width, height, src_type, buf_type,
                         pixel_space, line_space, &b, op_rescale, a);
}

static CPLErr pix_water(void **sources, int n_sources, void *data, int width, int height,
                        GDALDataType src_type, GDALDataType buf_type, int pixel_space,
                        int line_space, CSLConstList args)
{
    const char *mode = CSLFetchNameValue(args, "mode");
    double a[2];
    pix_buf b;
    if (pix_common(args, "tsyn_water", width, height, &b) != 0 ||
        pix_number(args, "tsyn_water", "level", 1, &a[0]) < 0)
        return CE_Failure;
    if (!mode || !strcmp(mode, "fill"))
        a[1] = TS_WATER_FILL;
    else if (!strcmp(mode, "depth"))
        a[1] = TS_WATER_DEPTH;
    else if (!strcmp(mode, "mask"))
        a[1] = TS_WATER_MASK;
    else {
        CPLError(CE_Failure, CPLE_AppDefined, "tsyn_water: mode='%s' is not fill, depth or mask",
                 mode);
        return CE_Failure;
    }
    return pix_run_unary("tsyn_water", sources, n_sources, data, width, height, src_type, buf_type,
                         pixel_space, line_space, &b, op_water, a);
}

void tsyn_register_pixel_functions(void)
{
    GDALAddDerivedBandPixelFuncWithArgs(
        "tsyn_blend", pix_blend,
        "<PixelFunctionArgumentsList>"
        "<Argument name='nodata' description='nodata of the terrains and of the result' "
        "type='double'/></PixelFunctionArgumentsList>");
    GDALAddDerivedBandPixelFuncWithArgs(
        "tsyn_rescale", pix_rescale,
        "<PixelFunctionArgumentsList>"
        "<Argument name='from_min' type='double' mandatory='1'/>"
        "<Argument name='from_max' type='double' mandatory='1'/>"
        "<Argument name='to_min' type='double' mandatory='1'/>"
        "<Argument name='to_max' type='double' mandatory='1'/>"
        "<Argument name='nodata' type='double'/></PixelFunctionArgumentsList>");
    GDALAddDerivedBandPixelFuncWithArgs(
        "tsyn_units", pix_units,
        "<PixelFunctionArgumentsList>"
        "<Argument name='from' type='string' mandatory='1' description='m, ft or ftUS'/>"
        "<Argument name='to' type='string' mandatory='1' description='m, ft or ftUS'/>"
        "<Argument name='nodata' type='double'/></PixelFunctionArgumentsList>");
    GDALAddDerivedBandPixelFuncWithArgs(
        "tsyn_water", pix_water,
        "<PixelFunctionArgumentsList>"
        "<Argument name='level' type='double' mandatory='1'/>"
        "<Argument name='mode' type='string' default='fill' description='fill, depth or mask'/>"
        "<Argument name='nodata' type='double'/></PixelFunctionArgumentsList>");
}
