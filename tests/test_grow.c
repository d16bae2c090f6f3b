/* Strip growth (common/grow.h) checked from scratch as it runs: after every
 * split of cow, of two generated meshes (a torus and a terrain with a hole,
 * so rings with and without borders), and at sampled levels and every key
 * level of bunny00 and fandisk_large, mts_grow_check compares the whole
 * incremental state (twins, listed corners, paths, and each slot's indices,
 * which a split re-derives only where its path changed) with a derivation
 * from nothing, and every derived record with the model's. The same splits
 * described explicitly (moved triangle ids and new triangles, the builder's
 * fallback, which pairs twins another way) must give the same records.
 * Hostile explicit splits get errors. greedy.c's paths are checked as a
 * cover. */
#include <math.h>
#include <stdint.h>

#include "build.h"
#include "greedy.h"
#include "grow.h"
#include "mesh.h"
#include "model.h"
#include "test.h"

static int build_mesh(mts_test *t, const mts_mesh *mesh, const char *name, mts_model *m)
{
    mts_error err = {0};
    mts_result rc = mts_build_model(mesh, name, NULL, m, NULL, &err);
    CHECKF(t, rc == MTS_OK, "build %s: %s", name, err.msg);
    return rc == MTS_OK;
}

static int build_path(mts_test *t, const char *path, mts_model *m)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "load %s: %s", path, err.msg);
        return 0;
    }
    int ok = build_mesh(t, &mesh, path, m);
    mts_mesh_free(&mesh);
    return ok;
}

/* An OFF mesh made here, so that growth sees meshes no one tuned it on. */
static int build_off(mts_test *t, const char *name, const char *text, mts_model *m)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    if (mts_mesh_load_memory(name, text, strlen(text), NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "load %s: %s", name, err.msg);
        return 0;
    }
    int ok = build_mesh(t, &mesh, name, m);
    mts_mesh_free(&mesh);
    return ok;
}

typedef struct text {
    char *s;
    size_t n, cap;
} text;

static void say(text *x, const char *fmt, double a, double b, double c)
{
    if (x->n + 96 > x->cap) {
        x->cap = x->cap ? 2 * x->cap : 1 << 16;
        x->s = realloc(x->s, x->cap);
    }
    x->n += (size_t)snprintf(x->s + x->n, x->cap - x->n, fmt, a, b, c);
}

/* A torus, bumped so that its quadrics differ: closed, every ring full. */
static char *torus_off(void)
{
    const int nu = 40, nv = 20;
    text x = {0};
    say(&x, "OFF\n%.0f %.0f %.0f\n", nu * nv, 2.0 * nu * nv, 0);
    for (int i = 0; i < nu; i++) {
        for (int j = 0; j < nv; j++) {
            double a = 2 * M_PI * i / nu, b = 2 * M_PI * j / nv;
            double r = 0.35 + 0.04 * sin(5 * a) * cos(3 * b);
            say(&x, "%.6f %.6f %.6f\n", (1 + r * cos(b)) * cos(a), (1 + r * cos(b)) * sin(a),
                r * sin(b));
        }
    }
    for (int i = 0; i < nu; i++) {
        for (int j = 0; j < nv; j++) {
            int p = i * nv + j, q = ((i + 1) % nu) * nv + j, r = i * nv + (j + 1) % nv,
                s = ((i + 1) % nu) * nv + (j + 1) % nv;
            say(&x, "3 %.0f %.0f %.0f\n", p, q, s);
            say(&x, "3 %.0f %.0f %.0f\n", p, s, r);
        }
    }
    return x.s;
}

