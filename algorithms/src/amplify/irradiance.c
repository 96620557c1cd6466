/*
 * irradiance.c - mean annual direct solar irradiance with self-shadowing
 * (Argudo et al. 2017, section 5.6: "calculated based on latitude and
 * longitude by intersecting rays from the sun position along its
 * trajectory with the terrain").
 *
 * The sun's trajectory over a year is sampled: 12 days (the middle of each
 * month; declination delta = 23.44 deg sin(2 pi (284 + n) / 365)) x 48 hour
 * angles (every half hour of solar time).  For a cell at latitude phi, the
 * sun direction in local east-north-up coordinates is
 *   E = -cos(delta) sin(h),
 *   N =  sin(delta) cos(phi) - cos(delta) sin(phi) cos(h),
 *   U =  sin(delta) sin(phi) + cos(delta) cos(phi) cos(h),
 * turned into the grid's frame by the azimuth of the grid's up direction
 * (meridian convergence: 0 on a north-up geographic grid).  A sample lights
 * the cell when the sun is above the cell's horizon in its direction (the
 * horizon: the steepest elevation angle to the terrain along 16 directions,
 * interpolated between the two nearest, marched out to HORIZON_CELLS cells)
 * and the beam's power on the slope is
 *   I0 * tau^(AM^0.678) * max(0, n . s)       (Meinel's clear-sky model,
 * I0 = 1361 W/m^2, tau = 0.7, air mass AM = 1 / U).  The result is the mean
 * over the whole year (nights count as 0), in W/m^2.  Simplified, and named
 * as such: no diffuse light, no atmosphere beyond that model, no refraction.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "amplify.h"

#define N_DAYS 12
#define N_HOURS 48
#define N_DIRS 16
#define HORIZON_CELLS 64
#define SOLAR_CONSTANT 1361.0
#define TAU 0.7
#define PI_D 3.14159265358979323846

typedef struct irr_job {
    const ts_raster *dem, *lat, *north;
    const double *dx, *dy;
    ts_raster *out;
    double sin_d[N_DAYS], cos_d[N_DAYS];
    double sin_h[N_HOURS], cos_h[N_HOURS];
    double trans[257]; /* tau^(AM^0.678) at U = i / 256 */
} irr_job;

/* The clear-sky transmittance at sine of elevation u (0 < u <= 1). */
static double transmittance(const irr_job *j, double u)
{
    double t = u * 256.0;
    int i = (int)t;
    if (i >= 256)
        return j->trans[256];
    return j->trans[i] + (t - i) * (j->trans[i + 1] - j->trans[i]);
}

static double cell_dx(const irr_job *j, int y)
{
    return j->dx ? j->dx[y] : 1.0;
}

static double cell_dy(const irr_job *j, int y)
{
    return j->dy ? j->dy[y] : 1.0;
}

