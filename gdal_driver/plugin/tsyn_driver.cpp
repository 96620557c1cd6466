/*
 * tsyn_driver.cpp - the TSYN GDAL driver: the thin C++ shim GDAL's driver
 * API requires (GDAL 3.6 has no C hook for Open/Identify).  Everything else
 * is C: recipe.c parses and computes, pixfun.c holds the VRT pixel
 * functions.  A recipe is computed once, on the first block read, under a
 * mutex, and served block by block from that cache; a lazy one (amplify)
 * computes only what every block shares then, and each block on its own (a
 * read larger than a block in windows of up to 2048^2, each on its own).
 * Pixel and amplify recipes have overviews (recipe_overviews.c), each a
 * small dataset of its own whose blocks are made as they are read.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <algorithm>
#include <cstring>
#include <dlfcn.h>
#include <memory>
#include <vector>

#include "cpl_multiproc.h"
#include "gdal_pam.h"
#include "gdal_priv.h"
#include "ogr_spatialref.h"

#include "pixfun.h"
#include "recipe.h"

namespace
{

class TSYNOverviewDataset;

class TSYNDataset final : public GDALPamDataset
{
    friend class TSYNRasterBand;
    friend class TSYNOverviewBand;

    tsrecipe *m_recipe = nullptr;
    CPLMutex *m_mutex = nullptr;
    bool m_failed = false;
    double m_gt[6] = {0, 1, 0, 0, 0, 1};
    bool m_has_gt = false;
    OGRSpatialReference m_srs{};
    CPLStringList m_schedule; /* metadata domain "TSYN": how the recipe is made */
    std::vector<std::unique_ptr<TSYNOverviewDataset>> m_overviews;

    bool Compute();

  public:
    ~TSYNDataset() override;
    static int Identify(GDALOpenInfo *info);
    static GDALDataset *Open(GDALOpenInfo *info);
    CPLErr GetGeoTransform(double *gt) override;
    const OGRSpatialReference *GetSpatialRef() const override;
    char **GetMetadataDomainList() override;
    char **GetMetadata(const char *domain) override;
    const char *GetMetadataItem(const char *name, const char *domain) override;
};

class TSYNRasterBand final : public GDALPamRasterBand
{
  public:
    TSYNRasterBand(TSYNDataset *ds, GDALDataType type)
    {
        poDS = ds;
        nBand = 1;
        eDataType = type;
        nBlockXSize = tsrecipe_block_size(ds->m_recipe);
        nBlockYSize = nBlockXSize;
    }
    CPLErr IReadBlock(int bx, int by, void *image) override;
    CPLErr IRasterIO(GDALRWFlag rw, int x, int y, int w, int h, void *buf, int bw, int bh,
                     GDALDataType type, GSpacing ps, GSpacing ls,
                     GDALRasterIOExtraArg *extra) override;
    int GetOverviewCount() override;
    GDALRasterBand *GetOverview(int i) override;
    double GetNoDataValue(int *success) override
    {
        if (success)
            *success = TRUE;
        return tsrecipe_nodata(static_cast<TSYNDataset *>(poDS)->m_recipe);
    }
};

/* Overview i of a recipe: ceil(width / factor) x ceil(height / factor) cells,
 * blocks of 256 made as they are read. */
class TSYNOverviewBand final : public GDALRasterBand
{
    TSYNDataset *m_parent;
    int m_index;

  public:
    TSYNOverviewBand(GDALDataset *ds, TSYNDataset *parent, int index)
        : m_parent(parent), m_index(index)
    {
        poDS = ds;
        nBand = 1;
        eDataType = GDT_Float32;
        nRasterXSize = ds->GetRasterXSize();
        nRasterYSize = ds->GetRasterYSize();
        nBlockXSize = nBlockYSize = 256;
    }
    CPLErr IReadBlock(int bx, int by, void *image) override;
    double GetNoDataValue(int *success) override
    {
        return m_parent->GetRasterBand(1)->GetNoDataValue(success);
    }
};

class TSYNOverviewDataset final : public GDALDataset
{
    double m_gt[6];
    bool m_has_gt;
    const OGRSpatialReference *m_srs;

  public:
    TSYNOverviewDataset(TSYNDataset *parent, int index, int factor, const double *gt, bool has_gt,
                        const OGRSpatialReference *srs)
        : m_has_gt(has_gt), m_srs(srs)
    {
        nRasterXSize = (parent->GetRasterXSize() + factor - 1) / factor;
        nRasterYSize = (parent->GetRasterYSize() + factor - 1) / factor;
        for (int k = 0; k < 6; k++)
            m_gt[k] = gt[k] * (k == 0 || k == 3 ? 1 : factor);
        SetBand(1, new TSYNOverviewBand(this, parent, index));
    }
    CPLErr GetGeoTransform(double *gt) override
    {
        std::memcpy(gt, m_gt, sizeof m_gt);
        return m_has_gt ? CE_None : CE_Failure;
    }
    const OGRSpatialReference *GetSpatialRef() const override { return m_srs; }
};