/* A rolling terrain with a square hole: an outer border and an inner one. */
static char *terrain_off(void)
{
    const int n = 36;
    text x = {0}, f = {0};
    int faces = 0;
    for (int i = 0; i + 1 < n; i++) {
        for (int j = 0; j + 1 < n; j++) {
            if (i >= 14 && i < 20 && j >= 12 && j < 21)
                continue;
            int p = i * n + j;
            say(&f, "3 %.0f %.0f %.0f\n", p, p + n, p + n + 1);
            say(&f, "3 %.0f %.0f %.0f\n", p, p + n + 1, p + 1);
            faces += 2;
        }
    }
    say(&x, "OFF\n%.0f %.0f %.0f\n", n * n, faces, 0);
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++)
            say(&x, "%.6f %.6f %.6f\n", j / (double)n, i / (double)n,
                0.08 * sin(7.0 * i / n) * cos(5.0 * j / n) + 0.01 * sin(i * j));
    }
    text all = {0};
    all.cap = x.n + f.n + 1;
    all.s = malloc(all.cap);
    memcpy(all.s, x.s, x.n);
    memcpy(all.s + x.n, f.s, f.n);
    all.s[x.n + f.n] = 0;
    free(x.s);
    free(f.s);
    return all.s;
}

static int is_key(const mts_model *m, uint32_t level)
{
    for (uint32_t k = 0; k < m->key_count; k++) {
        if (m->key_levels[k] == level)
            return 1;
    }
    return 0;
}

/* A client's swap bits: the described ones the walk does not force, in
 * order; `previous` must be the bit before, forced or not. */
typedef struct free_bits {
    const uint8_t *swaps;
    uint64_t count, at, calls, bad_previous;
    /* and each strip's start, through its place among the triangles near
     * the strip before where describe found it there */
    const mts_grow_full_path *paths;
    uint32_t slots, slot, starts, near_starts, bad_near;
} free_bits;

static int next_start(void *user, const uint32_t *near, uint32_t near_count, uint32_t *near_at,
                      uint32_t *first, uint32_t *rotation)
{
    free_bits *f = user;
    while (f->slot < f->slots && f->paths[f->slot].triangles == 0)
        f->slot++;
    if (f->slot >= f->slots)
        return 0;
    const mts_grow_full_path *p = &f->paths[f->slot++];
    f->starts++;
    f->bad_near += p->near_count != near_count;
    if (p->near != MTS_GROW_NONE) {
        f->near_starts++;
        if (p->near >= near_count)
            return 0;
        f->bad_near += near[p->near] != p->first;
        *near_at = p->near;
    } else {
        *first = p->first;
    }
    *rotation = p->rotation;
    return 1;
}

static unsigned next_free_bit(void *user, unsigned previous)
{
    free_bits *f = user;
    while (f->at < f->count && (f->swaps[f->at] & 2))
        f->at++;
    if (f->at >= f->count)
        return 0;
    if (previous != (f->at ? (f->swaps[f->at - 1] & 1u) : 0u))
        f->bad_previous++;
    f->calls++;
    return f->swaps[f->at++] & 1;
}

/* Growth as a client runs it (the full strips described, not given), with
 * mts_grow_check after split j whenever check(j) says so; every record must
 * be the model's. */
