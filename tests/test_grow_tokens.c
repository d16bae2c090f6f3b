/* Growth cut at its key levels (common/grow_tokens.h), against one grow:
 *  - a mesh-only grow, never renumbered, gives every split of bunny00 and
 *    cow the same ring (in order, and whether it closes), fan and the same
 *    triangles round the new vertex as one grow that renumbers at each key:
 *    what a decoder's sequential pass reads does not depend on triangle ids.
 *  - every record of cow, bunny00 and fandisk_large derived interval by
 *    interval -- a worker per key interval made from the mesh-only grow,
 *    its records in slot tokens, fixed up in order -- is the model's, word
 *    for word, with the full level's strips given (the builder) or
 *    described (a client), and on cow with every fourth split explicit
 *    (triangle ids, mapped to the mesh-only grow's). Each worker's rings
 *    are the mesh-only grow's too.
 *  - a grow handed every ring the mesh-only grow walked, through its own
 *    renumbering at the keys, takes each one and gives one grow's records
 *    word for word, and refuses a ring turned by one corner, run backwards
 *    or with a corner of another vertex.
 * And the calls refuse what they cannot work on. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "build.h"
#include "grow.h"
#include "grow_tokens.h"
#include "mesh.h"
#include "model.h"
#include "test.h"

/* Builds the mesh at path; with `holes`, first drops every holes-th
 * triangle that shares no vertex with one dropped before, so that rings
 * open on the borders that leaves (the shared meshes are closed). */
static int build_holed(mts_test *t, const char *path, uint32_t holes, mts_model *m)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "load %s: %s", path, err.msg);
        return 0;
    }
    uint8_t *gone = holes ? calloc(mesh.vertex_count, 1) : NULL;
    if (holes && gone) {
        uint32_t kept = 0;
        for (uint32_t f = 0; f < mesh.triangle_count; f++) {
            const uint32_t *x = mesh.triangles + 3 * (size_t)f;
            if (f % holes == 0 && !gone[x[0]] && !gone[x[1]] && !gone[x[2]]) {
                gone[x[0]] = gone[x[1]] = gone[x[2]] = 1;
                continue;
            }
            memmove(mesh.triangles + 3 * (size_t)kept++, x, 12);
        }
        CHECKF(t, kept < mesh.triangle_count, "%s: no triangle dropped", path);
        mesh.triangle_count = kept;
    }
    free(gone);
    mts_result rc = mts_build_model(&mesh, path, NULL, m, NULL, &err);
    CHECKF(t, rc == MTS_OK, "build %s: %s", path, err.msg);
    mts_mesh_free(&mesh);
    return rc == MTS_OK;
}

static int build_path(mts_test *t, const char *path, mts_model *m)
{
    return build_holed(t, path, 0, m);
}

/* The shared models are built once (bunny00 takes seconds). */
static mts_model shared[2];
static int shared_state[2]; /* 0: not yet, 1: built, -1: missing or failed */

static const mts_model *shared_model(mts_test *t, int k)
{
    static const char *file[2] = {"bunny00.off", "fandisk_large.off"};
    if (shared_state[k] == 0) {
        char buf[512];
        const char *path = mts_test_model(file[k], buf, sizeof buf);
        shared_state[k] = path && build_path(t, path, &shared[k]) ? 1 : -1;
    }
    return shared_state[k] > 0 ? &shared[k] : NULL;
}

static int is_key(const mts_model *m, uint32_t level)
{
    if (level == m->level_count)
        return 1;
    for (uint32_t k = 0; k < m->key_count; k++) {
        if (m->key_levels[k] == level)
            return 1;
    }
    return 0;
}

static uint32_t explicit_splits(const mts_model *m)
{
    uint32_t count = 0;
    for (uint32_t j = 0; j < m->level_count; j++) {
        const uint32_t o = m->growth_offsets[j];
        count += m->growth_offsets[j + 1] - o >= 3 && m->growth_data[o + 2] == MTS_GROWTH_EXPLICIT;
    }
    return count;
}

/* A grow's last renumbering, as mts_grow_on_key_order tells it (n 0 until
 * one, or when out of memory). */
typedef struct told_order {
    uint32_t *w, n;
} told_order;

static void keep_told(void *user, const uint32_t *order, uint32_t count)
{
    told_order *o = user;
    uint32_t *w = realloc(o->w, (size_t)count * 4 + 4);
    o->n = w ? count : 0;
    if (w) {
        o->w = w;
        memcpy(w, order, (size_t)count * 4);
    }
}

/* ---- the mesh-only grow ---- */

/* Every split's ring and fan, and the triangles round its vertex after,
 * on one grow and on a mesh-only grow. The ring is compared whole, in
 * order: each position's one-triangle fan code decodes to that triangle's
 * other two vertices. */
