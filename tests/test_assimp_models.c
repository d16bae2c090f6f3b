/* Real files: every OFF, OBJ, PLY, STL, glTF and GLB file of Debian's assimp-testmodels
 * (the files assimp's own tests read: exporters' quirks, UTF-16 text, point
 * clouds, broken files) either builds into a model that verifies, through
 * the library calls mts-build makes, and streams to its checksum, or is
 * refused with a message that names the problem. The files expected to be refused are listed below with
 * the words their message must contain; every other file must build, so a
 * reader that starts refusing a real file fails here.
 *
 * The files are looked for in $MTS_ASSIMP_MODELS, else where the package
 * puts them (/usr/share/assimp/models). Without them the test skips, saying
 * so, unless MTS_TEST_REQUIRE_ASSIMP is set (CI: deps.sh installs the
 * package), where a skip is a failure. */
#define _XOPEN_SOURCE 700 /* nftw */
#include <ftw.h>
#include <stdint.h>
#include <strings.h>

#include "build.h"
#include "clock.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "test_proc.h"
#include "verify.h"

#define DEFAULT_DIR "/usr/share/assimp/models"
/* Files over this are skipped (with a line saying so) to keep the test to
 * seconds under ASan; the package's largest mesh file is 2.1 MB. */
#define MAX_FILE_BYTES ((long long)8 << 20)
#define MAX_FILES 256

/* Refused, by path under the models folder, and what the message must say. */
static const struct {
    const char *path, *reason;
} refused[] = {
    {"OBJ/box_UTF16BE.obj", "the file is UTF-16 (big-endian), not ASCII OBJ"},
    /* "3.1+e2" and the like: not numbers (assimp's lenient atof reads 3.1) */
    {"OBJ/number_formats.obj", "line 11: bad number"},
    {"OBJ/point_cloud.obj", "no triangles: the file has 3 vertices but no faces (a point cloud"},
    {"OBJ/testline.obj", "6 lines ('l') but no faces"},
    {"OBJ/testpoints.obj", "6 points ('p') and 0 lines ('l') but no faces"},
    {"OFF/invalid.off", "line 7: face 1: vertex index 20 out of range (3 vertices)"},
    /* a list of indices in the vertex element, no face element */
    {"PLY/issue623.ply", "no triangles: the PLY file has no face element with vertex_indices"},
    {"PLY/points.ply", "no triangles: the PLY file has no face element with vertex_indices"},
    {"PLY/pond.0.ply", "no triangles: the PLY file has no face element with vertex_indices"},
    {"invalid/OutOfMemory.off", "a vertex count of 353535235358 is over the limit"},
    {"invalid/empty.obj", "empty file"},
    {"invalid/empty.off", "empty file"},
    {"invalid/empty.ply", "empty file"},
    {"invalid/malformed.obj", "line 23: vertex index 12 out of range (8 defined)"},
    /* glTF 2.0: the invalid files assimp's tests name, and files of no surface */
    {"glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
     "mesh 0 primitive 0: position 0 is not a finite number (infinite or NaN)"},
    {"glTF2/IncorrectVertexArrays/Cube.gltf",
     "mesh 1 primitive 0: a TRIANGLES primitive of 35 vertices, not a multiple of 3"},
    {"glTF2/IndexOutOfRange/AllIndicesOutOfRange.gltf",
     "mesh 0 primitive 0: index 0 is 65535, out of range (24 vertices)"},
    {"glTF2/IndexOutOfRange/IndexOutOfRange.gltf",
     "mesh 0 primitive 0: index 0 is 255, out of range (24 vertices)"},
    {"glTF2/MissingBin/BoxTextured.gltf", "an external buffer file the model names is missing"},
    /* its "scene" of the wrong type is ignored; its buffer is missing too */
    {"glTF2/SchemaFailures/sceneWrongType.gltf",
     "an external buffer file the model names is missing"},
    {"glTF2/RecursiveNodes/RecursiveNodes.gltf",
     "node 0 is its own ancestor (the node hierarchy has a cycle)"},
    {"glTF2/TestNoRootNode/NoScene.gltf", "no triangles: the scene has no triangle primitives"},
    {"glTF2/TestNoRootNode/SceneWithoutNodes.gltf",
     "no triangles: the scene has no triangle primitives"},
    {"glTF2/wrongTypes/badArray.gltf", "no triangles: the scene has no triangle primitives"},
#define GEN_MODE "glTF2/glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_"
#define POINTS_ONLY "no triangles: the scene has 1 point and 0 line primitives but no triangle"
#define LINES_ONLY "no triangles: the scene has 0 point and 1 line primitives but no triangle"
    {GEN_MODE "00.gltf", POINTS_ONLY},
    {GEN_MODE "01.gltf", LINES_ONLY},
    {GEN_MODE "02.gltf", LINES_ONLY},
    {GEN_MODE "03.gltf", LINES_ONLY},
    {GEN_MODE "07.gltf", POINTS_ONLY},
    {GEN_MODE "08.gltf", LINES_ONLY},
    {GEN_MODE "09.gltf", LINES_ONLY},
    {GEN_MODE "10.gltf", LINES_ONLY},
};

