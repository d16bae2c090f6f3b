/* LOD builder: strips grown upward from the base with key levels (see
 * lodbuild.h for the why): growth alone wears the strips down, replaying
 * collapses downward from the full strips wears them faster, and a key
 * level once the strips have worn to MTS_LODBUILD_KEY_QUALITY keeps every
 * level near it with the fewest key triangles for clients to restripify.
 * The measurements behind the choice are in docs/client-cost.md. */
#include "lodbuild.h"

#include <stdlib.h>
#include <string.h>

#include "grow.h"
#include "stripify.h"
#include "words.h"
#include "tunnel.h"


/* The full mesh's view of the levels: what each split truly brings back,
 * from the collapse chains, against which the fan rule is checked. */
typedef struct truth {
    uint32_t nb, n;
    const uint32_t *parent; /* n, stream ids */
    uint32_t (*corner)[3];  /* full-level vertices of each triangle, stream ids */
    uint32_t *birth;        /* first level at which it is not degenerate */
    uint32_t *born_off, *born;
    /* per vertex v >= nb: the (triangle, corner) pairs whose vertex becomes
     * v when v is split off (every corner whose collapse chain passes v) */
    uint32_t *chain_off, *chain;
} truth;

static uint32_t ancestor(const truth *tr, uint32_t w, uint32_t level)
{
    while (w >= tr->nb + level)
        w = tr->parent[w - tr->nb];
    return w;
}

static void image(const truth *tr, uint32_t t, uint32_t level, uint32_t out[3])
{
    for (int c = 0; c < 3; c++)
        out[c] = ancestor(tr, tr->corner[t][c], level);
}

static int cmp_tri(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (int c = 0; c < 3; c++) {
        if (x[c] != y[c])
            return x[c] < y[c] ? -1 : 1;
    }
    return 0;
}

static void truth_free(truth *tr)
{
    free(tr->corner);
    free(tr->birth);
    free(tr->born_off);
    free(tr->born);
    free(tr->chain_off);
    free(tr->chain);
}

/* Describes split j (level j to j + 1) for mts_grow_next: by the fan rule
 * when it reproduces the truth, else explicitly. The lists live in the
 * scratch arrays. */
typedef struct describer {
    mts_words moved_tris, fan_tris, born, ids;
    uint32_t explicit_splits;
} describer;

static mts_result describe_explicitly(const truth *tr, const mts_grow *g, uint32_t j,
                                      describer *d, mts_grow_split *sp, mts_error *err);