static void mesh_only_matches(mts_test *t, const mts_model *m, const char *name)
{
    mts_error err = {0};
    mts_grow_options go = {0};
    go.key_levels = m->key_levels;
    go.key_count = m->key_count;
    const mts_grow_full given = {.strips = &m->full};
    mts_grow *g = NULL, *h = NULL, *k = NULL;
    CHECKF(t, mts_grow_create(&m->base, m->base_vertex_count, m->level_count, &go, &g, &err) ==
                  MTS_OK,
           "%s", err.msg);
    /* k: a grow that takes h's rings, its ids kept as mesh-only -> k's */
    CHECKF(t, mts_grow_create(&m->base, m->base_vertex_count, m->level_count, &go, &k, &err) ==
                  MTS_OK,
           "%s", err.msg);
    told_order kt = {0};
    if (k)
        mts_grow_on_key_order(k, keep_told, &kt);
    uint32_t *kids = NULL, kids_n = 0, taken = 0, fans = 0, refused = 0, tries = 0;
    uint32_t wrong[64];
    CHECKF(t, mts_grow_create_mesh(&m->base, m->base_vertex_count, m->level_count, &h, &err) ==
                  MTS_OK,
           "%s", err.msg);
    CHECKF(t, explicit_splits(m) == 0,
           "%s: %u explicit splits (they name triangle ids: this test maps none)", name,
           explicit_splits(m));
    uint32_t bad = 0, keys = 0, renumbered = 0, ringed = 0;
    uint64_t positions = 0;
    for (uint32_t j = 0; g && h && k && j < m->level_count && bad < 5; j++) {
        mts_grow_split sg, sh;
        if (!mts_grow_model_split(g, m, j, &sg) || !mts_grow_model_split(h, m, j, &sh)) {
            CHECKF(t, 0, "%s: split %u does not decode", name, j);
            bad++;
            break;
        }
        if (sg.parent != sh.parent || sg.left != sh.left || sg.right != sh.right) {
            CHECKF(t, 0, "%s: split %u's fan is (%u, %u, %u), mesh-only (%u, %u, %u)", name, j,
                   sg.parent, sg.left, sg.right, sh.parent, sh.left, sh.right);
            bad++;
        }
        int cg, ch;
        const int32_t kg = mts_grow_ring_size(g, sg.parent, &cg),
                      kh = mts_grow_ring_size(h, sh.parent, &ch);
        if (kg != kh || cg != ch) {
            CHECKF(t, 0, "%s: split %u's ring: %d triangles (closed %d), mesh-only %d (%d)",
                   name, j, kg, cg, kh, ch);
            bad++;
        }
        for (int32_t i = 0; kg == kh && i < kg; i++) {
            const mts_grow_fan_code code = {(uint32_t)i, 1, 0};
            uint32_t lg = 0, rg = 0, lh = 1, rh = 1;
            int og = mts_grow_fan_decode(g, sg.parent, &code, &lg, &rg),
                oh = mts_grow_fan_decode(h, sh.parent, &code, &lh, &rh);
            positions++;
            if (!og || !oh || lg != lh || rg != rh) {
                CHECKF(t, 0, "%s: split %u, ring position %d: (%u %u), mesh-only (%u %u)", name,
                       j, i, rg, lg, rh, lh);
                bad++;
                break;
            }
        }
        /* h's ring handed to k: now and then a wrong one first */
        uint32_t hn = 0;
        int hc = 0;
        const uint32_t *hr = mts_grow_ring_at_hand(h, sh.parent, &hn, &hc);
        fans += j + 1 < m->level_count;
        if (hr && hn >= 2 && hn <= 64 && j % 5 == 0) {
            const uint32_t how = j / 5 % 3;
            for (uint32_t x = 0; x < hn; x++)
                wrong[x] = how == 0 ? hr[(x + 1) % hn] : how == 1 ? hr[hn - 1 - x] : hr[x];
            if (how == 2) /* another corner of the first one's triangle */
                wrong[0] = hr[0] / 3 * 3 + (hr[0] % 3 + 1) % 3;
            tries++;
            if (!mts_grow_take_ring(k, sh.parent, wrong, hn, hc, kids, kids_n))
                refused++;
            else
                CHECKF(t, 0, "%s: split %u: a wrong ring (%u) was taken", name, j, how);
        }
        /* the vertices a decoder asks the positions of early: checked
         * below against what the split's prediction reads */
        uint32_t near[64], near_n = hr ? mts_grow_ring_vertices(h, sh.parent, near, 64) : 0;
        if (hr && hn < 64)
            CHECKF(t, near_n == hn + !hc,
                   "%s: split %u: %u ring vertices of %u triangles (closed %d)", name, j, near_n,
                   hn, hc);
        if (hr && j + 1 < m->level_count) {
            /* every link of the hints the pool gives (they must change
             * nothing: the records are compared below) */
            for (unsigned d = 0; d < 4; d++)
                mts_grow_prefetch_ring(k, d, sh.parent, hr, hn, kids, kids_n);
            taken += (uint32_t)mts_grow_take_ring(k, sh.parent, hr, hn, hc, kids, kids_n);
        }
        const uint32_t *r, *rk;
        uint32_t w, wk;
        if (mts_grow_next(k, &sg, &given, &rk, &wk, &err) != MTS_OK) {
            CHECKF(t, 0, "%s: split %u, the grow handed rings: %s", name, j, err.msg);
            bad++;
            break;
        }
        if (mts_grow_next(g, &sg, &given, &r, &w, &err) != MTS_OK ||
            mts_grow_split_mesh(h, &sh, &err) != MTS_OK) {
            CHECKF(t, 0, "%s: split %u: %s", name, j, err.msg);
            bad++;
            break;
        }
        if (w != wk || memcmp(r, rk, (size_t)w * 4) != 0) {
            CHECKF(t, 0, "%s: split %u: the grow handed rings makes another record", name, j);
            bad++;
        }
        const uint32_t kc = kt.n, *ko = is_key(m, j + 1) ? kt.w : NULL;
        if (ko && kc && j + 1 < m->level_count) {
            /* k renumbered: mesh-only ids through it (born since: the same) */
            uint32_t *a = realloc(kids, (size_t)kc * 4 + 4);
            CHECK(t, a != NULL);
            if (!a)
                break;
            kids = a;
            for (; kids_n < kc; kids_n++)
                kids[kids_n] = kids_n;
            for (uint32_t x = 0; x < kc; x++)
                kids[x] = ko[kids[x]];
        }
        const uint32_t *ag, *ah;
        uint32_t ng, nh;
        if (mts_grow_around_newest(g, &ag, &ng, &err) != MTS_OK ||
            mts_grow_around_newest(h, &ah, &nh, &err) != MTS_OK || ng != nh ||
            (ng && memcmp(ag, ah, (size_t)ng * 4) != 0)) {
            CHECKF(t, 0, "%s: split %u: the triangles round the new vertex differ (%u, %u ids)",
                   name, j, ng, nh);
            bad++;
        }
        for (uint32_t x = 0; hr && hn < 64 && x < nh; x++) {
            uint32_t y = 0;
            while (y < near_n && near[y] != ah[x])
                y++;
            if (ah[x] != sh.parent && y == near_n) {
                CHECKF(t, 0, "%s: split %u: vertex %u round the new one was not on u's ring",
                       name, j, ah[x]);
                bad++;
                break;
            }
        }
        ringed += hr && hn < 64;
        if (is_key(m, j + 1)) {
            keys++;
            CHECKF(t, mts_grow_check(h, &err) == MTS_OK, "%s: at key %u: %s", name, j + 1,
                   err.msg);
            /* one grow has renumbered its triangles, the mesh-only one not */
            mts_grow_figures fg;
            mts_grow_get_figures(h, &fg);
            for (uint32_t x = 0; x < fg.triangles; x++) {
                uint32_t a[3], b[3];
                mts_grow_triangle(g, x, a);
                mts_grow_triangle(h, x, b);
                if (memcmp(a, b, sizeof a) != 0) {
                    renumbered++;
                    break;
                }
            }
        }
    }
    CHECKF(t, bad == 0 && keys == m->key_count + 1 && renumbered + 1 >= keys && positions > 0,
           "%s: %u differences, %u keys (%u renumbered), %llu ring positions", name, bad, keys,
           renumbered, (unsigned long long)positions);
    /* every fan's ring is at hand after its code is decoded; handed over,
     * all are taken, through the renumbering of every key */
    CHECKF(t, fans > 0 && taken == fans && tries > 30 && refused == tries,
           "%s: %u of %u rings taken, %u of %u wrong ones refused", name, taken, fans, refused,
           tries);
    CHECKF(t, ringed + 1 >= fans, "%s: %u of %u fans' ring vertices checked", name, ringed, fans);
    free(kids);
    free(kt.w);
    mts_grow_free(g);
    mts_grow_free(h);
    mts_grow_free(k);
}

