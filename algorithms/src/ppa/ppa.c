/*
 * ppa.c - the Profile recognition and Polygon breaking Algorithm (Chang,
 * Song & Hsu 1998) as summarised by Zhou et al. 2007 section 3: the
 * pipeline only; each step lives in its own file:
 *   ppa_profile.c  profile recognition      -> targets
 *   ppa_connect.c  target connection        -> segments
 *   ppa_polygon.c  polygon breaking         -> maximum spanning forest
 *   ppa_branch.c   branch reduction         -> pruned forest
 *   feature_graph.c                         -> endpoints, branch points, paths
 * Valleys are ridges of the negated DEM (the weights are negated).
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

TS_API void ts_features_free(ts_features *f)
{
    if (!f)
        return;
    free(f->mask);
    free(f->nodes);
    free(f->paths);
    free(f->verts);
    free(f);
}

TS_API ts_status ts_features_codes(ts_ctx *ctx, const ts_features *f, const ts_raster *dem,
                                   unsigned char *codes)
{
    int x, y;
    ts__clear(ctx);
    if (!f || !dem || !dem->data || !codes || f->width != dem->width || f->height != dem->height)
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "features and DEM do not match");
    for (y = 0; y < dem->height; y++)
        for (x = 0; x < dem->width; x++) {
            size_t k = (size_t)y * (size_t)dem->width + (size_t)x;
            codes[k] = isnan(TS_PIX(dem, x, y)) ? 255 : f->mask[k];
        }
    return TS_OK;
}

/* Steps 2-4 for one kind, into f; share: the kinds running side by side. */
static ts_status ppa_one_kind(ts_ctx *ctx, const ts_raster *dem, const ts_grid_metrics *m,
                              const unsigned char *targets, int kind, double min_length,
                              ts_features *f, int share)
{
    size_t n = (size_t)dem->width * (size_t)dem->height, i, n_segs = 0;
    ts_ppa_segment *segs = NULL;
    unsigned char *keep = NULL, *adj = NULL;
    ts_progress_saved sv;
    ts_status st;

    if (n < ((size_t)1 << 30)) { /* the lean way, in one pass: the same forest */
        adj = ts__calloc_array(n, 1);
        if (!adj)
            return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "out of memory");
        sv = ts__progress_push(ctx, 0.0, 0.7);
        /* strips of 64 rows at least, one per thread (half each when
         * ridges and valleys run side by side) */
        st = ppa_spanning_forest_strips(
            ctx, dem, targets, kind, adj,
            TS_MAX(1, ts__thread_count(ctx, (size_t)dem->height / 64) / share));
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            goto done;
        goto reduce;
    }
    sv = ts__progress_push(ctx, 0.0, 0.3);
    st = ts_ppa_target_connection(ctx, dem, targets, kind, &segs, &n_segs);
    ts__progress_pop(ctx, sv);
    if (st != TS_OK)
        return st;
    keep = ts__malloc_array(n_segs, 1);
    adj = ts__calloc_array(n, 1);
    if (!keep || !adj) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa", "out of memory for %zu segments", n_segs);
        goto done;
    }
    sv = ts__progress_push(ctx, 0.3, 0.7);
    st = ts_ppa_polygon_breaking(ctx, segs, n_segs, n, keep);
    ts__progress_pop(ctx, sv);
    if (st != TS_OK)
        goto done;
    for (i = 0; i < n_segs; i++) {
        int w = dem->width, dx, dy, d;
        if (!keep[i])
            continue;
        dx = (int)(segs[i].b % (uint32_t)w) - (int)(segs[i].a % (uint32_t)w);
        dy = (int)(segs[i].b / (uint32_t)w) - (int)(segs[i].a / (uint32_t)w);
        d = ppa_dir_of(dx, dy);
        adj[segs[i].a] |= (unsigned char)(1u << d);
        adj[segs[i].b] |= (unsigned char)(1u << ((d + 4) & 7));
    }
    free(segs);
    segs = NULL;
    free(keep);
    keep = NULL;
