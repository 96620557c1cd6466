/*
 * ppa_branch.c - PPA step 4, branch reduction (Zhou et al. 2007 section 3,
 * Fig. 4d).
 *
 * A branch is a chain of cells from an endpoint (degree 1) to the first
 * cell whose degree is not 2.  Branches shorter than the minimum length are
 * removed, in passes, until none is left.  Two rules keep the main axes
 * whole: at a junction with a single non-branch arm, the longest short
 * branch stays (it continues the axis rather than being a side twig); at a
 * junction whose arms are all branches, the two longest stay (they then
 * form one path, judged as a whole in the next pass).  Isolated paths
 * shorter than the minimum and isolated cells go.
 * Cost: O(cells) per pass; a handful of passes in practice.  Each pass
 * walks its branches side by side (the walks only read) and groups them by
 * junction with a radix sort, so the result never depends on the threads.
 */
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

typedef struct branch {
    uint32_t start;    /* the endpoint */
    uint32_t junction; /* first cell of degree != 2 (the other end of an isolated path) */
    int64_t length;    /* fixed point: ppa_length_q */
    int remove;        /* after the walk: -1 no branch, 1 an isolated path, 0 a branch */
} branch;

/* Walk from endpoint `start` until a cell of degree != 2.  Returns the last
 * cell; *length gets the ground length. */
static uint32_t branch_walk(const unsigned char *adj, int w, uint32_t start,
                            const ts_grid_metrics *m, int64_t *length)
{
    uint32_t cur = start;
    int from = -1; /* direction we came in through, seen from cur */
    int64_t len = 0;
    for (;;) {
        unsigned char bits = adj[cur];
        int d, x = (int)(cur % (uint32_t)w), y = (int)(cur / (uint32_t)w);
        if (from >= 0)
            bits &= (unsigned char)~(1u << from);
        if (cur != start && ppa_degree(adj[cur]) != 2)
            break;
        if (!bits)
            break;
        d = __builtin_ctz(bits);
        len += ppa_step_q(m, y, d);
        cur = (uint32_t)((y + ppa_dir[d][1]) * w + x + ppa_dir[d][0]);
        from = (d + 4) & 7;
    }
    *length = len;
    return cur;
}

/* Remove the chain from endpoint `start` up to (not including) `stop`. */
static void branch_remove(unsigned char *adj, int w, uint32_t start, uint32_t stop)
{
    uint32_t cur = start;
    while (cur != stop) {
        unsigned char bits = adj[cur];
        int x = (int)(cur % (uint32_t)w), y = (int)(cur / (uint32_t)w), d;
        uint32_t next;
        if (!bits)
            break;
        d = __builtin_ctz(bits);
        next = (uint32_t)((y + ppa_dir[d][1]) * w + x + ppa_dir[d][0]);
        adj[cur] = 0;
        adj[next] &= (unsigned char)~(1u << ((d + 4) & 7));
        cur = next;
    }
}

/* (junction, longest first, then start): a total order */
static int branch_before(const branch *a, const branch *b)
{
    if (a->junction != b->junction)
        return a->junction < b->junction;
    if (a->length != b->length)
        return a->length > b->length;
    return a->start < b->start;
}

/* br sorted by branch_before: a stable radix sort on the junction, then
 * each junction's few branches (at most 8) by insertion. */
static void branch_sort(branch *br, branch *tmp, size_t n)
{
    size_t i, j;
    int pass;
    for (pass = 0; pass < 4 && n; pass++) {
        size_t count[257] = {0};
        int shift = pass * 8, b;
        for (i = 0; i < n; i++)
            count[((br[i].junction >> shift) & 0xffu) + 1]++;
        if (count[((br[0].junction >> shift) & 0xffu) + 1] == n)
            continue;
        for (b = 0; b < 256; b++)
            count[b + 1] += count[b];
        for (i = 0; i < n; i++)
            tmp[count[(br[i].junction >> shift) & 0xffu]++] = br[i];
        memcpy(br, tmp, n * sizeof *br);
    }
    for (i = 1; i < n; i++)
        for (j = i; j > 0 && br[j].junction == br[j - 1].junction && branch_before(&br[j], &br[j - 1]);
             j--) {
            branch t = br[j];
            br[j] = br[j - 1];
            br[j - 1] = t;
        }
}

typedef struct walk_job {
    const unsigned char *adj;
    int w;
    const uint32_t *ends;
    const ts_grid_metrics *m;
    branch *br; /* one per end */
} walk_job;

/* Walk the branch of each end (reads adj only). */
static void branch_walks(void *arg, size_t begin, size_t end)
{
    walk_job *j = arg;
    size_t i;
    for (i = begin; i < end; i++) {
        branch *b = &j->br[i];
        b->start = j->ends[i];
        b->remove = -1;
        if (ppa_degree(j->adj[b->start]) != 1)
            continue;
        b->junction = branch_walk(j->adj, j->w, b->start, j->m, &b->length);
        b->remove = ppa_degree(j->adj[b->junction]) == 1;
    }
}