static mts_result describe_split(const truth *tr, const mts_grow *g, uint32_t j, describer *d,
                                 mts_grow_split *sp, mts_error *err)
{
    const uint32_t u = tr->parent[j], v = tr->nb + j, level = j + 1;
    memset(sp, 0, sizeof *sp);
    sp->parent = u;
    sp->left = sp->right = MTS_GROW_NONE;
    /* the triangles v truly takes over, at level j, canonical and sorted */
    d->moved_tris.n = 0;
    for (uint32_t k = tr->chain_off[v]; k < tr->chain_off[v + 1]; k++) {
        uint32_t t = tr->chain[k] / 3;
        if (tr->birth[t] > j || (d->moved_tris.n && d->ids.w[d->ids.n - 1] == t))
            continue;
        if (!mts_words_reserve(&d->moved_tris, 3) || !mts_words_reserve(&d->ids, 1))
            goto nomem;
        uint32_t *x = d->moved_tris.w + d->moved_tris.n;
        image(tr, t, j, x);
        mts_tri_canonical(x);
        d->moved_tris.n += 3;
        d->ids.w[d->ids.n++] = t;
    }
    d->ids.n = 0;
    size_t moved = d->moved_tris.n / 3;
    qsort(d->moved_tris.w, moved, 12, cmp_tri);
    /* the new triangles, at level j + 1 */
    int fan_ok = 1;
    d->born.n = 0;
    for (uint32_t k = tr->born_off[level]; k < tr->born_off[level + 1]; k++) {
        if (!mts_words_reserve(&d->born, 3))
            goto nomem;
        uint32_t *x = d->born.w + d->born.n;
        image(tr, tr->born[k], level, x);
        d->born.n += 3;
        int c = x[0] == u ? 0 : x[1] == u ? 1 : x[2] == u ? 2 : -1;
        if (c < 0) {
            fan_ok = 0;
        } else if (x[(c + 1) % 3] == v && sp->left == MTS_GROW_NONE) {
            sp->left = x[(c + 2) % 3];
        } else if (x[(c + 2) % 3] == v && sp->right == MTS_GROW_NONE) {
            sp->right = x[(c + 1) % 3];
        } else {
            fan_ok = 0;
        }
    }
    if (d->born.n > 6 || (sp->left == MTS_GROW_NONE && sp->right == MTS_GROW_NONE))
        fan_ok = 0;
    if (fan_ok) {
        int32_t k = mts_grow_fan(g, u, sp->left, sp->right, NULL, 0);
        if (k >= 0 && (size_t)k == moved) {
            if (!mts_words_reserve(&d->ids, (size_t)k) || !mts_words_reserve(&d->fan_tris, 3 * (size_t)k))
                goto nomem;
            mts_grow_fan(g, u, sp->left, sp->right, d->ids.w, (uint32_t)k);
            for (int32_t q = 0; q < k; q++) {
                uint32_t *x = d->fan_tris.w + 3 * (size_t)q;
                mts_grow_triangle(g, d->ids.w[q], x);
                mts_tri_canonical(x);
            }
            qsort(d->fan_tris.w, (size_t)k, 12, cmp_tri);
            if (memcmp(d->fan_tris.w, d->moved_tris.w, (size_t)k * 12) == 0)
                return MTS_OK;
        }
    }
    return describe_explicitly(tr, g, j, d, sp, err);
nomem:
    return mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
}

/* The split as lists: the moved triangles by id, the new ones by vertices
 * (d->moved_tris and d->born as describe_split left them). */
static mts_result describe_explicitly(const truth *tr, const mts_grow *g, uint32_t j,
                                      describer *d, mts_grow_split *sp, mts_error *err)
{
    (void)tr;
    size_t moved = d->moved_tris.n / 3;
    d->explicit_splits++;
    if (!mts_words_reserve(&d->ids, moved))
        goto nomem;
    for (size_t q = 0; q < moved; q++) {
        const uint32_t *x = d->moved_tris.w + 3 * q;
        int32_t t = mts_grow_find(g, x[0], x[1], x[2]);
        if (t < 0)
            return mts_error_set(err, MTS_ERR_INTERNAL,
                                 "lodbuild: split %u moves (%u %u %u), not a live triangle", j,
                                 x[0], x[1], x[2]);
        d->ids.w[q] = (uint32_t)t;
    }
    sp->left = sp->right = MTS_GROW_NONE;
    sp->moved = d->ids.w;
    sp->moved_count = (uint32_t)moved;
    sp->born = d->born.w;
    sp->born_count = (uint32_t)(d->born.n / 3);
    if (sp->moved_count == 0 && sp->born_count == 0)
        return mts_error_set(err, MTS_ERR_INTERNAL, "lodbuild: split %u changes no triangle", j);
    return MTS_OK;
nomem:
    return mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
}

/* The base mesh's strips in the form growth derives: stripified, tunnelled,
 * longest first. */