static void grow_checked(mts_test *t, const mts_model *m, uint32_t every)
{
    mts_error err = {0};
    mts_grow_options go = {0};
    go.key_levels = m->key_levels;
    go.key_count = m->key_count;
    /* the description needs a grow at the full level: a first, unchecked pass */
    mts_grow *g = NULL;
    const mts_grow_full given = {.strips = &m->full, .slot_count = 0};
    CHECKF(t, mts_grow_create(&m->base, m->base_vertex_count, m->level_count, &go, &g, &err) ==
                  MTS_OK,
           "%s", err.msg);
    if (!g)
        return;
    for (uint32_t j = 0; j < m->level_count; j++) {
        mts_grow_split sp;
        const uint32_t *r;
        uint32_t w;
        if (!mts_grow_model_split(g, m, j, &sp) ||
            mts_grow_next(g, &sp, &given, &r, &w, &err) != MTS_OK) {
            CHECKF(t, 0, "first pass, split %u: %s", j, err.msg);
            mts_grow_free(g);
            return;
        }
    }
    mts_grow_full_path *paths = malloc(((size_t)m->strip_count + 1) * sizeof *paths);
    uint8_t *swaps = malloc((size_t)m->full.index_count + 1);
    uint64_t swap_count = 0;
    CHECKF(t, mts_grow_full_describe(g, &m->full, paths, swaps, &swap_count, &err) == MTS_OK,
           "%s", err.msg);
    mts_grow_free(g);
    g = NULL;
    /* as a stream's client: only the bits the walk does not force */
    uint64_t forced = 0;
    for (uint64_t k = 0; k < swap_count; k++)
        forced += (swaps[k] & 2) != 0;
    free_bits src = {swaps, swap_count, 0, 0, 0, paths, m->strip_count, 0, 0, 0, 0};
    uint32_t strips = 0;
    for (uint32_t st = 0; st < m->strip_count; st++)
        strips += paths[st].triangles > 0;
    const mts_grow_full described = {.paths = paths,
                                     .slot_count = m->strip_count,
                                     .swap_bit = next_free_bit,
                                     .start = next_start,
                                     .user = &src};
    CHECK(t, mts_grow_create(&m->base, m->base_vertex_count, m->level_count, &go, &g, &err) ==
                 MTS_OK);
    CHECKF(t, g && mts_grow_check(g, &err) == MTS_OK, "base: %s", err.msg);
    uint32_t checked = 0, failures = 0;
    for (uint32_t j = 0; g && j < m->level_count && failures < 3; j++) {
        mts_grow_split sp;
        const uint32_t *r;
        uint32_t w;
        if (!mts_grow_model_split(g, m, j, &sp) ||
            mts_grow_next(g, &sp, &described, &r, &w, &err) != MTS_OK) {
            CHECKF(t, 0, "split %u: %s", j, err.msg);
            break;
        }
        uint32_t want = m->record_offsets[j + 1] - m->record_offsets[j];
        if (w != want || memcmp(r, m->record_data + m->record_offsets[j], (size_t)w * 4) != 0) {
            CHECKF(t, 0, "split %u derives a record of %u words, the model has %u", j, w, want);
            failures++;
        }
        uint32_t l = j + 1;
        if (j % every == 0 || l == m->level_count || is_key(m, l) || is_key(m, l - 1) ||
            is_key(m, l + 1)) {
            checked++;
            if (mts_grow_check(g, &err) != MTS_OK) {
                CHECKF(t, 0, "after split %u: %s", j, err.msg);
                failures++;
            }
        }
    }
    CHECK(t, checked > 0);
    /* a real mesh's strips run beside each other and into borders: some
     * bits are forced, and the walk asked for exactly the others */
    CHECKF(t, forced > 0 && forced < swap_count, "%llu of %llu swap bits forced",
           (unsigned long long)forced, (unsigned long long)swap_count);
    CHECKF(t, src.calls == swap_count - forced && src.bad_previous == 0,
           "the walk asked for %llu bits (%llu free), %llu with the wrong previous bit",
           (unsigned long long)src.calls, (unsigned long long)(swap_count - forced),
           (unsigned long long)src.bad_previous);
    /* every strip's start asked for once, with the triangles describe saw;
     * side by side, some strips start next to the one before */
    CHECKF(t, src.starts == strips && src.bad_near == 0 && (strips < 8 || src.near_starts > 0),
           "%u starts asked for (%u strips), %u near the strip before, %u disagree", src.starts,
           strips, src.near_starts, src.bad_near);
    mts_grow_free(g);
    free(paths);
    free(swaps);
}

static void test_cow_every_split(mts_test *t)
{
    mts_model m = {0};
    if (!build_path(t, "tests/data/cow.off", &m))
        return;
    CHECK(t, m.key_count > 0);
    grow_checked(t, &m, 1);
    mts_model_free(&m);
}

