/*
 * fuzz_recipe.c - libFuzzer target for the recipe parser: any bytes as a
 * recipe file must give a recipe or a clean error, never a crash, leak or
 * undefined behaviour.  Inputs named in the bytes resolve relative to
 * /vsimem/fuzz/, where a tiny DEM is placed so that valid recipes get far.
 *
 * Build: tools/fuzz.sh (clang -fsanitize=fuzzer,address,undefined).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cpl_conv.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include "recipe.h"

static void fuzz_setup(void)
{
    static int done;
    GDALDatasetH ds;
    OGRSpatialReferenceH srs;
    char *wkt = NULL;
    float z[16 * 16];
    double gt[6] = {500000, 30, 0, 4000000, 0, -30};
    int i;
    if (done)
        return;
    done = 1;
    GDALAllRegister();
    CPLSetConfigOption("CPL_LOG", "/dev/null");
    ds = GDALCreate(GDALGetDriverByName("GTiff"), "/vsimem/fuzz/dem.tif", 16, 16, 1,
                    GDT_Float32, NULL);
    for (i = 0; i < 16 * 16; i++)
        z[i] = (float)(100 + (i * 37) % 50);
    GDALSetGeoTransform(ds, gt);
    srs = OSRNewSpatialReference(NULL);
    OSRImportFromEPSG(srs, 32633);
    OSRExportToWkt(srs, &wkt);
    GDALSetProjection(ds, wkt);
    CPLFree(wkt);
    OSRDestroySpatialReference(srs);
    if (GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Write, 0, 0, 16, 16, z, 16, 16, GDT_Float32,
                     0, 0) != CE_None)
        abort();
    GDALClose(ds);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    tsrecipe *r = NULL;
    tsio_err err;
    VSILFILE *fp;
    fuzz_setup();
    fp = VSIFileFromMemBuffer("/vsimem/fuzz/r.tsyn", (GByte *)data, (vsi_l_offset)size, FALSE);
    if (!fp)
        return 0;
    VSIFCloseL(fp);
    CPLPushErrorHandler(CPLQuietErrorHandler);
    if (tsrecipe_open("/vsimem/fuzz/r.tsyn", NULL, &r, &err) == 0) {
        const tsio_georef *g = tsrecipe_georef(r);
        /* compute only what is cheap: small ppa grids */
        if (tsrecipe_gdal_type(r) == GDT_Byte && (size_t)g->width * (size_t)g->height <= 4096)
            tsrecipe_compute(r, &err);
        tsrecipe_free(r);
    }
    CPLPopErrorHandler();
    VSIUnlink("/vsimem/fuzz/r.tsyn");
    return 0;
}