/* Block (bx, by) of a Float32 band made by read(x0, y0, w, h, cells, err) over
 * its part inside the raster, the rest nodata. */
template <typename Read>
CPLErr ReadFloatBlock(GDALRasterBand *band, int bx, int by, void *image, Read read)
{
    int nbx = 0, nby = 0;
    band->GetBlockSize(&nbx, &nby);
    const int x0 = bx * nbx, y0 = by * nby;
    const int w = std::min(nbx, band->GetXSize() - x0);
    const int h = std::min(nby, band->GetYSize() - y0);
    std::vector<float> cells(static_cast<size_t>(w) * h);
    tsio_err err;
    if (read(x0, y0, w, h, cells.data(), &err) != 0) {
        CPLError(CE_Failure, CPLE_AppDefined, "%s", err.msg);
        return CE_Failure;
    }
    auto *dst = static_cast<float *>(image);
    std::fill(dst, dst + static_cast<size_t>(nbx) * nby, (float)TSIO_NODATA);
    for (int y = 0; y < h; y++)
        std::memcpy(dst + static_cast<size_t>(y) * nbx, cells.data() + static_cast<size_t>(y) * w,
                    static_cast<size_t>(w) * 4);
    return CE_None;
}

TSYNDataset::~TSYNDataset()
{
    FlushCache(true);
    m_overviews.clear(); /* (they read the recipe) */
    tsrecipe_free(m_recipe);
    if (m_mutex)
        CPLDestroyMutex(m_mutex);
}

int TSYNDataset::Identify(GDALOpenInfo *info)
{
    return tsrecipe_identify(info->pszFilename, info->pabyHeader, info->nHeaderBytes);
}

GDALDataset *TSYNDataset::Open(GDALOpenInfo *info)
{
    if (!Identify(info))
        return nullptr;
    if (info->eAccess == GA_Update) {
        CPLError(CE_Failure, CPLE_NotSupported, "%s: TSYN recipes are read-only",
                 info->pszFilename);
        return nullptr;
    }
    tsio_err err;
    tsrecipe *recipe = nullptr;
    if (tsrecipe_open(info->pszFilename, info->papszOpenOptions, &recipe, &err) != 0) {
        CPLError(CE_Failure, CPLE_AppDefined, "%s", err.msg);
        return nullptr;
    }
    auto *ds = new TSYNDataset();
    ds->m_recipe = recipe;
    const tsio_georef *geo = tsrecipe_georef(recipe);
    ds->nRasterXSize = geo->width;
    ds->nRasterYSize = geo->height;
    ds->m_has_gt = geo->has_gt != 0;
    std::memcpy(ds->m_gt, geo->gt, sizeof ds->m_gt);
    if (geo->wkt) {
        ds->m_srs.importFromWkt(geo->wkt);
        ds->m_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    }
    ds->SetBand(1, new TSYNRasterBand(ds, static_cast<GDALDataType>(tsrecipe_gdal_type(recipe))));
    /* for schedulers (the Dask runner): the job, how its windows are made, the
     * files it reads; kept apart from PAM's metadata, so nothing is written */
    ds->m_schedule.SetNameValue("JOB", tsrecipe_job_name(recipe));
    ds->m_schedule.SetNameValue("WINDOWS", tsrecipe_schedule(recipe));
    ds->m_schedule.SetNameValue("TILE_SIZE", CPLSPrintf("%d", tsrecipe_tile_size(recipe)));
    ds->m_schedule.SetNameValue("DRAINAGE_MARGIN",
                                CPLSPrintf("%d", tsrecipe_drainage_margin(recipe)));
    {
        const char *const *in = tsrecipe_inputs(recipe);
        for (int i = 0; in && in[i]; i++)
            ds->m_schedule.SetNameValue(CPLSPrintf("INPUT_%d", i + 1), in[i]);
    }
    for (int i = 0; i < tsrecipe_overview_count(recipe); i++)
        ds->m_overviews.emplace_back(new TSYNOverviewDataset(
            ds, i, tsrecipe_overview_factor(recipe, i), ds->m_gt, ds->m_has_gt,
            ds->m_srs.IsEmpty() ? nullptr : &ds->m_srs));
    ds->SetDescription(info->pszFilename);
    ds->TryLoadXML();
    return ds;
}