static void test_mesh_only_cow(mts_test *t)
{
    mts_model m = {0};
    if (build_path(t, "tests/data/cow.off", &m))
        mesh_only_matches(t, &m, "cow");
    mts_model_free(&m);
    /* with holes: open rings on their borders */
    mts_model h = {0};
    if (build_holed(t, "tests/data/cow.off", 101, &h))
        mesh_only_matches(t, &h, "cow with holes");
    mts_model_free(&h);
}

static void test_mesh_only_bunny(mts_test *t)
{
    const mts_model *m = shared_model(t, 0);
    if (!m)
        SKIP(t, "bunny00.off not found (../shared/models or $MTS_MODELS) or not built");
    mesh_only_matches(t, m, "bunny00");
}

/* ---- intervals ---- */

/* Whether u's ring, whole and in order, is the same on g and h. */
static int rings_match(mts_grow *g, mts_grow *h, uint32_t u)
{
    int cg, ch;
    const int32_t kg = mts_grow_ring_size(g, u, &cg), kh = mts_grow_ring_size(h, u, &ch);
    if (kg != kh || cg != ch)
        return 0;
    for (int32_t i = 0; i < kg; i++) {
        const mts_grow_fan_code code = {(uint32_t)i, 1, 0};
        uint32_t lg = 0, rg = 0, lh = 1, rh = 1;
        if (!mts_grow_fan_decode(g, u, &code, &lg, &rg) ||
            !mts_grow_fan_decode(h, u, &code, &lh, &rh) || lg != lh || rg != rh)
            return 0;
    }
    return 1;
}