/* A pass after the walks, in buckets of rows (fixed by the raster, not by
 * the threads): each branch goes to the bucket of its junction, each
 * isolated path (once, from its lower end) to the bucket of its start, so
 * a junction's branches are decided and removed by one thread; the chains
 * removed are disjoint (a cell of degree 2 is on one chain), so the
 * buckets run side by side and the result never depends on the threads. */
#define BR_CHUNKS 64

typedef struct pass_job {
    unsigned char *adj;
    int w, h, nbk;
    int64_t min_q;
    branch *br, *sorted;  /* the walks, by end; by bucket */
    size_t n, *count;     /* count[c * nbk + b]: chunk c's items of bucket b, then
                             where they go */
    size_t *bs;           /* bucket b's items: sorted[bs[b] .. bs[b + 1]) */
    uint32_t *nx;         /* bucket b's next ends from nx[2 bs[b]] */
    size_t *n_nx;         /* how many */
    unsigned char *changed; /* per bucket */
} pass_job;

static int branch_bucket(const pass_job *j, const branch *b)
{
    uint32_t v = b->remove ? b->start : b->junction;
    return (int)((uint64_t)(v / (uint32_t)j->w) * (uint64_t)j->nbk / (uint64_t)j->h);
}

static int branch_kept(const branch *b)
{
    return b->remove == 0 || (b->remove == 1 && b->junction > b->start);
}

static void pass_count(void *arg, size_t begin, size_t end)
{
    pass_job *j = arg;
    size_t c, i, per = (j->n + BR_CHUNKS - 1) / BR_CHUNKS;
    for (c = begin; c < end; c++) {
        size_t *cnt = j->count + c * (size_t)j->nbk;
        for (i = c * per; i < TS_MIN(j->n, (c + 1) * per); i++)
            if (branch_kept(&j->br[i]))
                cnt[branch_bucket(j, &j->br[i])]++;
    }
}

static void pass_scatter(void *arg, size_t begin, size_t end)
{
    pass_job *j = arg;
    size_t c, i, per = (j->n + BR_CHUNKS - 1) / BR_CHUNKS;
    for (c = begin; c < end; c++) {
        size_t *at = j->count + c * (size_t)j->nbk;
        for (i = c * per; i < TS_MIN(j->n, (c + 1) * per); i++)
            if (branch_kept(&j->br[i]))
                j->sorted[at[branch_bucket(j, &j->br[i])]++] = j->br[i];
    }
}

/* Decide and remove bucket by bucket; each bucket's next ends. */
static void pass_buckets(void *arg, size_t begin, size_t end)
{
    pass_job *j = arg;
    size_t b;
    for (b = begin; b < end; b++) {
        branch *br = j->sorted + j->bs[b];
        size_t n = j->bs[b + 1] - j->bs[b], i, nb = 0, k0;
        uint32_t *nx = j->nx + 2 * j->bs[b];
        size_t m = 0;
        unsigned char changed = 0;
        /* isolated paths first (their own components) */
        for (i = 0; i < n; i++) {
            if (br[i].remove == 0) {
                br[nb++] = br[i];
                continue;
            }
            if (br[i].length < j->min_q) {
                branch_remove(j->adj, j->w, br[i].start, br[i].junction);
                j->adj[br[i].junction] = 0;
                changed = 1;
            } else {
                nx[m++] = br[i].start;
                nx[m++] = br[i].junction;
            }
        }
        branch_sort(br, j->br + j->bs[b], nb); /* the walks' slots of the bucket: free now */
        for (i = 0; i < nb; i = k0) {
            size_t k, leaves;
            int degree, other, any = 0;
            for (k0 = i; k0 < nb && br[k0].junction == br[i].junction; k0++)
                ;
            leaves = k0 - i;
            degree = ppa_degree(j->adj[br[i].junction]);
            other = degree - (int)leaves;
            for (k = i; k < k0; k++) {
                size_t rank = k - i; /* 0 = longest */
                if (br[k].length >= j->min_q || (other <= 0 && rank < 2) ||
                    (other == 1 && rank == 0)) {
                    if (ppa_degree(j->adj[br[k].start]) == 1)
                        nx[m++] = br[k].start;
                    continue;
                }
                branch_remove(j->adj, j->w, br[k].start, br[k].junction);
                changed = 1;
                any = 1;
            }
            /* a junction that lost all but one arm is an endpoint now */
            if (any && ppa_degree(j->adj[br[i].junction]) == 1)
                nx[m++] = br[i].junction;
        }
        j->n_nx[b] = m;
        j->changed[b] = changed;
    }
}

/* The initial endpoints, in chunks of cells: counted, then written in order. */
static void ends_count(void *arg, size_t begin, size_t end)
{
    pass_job *j = arg;
    size_t c, i, n = (size_t)j->w * (size_t)j->h, per = (n + BR_CHUNKS - 1) / BR_CHUNKS;
    for (c = begin; c < end; c++) {
        size_t cnt = 0;
        for (i = c * per; i < TS_MIN(n, (c + 1) * per); i++)
            cnt += ppa_degree(j->adj[i]) == 1;
        j->count[c] = cnt;
    }
}

