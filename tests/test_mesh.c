/* Mesh loading: every format and variant on small meshes whose answer is
 * known, the cleaning pipeline's counts, every kind of bad input (which must
 * give the right code and a message naming the file, never a crash), and the
 * real models for counts and load time. */
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "clock.h"
#include "draco.h"
#include "gltf_read.h"
#include "mesh.h"
#include "mesh_read.h"
#include "test.h"

/* ------------------------------------------------------------------------ */
/* Helpers                                                                  */

typedef struct buf {
    unsigned char *d;
    size_t n, cap;
} buf;

static void buf_put(buf *b, const void *p, size_t n)
{
    if (b->n + n > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < b->n + n)
            cap *= 2;
        unsigned char *d = realloc(b->d, cap);
        if (!d)
            abort();
        b->d = d;
        b->cap = cap;
    }
    memcpy(b->d + b->n, p, n);
    b->n += n;
}

static void buf_printf(buf *b, const char *fmt, ...)
{
    char tmp[1024];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    buf_put(b, tmp, (size_t)n);
}

static void buf_free(buf *b)
{
    free(b->d);
    *b = (buf){0};
}

/* Writes data to NAME in the scratch directory; returns the path in out. */
static const char *write_file(const char *name, const void *data, size_t size, char *out,
                              size_t out_size)
{
    snprintf(out, out_size, "%s/mts_test_mesh_%s", mts_test_tmpdir(), name);
    FILE *f = fopen(out, "wb");
    if (!f)
        return NULL;
    if (size && fwrite(data, 1, size, f) != size) {
        fclose(f);
        return NULL;
    }
    fclose(f);
    return out;
}

/* Loads text as a file named NAME (through the file path, like a user would). */
static mts_result load_text(const char *name, const char *text, mts_mesh *mesh,
                            mts_mesh_stats *stats, mts_error *err)
{
    char path[512];
    if (!write_file(name, text, strlen(text), path, sizeof path))
        return mts_error_set(err, MTS_ERR_IO, "test could not write %s", name);
    mts_result r = mts_mesh_load(path, NULL, mesh, stats, err);
    remove(path);
    return r;
}

/* Loads bytes from an exactly sized heap copy, so that ASan sees any read
 * past the end (the parsers must not need a terminator). */
static mts_result load_bytes(const char *name, const void *data, size_t size, mts_mesh *mesh,
                             mts_mesh_stats *stats, mts_error *err)
{
    void *copy = malloc(size ? size : 1);
    if (!copy)
        abort();
    if (size)
        memcpy(copy, data, size);
    mts_result r = mts_mesh_load_memory(name, copy, size, NULL, mesh, stats, err);
    free(copy);
    return r;
}

static int tri_equal(const uint32_t *t, uint32_t a, uint32_t b, uint32_t c)
{
    return t[0] == a && t[1] == b && t[2] == c;
}

/* Every normal is unit length and points away from the centroid (the test
 * meshes are convex and closed), and every triangle faces outward. */
static int outward(const mts_mesh *m)
{
    double c[3] = {0, 0, 0};
    for (uint32_t v = 0; v < m->vertex_count; v++)
        for (int k = 0; k < 3; k++)
            c[k] += m->positions[v * 3 + k] / m->vertex_count;
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        const float *n = m->normals + v * 3, *p = m->positions + v * 3;
        double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        double dot = n[0] * (p[0] - c[0]) + n[1] * (p[1] - c[1]) + n[2] * (p[2] - c[2]);
        if (fabs(len - 1) > 1e-5 || dot <= 0)
            return 0;
    }
    for (uint32_t f = 0; f < m->triangle_count; f++) {
        const uint32_t *t = m->triangles + f * 3;
        const float *a = m->positions + t[0] * 3, *b = m->positions + t[1] * 3,
                    *d = m->positions + t[2] * 3;
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                       u[0] * w[1] - u[1] * w[0]};
        double dot = 0;
        for (int k = 0; k < 3; k++)
            dot += n[k] * ((a[k] + b[k] + d[k]) / 3 - c[k]);
        if (dot <= 0)
            return 0;
    }
    return 1;
}

static int all_unit(const mts_mesh *m)
{
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        const float *n = m->normals + v * 3;
        double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (fabs(len - 1) > 1e-5)
            return 0;
    }
    return 1;
}