/* A client's full level: the described strips' starts and swap bits, the
 * latter only where the walk does not force them (as test_grow.c). */
typedef struct described {
    mts_grow_full_path *paths;
    uint8_t *swaps;
    uint64_t count, at;
    uint32_t slots, slot;
} described;

static int next_start(void *user, const uint32_t *near, uint32_t near_count, uint32_t *near_at,
                      uint32_t *first, uint32_t *rotation)
{
    described *d = user;
    (void)near;
    while (d->slot < d->slots && d->paths[d->slot].triangles == 0)
        d->slot++;
    if (d->slot >= d->slots)
        return 0;
    const mts_grow_full_path *p = &d->paths[d->slot++];
    if (p->near != MTS_GROW_NONE) {
        if (p->near >= near_count)
            return 0;
        *near_at = p->near;
    } else {
        *first = p->first;
    }
    *rotation = p->rotation;
    return 1;
}

static unsigned next_free_bit(void *user, unsigned previous)
{
    described *d = user;
    (void)previous;
    while (d->at < d->count && (d->swaps[d->at] & 2))
        d->at++;
    return d->at < d->count ? d->swaps[d->at++] & 1 : 0;
}

/* One grow over every split: each split's fan (lr: left, right) and the
 * full level's description. 0 on failure (reported). */
static int first_pass(mts_test *t, const mts_model *m, uint32_t *lr, described *d)
{
    mts_error err = {0};
    mts_grow_options go = {0};
    go.key_levels = m->key_levels;
    go.key_count = m->key_count;
    const mts_grow_full given = {.strips = &m->full};
    mts_grow *g = NULL;
    int ok = mts_grow_create(&m->base, m->base_vertex_count, m->level_count, &go, &g, &err) ==
             MTS_OK;
    for (uint32_t j = 0; ok && j < m->level_count; j++) {
        mts_grow_split sp;
        const uint32_t *r;
        uint32_t w;
        ok = mts_grow_model_split(g, m, j, &sp) && sp.moved_count == 0 &&
             mts_grow_next(g, &sp, &given, &r, &w, &err) == MTS_OK;
        lr[2 * j] = sp.left;
        lr[2 * j + 1] = sp.right;
    }
    memset(d, 0, sizeof *d);
    d->paths = calloc((size_t)m->strip_count + 1, sizeof *d->paths);
    d->swaps = malloc((size_t)m->full.index_count + 1);
    d->slots = m->strip_count;
    ok = ok && d->paths && d->swaps &&
         mts_grow_full_describe(g, &m->full, d->paths, d->swaps, &d->count, &err) == MTS_OK;
    CHECKF(t, ok, "first pass: %s", err.msg);
    mts_grow_free(g);
    return ok;
}

/* Every record derived interval by interval, as a threaded decoder would:
 * the splits decoded against the mesh-only grow; per key a worker made
 * from it before the key split (its ids: the renumbering the workers
 * before made); every worker's record fixed up in order. */