static void ends_fill(void *arg, size_t begin, size_t end)
{
    pass_job *j = arg;
    size_t c, i, n = (size_t)j->w * (size_t)j->h, per = (n + BR_CHUNKS - 1) / BR_CHUNKS;
    for (c = begin; c < end; c++) {
        size_t at = j->count[c];
        for (i = c * per; i < TS_MIN(n, (c + 1) * per); i++)
            if (ppa_degree(j->adj[i]) == 1)
                j->nx[at++] = (uint32_t)i;
    }
}

ts_status ppa_branch_reduction(ts_ctx *ctx, int w, int h, unsigned char *adj,
                               const ts_grid_metrics *m, double min_length)
{
    size_t n_ends = 0, cap = 0, c, b, total;
    branch *br = NULL, *sorted = NULL;
    uint32_t *ends = NULL, *nx = NULL;
    size_t *count = NULL, *bs = NULL, *n_nx = NULL;
    unsigned char *changed = NULL;
    int any = 1, pass = 0;
    ts_status st;
    pass_job pj;
    memset(&pj, 0, sizeof pj);
    pj.adj = adj;
    pj.w = w;
    pj.h = h;
    pj.nbk = TS_MAX(1, TS_MIN(1024, h / 8));
    pj.min_q = ppa_length_q(min_length);
    count = ts__calloc_array((size_t)BR_CHUNKS * (size_t)pj.nbk + 1, sizeof *count);
    bs = ts__malloc_array((size_t)pj.nbk + 1, sizeof *bs);
    n_nx = ts__malloc_array((size_t)pj.nbk, sizeof *n_nx);
    changed = ts__malloc_array((size_t)pj.nbk, 1);
    if (!count || !bs || !n_nx || !changed)
        goto nomem;
    /* the endpoints; later passes only revisit endpoints and the junctions
     * that removals touched */
    pj.count = count;
    ts__parallel_for(ctx, BR_CHUNKS, ends_count, &pj);
    for (c = 0, total = 0; c < BR_CHUNKS; c++) {
        size_t t = count[c];
        count[c] = total;
        total += t;
    }
    n_ends = total;
    cap = TS_MAX(n_ends, 1);
    ends = ts__malloc_array(cap, sizeof *ends);
    br = ts__malloc_array(cap, sizeof *br);
    sorted = ts__malloc_array(cap, sizeof *sorted);
    nx = ts__malloc_array(2 * cap, sizeof *nx);
    if (!ends || !br || !sorted || !nx)
        goto nomem;
    pj.nx = ends;
    ts__parallel_for(ctx, BR_CHUNKS, ends_fill, &pj);
    while (any) {
        walk_job wj;
        wj.adj = adj;
        wj.w = w;
        wj.ends = ends;
        wj.m = m;
        wj.br = br;
        ts__parallel_for(ctx, n_ends, branch_walks, &wj);
        /* group by bucket: counted in fixed chunks, then scattered in order */
        pj.br = br;
        pj.sorted = sorted;
        pj.n = n_ends;
        pj.count = count;
        pj.bs = bs;
        pj.nx = nx;
        pj.n_nx = n_nx;
        pj.changed = changed;
        memset(count, 0, (size_t)BR_CHUNKS * (size_t)pj.nbk * sizeof *count);
        ts__parallel_for(ctx, BR_CHUNKS, pass_count, &pj);
        for (b = 0, total = 0; b < (size_t)pj.nbk; b++) {
            bs[b] = total;
            for (c = 0; c < BR_CHUNKS; c++) {
                size_t t = count[c * (size_t)pj.nbk + b];
                count[c * (size_t)pj.nbk + b] = total;
                total += t;
            }
        }
        bs[pj.nbk] = total;
        ts__parallel_for(ctx, BR_CHUNKS, pass_scatter, &pj);
        ts__parallel_for(ctx, (size_t)pj.nbk, pass_buckets, &pj);
        /* next pass: surviving endpoints and junctions that became
         * endpoints, bucket by bucket */
        any = 0;
        for (b = 0, total = 0; b < (size_t)pj.nbk; b++) {
            memcpy(ends + total, nx + 2 * bs[b], n_nx[b] * sizeof *ends);
            total += n_nx[b];
            any |= changed[b];
        }
        n_ends = total;
        if (++pass % 4 == 0 && ts__progress(ctx, 0.5, "branch reduction") != TS_OK)
            break;
    }
    st = ctx->status;
    goto out;
nomem:
    st = ts__fail(ctx, TS_ERR_NOMEM, "ppa branch reduction", "out of memory");
out:
    free(count);
    free(bs);
    free(n_nx);
    free(changed);
    free(ends);
    free(br);
    free(sorted);
    free(nx);
    return st;
}