reduce:
    sv = ts__progress_push(ctx, 0.7, 0.9);
    st = ppa_branch_reduction(ctx, dem->width, dem->height, adj, m, min_length);
    ts__progress_pop(ctx, sv);
    if (st != TS_OK)
        goto done;
    st = ppa_graph_collect(ctx, dem, adj, m, kind, f);
    if (st == TS_OK)
        st = ts__progress(ctx, 1.0, kind == TS_RIDGE ? "ridges" : "valleys");
done:
    free(segs);
    free(keep);
    free(adj);
    return st;
}

/* Valleys on a second thread while the calling thread does ridges: the two
 * kinds share nothing but the read-only DEM and targets.  The worker has a
 * child context: no progress of its own, the caller's cancel flag. */
typedef struct valley_job {
    const ts_raster *dem;
    const ts_grid_metrics *m;
    const unsigned char *targets;
    double min_length;
    ts_ctx *ctx;
    ts_features *f;
    ts_status status;
    /* valleys where the water runs, routed here while the caller finds the
     * targets (min_drainage > 0): the drainage test, then, once the targets
     * are ready, vt the valley targets that pass it */
    double min_drainage;
    unsigned char *vt;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int ready, abort;
} valley_job;

/* Cell-by-cell mask work, side by side (chan: the drainage test's bits). */
typedef struct mask_job {
    unsigned char *to;
    const unsigned char *from;
    const uint64_t *chan;
    int op; /* 0: to = chan ? from & valley : 0; 1: to |= from; 2: to &= ~valley where !chan */
} mask_job;

static void mask_range(void *arg, size_t b, size_t e)
{
    mask_job *j = arg;
    size_t i;
    if (j->op == 0)
        for (i = b; i < e; i++)
            j->to[i] = ppa_channel(j->chan, i) ? j->from[i] & TS_VALLEY : 0;
    else if (j->op == 1)
        for (i = b; i < e; i++)
            j->to[i] |= j->from[i];
    else
        for (i = b; i < e; i++)
            if (!ppa_channel(j->chan, i))
                j->to[i] &= (unsigned char)~TS_VALLEY;
}

static void mask_apply(ts_ctx *ctx, size_t n, int op, unsigned char *to, const unsigned char *from,
                       const uint64_t *chan)
{
    mask_job j;
    j.to = to;
    j.from = from;
    j.chan = chan;
    j.op = op;
    ts__parallel_for(ctx, n, mask_range, &j);
}

/* The drainage's tiles in memory: one flood in one tile on few threads,
 * tiles side by side (each flooded once, the flow kept) on more: the same
 * areas either way. */
static void *valley_run(void *p)
{
    valley_job *j = p;
    if (j->min_drainage > 0) {
        size_t n = (size_t)j->dem->width * (size_t)j->dem->height;
        uint64_t *chan = NULL;
        int go;
        j->status = ppa_channels(j->ctx, j->dem->width, j->dem->height, ppa_drainage_tile(j->ctx),
                                 1, ppa_raster_window, (void *)j->dem, j->min_drainage, &chan);
        pthread_mutex_lock(&j->mu);
        while (!j->ready && !j->abort)
            pthread_cond_wait(&j->cv, &j->mu);
        go = !j->abort;
        pthread_mutex_unlock(&j->mu);
        if (j->status == TS_OK && go)
            mask_apply(j->ctx, n, 0, j->vt, j->targets, chan);
        free(chan);
        if (j->status != TS_OK || !go)
            return NULL;
        j->status = ppa_one_kind(j->ctx, j->dem, j->m, j->vt, TS_VALLEY, j->min_length, j->f, 2);
        return NULL;
    }
    j->status = ppa_one_kind(j->ctx, j->dem, j->m, j->targets, TS_VALLEY, j->min_length, j->f, 2);
    return NULL;
}