static void intervals_match(mts_test *t, const mts_model *m, const char *name, int client,
                            uint32_t explicit_every)
{
    mts_error err = {0};
    mts_grow_options go = {0};
    go.key_levels = m->key_levels;
    go.key_count = m->key_count;
    mts_grow *mesh = NULL, *w = NULL;
    mts_grow_fixup *f = NULL;
    /* ids: the mesh-only grow's triangle x is x in one grow, or ids[x]
     * below ids_n; inv the other way */
    uint32_t *ids = NULL, *inv = NULL, ids_n = 0, ids_cap = 0;
    uint32_t *lr = malloc(((size_t)m->level_count + 1) * 8), *moved = NULL, moved_cap = 0;
    described d = {0};
    CHECKF(t, explicit_splits(m) == 0, "%s: %u explicit splits (this test maps none)", name,
           explicit_splits(m));
    if (!first_pass(t, m, lr, &d))
        goto done;
    const mts_grow_full given = {.strips = &m->full},
                        told = {.paths = d.paths,
                                .slot_count = m->strip_count,
                                .swap_bit = next_free_bit,
                                .start = next_start,
                                .user = &d},
                        *full = client ? &told : &given;
    if (mts_grow_create_mesh(&m->base, m->base_vertex_count, m->level_count, &mesh, &err) !=
            MTS_OK ||
        mts_grow_fixup_create(&f, &err) != MTS_OK ||
        mts_grow_create(&m->base, m->base_vertex_count, m->level_count, &go, &w, &err) !=
            MTS_OK) {
        CHECKF(t, 0, "%s: %s", name, err.msg);
        goto done;
    }
    uint32_t bad = 0, workers = 1, keyed = 0, explicit = 0;
    uint64_t words = 0;
    for (uint32_t j = 0; j < m->level_count && bad < 3; j++) {
        /* the fan codes were made on a grow of fan splits only, whose
         * listed corners an explicit split leaves elsewhere: with explicit
         * splits, the fans come from the first pass */
        mts_grow_split sp = {m->parents[j], lr[2 * j], lr[2 * j + 1], 0, NULL, 0, NULL};
        if (!explicit_every && (!mts_grow_model_split(mesh, m, j, &sp) ||
                                sp.left != lr[2 * j] || sp.right != lr[2 * j + 1])) {
            CHECKF(t, 0, "%s: split %u does not decode to its fan", name, j);
            break;
        }
        /* the decoder's split: the fan, or its triangles by id (one grow's,
         * as a stream names them; the mesh-only grow's through inv) */
        const uint32_t u = sp.parent, v = m->base_vertex_count + j;
        mts_grow_split xs = {0}, xm = {0};
        uint32_t born[6], nborn = 0;
        int32_t k = 0;
        const int ex = explicit_every && j % explicit_every == explicit_every - 1;
        if (ex) {
            if (sp.left != MTS_GROW_NONE) {
                born[3 * nborn] = u, born[3 * nborn + 1] = v, born[3 * nborn + 2] = sp.left;
                nborn++;
            }
            if (sp.right != MTS_GROW_NONE) {
                born[3 * nborn] = v, born[3 * nborn + 1] = u, born[3 * nborn + 2] = sp.right;
                nborn++;
            }
            k = mts_grow_fan(mesh, u, sp.left, sp.right, NULL, 0);
            if (k > 0 && 2 * (uint32_t)k > moved_cap) {
                moved_cap = 4 * (uint32_t)k;
                moved = realloc(moved, (size_t)moved_cap * 4);
            }
            if (k <= 0 || mts_grow_fan(mesh, u, sp.left, sp.right, moved + k, (uint32_t)k) != k) {
                CHECKF(t, 0, "%s: split %u: no fan", name, j);
                break;
            }
            for (int32_t i = 0; i < k; i++) {
                const uint32_t x = moved[k + i];
                moved[i] = x < ids_n ? ids[x] : x;
            }
            xs = (mts_grow_split){u, MTS_GROW_NONE, MTS_GROW_NONE, (uint32_t)k, moved, nborn, born};
            /* back from one grow's ids, as a decoder must */
            for (int32_t i = 0; i < k; i++)
                moved[k + i] = moved[i] < ids_n ? inv[moved[i]] : moved[i];
            xm = xs;
            xm.moved = moved + k;
            explicit++;
        }
        const mts_grow_split *split = ex ? &xs : &sp, *msplit = ex ? &xm : &sp;
        const uint32_t *r, *o;
        uint32_t rw, ow;
        mts_result rc;
        if (is_key(m, j + 1)) {
            /* the interval before ends; a worker for this one, in the ids
             * one grow has now: the old ones renumbered, the new as born */
            mts_grow_figures fig;
            mts_grow_get_figures(mesh, &fig);
            if (fig.triangles > ids_cap) {
                ids_cap = 2 * fig.triangles;
                ids = realloc(ids, (size_t)ids_cap * 4);
                inv = realloc(inv, (size_t)ids_cap * 4);
            }
            for (; ids_n < fig.triangles; ids_n++)
                ids[ids_n] = inv[ids_n] = ids_n;
            mts_grow *next = NULL;
            rc = mts_grow_fixup_end(f, w, &err);
            if (rc == MTS_OK)
                rc = mts_grow_create_worker(mesh, ids, &go, &next, &err);
            if (rc == MTS_OK) {
                mts_grow_free(w);
                w = next;
                workers++;
                if (!rings_match(w, mesh, u)) {
                    CHECKF(t, 0, "%s: split %u: the worker's ring differs", name, j);
                    bad++;
                }
                rc = mts_grow_next(w, split, full, &r, &rw, &err);
            }
            if (rc == MTS_OK && j + 1 < m->level_count) {
                uint32_t count;
                const uint32_t *order = mts_grow_key_order(w, &count);
                CHECK(t, order && count >= ids_n);
                if (count > ids_cap) {
                    ids_cap = 2 * count;
                    ids = realloc(ids, (size_t)ids_cap * 4);
                    inv = realloc(inv, (size_t)ids_cap * 4);
                }
                for (; ids_n < count; ids_n++)
                    ids[ids_n] = ids_n;
                for (uint32_t x = 0; order && x < count; x++) {
                    ids[x] = order[ids[x]];
                    inv[ids[x]] = x;
                }
            }
            if (rc == MTS_OK)
                rc = mts_grow_fixup_key(f, r, rw, sp.parent, m->base_vertex_count + j,
                                        j + 1 == m->level_count, &o, &ow, &err);
            keyed = 1;
        } else {
            if (!rings_match(w, mesh, u)) {
                CHECKF(t, 0, "%s: split %u: the worker's ring differs", name, j);
                bad++;
            }
            rc = mts_grow_next(w, split, full, &r, &rw, &err);
            o = r;
            ow = rw;
            if (rc == MTS_OK && keyed)
                rc = mts_grow_fixup_record(f, r, rw, &o, &ow, &err);
        }
        if (rc == MTS_OK)
            rc = mts_grow_split_mesh(mesh, msplit, &err);
        if (rc != MTS_OK) {
            CHECKF(t, 0, "%s: split %u: %s", name, j, err.msg);
            break;
        }
        const uint32_t want = m->record_offsets[j + 1] - m->record_offsets[j];
        if (ow != want || memcmp(o, m->record_data + m->record_offsets[j], (size_t)ow * 4) != 0) {
            uint32_t at = 0;
            while (at < ow && at < want && o[at] == m->record_data[m->record_offsets[j] + at])
                at++;
            CHECKF(t, 0,
                   "%s: split %u (%s) derives a record of %u words, the model has %u; first "
                   "difference at word %u",
                   name, j, is_key(m, j + 1) ? "key" : "between keys", ow, want, at);
            bad++;
        }
        words += ow;
    }
    CHECKF(t,
           bad == 0 && workers == m->key_count + 2 && words == m->record_word_count &&
               (explicit > 0) == (explicit_every > 0),
           "%s: %u records differ, %u workers for %u keys, %llu of %u words, %u explicit",
           name, bad, workers, m->key_count, (unsigned long long)words, m->record_word_count,
           explicit);
done:
    mts_grow_free(mesh);
    mts_grow_free(w);
    mts_grow_fixup_free(f);
    free(ids);
    free(inv);
    free(lr);
    free(moved);
    free(d.paths);
    free(d.swaps);
}

