/*
 * pixfun.h - TerraSynth's VRT pixel functions (tsyn_blend, tsyn_rescale,
 * tsyn_units, tsyn_water), registered with GDAL by the TSYN plugin.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_PIXFUN_H
#define TS_PIXFUN_H

#ifdef __cplusplus
extern "C" {
#endif

void tsyn_register_pixel_functions(void);

#ifdef __cplusplus
}
#endif
#endif
