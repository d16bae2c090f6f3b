/* Tests of the tunnelling pass (builder/tunnel.c): the strips after it draw
 * exactly the oriented triangles the greedy strips drew (docs/architecture.md,
 * invariant 1), none over the cap, with no more indices, the same bytes on
 * every run; and on a hand-made mesh the one tunnel of length 3 that joins
 * two of three strips is found (and not with length 1).
 *
 * With MTS_TEST_VERBOSE set, the model cases print the figures before and
 * after: strips, swaps, indices per triangle (one restart between strips),
 * ACMR of a FIFO cache of 16 and 32 fed every index, and seconds. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "error.h"
#include "mesh.h"
#include "stripify.h"
#include "strips.h"
#include "test.h"
#include "test_proc.h"
#include "tunnel.h"

/* The canonical oriented triangles the strips draw, sorted; *count gets
 * their number. NULL when out of memory. */
static uint32_t *drawn_triangles(const mts_strips *s, uint64_t *count)
{
    mts_strip_stats st;
    mts_strips_stats(s, &st);
    uint32_t *got = malloc((size_t)(st.triangles + 1) * 3 * sizeof *got);
    if (!got)
        return NULL;
    uint64_t k = 0;
    for (uint32_t i = 0; i < s->strip_count; i++) {
        const uint32_t *p = s->indices + s->offsets[i];
        uint32_t len = s->offsets[i + 1] - s->offsets[i];
        for (uint32_t w = 0; w + 2 < len; w++) {
            if (mts_strip_window(p, w, got + 3 * k)) {
                mts_tri_canonical(got + 3 * k);
                k++;
            }
        }
    }
    qsort(got, (size_t)k, 3 * sizeof *got, mts_tri_compare);
    *count = k;
    return got;
}

static int same_strips(const mts_strips *a, const mts_strips *b)
{
    return a->strip_count == b->strip_count && a->index_count == b->index_count &&
           memcmp(a->offsets, b->offsets, ((size_t)a->strip_count + 1) * sizeof *a->offsets) == 0 &&
           memcmp(a->indices, b->indices, (size_t)a->index_count * sizeof *a->indices) == 0;
}

/* after draws what before drew, once each, with the winding; every strip
 * draws 1..cap triangles; the stats agree with the strips. */
static void check_same_surface(mts_test *t, const mts_strips *before, const mts_strips *after,
                               const mts_tunnel_stats *ts)
{
    uint64_t nb = 0, na = 0;
    uint32_t *a = drawn_triangles(before, &nb), *b = drawn_triangles(after, &na);
    CHECK(t, a && b);
    if (a && b) {
        CHECKF(t, na == nb, "%llu triangles before, %llu after", (unsigned long long)nb,
               (unsigned long long)na);
        CHECKF(t, na == nb && memcmp(a, b, (size_t)na * 3 * sizeof *a) == 0,
               "the oriented triangles differ");
    }
    free(a);
    free(b);
    CHECK(t, after->offsets[0] == 0 && after->offsets[after->strip_count] == after->index_count);
    for (uint32_t i = 0; i < after->strip_count; i++) {
        mts_strip_stats one = {0};
        mts_strip_stats_add(&one, after->indices + after->offsets[i],
                            after->offsets[i + 1] - after->offsets[i]);
        CHECKF(t, one.triangles >= 1 && one.triangles <= MTS_STRIPIFY_MAX_STRIP,
               "strip %u draws %llu triangles", i, (unsigned long long)one.triangles);
    }
    mts_strip_stats sb, sa;
    mts_strips_stats(before, &sb);
    mts_strips_stats(after, &sa);
    CHECK(t, ts->strips_before == sb.strips && ts->strips_after == sa.strips);
    CHECK(t, ts->swaps_before == sb.degenerate && ts->swaps_after == sa.degenerate);
    CHECK(t, ts->draw_indices_before == mts_strip_stats_draw_indices(&sb));
    CHECK(t, ts->draw_indices_after == mts_strip_stats_draw_indices(&sa));
    CHECKF(t, ts->draw_indices_after <= ts->draw_indices_before, "%llu indices after, %llu before",
           (unsigned long long)ts->draw_indices_after,
           (unsigned long long)ts->draw_indices_before);
}

