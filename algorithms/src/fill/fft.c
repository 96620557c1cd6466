/*
 * fft.c - FFTW3 wrapper (single precision, and the double-precision cosine
 * transform of the Poisson solver): fast sizes, aligned buffers, and plan
 * creation/destruction under one lock.
 *
 * The FFTW planner (and everything but fftwf_execute*) is not thread-safe,
 * so planner calls and fftwf_malloc/fftwf_free go through fft_planner_lock:
 * a static mutex, the one piece of process-wide state in the core, required
 * by FFTW.  Executing a plan with the new-array functions is thread-safe.
 * Plans use FFTW_ESTIMATE: no measuring, so creating one takes microseconds
 * and the chosen algorithm (hence every rounding) depends only on the size.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <limits.h>
#include <pthread.h>
#include <stdint.h>

#include "fft.h"

static pthread_mutex_t fft_planner_lock = PTHREAD_MUTEX_INITIALIZER;

static int fft_is_smooth(size_t n)
{
    static const size_t primes[4] = {2, 3, 5, 7};
    int i;
    for (i = 0; i < 4; i++)
        while (n % primes[i] == 0)
            n /= primes[i];
    return n == 1;
}

size_t ts__fft_good_size(size_t n)
{
    size_t m;
    if (n == 0)
        return 0;
    for (m = n; m <= (size_t)INT_MAX; m++)
        if (fft_is_smooth(m))
            return m;
    return 0;
}

void *ts__fft_alloc(size_t n, size_t size)
{
    void *p;
    if (size && n > SIZE_MAX / size)
        return NULL;
    pthread_mutex_lock(&fft_planner_lock);
    p = fftwf_malloc((n && size) ? n * size : 1);
    pthread_mutex_unlock(&fft_planner_lock);
    return p;
}

void ts__fft_free(void *p)
{
    if (!p)
        return;
    pthread_mutex_lock(&fft_planner_lock);
    fftwf_free(p);
    pthread_mutex_unlock(&fft_planner_lock);
}

fftwf_plan ts__fft_plan_row_r2c(int n, fftwf_complex *row)
{
    fftwf_plan p;
    pthread_mutex_lock(&fft_planner_lock);
    p = fftwf_plan_dft_r2c_1d(n, (float *)row, row, FFTW_ESTIMATE);
    pthread_mutex_unlock(&fft_planner_lock);
    return p;
}

fftwf_plan ts__fft_plan_row_c2r(int n, fftwf_complex *row)
{
    fftwf_plan p;
    pthread_mutex_lock(&fft_planner_lock);
    p = fftwf_plan_dft_c2r_1d(n, row, (float *)row, FFTW_ESTIMATE);
    pthread_mutex_unlock(&fft_planner_lock);
    return p;
}

fftwf_plan ts__fft_plan_columns(int n, int count, fftwf_complex *buf, int sign)
{
    fftwf_plan p;
    pthread_mutex_lock(&fft_planner_lock);
    p = fftwf_plan_many_dft(1, &n, count, buf, NULL, 1, n, buf, NULL, 1, n, sign, FFTW_ESTIMATE);
    pthread_mutex_unlock(&fft_planner_lock);
    return p;
}

void ts__fft_destroy(fftwf_plan plan)
{
    if (!plan)
        return;
    pthread_mutex_lock(&fft_planner_lock);
    fftwf_destroy_plan(plan);
    pthread_mutex_unlock(&fft_planner_lock);
}

fftw_plan ts__fft_plan_dct_2d(int w, int h, double *buf, int inverse)
{
    fftw_plan p;
    fftw_r2r_kind kind = inverse ? FFTW_REDFT01 : FFTW_REDFT10;
    pthread_mutex_lock(&fft_planner_lock);
    p = fftw_plan_r2r_2d(h, w, buf, buf, kind, kind, FFTW_ESTIMATE);
    pthread_mutex_unlock(&fft_planner_lock);
    return p;
}

void ts__fft_destroy_double(fftw_plan plan)
{
    if (!plan)
        return;
    pthread_mutex_lock(&fft_planner_lock);
    fftw_destroy_plan(plan);
    pthread_mutex_unlock(&fft_planner_lock);
}