static void test_intervals_cow(mts_test *t)
{
    mts_model m = {0};
    if (build_path(t, "tests/data/cow.off", &m)) {
        intervals_match(t, &m, "cow, full strips given", 0, 0);
        intervals_match(t, &m, "cow, full strips described", 1, 0);
        intervals_match(t, &m, "cow, every fourth split explicit", 1, 4);
    }
    mts_model_free(&m);
}

static void test_intervals_bunny(mts_test *t)
{
    const mts_model *m = shared_model(t, 0);
    if (!m)
        SKIP(t, "bunny00.off not found (../shared/models or $MTS_MODELS) or not built");
    intervals_match(t, m, "bunny00", 1, 0);
}

static void test_intervals_fandisk(mts_test *t)
{
    const mts_model *m = shared_model(t, 1);
    if (!m)
        SKIP(t, "fandisk_large.off not found (../shared/models or $MTS_MODELS) or not built");
    intervals_match(t, m, "fandisk_large", 1, 0);
}

/* As a two-thread decoder grows (docs/threads.md): one grow from the base
 * derives the records, a mesh-only grow (never renumbered) goes ahead of
 * it. At every key the mesh-only grow stripifies, seeded in the one grow's
 * ids, and hands the paths over; at the full level it walks the described
 * strips (its start ids mapped from the one grow's) and the one grow takes
 * them as they are. Every record must be the model's. `spoil`: key paths
 * with a triangle twice must fail the key's split. */
