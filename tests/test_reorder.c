/* Split reordering (builder/reorder.h): the reordered collapses are the same
 * collapses, each legal where it now stands and removing the faces it
 * removed before; the mesh after all of them is the same face for face; and
 * the parents come in a few ascending runs a window, which is the point.
 * On cow and, where ../shared is, bunny00; plus malformed sequences.
 * (docs/architecture.md's invariants on reordered models: test_lod, every level.) */
#include <stdint.h>

#include "mesh.h"
#include "reorder.h"
#include "simplify.h"
#include "test.h"

/* Replays collapses on a face set (the obvious way: every face scanned a
 * collapse, small meshes only): 0 when one names a vertex that is gone;
 * each collapse's removed-face count in removed[]; the faces left, rotated
 * to start at their lowest index and sorted, in out (3 a face). */
static int cmp_face(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (int k = 0; k < 3; k++) {
        if (x[k] != y[k])
            return x[k] < y[k] ? -1 : 1;
    }
    return 0;
}

static int replay(const mts_mesh *mesh, const mts_collapse *c, uint32_t n, uint32_t *removed,
                  uint32_t *out, uint32_t *out_count)
{
    const uint32_t F = mesh->triangle_count;
    uint32_t *tri = malloc((size_t)F * 12);
    uint8_t *dead = calloc(F, 1), *gone = calloc(mesh->vertex_count, 1);
    int ok = tri && dead && gone;
    if (ok)
        memcpy(tri, mesh->triangles, (size_t)F * 12);
    for (uint32_t i = 0; i < n && ok; i++) {
        const uint32_t r = c[i].removed, k = c[i].kept;
        if (gone[r] || gone[k]) {
            ok = 0;
            break;
        }
        removed[i] = 0;
        for (uint32_t f = 0; f < F; f++) {
            uint32_t *t = tri + 3 * (size_t)f;
            if (dead[f] || (t[0] != r && t[1] != r && t[2] != r))
                continue;
            if (t[0] == k || t[1] == k || t[2] == k) {
                dead[f] = 1;
                removed[i]++;
            } else {
                for (int e = 0; e < 3; e++)
                    t[e] = t[e] == r ? k : t[e];
            }
        }
        gone[r] = 1;
    }
    uint32_t m = 0;
    for (uint32_t f = 0; f < F && ok; f++) {
        if (dead[f])
            continue;
        const uint32_t *t = tri + 3 * (size_t)f;
        int lo = t[0] <= t[1] && t[0] <= t[2] ? 0 : t[1] <= t[2] ? 1 : 2;
        for (int e = 0; e < 3; e++)
            out[3 * m + e] = t[(lo + e) % 3];
        m++;
    }
    if (ok)
        qsort(out, m, 12, cmp_face);
    *out_count = m;
    free(tri);
    free(dead);
    free(gone);
    return ok;
}

/* Splits whose parent's final id is at least the previous split's. */
static uint32_t ascending(const mts_mesh *mesh, const mts_collapse *c, uint32_t n)
{
    const uint32_t nv = mesh->vertex_count, nb = nv - n;
    uint32_t *id = malloc((size_t)nv * 4), up = 0, next = 0, prev = 0;
    for (uint32_t x = 0; x < nv; x++)
        id[x] = UINT32_MAX;
    for (uint32_t i = 0; i < n; i++)
        id[c[i].removed] = nb + (n - 1 - i);
    for (uint32_t x = 0; x < nv; x++) {
        if (id[x] == UINT32_MAX)
            id[x] = next++;
    }
    for (uint32_t j = 0; j < n; j++) {
        const uint32_t u = id[c[n - 1 - j].kept];
        up += u >= prev;
        prev = u;
    }
    free(id);
    return up;
}

/* replay_too: also replay both orders the obvious way (a scan of every face
 * a collapse: cow only) */