/* Append graph b to a (node indices and vertex offsets shifted). */
static ts_status ppa_merge(ts_ctx *ctx, ts_features *a, const ts_features *b)
{
    size_t i, n = (size_t)a->width * (size_t)a->height;
    ts_feature_node *nodes = realloc(a->nodes, (a->n_nodes + b->n_nodes + 1) * sizeof *nodes);
    ts_feature_path *paths;
    ts_feature_vertex *verts;
    if (!nodes)
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "out of memory");
    a->nodes = nodes;
    paths = realloc(a->paths, (a->n_paths + b->n_paths + 1) * sizeof *paths);
    if (!paths)
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "out of memory");
    a->paths = paths;
    verts = realloc(a->verts, (a->n_verts + b->n_verts + 1) * sizeof *verts);
    if (!verts)
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "out of memory");
    a->verts = verts;
    if (b->n_nodes)
        memcpy(a->nodes + a->n_nodes, b->nodes, b->n_nodes * sizeof *nodes);
    if (b->n_verts)
        memcpy(a->verts + a->n_verts, b->verts, b->n_verts * sizeof *verts);
    for (i = 0; i < b->n_paths; i++) {
        ts_feature_path p = b->paths[i];
        p.node_a += a->n_nodes;
        p.node_b += a->n_nodes;
        p.first += a->n_verts;
        a->paths[a->n_paths + i] = p;
    }
    a->n_nodes += b->n_nodes;
    a->n_paths += b->n_paths;
    a->n_verts += b->n_verts;
    mask_apply(ctx, n, 1, a->mask, b->mask, NULL);
    return TS_OK;
}

/* Profile recognition, when the targets are still to be found (the
 * drainage runs meanwhile). */
typedef struct profile_step {
    int profile_length, kinds;
    double threshold[2];
} profile_step;

static void job_release(valley_job *j, int abort)
{
    pthread_mutex_lock(&j->mu);
    if (abort)
        j->abort = 1;
    else
        j->ready = 1;
    pthread_cond_signal(&j->cv);
    pthread_mutex_unlock(&j->mu);
}

/* Ridges here, valleys on a worker thread; same result as in sequence.
 * With ps, the targets are found here first, while the worker routes the
 * drainage (min_drainage > 0), which then gives it its valley targets. */
static ts_status ppa_both_parallel(ts_ctx *ctx, const ts_raster *dem,
                                   const ts_grid_metrics *m_ridges, double len_ridges,
                                   const ts_grid_metrics *m_valleys, double len_valleys,
                                   unsigned char *targets, ts_features *f,
                                   const profile_step *ps, double min_drainage)
{
    valley_job job;
    pthread_t tid;
    ts_features *fv = calloc(1, sizeof *fv);
    ts_ctx *wctx = ts__ctx_child(ctx);
    ts_status st = TS_OK;
    ts_progress_saved sv;
    size_t n = (size_t)dem->width * (size_t)dem->height;
    int threaded;
    memset(&job, 0, sizeof job);
    if (min_drainage > 0)
        job.vt = ts__malloc_array(n, 1);
    if (!fv || !wctx || !(fv->mask = ts__calloc_array(n, 1)) || (min_drainage > 0 && !job.vt)) {
        ts_features_free(fv);
        ts_ctx_free(wctx);
        free(job.vt);
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "out of memory");
    }
    fv->width = dem->width;
    fv->height = dem->height;
    job.dem = dem;
    job.m = m_valleys;
    job.targets = targets;
    job.min_length = len_valleys;
    job.ctx = wctx;
    job.f = fv;
    job.status = TS_ERR_INTERNAL;
    job.min_drainage = min_drainage;
    pthread_mutex_init(&job.mu, NULL);
    pthread_cond_init(&job.cv, NULL);
    job.ready = !ps;
    threaded = pthread_create(&tid, NULL, valley_run, &job) == 0;
    if (ps) {
        sv = ts__progress_push(ctx, 0.0, 0.3);
        st = ppa_profile_targets(ctx, dem, ps->profile_length, ps->threshold[0], ps->threshold[1],
                                 ps->kinds, targets);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            ts__cancel(ctx); /* the worker need not finish */
        job_release(&job, st != TS_OK);
    }
    if (!threaded)
        valley_run(&job); /* no thread: in sequence */
    sv = ts__progress_push(ctx, ps ? 0.3 : 0.0, 1.0);
    if (st == TS_OK)
        st = ppa_one_kind(ctx, dem, m_ridges, targets, TS_RIDGE, len_ridges, f, 2);
    ts__progress_pop(ctx, sv);
    if (threaded) {
        if (st != TS_OK)
            ts__cancel(ctx); /* the valleys need not finish */
        pthread_join(tid, NULL);
    }
    if (st == TS_OK && job.status != TS_OK)
        st = ts__fail(ctx, job.status, "ppa", "%s", ts_ctx_message(wctx));
    if (st == TS_OK)
        st = ppa_merge(ctx, f, fv);
    pthread_mutex_destroy(&job.mu);
    pthread_cond_destroy(&job.cv);
    free(job.vt);
    ts_features_free(fv);
    ts_ctx_free(wctx);
    return st;
}