static void handed_across_match(mts_test *t, const mts_model *m, const char *name, int spoil)
{
    mts_error err = {0};
    mts_grow_options go = {0};
    go.key_levels = m->key_levels;
    go.key_count = m->key_count;
    mts_grow *mesh = NULL, *g = NULL;
    /* ids: the mesh-only grow's triangle x is the one grow's ids[x] (x from
     * ids_n on); inv the other way */
    uint32_t *ids = NULL, *inv = NULL, *mine = NULL, *order = NULL, *starts = NULL;
    uint32_t ids_n = 0, bad = 0, keys = 0;
    uint32_t *lr = malloc(((size_t)m->level_count + 1) * 8);
    described d = {0};
    mts_strips walked = {0};
    told_order gt = {0}; /* the one grow's renumberings */
    if (!first_pass(t, m, lr, &d))
        goto done;
    if (mts_grow_create_mesh(&m->base, m->base_vertex_count, m->level_count, &mesh, &err) !=
            MTS_OK ||
        mts_grow_create(&m->base, m->base_vertex_count, m->level_count, &go, &g, &err) != MTS_OK) {
        CHECKF(t, 0, "%s: %s", name, err.msg);
        goto done;
    }
    mts_grow_on_key_order(g, keep_told, &gt);
    for (uint32_t j = 0; j < m->level_count && bad < 3; j++) {
        mts_grow_split sp = {m->parents[j], lr[2 * j], lr[2 * j + 1], 0, NULL, 0, NULL};
        const uint32_t *r;
        uint32_t rw;
        mts_result rc = mts_grow_split_mesh(mesh, &sp, &err);
        mts_grow_figures fig;
        mts_grow_get_figures(mesh, &fig);
        const uint32_t n = fig.triangles;
        if (rc == MTS_OK && (is_key(m, j + 1) || j + 1 == m->level_count)) {
            ids = realloc(ids, (size_t)n * 4);
            inv = realloc(inv, (size_t)n * 4);
            for (; ids_n < n; ids_n++)
                ids[ids_n] = inv[ids_n] = ids_n;
        }
        if (rc == MTS_OK && is_key(m, j + 1) && j + 1 < m->level_count) {
            mine = realloc(mine, (size_t)n * 4);
            order = realloc(order, (size_t)n * 4);
            starts = realloc(starts, ((size_t)n + 1) * 4);
            uint32_t count = 0;
            rc = mts_grow_key_paths(mesh, ids, inv, order, starts, &count, &err);
            for (uint32_t i = 0; rc == MTS_OK && i < n; i++)
                mine[i] = inv[order[i]];
            if (spoil && rc == MTS_OK) {
                order[n - 1] = order[0];
                mts_grow_give_key_paths(g, j + 1, n, order, starts, count);
                CHECKF(t, mts_grow_next(g, &sp, NULL, &r, &rw, &err) == MTS_ERR_INTERNAL,
                       "%s: key paths with a triangle twice taken (%s)", name, err.msg);
                goto done;
            }
            mts_grow_give_key_paths(g, j + 1, n, order, starts, count);
            rc = rc == MTS_OK ? mts_grow_next(g, &sp, NULL, &r, &rw, &err) : rc;
            for (uint32_t i = 0; rc == MTS_OK && i < n; i++) {
                ids[mine[i]] = i;
                inv[i] = mine[i];
            }
            /* the one grow renumbered by what it was given */
            uint32_t count2 = gt.n, same = 1;
            const uint32_t *kept = gt.n ? gt.w : NULL;
            for (uint32_t i = 0; rc == MTS_OK && kept && count2 == n && i < n; i++)
                same &= kept[order[i]] == i;
            CHECKF(t, rc != MTS_OK || (kept && count2 == n && same),
                   "%s: key at level %u renumbered otherwise than its paths say", name, j + 1);
            keys++;
        } else if (rc == MTS_OK && j + 1 == m->level_count) {
            d.at = d.slot = 0;
            const mts_grow_full told = {.paths = d.paths,
                                        .slot_count = m->strip_count,
                                        .swap_bit = next_free_bit,
                                        .start = next_start,
                                        .user = &d,
                                        .first_ids = inv,
                                        .first_id_count = n},
                                taken = {.derived = &walked};
            rc = mts_grow_full_strips(mesh, &told, &walked, &err);
            if (rc == MTS_OK)
                rc = mts_grow_next(g, &sp, &taken, &r, &rw, &err);
            if (rc == MTS_OK) /* the mesh is kept, the paths are not */
                rc = mts_grow_check(g, &err);
        } else if (rc == MTS_OK) {
            rc = mts_grow_next(g, &sp, NULL, &r, &rw, &err);
        }
        if (rc != MTS_OK) {
            CHECKF(t, 0, "%s: split %u: %s", name, j, err.msg);
            break;
        }
        const uint32_t want = m->record_offsets[j + 1] - m->record_offsets[j];
        if (rw != want || memcmp(r, m->record_data + m->record_offsets[j], (size_t)rw * 4) != 0) {
            CHECKF(t, 0, "%s: split %u (%s) derives a record of %u words, the model has %u", name,
                   j, is_key(m, j + 1) ? "key" : "between keys", rw, want);
            bad++;
        }
    }
    uint32_t below = 0; /* the full level may be listed as a key too */
    for (uint32_t k = 0; k < m->key_count; k++)
        below += m->key_levels[k] < m->level_count;
    CHECKF(t, spoil || (bad == 0 && keys == below && walked.strip_count == m->strip_count),
           "%s: %u records differ, %u keys handed across of %u", name, bad, keys, below);
done:
    mts_grow_free(mesh);
    mts_grow_free(g);
    mts_strips_free(&walked);
    free(ids);
    free(inv);
    free(mine);
    free(order);
    free(starts);
    free(gt.w);
    free(lr);
    free(d.paths);
    free(d.swaps);
}