/* Two quads' worth of triangles y = (0 1 3), y' = (1 2 3) sharing 1-3, with
 * an ear on each other edge: p0 on 3-0, z on 0-1, p3 on 1-2, w on 2-3. The
 * dual graph is an H: y - y' with leaves p0, z on y and p3, w on y'. Strips:
 * p0 y y' p3 (no swap), z, w. No strip end touches another (no 1-tunnel),
 * there is no swap to repair, but z -dashed- y -solid- y' -dashed- w is a
 * 3-tunnel: complemented, z y p0 and w y' p3, two strips without a swap. */
static void make_h(mts_strips *s)
{
    static const uint32_t idx[] = {5, 0, 3, 1, 2, 6, /* p0 y y' p3 */
                                   1, 0, 4,          /* z = (1 0 4) */
                                   3, 2, 7};         /* w = (3 2 7) */
    static const uint32_t off[] = {0, 6, 9, 12};
    s->strip_count = 3;
    s->index_count = 12;
    s->offsets = (uint32_t *)off;
    s->indices = (uint32_t *)idx;
}

static void test_known_tunnel(mts_test *t)
{
    mts_strips in, out = {0};
    make_h(&in);
    mts_error err = {0};
    mts_tunnel_stats ts;
    mts_tunnel_options o = {0};
    o.anneal = -1; /* the exhaustive search alone */

    o.length = 1;
    mts_result r = mts_tunnel(&in, 8, &o, &out, &ts, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        check_same_surface(t, &in, &out, &ts);
        CHECKF(t, out.strip_count == 3, "length 1 made %u strips", out.strip_count);
    }
    mts_strips_free(&out);

    o.length = 3;
    r = mts_tunnel(&in, 8, &o, &out, &ts, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        check_same_surface(t, &in, &out, &ts);
        CHECKF(t, out.strip_count == 2, "length 3 made %u strips", out.strip_count);
        CHECK(t, ts.swaps_after == 0);
        CHECK(t, ts.draw_indices_before == 14 && ts.draw_indices_after == 11);
    }
    mts_strips_free(&out);

    /* the defaults (annealing included) find it too */
    r = mts_tunnel(&in, 8, NULL, &out, &ts, &err);
    CHECK(t, r == MTS_OK && out.strip_count == 2);
    mts_strips_free(&out);
}

static void test_empty_and_errors(mts_test *t)
{
    uint32_t off[1] = {0}, idx[1] = {0};
    mts_strips in = {.offsets = off, .indices = idx}, out = {0};
    mts_error err = {0};
    mts_tunnel_stats ts;
    CHECK(t, mts_tunnel(&in, 0, NULL, &out, &ts, &err) == MTS_OK);
    CHECK(t, out.strip_count == 0 && ts.strips_after == 0);
    mts_strips_free(&out);

    uint32_t off1[2] = {0, 3}, idx1[3] = {0, 1, 9};
    mts_strips bad = {.strip_count = 1, .index_count = 3, .offsets = off1, .indices = idx1};
    CHECK(t, mts_tunnel(&bad, 5, NULL, &out, NULL, &err) == MTS_ERR_RANGE);
    CHECK(t, out.offsets == NULL && out.indices == NULL);
}

/* Misses of the strips, in order, through a FIFO cache of `size` (UINT64_MAX
 * when out of memory). */
static uint64_t fifo_misses(const mts_strips *s, uint32_t vertex_count, uint32_t size)
{
    uint64_t *stamp = calloc((size_t)vertex_count + 1, sizeof *stamp), misses = 0;
    if (!stamp)
        return UINT64_MAX;
    for (uint32_t k = 0; k < s->index_count; k++) {
        uint32_t v = s->indices[k];
        if (!(stamp[v] && stamp[v] + size > misses))
            stamp[v] = ++misses;
    }
    free(stamp);
    return misses;
}