double ppa_kind_fraction(const ts_ppa_params *p, int kind)
{
    if (p->threshold_fraction >= 0)
        return p->threshold_fraction;
    return kind == TS_VALLEY && p->min_drainage > 0 ? PPA_AUTO_FRACTION_CHANNELS
                                                    : PPA_AUTO_FRACTION;
}

double ppa_kind_branch(const ts_ppa_params *p, int kind, int *in_metres)
{
    if (p->min_branch_length.value >= 0) {
        *in_metres = p->min_branch_length.unit == TS_UNIT_METRES;
        return p->min_branch_length.value;
    }
    *in_metres = 0;
    return kind == TS_VALLEY && p->min_drainage > 0 ? PPA_AUTO_BRANCH_CHANNELS : PPA_AUTO_BRANCH;
}

/* The elevation range, rows side by side (min and max: the same on any split). */
#define RANGE_CHUNKS 64
typedef struct range_job {
    const ts_raster *dem;
    float lo[RANGE_CHUNKS], hi[RANGE_CHUNKS];
} range_job;

static void range_rows(void *arg, size_t b, size_t e)
{
    range_job *j = arg;
    int H = j->dem->height, x, y;
    size_t c;
    for (c = b; c < e; c++) {
        float lo = INFINITY, hi = -INFINITY;
        for (y = (int)((size_t)H * c / RANGE_CHUNKS); y < (int)((size_t)H * (c + 1) / RANGE_CHUNKS);
             y++)
            for (x = 0; x < j->dem->width; x++) {
                float v = TS_PIX(j->dem, x, y);
                lo = v < lo ? v : lo; /* NaN compares false: skipped */
                hi = v > hi ? v : hi;
            }
        j->lo[c] = lo;
        j->hi[c] = hi;
    }
}

static int dem_range(ts_ctx *ctx, const ts_raster *dem, double *lo, double *hi)
{
    range_job j;
    size_t c;
    j.dem = dem;
    ts__parallel_for(ctx, RANGE_CHUNKS, range_rows, &j);
    *lo = INFINITY;
    *hi = -INFINITY;
    for (c = 0; c < RANGE_CHUNKS; c++) {
        *lo = TS_MIN(*lo, (double)j.lo[c]);
        *hi = TS_MAX(*hi, (double)j.hi[c]);
    }
    return *lo <= *hi;
}