/* The unit tetrahedron, faces counter-clockwise seen from outside. */
static const float tet_pos[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
static const uint32_t tet_tri[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

/* The unit cube: vertex x + 2y + 4z; quads counter-clockwise from outside. */
static const uint32_t cube_quad[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                         {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};

static void check_cube(mts_test *t, const mts_mesh *m, const mts_mesh_stats *st)
{
    CHECK(t, m->vertex_count == 8);
    CHECK(t, m->triangle_count == 12);
    CHECK(t, st->file_vertices == 8);
    CHECK(t, st->file_faces == 6);
    CHECK(t, st->polygons_triangulated == 6);
    CHECK(t, st->degenerate_faces == 0 && st->duplicate_faces == 0);
    CHECK(t, st->nonmanifold_faces == 0 && st->unreferenced_vertices == 0);
    if (m->vertex_count != 8 || m->triangle_count != 12)
        return;
    for (int v = 0; v < 8; v++) {
        CHECK(t, m->positions[v * 3] == (float)(v & 1));
        CHECK(t, m->positions[v * 3 + 1] == (float)(v >> 1 & 1));
        CHECK(t, m->positions[v * 3 + 2] == (float)(v >> 2 & 1));
    }
    /* fan triangulation keeps the winding: (a b c d) -> (a b c) (a c d) */
    for (int f = 0; f < 6; f++) {
        const uint32_t *q = cube_quad[f];
        CHECK(t, tri_equal(m->triangles + f * 6, q[0], q[1], q[2]));
        CHECK(t, tri_equal(m->triangles + f * 6 + 3, q[0], q[2], q[3]));
    }
    CHECK(t, outward(m));
}

static void cube_off(buf *b)
{
    buf_printf(b, "OFF\n8 6 12\n");
    for (int v = 0; v < 8; v++)
        buf_printf(b, "%d %d %d\n", v & 1, v >> 1 & 1, v >> 2 & 1);
    for (int f = 0; f < 6; f++)
        buf_printf(b, "4 %u %u %u %u\n", cube_quad[f][0], cube_quad[f][1], cube_quad[f][2],
                   cube_quad[f][3]);
}

/* ------------------------------------------------------------------------ */
/* OFF                                                                      */

static void test_off_tetrahedron(mts_test *t)
{
    const char *text = "# a comment before the header\n"
                       "OFF\n"
                       "# counts follow\n"
                       "4 4 6\n"
                       "0 0 0\n"
                       "1.0 0 0 # trailing comment\n"
                       "\n"
                       "0 1e0 0\n"
                       "0 0 +1\n"
                       "3 0 2 1\n"
                       "3 0 1 3\n"
                       "3 0 3 2\n"
                       "3\t1 2 3\r\n";
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = load_text("tet.off", text, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return;
    CHECK(t, st.format == MTS_MESH_OFF);
    CHECK(t, m.vertex_count == 4 && m.triangle_count == 4);
    CHECK(t, st.file_vertices == 4 && st.file_faces == 4);
    CHECK(t, st.polygons_triangulated == 0 && st.degenerate_faces == 0);
    CHECK(t, st.normals_from_file == 0);
    CHECK(t, memcmp(m.positions, tet_pos, sizeof tet_pos) == 0);
    CHECK(t, memcmp(m.triangles, tet_tri, sizeof tet_tri) == 0);
    CHECK(t, outward(&m));
    /* vertex 0 touches three right-triangle faces of equal area */
    const float k = (float)(1 / sqrt(3.0));
    CHECK(t, fabsf(m.normals[0] + k) < 1e-6f && fabsf(m.normals[1] + k) < 1e-6f);
    mts_mesh_free(&m);
    CHECK(t, m.positions == NULL && m.vertex_count == 0);
}

static void test_off_cube_quads(mts_test *t)
{
    buf b = {0};
    cube_off(&b);
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = load_bytes("cube.off", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK)
        check_cube(t, &m, &st);
    mts_mesh_free(&m);
    buf_free(&b);
}

static void test_off_variants(mts_test *t)
{
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    /* NOFF: normals after the position, not unit length in the file */
    const char *noff = "NOFF\n4 4 0\n"
                       "0 0 0  -2 -2 -2\n"
                       "1 0 0  3 0 0\n"
                       "0 1 0  0 0.5 0\n"
                       "0 0 1  0 0 7\n"
                       "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    mts_result r = load_text("tet.noff.off", noff, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        CHECK(t, st.normals_from_file == 1);
        CHECK(t, all_unit(&m));
        CHECK(t, m.normals[3] == 1 && m.normals[4] == 0 && m.normals[5] == 0);
        CHECK(t, m.normals[7] == 1 && m.normals[11] == 1);
    }
    mts_mesh_free(&m);

    /* COFF: colours on vertex and face lines are ignored */
    const char *coff = "COFF\n4 4 0\n"
                       "0 0 0 255 0 0 255\n"
                       "1 0 0 0 255 0 255\n"
                       "0 1 0 0 0 255 255\n"
                       "0 0 1 1 1 1 1\n"
                       "3 0 2 1 0.1 0.2 0.3\n3 0 1 3 1 1 1\n3 0 3 2\n3 1 2 3 9 9 9 9\n";
    r = load_text("tet_c.off", coff, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        CHECK(t, st.normals_from_file == 0);
        CHECK(t, memcmp(m.positions, tet_pos, sizeof tet_pos) == 0);
        CHECK(t, memcmp(m.triangles, tet_tri, sizeof tet_tri) == 0);
    }
    mts_mesh_free(&m);

    /* the ModelNet header with the count glued to the keyword, no edge count,
     * everything on few lines */
    const char *glued = "OFF4 4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                        "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3";
    r = load_text("glued.off", glued, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, m.triangle_count == 4);
    mts_mesh_free(&m);

    r = load_text("four.off", "4OFF\n1 0 0\n0 0 0 0\n", &m, &st, &err);
    CHECK(t, r == MTS_ERR_VERSION);
    CHECK(t, strstr(err.msg, "four.off") != NULL);
}

/* ------------------------------------------------------------------------ */
/* Binary OFF                                                               */

static void put_u32(buf *b, uint32_t u, int big)
{
    unsigned char c[4];
    for (int i = 0; i < 4; i++)
        c[i] = (unsigned char)(big ? u >> (24 - 8 * i) : u >> (8 * i));
    buf_put(b, c, 4);
}

static void put_f32(buf *b, float f, int big)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    put_u32(b, u, big);
}

enum { OFFB_NORMALS = 1, OFFB_COLORS = 2, OFFB_ST = 4 };

/* The tetrahedron as binary OFF. big = 0 is OpenMesh's layout (little
 * endian, nothing after a face's indices unless C: then 3 int colour words
 * per vertex and per face); big = 1 is Geomview's (big endian, a colour count
 * after every face's indices, face 2 with an RGBA colour; C: 4 floats per
 * vertex). Normals point away from the centroid, not unit length. */
static void tet_off_binary(buf *b, int big, int flags)
{
    buf_printf(b, "%s%s%sOFF BINARY\n", flags & OFFB_ST ? "ST" : "", flags & OFFB_COLORS ? "C" : "",
               flags & OFFB_NORMALS ? "N" : "");
    put_u32(b, 4, big);
    put_u32(b, 4, big);
    put_u32(b, 6, big);
    for (int v = 0; v < 4; v++) {
        for (int k = 0; k < 3; k++)
            put_f32(b, tet_pos[v][k], big);
        if (flags & OFFB_NORMALS)
            for (int k = 0; k < 3; k++)
                put_f32(b, 2 * (tet_pos[v][k] - 0.25f), big);
        if ((flags & OFFB_COLORS) && big)
            for (int k = 0; k < 4; k++)
                put_f32(b, 0.5f, big);
        else if (flags & OFFB_COLORS)
            for (int k = 0; k < 3; k++)
                put_u32(b, 200, big);
        if (flags & OFFB_ST)
            for (int k = 0; k < 2; k++)
                put_f32(b, 0.25f * k, big);
    }
    for (int f = 0; f < 4; f++) {
        put_u32(b, 3, big);
        for (int k = 0; k < 3; k++)
            put_u32(b, tet_tri[f][k], big);
        if (big) {
            put_u32(b, f == 2 ? 4 : 0, big);
            for (int k = 0; k < (f == 2 ? 4 : 0); k++)
                put_f32(b, 0.75f, big);
        } else if (flags & OFFB_COLORS) {
            for (int k = 0; k < 3; k++)
                put_u32(b, 100, big);
        }
    }
}

static void check_tet(mts_test *t, const mts_mesh *m, const mts_mesh_stats *st, const char *what)
{
    CHECKF(t, st->format == MTS_MESH_OFF, "%s", what);
    CHECKF(t, m->vertex_count == 4 && m->triangle_count == 4, "%s: %u %u", what, m->vertex_count,
           m->triangle_count);
    CHECKF(t, st->file_vertices == 4 && st->file_faces == 4, "%s", what);
    if (m->vertex_count != 4 || m->triangle_count != 4)
        return;
    CHECKF(t, memcmp(m->positions, tet_pos, sizeof tet_pos) == 0, "%s", what);
    CHECKF(t, memcmp(m->triangles, tet_tri, sizeof tet_tri) == 0, "%s", what);
    CHECKF(t, outward(m), "%s", what);
}

static void test_off_binary(mts_test *t)
{
    static const struct {
        const char *name;
        int big, flags;
    } cases[] = {{"le.off", 0, 0},         {"be.off", 1, 0},
                 {"le_n.off", 0, OFFB_NORMALS}, {"be_n.off", 1, OFFB_NORMALS},
                 {"le_c.off", 0, OFFB_COLORS},  {"be_c.off", 1, OFFB_COLORS},
                 {"le_stcn.off", 0, OFFB_ST | OFFB_COLORS | OFFB_NORMALS},
                 {"be_stcn.off", 1, OFFB_ST | OFFB_COLORS | OFFB_NORMALS},
                 {"tet", 0, 0} /* by content */, {"tet", 1, 0}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        buf b = {0};
        tet_off_binary(&b, cases[i].big, cases[i].flags);
        mts_mesh m;
        mts_mesh_stats st;
        mts_error err = {0};
        char what[64];
        snprintf(what, sizeof what, "%s %s", cases[i].name, cases[i].big ? "BE" : "LE");
        mts_result r = load_bytes(cases[i].name, b.d, b.n, &m, &st, &err);
        CHECKF(t, r == MTS_OK, "%s: %s", what, err.msg);
        if (r == MTS_OK) {
            check_tet(t, &m, &st, what);
            int normals = (cases[i].flags & OFFB_NORMALS) != 0;
            CHECKF(t, st.normals_from_file == normals, "%s", what);
            /* vertex 1's file normal (1.5, -0.5, -0.5), made unit length */
            if (normals)
                CHECKF(t, fabsf(m.normals[3] * m.normals[3] - 9.0f / 11) < 1e-6f && m.normals[4] < 0,
                       "%s: %g", what, m.normals[3]);
        }
        mts_mesh_free(&m);
        buf_free(&b);
    }

    /* quads, and a comment after BINARY */
    buf b = {0};
    buf_printf(&b, "OFF BINARY # from a test\r\n");
    put_u32(&b, 8, 0);
    put_u32(&b, 6, 0);
    put_u32(&b, 12, 0);
    for (int v = 0; v < 8; v++)
        for (int k = 0; k < 3; k++)
            put_f32(&b, (float)(v >> k & 1), 0);
    for (int f = 0; f < 6; f++) {
        put_u32(&b, 4, 0);
        for (int k = 0; k < 4; k++)
            put_u32(&b, cube_quad[f][k], 0);
    }
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = load_bytes("cube.off", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK)
        check_cube(t, &m, &st);
    mts_mesh_free(&m);
    /* a trailing newline is fine */
    buf_put(&b, "\n", 1);
    r = load_bytes("cube.off", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK && m.triangle_count == 12, "%s", err.msg);
    mts_mesh_free(&m);
    buf_free(&b);
}

/* The path of an executable on $PATH, or NULL. */
static const char *find_program(const char *prog, char *out, size_t size)
{
    const char *path = getenv("PATH");
    if (!path || !*path)
        path = "/usr/bin:/bin";
    while (*path) {
        const char *colon = strchr(path, ':');
        size_t n = colon ? (size_t)(colon - path) : strlen(path);
        snprintf(out, size, "%.*s/%s", (int)n, n ? path : ".", prog);
        if (access(out, X_OK) == 0)
            return out;
        path += n + (colon != NULL);
    }
    return NULL;
}

/* OpenMesh's own binary OFF: the cow, Loop-subdivided once by
 * OpenMesh-commandlineSubdivider, loads with V + E vertices and 4F
 * triangles, the same mesh as the subdivider's ASCII OBJ output. */
static void test_off_binary_openmesh(mts_test *t)
{
    char prog[1024];
    if (!find_program("OpenMesh-commandlineSubdivider", prog, sizeof prog))
        SKIP(t, "OpenMesh-commandlineSubdivider is not installed (Debian: libopenmesh-apps)");
    mts_mesh cow, off, obj;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = mts_mesh_load("tests/data/cow.off", NULL, &cow, NULL, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return;
    /* the edges of the closed cow: every undirected edge once */
    uint64_t edges = 0;
    for (uint32_t f = 0; f < cow.triangle_count; f++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = cow.triangles[f * 3 + k], b = cow.triangles[f * 3 + (k + 1) % 3];
            edges += a < b; /* closed and consistently oriented: each edge is a<b once */
        }
    const uint64_t want_v = cow.vertex_count + edges, want_t = 4 * (uint64_t)cow.triangle_count;
    CHECK(t, cow.vertex_count - edges + cow.triangle_count == 2); /* a sphere */
    mts_mesh_free(&cow);

    char off_path[512], obj_path[512], cmd[3 * 1024];
    snprintf(off_path, sizeof off_path, "%s/mts_test_mesh_cow_loop1.off", mts_test_tmpdir());
    snprintf(obj_path, sizeof obj_path, "%s/mts_test_mesh_cow_loop1.obj", mts_test_tmpdir());
    for (int i = 0; i < 2; i++) {
        snprintf(cmd, sizeof cmd, "'%s' -l 1 tests/data/cow.off '%s' >/dev/null 2>&1", prog,
                 i ? obj_path : off_path);
        int rc = system(cmd);
        CHECKF(t, rc == 0, "%s: exit %d", cmd, rc);
        if (rc != 0)
            return;
    }
    FILE *f = fopen(off_path, "rb");
    char head[16] = {0};
    CHECK(t, f && fread(head, 1, 11, f) == 11 && memcmp(head, "OFF BINARY\n", 11) == 0);
    if (f)
        fclose(f);

    r = mts_mesh_load(off_path, NULL, &off, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    mts_result r2 = mts_mesh_load(obj_path, NULL, &obj, NULL, &err);
    CHECKF(t, r2 == MTS_OK, "%s", err.msg);
    if (r == MTS_OK && r2 == MTS_OK) {
        CHECKF(t, st.file_vertices == want_v && st.file_faces == want_t, "%u %u, want %llu %llu",
               st.file_vertices, st.file_faces, (unsigned long long)want_v,
               (unsigned long long)want_t);
        CHECKF(t, off.vertex_count == want_v && off.triangle_count == want_t, "%u %u",
               off.vertex_count, off.triangle_count);
        CHECK(t, st.degenerate_faces == 0 && st.nonmanifold_faces == 0);
        CHECK(t, all_unit(&off));
        CHECK(t, off.vertex_count == obj.vertex_count && off.triangle_count == obj.triangle_count);
        if (off.vertex_count == obj.vertex_count && off.triangle_count == obj.triangle_count) {
            CHECK(t, memcmp(off.triangles, obj.triangles,
                            (size_t)off.triangle_count * 3 * sizeof *off.triangles) == 0);
            /* the OBJ has 6 decimals */
            double worst = 0;
            for (size_t i = 0; i < (size_t)off.vertex_count * 3; i++) {
                double d = fabs((double)off.positions[i] - obj.positions[i]);
                worst = d > worst ? d : worst;
            }
            CHECKF(t, worst <= 5.1e-7, "%g", worst);
        }
    }
    if (r == MTS_OK)
        mts_mesh_free(&off);
    if (r2 == MTS_OK)
        mts_mesh_free(&obj);
    remove(off_path);
    remove(obj_path);
}

/* ------------------------------------------------------------------------ */
/* OBJ                                                                      */

static void test_obj_cube(mts_test *t)
{
    /* v/vt/vn corners with negative indices, and lines that do not matter */
    buf b = {0};
    buf_printf(&b, "# cube\nmtllib cube.mtl\no cube\n");
    for (int v = 0; v < 8; v++)
        buf_printf(&b, "v %d %d %d\n", v & 1, v >> 1 & 1, v >> 2 & 1);
    buf_printf(&b, "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n");
    static const int fn[6][3] = {{0, 0, -1}, {0, 0, 1}, {0, -1, 0},
                                 {0, 1, 0},  {-1, 0, 0}, {1, 0, 0}};
    for (int f = 0; f < 6; f++)
        buf_printf(&b, "vn %d %d %d\n", fn[f][0], fn[f][1], fn[f][2]);
    buf_printf(&b, "g all\nusemtl red\ns off\n");
    for (int f = 0; f < 6; f++) {
        buf_printf(&b, "f");
        for (int k = 0; k < 4; k++) {
            int v = (int)cube_quad[f][k];
            if (f % 2) /* negative: counted back from the 8th vertex, 6th normal */
                buf_printf(&b, " %d/%d/%d", v - 8, k - 4, f - 6);
            else if (f == 2)
                buf_printf(&b, " %d//%d", v + 1, f + 1);
            else
                buf_printf(&b, " %d/%d/%d", v + 1, k + 1, f + 1);
        }
        buf_printf(&b, "\n");
    }
    buf_printf(&b, "l 1 2\n");
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = load_bytes("cube.obj", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        CHECK(t, st.format == MTS_MESH_OBJ);
        check_cube(t, &m, &st);
        /* every corner names a normal: the file's, averaged per vertex */
        CHECK(t, st.normals_from_file == 1);
        const float k = (float)(1 / sqrt(3.0));
        CHECK(t, fabsf(m.normals[21] - k) < 1e-6f && fabsf(m.normals[23] - k) < 1e-6f);
    }
    mts_mesh_free(&m);
    buf_free(&b);
}

static void test_obj_normals_partial(mts_test *t)
{
    /* one corner without a normal: the file's normals are not used */
    const char *text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 5\n"
                       "f 1//1 3//1 2//1\nf 1//1 2//1 4//1\nf 1//1 4//1 3//1\nf 2 3 4\n";
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = load_text("partial.obj", text, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        CHECK(t, st.normals_from_file == 0);
        CHECK(t, memcmp(m.triangles, tet_tri, sizeof tet_tri) == 0);
        CHECK(t, outward(&m));
    }
    mts_mesh_free(&m);
    /* negative indices count back from the vertices defined so far */
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -1 -2\nv 0 0 1\nf -4 -3 -1\nf 1 4 3\nf -3 -2 -1\n";
    r = load_text("neg.obj", text, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK)
        CHECK(t, memcmp(m.triangles, tet_tri, sizeof tet_tri) == 0);
    mts_mesh_free(&m);
}

/* ------------------------------------------------------------------------ */
/* PLY                                                                      */

enum { T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 };
static const char *const type_name[] = {"char", "uchar", "short", "ushort",
                                        "int",  "uint",  "float", "double"};

/* One value in ASCII (fmt 0), little (1) or big (2) endian binary. */
static void put_value(buf *b, int fmt, int type, double v)
{
    if (fmt == 0) {
        buf_printf(b, "%.9g ", v);
        return;
    }
    unsigned char raw[8];
    size_t n;
    uint64_t u;
    switch (type) {
    case T_I8: u = (uint8_t)(int8_t)v; n = 1; break;
    case T_U8: u = (uint8_t)v; n = 1; break;
    case T_I16: u = (uint16_t)(int16_t)v; n = 2; break;
    case T_U16: u = (uint16_t)v; n = 2; break;
    case T_I32: u = (uint32_t)(int32_t)v; n = 4; break;
    case T_U32: u = (uint32_t)v; n = 4; break;
    case T_F32: {
        float f = (float)v;
        uint32_t w;
        memcpy(&w, &f, 4);
        u = w;
        n = 4;
        break;
    }
    default: memcpy(&u, &v, 8); n = 8; break;
    }
    for (size_t i = 0; i < n; i++)
        raw[fmt == 1 ? i : n - 1 - i] = (unsigned char)(u >> (8 * i));
    buf_put(b, raw, n);
}

static void put_end(buf *b, int fmt)
{
    if (fmt == 0)
        buf_printf(b, "\n");
}

static const char *const ply_format[] = {"ascii", "binary_little_endian", "binary_big_endian"};

/* The cube with properties and elements the loader must skip, including
 * lists in the vertex element and elements before and after the faces. */
static void cube_ply(buf *b, int fmt)
{
    buf_printf(b, "ply\nformat %s 1.0\ncomment test cube\nobj_info nothing\n", ply_format[fmt]);
    buf_printf(b, "element vertex 8\nproperty float confidence\nproperty double x\n"
                  "property float y\nproperty int z\nproperty uchar red\n"
                  "property list uchar int extra\n");
    buf_printf(b, "element edge 2\nproperty int vertex1\nproperty int vertex2\n");
    buf_printf(b, "element face 6\nproperty uchar flags\nproperty list ushort short vertex_index\n"
                  "property list uchar float texcoord\n");
    buf_printf(b, "element material 1\nproperty list uint uchar name\nend_header\n");
    for (int v = 0; v < 8; v++) {
        put_value(b, fmt, T_F32, 0.5);
        put_value(b, fmt, T_F64, v & 1);
        put_value(b, fmt, T_F32, v >> 1 & 1);
        put_value(b, fmt, T_I32, v >> 2 & 1);
        put_value(b, fmt, T_U8, 255);
        put_value(b, fmt, T_U8, 2);
        put_value(b, fmt, T_I32, 7);
        put_value(b, fmt, T_I32, -8);
        put_end(b, fmt);
    }
    for (int e = 0; e < 2; e++) {
        put_value(b, fmt, T_I32, 0);
        put_value(b, fmt, T_I32, 1);
        put_end(b, fmt);
    }
    for (int f = 0; f < 6; f++) {
        put_value(b, fmt, T_U8, 1);
        put_value(b, fmt, T_U16, 4);
        for (int k = 0; k < 4; k++)
            put_value(b, fmt, T_I16, cube_quad[f][k]);
        put_value(b, fmt, T_U8, 2);
        put_value(b, fmt, T_F32, 0.25);
        put_value(b, fmt, T_F32, 0.75);
        put_end(b, fmt);
    }
    put_value(b, fmt, T_U32, 3);
    for (int c = 0; c < 3; c++)
        put_value(b, fmt, T_U8, 'A' + c);
    put_end(b, fmt);
}

/* The tetrahedron with (unnormalised) normals and given vertex/index types. */
static void tet_ply(buf *b, int fmt, int pos_type, int count_type, int index_type)
{
    buf_printf(b, "ply\r\nformat %s 1.0\r\nelement vertex 4\r\n", ply_format[fmt]);
    const char *names[] = {"x", "y", "z", "nx", "ny", "nz"};
    for (int c = 0; c < 6; c++)
        buf_printf(b, "property %s %s\r\n", type_name[c < 3 ? pos_type : T_F32], names[c]);
    buf_printf(b, "element face 4\r\nproperty list %s %s vertex_indices\r\nend_header\r\n",
               type_name[count_type], type_name[index_type]);
    static const float normal[4][3] = {{-1, -1, -1}, {2, 0, 0}, {0, 3, 0}, {0, 0, 0.5f}};
    for (int v = 0; v < 4; v++) {
        for (int c = 0; c < 3; c++)
            put_value(b, fmt, pos_type, tet_pos[v][c]);
        for (int c = 0; c < 3; c++)
            put_value(b, fmt, T_F32, normal[v][c]);
        put_end(b, fmt);
    }
    for (int f = 0; f < 4; f++) {
        put_value(b, fmt, count_type, 3);
        for (int c = 0; c < 3; c++)
            put_value(b, fmt, index_type, tet_tri[f][c]);
        put_end(b, fmt);
    }
}

static void test_ply_cube(mts_test *t)
{
    for (int fmt = 0; fmt < 3; fmt++) {
        buf b = {0};
        cube_ply(&b, fmt);
        mts_mesh m;
        mts_mesh_stats st;
        mts_error err = {0};
        mts_result r = load_bytes("cube.ply", b.d, b.n, &m, &st, &err);
        CHECKF(t, r == MTS_OK, "%s: %s", ply_format[fmt], err.msg);
        if (r == MTS_OK) {
            CHECK(t, st.format == MTS_MESH_PLY);
            CHECK(t, st.normals_from_file == 0);
            check_cube(t, &m, &st);
        }
        mts_mesh_free(&m);
        buf_free(&b);
    }
}

static void test_ply_tet_types(mts_test *t)
{
    static const int combos[][3] = {{T_F32, T_U8, T_I32},  {T_F64, T_U16, T_U32},
                                    {T_I8, T_I32, T_U8},   {T_I16, T_U32, T_I16},
                                    {T_U8, T_I8, T_U16},   {T_I32, T_U8, T_F32}};
    for (int fmt = 0; fmt < 3; fmt++)
        for (size_t c = 0; c < sizeof combos / sizeof combos[0]; c++) {
            buf b = {0};
            tet_ply(&b, fmt, combos[c][0], combos[c][1], combos[c][2]);
            mts_mesh m;
            mts_mesh_stats st;
            mts_error err = {0};
            mts_result r = load_bytes("tet.ply", b.d, b.n, &m, &st, &err);
            CHECKF(t, r == MTS_OK, "%s combo %zu: %s", ply_format[fmt], c, err.msg);
            if (r == MTS_OK) {
                CHECK(t, m.vertex_count == 4 && m.triangle_count == 4);
                CHECK(t, memcmp(m.positions, tet_pos, sizeof tet_pos) == 0);
                CHECK(t, memcmp(m.triangles, tet_tri, sizeof tet_tri) == 0);
                CHECK(t, st.normals_from_file == 1);
                CHECK(t, all_unit(&m));
                CHECK(t, m.normals[3] == 1 && m.normals[7] == 1 && m.normals[11] == 1);
            }
            mts_mesh_free(&m);
            buf_free(&b);
        }
}

/* ------------------------------------------------------------------------ */
/* STL                                                                      */

static void tet_stl_ascii(buf *b)
{
    buf_printf(b, "solid tet\n");
    for (int f = 0; f < 4; f++) {
        buf_printf(b, "  facet normal 0 0 0\n    outer loop\n");
        for (int c = 0; c < 3; c++) {
            const float *p = tet_pos[tet_tri[f][c]];
            /* -0 must weld with 0 */
            buf_printf(b, "      vertex %s %g %g\n", p[0] == 0 && f == 3 ? "-0" : p[0] ? "1" : "0",
                       p[1], p[2]);
        }
        buf_printf(b, "    endloop\n  endfacet\n");
    }
    buf_printf(b, "endsolid tet\n");
}

static void tet_stl_binary(buf *b, const char *header)
{
    char head[80];
    memset(head, ' ', sizeof head);
    memcpy(head, header, strlen(header));
    buf_put(b, head, 80);
    unsigned char count[4] = {4, 0, 0, 0};
    buf_put(b, count, 4);
    for (int f = 0; f < 4; f++) {
        for (int c = 0; c < 3; c++)
            put_value(b, 1, T_F32, 0); /* the facet normal, which is ignored */
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++)
                put_value(b, 1, T_F32, tet_pos[tet_tri[f][c]][k]);
        put_value(b, 1, T_U16, 0);
    }
}

/* Welding renumbers in order of first appearance: corners of the facets
 * (0 2 1) (0 1 3) ... meet the vertices as 0, 2, 1, 3. */
static void check_stl_tet(mts_test *t, const mts_mesh *m, const mts_mesh_stats *st)
{
    CHECK(t, st->format == MTS_MESH_STL);
    CHECK(t, m->vertex_count == 4 && m->triangle_count == 4);
    CHECK(t, st->file_vertices == 12 && st->file_faces == 4);
    CHECK(t, st->welded_vertices == 8);
    CHECK(t, st->normals_from_file == 0);
    if (m->vertex_count != 4 || m->triangle_count != 4)
        return;
    for (int f = 0; f < 4; f++)
        for (int c = 0; c < 3; c++)
            CHECK(t, memcmp(m->positions + m->triangles[f * 3 + c] * 3, tet_pos[tet_tri[f][c]],
                            3 * sizeof(float)) == 0 ||
                         (tet_pos[tet_tri[f][c]][0] == 0 &&
                          m->positions[m->triangles[f * 3 + c] * 3] == 0));
    CHECK(t, tri_equal(m->triangles, 0, 1, 2));
    CHECK(t, outward(m));
}

static void test_stl(mts_test *t)
{
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    buf b = {0};
    tet_stl_ascii(&b);
    mts_result r = load_bytes("tet.stl", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK)
        check_stl_tet(t, &m, &st);
    mts_mesh_free(&m);
    buf_free(&b);

    /* binary, with a header that starts like an ASCII file */
    tet_stl_binary(&b, "solid but binary");
    r = load_bytes("tet.STL", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK)
        check_stl_tet(t, &m, &st);
    mts_mesh_free(&m);
    /* and recognised by content alone */
    r = load_bytes("tet.bin", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, st.format == MTS_MESH_STL);
    mts_mesh_free(&m);
    buf_free(&b);
}

/* ------------------------------------------------------------------------ */
/* Cleaning                                                                 */

static void test_cleaning(mts_test *t)
{
    /* the tetrahedron on vertices 0 1 3 4 (2 is unused, 5 and 6 are only used
     * by dropped faces), plus faces to drop: a repeated index, a zero-area
     * sliver, a rotated copy, a 2-gon, and a third face on edge 0-1 */
    const char *text = "OFF\n7 10 0\n"
                       "0 0 0\n1 0 0\n5 5 5\n0 1 0\n0 0 1\n2 0 0\n0 0 -1\n"
                       "3 0 3 1\n"
                       "3 0 1 0\n"     /* repeated index */
                       "3 0 1 5\n"     /* collinear: zero area */
                       "3 0 1 4\n"
                       "3 3 1 0\n"     /* rotation of the first: duplicate */
                       "3 0 4 3\n"
                       "2 0 1\n"       /* a 2-gon: degenerate */
                       "3 1 3 4\n"
                       "3 0 1 6\n"     /* third face on edge 0->1, refused */
                       "3 0 3 1\n";    /* exact copy: duplicate */
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = load_text("clean.off", text, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return;
    CHECK(t, st.file_vertices == 7 && st.file_faces == 10);
    CHECKF(t, st.degenerate_faces == 3, "%u", st.degenerate_faces);
    CHECKF(t, st.duplicate_faces == 2, "%u", st.duplicate_faces);
    CHECKF(t, st.nonmanifold_faces == 1, "%u", st.nonmanifold_faces);
    CHECKF(t, st.unreferenced_vertices == 3, "%u", st.unreferenced_vertices);
    CHECK(t, m.vertex_count == 4 && m.triangle_count == 4);
    if (m.vertex_count == 4 && m.triangle_count == 4) {
        /* renumbered in file order: 0 1 3 4 -> 0 1 2 3 */
        CHECK(t, memcmp(m.positions, tet_pos, sizeof tet_pos) == 0);
        CHECK(t, tri_equal(m.triangles, 0, 2, 1) && tri_equal(m.triangles + 3, 0, 1, 3));
        CHECK(t, tri_equal(m.triangles + 6, 0, 3, 2) && tri_equal(m.triangles + 9, 1, 2, 3));
        CHECK(t, outward(&m));
    }
    mts_mesh_free(&m);

    /* three triangles on one edge: OpenMesh refuses the one that reuses 0->1 */
    text = "OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n3 0 1 2\n3 1 0 3\n3 0 1 4\n";
    r = load_text("fin.off", text, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, st.nonmanifold_faces == 1 && m.triangle_count == 2);
    CHECK(t, st.unreferenced_vertices == 1 && m.vertex_count == 4);
    mts_mesh_free(&m);

    /* a face and its reverse are two faces, not duplicates (a closed pillow) */
    text = "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 2 1 0\n";
    r = load_text("pillow.off", text, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, st.duplicate_faces == 0 && st.nonmanifold_faces == 0 && m.triangle_count == 2);
    mts_mesh_free(&m);
}

static void test_compute_normals(mts_test *t)
{
    /* a vertex of zero-area faces only keeps a zero normal */
    float pos[] = {0, 0, 0, 2, 0, 0, 0, 2, 0, 1, 0, 0};
    uint32_t tri[] = {0, 1, 2, 0, 1, 3};
    mts_mesh m = {4, 2, pos, NULL, tri, NULL, 0};
    mts_mesh_compute_normals(&m);
    CHECK(t, m.normals != NULL);
    if (!m.normals)
        return;
    for (int v = 0; v < 3; v++)
        CHECK(t, m.normals[v * 3] == 0 && m.normals[v * 3 + 1] == 0 && m.normals[v * 3 + 2] == 1);
    CHECK(t, m.normals[9] == 0 && m.normals[10] == 0 && m.normals[11] == 0);
    free(m.normals);
}

/* ------------------------------------------------------------------------ */
/* Errors                                                                   */

/* Loads text as NAME and checks the code and that the message names the
 * file and contains `want` (when not NULL). */
static void expect_error(mts_test *t, const char *name, const void *data, size_t size,
                         mts_result code, const char *want)
{
    char path[512];
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    if (!write_file(name, data, size, path, sizeof path)) {
        CHECKF(t, 0, "could not write %s", name);
        return;
    }
    mts_result r = mts_mesh_load(path, NULL, &m, &st, &err);
    remove(path);
    CHECKF(t, r == code, "%s: got %s, want %s: %s", name, mts_result_name(r),
           mts_result_name(code), err.msg);
    CHECKF(t, r == MTS_OK || strstr(err.msg, path) != NULL, "%s: '%s'", name, err.msg);
    CHECKF(t, !want || strstr(err.msg, want) != NULL, "%s: '%s' lacks '%s'", name, err.msg, want);
    CHECK(t, m.positions == NULL && m.triangles == NULL && m.normals == NULL);
    mts_mesh_free(&m);
}

static void expect_text_error(mts_test *t, const char *name, const char *text, mts_result code,
                              const char *want)
{
    expect_error(t, name, text, strlen(text), code, want);
}

static void test_error_files(mts_test *t)
{
    char path[512];
    snprintf(path, sizeof path, "%s/mts_test_mesh_no_such_file.off", mts_test_tmpdir());
    remove(path);
    mts_mesh m;
    mts_error err = {0};
    mts_result r = mts_mesh_load(path, NULL, &m, NULL, &err);
    CHECK(t, r == MTS_ERR_IO && err.code == MTS_ERR_IO);
    CHECK(t, strstr(err.msg, path) != NULL && strstr(err.msg, "No such file") != NULL);
    r = mts_mesh_load(mts_test_tmpdir(), NULL, &m, NULL, &err);
    CHECK(t, r == MTS_ERR_IO);

    expect_error(t, "empty.off", "", 0, MTS_ERR_FORMAT, "empty");
    expect_error(t, "empty.unknown", "", 0, MTS_ERR_FORMAT, "empty");
    expect_text_error(t, "garbage.xyz", "hello world\nthis is not a mesh\n", MTS_ERR_FORMAT,
                      "unknown mesh format");
    unsigned char noise[300];
    uint32_t s = 12345;
    for (size_t i = 0; i < sizeof noise; i++) {
        s = s * 1103515245 + 12345;
        noise[i] = (unsigned char)(s >> 16);
    }
    noise[81] = noise[82] = noise[83] = 0; /* as binary STL: a few facets, not the size */
    expect_error(t, "noise", noise, sizeof noise, MTS_ERR_FORMAT, "unknown mesh format");
    expect_error(t, "noise.off", noise, sizeof noise, MTS_ERR_FORMAT, "not an OFF file");
    expect_error(t, "noise.ply", noise, sizeof noise, MTS_ERR_FORMAT, "not a PLY file");
    expect_error(t, "noise.stl", noise, sizeof noise, MTS_ERR_FORMAT, "truncated");
    expect_text_error(t, "text.obj", "this is\nnot an obj\n", MTS_ERR_FORMAT, "no triangles");

    mts_mesh_options bad = {.format = (mts_mesh_format)42};
    r = mts_mesh_load_memory("x.off", "OFF", 3, &bad, &m, NULL, &err);
    CHECK(t, r == MTS_ERR_ARG);
    r = mts_mesh_load_memory("x.off", "OFF", 3, NULL, NULL, NULL, NULL);
    CHECK(t, r == MTS_ERR_ARG);
}

static void test_error_truncated(mts_test *t)
{
    /* cow.off cut after its 17th vertex line */
    FILE *f = fopen("tests/data/cow.off", "rb");
    if (f) {
        char line[256];
        buf b = {0};
        for (int i = 0; i < 3 + 17 && fgets(line, sizeof line, f); i++)
            buf_printf(&b, "%s", line);
        fclose(f);
        expect_error(t, "cow.off", b.d, b.n, MTS_ERR_FORMAT,
                     "cow.off: truncated: expected 2904 vertices, file ends after 17");
        buf_free(&b);
    } else {
        CHECKF(t, 0, "tests/data/cow.off not found (run from the project root)");
    }
    expect_text_error(t, "faces.off", "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1",
                      MTS_ERR_FORMAT, "truncated: expected 4 faces, file ends after 1");
    expect_text_error(t, "header.off", "OFF\n4", MTS_ERR_FORMAT, "truncated");
    expect_text_error(t, "short.off", "OFF\n1 1 0\n0 0\n3 0 0 0\n", MTS_ERR_FORMAT,
                      "line 3: vertex 0 has 2 values, expected 3");
    expect_text_error(t, "short.obj", "v 0 0 0\nv 1 0 0\nv 0 1", MTS_ERR_FORMAT,
                      "truncated at line 3");

    buf b = {0};
    tet_stl_ascii(&b);
    expect_error(t, "cut.stl", b.d, b.n - 20, MTS_ERR_FORMAT, "truncated");
    expect_error(t, "noend.stl", b.d, b.n - strlen("endsolid tet\n"), MTS_ERR_FORMAT,
                 "no 'endsolid'");
    buf_free(&b);
    tet_stl_binary(&b, "binary");
    expect_error(t, "cut_bin.stl", b.d, b.n - 1, MTS_ERR_FORMAT, "truncated: expected 4 facets");
    buf_free(&b);

    for (int fmt = 0; fmt < 3; fmt++) {
        tet_ply(&b, fmt, T_F32, T_U8, T_I32);
        size_t cut = fmt == 0 ? b.n - 8 : b.n - 13 * 3; /* inside face 1 */
        expect_error(t, "cut.ply", b.d, cut, MTS_ERR_FORMAT, "truncated: expected 4 faces");
        size_t header = 0;
        while (header + 12 <= b.n && memcmp(b.d + header, "end_header\r\n", 12) != 0)
            header++;
        header += 12;
        expect_error(t, "cut_v.ply", b.d, header + 10, MTS_ERR_FORMAT,
                     "truncated: expected 4 vertices, file ends after 0");
        buf_free(&b);
    }
    expect_text_error(t, "nohead.ply", "ply\nformat ascii 1.0\nelement vertex 1\n", MTS_ERR_FORMAT,
                      "end_header");
}

static void test_error_huge_counts(mts_test *t)
{
    expect_text_error(t, "huge.off", "OFF\n4000000000 1 0\n0 0 0\n", MTS_ERR_LIMIT, "4000000000");
    expect_text_error(t, "big.off", "OFF\n2000000000 2000000000 0\n0 0 0\n", MTS_ERR_FORMAT,
                      "truncated: expected 2000000000 vertices, file ends after 1");
    expect_text_error(t, "bigf.off", "OFF\n3 2000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                      MTS_ERR_FORMAT, "truncated: expected 2000000000 faces, file ends after 1");
    expect_text_error(t, "bigpoly.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2000000000 0 1 2\n",
                      MTS_ERR_FORMAT, "face 0 has 3 indices, expected 2000000000");
    expect_text_error(t, "neg.off", "OFF\n-3 1 0\n", MTS_ERR_FORMAT, "negative");
    expect_text_error(t, "huge.ply",
                      "ply\nformat binary_little_endian 1.0\nelement vertex 4294967295\n"
                      "property float x\nproperty float y\nproperty float z\nend_header\n",
                      MTS_ERR_LIMIT, "4294967295");
    expect_text_error(t, "big.ply",
                      "ply\nformat binary_big_endian 1.0\nelement vertex 2000000000\n"
                      "property float x\nproperty float y\nproperty float z\n"
                      "element face 2000000000\nproperty list uint uint vertex_indices\n"
                      "end_header\n0123456789ab",
                      MTS_ERR_FORMAT, "truncated: expected 2000000000 vertices, file ends after 1");
    /* a list claiming 4 billion items in a short file */
    buf b = {0};
    buf_printf(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                   "property float y\nproperty float z\nelement face 1\n"
                   "property list uint int vertex_indices\nend_header\n");
    for (int i = 0; i < 9; i++)
        put_value(&b, 1, T_F32, i % 4 == 0);
    put_value(&b, 1, T_U32, 4294967295.0);
    put_value(&b, 1, T_I32, 0);
    expect_error(t, "biglist.ply", b.d, b.n, MTS_ERR_FORMAT, "face 0");
    buf_free(&b);
    /* binary STL counts */
    unsigned char stl[84 + 50];
    memset(stl, 0, sizeof stl);
    memset(stl + 80, 0xff, 4);
    expect_error(t, "huge.stl", stl, sizeof stl, MTS_ERR_LIMIT, "4294967295");
    stl[80] = 0x40, stl[81] = 0x42, stl[82] = 0x0f, stl[83] = 0; /* 1,000,000 */
    expect_error(t, "big.stl", stl, sizeof stl, MTS_ERR_FORMAT, "truncated: expected 1000000");
    stl[80] = 1, stl[81] = stl[82] = stl[83] = 0;
    memset(stl + 84 + 12, 0xff, 4); /* a NaN corner */
    expect_error(t, "nan.stl", stl, sizeof stl, MTS_ERR_FORMAT, "non-finite");
}

static void test_error_corrupt(mts_test *t)
{
    const char *tet = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
    char text[512];
    snprintf(text, sizeof text, "OFF\n4 2 0\n%s3 0 2 1\n3 0 1 9999\n", tet);
    expect_text_error(t, "range.off", text, MTS_ERR_RANGE,
                      "line 8: face 1: vertex index 9999 out of range");
    snprintf(text, sizeof text, "OFF\n4 1 0\n%s3 0 -1 2\n", tet);
    expect_text_error(t, "minus.off", text, MTS_ERR_RANGE, "index -1 out of range");
    expect_text_error(t, "bad.off", "OFF\n3 1 0\n0 0 0\n1 0.5.0 0\n0 1 0\n3 0 1 2\n",
                      MTS_ERR_FORMAT, "line 4: bad number");
    expect_text_error(t, "nan.off", "OFF\n3 1 0\nnan 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                      MTS_ERR_FORMAT, "line 3: bad number");
    expect_text_error(t, "inf.off", "OFF\n3 1 0\n1e39 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                      MTS_ERR_FORMAT, "out of range");
    expect_text_error(t, "bad_face.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 x\n",
                      MTS_ERR_FORMAT, "line 6: bad number");
    expect_text_error(t, "zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", MTS_ERR_RANGE,
                      "line 4: vertex index 0 out of range");
    expect_text_error(t, "far.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n", MTS_ERR_RANGE,
                      "vertex index 99 out of range");
    expect_text_error(t, "back.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", MTS_ERR_RANGE,
                      "vertex index -4 out of range");
    expect_text_error(t, "vn.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n", MTS_ERR_RANGE,
                      "normal index 1 out of range");
    expect_text_error(t, "slash.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n", MTS_ERR_FORMAT,
                      "line 4: bad number");
    expect_text_error(t, "range.ply",
                      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                      "property float y\nproperty float z\nelement face 1\n"
                      "property list uchar int vertex_indices\nend_header\n"
                      "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
                      MTS_ERR_RANGE, "line 13: face 0: vertex index 3 out of range");
    buf b = {0};
    tet_ply(&b, 2, T_F32, T_U8, T_I32);
    b.d[b.n - 1] = 9; /* the last index of the last face */
    expect_error(t, "range_be.ply", b.d, b.n, MTS_ERR_RANGE, "face 3: vertex index 9 out of range");
    buf_free(&b);
    expect_text_error(t, "noxyz.ply",
                      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
                      MTS_ERR_FORMAT, "x, y, z");
    expect_text_error(t, "version.ply", "ply\nformat ascii 2.0\nend_header\n", MTS_ERR_VERSION,
                      "line 2: the PLY version is not 1.x");
    expect_text_error(t, "bad.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
                                    "vertex 1 0 0\nvertx 0 1 0\nendloop\nendfacet\nendsolid\n",
                      MTS_ERR_FORMAT, "line 6: expected 'vertex'");
    snprintf(text, sizeof text, "OFF\n4 2 0\n%s3 0 1 1\n4 0 1 1 0\n", tet);
    expect_text_error(t, "degenerate.off", text, MTS_ERR_FORMAT, "no triangles");
    expect_text_error(t, "line.off", "OFF\n3 1 0\n0 0 0\n1 1 1\n2 2 2\n3 0 1 2\n", MTS_ERR_FORMAT,
                      "no triangles");
    expect_text_error(t, "points.ply",
                      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                      "property float y\nproperty float z\nend_header\n0 0 0\n",
                      MTS_ERR_FORMAT, "no triangles");
    expect_text_error(t, "empty.stl", "solid x\nendsolid x\n", MTS_ERR_FORMAT, "no triangles");
}

static void test_off_binary_errors(mts_test *t)
{
    /* every prefix of both layouts is an error that names the file and, from
     * the keyword on, says it is truncated */
    for (int big = 0; big < 2; big++) {
        for (int flags = 0; flags < 8; flags += OFFB_NORMALS | OFFB_COLORS) {
            buf b = {0};
            tet_off_binary(&b, big, flags);
            size_t line = (size_t)((unsigned char *)memchr(b.d, '\n', b.n) - b.d);
            for (size_t cut = 1; cut < b.n; cut++) {
                mts_mesh m;
                mts_error err = {0};
                mts_result r = load_bytes("cut.off", b.d, cut, &m, NULL, &err);
                /* "OF" is not an OFF file yet; from "OFF" on it is a cut one */
                CHECKF(t, r == MTS_ERR_FORMAT && strstr(err.msg, "cut.off: ") == err.msg &&
                              (cut < line - 7 || strstr(err.msg, "truncated") != NULL),
                       "%s flags %d cut %zu/%zu: %s: %s", big ? "BE" : "LE", flags, cut, b.n,
                       mts_result_name(r), err.msg);
                mts_mesh_free(&m);
            }
            buf_free(&b);
        }
    }
    buf b = {0};
    tet_off_binary(&b, 0, 0);
    const size_t header = strlen("OFF BINARY\n");
    expect_error(t, "cut_v.off", b.d, header + 12 + 20, MTS_ERR_FORMAT,
                 "truncated: expected 4 vertices, file ends after 1");
    expect_error(t, "cut_f.off", b.d, b.n - 1, MTS_ERR_FORMAT,
                 "truncated: expected 4 faces, file ends after 3");
    expect_error(t, "cut_h.off", b.d, header + 5, MTS_ERR_FORMAT,
                 "truncated: the binary OFF counts take 12 bytes");
    buf_free(&b);

    /* huge counts: over the limit, or more than the file holds */
    unsigned char *p;
    static const uint32_t le_over = 0xffffffffu;
    tet_off_binary(&b, 0, 0);
    memcpy(b.d + header, &le_over, 4);
    expect_error(t, "huge.off", b.d, b.n, MTS_ERR_LIMIT, "4294967295 vertices is over the limit");
    buf_free(&b);
    tet_off_binary(&b, 0, 0);
    p = b.d + header;
    p[0] = 0x00, p[1] = 0x94, p[2] = 0x35, p[3] = 0x77; /* 2,000,000,000 little endian */
    expect_error(t, "big.off", b.d, b.n, MTS_ERR_FORMAT,
                 "truncated: expected 2000000000 vertices, file ends after 9");
    buf_free(&b);
    tet_off_binary(&b, 1, 0);
    p = b.d + header + 4;
    p[0] = 0x77, p[1] = 0x35, p[2] = 0x94, p[3] = 0x00; /* 2,000,000,000 faces big endian */
    expect_error(t, "bigf.off", b.d, b.n, MTS_ERR_FORMAT,
                 "truncated: expected 2000000000 faces, file ends after 4");
    buf_free(&b);
    /* a face claiming 2 billion corners, and one claiming a negative count */
    const size_t faces = header + 12 + 4 * 12;
    tet_off_binary(&b, 0, 0);
    p = b.d + faces + 16;
    p[0] = 0x00, p[1] = 0x94, p[2] = 0x35, p[3] = 0x77;
    expect_error(t, "bigpoly.off", b.d, b.n, MTS_ERR_FORMAT,
                 "face 1 claims 2000000000 corners, the file holds 11 more");
    memset(p, 0xff, 4);
    expect_error(t, "negpoly.off", b.d, b.n, MTS_ERR_FORMAT, "face 1 has -1 corners");
    buf_free(&b);

    /* indices out of range, both layouts */
    tet_off_binary(&b, 0, 0);
    b.d[b.n - 4] = 9; /* the last index of the last face */
    expect_error(t, "range.off", b.d, b.n, MTS_ERR_RANGE,
                 "face 3: vertex index 9 out of range (4 vertices)");
    memset(b.d + faces + 4, 0xff, 4); /* the first index of face 0: -1 */
    expect_error(t, "minus.off", b.d, b.n, MTS_ERR_RANGE, "face 0: vertex index -1 out of range");
    buf_free(&b);
    tet_off_binary(&b, 1, 0);
    b.d[b.n - 5] = 4; /* the last index of the last face, before its colour count */
    expect_error(t, "range_be.off", b.d, b.n, MTS_ERR_RANGE,
                 "face 3: vertex index 4 out of range (4 vertices)");
    buf_free(&b);

    /* a bad colour count, a NaN, a bad header line, binary nOFF */
    tet_off_binary(&b, 1, 0);
    b.d[faces + 19] = 5; /* face 0's colour count */
    expect_error(t, "color.off", b.d, b.n, MTS_ERR_FORMAT, "face 0: colour count 5 is not 0 to 4");
    buf_free(&b);
    tet_off_binary(&b, 0, 0);
    memset(b.d + header + 12 + 12, 0xff, 4); /* vertex 1's x */
    expect_error(t, "nan.off", b.d, b.n, MTS_ERR_FORMAT, "vertex 1 has a non-finite coordinate");
    buf_free(&b);
    expect_text_error(t, "junk.off", "OFF BINARY junk\n\x04\0\0\0", MTS_ERR_FORMAT,
                      "line 1: unexpected text after OFF BINARY");
    expect_text_error(t, "ndim.off", "nOFF BINARY\n\x03", MTS_ERR_VERSION, "binary nOFF");
    expect_text_error(t, "nonl.off", "OFF BINARY", MTS_ERR_FORMAT, "truncated");
}

/* A bad file's text never reaches the message: each of these has its
 * offending word, value, keyword or element name spelled SECRET. */
static void test_messages_quote_nothing(mts_test *t)
{
    static const struct {
        const char *name, *text;
    } cases[] = {
        {"q1.off", "SECRET:x:0:0:root:/root:/bin/bash\n"},
        {"q2.off", "OFFSECRET 1 0\n"},
        {"q3.off", "OFF\n3 1 0\n0 0 0\n1 SECRET 0\n0 1 0\n3 0 1 2\n"},
        {"q4.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2SECRET\n"},
        {"q5.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 1SECRET"},
        {"q6.off", "OFF BINARY SECRET\n\x04\0\0\0"},
        {"q7.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 1e99SECRET\n3 0 1 2\n"},
        {"q1.ply", "SECRET\nformat ascii 1.0\nend_header\n"},
        {"q2.ply", "ply\nformat SECRET 1.0\nend_header\n"},
        {"q3.ply", "ply\nformat ascii SECRET\nend_header\n"},
        {"q4.ply", "ply\nformat ascii 1.0\nSECRET here\nend_header\n"},
        {"q5.ply", "ply\nformat ascii 1.0\nelement SECRET 99999999999\nend_header\n"},
        {"q6.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty SECRET x\nend_header\n"},
        {"q7.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                   "property float y\nproperty float z\nelement SECRET 1\n"
                   "property list uchar int w\n"
                   "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                   "0 0 0\n1 0 0\n0 1 0\nSECRET\n3 0 1 2\n"},
        {"q8.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                   "property float y\nproperty float z\nelement SECRET 2\nproperty float w\n"
                   "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                   "0 0 0\n1 0 0\n0 1 0\n1\n"},
        {"q1.stl", "solid x\nfacet SECRET 0 0 1\n"},
        {"q2.stl", "solid x\nSECRET normal 0 0 1\n"},
        {"q1.obj", "v 0 0 0\nv 1 SECRET 0\nv 0 1 0\nf 1 2 3\n"},
        {"q2.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 SECRET\n"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char path[512];
        mts_mesh m;
        mts_error err = {0};
        size_t len = strlen(cases[i].text);
        if (!strcmp(cases[i].name, "q6.off"))
            len += 4; /* its binary tail */
        if (!write_file(cases[i].name, cases[i].text, len, path, sizeof path)) {
            CHECKF(t, 0, "could not write %s", cases[i].name);
            continue;
        }
        mts_result r = mts_mesh_load(path, NULL, &m, NULL, &err);
        remove(path);
        CHECKF(t, r != MTS_OK && strstr(err.msg, path) && !strstr(err.msg, "SECRET"), "%s: %s: %s",
               cases[i].name, mts_result_name(r), err.msg);
        mts_mesh_free(&m);
    }
    /* a PLY element of another name is named by its place in the header */
    mts_mesh m;
    mts_error err = {0};
    const char *ply = cases[13].text;
    CHECK(t, load_bytes("q7.ply", ply, strlen(ply), &m, NULL, &err) == MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "line 15: bad value in element 2, item 0"), "%s", err.msg);
    ply = cases[14].text;
    CHECK(t, load_bytes("q8.ply", ply, strlen(ply), &m, NULL, &err) == MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "truncated: expected 2 items of element 2, file ends after 1"),
           "%s", err.msg);
}

/* Runs fn(arg) in a child process: 1 when it returned nonzero within
 * `seconds`; the child is killed past them (a load that blocks). Under
 * `as_bytes` of address space when not 0, except under ASan, whose shadow
 * needs terabytes of it. */
static int in_child(int (*fn)(void *), void *arg, size_t as_bytes, double seconds)
{
    pid_t pid = fork();
    if (pid == 0) {
#ifndef __SANITIZE_ADDRESS__
        struct rlimit rl = {as_bytes, as_bytes};
        if (as_bytes && setrlimit(RLIMIT_AS, &rl) != 0)
            _exit(2);
#else
        (void)as_bytes;
#endif
        _exit(fn(arg) ? 0 : 1);
    }
    if (pid < 0)
        return 0;
    int status = 0;
    double t0 = mts_clock_seconds();
    while (waitpid(pid, &status, WNOHANG) == 0) {
        if (mts_clock_seconds() - t0 > seconds) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            return 0;
        }
        struct timespec ts = {0, 10 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

typedef struct load_case {
    const char *path;
    uint64_t max_bytes;
    mts_result want;
    const char *want_msg; /* or NULL */
    uint32_t triangles;   /* when want is MTS_OK */
} load_case;

static int load_case_ok(void *arg)
{
    const load_case *c = arg;
    mts_mesh m;
    mts_error err = {0};
    mts_mesh_options o = {0};
    o.max_bytes = c->max_bytes;
    mts_result r = mts_mesh_load(c->path, &o, &m, NULL, &err);
    int ok = r == c->want &&
             (r == MTS_OK ? m.triangle_count == c->triangles
                          : strstr(err.msg, c->path) != NULL && !strstr(err.msg, "SECRET") &&
                                (!c->want_msg || strstr(err.msg, c->want_msg) != NULL));
    if (!ok)
        fprintf(stderr, "  %s: %s: %s\n", c->path, mts_result_name(r), err.msg);
    mts_mesh_free(&m);
    return ok;
}

/* Only regular files are read, never past the cap, and never blocking: a
 * FIFO's open would wait for a writer without O_NONBLOCK. */
static void test_not_a_file(mts_test *t)
{
    char dir[512], p[700], target[700];
    snprintf(dir, sizeof dir, "%s/mts_test_mesh_files", mts_test_tmpdir());
    snprintf(p, sizeof p, "rm -rf '%s'", dir);
    if (system(p) != 0 || mkdir(dir, 0755) != 0) {
        CHECKF(t, 0, "cannot make %s", dir);
        return;
    }
    snprintf(p, sizeof p, "%s/fifo.off", dir);
    CHECK(t, mkfifo(p, 0644) == 0);
    load_case fifo = {p, 0, MTS_ERR_IO, "FIFO", 0};
    CHECKF(t, in_child(load_case_ok, &fifo, 0, 5), "%s", p);

    snprintf(p, sizeof p, "%s/dir.off", dir);
    CHECK(t, mkdir(p, 0755) == 0);
    load_case d = {p, 0, MTS_ERR_IO, "directory", 0};
    CHECK(t, load_case_ok(&d));

    snprintf(p, sizeof p, "%s/dangling.off", dir);
    snprintf(target, sizeof target, "%s/nothing-here", dir);
    CHECK(t, symlink(target, p) == 0);
    load_case dl = {p, 0, MTS_ERR_IO, "symbolic link to nothing", 0};
    CHECK(t, load_case_ok(&dl));

    snprintf(p, sizeof p, "%s/dev.off", dir);
    CHECK(t, symlink("/dev/zero", p) == 0);
    load_case dev = {p, 0, MTS_ERR_IO, "character device", 0};
    CHECKF(t, in_child(load_case_ok, &dev, 0, 5), "%s", p);

    /* over the cap: refused by its size, with the figures; at the cap: read */
    load_case cap = {"tests/data/cow.off", 182965, MTS_ERR_LIMIT,
                     "182966 bytes, over the size cap of 182965 bytes", 0};
    CHECK(t, load_case_ok(&cap));
    load_case at = {"tests/data/cow.off", 182966, MTS_OK, NULL, 5804};
    CHECK(t, load_case_ok(&at));
    mts_mesh m;
    mts_error err = {0};
    mts_mesh_options o = {0};
    o.max_bytes = 10;
    CHECK(t, mts_mesh_load_memory("x.off", "OFF\n3 1 0\n0 0 0\n", 16, &o, &m, NULL, &err) ==
                 MTS_ERR_LIMIT);
    CHECKF(t, strstr(err.msg, "x.off: 16 bytes, over the size cap of 10 bytes"), "%s", err.msg);
    snprintf(p, sizeof p, "rm -rf '%s'", dir);
    CHECK(t, system(p) == 0);
}

/* Makes path a sparse file of `size` bytes that starts with head (no disk
 * but head's block). */
static int sparse_file(const char *path, const void *head, size_t head_size, uint64_t size)
{
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0)
        return 0;
    int ok = (head_size == 0 || write(fd, head, head_size) == (ssize_t)head_size) &&
             ftruncate(fd, (off_t)size) == 0;
    return (close(fd) == 0) && ok;
}

/* A 3 GB file (under the default cap) that is not what its name says is
 * refused from its first bytes: quickly, and within far less memory than
 * the file (the whole file read first took 3 GB to say "not an OFF file");
 * a binary STL is read only as far as its facets go. */
static void test_refused_from_head(mts_test *t)
{
    const uint64_t size = (uint64_t)3 << 30;
    const char junk[] = "SECRET:x:0:0:root:/root:/bin/bash\n";
    char paths[10][512];
    buf stl = {0};
    tet_stl_binary(&stl, "binary");
    static const struct {
        const char *name;
        int stl_head; /* 1: a binary STL's bytes first, 2: nothing but zeros */
        mts_result want;
        const char *msg;
        uint32_t triangles;
    } cases[] = {
        {"head.off", 0, MTS_ERR_FORMAT, "not an OFF file", 0},
        {"head.ply", 0, MTS_ERR_FORMAT, "not a PLY file", 0},
        {"head.obj", 0, MTS_ERR_FORMAT, "not an OBJ file: the file is binary (byte 34 is a NUL", 0},
        {"head.stl", 0, MTS_ERR_FORMAT, "no triangles", 0},
        {"head", 0, MTS_ERR_FORMAT, "unknown mesh format", 0},
        {"padded.stl", 1, MTS_OK, NULL, 4},
        /* nothing but zeros: a first word as long as the head */
        {"zero.off", 2, MTS_ERR_FORMAT, "not an OFF file", 0},
        {"zero.ply", 2, MTS_ERR_FORMAT, "not a PLY file", 0},
        {"zero.obj", 2, MTS_ERR_FORMAT, "not an OBJ file: the file is binary (byte 0 is a NUL", 0},
        {"zero.stl", 2, MTS_ERR_FORMAT, "no triangles", 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(paths[i], sizeof paths[i], "%s/mts_test_mesh_%s", mts_test_tmpdir(),
                 cases[i].name);
        int made = cases[i].stl_head == 1   ? sparse_file(paths[i], stl.d, stl.n, size)
                   : cases[i].stl_head == 2 ? sparse_file(paths[i], NULL, 0, size)
                                            : sparse_file(paths[i], junk, sizeof junk - 1, size);
        if (!made) {
            remove(paths[i]);
            buf_free(&stl);
            SKIP(t, "cannot make a sparse file of 3 GB in %s", mts_test_tmpdir());
        }
        load_case c = {paths[i], 0, cases[i].want, cases[i].msg, cases[i].triangles};
        /* 512 MB of address space: a loader that read the 3 GB before
         * deciding dies of it; 20 s: one that blocked is killed */
        CHECKF(t, in_child(load_case_ok, &c, (size_t)512 << 20, 20), "%s", cases[i].name);
        remove(paths[i]);
    }
    buf_free(&stl);
}

/* Every prefix and many single-byte corruptions of a valid file of each
 * format either load or fail with a message naming the file: never a crash,
 * an over-read or a leak (under ASan). */
static void test_robust(mts_test *t)
{
    buf files[11] = {{0}};
    const char *names[11] = {"f.off", "f.obj", "f.ply", "f.ply", "f.ply", "f.stl",
                             "f.stl", "f.off", "f.off", "f.off", "f.off"};
    cube_off(&files[0]);
    buf_printf(&files[1], "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvn 0 0 1\n"
                          "f 1/1/1 3/1/1 2/1/1\nf -4//-1 -3//-1 -1//-1\nf 1 4 3\nf 2 3 4\n");
    cube_ply(&files[2], 0);
    cube_ply(&files[3], 1);
    tet_ply(&files[4], 2, T_F64, T_U16, T_U32);
    tet_stl_ascii(&files[5]);
    tet_stl_binary(&files[6], "solid");
    buf_printf(&files[7], "NOFF\n4 4 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n0 0 1 0 0 1\n"
                          "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n");
    tet_off_binary(&files[8], 0, 0);
    tet_off_binary(&files[9], 1, OFFB_NORMALS);
    tet_off_binary(&files[10], 0, OFFB_COLORS | OFFB_ST);
    uint32_t seed = 1;
    for (int i = 0; i < 11; i++) {
        buf *b = &files[i];
        mts_mesh m;
        mts_error err;
        mts_result r = load_bytes(names[i], b->d, b->n, &m, NULL, &err);
        CHECKF(t, r == MTS_OK, "file %d: %s", i, err.msg);
        mts_mesh_free(&m);
        for (size_t cut = 0; cut < b->n; cut++) {
            err.msg[0] = 0;
            r = load_bytes(names[i], b->d, cut, &m, NULL, &err);
            CHECKF(t, r == MTS_OK || strstr(err.msg, names[i]) == err.msg, "file %d cut %zu: %s",
                   i, cut, err.msg);
            mts_mesh_free(&m);
        }
        for (int k = 0; k < 3000; k++) {
            unsigned char *copy = malloc(b->n);
            memcpy(copy, b->d, b->n);
            for (int flips = 0; flips < 1 + k % 3; flips++) {
                seed = seed * 1664525 + 1013904223;
                size_t at = (seed >> 8) % b->n;
                seed = seed * 1664525 + 1013904223;
                static const char pick[] = "0123456789-+.eE \n#/x\xff";
                copy[at] = (k & 1) ? (unsigned char)(seed >> 24)
                                   : (unsigned char)pick[(seed >> 24) % (sizeof pick - 1)];
            }
            err.msg[0] = 0;
            r = load_bytes(names[i], copy, b->n, &m, NULL, &err);
            CHECKF(t, r == MTS_OK || strstr(err.msg, names[i]) == err.msg, "file %d flip %d: %s",
                   i, k, err.msg);
            if (r == MTS_OK) {
                for (uint32_t v = 0; v < m.triangle_count * 3; v++)
                    CHECK(t, m.triangles[v] < m.vertex_count);
                for (uint32_t v = 0; v < m.vertex_count * 3; v++)
                    CHECK(t, isfinite(m.positions[v]) && isfinite(m.normals[v]));
            }
            mts_mesh_free(&m);
            free(copy);
        }
        buf_free(b);
    }
}

/* ------------------------------------------------------------------------ */
/* Detection, numbers, real models                                          */

static void test_detection(mts_test *t)
{
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    buf b = {0};
    cube_off(&b);
    static const char *const off_names[] = {"CUBE.OFF", "cube.Off", "cube", "dir.v2/cube.dat"};
    for (size_t i = 0; i < 4; i++) {
        mts_result r = load_bytes(off_names[i], b.d, b.n, &m, &st, &err);
        CHECKF(t, r == MTS_OK && st.format == MTS_MESH_OFF, "%s: %s", off_names[i], err.msg);
        mts_mesh_free(&m);
    }
    /* the option overrides the name */
    mts_mesh_options o = {.format = MTS_MESH_OFF};
    mts_result r = mts_mesh_load_memory("cube.stl", b.d, b.n, &o, &m, &st, &err);
    CHECKF(t, r == MTS_OK && st.format == MTS_MESH_OFF, "%s", err.msg);
    mts_mesh_free(&m);
    buf_free(&b);

    cube_ply(&b, 1);
    r = load_bytes("cube", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK && st.format == MTS_MESH_PLY, "%s", err.msg);
    mts_mesh_free(&m);
    buf_free(&b);

    tet_stl_ascii(&b);
    r = load_bytes("tet.txt", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK && st.format == MTS_MESH_STL, "%s", err.msg);
    mts_mesh_free(&m);
    buf_free(&b);

    /* with a UTF-8 byte order mark, which must not hide the first vertex */
    const char *obj = "\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    r = load_bytes("tri", obj, strlen(obj), &m, &st, &err);
    CHECKF(t, r == MTS_OK && st.format == MTS_MESH_OBJ, "%s", err.msg);
    CHECK(t, m.triangle_count == 1 && m.normals[2] == 1);
    mts_mesh_free(&m);

    CHECK(t, strcmp(mts_mesh_format_name(MTS_MESH_PLY), "PLY") == 0);
    CHECK(t, strcmp(mts_mesh_format_name(MTS_MESH_AUTO), "auto") == 0);
}

/* Text in UTF-16 (or UTF-32), as Windows editors save "Unicode": each
 * ASCII character c as 00 c (big-endian) or c 00, after a byte order mark
 * when bom is set. */
static void put_wide(buf *b, const char *text, int width, int big, int bom)
{
    unsigned char c[4] = {0, 0, 0, 0};
    if (bom) {
        unsigned char mark[4] = {0, 0, 0, 0};
        if (width == 2)
            memcpy(mark, big ? "\xFE\xFF" : "\xFF\xFE", 2);
        else
            memcpy(mark, big ? "\0\0\xFE\xFF" : "\xFF\xFE\0\0", 4);
        buf_put(b, mark, (size_t)width);
    }
    for (const char *p = text; *p; p++) {
        c[big ? width - 1 : 0] = (unsigned char)*p;
        buf_put(b, c, (size_t)width);
    }
}

/* A file that is text in another encoding, or binary, where text is
 * expected, is named as what it is: not "no triangles (0 faces read)" or
 * "bad number". */
static void test_foreign_text(mts_test *t)
{
    const char *obj = "# tet\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nv 0 0 1\r\n"
                      "f 1 3 2\r\nf 1 2 4\r\nf 1 4 3\r\nf 2 3 4\r\n";
    const char *off = "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                      "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    const char *ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                      "property float y\nproperty float z\nelement face 1\n"
                      "property list uchar int vertex_indices\nend_header\n"
                      "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    const char *stl = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                      "vertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    static const struct {
        int width, big, bom;
        const char *enc;
    } encs[] = {
        {2, 1, 1, "UTF-16 (big-endian)"}, {2, 0, 1, "UTF-16 (little-endian)"},
        {2, 1, 0, "UTF-16 (big-endian)"}, {2, 0, 0, "UTF-16 (little-endian)"},
        {4, 1, 1, "UTF-32 (big-endian)"}, {4, 0, 1, "UTF-32 (little-endian)"},
    };
    static const struct {
        const char *name, *ascii;
    } fmts[] = {{"w.obj", "not ASCII OBJ"}, {"w.off", "not ASCII OFF"},
                {"w.ply", "not ASCII PLY"}, {"w.stl", "not ASCII STL"},
                {"w.mesh", "unknown mesh format"}};
    const char *texts[] = {obj, off, ply, stl, obj};
    for (size_t e = 0; e < sizeof encs / sizeof encs[0]; e++)
        for (size_t f = 0; f < sizeof fmts / sizeof fmts[0]; f++) {
            buf b = {0};
            put_wide(&b, texts[f], encs[e].width, encs[e].big, encs[e].bom);
            char want[128];
            snprintf(want, sizeof want, "the file is %s", encs[e].enc);
            expect_error(t, fmts[f].name, b.d, b.n, MTS_ERR_FORMAT, want);
            expect_error(t, fmts[f].name, b.d, b.n, MTS_ERR_FORMAT, fmts[f].ascii);
            /* and from memory, where the whole file is the head */
            mts_mesh m;
            mts_error err = {0};
            mts_result r = load_bytes(fmts[f].name, b.d, b.n, &m, NULL, &err);
            CHECKF(t, r == MTS_ERR_FORMAT && strstr(err.msg, want), "%s %s: %s", fmts[f].name,
                   encs[e].enc, err.msg);
            buf_free(&b);
        }
    /* a short UTF-16 STL, under a binary STL's 84 header bytes */
    buf b = {0};
    put_wide(&b, "solid x\n", 2, 0, 1);
    expect_error(t, "short.stl", b.d, b.n, MTS_ERR_FORMAT, "the file is UTF-16 (little-endian)");
    buf_free(&b);

    /* binary data under a text format's name */
    unsigned char bin[400];
    for (size_t i = 0; i < sizeof bin; i++)
        bin[i] = (unsigned char)(i * 37 % 251);
    expect_error(t, "bin.obj", bin, sizeof bin, MTS_ERR_FORMAT,
                 "not an OBJ file: the file is binary (byte 0 is a NUL byte), not ASCII OBJ");
    expect_error(t, "bin.off", bin, sizeof bin, MTS_ERR_FORMAT,
                 "not an OFF file: the file is binary (byte 0 is a NUL byte), not ASCII OFF");
    expect_error(t, "bin.ply", bin, sizeof bin, MTS_ERR_FORMAT,
                 "not a PLY file: the file is binary (byte 0 is a NUL byte), not ASCII PLY "
                 "(and no 'ply' magic)");
    /* an ascii PLY header over binary data */
    buf_printf(&b, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                   "property float y\nproperty float z\nelement face 1\n"
                   "property list uchar int vertex_indices\nend_header\n");
    float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    buf_put(&b, xyz, sizeof xyz);
    expect_error(t, "lies.ply", b.d, b.n, MTS_ERR_FORMAT,
                 "vertex 0: the header says ascii, but the data is binary");
    buf_free(&b);
    /* text that is no OFF keeps its message */
    expect_text_error(t, "words.off", "hello world\n", MTS_ERR_FORMAT,
                      "not an OFF file (the first word is not OFF");
}

/* Files real tools write and read, which are a little off the format, are
 * read; where one has no surface the message says what it has instead. */
static void test_lenient(mts_test *t)
{
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    /* Blender 2.47's PLY header: "Created by ..." without "comment" */
    const char *ply = "ply\nformat ascii 1.0\nCreated by Blender3D 247 - www.blender.org, "
                      "source file: \nelement vertex 4\nproperty float x\nproperty float y\n"
                      "property float z\nproperty uchar red\nproperty uchar green\n"
                      "property uchar blue\nelement face 4\n"
                      "property list uchar uint vertex_indices\nend_header\n"
                      "0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n0 0 1 9 9 9\n"
                      "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    mts_result r = load_text("blender.ply", ply, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        st.format = MTS_MESH_OFF; /* check_tet's */
        check_tet(t, &m, &st, "blender.ply");
    }
    CHECKF(t, st.skipped_header_lines == 1 && st.first_skipped_header_line == 3, "%u at %u",
           st.skipped_header_lines, st.first_skipped_header_line);
    mts_mesh_free(&m);
    /* a standard file warns of nothing */
    r = load_text("plain.ply", "ply\nformat ascii 1.0\ncomment x\nobj_info y\n"
                               "element vertex 3\nproperty float x\nproperty float y\n"
                               "property float z\nelement face 1\n"
                               "property list uchar int vertex_indices\nend_header\n"
                               "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                  &m, &st, &err);
    CHECKF(t, r == MTS_OK && st.skipped_header_lines == 0, "%s", err.msg);
    mts_mesh_free(&m);

    /* OBJ vertex colours ("v x y z r g b") leave the positions as they are */
    const char *obj = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 0 0 1 0.5 0.5 0.5\n"
                      "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    r = load_text("colours.obj", obj, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        st.format = MTS_MESH_OFF;
        check_tet(t, &m, &st, "colours.obj");
    }
    mts_mesh_free(&m);

    /* no faces: said, and by what the file has instead */
    const char *cloud = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\n";
    expect_text_error(t, "cloud.obj", cloud, MTS_ERR_FORMAT,
                      "no triangles: the file has 3 vertices but no faces (a point cloud");
    expect_text_error(t, "lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3 1\np 1\np 2\n",
                      MTS_ERR_FORMAT,
                      "the file has 3 vertices, 2 points ('p') and 1 lines ('l') but no faces");
    expect_text_error(t, "cloud.off", "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", MTS_ERR_FORMAT,
                      "no triangles: the file has 3 vertices but no faces");
    expect_text_error(t, "none.obj", "# nothing\ng x\n", MTS_ERR_FORMAT,
                      "no triangles: the file has no faces and no vertices");
    /* faces that cleaning removes keep the count of what was read */
    expect_text_error(t, "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", MTS_ERR_FORMAT,
                      "no triangles left after cleaning (1 faces read: 1 degenerate");
}

static uint32_t rng(uint64_t *s)
{
    *s = *s * 6364136223846793005u + 1442695040888963407u;
    return (uint32_t)(*s >> 33);
}

/* The hand-written scanner gives exactly strtof's float. */
static void test_scan_float(mts_test *t)
{
    static const char *const cases[] = {
        "0", "-0", "1", "0.5", ".5", "5.", "1e3", "1E-3", "-1.55991e-008", "0.281526",
        "3.4028234e38", "1.17549435e-38", "1e-40", "1.4e-45", "1e-50", "123456789012345678901234",
        "0.000000000000000000000000000000000001", "1.000000059604644775390625",
        "1.0000000596046447753906250001", "1.00000017881393432617187499",
        "16777217", "16777219", "9007199254740993", "0.1", "0.3", "2.5e-8", "+7"};
    int bad = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *s = cases[i];
        float got = -1;
        int r = mts__mesh_scan_float(&s, cases[i] + strlen(cases[i]), &got);
        float want = strtof(cases[i], NULL);
        CHECKF(t, r == 0 && memcmp(&got, &want, 4) == 0 && *s == 0, "%s: %.9g vs %.9g", cases[i],
               got, want);
    }
    const char *s = "1e39";
    float f;
    CHECK(t, mts__mesh_scan_float(&s, s + 4, &f) == -2);
    static const char *const rejects[] = {"", "-", ".", "e5", "1e", "1e+", "nan", "inf", "+.e1"};
    for (size_t i = 0; i < sizeof rejects / sizeof rejects[0]; i++) {
        s = rejects[i];
        CHECKF(t, mts__mesh_scan_float(&s, s + strlen(s), &f) == -1, "'%s'", rejects[i]);
    }
    /* random decimals, many near float midpoints */
    uint64_t seed = 42;
    char str[64];
    for (int i = 0; i < 200000 && bad < 10; i++) {
        int n = 0;
        if (rng(&seed) & 1)
            str[n++] = '-';
        int digits = 1 + rng(&seed) % 24, dot = rng(&seed) % (digits + 1);
        for (int d = 0; d < digits; d++) {
            if (d == dot)
                str[n++] = '.';
            str[n++] = (char)('0' + rng(&seed) % 10);
        }
        if (rng(&seed) % 3 == 0)
            n += snprintf(str + n, sizeof str - n, "e%d", (int)(rng(&seed) % 90) - 45);
        str[n] = 0;
        if (i % 4 == 0) /* an exact midpoint between two floats, written out */
            n = snprintf(str, sizeof str, "%.25g",
                         (double)ldexpf((float)(rng(&seed) | 1u << 23), (int)(rng(&seed) % 40) - 60) *
                             (1 + ldexp(1, -24)));
        const char *p = str;
        float got, want = strtof(str, NULL);
        int r = mts__mesh_scan_float(&p, str + n, &got);
        if (isinf(want))
            continue;
        if (r != 0 || memcmp(&got, &want, 4) != 0 || p != str + n) {
            bad++;
            CHECKF(t, 0, "'%s': %.9g vs strtof %.9g", str, got, want);
        }
    }
}

/* ------------------------------------------------------------------------ */
/* Vertex colours                                                           */

static int color_is(const mts_mesh *m, uint32_t v, int r, int g, int b)
{
    const uint8_t *c = m->colors + 3 * (size_t)v;
    return abs(c[0] - r) + abs(c[1] - g) + abs(c[2] - b) == 0;
}

/* The tetrahedron's colours, 8-bit sRGB, and as the files write them. */
static const int tet_rgb[4][3] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {128, 64, 32}};

/* A tetrahedron PLY with colour channels of `type`, written in its range
 * (0..255, 0..65535 or 0..1), with alpha when alpha_type >= 0. */
static void tet_ply_colors(buf *b, int fmt, int type, int alpha_type, const double (*rgb)[3],
                           const double *alpha)
{
    buf_printf(b, "ply\nformat %s 1.0\nelement vertex 4\n", ply_format[fmt]);
    buf_printf(b, "property float x\nproperty float y\nproperty float z\n");
    buf_printf(b, "property %s red\nproperty %s green\nproperty %s blue\n", type_name[type],
               type_name[type], type_name[type]);
    if (alpha_type >= 0)
        buf_printf(b, "property %s alpha\n", type_name[alpha_type]);
    buf_printf(b, "element face 4\nproperty list uchar int vertex_indices\nend_header\n");
    for (int v = 0; v < 4; v++) {
        for (int c = 0; c < 3; c++)
            put_value(b, fmt, T_F32, tet_pos[v][c]);
        for (int c = 0; c < 3; c++)
            put_value(b, fmt, type, rgb[v][c]);
        if (alpha_type >= 0)
            put_value(b, fmt, alpha_type, alpha[v]);
        put_end(b, fmt);
    }
    for (int f = 0; f < 4; f++) {
        put_value(b, fmt, T_U8, 3);
        for (int c = 0; c < 3; c++)
            put_value(b, fmt, T_I32, tet_tri[f][c]);
        put_end(b, fmt);
    }
}

static void test_ply_colors(mts_test *t)
{
    for (int fmt = 0; fmt < 3; fmt++) {
        /* uchar with alpha, the common form; one vertex translucent */
        double rgb[4][3], alpha[4] = {255, 255, 100, 255};
        for (int v = 0; v < 4; v++)
            for (int c = 0; c < 3; c++)
                rgb[v][c] = tet_rgb[v][c];
        buf b = {0};
        tet_ply_colors(&b, fmt, T_U8, T_U8, rgb, alpha);
        mts_mesh m;
        mts_mesh_stats st;
        mts_error err = {0};
        mts_result r = load_bytes("tet.ply", b.d, b.n, &m, &st, &err);
        CHECKF(t, r == MTS_OK, "%s: %s", ply_format[fmt], err.msg);
        if (r == MTS_OK) {
            CHECK(t, m.colors != NULL && st.colors_from_file == 1);
            for (int v = 0; m.colors && v < 4; v++)
                CHECKF(t, color_is(&m, (uint32_t)v, tet_rgb[v][0], tet_rgb[v][1], tet_rgb[v][2]),
                       "%s vertex %d", ply_format[fmt], v);
            CHECK(t, st.colors_alpha == 1 && st.colors_translucent == 1);
            CHECK(t, st.colors_clamped == 0 && st.colors_missing == 0);
        }
        mts_mesh_free(&m);
        buf_free(&b);

        /* ushort: 0..65535 */
        for (int v = 0; v < 4; v++)
            for (int c = 0; c < 3; c++)
                rgb[v][c] = tet_rgb[v][c] * 257.0;
        tet_ply_colors(&b, fmt, T_U16, -1, rgb, NULL);
        r = load_bytes("tet.ply", b.d, b.n, &m, &st, &err);
        CHECKF(t, r == MTS_OK, "%s: %s", ply_format[fmt], err.msg);
        for (int v = 0; r == MTS_OK && m.colors && v < 4; v++)
            CHECKF(t, color_is(&m, (uint32_t)v, tet_rgb[v][0], tet_rgb[v][1], tet_rgb[v][2]),
                   "ushort %s vertex %d", ply_format[fmt], v);
        CHECK(t, r != MTS_OK || (m.colors && st.colors_alpha == 0));
        mts_mesh_free(&m);
        buf_free(&b);

        /* float and double in 0..1 (assimp's float-color.ply); two values
         * out of range are clamped and counted */
        for (int type = T_F32; type <= T_F64; type++) {
            const double f[4][3] = {{1, 0, 0}, {0, 1, 0}, {-0.25, 0, 1.5}, {0.5, 0.25, 0.125}};
            tet_ply_colors(&b, fmt, type, -1, f, NULL);
            r = load_bytes("tet.ply", b.d, b.n, &m, &st, &err);
            CHECKF(t, r == MTS_OK, "%s: %s", ply_format[fmt], err.msg);
            if (r == MTS_OK && m.colors) {
                CHECK(t, color_is(&m, 0, 255, 0, 0) && color_is(&m, 1, 0, 255, 0));
                CHECK(t, color_is(&m, 2, 0, 0, 255));
                CHECK(t, color_is(&m, 3, 128, 64, 32)); /* 127.5 -> 128, 63.75, 31.875 */
                CHECK(t, st.colors_clamped == 2);
            }
            CHECK(t, r != MTS_OK || m.colors);
            mts_mesh_free(&m);
            buf_free(&b);
        }
    }
    /* a non-finite colour is refused naming the vertex, in binary and ASCII */
    {
        const double f[4][3] = {{1, 0, 0}, {0, 1, 0}, {0, NAN, 1}, {0, 0, 0}};
        buf b = {0};
        tet_ply_colors(&b, 1, T_F32, -1, f, NULL);
        expect_error(t, "nan_color.ply", b.d, b.n, MTS_ERR_FORMAT, "vertex 2");
        buf_free(&b);
        tet_ply_colors(&b, 0, T_F32, -1, f, NULL);
        expect_error(t, "nan_color_ascii.ply", b.d, b.n, MTS_ERR_FORMAT, "vertex 2");
        buf_free(&b);
    }
    /* only red and green: not a colour */
    {
        const char *ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                          "property float y\nproperty float z\nproperty uchar red\n"
                          "property uchar green\nelement face 1\n"
                          "property list uchar int vertex_indices\nend_header\n"
                          "0 0 0 1 2\n1 0 0 1 2\n0 1 0 1 2\n3 0 1 2\n";
        mts_mesh m;
        mts_mesh_stats st;
        mts_error err = {0};
        mts_result r = load_text("rg.ply", ply, &m, &st, &err);
        CHECKF(t, r == MTS_OK, "%s", err.msg);
        CHECK(t, m.colors == NULL && st.colors_from_file == 0);
        mts_mesh_free(&m);
    }
}

static void test_off_colors(mts_test *t)
{
    static const char *const files[] = {
        /* MeshLab's and OpenMesh's: integers 0..255 with alpha */
        "COFF\n4 4 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 128\n"
        "0 0 1 128 64 32 255\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
        /* Geomview's: floats 0..1, r g b a */
        "COFF\n4 4 0\n0 0 0 1 0 0 1\n1 0 0 0 1 0 1\n0 1 0 0 0 1 0.5\n"
        "0 0 1 0.5 0.25 0.125 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
        /* three integers, no alpha, with normals (CNOFF) and a comment */
        "CNOFF\n4 4 0\n0 0 0 -1 -1 -1 255 0 0\n1 0 0 1 0 0 0 255 0\n0 1 0 0 1 0 0 0 255 # c\n"
        "0 0 1 0 0 1 128 64 32\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
        /* with texture coordinates after the colour */
        "STCOFF\n4 4 0\n0 0 0 1 0 0 1 0.5 0.5\n1 0 0 0 1 0 1 0 0\n0 1 0 0 0 1 1 1 1\n"
        "0 0 1 0.5 0.25 0.125 1 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
    };
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        mts_mesh m;
        mts_mesh_stats st;
        mts_error err = {0};
        mts_result r = load_text("tet.off", files[i], &m, &st, &err);
        CHECKF(t, r == MTS_OK, "file %zu: %s", i, err.msg);
        CHECKF(t, r != MTS_OK || (m.colors && st.colors_from_file), "file %zu", i);
        for (int v = 0; r == MTS_OK && m.colors && v < 4; v++)
            CHECKF(t, color_is(&m, (uint32_t)v, tet_rgb[v][0], tet_rgb[v][1], tet_rgb[v][2]),
                   "file %zu vertex %d: %d %d %d", i, v, m.colors[3 * v], m.colors[3 * v + 1],
                   m.colors[3 * v + 2]);
        CHECKF(t, st.colors_alpha == (i != 2) && st.colors_translucent == (i < 2),
               "file %zu: alpha %d translucent %u", i, st.colors_alpha, st.colors_translucent);
        mts_mesh_free(&m);
    }
    expect_text_error(t, "nan.off", "COFF\n3 1 0\n0 0 0 1 0 0 1\n1 0 0 nan 0 0 1\n0 1 0 1 0 0 1\n"
                      "3 0 1 2\n", MTS_ERR_FORMAT, "vertex 1: a colour value is not a finite");
    /* a colour-map index (one value) is no colour: a vertex without, beside
     * others with, drops them all */
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = load_text("mixed.off", "COFF\n3 1 0\n0 0 0 1 0 0 1\n1 0 0 7\n0 1 0 1 0 0 1\n"
                             "3 0 1 2\n", &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, m.colors == NULL && st.colors_missing == 1 && st.colors_from_file == 0);
    mts_mesh_free(&m);
}

/* The tetrahedron as binary COFF with tet_rgb's vertex colours: big = 1 is
 * Geomview's layout (big endian, RGBA floats, a colour count after each
 * face's indices and face 2 with a colour of its own), big = 0 OpenMesh's
 * (little endian, integer RGB, nothing after a face). bytes writes the
 * floats in 0..255. Vertex 2's alpha is half; nan_at puts NaN in that
 * vertex's red (-1: none). */
static void tet_coff_binary(buf *b, int big, int bytes, int nan_at)
{
    buf_printf(b, "COFF BINARY\n");
    put_u32(b, 4, big);
    put_u32(b, 4, big);
    put_u32(b, 6, big);
    const float scale = bytes ? 1.0f : 1.0f / 255.0f;
    for (int v = 0; v < 4; v++) {
        for (int k = 0; k < 3; k++)
            put_f32(b, tet_pos[v][k], big);
        for (int k = 0; k < 3; k++) {
            if (!big)
                put_u32(b, (uint32_t)tet_rgb[v][k], big);
            else
                put_f32(b, v == nan_at && k == 0 ? NAN : (float)tet_rgb[v][k] * scale, big);
        }
        if (big)
            put_f32(b, (v == 2 ? 128.0f : 255.0f) * scale, big);
    }
    for (int f = 0; f < 4; f++) {
        put_u32(b, 3, big);
        for (int k = 0; k < 3; k++)
            put_u32(b, tet_tri[f][k], big);
        if (big) {
            put_u32(b, f == 2 ? 4 : 0, big);
            for (int k = 0; k < (f == 2 ? 4 : 0); k++)
                put_f32(b, 0.75f, big);
        }
    }
}

/* Binary COFF keeps its vertex colours, ranged as ASCII COFF's are. */
static void test_off_binary_colors(mts_test *t)
{
    static const struct {
        const char *name;
        int big, bytes;
    } cases[] = {{"geomview.off", 1, 0}, {"openmesh.off", 0, 0}, {"floats255.off", 1, 1}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        buf b = {0};
        tet_coff_binary(&b, cases[i].big, cases[i].bytes, -1);
        mts_mesh m;
        mts_mesh_stats st;
        mts_error err = {0};
        mts_result r = load_bytes(cases[i].name, b.d, b.n, &m, &st, &err);
        CHECKF(t, r == MTS_OK, "%s: %s", cases[i].name, err.msg);
        if (r == MTS_OK) {
            check_tet(t, &m, &st, cases[i].name);
            CHECKF(t, m.colors && st.colors_from_file, "%s", cases[i].name);
            for (int v = 0; m.colors && v < 4; v++)
                CHECKF(t, color_is(&m, (uint32_t)v, tet_rgb[v][0], tet_rgb[v][1], tet_rgb[v][2]),
                       "%s vertex %d: %d %d %d", cases[i].name, v, m.colors[3 * v],
                       m.colors[3 * v + 1], m.colors[3 * v + 2]);
            /* OpenMesh's words here are RGB; Geomview's RGBA, vertex 2 half */
            const uint32_t rgba = (uint32_t)cases[i].big;
            CHECKF(t, st.colors_alpha == (int)rgba && st.colors_translucent == rgba,
                   "%s: alpha %d translucent %u", cases[i].name, st.colors_alpha,
                   st.colors_translucent);
        }
        mts_mesh_free(&m);
        buf_free(&b);
    }
    /* a non-finite colour is refused, naming the vertex, as in ASCII COFF */
    buf b = {0};
    tet_coff_binary(&b, 1, 0, 1);
    mts_mesh m;
    mts_error err = {0};
    mts_result r = load_bytes("nan.off", b.d, b.n, &m, NULL, &err);
    CHECKF(t, r == MTS_ERR_FORMAT &&
                  strstr(err.msg, "vertex 1: a colour value is not a finite number"),
           "%d %s", r, err.msg);
    mts_mesh_free(&m);
    buf_free(&b);
}

static void test_obj_colors(mts_test *t)
{
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    /* with an unreferenced vertex first, so that cleaning moves the colours */
    mts_result r = load_text("tet.obj",
                             "v 9 9 9 0.1 0.1 0.1\n"
                             "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\n"
                             "v 0 0 1 0.5 0.25 0.125 0.5\n"
                             "f 2 4 3\nf 2 3 5\nf 2 5 4\nf 3 4 5\n",
                             &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        CHECK(t, m.vertex_count == 4 && st.unreferenced_vertices == 1);
        CHECK(t, m.colors && st.colors_from_file == 1);
        for (int v = 0; m.colors && v < 4; v++)
            CHECKF(t, color_is(&m, (uint32_t)v, tet_rgb[v][0], tet_rgb[v][1], tet_rgb[v][2]),
                   "vertex %d", v);
        CHECK(t, st.colors_alpha == 1 && st.colors_translucent == 1);
    }
    mts_mesh_free(&m);

    /* w is no colour; a file that mixes coloured and plain vertices keeps
     * none and counts the plain ones (the unreferenced plain one not) */
    r = load_text("mixed.obj",
                  "v 9 9 9\nv 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 1.0\nv 0 0 1 0.5 0.25 0.125\n"
                  "f 2 4 3\nf 2 3 5\nf 2 5 4\nf 3 4 5\n",
                  &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, m.colors == NULL && st.colors_missing == 2 && st.colors_from_file == 0);
    mts_mesh_free(&m);

    /* without the unreferenced coloured one: all have colours but it */
    r = load_text("unref.obj",
                  "v 9 9 9\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 0 0 1 0.5 0.25 0.125\n"
                  "f 2 4 3\nf 2 3 5\nf 2 5 4\nf 3 4 5\n",
                  &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, m.colors != NULL && st.colors_missing == 0);
    mts_mesh_free(&m);

    /* dropped on request: nothing kept, nothing counted */
    {
        char path[512];
        const char *obj = "v 0 0 0 1 0 0 0.5\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n";
        CHECK(t, write_file("nocolor.obj", obj, strlen(obj), path, sizeof path) != NULL);
        mts_mesh_options o = {.no_colors = 1};
        r = mts_mesh_load(path, &o, &m, &st, &err);
        remove(path);
        CHECKF(t, r == MTS_OK, "%s", err.msg);
        CHECK(t, m.colors == NULL && st.colors_from_file == 0 && st.colors_alpha == 0);
        mts_mesh_free(&m);
    }

    expect_text_error(t, "inf.obj", "v 0 0 0 1 0 0\nv 1 0 0 0 inf 0\nv 0 1 0 0 0 1\nf 1 2 3\n",
                      MTS_ERR_FORMAT, "vertex 1: a colour value is not a finite number");
    expect_text_error(t, "big.obj", "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1e99\nf 1 2 3\n",
                      MTS_ERR_FORMAT, "vertex 2: a colour value is not a finite number");
}

/* A GLB of the tetrahedron: POSITION, COLOR_0 of the given accessor type
 * and component type (values in `color`, comps per vertex) and indices. */
static void tet_glb(buf *out, const char *color_type, int ctype, int normalized,
                    const void *color, size_t color_bytes)
{
    buf bin = {0};
    for (int v = 0; v < 4; v++)
        buf_put(&bin, tet_pos[v], 12);
    size_t color_at = bin.n;
    buf_put(&bin, color, color_bytes);
    while (bin.n % 4)
        buf_put(&bin, "", 1);
    size_t index_at = bin.n;
    for (int f = 0; f < 4; f++)
        for (int c = 0; c < 3; c++) {
            uint16_t i = (uint16_t)tet_tri[f][c];
            buf_put(&bin, &i, 2);
        }
    buf json = {0};
    buf_printf(&json,
               "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
               "\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":"
               "{\"POSITION\":0,\"COLOR_0\":1},\"indices\":2}]}],");
    buf_printf(&json,
               "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":4,"
               "\"type\":\"VEC3\",\"min\":[0,0,0],\"max\":[1,1,1]},"
               "{\"bufferView\":1,\"componentType\":%d,\"normalized\":%s,\"count\":4,"
               "\"type\":\"%s\"},"
               "{\"bufferView\":2,\"componentType\":5123,\"count\":12,\"type\":\"SCALAR\"}],",
               ctype, normalized ? "true" : "false", color_type);
    buf_printf(&json,
               "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48},"
               "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu},"
               "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":24}],"
               "\"buffers\":[{\"byteLength\":%zu}]}",
               color_at, color_bytes, index_at, bin.n);
    while (json.n % 4)
        buf_put(&json, " ", 1);
    while (bin.n % 4)
        buf_put(&bin, "", 1);
    uint32_t head[3] = {0x46546C67u, 2, (uint32_t)(12 + 8 + json.n + 8 + bin.n)};
    buf_put(out, head, 12);
    uint32_t ch[2] = {(uint32_t)json.n, 0x4E4F534Au};
    buf_put(out, ch, 8);
    buf_put(out, json.d, json.n);
    uint32_t cb[2] = {(uint32_t)bin.n, 0x004E4942u};
    buf_put(out, cb, 8);
    buf_put(out, bin.d, bin.n);
    buf_free(&json);
    buf_free(&bin);
}

static void test_gltf_colors(mts_test *t)
{
    /* linear float VEC3: 0 and 1 stay, 0.5 is sRGB 0.7354 (188), 0.2 is
     * 0.4845 (124), 0.05 is 0.2474 (63) */
    const float lin[4][3] = {{1, 0, 0}, {0, 1, 0}, {0.5f, 0.2f, 0.05f}, {0, 0, 2}};
    const int srgb[4][3] = {{255, 0, 0}, {0, 255, 0}, {188, 124, 63}, {0, 0, 255}};
    buf b = {0};
    tet_glb(&b, "VEC3", 5126, 0, lin, sizeof lin);
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = load_bytes("tet.glb", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, r != MTS_OK || (m.colors && st.colors_from_file && st.format == MTS_MESH_GLTF));
    for (int v = 0; r == MTS_OK && m.colors && v < 4; v++)
        CHECKF(t, color_is(&m, (uint32_t)v, srgb[v][0], srgb[v][1], srgb[v][2]),
               "float vertex %d: %d %d %d", v, m.colors[3 * v], m.colors[3 * v + 1],
               m.colors[3 * v + 2]);
    CHECK(t, st.colors_clamped == 1 && st.colors_alpha == 0);
    mts_mesh_free(&m);
    buf_free(&b);

    /* normalized unsigned byte VEC4: 128/255 linear is sRGB 0.7367 (188),
     * 51/255 is 0.4845 (124); alpha dropped and counted */
    const uint8_t u8[4][4] = {{255, 0, 0, 255}, {0, 255, 0, 255}, {128, 51, 0, 255},
                              {0, 0, 255, 10}};
    const int srgb8[4][3] = {{255, 0, 0}, {0, 255, 0}, {188, 124, 0}, {0, 0, 255}};
    tet_glb(&b, "VEC4", 5121, 1, u8, sizeof u8);
    r = load_bytes("tet.glb", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    for (int v = 0; r == MTS_OK && m.colors && v < 4; v++)
        CHECKF(t, color_is(&m, (uint32_t)v, srgb8[v][0], srgb8[v][1], srgb8[v][2]),
               "ubyte vertex %d: %d %d %d", v, m.colors[3 * v], m.colors[3 * v + 1],
               m.colors[3 * v + 2]);
    CHECK(t, r != MTS_OK || m.colors);
    CHECK(t, st.colors_alpha == 1 && st.colors_translucent == 1);
    mts_mesh_free(&m);
    buf_free(&b);

    /* normalized unsigned short VEC3 */
    const uint16_t u16[4][3] = {{65535, 0, 0}, {0, 65535, 0}, {0, 0, 65535}, {0, 0, 0}};
    tet_glb(&b, "VEC3", 5123, 1, u16, sizeof u16);
    r = load_bytes("tet.glb", b.d, b.n, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECK(t, r != MTS_OK || (m.colors && color_is(&m, 2, 0, 0, 255) && color_is(&m, 3, 0, 0, 0)));
    mts_mesh_free(&m);
    buf_free(&b);

    const float bad[4][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, INFINITY, 0}};
    tet_glb(&b, "VEC3", 5126, 0, bad, sizeof bad);
    expect_error(t, "inf.glb", b.d, b.n, MTS_ERR_FORMAT, "COLOR_0 of vertex 3 is not a finite");
    buf_free(&b);
}

/* ------------------------------------------------------------------------ */
/* glTF KHR_draco_mesh_compression                                          */

/* The assimp test models' glTF2 folder (assimp-testmodels), or NULL with
 * the case skipped, failed where MTS_TEST_REQUIRE_ASSIMP says it must be
 * there. */
static const char *assimp_gltf2(mts_test *t, char *out, size_t size)
{
    const char *root = getenv("MTS_ASSIMP_MODELS");
    snprintf(out, size, "%s/glTF2", root && *root ? root : "/usr/share/assimp/models");
    struct stat ds;
    if (stat(out, &ds) == 0 && S_ISDIR(ds.st_mode))
        return out;
    CHECKF(t, !getenv("MTS_TEST_REQUIRE_ASSIMP"), "MTS_TEST_REQUIRE_ASSIMP is set and there "
           "is no %s (apt-get install assimp-testmodels)", out);
    if (!t->case_failed) {
        fprintf(stderr, "  SKIP %s: no %s (apt-get install assimp-testmodels)\n",
                t->case_name, out);
        t->case_skipped = 1;
    }
    return NULL;
}

static unsigned char *read_whole(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    buf b = {0};
    unsigned char chunk[65536];
    size_t n;
    while ((n = fread(chunk, 1, sizeof chunk, f)) > 0)
        buf_put(&b, chunk, n);
    fclose(f);
    *size = b.n;
    return b.d ? b.d : malloc(1);
}

/* A GLB of this JSON and binary chunk. */
static void glb_pack(buf *out, const buf *json, const void *bin, size_t bin_n)
{
    size_t jn = (json->n + 3) & ~(size_t)3, bn = (bin_n + 3) & ~(size_t)3;
    uint32_t head[3] = {0x46546C67u, 2, (uint32_t)(12 + 8 + jn + 8 + bn)};
    buf_put(out, head, 12);
    uint32_t ch[2] = {(uint32_t)jn, 0x4E4F534Au};
    buf_put(out, ch, 8);
    buf_put(out, json->d, json->n);
    for (size_t i = json->n; i < jn; i++)
        buf_put(out, " ", 1);
    uint32_t cb[2] = {(uint32_t)bn, 0x004E4942u};
    buf_put(out, cb, 8);
    buf_put(out, bin, bin_n);
    for (size_t i = bin_n; i < bn; i++)
        buf_put(out, "", 1);
}

/* A point of a grid of cubes, keyed by its cube. */
typedef struct cell_point {
    uint64_t key;
    uint32_t i;
} cell_point;

static int by_key(const void *x, const void *y)
{
    uint64_t a = ((const cell_point *)x)->key, b = ((const cell_point *)y)->key;
    return a < b ? -1 : a > b;
}

static uint64_t cell_key(const double lo[3], double tol, const float *p, int dx, int dy, int dz)
{
    int64_t c[3];
    int d[3] = {dx, dy, dz};
    for (int k = 0; k < 3; k++)
        c[k] = (int64_t)floor((p[k] - lo[k]) / tol) + 1 + d[k]; /* >= 0 for b's box */
    return ((uint64_t)c[0] << 42) | ((uint64_t)c[1] << 21) | (uint64_t)c[2];
}

/* The largest distance from a point of a to the nearest point of b, or
 * INFINITY when some point of a has none within tol: b's points are
 * bucketed on a grid of cell tol, so only the 27 cells around each point of
 * a are searched. */
static double nearest_worst(const float *a, uint32_t na, const float *b, uint32_t nb,
                            const double lo[3], double tol)
{
    cell_point *cells = malloc((nb ? nb : 1) * sizeof *cells);
    if (!cells)
        abort();
    for (uint32_t i = 0; i < nb; i++)
        cells[i] = (cell_point){cell_key(lo, tol, b + 3 * (size_t)i, 0, 0, 0), i};
    qsort(cells, nb, sizeof *cells, by_key);
    double worst = 0;
    for (uint32_t i = 0; i < na && worst < INFINITY; i++) {
        const float *p = a + 3 * (size_t)i;
        double best = INFINITY;
        for (int dx = -1; dx <= 1; dx++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dz = -1; dz <= 1; dz++) {
                    uint64_t key = cell_key(lo, tol, p, dx, dy, dz);
                    size_t l = 0, h = nb;
                    while (l < h) {
                        size_t m = (l + h) / 2;
                        if (cells[m].key < key)
                            l = m + 1;
                        else
                            h = m;
                    }
                    for (; l < nb && cells[l].key == key; l++) {
                        const float *q = b + 3 * (size_t)cells[l].i;
                        double s = 0;
                        for (int k = 0; k < 3; k++)
                            s += ((double)p[k] - q[k]) * ((double)p[k] - q[k]);
                        if (sqrt(s) < best)
                            best = sqrt(s);
                    }
                }
        worst = best <= tol ? (best > worst ? best : worst) : INFINITY;
    }
    free(cells);
    return worst;
}

static double mesh_area(const mts_gltf_mesh *m)
{
    double area = 0;
    for (uint32_t f = 0; f < m->triangle_count; f++) {
        const float *p[3];
        for (int k = 0; k < 3; k++)
            p[k] = m->positions + 3 * (size_t)m->triangles[3 * (size_t)f + k];
        double u[3], v[3];
        for (int k = 0; k < 3; k++) {
            u[k] = (double)p[1][k] - p[0][k];
            v[k] = (double)p[2][k] - p[0][k];
        }
        double x = u[1] * v[2] - u[2] * v[1], y = u[2] * v[0] - u[0] * v[2],
               z = u[0] * v[1] - u[1] * v[0];
        area += 0.5 * sqrt(x * x + y * y + z * z);
    }
    return area;
}

/* Triangles whose three corners lie at three different positions. */
static uint32_t proper_triangles(const mts_gltf_mesh *m)
{
    uint32_t n = 0;
    for (uint32_t f = 0; f < m->triangle_count; f++) {
        const uint32_t *v = m->triangles + 3 * (size_t)f;
        const float *a = m->positions + 3 * (size_t)v[0], *b = m->positions + 3 * (size_t)v[1],
                    *c = m->positions + 3 * (size_t)v[2];
        n += memcmp(a, b, 12) && memcmp(b, c, 12) && memcmp(a, c, 12);
    }
    return n;
}

static void mesh_box(const mts_gltf_mesh *m, double lo[3], double hi[3])
{
    for (int k = 0; k < 3; k++)
        lo[k] = INFINITY, hi[k] = -INFINITY;
    for (uint32_t i = 0; i < m->vertex_count; i++)
        for (int k = 0; k < 3; k++) {
            double v = m->positions[3 * (size_t)i + k];
            lo[k] = v < lo[k] ? v : lo[k];
            hi[k] = v > hi[k] ? v : hi[k];
        }
}

/* Khronos's 2CylinderEngine, Draco-compressed and plain, read as the same
 * mesh. Draco quantizes each primitive's positions to 11 bits over that
 * primitive's box (read from its buffers: every one of the 34 uses 11), so
 * a coordinate moves by at most half a step, L / (2 (2^11 - 1)) with L
 * no more than the whole model's largest side, and a vertex by sqrt(3)
 * times that: those are the tolerances (0.18 and 0.31 on a largest side of
 * 743; the worst vertex measured is 0.11 off). The encoder dropped the
 * plain file's degenerate triangles (11,160 of them, corners at one
 * position), so Draco's count is the plain file's proper triangles. */
static void test_gltf_draco_engine(mts_test *t)
{
    char dir[512], path[700], draco_dir[600];
    if (!assimp_gltf2(t, dir, sizeof dir))
        return;
    size_t dn = 0, pn = 0;
    snprintf(draco_dir, sizeof draco_dir, "%s/draco", dir);
    snprintf(path, sizeof path, "%s/2CylinderEngine.gltf", draco_dir);
    unsigned char *dbytes = read_whole(path, &dn);
    snprintf(path, sizeof path, "%s/2CylinderEngine-glTF-Binary/2CylinderEngine.glb", dir);
    unsigned char *pbytes = read_whole(path, &pn);
    CHECKF(t, dbytes && pbytes, "the 2CylinderEngine files are missing under %s", dir);
    mts_gltf_mesh d = {0}, p = {0};
    mts_error err = {0};
    mts_result r = dbytes ? mts_gltf_read("draco.gltf", dbytes, dn, draco_dir, 0, &d, &err)
                          : MTS_ERR_IO;
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    mts_result r2 = pbytes ? mts_gltf_read("plain.glb", pbytes, pn, NULL, 0, &p, &err)
                           : MTS_ERR_IO;
    CHECKF(t, r2 == MTS_OK, "%s", err.msg);
    if (r == MTS_OK && r2 == MTS_OK) {
        CHECKF(t, d.primitives == p.primitives && d.primitives == 115, "%u and %u primitives",
               d.primitives, p.primitives);
        uint32_t proper = proper_triangles(&p);
        CHECKF(t, d.triangle_count == proper && proper == 110336,
               "Draco %u triangles, plain %u of which %u proper", d.triangle_count,
               p.triangle_count, proper);
        CHECK(t, d.colors == NULL && p.colors == NULL);
        double dlo[3], dhi[3], plo[3], phi[3], side = 0;
        mesh_box(&d, dlo, dhi);
        mesh_box(&p, plo, phi);
        for (int k = 0; k < 3; k++)
            side = phi[k] - plo[k] > side ? phi[k] - plo[k] : side;
        double step = side / ((1 << 11) - 1), axis_tol = step / 2, tol = sqrt(3.0) * step / 2;
        for (int k = 0; k < 3; k++)
            CHECKF(t, fabs(dlo[k] - plo[k]) <= axis_tol && fabs(dhi[k] - phi[k]) <= axis_tol,
                   "axis %d: Draco %g..%g, plain %g..%g (tolerance %g)", k, dlo[k], dhi[k],
                   plo[k], phi[k], axis_tol);
        double lo[3];
        for (int k = 0; k < 3; k++)
            lo[k] = (dlo[k] < plo[k] ? dlo[k] : plo[k]) - 2 * tol;
        double w1 =
            nearest_worst(d.positions, d.vertex_count, p.positions, p.vertex_count, lo, tol);
        double w2 =
            nearest_worst(p.positions, p.vertex_count, d.positions, d.vertex_count, lo, tol);
        CHECKF(t, w1 <= tol && w2 <= tol, "nearest vertex: Draco to plain %g, plain to Draco %g "
               "(tolerance %g)", w1, w2, tol);
        double da = mesh_area(&d), pa = mesh_area(&p);
        CHECKF(t, fabs(da - pa) <= 1e-3 * pa, "area %g and %g", da, pa);
        if (getenv("MTS_TEST_VERBOSE"))
            fprintf(stderr, "  2CylinderEngine: Draco %u v %u t, plain %u v %u t (%u proper); "
                    "nearest %.4f %.4f of %.4f; area %.1f %.1f\n", d.vertex_count,
                    d.triangle_count, p.vertex_count, p.triangle_count, proper, w1, w2, tol,
                    da, pa);
    }
    mts_gltf_mesh_free(&d);
    mts_gltf_mesh_free(&p);
    free(dbytes);
    free(pbytes);
}

/* Mesh 0 of the Draco 2CylinderEngine, alone in a GLB: its compressed
 * bytes (the .bin's first 7048) and the accessors' counts, each of which
 * the case may change. */
typedef struct draco_case {
    const unsigned char *draco; /* the compressed bytes */
    size_t draco_n;
    size_t view_len;            /* the buffer view's byteLength */
    int points, indices, position_id, mode;
    const char *indices_key;    /* how the JSON spells "indices", NULL: so */
    const char *extras;         /* the primitive's "extras" member, or NULL */
} draco_case;

static mts_result draco_case_read(const draco_case *c, mts_gltf_mesh *m, mts_error *err)
{
    buf json = {0}, glb = {0};
    buf_printf(&json,
               "{\"asset\":{\"version\":\"2.0\"},"
               "\"extensionsUsed\":[\"KHR_draco_mesh_compression\"],"
               "\"extensionsRequired\":[\"KHR_draco_mesh_compression\"],\"scene\":0,"
               "\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],");
    buf_printf(&json,
               "\"meshes\":[{\"primitives\":[{%s%s\"attributes\":{\"POSITION\":0,\"NORMAL\":2},"
               "\"%s\" : 1,\"mode\":%d,\"extensions\":{\"KHR_draco_mesh_compression\":"
               "{\"bufferView\":0,\"attributes\":{\"POSITION\":%d,\"NORMAL\":0}}}}]}],",
               c->extras ? c->extras : "", c->extras ? "," : "",
               c->indices_key ? c->indices_key : "indices", c->mode, c->position_id);
    buf_printf(&json,
               "\"accessors\":[{\"componentType\":5126,\"count\":%d,\"type\":\"VEC3\"},"
               "{\"componentType\":5123,\"count\":%d,\"type\":\"SCALAR\"},"
               "{\"componentType\":5126,\"count\":%d,\"type\":\"VEC3\"}],",
               c->points, c->indices, c->points);
    buf_printf(&json,
               "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":%zu}],"
               "\"buffers\":[{\"byteLength\":%zu}]}",
               c->view_len, c->draco_n);
    glb_pack(&glb, &json, c->draco, c->draco_n);
    mts_result r = mts_gltf_read("engine0.glb", glb.d, glb.n, NULL, 0, m, err);
    buf_free(&json);
    buf_free(&glb);
    return r;
}

static void expect_draco_refused(mts_test *t, const draco_case *c, const char *want,
                                 const char *label)
{
    mts_gltf_mesh m = {0};
    mts_error err = {0};
    mts_result r = draco_case_read(c, &m, &err);
    CHECKF(t, r == MTS_ERR_FORMAT || r == MTS_ERR_RANGE || r == MTS_ERR_LIMIT,
           "%s: %d (%s)", label, (int)r, err.msg);
    CHECKF(t, strstr(err.msg, "engine0.glb: mesh 0 primitive 0: ") && strstr(err.msg, want),
           "%s: '%s' lacks '%s'", label, err.msg, want);
    mts_gltf_mesh_free(&m);
}

/* The compressed bytes are the file's: cut short, bytes flipped, an
 * attribute id the buffer has not, counts the accessors contradict. Each
 * is refused with the primitive and the problem named, never read past or
 * crashed on (ASan runs this too). */
static void test_gltf_draco_hostile(mts_test *t)
{
    char dir[512], path[600];
    if (!assimp_gltf2(t, dir, sizeof dir))
        return;
    snprintf(path, sizeof path, "%s/draco/2CylinderEngine.bin", dir);
    size_t bn = 0;
    unsigned char *bin = read_whole(path, &bn);
    CHECKF(t, bin && bn >= 7048 && !memcmp(bin, "DRACO", 5), "%s: not the Draco engine", path);
    if (!bin || bn < 7048) {
        free(bin);
        return;
    }
    unsigned char draco[7048];
    memcpy(draco, bin, sizeof draco);
    free(bin);
    const draco_case good = {draco, sizeof draco, sizeof draco, 2019, 8250, 1, 4, NULL, NULL};
    mts_gltf_mesh m = {0};
    mts_error err = {0};
    mts_result r = draco_case_read(&good, &m, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    CHECKF(t, m.vertex_count == 2019 && m.triangle_count == 2750, "%u v %u t", m.vertex_count,
           m.triangle_count);
    mts_gltf_mesh_free(&m);
    /* a strip primitive's Draco mesh is its triangles too */
    draco_case c = good;
    c.mode = 5;
    r = draco_case_read(&c, &m, &err);
    CHECKF(t, r == MTS_OK && m.triangle_count == 2750, "strip: %s", err.msg);
    mts_gltf_mesh_free(&m);
    /* the indices key escaped, extras of the primitive's own: still its
     * indices accessor that the decoded triangles are held to */
    c = good;
    c.indices_key = "ind\\u0069ces";
    c.extras = "\"extras\":{\"indices\":5}";
    r = draco_case_read(&c, &m, &err);
    CHECKF(t, r == MTS_OK && m.triangle_count == 2750, "escaped key, extras: %s", err.msg);
    mts_gltf_mesh_free(&m);
    c.indices = 8253;
    expect_draco_refused(t, &c, "the primitive's 8253 indices make 2751", "escaped key");

    /* cut short: inside the head, inside the body */
    const size_t cuts[] = {4, 11, 20, 100, 1000, 7000, 7047};
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        c = good;
        c.view_len = cuts[i];
        char label[64];
        snprintf(label, sizeof label, "cut to %zu bytes", cuts[i]);
        expect_draco_refused(t, &c, "KHR_draco_mesh_compression: ", label);
    }
    c = good;
    c.view_len = sizeof draco + 1;
    expect_draco_refused(t, &c, "runs past the end of its buffer", "view past its buffer");

    /* flipped: the magic, the version, the geometry type */
    unsigned char bad[sizeof draco];
    c = good;
    c.draco = bad;
    memcpy(bad, draco, sizeof bad);
    bad[0] ^= 0xff;
    expect_draco_refused(t, &c, "not a Draco buffer", "magic");
    memcpy(bad, draco, sizeof bad);
    bad[5] = 1;
    expect_draco_refused(t, &c, "bitstream version 1.2", "version");
    memcpy(bad, draco, sizeof bad);
    bad[7] = 0;
    expect_draco_refused(t, &c, "a point cloud, not a triangle mesh", "point cloud");
    /* and one byte in every 7 of the whole buffer: refused with the
     * primitive named, or read with its counts. Draco has no checksum: a
     * flip in the attribute values' entropy-coded bytes decodes as other
     * values (of 1007 flips, 785 are read so; the reader still holds them
     * finite and in range) */
    unsigned refused = 0, read = 0;
    for (size_t i = 0; i < sizeof bad; i += 7) {
        memcpy(bad, draco, sizeof bad);
        bad[i] ^= 0xff;
        mts_error e = {0};
        r = draco_case_read(&c, &m, &e);
        if (r == MTS_OK) {
            CHECKF(t, m.vertex_count == 2019 && m.triangle_count == 2750,
                   "byte %zu flipped: read as %u v %u t", i, m.vertex_count, m.triangle_count);
            read++;
        } else {
            CHECKF(t, r != MTS_ERR_NOMEM && r != MTS_ERR_INTERNAL &&
                          strstr(e.msg, "engine0.glb: mesh 0 primitive 0: "),
                   "byte %zu flipped: %s", i, e.msg);
            refused++;
        }
        mts_gltf_mesh_free(&m);
    }
    CHECKF(t, refused > 0, "of the flips %u refused, %u read", refused, read);
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  Draco byte flips: %u refused, %u read\n", refused, read);

    /* an attribute id the Draco mesh has not (it has 0, NORMAL, and 1) */
    c = good;
    c.position_id = 7;
    expect_draco_refused(t, &c, "POSITION's Draco attribute id 7 is not in the Draco mesh",
                         "id 7");
    /* counts the accessors contradict */
    c = good;
    c.points = 2018;
    expect_draco_refused(t, &c, "the Draco mesh has 2019 points, the POSITION accessor 2018",
                         "points");
    c = good;
    c.indices = 8253;
    expect_draco_refused(t, &c, "the Draco mesh has 2750 triangles, the primitive's 8253 "
                         "indices make 2751", "indices");
    c = good;
    c.indices = 30;
    expect_draco_refused(t, &c, "the Draco buffer declares 2750 triangles, more than the "
                         "primitive's 30 indices hold", "declared");
    c = good;
    c.mode = 6;
    expect_draco_refused(t, &c, "holds TRIANGLES (4) or TRIANGLE_STRIP (5)", "fan");
}

/* COLOR_0 in the Draco buffer takes the plain accessor's way: linear bytes
 * to sRGB, the same values as the tetrahedron's uncompressed COLOR_0. */
static void test_gltf_draco_colors(mts_test *t)
{
    const uint8_t u8[4][3] = {{255, 0, 0}, {0, 255, 0}, {128, 51, 13}, {0, 0, 255}};
    mts_draco_mesh in = {4, 4, &tet_pos[0][0], NULL, &tet_tri[0][0], &u8[0][0], NULL};
    mts_draco_options o = {0};
    uint8_t *draco = NULL;
    size_t dn = 0;
    mts_error err = {0};
    mts_result r = mts_draco_encode(&in, &o, &draco, &dn, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return;
    buf json = {0}, glb = {0}, plain = {0};
    /* the encoder adds POSITION (unique id 0), then COLOR (1) */
    buf_printf(&json,
               "{\"asset\":{\"version\":\"2.0\"},\"scenes\":[{\"nodes\":[0]}],"
               "\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"extensions\":"
               "{\"KHR_draco_mesh_compression\":{\"bufferView\":0,\"attributes\":"
               "{\"POSITION\":0,\"COLOR_0\":1}}},\"indices\":2,"
               "\"attributes\":{\"POSITION\":0,\"COLOR_0\":1}}]}],");
    buf_printf(&json,
               "\"accessors\":[{\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"},"
               "{\"componentType\":5121,\"normalized\":true,\"count\":4,\"type\":\"VEC3\"},"
               "{\"componentType\":5125,\"count\":12,\"type\":\"SCALAR\"}],"
               "\"bufferViews\":[{\"buffer\":0,\"byteLength\":%zu}],"
               "\"buffers\":[{\"byteLength\":%zu}]}",
               dn, dn);
    glb_pack(&glb, &json, draco, dn);
    tet_glb(&plain, "VEC3", 5121, 1, u8, sizeof u8);
    mts_gltf_mesh d = {0}, p = {0};
    r = mts_gltf_read("tet_draco.glb", glb.d, glb.n, NULL, 0, &d, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    mts_result r2 = mts_gltf_read("tet.glb", plain.d, plain.n, NULL, 0, &p, &err);
    CHECKF(t, r2 == MTS_OK, "%s", err.msg);
    if (r == MTS_OK && r2 == MTS_OK) {
        CHECKF(t, d.vertex_count == 4 && d.triangle_count == 4 && d.colors && p.colors,
               "%u v %u t", d.vertex_count, d.triangle_count);
        /* Edgebreaker may renumber: matched by position (14-bit grid) */
        for (uint32_t i = 0; d.colors && p.colors && i < d.vertex_count; i++) {
            int match = -1;
            for (int v = 0; v < 4; v++) {
                double s = 0;
                for (int k = 0; k < 3; k++)
                    s += fabs(d.positions[3 * i + k] - tet_pos[v][k]);
                if (s < 1e-3)
                    match = v;
            }
            CHECKF(t, match >= 0, "Draco vertex %u is no tetrahedron vertex", i);
            if (match >= 0)
                CHECKF(t, !memcmp(d.colors + 3 * i, p.colors + 3 * match, 12),
                       "vertex %u: %g %g %g, plain %g %g %g", i, d.colors[3 * i],
                       d.colors[3 * i + 1], d.colors[3 * i + 2], p.colors[3 * match],
                       p.colors[3 * match + 1], p.colors[3 * match + 2]);
        }
    }
    mts_gltf_mesh_free(&d);
    mts_gltf_mesh_free(&p);
    buf_free(&json);
    buf_free(&glb);
    buf_free(&plain);
    free(draco);
}

static void test_cow(mts_test *t)
{
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = mts_mesh_load("tests/data/cow.off", NULL, &m, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return;
    CHECKF(t, m.vertex_count == 2904 && m.triangle_count == 5804, "%u %u", m.vertex_count,
           m.triangle_count);
    CHECK(t, st.file_vertices == 2904 && st.file_faces == 5804);
    CHECK(t, st.degenerate_faces == 0 && st.duplicate_faces == 0 && st.nonmanifold_faces == 0);
    CHECK(t, st.unreferenced_vertices == 0 && st.normals_from_file == 0);
    CHECK(t, all_unit(&m));
    /* the first face as in the file */
    CHECK(t, tri_equal(m.triangles, 251, 210, 250));
    mts_mesh_free(&m);
}

static void test_bunny(mts_test *t)
{
    char buf_path[512];
    const char *path = mts_test_model("bunny00.off", buf_path, sizeof buf_path);
    if (!path)
        SKIP(t, "%s not found (set MTS_MODELS)", buf_path);
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    double best = 1e9;
    for (int rep = 0; rep < 3; rep++) {
        double t0 = mts_clock_seconds();
        mts_result r = mts_mesh_load(path, NULL, &m, &st, &err);
        double dt = mts_clock_seconds() - t0;
        best = dt < best ? dt : best;
        CHECKF(t, r == MTS_OK, "%s", err.msg);
        if (r != MTS_OK)
            return;
        if (rep < 2)
            mts_mesh_free(&m);
    }
    CHECK(t, st.file_vertices == 37706 && st.file_faces == 75408);
    CHECKF(t, m.vertex_count == 37706 && m.triangle_count == 75408,
           "%u v %u t (degenerate %u duplicate %u non-manifold %u unreferenced %u)",
           m.vertex_count, m.triangle_count, st.degenerate_faces, st.duplicate_faces,
           st.nonmanifold_faces, st.unreferenced_vertices);
    CHECK(t, all_unit(&m));
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  bunny00.off: %u v, %u t in %.1f ms\n", m.vertex_count,
                m.triangle_count, best * 1e3);
    mts_mesh_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_off_tetrahedron);
    RUN(&t, test_off_cube_quads);
    RUN(&t, test_off_variants);
    RUN(&t, test_off_binary);
    RUN(&t, test_obj_cube);
    RUN(&t, test_obj_normals_partial);
    RUN(&t, test_ply_cube);
    RUN(&t, test_ply_tet_types);
    RUN(&t, test_stl);
    RUN(&t, test_ply_colors);
    RUN(&t, test_off_colors);
    RUN(&t, test_off_binary_colors);
    RUN(&t, test_obj_colors);
    RUN(&t, test_gltf_colors);
    RUN(&t, test_gltf_draco_engine);
    RUN(&t, test_gltf_draco_hostile);
    RUN(&t, test_gltf_draco_colors);
    RUN(&t, test_cleaning);
    RUN(&t, test_compute_normals);
    RUN(&t, test_error_files);
    RUN(&t, test_error_truncated);
    RUN(&t, test_error_huge_counts);
    RUN(&t, test_error_corrupt);
    RUN(&t, test_off_binary_errors);
    RUN(&t, test_messages_quote_nothing);
    RUN(&t, test_not_a_file);
    RUN(&t, test_refused_from_head);
    RUN(&t, test_robust);
    RUN(&t, test_detection);
    RUN(&t, test_foreign_text);
    RUN(&t, test_lenient);
    RUN(&t, test_scan_float);
    RUN(&t, test_cow);
    RUN(&t, test_off_binary_openmesh);
    RUN(&t, test_bunny);
    return mts_test_end(&t);
}
