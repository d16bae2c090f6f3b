/* The dual-graph link structure of a strip set and the moves on it: the
 * cold half (adjacency, encoding, labels); see striplinks.h. */
#include "striplinks.h"

#include <stdlib.h>
#include <string.h>

/* ---- adjacency -------------------------------------------------------------- */

typedef struct edge_key {
    uint64_t key; /* low end << 32 | high end */
    uint32_t h;   /* half-edge id */
} edge_key;

static int edge_key_compare(const void *pa, const void *pb)
{
    const edge_key *a = pa, *b = pb;
    if (a->key != b->key)
        return a->key < b->key ? -1 : 1;
    return a->h < b->h ? -1 : a->h > b->h;
}

/* Half-edge h = 3t + i runs from tri[h] to tri[next_h(h)]. */
static inline uint32_t next_h(uint32_t h)
{
    return h % 3 == 2 ? h - 2 : h + 1;
}

static inline uint64_t key_of(const uint32_t *tri, uint32_t h)
{
    uint32_t a = tri[h], b = tri[next_h(h)];
    return a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a;
}

/* Sorts the n3 half-edges by (low end, high end, id) into order: two
 * stable counting sorts over the vertex range, O(n + V), when that range is
 * not much larger than the mesh; a comparison sort otherwise, so that a huge
 * vertex_count with few triangles cannot make us allocate for it. Returns 0
 * when out of memory. */
static int sort_half_edges(const uint32_t *tri, uint32_t n3, uint32_t vertex_count,
                           uint32_t *order)
{
    int ok = 0;
    uint32_t *count = NULL, *tmp = NULL;
    edge_key *keys = NULL;
    if ((uint64_t)vertex_count <= 4 * (uint64_t)n3 + 1024) {
        count = calloc((size_t)vertex_count + 1, sizeof *count);
        tmp = malloc((size_t)n3 * sizeof *tmp + 1);
        if (!count || !tmp)
            goto cleanup;
        for (uint32_t h = 0; h < n3; h++)
            count[(uint32_t)key_of(tri, h) + 1]++;
        for (uint32_t v = 0; v < vertex_count; v++)
            count[v + 1] += count[v];
        for (uint32_t h = 0; h < n3; h++)
            tmp[count[(uint32_t)key_of(tri, h)]++] = h;
        memset(count, 0, ((size_t)vertex_count + 1) * sizeof *count);
        for (uint32_t h = 0; h < n3; h++)
            count[(key_of(tri, h) >> 32) + 1]++;
        for (uint32_t v = 0; v < vertex_count; v++)
            count[v + 1] += count[v];
        for (uint32_t k = 0; k < n3; k++)
            order[count[key_of(tri, tmp[k]) >> 32]++] = tmp[k];
    } else {
        keys = malloc((size_t)n3 * sizeof *keys + 1);
        if (!keys)
            goto cleanup;
        for (uint32_t h = 0; h < n3; h++)
            keys[h] = (edge_key){key_of(tri, h), h};
        qsort(keys, n3, sizeof *keys, edge_key_compare);
        for (uint32_t k = 0; k < n3; k++)
            order[k] = keys[k].h;
    }
    ok = 1;
cleanup:
    free(count);
    free(tmp);
    free(keys);
    return ok;
}

mts_result mts__links_adjacency(const uint32_t *tri, uint32_t n, uint32_t vertex_count,
                                uint32_t *nb, const char *who, mts_error *err)
{
    uint32_t n3 = 3 * n;
    uint32_t *order = malloc((size_t)n3 * sizeof *order + 1);
    if (!order || !sort_half_edges(tri, n3, vertex_count, order)) {
        free(order);
        return mts_error_set(err, MTS_ERR_NOMEM,
                             "%s: out of memory for the adjacency of %u triangles", who, n);
    }
    for (uint32_t h = 0; h < n3; h++)
        nb[h] = MTS__NONE;
    for (uint32_t k = 0; k < n3;) {
        uint64_t key = key_of(tri, order[k]);
        uint32_t e = k + 1;
        while (e < n3 && key_of(tri, order[e]) == key)
            e++;
        /* Only an edge with exactly two faces that run through it in
         * opposite directions joins them: a strip across any other edge
         * would draw one of them with the wrong winding. */
        uint32_t h0 = order[k], h1 = order[k + 1 < n3 ? k + 1 : k];
        if (e - k == 2 && tri[h0] != tri[h1]) {
            nb[h0] = h1 / 3;
            nb[h1] = h0 / 3;
        }
        k = e;
    }
    free(order);
    return MTS_OK;
}

/* ---- encoding ----------------------------------------------------------------- */