static double fifo_acmr(const mts_strips *s, uint32_t vertex_count, uint32_t size, uint64_t tris)
{
    return tris ? (double)fifo_misses(s, vertex_count, size) / (double)tris : 0;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* Strips that start with a swap: a strip starts at even parity, and about
 * half the path ends need a swap there; tunnel.c counts a path that needs
 * one at both ends, so few are left. */
static uint32_t start_swaps(const mts_strips *s)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < s->strip_count; i++) {
        const uint32_t *p = s->indices + s->offsets[i];
        n += s->offsets[i + 1] - s->offsets[i] >= 4 && p[1] == p[3];
    }
    return n;
}

/* Greedy strips of the model, then tunnelling twice: same surface, cap,
 * fewer or equal indices, the same bytes both times; few strips that start
 * with a swap; the cache order misses no more than the strips' own order
 * (cache_size 1: the same strips, in the order they were found). */
static void check_model(mts_test *t, const char *path)
{
    mts_mesh mesh = {0};
    mts_error err = {0};
    mts_result r = mts_mesh_load(path, NULL, &mesh, NULL, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return;
    mts_strips greedy = {0}, a = {0}, b = {0};
    mts_tunnel_stats ta, tb;
    r = mts_stripify(mesh.triangles, mesh.triangle_count, mesh.vertex_count, &greedy, NULL, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        double t0 = now();
        r = mts_tunnel(&greedy, mesh.vertex_count, NULL, &a, &ta, &err);
        double t1 = now();
        CHECKF(t, r == MTS_OK, "%s", err.msg);
        if (r == MTS_OK) {
            check_same_surface(t, &greedy, &a, &ta);
            CHECK(t, ta.triangles == mesh.triangle_count);
            /* the order's own count, kept through every move of its
             * refinement, is the cache's */
            uint64_t m32 = fifo_misses(&a, mesh.vertex_count, 32);
            CHECKF(t, ta.cache_misses == m32, "the order counts %llu misses, the cache %llu",
                   (unsigned long long)ta.cache_misses, (unsigned long long)m32);
            r = mts_tunnel(&greedy, mesh.vertex_count, NULL, &b, &tb, &err);
            CHECK(t, r == MTS_OK);
            CHECKF(t, r == MTS_OK && same_strips(&a, &b), "two runs differ");
            uint32_t ss = start_swaps(&a);
            CHECKF(t, ss * 20 <= a.strip_count, "%u of %u strips start with a swap", ss,
                   a.strip_count);
            mts_strips_free(&b);
            /* and for another cache: the same strips, ordered for it */
            mts_tunnel_options small = {0};
            small.cache_size = 12;
            r = mts_tunnel(&greedy, mesh.vertex_count, &small, &b, &tb, &err);
            CHECK(t, r == MTS_OK && tb.draw_indices_after == ta.draw_indices_after);
            if (r == MTS_OK) {
                uint64_t m12 = fifo_misses(&b, mesh.vertex_count, 12);
                CHECKF(t, tb.cache_misses == m12, "cache of 12: the order counts %llu, the cache %llu",
                       (unsigned long long)tb.cache_misses, (unsigned long long)m12);
            }
            mts_strips_free(&b);
            mts_tunnel_options keep = {0};
            keep.cache_size = 1;
            r = mts_tunnel(&greedy, mesh.vertex_count, &keep, &b, &tb, &err);
            CHECK(t, r == MTS_OK && tb.draw_indices_after == ta.draw_indices_after);
            if (r == MTS_OK) {
                uint64_t n = mesh.triangle_count;
                double ordered = fifo_acmr(&a, mesh.vertex_count, 32, n),
                       kept = fifo_acmr(&b, mesh.vertex_count, 32, n);
                CHECKF(t, ordered <= kept, "ACMR-32 %.3f ordered, %.3f in the found order",
                       ordered, kept);
            }
            if (getenv("MTS_TEST_VERBOSE")) {
                uint64_t n = mesh.triangle_count;
                fprintf(stderr,
                        "  %s: greedy %u strips %llu swaps %.4f idx/tri ACMR %.3f/%.3f; "
                        "tunnelled %u strips %llu swaps %.4f idx/tri ACMR %.3f/%.3f, %.2f s\n",
                        path, ta.strips_before, (unsigned long long)ta.swaps_before,
                        (double)ta.draw_indices_before / n,
                        fifo_acmr(&greedy, mesh.vertex_count, 16, n),
                        fifo_acmr(&greedy, mesh.vertex_count, 32, n), ta.strips_after,
                        (unsigned long long)ta.swaps_after, (double)ta.draw_indices_after / n,
                        fifo_acmr(&a, mesh.vertex_count, 16, n),
                        fifo_acmr(&a, mesh.vertex_count, 32, n), t1 - t0);
            }
        }
    }
    mts_strips_free(&greedy);
    mts_strips_free(&a);
    mts_strips_free(&b);
    mts_mesh_free(&mesh);
}

static void test_cow(mts_test *t)
{
    check_model(t, "tests/data/cow.off");
}

/* A cache far larger than the mesh: the order is made (every vertex misses
 * once, whatever the order) without the refinement's per-position copies
 * of the cache, which would take gigabytes. */
static void test_huge_cache(mts_test *t)
{
    mts_mesh mesh = {0};
    mts_error err = {0};
    mts_result r = mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return;
    mts_strips greedy = {0}, out = {0};
    mts_tunnel_stats ts = {0};
    mts_tunnel_options o = {0};
    o.cache_size = 1u << 22;
    CHECK(t, mts_stripify(mesh.triangles, mesh.triangle_count, mesh.vertex_count, &greedy, NULL,
                          &err) == MTS_OK);
    r = mts_tunnel(&greedy, mesh.vertex_count, &o, &out, &ts, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        check_same_surface(t, &greedy, &out, &ts);
        uint8_t *used = calloc((size_t)mesh.vertex_count + 1, 1);
        uint64_t distinct = 0;
        for (uint32_t k = 0; used && k < out.index_count; k++) {
            distinct += !used[out.indices[k]];
            used[out.indices[k]] = 1;
        }
        free(used);
        CHECKF(t, distinct > 0 && ts.cache_misses == distinct &&
                      fifo_misses(&out, mesh.vertex_count, o.cache_size) == distinct,
               "%llu misses for %llu vertices drawn", (unsigned long long)ts.cache_misses,
               (unsigned long long)distinct);
    }
    mts_strips_free(&greedy);
    mts_strips_free(&out);
    mts_mesh_free(&mesh);
}

/* Vertex ids up to 2^32 - 2 on two triangles: the same triangles come out,
 * with the same ids, and (outside ASan, whose shadow memory needs terabytes
 * of address space) a child limited to 1 GB manages it: memory follows the
 * strips, not the ids. */
#ifndef __SANITIZE_ADDRESS__ /* a memory limit cannot work under ASan */
static int huge_ids_tunnel(void *arg)
{
    mts_strips out = {0};
    mts_error err;
    return mts_tunnel(arg, UINT32_MAX, NULL, &out, NULL, &err) == MTS_OK;
}
#endif

static void test_huge_vertex_ids(mts_test *t)
{
    uint32_t hi = UINT32_MAX - 1;
    uint32_t off[3] = {0, 3, 6}, idx[6] = {hi, hi - 1, 7, hi, 7, 0};
    mts_strips in = {.strip_count = 2, .index_count = 6, .offsets = off, .indices = idx}, out = {0};
    mts_tunnel_stats ts = {0};
    mts_error err = {0};
    mts_result r = mts_tunnel(&in, UINT32_MAX, NULL, &out, &ts, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK)
        check_same_surface(t, &in, &out, &ts);
    mts_strips_free(&out);
    CHECK(t, mts_tunnel(&in, hi, NULL, &out, NULL, &err) == MTS_ERR_RANGE);
#ifndef __SANITIZE_ADDRESS__
    CHECKF(t, mts_test_within_memory(huge_ids_tunnel, &in, 1u << 30),
           "tunnelling 2 triangles with huge vertex ids needs more than 1 GB");
#endif
}

static void test_bunny(mts_test *t)
{
    char buf[512];
    const char *path = mts_test_model("bunny00.off", buf, sizeof buf);
    if (!path)
        SKIP(t, "no bunny00.off in $MTS_MODELS or ../shared/models");
    check_model(t, path);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_known_tunnel);
    RUN(&t, test_empty_and_errors);
    RUN(&t, test_cow);
    RUN(&t, test_huge_cache);
    RUN(&t, test_huge_vertex_ids);
    RUN(&t, test_bunny);
    return mts_test_end(&t);
}