static mts_result base_strips(const truth *tr, mts_strips *out, mts_error *err)
{
    uint32_t live = tr->born_off[1];
    uint32_t *tris = malloc(((size_t)live + 1) * 12);
    if (!tris)
        return mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
    for (uint32_t k = 0; k < live; k++)
        image(tr, tr->born[k], 0, tris + 3 * (size_t)k);
    mts_strips strips = {0}, tunnelled = {0};
    mts_tunnel_options to = {0};
    to.length = MTS_TUNNEL_DEFAULT_LENGTH;
    mts_result rc = mts_stripify(tris, live, tr->nb, &strips, NULL, err);
    free(tris);
    if (rc == MTS_OK)
        rc = mts_tunnel(&strips, tr->nb, &to, &tunnelled, NULL, err);
    mts_strips_free(&strips);
    if (rc != MTS_OK)
        return rc;
    mts_grow_options go = {0};
    go.normalise_base = 1;
    mts_grow *g = NULL;
    rc = mts_grow_create(&tunnelled, tr->nb, tr->n, &go, &g, err);
    mts_strips_free(&tunnelled);
    if (rc != MTS_OK)
        return rc;
    mts_grow_figures fig;
    mts_grow_get_figures(g, &fig);
    uint64_t total = fig.indices;
    if (total > UINT32_MAX - 1)
        rc = mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: %llu base strip indices",
                           (unsigned long long)total);
    else
        rc = mts_strips_alloc(out, fig.slot_count, (uint32_t)total, err);
    if (rc == MTS_OK) {
        uint32_t o = 0;
        for (uint32_t s = 0; s < fig.slot_count; s++) {
            uint32_t len;
            const uint32_t *w = mts_grow_slot(g, s, &len);
            out->offsets[s] = o;
            if (len)
                memcpy(out->indices + o, w, (size_t)len * 4);
            o += len;
        }
        out->offsets[fig.slot_count] = o;
    }
    mts_grow_free(g);
    return rc;
}

/* The caller's full strips in stream ids (new_id): the last key level. */
static mts_result take_full(const mts_strips *strips, const uint32_t *new_id, uint32_t nv,
                            mts_strips *given, mts_error *err)
{
    if (!strips)
        return mts_error_set(err, MTS_ERR_ARG, "lodbuild: no full strips came");
    for (uint32_t i = 0; i < strips->index_count; i++) {
        if (strips->indices[i] >= nv)
            return mts_error_set(err, MTS_ERR_RANGE, "lodbuild: strip index %u out of range",
                                 strips->indices[i]);
    }
    mts_result rc = mts_strips_alloc(given, strips->strip_count, strips->index_count, err);
    if (rc != MTS_OK)
        return rc;
    memcpy(given->offsets, strips->offsets, ((size_t)strips->strip_count + 1) * 4);
    for (uint32_t i = 0; i < strips->index_count; i++)
        given->indices[i] = new_id[strips->indices[i]];
    return MTS_OK;
}