uint32_t mts__links_encode(const uint32_t *tri, const uint32_t *nb, const uint32_t *path,
                           uint32_t m, uint32_t *out, uint32_t *swaps)
{
    uint32_t t = path[0];
    *swaps = 0;
    if (m == 1) {
        if (out)
            memcpy(out, tri + 3 * (size_t)t, 3 * sizeof *out);
        return 3;
    }
    unsigned e = 0;
    while (e < 3 && nb[3 * (size_t)t + e] != path[1])
        e++;
    if (e == 3)
        return 0;
    /* window 0 = (v_e+2, v_e, v_e+1), a rotation of t; leaves by (v_e, v_e+1) */
    unsigned lq = e, lr = (e + 1) % 3;
    if (out) {
        out[0] = tri[3 * (size_t)t + (e + 2) % 3];
        out[1] = tri[3 * (size_t)t + lq];
        out[2] = tri[3 * (size_t)t + lr];
    }
    uint32_t len = 3;
    for (uint32_t k = 1; k < m; k++) {
        uint32_t u = path[k];
        unsigned lp = 3 - lq - lr, la;
        if (nb[3 * (size_t)t + mts__edge_of(lq, lr)] == u) {
            la = lq;
        } else if (nb[3 * (size_t)t + mts__edge_of(lp, lr)] == u) {
            /* "... p q r" becomes "... p q p r": window (q p r) at the next
             * parity is still t with its winding, and (p r x) is u's */
            la = lp;
            if (out) {
                out[len] = out[len - 1]; /* r, the last index so far */
                out[len - 1] = tri[3 * (size_t)t + lp];
            }
            len++;
            (*swaps)++;
        } else {
            return 0;
        }
        uint32_t va = tri[3 * (size_t)t + la], vr = tri[3 * (size_t)t + lr];
        unsigned ur = mts__local_of(tri, u, vr), ua = mts__local_of(tri, u, va);
        unsigned ux = 3 - ur - ua;
        if (out)
            out[len] = tri[3 * (size_t)u + ux];
        len++;
        t = u;
        lq = ur;
        lr = ux;
    }
    return len;
}

/* ---- labels ----------------------------------------------------------------- */

uint32_t mts__links_path_end(const mts__links *L, uint32_t t)
{
    uint32_t prev = MTS__NONE, cur = t;
    for (uint32_t k = 0; k <= L->n; k++) {
        uint32_t nx = mts__links_step(L, prev, cur);
        if (nx == MTS__NONE)
            return cur;
        prev = cur;
        cur = nx;
    }
    return MTS__NONE;
}

/* Labels the path through t. */
static void label_path(mts__links *L, uint32_t t)
{
    uint32_t first = mts__links_path_end(L, t), k = 0;
    if (first == MTS__NONE)
        return; /* a cycle: cannot happen; the read-out reports it */
    uint32_t prev = MTS__NONE, cur = first;
    while (cur != MTS__NONE) {
        L->pid[cur] = first;
        L->pos[cur] = k++;
        L->lab[cur] = L->lab_stamp;
        uint32_t nx = mts__links_step(L, prev, cur);
        prev = cur;
        cur = nx;
    }
    L->plen[first] = k;
    if (L->pend)
        L->pend[first] = prev;
}

void mts__links_label_all(mts__links *L)
{
    L->lab_stamp = 1;
    for (uint32_t t = 0; t < L->n; t++) {
        if (L->lab[t] != 1)
            label_path(L, t);
    }
}

void mts__links_relabel(mts__links *L, const mts__link_op *ops, int nops)
{
    if (++L->lab_stamp == 0) {
        /* wrapped (only on meshes of over 800 million triangles): forget
         * every old stamp; the labels themselves stay valid */
        memset(L->lab, 0, (size_t)L->n * sizeof *L->lab);
        L->lab_stamp = 1;
    }
    for (int i = 0; i < nops; i++) {
        uint32_t ends[2] = {ops[i].t, ops[i].u};
        for (int e = 0; e < 2; e++) {
            L->touched[ends[e]] = L->pass;
            for (unsigned k = 0; k < 3; k++) {
                uint32_t w = L->nb[3 * (size_t)ends[e] + k];
                if (w != MTS__NONE)
                    L->touched[w] = L->pass;
            }
        }
    }
    /* labelled in the order of the changes: a path is named by the end that
     * its first changed triangle reaches first */
    for (int i = 0; i < nops; i++) {
        if (L->lab[ops[i].t] != L->lab_stamp)
            label_path(L, ops[i].t);
        if (L->lab[ops[i].u] != L->lab_stamp)
            label_path(L, ops[i].u);
    }
}
