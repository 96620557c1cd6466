/*
 * pixel_ops.c - per-pixel terrain operations used by the VRT pixel
 * functions: weighted blending of terrains, linear rescaling (ranges and
 * units), water levels.  O(n), no state.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "internal.h"

TS_API void ts_blend_weighted(size_t n, int n_terms, const float *const *terrain,
                              const float *const *weight, float *out)
{
    size_t i;
    int k;
    for (i = 0; i < n; i++) {
        double s = 0.0, ws = 0.0;
        for (k = 0; k < n_terms; k++) {
            float t = terrain[k][i], w = weight[k][i];
            if (isnan(t) || !isfinite(w) || !(w > 0))
                continue;
            s += (double)w * t;
            ws += w;
        }
        out[i] = ws > 0 ? (float)(s / ws) : NAN;
    }
}

TS_API void ts_rescale_linear(size_t n, const float *in, double from_min, double from_max,
                              double to_min, double to_max, float *out)
{
    size_t i;
    double span = from_max - from_min;
    double scale = span != 0.0 ? (to_max - to_min) / span : 0.0;
    for (i = 0; i < n; i++)
        out[i] = isnan(in[i]) ? NAN : (float)(to_min + (in[i] - from_min) * scale);
}

TS_API void ts_water_level(size_t n, const float *in, double level, int mode, float *out)
{
    size_t i;
    for (i = 0; i < n; i++) {
        float z = in[i];
        if (isnan(z)) {
            out[i] = NAN;
            continue;
        }
        switch (mode) {
        case TS_WATER_DEPTH:
            out[i] = z < level ? (float)(level - z) : 0.0f;
            break;
        case TS_WATER_MASK:
            out[i] = z < level ? 1.0f : 0.0f;
            break;
        default:
            out[i] = z < level ? (float)level : z;
            break;
        }
    }
}
