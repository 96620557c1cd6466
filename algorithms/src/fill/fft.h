/*
 * fft.h - a small private wrapper around FFTW3, in single precision but for
 * one cosine transform in double: sizes, aligned buffers and the few plan
 * shapes the core uses.  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_FFT_H
#define TS_FFT_H

#include <stddef.h>

#include <fftw3.h>

/* Smallest n' >= n of the form 2^a 3^b 5^c 7^d (FFTW's fast sizes); 0 if
 * n is 0 or n' would not fit in an int. */
size_t ts__fft_good_size(size_t n);

/* n * size bytes from fftwf_malloc (SIMD-aligned, not initialised); NULL
 * on overflow or failure.  Free with ts__fft_free (NULL-safe).  Both run
 * under the planner lock. */
void *ts__fft_alloc(size_t n, size_t size);
void ts__fft_free(void *p);

/* In-place length-n real-to-complex (forward) and complex-to-real
 * (backward, unnormalised) transforms of one row: `row` holds n floats in,
 * n/2+1 complex values out (room for 2*(n/2+1) floats).  Planned with
 * FFTW_ESTIMATE on `row`; execute on other rows of the same alignment
 * with fftwf_execute_dft_r2c / fftwf_execute_dft_c2r, in place.
 * NULL if FFTW cannot plan. */
fftwf_plan ts__fft_plan_row_r2c(int n, fftwf_complex *row);
fftwf_plan ts__fft_plan_row_c2r(int n, fftwf_complex *row);

/* In-place length-n complex transforms of `count` consecutive sequences:
 * element j of sequence c is buf[c * n + j].  sign is FFTW_FORWARD or
 * FFTW_BACKWARD (unnormalised).  Execute with fftwf_execute_dft on other
 * buffers of the same shape and alignment. */
fftwf_plan ts__fft_plan_columns(int n, int count, fftwf_complex *buf, int sign);

/* Destroy a plan under the planner lock (NULL-safe). */
void ts__fft_destroy(fftwf_plan plan);

/* In double precision: the 2-D discrete cosine transform of a w x h grid at
 * stride w (rows of w), in place: DCT-II (FFTW_REDFT10) both ways when
 * !inverse, DCT-III (FFTW_REDFT01) when inverse, unnormalised (the two in
 * turn multiply by 4 w h).  `buf` from ts__fft_alloc.  NULL if FFTW cannot
 * plan; destroy with ts__fft_destroy_double. */
fftw_plan ts__fft_plan_dct_2d(int w, int h, double *buf, int inverse);
void ts__fft_destroy_double(fftw_plan plan);

#endif