mts_result mts_lodbuild(const mts_mesh *mesh, const mts_strips *strips,
                        const mts_simplify_result *simp, const mts_lodbuild_options *opts,
                        const mts_progress *progress, mts_model *model,
                        mts_lodbuild_stats *stats_out, mts_error *err)
{
    mts_result rc = MTS_ERR_NOMEM;
    truth tr = {0};
    describer d = {0};
    mts_words rec = {0}, growth = {0};
    mts_grow *g = NULL;
    uint32_t *new_id = NULL, *parents = NULL, *rec_off = NULL;
    mts_strips given = {0};
    const uint32_t nv = mesh->vertex_count;
    const uint32_t n = simp->collapse_count;
    const uint32_t F = mesh->triangle_count;
    double ratio = opts && opts->key_ratio != 0 ? opts->key_ratio : MTS_LODBUILD_DEFAULT_KEY_RATIO;
    memset(model, 0, sizeof *model);

    if (n >= nv)
        return mts_error_set(err, MTS_ERR_ARG, "lodbuild: %u collapses for %u vertices", n, nv);
    if (F > (UINT32_MAX - 2) / 3 || F > INT32_MAX / 2)
        return mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: %u triangles is too many", F);
    if (!strips && !(opts && opts->full_strips))
        return mts_error_set(err, MTS_ERR_ARG, "lodbuild: no full strips, nor a way to get them");
    for (size_t i = 0; i < 3 * (size_t)F; i++) {
        if (mesh->triangles[i] >= nv)
            return mts_error_set(err, MTS_ERR_RANGE, "lodbuild: triangle index %u out of range",
                                 mesh->triangles[i]);
    }

    /* Stream order: survivors keep their relative order, then the collapsed
     * vertices, last collapsed first. */
    const uint32_t nb = nv - n;
    new_id = malloc(((size_t)nv + 1) * 4);
    parents = malloc(((size_t)n + 1) * 4);
    if (!new_id || !parents)
        goto nomem;
    for (uint32_t v = 0; v < nv; v++)
        new_id[v] = UINT32_MAX;
    for (uint32_t c = 0; c < n; c++) {
        const uint32_t v = simp->collapses[c].removed, u = simp->collapses[c].kept;
        if (v >= nv || u >= nv || v == u) {
            rc = mts_error_set(err, MTS_ERR_RANGE, "lodbuild: collapse %u (%u -> %u) is invalid",
                               c, v, u);
            goto fail;
        }
        if (new_id[v] != UINT32_MAX) {
            rc = mts_error_set(err, MTS_ERR_ARG, "lodbuild: vertex %u collapses twice", v);
            goto fail;
        }
        new_id[v] = nb + (n - 1 - c);
    }
    /* the survivors: their given ids (each once, below nb), else in vertex
     * order */
    const uint32_t *ids = opts ? opts->base_ids : NULL;
    uint8_t *seen = ids ? calloc((size_t)nb + 1, 1) : NULL;
    if (ids && !seen)
        goto nomem;
    uint32_t bad = UINT32_MAX;
    for (uint32_t v = 0, next_id = 0; v < nv && bad == UINT32_MAX; v++) {
        if (new_id[v] != UINT32_MAX)
            continue; /* collapsed */
        new_id[v] = ids ? ids[v] : next_id++;
        if (ids && (new_id[v] >= nb || seen[new_id[v]]++))
            bad = v;
    }
    free(seen);
    if (bad != UINT32_MAX) {
        rc = mts_error_set(err, MTS_ERR_ARG,
                           "lodbuild: base id %u (vertex %u) given twice, or not below %u",
                           new_id[bad], bad, nb);
        goto fail;
    }
    for (uint32_t c = 0; c < n; c++) {
        uint32_t kept = new_id[simp->collapses[c].kept], j = n - 1 - c;
        if (kept >= nb + j) {
            rc = mts_error_set(err, MTS_ERR_ARG,
                               "lodbuild: collapse %u keeps vertex %u after it was removed", c,
                               simp->collapses[c].kept);
            goto fail;
        }
        parents[j] = kept;
    }

    tr.nb = nb;
    tr.n = n;
    tr.parent = parents;
    tr.corner = malloc(((size_t)F + 1) * 12);
    tr.birth = malloc(((size_t)F + 1) * 4);
    tr.chain_off = calloc((size_t)nv + 2, 4);
    tr.born_off = calloc((size_t)n + 3, 4);
    tr.born = malloc(((size_t)F + 1) * 4);
    rec_off = malloc(((size_t)n + 1) * 4);
    model->growth_offsets = malloc(((size_t)n + 1) * 4);
    model->level_triangles = malloc(((size_t)n + 1) * 4);
    model->level_strips = malloc(((size_t)n + 1) * 4);
    model->level_indices = malloc(((size_t)n + 1) * 4);
    if (!tr.corner || !tr.birth || !tr.chain_off || !tr.born_off || !tr.born || !rec_off ||
        !model->growth_offsets ||
        !model->level_triangles || !model->level_strips || !model->level_indices)
        goto nomem;

    /* Each triangle's first level: the lowest at which its corners' images
     * are three vertices (images only merge going down). */
    for (uint32_t t = 0; t < F; t++) {
        for (int c = 0; c < 3; c++)
            tr.corner[t][c] = new_id[mesh->triangles[3 * (size_t)t + c]];
        uint32_t lo = 0, hi = n + 1;
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo) / 2;
            uint32_t x[3];
            image(&tr, t, mid, x);
            if (x[0] != x[1] && x[1] != x[2] && x[0] != x[2])
                hi = mid;
            else
                lo = mid + 1;
        }
        if (lo > n) {
            rc = mts_error_set(err, MTS_ERR_ARG, "lodbuild: triangle %u repeats a vertex", t);
            goto fail;
        }
        tr.birth[t] = lo;
        tr.born_off[lo + 1]++;
    }
    for (uint32_t l = 0; l <= n; l++)
        tr.born_off[l + 1] += tr.born_off[l];
    {
        uint32_t *fill = calloc((size_t)n + 2, 4);
        if (!fill)
            goto nomem;
        for (uint32_t t = 0; t < F; t++)
            tr.born[tr.born_off[tr.birth[t]] + fill[tr.birth[t]]++] = t;
        free(fill);
    }
    /* Corner chains: the corners whose vertex becomes v when v splits off. */
    uint64_t chain_total = 0;
    for (uint32_t t = 0; t < F; t++) {
        for (int c = 0; c < 3; c++) {
            for (uint32_t w = tr.corner[t][c]; w >= nb; w = parents[w - nb]) {
                tr.chain_off[w + 1]++;
                chain_total++;
            }
        }
    }
    if (chain_total > UINT32_MAX - 1) {
        rc = mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: collapse chains too deep (%llu links)",
                           (unsigned long long)chain_total);
        goto fail;
    }
    for (uint32_t v = 0; v < nv; v++)
        tr.chain_off[v + 1] += tr.chain_off[v];
    tr.chain = malloc((chain_total + 1) * 4);
    {
        uint32_t *fill = calloc((size_t)nv + 1, 4);
        if (!tr.chain || !fill) {
            free(fill);
            goto nomem;
        }
        for (uint32_t t = 0; t < F; t++) {
            for (uint32_t c = 0; c < 3; c++) {
                for (uint32_t w = tr.corner[t][c]; w >= nb; w = parents[w - nb])
                    tr.chain[tr.chain_off[w] + fill[w]++] = 3 * t + c;
            }
        }
        free(fill);
    }

    if (strips && (rc = take_full(strips, new_id, nv, &given, err)) != MTS_OK)
        goto fail;

    /* Level 0: the base mesh, stripified and tunnelled, in the form growth
     * derives; growth then starts from it exactly as a client does. */
    if ((rc = base_strips(&tr, &model->base, err)) != MTS_OK)
        goto fail;
    mts_grow_options go = {0};
    go.key_ratio = ratio > 1 ? ratio : -1;
    if (ratio > 1) {
        go.key_quality = MTS_LODBUILD_KEY_QUALITY;
        go.key_min_ratio = MTS_LODBUILD_KEY_MIN_RATIO;
    }
    if ((rc = mts_grow_create(&model->base, nb, n, &go, &g, err)) != MTS_OK)
        goto fail;
    mts_grow_figures fig;
    mts_grow_get_figures(g, &fig);
    if (fig.indices > UINT32_MAX) {
        rc = mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: the base has too many strip indices");
        goto fail;
    }
    model->level_triangles[0] = fig.triangles;
    model->level_strips[0] = fig.strips;
    model->level_indices[0] = (uint32_t)fig.indices;

    for (uint32_t j = 0; j < n; j++) {
        mts_grow_split sp;
        if ((rc = describe_split(&tr, g, j, &d, &sp, err)) != MTS_OK)
            goto fail;
        mts_grow_fan_code code;
        if (!sp.moved_count && !sp.born_count &&
            !mts_grow_fan_encode(g, sp.parent, sp.left, sp.right, &code)) {
            /* a fan, but not one the ring code reaches: say it explicitly */
            if ((rc = describe_explicitly(&tr, g, j, &d, &sp, err)) != MTS_OK)
                goto fail;
        }
        model->growth_offsets[j] = (uint32_t)growth.n;
        if (!mts_words_reserve(&growth, 5 + (size_t)sp.moved_count + 3 * (size_t)sp.born_count))
            goto nomem;
        if (sp.moved_count || sp.born_count) {
            growth.w[growth.n++] = 0;
            growth.w[growth.n++] = 0;
            growth.w[growth.n++] = MTS_GROWTH_EXPLICIT;
            growth.w[growth.n++] = sp.moved_count;
            growth.w[growth.n++] = sp.born_count;
            memcpy(growth.w + growth.n, sp.moved, (size_t)sp.moved_count * 4);
            growth.n += sp.moved_count;
            memcpy(growth.w + growth.n, sp.born, (size_t)sp.born_count * 12);
            growth.n += 3 * (size_t)sp.born_count;
        } else {
            growth.w[growth.n++] = code.start;
            growth.w[growth.n++] = code.count;
            growth.w[growth.n++] = code.sides;
        }
        const uint32_t *r;
        uint32_t words_in;
        if (j + 1 == n && !strips) { /* the full strips, now that they are needed */
            const mts_strips *late = NULL;
            if ((rc = opts->full_strips(opts->full_strips_user, &late, err)) != MTS_OK)
                goto fail;
            if ((rc = take_full(late, new_id, nv, &given, err)) != MTS_OK)
                goto fail;
        }
        mts_grow_full gf = {.strips = &given, .slot_count = 0};
        if ((rc = mts_grow_next(g, &sp, &gf, &r, &words_in, err)) != MTS_OK)
            goto fail;
        rec_off[j] = (uint32_t)rec.n;
        if (!mts_words_reserve(&rec, words_in))
            goto nomem;
        memcpy(rec.w + rec.n, r, (size_t)words_in * 4);
        rec.n += words_in;
        if (rec.n > UINT32_MAX - 1) {
            rc = mts_error_set(err, MTS_ERR_LIMIT,
                               "lodbuild: the records take %zu words, more than 32-bit offsets "
                               "reach",
                               rec.n);
            goto fail;
        }
        mts_grow_get_figures(g, &fig);
        if (fig.indices > UINT32_MAX) {
            rc = mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: level %u has %llu strip indices",
                               j + 1, (unsigned long long)fig.indices);
            goto fail;
        }
        model->level_triangles[j + 1] = fig.triangles;
        model->level_strips[j + 1] = fig.strips;
        model->level_indices[j + 1] = (uint32_t)fig.indices;
        if ((j & 1023) == 0)
            mts_progress_report(progress, "records", (double)j / n);
    }
    rec_off[n] = (uint32_t)rec.n;
    if (growth.n > UINT32_MAX - 1) {
        rc = mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: the split descriptions are too long");
        goto fail;
    }
    model->growth_offsets[n] = (uint32_t)growth.n;
    model->growth_word_count = (uint32_t)growth.n;
    model->growth_data = growth.w ? growth.w : malloc(4);
    growth.w = NULL;
    {
        uint32_t kc;
        const uint32_t *keys = mts_grow_keys(g, &kc);
        kc -= kc && keys[kc - 1] == n; /* the full level is implicit */
        model->key_count = kc;
        model->key_levels = malloc(((size_t)kc + 1) * 4);
        if (!model->growth_data || !model->key_levels)
            goto nomem;
        if (kc)
            memcpy(model->key_levels, keys, (size_t)kc * 4);
    }
    mts_grow_get_figures(g, &fig);

    model->vertex_count = nv;
    model->base_vertex_count = nb;
    model->level_count = n;
    model->strip_count = fig.slot_count;
    model->positions = malloc((size_t)nv * 12 + 1);
    model->normals = malloc((size_t)nv * 12 + 1);
    model->capacity = malloc(((size_t)fig.slot_count + 1) * 4);
    if (!model->positions || !model->normals || !model->capacity)
        goto nomem;
    memcpy(model->capacity, fig.capacity, (size_t)fig.slot_count * 4);
    model->flags = mesh->normals_given ? MTS_MODEL_NORMALS_GIVEN : 0;
    if (mesh->colors) {
        model->colors = malloc((size_t)nv * 3 + 1);
        if (!model->colors)
            goto nomem;
        model->flags |= MTS_MODEL_COLORS;
    }
    for (int a = 0; a < 3; a++) {
        model->bbox_min[a] = nv ? mesh->positions[a] : 0;
        model->bbox_max[a] = nv ? mesh->positions[a] : 0;
    }
    for (uint32_t v = 0; v < nv; v++) {
        memcpy(model->positions + 3 * (size_t)new_id[v], mesh->positions + 3 * (size_t)v, 12);
        memcpy(model->normals + 3 * (size_t)new_id[v], mesh->normals + 3 * (size_t)v, 12);
        /* a collapse keeps one of its two vertices where it was, so each
         * vertex's colour is the source vertex's at every level */
        if (model->colors)
            memcpy(model->colors + 3 * (size_t)new_id[v], mesh->colors + 3 * (size_t)v, 3);
        for (int a = 0; a < 3; a++) {
            float x = mesh->positions[3 * (size_t)v + a];
            if (x < model->bbox_min[a])
                model->bbox_min[a] = x;
            if (x > model->bbox_max[a])
                model->bbox_max[a] = x;
        }
    }
    model->parents = parents;
    parents = NULL;
    model->record_offsets = rec_off;
    rec_off = NULL;
    model->record_word_count = (uint32_t)rec.n;
    model->record_data = rec.w;
    rec.w = NULL;
    if (!model->record_data && !(model->record_data = malloc(4)))
        goto nomem;
    /* every slot exists at every level: grow the base's slot list */
    if (model->base.strip_count < fig.slot_count) {
        mts_strips base = {0};
        if ((rc = mts_strips_alloc(&base, fig.slot_count, model->base.index_count, err)) != MTS_OK)
            goto fail;
        memcpy(base.offsets, model->base.offsets, ((size_t)model->base.strip_count + 1) * 4);
        for (uint32_t s = model->base.strip_count + 1; s <= fig.slot_count; s++)
            base.offsets[s] = model->base.index_count;
        memcpy(base.indices, model->base.indices, (size_t)model->base.index_count * 4);
        mts_strips_free(&model->base);
        model->base = base;
    }
    {
        uint64_t total = 0;
        for (uint32_t s = 0; s < fig.slot_count; s++) {
            uint32_t len;
            mts_grow_slot(g, s, &len);
            total += len;
        }
        if (total > UINT32_MAX - 1) {
            rc = mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: %llu strip indices at one level",
                               (unsigned long long)total);
            goto fail;
        }
        if ((rc = mts_strips_alloc(&model->full, fig.slot_count, (uint32_t)total, err)) != MTS_OK)
            goto fail;
        uint32_t o = 0;
        for (uint32_t s = 0; s < fig.slot_count; s++) {
            uint32_t len;
            const uint32_t *w = mts_grow_slot(g, s, &len);
            model->full.offsets[s] = o;
            if (len)
                memcpy(model->full.indices + o, w, (size_t)len * 4);
            o += len;
        }
        model->full.offsets[fig.slot_count] = o;
    }

    mts_progress_report(progress, "records", 1.0);
    if (stats_out) {
        memset(stats_out, 0, sizeof *stats_out);
        stats_out->edits = fig.edits;
        stats_out->substitutions = fig.substitutions;
        stats_out->erased_indices = fig.erased_indices;
        stats_out->inserted_indices = fig.inserted_indices;
        stats_out->key_levels = fig.key_count;
        stats_out->grown_inserted = fig.grown_inserted;
        stats_out->grown_appended = fig.grown_appended;
        stats_out->grown_joined = fig.grown_joined;
        stats_out->grown_alone = fig.grown_alone;
        stats_out->strips_cut = fig.strips_cut;
        stats_out->explicit_splits = d.explicit_splits;
    }
    rc = MTS_OK;
    goto done;

nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
    goto fail;
fail:
    mts_model_free(model);
done:
    mts_grow_free(g);
    truth_free(&tr);
    free(d.moved_tris.w);
    free(d.fan_tris.w);
    free(d.born.w);
    free(d.ids.w);
    free(rec.w);
    free(growth.w);
    free(rec_off);
    mts_strips_free(&given);
    free(new_id);
    free(parents);
    return rc;
}