/* Built, with header lines skipped (and counted for mts-build's warning). */
static const struct {
    const char *path;
    uint32_t lines, first;
} skipped_lines[] = {
    {"PLY/Wuson.ply", 1, 3}, /* Blender 2.47: "Created by Blender3D 247 ..." */
};

/* Built with vertex colours: every file whose vertices all have one (and
 * no other file: a reader that starts reading colours where there are
 * none fails here too). */
static const char *const colored[] = {
    "OBJ/cube_with_vertexcolors.obj", /* v x y z r g b */
    "OBJ/cube_with_vertexcolors_uni.obj",
    "PLY/float-color.ply", /* float red green blue alpha, VCGLIB */
};

static int listed_colored(const char *rel)
{
    for (size_t i = 0; i < sizeof colored / sizeof colored[0]; i++)
        if (!strcmp(colored[i], rel))
            return 1;
    return 0;
}

static char bin_dir[512];
static char *files[MAX_FILES];
static size_t file_count;
static int too_many;

static int has_mesh_ext(const char *path)
{
    const char *dot = strrchr(path, '.');
    if (!dot || strchr(dot, '/'))
        return 0;
    return !strcasecmp(dot, ".obj") || !strcasecmp(dot, ".ply") || !strcasecmp(dot, ".off") ||
           !strcasecmp(dot, ".stl") || !strcasecmp(dot, ".gltf") || !strcasecmp(dot, ".glb");
}

static int collect(const char *path, const struct stat *sb, int type, struct FTW *ftw)
{
    (void)sb;
    (void)ftw;
    if (type != FTW_F || !has_mesh_ext(path))
        return 0;
    if (file_count == MAX_FILES) {
        too_many = 1;
        return 0;
    }
    files[file_count++] = strdup(path);
    return 0;
}

