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

static int branch_cmp_u32(const void *pa, const void *pb)
{
    uint32_t a = *(const uint32_t *)pa, b = *(const uint32_t *)pb;
    return a < b ? -1 : (a > b);
}

static int branch_push(uint32_t **list, size_t *n, size_t *cap, uint32_t v)
{
    if (*n == *cap) {
        size_t ncap = *cap ? *cap * 2 : 1024;
        uint32_t *nl = realloc(*list, ncap * sizeof **list);
        if (!nl)
            return -1;
        *list = nl;
        *cap = ncap;
    }
    (*list)[(*n)++] = v;
    return 0;
}

ts_status ppa_branch_reduction(ts_ctx *ctx, int w, int h, unsigned char *adj,
                               const ts_grid_metrics *m, double min_length)
{
    size_t n = (size_t)w * (size_t)h, i, cap = 0, nb, n_ends = 0, cap_ends = 0, n_next,
           cap_next = 0;
    branch *br = NULL, *btmp = NULL;
    uint32_t *ends = NULL, *next = NULL;
    int changed = 1, pass = 0;
    int64_t min_q = ppa_length_q(min_length);
    /* the endpoints; later passes only revisit endpoints and the junctions
     * that removals touched */
    for (i = 0; i < n; i++)
        if (ppa_degree(adj[i]) == 1 && branch_push(&ends, &n_ends, &cap_ends, (uint32_t)i))
            goto nomem;
    while (changed) {
        walk_job wj;
        changed = 0;
        nb = 0;
        n_next = 0;
        if (n_ends > cap) {
            branch *nbr = realloc(br, n_ends * sizeof *br), *ntmp;
            if (!nbr)
                goto nomem;
            br = nbr;
            if (!(ntmp = realloc(btmp, n_ends * sizeof *btmp)))
                goto nomem;
            btmp = ntmp;
            cap = n_ends;
        }
        wj.adj = adj;
        wj.w = w;
        wj.ends = ends;
        wj.m = m;
        wj.br = br;
        ts__parallel_for(ctx, n_ends, branch_walks, &wj);
        /* isolated paths (their own components: the walks above are not
         * touched by removing them), each once, from its lower end; the
         * branches kept in the order of their ends */
        for (i = 0; i < n_ends; i++) {
            uint32_t start = br[i].start, end = br[i].junction;
            int64_t len = br[i].length;
            if (br[i].remove < 0)
                continue;
            if (br[i].remove == 0) {
                br[nb] = br[i];
                nb++;
                continue;
            }
            if (end < start)
                continue;
            if (len < min_q) {
                branch_remove(adj, w, start, end);
                adj[end] = 0;
                changed = 1;
            } else if (branch_push(&next, &n_next, &cap_next, start) ||
                       branch_push(&next, &n_next, &cap_next, end)) {
                goto nomem;
            }
        }
        branch_sort(br, btmp, nb);
        for (i = 0; i < nb;) {
            size_t j = i, k, leaves;
            int degree, other;
            while (j < nb && br[j].junction == br[i].junction)
                j++;
            leaves = j - i;
            degree = ppa_degree(adj[br[i].junction]);
            other = degree - (int)leaves;
            for (k = i; k < j; k++) {
                size_t rank = k - i; /* 0 = longest */
                if (br[k].length >= min_q)
                    continue;
                if (other <= 0 && rank < 2)
                    continue;
                if (other == 1 && rank == 0)
                    continue;
                br[k].remove = 1;
            }
            i = j;
        }
        for (i = 0; i < nb; i++) {
            if (br[i].remove) {
                branch_remove(adj, w, br[i].start, br[i].junction);
                changed = 1;
            }
        }
        /* next pass: surviving endpoints and junctions that became endpoints */
        for (i = 0; i < nb; i++) {
            uint32_t v = br[i].remove ? br[i].junction : br[i].start;
            if (ppa_degree(adj[v]) == 1 && branch_push(&next, &n_next, &cap_next, v))
                goto nomem;
        }
        /* a junction may have lost several branches: keep each cell once */
        if (n_next) {
            size_t u = 1;
            qsort(next, n_next, sizeof *next, branch_cmp_u32);
            for (i = 1; i < n_next; i++)
                if (next[i] != next[u - 1])
                    next[u++] = next[i];
            n_next = u;
        }
        {
            uint32_t *t = ends;
            size_t tc = cap_ends;
            ends = next;
            cap_ends = cap_next;
            n_ends = n_next;
            next = t;
            cap_next = tc;
        }
        if (++pass % 4 == 0 && ts__progress(ctx, 0.5, "branch reduction") != TS_OK)
            goto out;
    }
out:
    free(btmp);
    free(br);
    free(ends);
    free(next);
    (void)h;
    return ctx->status;
nomem:
    free(btmp);
    free(br);
    free(ends);
    free(next);
    return ts__fail(ctx, TS_ERR_NOMEM, "ppa branch reduction", "out of memory");
}