static void test_generated_meshes_every_split(mts_test *t)
{
    char *off[2] = {torus_off(), terrain_off()};
    const char *name[2] = {"torus.off", "terrain.off"};
    for (int k = 0; k < 2; k++) {
        mts_model m = {0};
        if (build_off(t, name[k], off[k], &m)) {
            CHECKF(t, m.level_count > 500, "%s: %u levels", name[k], m.level_count);
            grow_checked(t, &m, 1);
        }
        mts_model_free(&m);
        free(off[k]);
    }
}

static void shared_sampled(mts_test *t, const char *file)
{
    char buf[512];
    const char *path = mts_test_model(file, buf, sizeof buf);
    if (!path)
        SKIP(t, "%s not found (../shared/models or $MTS_MODELS)", file);
    mts_model m = {0};
    if (!build_path(t, path, &m))
        return;
    grow_checked(t, &m, m.level_count / 500 + 1); /* about 500 levels, and every key */
    mts_model_free(&m);
}

static void test_bunny_sampled(mts_test *t)
{
    shared_sampled(t, "bunny00.off");
}

static void test_fandisk_sampled(mts_test *t)
{
    shared_sampled(t, "fandisk_large.off");
}

/* Every split of cow described explicitly -- the moved triangles by id and
 * the new ones by vertices, as the builder does where the fan rule fails --
 * grows exactly the same records as its fan code: the explicit path pairs
 * twins by a search of the whole mesh, not by the fan's two edges. */
static void test_explicit_splits_match_fans(mts_test *t)
{
    mts_model m = {0};
    if (!build_path(t, "tests/data/cow.off", &m))
        return;
    mts_error err = {0};
    mts_grow_options go = {0};
    go.key_levels = m.key_levels;
    go.key_count = m.key_count;
    mts_grow *fan = NULL, *ex = NULL;
    CHECK(t, mts_grow_create(&m.base, m.base_vertex_count, m.level_count, &go, &fan, &err) ==
                 MTS_OK);
    CHECK(t, mts_grow_create(&m.base, m.base_vertex_count, m.level_count, &go, &ex, &err) ==
                 MTS_OK);
    const mts_grow_full given = {.strips = &m.full, .slot_count = 0};
    uint32_t *ids = malloc(((size_t)m.vertex_count * 8 + 16) * 4);
    uint32_t born[6];
    for (uint32_t j = 0; fan && ex && j < m.level_count; j++) {
        mts_grow_split sp, xs = {0};
        CHECK(t, mts_grow_model_split(fan, &m, j, &sp));
        const uint32_t u = sp.parent, v = m.base_vertex_count + j;
        int32_t k = mts_grow_fan(ex, u, sp.left, sp.right, ids, m.vertex_count * 8 + 16);
        CHECKF(t, k > 0, "split %u: no fan", j);
        if (k <= 0)
            break;
        xs.parent = u;
        xs.left = xs.right = MTS_GROW_NONE;
        xs.moved = ids;
        xs.moved_count = (uint32_t)k;
        uint32_t nb = 0;
        if (sp.left != MTS_GROW_NONE) {
            born[3 * nb] = u, born[3 * nb + 1] = v, born[3 * nb + 2] = sp.left;
            nb++;
        }
        if (sp.right != MTS_GROW_NONE) {
            born[3 * nb] = v, born[3 * nb + 1] = u, born[3 * nb + 2] = sp.right;
            nb++;
        }
        xs.born = born;
        xs.born_count = nb;
        const uint32_t *r1, *r2;
        uint32_t w1, w2;
        CHECKF(t, mts_grow_next(fan, &sp, &given, &r1, &w1, &err) == MTS_OK, "%s", err.msg);
        CHECKF(t, mts_grow_next(ex, &xs, &given, &r2, &w2, &err) == MTS_OK, "%s", err.msg);
        if (w1 != w2 || memcmp(r1, r2, (size_t)w1 * 4) != 0) {
            CHECKF(t, 0, "split %u: explicit record differs from the fan's", j);
            break;
        }
        if (j % 7 == 0 && mts_grow_check(ex, &err) != MTS_OK) {
            CHECKF(t, 0, "after explicit split %u: %s", j, err.msg);
            break;
        }
    }
    free(ids);
    mts_grow_free(fan);
    mts_grow_free(ex);
    mts_model_free(&m);
}

