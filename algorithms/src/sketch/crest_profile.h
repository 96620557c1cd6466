/*
 * crest_profile.h - private: peaks and saddles along a sketch's ridges,
 * taken from the exemplars' own crests (a TerraSynth addition to Zhou et
 * al. 2007, see crest_profile.c).  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_CREST_PROFILE_H
#define TS_CREST_PROFILE_H

#include "internal.h"

/* One exemplar's crest pieces: the heights along each of its main ridge
 * paths at least a patch long, a cell of arc length apart, band-passed
 * (the variation between an eighth of a patch and two patches).  Piece k
 * is z[start[k] .. start[k + 1]). */
typedef struct ts__crest_library {
    float *z;
    size_t *start; /* n_pieces + 1 entries */
    size_t n_pieces;
} ts__crest_library;

/* The pieces of the ridge paths of `ef` (an exemplar's main features at
 * the output's cells) a patch long or more; none when it has none. */
ts_status ts__crest_library_measure(ts_ctx *ctx, const ts_features *ef, int patch,
                                    ts__crest_library *lib);
void ts__crest_library_free(ts__crest_library *lib);

/* Height offsets along the ridge paths of the sketch's feature graph sf:
 * off (sf->width * sf->height floats) gets, on every ridge path cell, the
 * crest profile laid along its path (pieces of the library of the exemplar
 * its region takes, cell_exemplar may be NULL, chained by equal-power
 * cross-fades; the ends meet their nodes' own offsets), NaN elsewhere.
 * *any: 0 when no offset was laid (no ridge path, no library).  The same
 * offsets for the same seed. */
ts_status ts__crest_offsets(ts_ctx *ctx, const ts_features *sf, const ts__crest_library *libs,
                            int n_libs, const int32_t *cell_exemplar, int patch, uint64_t seed,
                            float *off, int *any);

/* The offsets spread to the land: add[i] = gain x the offset of the nearest
 * ridge path cell times exp(-d / reach) (a peak), exp(-d / (4 reach)) (a
 * saddle: a negative offset), d the distance to it, and, when
 * valley_dist (the distance to the valleys) is given, times a smoothstep
 * of valley_dist / (2 patch) (nothing on a valley floor, and valley walls
 * no steeper); add_hp = add less
 * its Gaussian blur at sigma.  Both library-allocated width*height floats
 * (free()), NULL when no ridge has a profile. */
ts_status ts__crest_field(ts_ctx *ctx, const ts_features *sf, const ts__crest_library *libs,
                          int n_libs, const int32_t *cell_exemplar, int patch,
                          const float *valley_dist, double reach, double sigma, double gain,
                          float **add, float **add_hp);
#endif