static int by_name(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Refused, every file under a folder. */
static const struct {
    const char *prefix;
    const char *reason;
} refused_under[] = {
    {"glTF/", "glTF 1.0 is not supported"}, /* assimp's glTF (1.0) folder */
};

static const char *refusal_reason(const char *rel)
{
    for (size_t i = 0; i < sizeof refused_under / sizeof refused_under[0]; i++)
        if (!strncmp(refused_under[i].prefix, rel, strlen(refused_under[i].prefix)))
            return refused_under[i].reason;
    for (size_t i = 0; i < sizeof refused / sizeof refused[0]; i++)
        if (!strcmp(refused[i].path, rel))
            return refused[i].reason;
    return NULL;
}

/* The model's stream, what a connection for the full level is sent, fed to
 * a fresh client in small pieces: it must end at the full level with the
 * server's checksum, as END states it. */
static mts_result stream_one(const mts_model *model, mts_error *err)
{
    mts_stream s;
    mts_result r = mts_stream_build(model, "m", NULL, &s, err);
    if (r != MTS_OK)
        return r;
    const uint32_t n = mts_stream_stop_level(&s, MTS_STOP_FULL, 0);
    mts_buf b = {0};
    size_t off, len;
    mts_stream_put_model_info(&s, n, &b);
    r = mts_stream_range(&s, 0, n, &off, &len, err);
    if (r == MTS_OK) {
        mts_buf_put(&b, s.bytes + off, len);
        mts_stream_put_end(&s, n, (uint32_t)b.size, &b);
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_test_events ev = {0};
        r = mts_test_feed(&c, b.data, b.size, n, 977, &ev, err);
        if (r == MTS_OK && !(ev.end == 1 && c.have_lod && c.lod.level == n &&
                             c.checksum == s.level_checksum[n] && c.end_checksum == c.checksum))
            r = mts_error_set(err, MTS_ERR_FORMAT,
                              "streamed to level %u of %u, checksum %016llx, the server's %016llx",
                              c.have_lod ? c.lod.level : 0, n, (unsigned long long)c.checksum,
                              (unsigned long long)s.level_checksum[n]);
        mts_stream_client_free(&c);
    }
    mts_buf_free(&b);
    mts_stream_free(&s);
    return r;
}

/* Loads, builds, verifies and streams one file as mts-build and a client
 * would; 0 with the model's size in *vertices / *triangles, else the error
 * in err. */
static mts_result build_one(const char *path, mts_mesh_stats *st, uint32_t *vertices,
                            uint32_t *triangles, int *colors, mts_error *err)
{
    mts_mesh mesh = {0};
    mts_model model = {0};
    mts_build_report rep;
    mts_result r = mts_mesh_load(path, NULL, &mesh, st, err);
    if (r != MTS_OK)
        return r;
    mts_build_options bo = {0};
    bo.threads = 1; /* two cores shared by the whole test run */
    r = mts_build_model(&mesh, path, &bo, &model, &rep, err);
    if (r == MTS_OK) {
        mts_verify_options vo = {0}; /* every level: these models are small */
        mts_verify_report vr;
        r = mts_verify_model(&model, &vo, &vr, err);
        if (r == MTS_OK)
            r = mts_verify_growth(&model, &vr, err);
        if (r == MTS_OK)
            r = stream_one(&model, err);
        *vertices = model.vertex_count;
        *triangles = model.level_triangles[model.level_count];
        *colors = model.colors != NULL && (model.flags & MTS_MODEL_COLORS);
    }
    mts_model_free(&model);
    mts_mesh_free(&mesh);
    return r;
}

/* The models folder, or NULL after skipping (or failing, where the files
 * are required) with the reason. */
static const char *models_dir(mts_test *t)
{
    const char *dir = getenv("MTS_ASSIMP_MODELS");
    if (!dir || !*dir)
        dir = DEFAULT_DIR;
    struct stat ds;
    if (stat(dir, &ds) == 0 && S_ISDIR(ds.st_mode))
        return dir;
    CHECKF(t, !getenv("MTS_TEST_REQUIRE_ASSIMP"),
           "MTS_TEST_REQUIRE_ASSIMP is set and there is no %s (apt-get install "
           "assimp-testmodels; scripts/deps.sh does)", dir);
    if (!t->case_failed) {
        fprintf(stderr, "  SKIP %s: no %s: apt-get install assimp-testmodels (scripts/deps.sh), "
                        "or set MTS_ASSIMP_MODELS\n", t->case_name, dir);
        t->case_skipped = 1;
    }
    return NULL;
}

static void test_assimp_models(mts_test *t)
{
    const char *dir = models_dir(t);
    if (!dir)
        return;
    CHECKF(t, nftw(dir, collect, 16, FTW_PHYS) == 0, "cannot walk %s", dir);
    CHECKF(t, !too_many, "more than %d mesh files under %s", MAX_FILES, dir);
    CHECKF(t, file_count > 0, "no .obj .ply .off .stl .gltf .glb file under %s", dir);
    qsort(files, file_count, sizeof *files, by_name);

    double t0 = mts_clock_seconds();
    size_t dir_len = strlen(dir);
    unsigned built = 0, refused_ok = 0, skipped = 0;
    for (size_t i = 0; i < file_count; i++) {
        const char *path = files[i];
        const char *rel = path + dir_len + (path[dir_len] == '/');
        struct stat fs;
        if (stat(path, &fs) == 0 && (long long)fs.st_size > MAX_FILE_BYTES) {
            printf("  skipped %s: %lld bytes, over the test's %lld\n", rel,
                   (long long)fs.st_size, MAX_FILE_BYTES);
            skipped++;
            continue;
        }
        const char *reason = refusal_reason(rel);
        mts_mesh_stats st = {0};
        mts_error err = {0};
        uint32_t nv = 0, nt = 0;
        int colors = 0;
        double f0 = mts_clock_seconds();
        mts_result r = build_one(path, &st, &nv, &nt, &colors, &err);
        double secs = mts_clock_seconds() - f0;
        if (r == MTS_OK) {
            printf("  built   %-40s %6u vertices %6u triangles %5.2f s%s\n", rel, nv, nt, secs,
                   colors ? " colours" : "");
            CHECKF(t, colors == listed_colored(rel), "%s built %s colours", rel,
                   colors ? "with" : "without");
            CHECKF(t, !reason, "%s built, but is listed as refused (\"%s\")", rel, reason);
            built++;
        } else {
            printf("  refused %-40s %s\n", rel, err.msg);
            CHECKF(t, reason, "%s is refused and should build: %s", rel, err.msg);
            CHECKF(t, r != MTS_ERR_INVARIANT && r != MTS_ERR_NOMEM,
                   "%s: the model did not verify or memory ran out: %s", rel, err.msg);
            /* the message names the file and the problem, never the bare
             * "0 faces read" of a file that had none */
            CHECKF(t, strstr(err.msg, path) != NULL, "%s: the message lacks the path: %s", rel,
                   err.msg);
            CHECKF(t, !strstr(err.msg, "(0 faces read"), "%s: %s", rel, err.msg);
            CHECKF(t, !reason || strstr(err.msg, reason), "%s: '%s' lacks '%s'", rel, err.msg,
                   reason ? reason : "");
            refused_ok += reason && strstr(err.msg, reason);
        }
        uint32_t want_lines = 0, want_first = 0;
        for (size_t k = 0; k < sizeof skipped_lines / sizeof skipped_lines[0]; k++)
            if (!strcmp(skipped_lines[k].path, rel)) {
                want_lines = skipped_lines[k].lines;
                want_first = skipped_lines[k].first;
            }
        if (r == MTS_OK || want_lines)
            CHECKF(t, st.skipped_header_lines == want_lines &&
                          (!want_lines || st.first_skipped_header_line == want_first),
                   "%s: %u header lines skipped (the first at %u), expected %u (at %u)", rel,
                   st.skipped_header_lines, st.first_skipped_header_line, want_lines,
                   want_first);
    }
    /* a newer package may drop or rename a listed file: said, not failed */
    for (size_t k = 0; k < sizeof refused / sizeof refused[0]; k++) {
        int found = 0;
        for (size_t i = 0; i < file_count && !found; i++)
            found = !strcmp(files[i] + dir_len + (files[i][dir_len] == '/'), refused[k].path);
        if (!found)
            printf("  note: %s (listed as refused) is not in %s\n", refused[k].path, dir);
    }
    printf("  %zu files: %u built, %u refused as listed, %u skipped, %.1f s\n", file_count,
           built, refused_ok, skipped, mts_clock_seconds() - t0);
    for (size_t i = 0; i < file_count; i++)
        free(files[i]);
}

/* What mts-build shows of it: the warning of a skipped header line (on
 * stderr, with --json's one line on stdout) and a refusal's message. */
static void test_mts_build(mts_test *t)
{
    const char *dir = models_dir(t);
    if (!dir)
        return;
    char cmd[2048], out[8192], model[600];
    snprintf(model, sizeof model, "%s/mts_test_assimp_wuson.mtsm", mts_test_tmpdir());
    snprintf(cmd, sizeof cmd, "%s/mts-build %s/PLY/Wuson.ply -o %s --json --threads 1", bin_dir,
             dir, model);
    int rc = mts_test_run(cmd, out, sizeof out);
    CHECKF(t, rc == 0, "%s: exit %d: %s", cmd, rc, out);
    char want[800];
    snprintf(want, sizeof want, "mts-build: warning: %s/PLY/Wuson.ply: skipped 1 header line that "
                                "is no PLY keyword (line 3)\n", dir);
    CHECKF(t, strstr(out, want), "%s: %s", cmd, out);
    CHECKF(t, strstr(out, "\"header_lines\":1"), "%s: %s", cmd, out);
    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s --verify --sample 32", bin_dir, model);
    rc = mts_test_run(cmd, out, sizeof out);
    CHECKF(t, rc == 0, "%s: exit %d: %s", cmd, rc, out);
    remove(model);

    snprintf(cmd, sizeof cmd, "%s/mts-build %s/OBJ/box_UTF16BE.obj -o %s", bin_dir, dir, model);
    rc = mts_test_run(cmd, out, sizeof out);
    CHECKF(t, rc == 1 && strstr(out, "box_UTF16BE.obj: the file is UTF-16 (big-endian), not ASCII "
                                     "OBJ: save it as UTF-8 or ASCII"),
           "%s: exit %d: %s", cmd, rc, out);
    remove(model);
}

/* A glTF of one TRIANGLE_STRIP of 4 vertices, its buffer at `uri`, under a
 * node translated by (10, 0, 0). */
static int gltf_text(char *out, size_t size, const char *uri)
{
    return snprintf(out, size,
                    "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
                    "\"nodes\":[{\"mesh\":0,\"translation\":[10,0,0]}],"
                    "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"mode\":5},"
                    "{\"attributes\":{\"POSITION\":0},\"mode\":1}]}],"
                    "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":4,"
                    "\"type\":\"VEC3\"}],"
                    "\"bufferViews\":[{\"buffer\":0,\"byteLength\":48}],"
                    "\"buffers\":[{\"byteLength\":48,\"uri\":\"%s\"}]}",
                    uri);
}

/* Synthetic glTF: a data: URI read in place (strip to triangles, the node's
 * translation applied, the LINES primitive skipped and counted); external
 * buffers refused outside the model's folder and for a model from memory. */
static void test_gltf_uris(mts_test *t)
{
    char text[2048], path[600];
    gltf_text(text, sizeof text,
              "data:application/octet-stream;base64,"
              "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAACAPwAAgD8AAAAA");
    mts_mesh mesh;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result r = mts_mesh_load_memory("strip.gltf", text, strlen(text), NULL, &mesh, &st, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r == MTS_OK) {
        CHECKF(t, mesh.triangle_count == 2 && mesh.vertex_count == 4 &&
                      st.format == MTS_MESH_GLTF && st.skipped_primitives == 1,
               "%u triangles, %u vertices, %u primitives skipped", mesh.triangle_count,
               mesh.vertex_count, st.skipped_primitives);
        float xmin = 1e9f;
        for (uint32_t v = 0; v < mesh.vertex_count; v++)
            xmin = mesh.positions[v * 3] < xmin ? mesh.positions[v * 3] : xmin;
        CHECKF(t, xmin == 10.0f, "the node's translation was not applied: x from %g", xmin);
        mts_mesh_free(&mesh);
    }
    /* external buffers: never from memory, never outside the folder */
    gltf_text(text, sizeof text, "strip.bin");
    r = mts_mesh_load_memory("strip.gltf", text, strlen(text), NULL, &mesh, &st, &err);
    CHECKF(t, r != MTS_OK && strstr(err.msg, "not a local file"), "%s", err.msg);
    static const char *const bad[] = {"../strip.bin", "/etc/passwd", "sub/strip.bin",
                                      "file:///etc/passwd"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        gltf_text(text, sizeof text, bad[i]);
        snprintf(path, sizeof path, "%s/mts_test_gltf_uri.gltf", mts_test_tmpdir());
        FILE *f = fopen(path, "wb");
        CHECKF(t, f && fwrite(text, 1, strlen(text), f) == strlen(text), "cannot write %s", path);
        if (f)
            fclose(f);
        r = mts_mesh_load(path, NULL, &mesh, &st, &err);
        CHECKF(t, r != MTS_OK && strstr(err.msg, "'/', '..' or a scheme is refused") &&
                      !strstr(err.msg, bad[i]),
               "%s: %s", bad[i], err.msg);
        remove(path);
    }
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    mts_test t = {0};
    RUN(&t, test_assimp_models);
    RUN(&t, test_mts_build);
    RUN(&t, test_gltf_uris);
    return mts_test_end(&t);
}