static void irr_rows(void *arg, size_t begin, size_t end)
{
    irr_job *j = arg;
    const ts_raster *z = j->dem;
    int W = z->width, H = z->height, x, k, d, h;
    size_t yy;
    for (yy = begin; yy < end; yy++) {
        int y = (int)yy;
        double dxm = cell_dx(j, y), dym = cell_dy(j, y);
        for (x = 0; x < W; x++) {
            float z0 = TS_PIX(z, x, y);
            double hz[N_DIRS + 1], hmax = -1e30, gx, gy, nx, ny, nz, nn, phi, rot, sp, cp, sr, cr;
            double sum = 0.0;
            float zl, zr, zu, zd;
            if (isnan(z0) || isnan(TS_PIX(j->lat, x, y))) {
                TS_PIX(j->out, x, y) = NAN;
                continue;
            }
            /* the horizon: tan of the steepest elevation angle along each direction
             * (direction k: azimuth 2 pi k / N_DIRS clockwise from the grid's up) */
            for (k = 0; k < N_DIRS; k++) {
                double a = 2.0 * PI_D * k / N_DIRS, sx = sin(a), sy = -cos(a), best = -1e30, r;
                for (r = 1.0; r <= HORIZON_CELLS; r = r < 8 ? r + 1 : r * 1.15) {
                    int xi = x + (int)lround(sx * r), yi = y + (int)lround(sy * r);
                    double ex, ey, dist, t;
                    float v;
                    if (xi < 0 || yi < 0 || xi >= W || yi >= H)
                        break;
                    v = TS_PIX(z, xi, yi);
                    if (isnan(v))
                        continue;
                    ex = (xi - x) * dxm;
                    ey = (yi - y) * dym;
                    dist = sqrt(ex * ex + ey * ey);
                    t = (v - z0) / dist;
                    if (t > best)
                        best = t;
                }
                hz[k] = best;
                if (best > hmax)
                    hmax = best;
            }
            hz[N_DIRS] = hz[0];
            /* the slope's normal from central differences (one-sided at edges and nodata) */
            zl = x > 0 ? TS_PIX(z, x - 1, y) : z0;
            zr = x + 1 < W ? TS_PIX(z, x + 1, y) : z0;
            zu = y > 0 ? TS_PIX(z, x, y - 1) : z0;
            zd = y + 1 < H ? TS_PIX(z, x, y + 1) : z0;
            if (isnan(zl))
                zl = z0;
            if (isnan(zr))
                zr = z0;
            if (isnan(zu))
                zu = z0;
            if (isnan(zd))
                zd = z0;
            {
                int cx = (x > 0) + (x + 1 < W), cy = (y > 0) + (y + 1 < H);
                gx = cx ? (zr - zl) / (cx * dxm) : 0.0; /* dz / d(grid right) */
                gy = cy ? (zu - zd) / (cy * dym) : 0.0; /* dz / d(grid up) */
            }
            nn = sqrt(gx * gx + gy * gy + 1.0);
            nx = -gx / nn;
            ny = -gy / nn;
            nz = 1.0 / nn;
            phi = TS_PIX(j->lat, x, y) * PI_D / 180.0;
            rot = j->north ? TS_PIX(j->north, x, y) * PI_D / 180.0 : 0.0;
            if (isnan(rot))
                rot = 0.0;
            sp = sin(phi);
            cp = cos(phi);
            sr = sin(rot);
            cr = cos(rot);
            for (d = 0; d < N_DAYS; d++)
                for (h = 0; h < N_HOURS; h++) {
                    double E = -j->cos_d[d] * j->sin_h[h];
                    double N = j->sin_d[d] * cp - j->cos_d[d] * sp * j->cos_h[h];
                    double U = j->sin_d[d] * sp + j->cos_d[d] * cp * j->cos_h[h];
                    double gr, gu, hor, az, t, inc, horiz_len;
                    int k0;
                    if (U <= 0.0)
                        continue;
                    /* into the grid's frame: its up is at azimuth rot from north */
                    gr = E * cr - N * sr;
                    gu = E * sr + N * cr;
                    inc = nx * gr + ny * gu + nz * U;
                    if (inc <= 0.0)
                        continue;
                    horiz_len = sqrt(gr * gr + gu * gu);
                    /* above every horizon: lit whatever its direction (the same test) */
                    if (U > hmax * horiz_len) {
                        sum += SOLAR_CONSTANT * transmittance(j, U) * inc;
                        continue;
                    }
                    az = atan2(gr, gu); /* clockwise from the grid's up */
                    if (az < 0)
                        az += 2.0 * PI_D;
                    t = az / (2.0 * PI_D) * N_DIRS;
                    k0 = (int)t;
                    if (k0 >= N_DIRS)
                        k0 = N_DIRS - 1;
                    hor = hz[k0] + (t - k0) * (hz[k0 + 1] - hz[k0]);
                    if (U <= hor * horiz_len)
                        continue; /* behind the terrain */
                    sum += SOLAR_CONSTANT * transmittance(j, U) * inc;
                }
            TS_PIX(j->out, x, y) = (float)(sum / (N_DAYS * N_HOURS));
        }
    }
}

TS_API ts_status ts_irradiance(ts_ctx *ctx, const ts_raster *dem, const ts_grid_metrics *metrics,
                               const ts_raster *lat, const ts_raster *north, ts_raster *out)
{
    irr_job j;
    int i;
    ts__clear(ctx);
    if (!dem || !dem->data || !lat || !lat->data || !out || !out->data)
        return ts__fail(ctx, TS_ERR_ARG, "irradiance", "missing DEM, latitude or output");
    if (lat->width != dem->width || lat->height != dem->height || out->width != dem->width ||
        out->height != dem->height ||
        (north && (!north->data || north->width != dem->width || north->height != dem->height)))
        return ts__fail(ctx, TS_ERR_ARG, "irradiance",
                        "the latitude, north and output rasters must be on the DEM's grid");
    memset(&j, 0, sizeof j);
    j.dem = dem;
    j.lat = lat;
    j.north = north;
    j.dx = metrics ? metrics->dx : NULL;
    j.dy = metrics ? metrics->dy : NULL;
    j.out = out;
    for (i = 0; i < N_DAYS; i++) {
        double n = 15.0 + 365.0 * i / N_DAYS;
        double delta = 23.44 * PI_D / 180.0 * sin(2.0 * PI_D * (284.0 + n) / 365.0);
        j.sin_d[i] = sin(delta);
        j.cos_d[i] = cos(delta);
    }
    for (i = 0; i < N_HOURS; i++) {
        double h = 2.0 * PI_D * ((i + 0.5) / N_HOURS - 0.5);
        j.sin_h[i] = sin(h);
        j.cos_h[i] = cos(h);
    }
    j.trans[0] = 0.0;
    for (i = 1; i <= 256; i++)
        j.trans[i] = pow(TAU, pow(256.0 / i, 0.678));
    ts__parallel_for(ctx, (size_t)dem->height, irr_rows, &j);
    return ts__check_cancel(ctx);
}
