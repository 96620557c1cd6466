/*
 * hillshade.c - shaded relief and the preview image a person looks at.
 * Horn's (1981) third-order finite differences on ground distances, the
 * usual cartographic illumination model; nodata neighbours are replaced by
 * the centre cell.
 * Cost: O(cells), rows split over threads.
 */
#include <string.h>

#include "internal.h"

typedef struct shade_job {
    const ts_raster *dem;
    const ts_grid_metrics *m;
    double zenith, azimuth, zf;
    ts_raster *out;
} shade_job;

static float shade_at(const ts_raster *dem, int x, int y, float c)
{
    float v;
    if (x < 0)
        x = 0;
    if (y < 0)
        y = 0;
    if (x >= dem->width)
        x = dem->width - 1;
    if (y >= dem->height)
        y = dem->height - 1;
    v = TS_PIX(dem, x, y);
    return isnan(v) ? c : v;
}

static void shade_rows(void *arg, size_t y0, size_t y1)
{
    const shade_job *j = arg;
    const ts_raster *dem = j->dem;
    size_t yy;
    for (yy = y0; yy < y1; yy++) {
        int y = (int)yy, x;
        double dx = j->m ? j->m->dx[y] : 1.0, dy = j->m ? j->m->dy[y] : 1.0;
        for (x = 0; x < dem->width; x++) {
            float c = TS_PIX(dem, x, y);
            double a, b, cc, d, f, g, h, i, gx, gy, slope, aspect, s;
            if (isnan(c)) {
                TS_PIX(j->out, x, y) = NAN;
                continue;
            }
            a = shade_at(dem, x - 1, y - 1, c);
            b = shade_at(dem, x, y - 1, c);
            cc = shade_at(dem, x + 1, y - 1, c);
            d = shade_at(dem, x - 1, y, c);
            f = shade_at(dem, x + 1, y, c);
            g = shade_at(dem, x - 1, y + 1, c);
            h = shade_at(dem, x, y + 1, c);
            i = shade_at(dem, x + 1, y + 1, c);
            gx = ((cc + 2 * f + i) - (a + 2 * d + g)) / (8.0 * dx) * j->zf; /* east */
            gy = ((g + 2 * h + i) - (a + 2 * b + cc)) / (8.0 * dy) * j->zf; /* south */
            slope = atan(sqrt(gx * gx + gy * gy));
            aspect = atan2(gy, -gx);
            s = cos(j->zenith) * cos(slope) +
                sin(j->zenith) * sin(slope) * cos(j->azimuth - aspect);
            TS_PIX(j->out, x, y) = (float)(s < 0 ? 0 : s > 1 ? 1 : s);
        }
    }
}

TS_API ts_status ts_hillshade(ts_ctx *ctx, const ts_raster *dem, const ts_grid_metrics *metrics,
                              double azimuth_deg, double altitude_deg, double z_factor,
                              ts_raster *out)
{
    shade_job j;
    ts__clear(ctx);
    if (!dem || !dem->data || !out || !out->data || out->width != dem->width ||
        out->height != dem->height)
        return ts__fail(ctx, TS_ERR_ARG, "hillshade", "output must match the DEM's size");
    if (!(altitude_deg >= 0 && altitude_deg <= 90) || !isfinite(azimuth_deg) || !(z_factor > 0) ||
        !isfinite(z_factor))
        return ts__fail(ctx, TS_ERR_ARG, "hillshade",
                        "bad illumination (azimuth %g, altitude %g, z %g)", azimuth_deg,
                        altitude_deg, z_factor);
    j.dem = dem;
    j.m = metrics;
    j.zenith = (90.0 - altitude_deg) * TS_PI / 180.0;
    /* compass azimuth -> mathematical angle, matching atan2(gy, -gx) */
    j.azimuth = (360.0 - azimuth_deg + 90.0) * TS_PI / 180.0;
    j.zf = z_factor;
    j.out = out;
    ts__parallel_for(ctx, (size_t)dem->height, shade_rows, &j);
    return TS_OK;
}