static void check_mesh(mts_test *t, const char *path, uint32_t window, int replay_too)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return;
    }
    mts_simplify_result simp = {0};
    mts_simplify_options so = {0};
    if (mts_simplify(mesh.positions, mesh.vertex_count, mesh.triangles, mesh.triangle_count, &so,
                     &simp, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        mts_mesh_free(&mesh);
        return;
    }
    const uint32_t n = simp.collapse_count, F = mesh.triangle_count;
    mts_collapse *orig = malloc((size_t)n * sizeof *orig);
    uint32_t *rem0 = malloc((size_t)n * 4), *rem1 = malloc((size_t)n * 4);
    uint32_t *faces0 = malloc((size_t)F * 12), *faces1 = malloc((size_t)F * 12);
    memcpy(orig, simp.collapses, (size_t)n * sizeof *orig);
    mts_reorder_options ro = {0};
    ro.window = window;
    mts_reorder_stats st;
    CHECKF(t, mts_reorder_collapses(mesh.triangles, F, mesh.vertex_count, simp.collapses, n, &ro,
                                    &st, &err) == MTS_OK,
           "%s", err.msg);
    /* a permutation: every removed vertex once, with the same kept vertex */
    uint32_t *kept_of = malloc((size_t)mesh.vertex_count * 4);
    for (uint32_t x = 0; x < mesh.vertex_count; x++)
        kept_of[x] = UINT32_MAX;
    for (uint32_t i = 0; i < n; i++)
        kept_of[orig[i].removed] = orig[i].kept;
    uint32_t same = 0, moved = 0;
    for (uint32_t i = 0; i < n; i++) {
        same += kept_of[simp.collapses[i].removed] == simp.collapses[i].kept;
        kept_of[simp.collapses[i].removed] = UINT32_MAX - 1; /* once */
        moved += simp.collapses[i].removed != orig[i].removed;
    }
    CHECKF(t, same == n, "%u of %u collapses are the originals", same, n);
    CHECKF(t, moved > n / 4, "only %u of %u collapses moved", moved, n);
    /* each legal where it stands, removing what it removed; the same mesh */
    uint32_t m0 = 0, m1 = 0;
    if (!replay_too)
        goto runs;
    CHECK(t, replay(&mesh, orig, n, rem0, faces0, &m0));
    CHECKF(t, replay(&mesh, simp.collapses, n, rem1, faces1, &m1),
           "a reordered collapse names a vertex already gone");
    if (!t->case_failed) {
        CHECKF(t, m0 == m1 && memcmp(faces0, faces1, (size_t)m0 * 12) == 0,
               "the mesh after every collapse differs (%u faces against %u)", m1, m0);
        /* collapse i of the new order is some collapse of the old one: the
         * same removed vertex removes the same number of faces */
        uint32_t *by_vertex = malloc((size_t)mesh.vertex_count * 4);
        for (uint32_t i = 0; i < n; i++)
            by_vertex[orig[i].removed] = rem0[i];
        uint32_t differ = 0;
        for (uint32_t i = 0; i < n; i++)
            differ += by_vertex[simp.collapses[i].removed] != rem1[i];
        CHECKF(t, differ == 0, "%u collapses remove other faces than before", differ);
        free(by_vertex);
    }
runs:;
    /* the point: a parent is mostly at least the one before it (final ids
     * as lodbuild gives them), where in the decimation's order it is so
     * about half the time */
    uint32_t up0 = ascending(&mesh, orig, n), up1 = ascending(&mesh, simp.collapses, n);
    CHECKF(t, up1 >= n - n / 10 && up1 > up0,
           "%u of %u parents at least the one before (%u before reordering; %u runs)", up1, n,
           up0, st.runs);
    free(kept_of);
    free(orig);
    free(rem0);
    free(rem1);
    free(faces0);
    free(faces1);
    mts_simplify_result_free(&simp);
    mts_mesh_free(&mesh);
}

static void test_cow(mts_test *t)
{
    check_mesh(t, "tests/data/cow.off", 0, 1);
    check_mesh(t, "tests/data/cow.off", 500, 1);
}

static void test_bunny(mts_test *t)
{
    char buf[512];
    const char *p = mts_test_model("bunny00.off", buf, sizeof buf);
    if (!p) {
        SKIP(t, "%s not found", buf);
        return;
    }
    /* its reordering is replayed by reorder.c itself, which refuses a
     * collapse that names a vertex already gone */
    check_mesh(t, p, 0, 0);
}

static void test_malformed(mts_test *t)
{
    /* two triangles (0 1 2) (0 2 3) */
    const uint32_t tri[6] = {0, 1, 2, 0, 2, 3};
    mts_error err = {0};
    mts_collapse twice[2] = {{1, 0, 1}, {1, 2, 1}};
    CHECK(t, mts_reorder_collapses(tri, 2, 4, twice, 2, NULL, NULL, &err) == MTS_ERR_ARG);
    CHECKF(t, strstr(err.msg, "gone") != NULL, "%s", err.msg);
    mts_collapse into_gone[2] = {{1, 0, 1}, {3, 1, 1}};
    CHECK(t, mts_reorder_collapses(tri, 2, 4, into_gone, 2, NULL, NULL, &err) == MTS_ERR_ARG);
    mts_collapse out_of_range[2] = {{7, 0, 1}, {3, 2, 1}};
    CHECK(t, mts_reorder_collapses(tri, 2, 4, out_of_range, 2, NULL, NULL, &err) == MTS_ERR_ARG);
    mts_collapse too_many[4] = {{1, 0, 1}, {2, 0, 1}, {3, 0, 1}, {0, 1, 1}};
    CHECK(t, mts_reorder_collapses(tri, 2, 4, too_many, 4, NULL, NULL, &err) == MTS_ERR_ARG);
    /* window 1: nothing moves */
    mts_collapse one[2] = {{1, 0, 1}, {3, 2, 1}};
    mts_reorder_options ro = {.window = 1};
    CHECK(t, mts_reorder_collapses(tri, 2, 4, one, 2, &ro, NULL, &err) == MTS_OK);
    CHECK(t, one[0].removed == 1 && one[1].removed == 3);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_cow);
    RUN(&t, test_malformed);
    RUN(&t, test_bunny);
    return mts_test_end(&t);
}