/* Explicit splits a broken server could send: a triangle moved twice, one
 * without the parent, one out of range, a new triangle naming a vertex not
 * yet there, one that repeats a triangle the mesh holds. Each is an error
 * that names it; none crashes or hangs. */
static void test_hostile_explicit_splits(mts_test *t)
{
    mts_model m = {0};
    if (!build_path(t, "tests/data/cow.off", &m))
        return;
    mts_grow_options go = {0};
    go.key_levels = m.key_levels;
    go.key_count = m.key_count;
    const mts_grow_full given = {.strips = &m.full, .slot_count = 0};
    const uint32_t nb = m.base_vertex_count, u = m.parents[0];
    enum { TWICE, WITHOUT_U, OUT_OF_RANGE, UNBORN_VERTEX, REPEATED };
    static const struct {
        int kind;
        const char *needle;
    } cases[] = {
        {TWICE, "twice"},
        {WITHOUT_U, "no corner"},
        {OUT_OF_RANGE, "no corner"},
        {UNBORN_VERTEX, "not a triangle"},
        {REPEATED, "held by two triangles"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        mts_error err = {0};
        mts_grow *g = NULL;
        CHECK(t, mts_grow_create(&m.base, nb, m.level_count, &go, &g, &err) == MTS_OK);
        if (!g)
            continue;
        /* a triangle with corner u, and one without */
        uint32_t with_u = UINT32_MAX, without_u = UINT32_MAX, tri[3], u_tri[3] = {0};
        mts_grow_figures fig;
        mts_grow_get_figures(g, &fig);
        for (uint32_t x = 0; x < fig.triangles; x++) {
            mts_grow_triangle(g, x, tri);
            int has = tri[0] == u || tri[1] == u || tri[2] == u;
            if (has && with_u == UINT32_MAX) {
                with_u = x;
                memcpy(u_tri, tri, sizeof tri);
            } else if (!has && without_u == UINT32_MAX) {
                without_u = x;
            }
        }
        CHECK(t, with_u != UINT32_MAX && without_u != UINT32_MAX);
        uint32_t moved[2] = {with_u, with_u}, born[3] = {0, 0, 0};
        mts_grow_split sp = {0};
        sp.parent = u;
        sp.left = sp.right = MTS_GROW_NONE;
        sp.moved = moved;
        sp.born = born;
        switch (cases[c].kind) {
        case TWICE:
            sp.moved_count = 2;
            break;
        case WITHOUT_U:
            moved[0] = without_u;
            sp.moved_count = 1;
            break;
        case OUT_OF_RANGE:
            moved[0] = fig.triangles + 1000;
            sp.moved_count = 1;
            break;
        case UNBORN_VERTEX: /* u, another corner of its triangle, a vertex to come */
            born[0] = u;
            born[1] = u_tri[0] != u ? u_tri[0] : u_tri[1];
            born[2] = nb + 5;
            sp.born_count = 1;
            break;
        case REPEATED: /* an untouched triangle again */
            memcpy(born, u_tri, sizeof born);
            sp.born_count = 1;
            break;
        }
        const uint32_t *r;
        uint32_t w;
        mts_result rc = mts_grow_next(g, &sp, &given, &r, &w, &err);
        CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, cases[c].needle) != NULL,
               "case %zu: %s", c, err.msg);
        mts_grow_free(g);
    }
    mts_model_free(&m);
}

/* greedy.c on cow's full mesh: a cover (every triangle once), paths of
 * neighbours no longer than asked, the same paths twice. */