/* Hypsometric tint: green lowlands, ochre slopes, grey-white summits. */
static void preview_tint(double t, double rgb[3])
{
    static const double stops[4][3] = {
        {0.42, 0.60, 0.38}, {0.80, 0.75, 0.52}, {0.62, 0.50, 0.40}, {0.95, 0.95, 0.95}};
    double s = t * 3.0;
    int k = (int)s;
    double u;
    if (k > 2)
        k = 2;
    if (k < 0)
        k = 0;
    u = s - k;
    rgb[0] = stops[k][0] + u * (stops[k + 1][0] - stops[k][0]);
    rgb[1] = stops[k][1] + u * (stops[k + 1][1] - stops[k][1]);
    rgb[2] = stops[k][2] + u * (stops[k + 1][2] - stops[k][2]);
}

TS_API ts_status ts_render_preview(ts_ctx *ctx, const ts_raster *dem,
                                   const ts_grid_metrics *metrics, const ts_features *features,
                                   unsigned char *rgb)
{
    ts_raster shade;
    ts_raster_stats st;
    int x, y, radius = 0;
    ts_status s;
    ts__clear(ctx);
    if (!dem || !rgb)
        return ts__fail(ctx, TS_ERR_ARG, "preview", "missing DEM or output");
    if (features && (features->width != dem->width || features->height != dem->height))
        return ts__fail(ctx, TS_ERR_ARG, "preview", "features do not match the DEM");
    if ((s = ts_raster_stats_compute(ctx, dem, &st)) != TS_OK)
        return s;
    if ((s = ts_raster_alloc(ctx, dem->width, dem->height, &shade)) != TS_OK)
        return s;
    if ((s = ts_hillshade(ctx, dem, metrics, 315.0, 45.0, 1.0, &shade)) != TS_OK) {
        ts_raster_free(&shade);
        return s;
    }
    /* lines one cell wide vanish when a large image is shown small */
    if (TS_MAX(dem->width, dem->height) > 1200)
        radius = 1;
    for (y = 0; y < dem->height; y++) {
        for (x = 0; x < dem->width; x++) {
            unsigned char *p = rgb + 3 * ((size_t)y * (size_t)dem->width + (size_t)x);
            float z = TS_PIX(dem, x, y);
            double tint[3], l;
            int c;
            if (isnan(z)) {
                p[0] = p[1] = p[2] = 255;
                continue;
            }
            preview_tint(st.max > st.min ? (z - st.min) / (st.max - st.min) : 0.5, tint);
            l = 0.25 + 0.85 * TS_PIX(&shade, x, y);
            for (c = 0; c < 3; c++) {
                double v = 255.0 * tint[c] * l;
                p[c] = (unsigned char)(v > 255 ? 255 : v < 0 ? 0 : v + 0.5);
            }
        }
    }
    if (features) {
        for (y = 0; y < dem->height; y++) {
            for (x = 0; x < dem->width; x++) {
                unsigned char bits = features->mask[(size_t)y * (size_t)dem->width + (size_t)x];
                int ox, oy;
                if (!bits)
                    continue;
                for (oy = -radius; oy <= radius; oy++)
                    for (ox = -radius; ox <= radius; ox++) {
                        int xx = x + ox, yy = y + oy;
                        unsigned char *p;
                        if (xx < 0 || yy < 0 || xx >= dem->width || yy >= dem->height)
                            continue;
                        p = rgb + 3 * ((size_t)yy * (size_t)dem->width + (size_t)xx);
                        if (bits & TS_RIDGE) {
                            p[0] = 230;
                            p[1] = 30;
                            p[2] = 30;
                        } else {
                            p[0] = 20;
                            p[1] = 80;
                            p[2] = 240;
                        }
                    }
            }
        }
    }
    ts_raster_free(&shade);
    return TS_OK;
}