CPLErr TSYNDataset::GetGeoTransform(double *gt)
{
    std::memcpy(gt, m_gt, sizeof m_gt);
    return m_has_gt ? CE_None : CE_Failure;
}

const OGRSpatialReference *TSYNDataset::GetSpatialRef() const
{
    return m_srs.IsEmpty() ? nullptr : &m_srs;
}

char **TSYNDataset::GetMetadataDomainList()
{
    return BuildMetadataDomainList(GDALPamDataset::GetMetadataDomainList(), TRUE, "TSYN", nullptr);
}

char **TSYNDataset::GetMetadata(const char *domain)
{
    if (domain && EQUAL(domain, "TSYN"))
        return m_schedule.List();
    return GDALPamDataset::GetMetadata(domain);
}

const char *TSYNDataset::GetMetadataItem(const char *name, const char *domain)
{
    if (domain && EQUAL(domain, "TSYN"))
        return m_schedule.FetchNameValue(name);
    return GDALPamDataset::GetMetadataItem(name, domain);
}

bool TSYNDataset::Compute()
{
    CPLMutexHolderD(&m_mutex);
    if (m_failed)
        return false;
    if (tsrecipe_data(m_recipe))
        return true;
    tsio_err err;
    if (tsrecipe_compute(m_recipe, &err) != 0) {
        CPLError(CE_Failure, CPLE_AppDefined, "%s", err.msg);
        m_failed = true;
        return false;
    }
    return true;
}

CPLErr TSYNRasterBand::IReadBlock(int bx, int by, void *image)
{
    auto *ds = static_cast<TSYNDataset *>(poDS);
    if (!ds->Compute())
        return CE_Failure;
    if (tsrecipe_lazy(ds->m_recipe)) {
        /* computed block by block (with the margin it needs), never whole */
        return ReadFloatBlock(this, bx, by, image,
                              [ds](int x, int y, int w, int h, float *cells, tsio_err *err) {
                                  return tsrecipe_read_window(ds->m_recipe, x, y, w, h, cells, err);
                              });
    }
    const auto *data = static_cast<const GByte *>(tsrecipe_data(ds->m_recipe));
    const int size = GDALGetDataTypeSizeBytes(eDataType);
    const int x0 = bx * nBlockXSize, y0 = by * nBlockYSize;
    const int w = std::min(nBlockXSize, nRasterXSize - x0);
    const int h = std::min(nBlockYSize, nRasterYSize - y0);
    std::memset(image, 0, static_cast<size_t>(nBlockXSize) * nBlockYSize * size);
    for (int y = 0; y < h; y++)
        std::memcpy(static_cast<GByte *>(image) + static_cast<size_t>(y) * nBlockXSize * size,
                    data + (static_cast<size_t>(y0 + y) * nRasterXSize + x0) * size,
                    static_cast<size_t>(w) * size);
    return CE_None;
}

int TSYNRasterBand::GetOverviewCount()
{
    return static_cast<int>(static_cast<TSYNDataset *>(poDS)->m_overviews.size());
}

GDALRasterBand *TSYNRasterBand::GetOverview(int i)
{
    auto &ov = static_cast<TSYNDataset *>(poDS)->m_overviews;
    return i >= 0 && i < static_cast<int>(ov.size()) ? ov[i]->GetRasterBand(1) : nullptr;
}

/* A read zoomed out by more than 4 over more cells than this, with no
 * overview to take them from, is refused with why (it would make every cell at
 * full resolution: a 100 000^2 synth recipe for a 100 x 100 thumbnail). */
constexpr double TSYN_ZOOMED_OUT_CELLS = 268435456.0; /* 16 384^2 */

/* A read at full resolution of a lazy recipe over more cells than a block is made in
 * windows of at most this side, each drained once with its margin, not block by block (each
 * block drained with the whole margin again: 16 times the cells of a 256^2 block with a
 * margin of 388); the same bytes, as any window of a recipe is that window of the whole. */
constexpr int TSYN_DIRECT_SIDE = 2048;

/* Cells [x, x+w) x [y, y+h) of a lazy recipe into buf (type, ps, ls) in windows of at most
 * TSYN_DIRECT_SIDE a side. */