static void test_greedy_cover(mts_test *t)
{
    mts_model m = {0};
    if (!build_path(t, "tests/data/cow.off", &m))
        return;
    mts_error err = {0};
    mts_grow *g = NULL;
    const mts_grow_full given = {.strips = &m.full, .slot_count = 0};
    mts_grow_options go = {0};
    go.key_levels = m.key_levels;
    go.key_count = m.key_count;
    CHECK(t, mts_grow_create(&m.base, m.base_vertex_count, m.level_count, &go, &g, &err) ==
                 MTS_OK);
    for (uint32_t j = 0; g && j < m.level_count; j++) {
        mts_grow_split sp;
        const uint32_t *r;
        uint32_t w;
        CHECK(t, mts_grow_model_split(g, &m, j, &sp) &&
                     mts_grow_next(g, &sp, &given, &r, &w, &err) == MTS_OK);
    }
    mts_grow_figures fig;
    mts_grow_get_figures(g, &fig);
    const uint32_t n = fig.triangles;
    /* twins by brute force over the full mesh */
    uint32_t (*tri)[3] = malloc((size_t)n * 12), *twin = malloc((size_t)n * 12);
    for (uint32_t x = 0; x < n; x++)
        mts_grow_triangle(g, x, tri[x]);
    for (uint32_t h = 0; h < 3 * n; h++) {
        uint32_t a = tri[h / 3][h % 3], b = tri[h / 3][(h % 3 + 1) % 3];
        twin[h] = MTS_GREEDY_NONE;
        for (uint32_t o = 0; o < 3 * n && twin[h] == MTS_GREEDY_NONE; o++) {
            if (tri[o / 3][o % 3] == b && tri[o / 3][(o % 3 + 1) % 3] == a)
                twin[h] = o;
        }
    }
    uint32_t *order = malloc((size_t)n * 4), *again = malloc((size_t)n * 4);
    uint32_t *starts = malloc(((size_t)n + 1) * 4), *starts2 = malloc(((size_t)n + 1) * 4);
    uint8_t *seen = malloc(n);
    const uint32_t caps[] = {1, 2, 7, 256};
    for (size_t c = 0; c < sizeof caps / sizeof caps[0]; c++) {
        uint32_t count = 0, count2 = 0;
        CHECKF(t, mts_greedy_paths(n, twin, 3, caps[c], order, starts, &count, &err) == MTS_OK,
               "%s", err.msg);
        CHECK(t, mts_greedy_paths(n, twin, 3, caps[c], again, starts2, &count2, &err) == MTS_OK);
        CHECK(t, count == count2 && memcmp(order, again, (size_t)n * 4) == 0 &&
                     memcmp(starts, starts2, ((size_t)count + 1) * 4) == 0);
        CHECK(t, starts[0] == 0 && starts[count] == n);
        memset(seen, 0, n);
        for (uint32_t k = 0; k < count; k++) {
            CHECK(t, starts[k + 1] > starts[k] && starts[k + 1] - starts[k] <= caps[c]);
            for (uint32_t i = starts[k]; i < starts[k + 1]; i++) {
                CHECK(t, order[i] < n && !seen[order[i]]);
                seen[order[i] < n ? order[i] : 0] = 1;
                if (i > starts[k]) {
                    uint32_t a = order[i - 1], b = order[i], linked = 0;
                    for (int e = 0; e < 3; e++)
                        linked |= twin[3 * a + e] != MTS_GREEDY_NONE && twin[3 * a + e] / 3 == b;
                    CHECK(t, linked);
                }
            }
        }
        if (caps[c] == 1)
            CHECK(t, count == n);
        if (caps[c] == 256)
            CHECKF(t, count < n / 10, "%u paths for %u triangles", count, n);
    }
    free(tri);
    free(twin);
    free(order);
    free(again);
    free(starts);
    free(starts2);
    free(seen);
    mts_grow_free(g);
    mts_model_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_cow_every_split);
    RUN(&t, test_generated_meshes_every_split);
    RUN(&t, test_explicit_splits_match_fans);
    RUN(&t, test_hostile_explicit_splits);
    RUN(&t, test_greedy_cover);
    RUN(&t, test_bunny_sampled);
    RUN(&t, test_fandisk_sampled);
    return mts_test_end(&t);
}