static void test_handed_across(mts_test *t)
{
    mts_model m = {0};
    if (build_path(t, "tests/data/cow.off", &m)) {
        handed_across_match(t, &m, "cow", 0);
        handed_across_match(t, &m, "cow, key paths spoilt", 1);
    }
    mts_model_free(&m);
    const mts_model *b = shared_model(t, 0);
    if (b)
        handed_across_match(t, b, "bunny00", 0);
}

/* ---- refusals ---- */

static void test_refusals(mts_test *t)
{
    mts_model m = {0};
    if (!build_path(t, "tests/data/cow.off", &m))
        return;
    mts_error err = {0};
    mts_grow_options go = {0};
    go.key_levels = m.key_levels;
    go.key_count = m.key_count;
    mts_grow *g = NULL, *h = NULL, *w = NULL;
    mts_grow_fixup *f = NULL;
    CHECK(t, mts_grow_create(&m.base, m.base_vertex_count, m.level_count, &go, &g, &err) ==
                 MTS_OK);
    CHECK(t, mts_grow_create_mesh(&m.base, m.base_vertex_count, m.level_count, &h, &err) ==
                 MTS_OK);
    CHECK(t, mts_grow_fixup_create(&f, &err) == MTS_OK);
    if (g && h && f) {
        mts_grow_split sp;
        const uint32_t *r;
        uint32_t rw;
        CHECK(t, mts_grow_model_split(h, &m, 0, &sp));
        /* each kind of grow takes only its own kind of split */
        CHECK(t, mts_grow_next(h, &sp, NULL, &r, &rw, &err) == MTS_ERR_ARG);
        CHECK(t, mts_grow_split_mesh(g, &sp, &err) == MTS_ERR_ARG);
        /* a worker starts only before a key, and only with the keys listed */
        CHECK(t, m.key_count > 0 && m.key_levels[0] > 1);
        CHECK(t, mts_grow_create_worker(h, NULL, &go, &w, &err) == MTS_ERR_ARG && !w);
        mts_grow_options none = {0};
        CHECK(t, mts_grow_create_worker(h, NULL, &none, &w, &err) == MTS_ERR_ARG && !w);
        for (uint32_t j = 0; j + 1 < m.key_levels[0]; j++) {
            if (!mts_grow_model_split(h, &m, j, &sp) ||
                mts_grow_split_mesh(h, &sp, &err) != MTS_OK)
                break;
        }
        mts_grow_figures fig;
        mts_grow_get_figures(h, &fig);
        uint32_t *ids = malloc(((size_t)fig.triangles + 1) * 4);
        for (uint32_t x = 0; x < fig.triangles; x++)
            ids[x] = x;
        ids[0] = 1; /* not a permutation */
        CHECK(t, mts_grow_create_worker(h, ids, &go, &w, &err) == MTS_ERR_ARG && !w);
        free(ids);
        CHECK(t, mts_grow_create_worker(h, NULL, &go, &w, &err) == MTS_OK && w);
        /* records that are not a worker's */
        const uint32_t *o;
        uint32_t ow;
        const uint32_t erase[] = {1, 0, 1, 0, 0, 0, 2, 5, 6};
        const uint32_t cut[] = {1, 0, 0, 1, 2, 0, 3};
        CHECK(t, mts_grow_fixup_key(f, NULL, 0, 0, 1, 0, &o, &ow, &err) == MTS_ERR_FORMAT);
        CHECK(t, mts_grow_fixup_key(f, erase, 9, 0, 1, 0, &o, &ow, &err) == MTS_ERR_FORMAT);
        CHECK(t, mts_grow_fixup_record(f, cut, 7, &o, &ow, &err) == MTS_ERR_FORMAT);
    }
    mts_grow_free(g);
    mts_grow_free(h);
    mts_grow_free(w);
    mts_grow_fixup_free(f);
    mts_model_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_refusals);
    RUN(&t, test_mesh_only_cow);
    RUN(&t, test_intervals_cow);
    RUN(&t, test_mesh_only_bunny);
    RUN(&t, test_intervals_bunny);
    RUN(&t, test_intervals_fandisk);
    RUN(&t, test_handed_across);
    for (int k = 0; k < 2; k++)
        mts_model_free(&shared[k]);
    return mts_test_end(&t);
}