CPLErr ReadDirect(tsrecipe *r, int x, int y, int w, int h, void *buf, GDALDataType type,
                  GSpacing ps, GSpacing ls)
{
    for (int wy = 0; wy < h; wy += TSYN_DIRECT_SIDE)
        for (int wx = 0; wx < w; wx += TSYN_DIRECT_SIDE) {
            const int ww = std::min(TSYN_DIRECT_SIDE, w - wx);
            const int wh = std::min(TSYN_DIRECT_SIDE, h - wy);
            std::vector<float> cells;
            tsio_err err;
            try {
                cells.resize(static_cast<size_t>(ww) * wh);
            } catch (const std::bad_alloc &) {
                CPLError(CE_Failure, CPLE_OutOfMemory, "out of memory for %d x %d cells", ww, wh);
                return CE_Failure;
            }
            if (tsrecipe_read_window(r, x + wx, y + wy, ww, wh, cells.data(), &err) != 0) {
                CPLError(CE_Failure, CPLE_AppDefined, "%s", err.msg);
                return CE_Failure;
            }
            for (int row = 0; row < wh; row++)
                GDALCopyWords64(cells.data() + static_cast<size_t>(row) * ww, GDT_Float32, 4,
                                static_cast<GByte *>(buf) + (wy + row) * ls + wx * ps, type,
                                static_cast<int>(ps), ww);
        }
    return CE_None;
}

CPLErr TSYNRasterBand::IRasterIO(GDALRWFlag rw, int x, int y, int w, int h, void *buf, int bw,
                                 int bh, GDALDataType type, GSpacing ps, GSpacing ls,
                                 GDALRasterIOExtraArg *extra)
{
    auto *ds = static_cast<TSYNDataset *>(poDS);
    if (rw == GF_Read && ds->m_overviews.empty() && tsrecipe_lazy(ds->m_recipe) &&
        (w > 4.0 * bw || h > 4.0 * bh) && static_cast<double>(w) * h > TSYN_ZOOMED_OUT_CELLS) {
        CPLError(CE_Failure, CPLE_AppDefined,
                 "%s: a %s recipe has no overviews: reading %d x %d cells zoomed out to %d x %d "
                 "would make every one of them at full resolution; read windows at full "
                 "resolution, or make the terrain once (gdal_translate, terrasynth-dask) and "
                 "read that file's overviews",
                 ds->GetDescription(), tsrecipe_job_name(ds->m_recipe), w, h, bw, bh);
        return CE_Failure;
    }
    if (rw == GF_Read && tsrecipe_lazy(ds->m_recipe) && bw == w && bh == h &&
        static_cast<double>(w) * h > static_cast<double>(nBlockXSize) * nBlockYSize) {
        if (!ds->Compute())
            return CE_Failure;
        return ReadDirect(ds->m_recipe, x, y, w, h, buf, type, ps, ls);
    }
    return GDALPamRasterBand::IRasterIO(rw, x, y, w, h, buf, bw, bh, type, ps, ls, extra);
}

CPLErr TSYNOverviewBand::IReadBlock(int bx, int by, void *image)
{
    if (!m_parent->Compute())
        return CE_Failure;
    return ReadFloatBlock(this, bx, by, image,
                          [this](int x, int y, int w, int h, float *cells, tsio_err *err) {
                              return tsrecipe_read_overview(m_parent->m_recipe, m_index, x, y, w,
                                                            h, cells, err);
                          });
}

} // namespace

extern "C" __attribute__((visibility("default"))) void GDALRegister_TSYN(void)
{
    if (!GDAL_CHECK_VERSION("TSYN"))
        return;
    tsyn_register_pixel_functions();
    if (GDALGetDriverByName("TSYN") != nullptr)
        return;
    auto *drv = new GDALDriver();
    drv->SetDescription("TSYN");
    drv->SetMetadataItem(GDAL_DCAP_RASTER, "YES");
    drv->SetMetadataItem(GDAL_DMD_LONGNAME, "TerraSynth terrain synthesis recipe");
    drv->SetMetadataItem(GDAL_DMD_EXTENSION, "tsyn");
    drv->SetMetadataItem(GDAL_DMD_HELPTOPIC, "gdal_driver/docs/recipes.md");
    drv->SetMetadataItem(GDAL_DCAP_VIRTUALIO, "YES");
    /* where this plugin lies: the Dask runner calls its tsyn_tile_make */
    Dl_info self;
    if (dladdr(reinterpret_cast<void *>(&GDALRegister_TSYN), &self) && self.dli_fname)
        drv->SetMetadataItem("TSYN_LIBRARY", self.dli_fname);
    char *options = tsrecipe_open_option_list();
    if (options) {
        drv->SetMetadataItem(GDAL_DMD_OPENOPTIONLIST, options);
        free(options);
    }
    drv->pfnIdentify = TSYNDataset::Identify;
    drv->pfnOpen = TSYNDataset::Open;
    GetGDALDriverManager()->RegisterDriver(drv);
}

extern "C" __attribute__((visibility("default"))) void GDALRegisterMe(void)
{
    GDALRegister_TSYN();
}