TS_API ts_status ts_ppa_extract(ts_ctx *ctx, const ts_raster *dem, const ts_grid_metrics *metrics,
                                const ts_ppa_params *params, ts_features **out)
{
    double lo, hi;
    ts_features *f = NULL;
    unsigned char *targets = NULL;
    size_t n;
    double threshold[2], min_length[2];
    const ts_grid_metrics *km[2];
    int kinds, k;
    ts_status st;
    ts_progress_saved sv;

    ts__clear(ctx);
    if (out)
        *out = NULL;
    if (!dem || !dem->data || !params || !out)
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "missing DEM, parameters or output");
    if (ts_params_validate(ctx, "ppa", params) != TS_OK)
        return ctx->status;
    if (dem->width < 2 || dem->height < 2)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa", "the DEM is %d x %d cells; at least 2 x 2 needed",
                        dem->width, dem->height);
    if (metrics && (!metrics->dx || !metrics->dy))
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "ground metrics without cell sizes");
    if (params->min_branch_length.unit == TS_UNIT_METRES && params->min_branch_length.value >= 0 &&
        !metrics)
        return ts__fail(ctx, TS_ERR_ARG, "ppa",
                        "min_branch_length is in metres but the DEM has no ground metrics "
                        "(no CRS): give it in cells");
    if (!dem_range(ctx, dem, &lo, &hi))
        return ts__fail(ctx, TS_ERR_NUMERIC, "ppa", "every cell of the DEM is nodata");
    /* per kind ("auto" resolved): a length in cells is measured in cells,
     * one in metres on the ground */
    for (k = 0; k < 2; k++) {
        int in_metres;
        threshold[k] = TS_MAX(params->threshold,
                              ppa_kind_fraction(params, k + 1) * (hi - lo));
        min_length[k] = ppa_kind_branch(params, k + 1, &in_metres);
        km[k] = in_metres ? metrics : NULL;
    }
    kinds = params->features == TS_PPA_RIDGES    ? TS_RIDGE
            : params->features == TS_PPA_VALLEYS ? TS_VALLEY
                                                 : TS_RIDGE | TS_VALLEY;
    n = (size_t)dem->width * (size_t)dem->height;
    f = calloc(1, sizeof *f);
    targets = ts__malloc_array(n, 1);
    if (!f || !targets || !(f->mask = ts__calloc_array(n, 1))) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa", "cannot allocate for %d x %d cells", dem->width,
                      dem->height);
        goto fail;
    }
    f->width = dem->width;
    f->height = dem->height;
    f->threshold_used = params->features == TS_PPA_VALLEYS ? threshold[1] : threshold[0];
    f->threshold_used_valleys = threshold[1];

    if (kinds == (TS_RIDGE | TS_VALLEY) && ts__thread_count(ctx, 2) >= 2 &&
        params->min_drainage > 0) {
        /* both kinds: the drainage (one flood on few threads, tiles side by
         * side on many) while the targets and the ridges are made, then the
         * valleys */
        profile_step ps;
        ps.profile_length = params->profile_length;
        ps.kinds = kinds;
        ps.threshold[0] = threshold[0];
        ps.threshold[1] = threshold[1];
        st = ppa_both_parallel(ctx, dem, km[0], min_length[0], km[1], min_length[1], targets, f,
                               &ps, params->min_drainage);
        if (st != TS_OK)
            goto fail;
        kinds = 0;
    } else {
        sv = ts__progress_push(ctx, 0.0, 0.3);
        st = ppa_profile_targets(ctx, dem, params->profile_length, threshold[0], threshold[1],
                                 kinds, targets);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            goto fail;
    }
    if ((kinds & TS_VALLEY) && params->min_drainage > 0) {
        /* valleys where the water runs: hollows above the channel heads are not targets */
        uint64_t *chan = NULL;
        sv = ts__progress_push(ctx, 0.3, 0.3);
        st = ppa_channels(ctx, dem->width, dem->height, ppa_drainage_tile(ctx), 1,
                          ppa_raster_window, (void *)dem, params->min_drainage, &chan);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            goto fail;
        mask_apply(ctx, n, 2, targets, NULL, chan);
        free(chan);
    }
    if (kinds == (TS_RIDGE | TS_VALLEY) && ts__thread_count(ctx, 2) >= 2) {
        sv = ts__progress_push(ctx, 0.3, 1.0);
        st = ppa_both_parallel(ctx, dem, km[0], min_length[0], km[1], min_length[1], targets, f,
                               NULL, 0);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            goto fail;
        kinds = 0;
    }
    for (k = TS_RIDGE; k <= TS_VALLEY; k <<= 1) {
        if (!(kinds & k))
            continue;
        sv = kinds == (TS_RIDGE | TS_VALLEY)
                 ? ts__progress_push(ctx, k == TS_RIDGE ? 0.3 : 0.65, k == TS_RIDGE ? 0.65 : 1.0)
                 : ts__progress_push(ctx, 0.3, 1.0);
        st = ppa_one_kind(ctx, dem, km[k - 1], targets, k, min_length[k - 1], f, 1);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            goto fail;
    }
    free(targets);
    *out = f;
    return TS_OK;
fail:
    free(targets);
    ts_features_free(f);
    return st;
}
