/* The server's model catalog and URL fetching: a models directory with good,
 * corrupt and badly named files (the good ones served, the others reported);
 * the mesh cache (reused, rebuilt when the mesh changes, never stale); model
 * name rules; URL models from a python3 http.server on 127.0.0.1, refused
 * schemes, the size cap, HTTP errors, redirects, timeouts. Network traffic goes
 * to 127.0.0.1 only. */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdint.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "clock.h"
#include "build.h"
#include "catalog.h"
#include "crc32c.h"
#include "fetch.h"
#include "mesh.h"
#include "modelfile.h"
#include "test.h"
#include "test_proc.h"

static char work[1024];  /* scratch directory of this run */
static char cow_src[] = "tests/data/cow.off";

/* ------------------------------------------------------------------------ */
/* Files                                                                     */

static int copy_file(const char *from, const char *to)
{
    FILE *in = fopen(from, "rb");
    if (!in)
        return 0;
    FILE *out = fopen(to, "wb");
    if (!out) {
        fclose(in);
        return 0;
    }
    char buf[65536];
    size_t n;
    int ok = 1;
    while ((n = fread(buf, 1, sizeof buf, in)) > 0)
        ok = ok && fwrite(buf, 1, n, out) == n;
    fclose(in);
    return (fclose(out) == 0) && ok;
}

static int write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    int ok = fputs(text, f) >= 0;
    return (fclose(f) == 0) && ok;
}

/* A closed UV sphere as an OFF file. */
static int write_sphere_off(const char *path, unsigned rings, unsigned segments)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    unsigned nv = 2 + (rings - 1) * segments, nt = 2 * segments * (rings - 1);
    fprintf(f, "OFF\n%u %u 0\n0 0 1\n", nv, nt);
    for (unsigned r = 1; r < rings; r++)
        for (unsigned s = 0; s < segments; s++) {
            double th = M_PI * r / rings, ph = 2 * M_PI * s / segments;
            fprintf(f, "%.6f %.6f %.6f\n", sin(th) * cos(ph), sin(th) * sin(ph), cos(th));
        }
    fprintf(f, "0 0 -1\n");
    unsigned south = nv - 1;
    for (unsigned s = 0; s < segments; s++) {
        unsigned s1 = (s + 1) % segments;
        fprintf(f, "3 0 %u %u\n", 1 + s, 1 + s1);
        for (unsigned r = 1; r + 1 < rings; r++) {
            unsigned a = 1 + (r - 1) * segments + s, b = 1 + (r - 1) * segments + s1;
            unsigned c = 1 + r * segments + s, d = 1 + r * segments + s1;
            fprintf(f, "3 %u %u %u\n3 %u %u %u\n", a, c, d, a, d, b);
        }
        unsigned a = 1 + (rings - 2) * segments + s, b = 1 + (rings - 2) * segments + s1;
        fprintf(f, "3 %u %u %u\n", a, south, b);
    }
    return fclose(f) == 0;
}

static int mesh_to_model_file(const char *mesh_path, const char *model_path)
{
    mts_mesh mesh = {0};
    mts_model model = {0};
    mts_error err = {0};
    int ok = mts_mesh_load(mesh_path, NULL, &mesh, NULL, &err) == MTS_OK &&
             mts_build_model(&mesh, mesh_path, NULL, &model, NULL, &err) == MTS_OK &&
             mts_modelfile_save(&model, model_path, NULL, &err) == MTS_OK;
    if (!ok)
        fprintf(stderr, "  setup: %s\n", err.msg);
    mts_model_free(&model);
    mts_mesh_free(&mesh);
    return ok;
}

static int file_mtime(const char *path, struct timespec *ts)
{
    struct stat st;
    if (stat(path, &st) != 0)
        return 0;
    *ts = st.st_mtim;
    return 1;
}

static int set_mtime(const char *path, time_t sec)
{
    struct timespec ts[2] = {{sec, 0}, {sec, 0}};
    return utimensat(AT_FDCWD, path, ts, 0) == 0;
}


/* ------------------------------------------------------------------------ */
/* Reports                                                                   */

typedef struct report_line {
    mts_catalog_report_kind kind;
    char file[512];
    char msg[1024];
} report_line;

typedef struct reports {
    report_line lines[64];
    int count;
} reports;

static void collect(void *user, mts_catalog_report_kind kind, const char *file, const char *msg)
{
    reports *r = user;
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "    report %d %s: %s\n", (int)kind, file, msg);
    if (r->count >= 64)
        return;
    report_line *l = &r->lines[r->count++];
    l->kind = kind;
    snprintf(l->file, sizeof l->file, "%s", file);
    snprintf(l->msg, sizeof l->msg, "%s", msg);
}

/* The first report of this kind about a file whose path ends in file_end. */
static const report_line *find_report(const reports *r, mts_catalog_report_kind kind,
                                      const char *file_end)
{
    size_t n = strlen(file_end);
    for (int i = 0; i < r->count; i++) {
        size_t m = strlen(r->lines[i].file);
        if (r->lines[i].kind == kind && m >= n && !strcmp(r->lines[i].file + m - n, file_end))
            return &r->lines[i];
    }
    return NULL;
}

static int count_kind(const reports *r, mts_catalog_report_kind kind)
{
    int n = 0;
    for (int i = 0; i < r->count; i++)
        n += r->lines[i].kind == kind;
    return n;
}

typedef struct progress_count {
    int calls;
    int named; /* stages that start with "cow: " */
} progress_count;

static void count_progress(void *user, const char *stage, double done)
{
    progress_count *p = user;
    p->calls++;
    if (!strncmp(stage, "cow: ", 5) && done >= 0 && done <= 1)
        p->named++;
}

/* One catalog over dir, with its reports. */
static mts_catalog *open_dir(mts_test *t, const char *dir, const mts_catalog_options *opts,
                             reports *rep, unsigned *failed)
{
    mts_catalog *cat = NULL;
    mts_error err = {0};
    memset(rep, 0, sizeof *rep);
    mts_result rc = mts_catalog_create(opts, &cat, &err);
    CHECKF(t, rc == MTS_OK, "create: %s", err.msg);
    if (rc != MTS_OK)
        return NULL;
    mts_catalog_report cb = {collect, rep};
    rc = mts_catalog_add_dir(cat, dir, &cb, failed, &err);
    CHECKF(t, rc == MTS_OK, "add_dir: %s", err.msg);
    return cat;
}

/* ------------------------------------------------------------------------ */
/* The models directory                                                      */

static char models[1100]; /* work/models: cow.off, ball.mtsm, ball.off, broken.off, ... */

static int setup_models(void)
{
    char p[1300], sphere[1300];
    snprintf(models, sizeof models, "%s/models", work);
    if (mkdir(models, 0755) != 0)
        return 0;
    snprintf(sphere, sizeof sphere, "%s/sphere.src", work);
    int ok = write_sphere_off(sphere, 8, 10);
    snprintf(p, sizeof p, "%s/cow.off", models);
    ok = ok && copy_file(cow_src, p);
    snprintf(p, sizeof p, "%s/ball.mtsm", models);
    ok = ok && mesh_to_model_file(sphere, p);
    snprintf(p, sizeof p, "%s/ball.off", models); /* shadowed by ball.mtsm */
    ok = ok && copy_file(sphere, p);
    snprintf(p, sizeof p, "%s/broken.off", models); /* truncated: 3 vertices promised */
    ok = ok && write_text(p, "OFF\n3 1 0\n0 0 0\n1 0 0\n");
    snprintf(p, sizeof p, "%s/bad name.off", models);
    ok = ok && copy_file(sphere, p);
    snprintf(p, sizeof p, "%s/Sphere2.OFF", models); /* upper-case extension */
    ok = ok && copy_file(sphere, p);
    snprintf(p, sizeof p, "%s/Sphere2.off", models); /* same name: skipped */
    ok = ok && copy_file(sphere, p);
    snprintf(p, sizeof p, "%s/ball2.mtsm", models); /* a truncated model file: */
    ok = ok && write_text(p, "MTSM");
    snprintf(p, sizeof p, "%s/ball2.off", models); /* the mesh of its name is served */
    ok = ok && copy_file(sphere, p);
    snprintf(p, sizeof p, "%s/README.txt", models); /* not a model: ignored */
    ok = ok && write_text(p, "not a model\n");
    return ok;
}

static void test_models_dir(mts_test *t)
{
    reports rep;
    unsigned failed = 99;
    progress_count pc = {0};
    mts_catalog_options o = {0};
    o.progress.fn = count_progress;
    o.progress.user = &pc;
    mts_catalog *cat = open_dir(t, models, &o, &rep, &failed);
    if (!cat)
        return;
    CHECKF(t, mts_catalog_count(cat) == 4, "%zu models", mts_catalog_count(cat));
    /* listed in name order */
    const char *want[] = {"Sphere2", "ball", "ball2", "cow"};
    for (size_t i = 0; i < 4 && i < mts_catalog_count(cat); i++)
        CHECKF(t, !strcmp(mts_catalog_at(cat, i)->name, want[i]), "at %zu: %s", i,
               mts_catalog_at(cat, i)->name);
    CHECK(t, mts_catalog_at(cat, 4) == NULL);

    const mts_catalog_entry *cow = mts_catalog_find(cat, "cow");
    CHECK(t, cow != NULL);
    if (cow) {
        CHECK(t, cow->origin == MTS_CATALOG_BUILT);
        CHECK(t, cow->model.vertex_count == 2904);
        CHECK(t, cow->source_bytes == 182966);
        CHECK(t, cow->cache_path != NULL);
        char want_cache[1300];
        snprintf(want_cache, sizeof want_cache, "%s/.cow.off.mtsm", models);
        CHECKF(t, cow->cache_path && !strcmp(cow->cache_path, want_cache), "cache %s",
               cow->cache_path ? cow->cache_path : "(none)");
        struct timespec ts;
        CHECK(t, file_mtime(want_cache, &ts));
    }
    const mts_catalog_entry *ball = mts_catalog_find(cat, "ball");
    CHECK(t, ball && ball->origin == MTS_CATALOG_MODEL_FILE && ball->cache_path == NULL);
    CHECK(t, ball && strstr(ball->source, "ball.mtsm") != NULL);
    const mts_catalog_entry *s2 = mts_catalog_find(cat, "Sphere2");
    CHECK(t, s2 && s2->origin == MTS_CATALOG_BUILT && strstr(s2->source, "Sphere2.OFF"));

    /* a broken model file does not hide the mesh of its name: the
     * failure is reported, the mesh is built and served, and a note says so */
    const mts_catalog_entry *b2 = mts_catalog_find(cat, "ball2");
    CHECK(t, b2 && b2->origin == MTS_CATALOG_BUILT && strstr(b2->source, "ball2.off"));
    CHECK(t, find_report(&rep, MTS_CATALOG_FAILED, "/ball2.mtsm") != NULL);
    const report_line *n2 = find_report(&rep, MTS_CATALOG_NOTE, "/ball2.off");
    CHECKF(t, n2 && strstr(n2->msg, "ball2.mtsm did not load") && !strstr(n2->msg, "not built"),
           "message: %s", n2 ? n2->msg : "(none)");

    /* the corrupt mesh: reported with its file name, nothing served */
    CHECK(t, failed == 2);
    CHECK(t, mts_catalog_find(cat, "broken") == NULL);
    const report_line *l = find_report(&rep, MTS_CATALOG_FAILED, "/broken.off");
    CHECK(t, l != NULL);
    CHECKF(t, l && strstr(l->msg, "broken.off"), "message: %s", l ? l->msg : "");
    /* the bad name: skipped with a reason */
    l = find_report(&rep, MTS_CATALOG_SKIPPED, "/bad name.off");
    CHECK(t, l != NULL);
    CHECKF(t, l && strstr(l->msg, "model name") && strstr(l->msg, "' '"), "message: %s",
           l ? l->msg : "");
    CHECK(t, mts_catalog_find(cat, "bad name") == NULL);
    /* the .mtsm wins over the mesh of the same name, with a note */
    l = find_report(&rep, MTS_CATALOG_NOTE, "/ball.off");
    CHECKF(t, l && strstr(l->msg, "ball.mtsm"), "message: %s", l ? l->msg : "(none)");
    /* two meshes of one name: the first in byte order wins */
    l = find_report(&rep, MTS_CATALOG_SKIPPED, "/Sphere2.off");
    CHECKF(t, l && strstr(l->msg, "Sphere2.OFF"), "message: %s", l ? l->msg : "(none)");
    CHECK(t, count_kind(&rep, MTS_CATALOG_ADDED) == 4);
    CHECK(t, count_kind(&rep, MTS_CATALOG_FAILED) == 2);
    /* nothing about README.txt, nothing about the cache files */
    CHECK(t, find_report(&rep, MTS_CATALOG_SKIPPED, "README.txt") == NULL);
    CHECKF(t, pc.named > 0, "%d progress calls, %d for cow", pc.calls, pc.named);

    /* requests are looked up in the table only */
    CHECK(t, mts_catalog_find(cat, "../models/cow") == NULL);
    CHECK(t, mts_catalog_find(cat, "cow.off") == NULL);
    CHECK(t, mts_catalog_find(cat, ".cow.off") == NULL);
    CHECK(t, mts_catalog_find(cat, "") == NULL);
    CHECK(t, mts_catalog_find(cat, NULL) == NULL);
    CHECK(t, mts_catalog_find_n(cat, "cowboy", 3) == cow);
    CHECK(t, mts_catalog_find_n(cat, "cow\0x", 5) == NULL);
    mts_catalog_free(cat);

    mts_error err = {0};
    CHECK(t, mts_catalog_create(NULL, &cat, &err) == MTS_OK);
    CHECK(t, mts_catalog_add_dir(cat, "/nonexistent/models", NULL, NULL, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "/nonexistent/models") != NULL, "message: %s", err.msg);
    mts_catalog_free(cat);
}

static void test_cache_reuse_and_rebuild(mts_test *t)
{
    char cow[1300], cache[1300];
    snprintf(cow, sizeof cow, "%s/cow.off", models);
    snprintf(cache, sizeof cache, "%s/.cow.off.mtsm", models);
    struct timespec before, after;
    if (!file_mtime(cache, &before))
        SKIP(t, "no cache from test_models_dir at %s", cache);

    /* a second catalog over the same directory does not rebuild */
    reports rep;
    mts_catalog *cat = open_dir(t, models, NULL, &rep, NULL);
    if (!cat)
        return;
    const mts_catalog_entry *e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_CACHED);
    CHECK(t, e && e->model.vertex_count == 2904 && e->source_bytes == 182966);
    CHECK(t, file_mtime(cache, &after) && after.tv_sec == before.tv_sec &&
                 after.tv_nsec == before.tv_nsec);
    e = mts_catalog_find(cat, "Sphere2");
    CHECK(t, e && e->origin == MTS_CATALOG_CACHED);
    mts_catalog_free(cat);

    /* the mesh touched newer than its cache: rebuilt, with a note */
    CHECK(t, set_mtime(cow, before.tv_sec + 5));
    cat = open_dir(t, models, NULL, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT);
    const report_line *l = find_report(&rep, MTS_CATALOG_NOTE, "/cow.off");
    CHECKF(t, l && strstr(l->msg, "newer"), "note: %s", l ? l->msg : "(none)");
    mts_catalog_free(cat);
    /* ... and then reused, although the mesh is dated in the future */
    cat = open_dir(t, models, NULL, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_CACHED);
    mts_catalog_free(cat);

    /* the mesh replaced by a different file dated older than the cache: the
     * cache is not served (its key no longer matches) */
    FILE *f = fopen(cow, "ab");
    CHECK(t, f && fputs("# appended\n", f) >= 0);
    if (f)
        fclose(f);
    CHECK(t, set_mtime(cow, 1000000000));
    cat = open_dir(t, models, NULL, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->source_bytes == 182966 + 11);
    l = find_report(&rep, MTS_CATALOG_NOTE, "/cow.off");
    CHECKF(t, l && strstr(l->msg, "another version"), "note: %s", l ? l->msg : "(none)");
    mts_catalog_free(cat);

    /* other build options: another model, so a rebuild */
    mts_catalog_options o = {0};
    o.base_vertices = 100;
    cat = open_dir(t, models, &o, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->model.base_vertex_count <= 100);
    mts_catalog_free(cat);

    /* a damaged cache: rebuilt, with a note, never a failure */
    CHECK(t, write_text(cache, "MTSM garbage"));
    CHECK(t, set_mtime(cache, time(NULL) + 100));
    cat = open_dir(t, models, &o, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT);
    l = find_report(&rep, MTS_CATALOG_NOTE, "/cow.off");
    CHECKF(t, l && strstr(l->msg, "does not load"), "note: %s", l ? l->msg : "(none)");
    mts_catalog_free(cat);

    /* a cache of an older model file version (its header says 1.0, with a
     * checksum that matches: what an older build left behind): rebuilt,
     * with a note naming the version, never served, never a failure; the
     * rebuilt cache is then served */
    {
        FILE *f = fopen(cache, "r+b");
        uint8_t head[16 + 24 * 64];
        size_t got = f ? fread(head, 1, sizeof head, f) : 0;
        uint32_t count = got >= 16 ? (uint32_t)head[8] | (uint32_t)head[9] << 8 |
                                         (uint32_t)head[10] << 16 | (uint32_t)head[11] << 24
                                   : 0;
        CHECK(t, f && got >= 16 && count >= 1 && count <= 64 && got >= 16 + 24 * (size_t)count);
        if (f && count >= 1 && count <= 64 && got >= 16 + 24 * (size_t)count) {
            head[4] = 1; /* u16 major = 1, minor = 0 */
            head[5] = head[6] = head[7] = 0;
            uint32_t crc = mts_crc32c(0, head, 12);
            crc = mts_crc32c(crc, head + 16, 24 * (size_t)count);
            for (int i = 0; i < 4; i++)
                head[12 + i] = (uint8_t)(crc >> (8 * i));
            CHECK(t, fseek(f, 0, SEEK_SET) == 0 && fwrite(head, 1, 16, f) == 16);
        }
        CHECK(t, f && fclose(f) == 0);
    }
    CHECK(t, set_mtime(cache, time(NULL) + 100));
    cat = open_dir(t, models, &o, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT);
    l = find_report(&rep, MTS_CATALOG_NOTE, "/cow.off");
    CHECKF(t, l && strstr(l->msg, "does not load") && strstr(l->msg, "version 1"), "note: %s",
           l ? l->msg : "(none)");
    mts_catalog_free(cat);
    cat = open_dir(t, models, &o, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_CACHED);
    mts_catalog_free(cat);

    /* no_cache: built, nothing read or written */
    o.no_cache = 1;
    CHECK(t, file_mtime(cache, &before));
    cat = open_dir(t, models, &o, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->cache_path == NULL);
    CHECK(t, file_mtime(cache, &after) && after.tv_sec == before.tv_sec &&
                 after.tv_nsec == before.tv_nsec);
    mts_catalog_free(cat);
}

/* A coloured mesh whose cache an older builder wrote (no colours, the key
 * without the model file's minor version): rebuilt with its colours, with a
 * note, never served grey. */
static void test_cache_from_before_colors(mts_test *t)
{
    char dir[1300], mesh[1400], cache[1400];
    snprintf(dir, sizeof dir, "%s/colored", work);
    CHECK(t, mkdir(dir, 0755) == 0);
    snprintf(mesh, sizeof mesh, "%s/ccow.ply", dir);
    snprintf(cache, sizeof cache, "%s/.ccow.ply.mtsm", dir);
    CHECK(t, copy_file("tests/data/cow_colors.ply", mesh));

    reports rep;
    mts_catalog *cat = open_dir(t, dir, NULL, &rep, NULL);
    if (!cat)
        return;
    const mts_catalog_entry *e = mts_catalog_find(cat, "ccow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->model.colors &&
                 (e->model.flags & MTS_MODEL_COLORS));
    mts_catalog_free(cat);

    /* what a builder before colours left: the same model less its colours,
     * keyed "mtsm 5: " */
    mts_model m = {0};
    mts_error err = {0};
    CHECKF(t, mts_modelfile_load(cache, &m, &err) == MTS_OK, "%s", err.msg);
    char *v = strstr(m.build_key, "mtsm 5.");
    CHECKF(t, v != NULL, "key %s", m.build_key);
    if (v) {
        char *colon = strchr(v, ':');
        if (colon)
            memmove(v + 6, colon, strlen(colon) + 1);
    }
    free(m.colors);
    m.colors = NULL;
    m.flags &= ~MTS_MODEL_COLORS;
    CHECKF(t, mts_modelfile_save(&m, cache, NULL, &err) == MTS_OK, "%s", err.msg);
    mts_model_free(&m);
    CHECK(t, set_mtime(cache, time(NULL) + 100));

    cat = open_dir(t, dir, NULL, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "ccow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->model.colors &&
                 (e->model.flags & MTS_MODEL_COLORS));
    const report_line *l = find_report(&rep, MTS_CATALOG_NOTE, "/ccow.ply");
    CHECKF(t, l && strstr(l->msg, "another version"), "note: %s", l ? l->msg : "(none)");
    mts_catalog_free(cat);
    /* ... and the rebuilt cache, coloured, is served from then on */
    cat = open_dir(t, dir, NULL, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "ccow");
    CHECK(t, e && e->origin == MTS_CATALOG_CACHED && e->model.colors);
    mts_catalog_free(cat);
}

static void test_cache_dir_option(mts_test *t)
{
    char dir[1300], cache_dir[1300], p[1400];
    snprintf(dir, sizeof dir, "%s/ro", work);
    snprintf(cache_dir, sizeof cache_dir, "%s/cache", work);
    CHECK(t, mkdir(dir, 0755) == 0);
    snprintf(p, sizeof p, "%s/cow.off", dir);
    CHECK(t, copy_file(cow_src, p));

    mts_catalog_options o = {0};
    o.cache_dir = cache_dir; /* made when missing */
    reports rep;
    mts_catalog *cat = open_dir(t, dir, &o, &rep, NULL);
    if (!cat)
        return;
    const mts_catalog_entry *e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->cache_path);
    CHECK(t, e && e->cache_path && !strncmp(e->cache_path, cache_dir, strlen(cache_dir)) &&
                 e->cache_path[strlen(cache_dir)] == '/' &&
                 e->cache_path[strlen(cache_dir) + 1] == '.');
    mts_catalog_free(cat);
    cat = open_dir(t, dir, &o, &rep, NULL);
    if (!cat)
        return;
    e = mts_catalog_find(cat, "cow");
    CHECK(t, e && e->origin == MTS_CATALOG_CACHED);
    mts_catalog_free(cat);
    /* nothing was written beside the mesh */
    snprintf(p, sizeof p, "%s/.cow.off.mtsm", dir);
    struct stat st;
    CHECK(t, stat(p, &st) != 0);

    /* a cache dir that is a file */
    mts_error err = {0};
    o.cache_dir = cow_src;
    CHECK(t, mts_catalog_create(&o, &cat, &err) == MTS_ERR_IO && cat == NULL);
    CHECKF(t, strstr(err.msg, cow_src) != NULL, "message: %s", err.msg);

}

/* A models directory that is not writable: the cache goes to a private
 * directory under $TMPDIR, and only when that one is safe to use. */
static void test_cache_readonly_dir(mts_test *t)
{
    if (geteuid() == 0)
        SKIP(t, "running as root: a read-only directory is still writable");
    char dir[1300], tmp[1300], p[1400];
    snprintf(dir, sizeof dir, "%s/ro2", work);
    snprintf(tmp, sizeof tmp, "%s/tmpdir", work);
    CHECK(t, mkdir(dir, 0755) == 0 && mkdir(tmp, 0755) == 0);
    snprintf(p, sizeof p, "%s/cow.off", dir);
    CHECK(t, copy_file(cow_src, p));
    CHECK(t, chmod(dir, 0555) == 0);
    const char *old_tmp = getenv("TMPDIR");
    char saved[1024] = "";
    if (old_tmp)
        snprintf(saved, sizeof saved, "%s", old_tmp);
    setenv("TMPDIR", tmp, 1);

    reports rep;
    mts_catalog *cat = open_dir(t, dir, NULL, &rep, NULL);
    if (cat) {
        const mts_catalog_entry *e = mts_catalog_find(cat, "cow");
        CHECK(t, e && e->origin == MTS_CATALOG_BUILT);
        CHECKF(t, e && e->cache_path && !strncmp(e->cache_path, tmp, strlen(tmp)) &&
                      strstr(e->cache_path, "/mtstream-cache-"),
               "cache %s", e && e->cache_path ? e->cache_path : "(none)");
        mts_catalog_free(cat);
    }
    cat = open_dir(t, dir, NULL, &rep, NULL);
    if (cat) {
        const mts_catalog_entry *e = mts_catalog_find(cat, "cow");
        CHECK(t, e && e->origin == MTS_CATALOG_CACHED);
        mts_catalog_free(cat);
    }
    /* a cache directory others may write to is not used: built, not cached, a note */
    snprintf(p, sizeof p, "%s/mtstream-cache-%lu", tmp, (unsigned long)geteuid());
    CHECK(t, chmod(p, 0777) == 0);
    cat = open_dir(t, dir, NULL, &rep, NULL);
    if (cat) {
        const mts_catalog_entry *e = mts_catalog_find(cat, "cow");
        CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->cache_path == NULL);
        const report_line *l = find_report(&rep, MTS_CATALOG_NOTE, "/cow.off");
        CHECKF(t, l && strstr(l->msg, "not cached"), "note: %s", l ? l->msg : "(none)");
        mts_catalog_free(cat);
    }
    if (old_tmp)
        setenv("TMPDIR", saved, 1);
    else
        unsetenv("TMPDIR");
    chmod(dir, 0755);
}

/* ------------------------------------------------------------------------ */
/* Names and single models                                                   */

static void test_names(mts_test *t)
{
    char long_name[80];
    memset(long_name, 'a', 65);
    long_name[65] = 0;
    const char *bad[] = {"../x", "a/b", "", ".hidden", "..", "a b", "x\n", "a\\b", "c:d",
                         "%2e%2e", long_name, "caf\xc3\xa9"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        mts_error err = {0};
        CHECKF(t, mts_catalog_check_name(bad[i], &err) == MTS_ERR_ARG, "accepted \"%s\"", bad[i]);
        CHECK(t, err.msg[0] != 0);
        CHECK(t, !mts_catalog_name_valid(bad[i]));
    }
    CHECK(t, !mts_catalog_name_valid(NULL));
    long_name[64] = 0;
    const char *good[] = {"cow", "a.b-c_D9", "x.", "-", long_name, "bunny00"};
    for (size_t i = 0; i < sizeof good / sizeof good[0]; i++)
        CHECKF(t, mts_catalog_name_valid(good[i]), "refused \"%s\"", good[i]);

    mts_error err = {0};
    CHECK(t, mts_catalog_check_name("../x", &err) == MTS_ERR_ARG);
    CHECKF(t, strstr(err.msg, "'.'") || strstr(err.msg, "'/'"), "message: %s", err.msg);
    long_name[64] = 'a';
    CHECK(t, mts_catalog_check_name(long_name, &err) == MTS_ERR_ARG);
    CHECKF(t, strstr(err.msg, "too long") && strstr(err.msg, "64"), "message: %s", err.msg);

    /* add and add_spec refuse bad names before touching anything */
    mts_catalog *cat = NULL;
    CHECK(t, mts_catalog_create(NULL, &cat, &err) == MTS_OK);
    CHECK(t, mts_catalog_add(cat, "../x", cow_src, NULL, &err) == MTS_ERR_ARG);
    CHECK(t, mts_catalog_add(cat, "a/b", cow_src, NULL, &err) == MTS_ERR_ARG);
    CHECK(t, mts_catalog_add(cat, "", cow_src, NULL, &err) == MTS_ERR_ARG);
    CHECK(t, mts_catalog_add(cat, long_name, cow_src, NULL, &err) == MTS_ERR_ARG);
    CHECK(t, mts_catalog_add_spec(cat, "a/b=tests/data/cow.off", NULL, &err) == MTS_ERR_ARG);
    CHECK(t, mts_catalog_add_spec(cat, "=tests/data/cow.off", NULL, &err) == MTS_ERR_ARG);
    CHECK(t, mts_catalog_add_spec(cat, "tests/data/cow.off", NULL, &err) == MTS_ERR_ARG);
    CHECKF(t, strstr(err.msg, "NAME=PATH"), "message: %s", err.msg);
    CHECK(t, mts_catalog_add_spec(cat, "cow=", NULL, &err) == MTS_ERR_ARG);
    CHECK(t, mts_catalog_count(cat) == 0);
    mts_catalog_free(cat);
}

/* One file too big for the memory left fails by itself: the others are
 * still served (a file's allocation failing said nothing about the next). */
typedef struct oom_dir {
    const char *dir;
} oom_dir;

static int load_dir_in_little_memory(void *arg)
{
    oom_dir *o = arg;
    reports rep;
    memset(&rep, 0, sizeof rep);
    mts_catalog_options co = {0};
    co.no_cache = 1;
    mts_catalog *cat = NULL;
    mts_error err = {0};
    mts_catalog_report cb = {collect, &rep};
    unsigned failed = 0;
    if (mts_catalog_create(&co, &cat, &err) != MTS_OK ||
        mts_catalog_add_dir(cat, o->dir, &cb, &failed, &err) != MTS_OK) {
        fprintf(stderr, "  %s\n", err.msg);
        mts_catalog_free(cat);
        return 0;
    }
    const report_line *l = find_report(&rep, MTS_CATALOG_FAILED, "/huge.off");
    int ok = mts_catalog_find(cat, "cow") != NULL && failed == 1 && l &&
             strstr(l->msg, "out of memory");
    if (!ok)
        fprintf(stderr, "  %zu models, %u failed: %s\n", mts_catalog_count(cat), failed,
                l ? l->msg : "(no report)");
    mts_catalog_free(cat);
    return ok;
}

static void test_file_out_of_memory(mts_test *t)
{
#ifdef __SANITIZE_ADDRESS__
    (void)load_dir_in_little_memory;
    SKIP(t, "address-space limits and ASan's shadow memory do not mix");
#else
    char dir[1100], p[1300];
    snprintf(dir, sizeof dir, "%s/oom", work);
    CHECK(t, mkdir(dir, 0755) == 0);
    snprintf(p, sizeof p, "%s/cow.off", dir);
    CHECK(t, copy_file(cow_src, p));
    /* an OFF header, then 1 GB of nothing (sparse): under the size cap,
     * over the memory the child may have */
    snprintf(p, sizeof p, "%s/huge.off", dir);
    int fd = open(p, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    CHECK(t, fd >= 0 && write(fd, "OFF\n", 4) == 4 && ftruncate(fd, (off_t)1 << 30) == 0);
    if (fd >= 0)
        close(fd);
    oom_dir o = {dir};
    pid_t pid = fork();
    if (pid == 0) {
        struct rlimit rl = {(rlim_t)768 << 20, (rlim_t)768 << 20};
        _exit(setrlimit(RLIMIT_AS, &rl) == 0 && load_dir_in_little_memory(&o) ? 0 : 1);
    }
    int st = 0;
    CHECK(t, pid > 0 && waitpid(pid, &st, 0) == pid);
    CHECKF(t, WIFEXITED(st) && WEXITSTATUS(st) == 0, "status %d", st);
#endif
}

static void test_add_paths(mts_test *t)
{
    char cache_dir[1300], mtsm[1300];
    snprintf(cache_dir, sizeof cache_dir, "%s/addcache", work);
    snprintf(mtsm, sizeof mtsm, "%s/ball.mtsm", models);
    mts_catalog_options o = {0};
    o.cache_dir = cache_dir;
    mts_catalog *cat = NULL;
    mts_error err = {0};
    CHECK(t, mts_catalog_create(&o, &cat, &err) == MTS_OK);
    if (!cat)
        return;
    reports rep = {0};
    mts_catalog_report cb = {collect, &rep};
    mts_result rc = mts_catalog_add_spec(cat, "moo=tests/data/cow.off", &cb, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    rc = mts_catalog_add(cat, "ball2", mtsm, &cb, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    const mts_catalog_entry *e = mts_catalog_find(cat, "moo");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->model.vertex_count == 2904);
    CHECK(t, e && !strcmp(e->source, "tests/data/cow.off"));
    e = mts_catalog_find(cat, "ball2");
    CHECK(t, e && e->origin == MTS_CATALOG_MODEL_FILE);
    CHECK(t, count_kind(&rep, MTS_CATALOG_ADDED) == 2);

    /* a name already used */
    CHECK(t, mts_catalog_add(cat, "moo", mtsm, NULL, &err) == MTS_ERR_ARG);
    CHECKF(t, strstr(err.msg, "already used"), "message: %s", err.msg);
    /* files that do not load: errors naming the model and the file */
    CHECK(t, mts_catalog_add(cat, "gone", "/nonexistent/x.off", NULL, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "gone") && strstr(err.msg, "/nonexistent/x.off"), "message: %s",
           err.msg);
    char broken[1300];
    snprintf(broken, sizeof broken, "%s/broken.off", models);
    CHECK(t, mts_catalog_add(cat, "broken", broken, NULL, &err) != MTS_OK);
    CHECKF(t, strstr(err.msg, "broken.off"), "message: %s", err.msg);
    CHECK(t, mts_catalog_add(cat, "notmodel", cow_src, NULL, &err) == MTS_OK); /* again: fine */
    CHECK(t, mts_catalog_count(cat) == 3);
    mts_catalog_free(cat);

    /* the second time, moo comes from the cache */
    CHECK(t, mts_catalog_create(&o, &cat, &err) == MTS_OK);
    if (!cat)
        return;
    CHECK(t, mts_catalog_add(cat, "moo", cow_src, NULL, &err) == MTS_OK);
    e = mts_catalog_find(cat, "moo");
    CHECK(t, e && e->origin == MTS_CATALOG_CACHED);
    mts_catalog_free(cat);
}

/* ------------------------------------------------------------------------ */
/* URLs                                                                      */

/* A port nothing listens on right now (bound, read, closed). */
static int free_port(void)
{
    int s = socket(AF_INET, SOCK_STREAM, 0);
    if (s < 0)
        return -1;
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    int port = -1;
    if (bind(s, (struct sockaddr *)&a, sizeof a) == 0 &&
        getsockname(s, (struct sockaddr *)&a, &len) == 0)
        port = ntohs(a.sin_port);
    close(s);
    return port;
}

static int port_accepts(int port)
{
    int s = socket(AF_INET, SOCK_STREAM, 0);
    if (s < 0)
        return 0;
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons((uint16_t)port);
    int ok = connect(s, (struct sockaddr *)&a, sizeof a) == 0;
    close(s);
    return ok;
}

static int in_path(const char *prog)
{
    const char *path = getenv("PATH");
    if (!path)
        return 0;
    char buf[4096];
    while (*path) {
        size_t n = strcspn(path, ":");
        snprintf(buf, sizeof buf, "%.*s/%s", (int)n, path, prog);
        if (access(buf, X_OK) == 0)
            return 1;
        path += n;
        if (*path == ':')
            path++;
    }
    return 0;
}

static pid_t http_pid = -1;
static int http_port = -1;
static char www[1100];

/* python3 -m http.server on 127.0.0.1 serving www; 0 when it cannot run. */
static int start_http_server(char *why, size_t why_size)
{
    if (!in_path("python3")) {
        snprintf(why, why_size, "python3 is not in PATH");
        return 0;
    }
    snprintf(www, sizeof www, "%s/www", work);
    char p[1300];
    snprintf(p, sizeof p, "%s/cow.off", www);
    if (mkdir(www, 0755) != 0 || !copy_file(cow_src, p)) {
        snprintf(why, why_size, "cannot prepare the web directory");
        return 0;
    }
    for (int attempt = 0; attempt < 3; attempt++) {
        int port = free_port();
        if (port <= 0)
            continue;
        char port_s[16];
        snprintf(port_s, sizeof port_s, "%d", port);
        pid_t pid = fork();
        if (pid < 0)
            break;
        if (pid == 0) {
            prctl(PR_SET_PDEATHSIG, SIGKILL); /* never outlives the test */
            int null = open("/dev/null", O_RDWR);
            if (null >= 0) {
                dup2(null, 1);
                dup2(null, 2);
            }
            execlp("python3", "python3", "-m", "http.server", port_s, "--bind", "127.0.0.1",
                   "--directory", www, (char *)NULL);
            _exit(127);
        }
        double t0 = mts_clock_seconds();
        while (mts_clock_seconds() - t0 < 15) {
            if (port_accepts(port)) {
                http_pid = pid;
                http_port = port;
                return 1;
            }
            int st;
            if (waitpid(pid, &st, WNOHANG) == pid) { /* died: port taken, or no http.server */
                pid = -1;
                break;
            }
            usleep(20000);
        }
        if (pid > 0) {
            kill(pid, SIGKILL);
            waitpid(pid, NULL, 0);
        }
    }
    snprintf(why, why_size, "python3 -m http.server did not start on 127.0.0.1");
    return 0;
}

static void stop_http_server(void)
{
    if (http_pid > 0) {
        kill(http_pid, SIGTERM);
        waitpid(http_pid, NULL, 0);
        http_pid = -1;
    }
}

/* A one-answer server for what http.server cannot do: every connection gets
 * response (or, when NULL, no answer until the client hangs up). */
static pid_t canned_start(const char *response, size_t response_len, int *port_out)
{
    int s = socket(AF_INET, SOCK_STREAM, 0);
    if (s < 0)
        return -1;
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    if (bind(s, (struct sockaddr *)&a, sizeof a) != 0 || listen(s, 16) != 0 ||
        getsockname(s, (struct sockaddr *)&a, &len) != 0) {
        close(s);
        return -1;
    }
    *port_out = ntohs(a.sin_port);
    pid_t pid = fork();
    if (pid != 0) {
        close(s);
        return pid;
    }
    prctl(PR_SET_PDEATHSIG, SIGKILL); /* never outlives the test */
    signal(SIGPIPE, SIG_IGN);
    for (;;) {
        int c = accept(s, NULL, NULL);
        if (c < 0)
            continue;
        char req[4096];
        mts_test_read_request(c, req, sizeof req);
        if (response) {
            size_t off = 0;
            while (off < response_len) {
                ssize_t n = write(c, response + off, response_len - off);
                if (n <= 0)
                    break;
                off += (size_t)n;
            }
        } else {
            while (read(c, req, sizeof req) > 0) {
            }
        }
        close(c);
    }
}

static void canned_stop(pid_t pid)
{
    if (pid > 0) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
    }
}

static void test_url_checks(mts_test *t)
{
    CHECK(t, mts_fetch_is_url("http://x/y"));
    CHECK(t, mts_fetch_is_url("file:///etc/passwd"));
    CHECK(t, mts_fetch_is_url("svn+ssh://h/r"));
    CHECK(t, !mts_fetch_is_url("tests/data/cow.off"));
    CHECK(t, !mts_fetch_is_url("c:/x.off"));
    CHECK(t, !mts_fetch_is_url("://x"));
    CHECK(t, !mts_fetch_is_url(NULL));

    const char *refused[] = {"file:///etc/passwd", "ftp://127.0.0.1/x", "FILE:///etc/passwd",
                             "gopher://127.0.0.1/x", "dict://127.0.0.1/x", "scp://127.0.0.1/x",
                             "ldap://127.0.0.1/x", "smb://127.0.0.1/x"};
    for (size_t i = 0; i < sizeof refused / sizeof refused[0]; i++) {
        mts_error err = {0};
        mts_fetch_result r;
        CHECKF(t, mts_fetch_url(refused[i], NULL, &r, &err) == MTS_ERR_ARG, "%s", refused[i]);
        CHECKF(t, strstr(err.msg, "not allowed") && strstr(err.msg, "only http and https"),
               "%s: %s", refused[i], err.msg);
        CHECK(t, r.data == NULL);
    }
    mts_error err = {0};
    mts_fetch_result r;
    CHECK(t, mts_fetch_url("file:///etc/passwd", NULL, &r, &err) == MTS_ERR_ARG);
    CHECKF(t, strstr(err.msg, "\"file\""), "message: %s", err.msg);
    CHECK(t, mts_fetch_url("ftp://127.0.0.1/x", NULL, &r, &err) == MTS_ERR_ARG);
    CHECKF(t, strstr(err.msg, "\"ftp\""), "message: %s", err.msg);
    CHECK(t, mts_fetch_url("127.0.0.1/cow.off", NULL, &r, &err) == MTS_ERR_ARG);
    CHECK(t, mts_fetch_url("", NULL, &r, &err) == MTS_ERR_ARG);
    CHECK(t, mts_fetch_check_url("http://127.0.0.1:1/x.off", &err) == MTS_OK);
    CHECK(t, mts_fetch_check_url("HTTPS://example.invalid/x.off", &err) == MTS_OK);

    /* the catalog refuses them too, as a model error */
    mts_catalog *cat = NULL;
    CHECK(t, mts_catalog_create(NULL, &cat, &err) == MTS_OK);
    CHECK(t, mts_catalog_add(cat, "pw", "file:///etc/passwd", NULL, &err) == MTS_ERR_ARG);
    CHECKF(t, strstr(err.msg, "pw") && strstr(err.msg, "only http and https"), "message: %s",
           err.msg);
    CHECK(t, mts_catalog_add_spec(cat, "f=ftp://127.0.0.1/x", NULL, &err) == MTS_ERR_ARG);
    CHECK(t, mts_catalog_count(cat) == 0);
    mts_catalog_free(cat);

    /* a password never shows in messages */
    char shown[256];
    mts_fetch_display_url("http://user:secret@127.0.0.1:1/x.off", shown, sizeof shown);
    CHECKF(t, !strstr(shown, "secret") && strstr(shown, "127.0.0.1"), "shown: %s", shown);
}

static void test_url_models(mts_test *t)
{
    char why[256];
    if (!start_http_server(why, sizeof why))
        SKIP(t, "%s", why);
    char url[256];
    mts_error err = {0};

    /* a URL model: fetched, loaded by its file name, built */
    mts_catalog *cat = NULL;
    CHECK(t, mts_catalog_create(NULL, &cat, &err) == MTS_OK);
    if (!cat)
        return;
    snprintf(url, sizeof url, "http://127.0.0.1:%d/cow.off", http_port);
    reports rep = {0};
    mts_catalog_report cb = {collect, &rep};
    mts_result rc = mts_catalog_add(cat, "webcow", url, &cb, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    const mts_catalog_entry *e = mts_catalog_find(cat, "webcow");
    CHECK(t, e && e->origin == MTS_CATALOG_BUILT && e->model.vertex_count == 2904);
    CHECK(t, e && e->source_bytes == 182966 && !strcmp(e->source, url) && !e->cache_path);
    CHECK(t, count_kind(&rep, MTS_CATALOG_ADDED) == 1);
    /* the same through --model's form */
    char spec[300];
    snprintf(spec, sizeof spec, "webcow2=%s", url);
    rc = mts_catalog_add_spec(cat, spec, NULL, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    /* a 404 names the status */
    snprintf(url, sizeof url, "http://127.0.0.1:%d/nope.off", http_port);
    CHECK(t, mts_catalog_add(cat, "nope", url, NULL, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "404") && strstr(err.msg, "nope.off"), "message: %s", err.msg);
    CHECK(t, mts_catalog_count(cat) == 2);
    mts_catalog_free(cat);

    /* the fetch itself: body, status, file name without query and fragment,
     * percent-decoded */
    mts_fetch_result r;
    snprintf(url, sizeof url, "http://127.0.0.1:%d/c%%6Fw.off?x=1#frag", http_port);
    rc = mts_fetch_url(url, NULL, &r, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    CHECK(t, r.size == 182966 && r.status == 200 && r.data && r.data[r.size] == 0);
    CHECKF(t, !strcmp(r.file_name, "cow.off"), "file name %s", r.file_name);
    CHECK(t, r.data && !memcmp(r.data, "OFF", 3));
    mts_fetch_result_free(&r);
    CHECK(t, r.data == NULL);

    /* a body over the cap: refused, naming the cap (announced by Content-Length) */
    mts_fetch_options fo = {0};
    fo.max_bytes = 1000;
    snprintf(url, sizeof url, "http://127.0.0.1:%d/cow.off", http_port);
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_ERR_LIMIT);
    CHECKF(t, strstr(err.msg, "1000 bytes"), "message: %s", err.msg);
    CHECK(t, r.data == NULL);
    mts_catalog_options co = {0};
    co.fetch.max_bytes = 1000;
    CHECK(t, mts_catalog_create(&co, &cat, &err) == MTS_OK);
    CHECK(t, mts_catalog_add(cat, "big", url, NULL, &err) == MTS_ERR_LIMIT);
    CHECKF(t, strstr(err.msg, "1000 bytes") && strstr(err.msg, "big"), "message: %s", err.msg);
    mts_catalog_free(cat);
    co = (mts_catalog_options){0};
    co.max_mesh_bytes = 1000; /* the smaller cap, announced by Content-Length */
    CHECK(t, mts_catalog_create(&co, &cat, &err) == MTS_OK);
    CHECK(t, mts_catalog_add(cat, "big", url, NULL, &err) == MTS_ERR_LIMIT);
    CHECKF(t, strstr(err.msg, "cap of 1000 bytes") && strstr(err.msg, "big"), "message: %s",
           err.msg);
    mts_catalog_free(cat);
    /* exactly the cap is fine */
    fo.max_bytes = 182966;
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_OK && r.size == 182966);
    mts_fetch_result_free(&r);
    fo.max_bytes = 182965;
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_ERR_LIMIT);

    /* a directory without its '/' redirects (301) to a listing: followed */
    snprintf(url, sizeof url, "http://127.0.0.1:%d/sub", http_port);
    char sub[1300];
    snprintf(sub, sizeof sub, "%s/sub", www);
    mkdir(sub, 0755);
    rc = mts_fetch_url(url, NULL, &r, &err);
    CHECKF(t, rc == MTS_OK && r.status == 200, "%s", err.msg);
    mts_fetch_result_free(&r);
    fo = (mts_fetch_options){0};
    fo.no_redirects = 1;
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "301"), "message: %s", err.msg);
    /* a body that is not a mesh */
    CHECK(t, mts_catalog_create(NULL, &cat, &err) == MTS_OK);
    CHECK(t, mts_catalog_add(cat, "listing", url, NULL, &err) == MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "listing"), "message: %s", err.msg);
    mts_catalog_free(cat);
    stop_http_server();
}

static void test_url_failures(mts_test *t)
{
    mts_error err = {0};
    mts_fetch_result r;
    char url[256];

    /* nothing listens: fails at once, well within the connect timeout */
    int port = free_port();
    CHECK(t, port > 0);
    snprintf(url, sizeof url, "http://user:secret@127.0.0.1:%d/cow.off", port);
    mts_fetch_options fo = {0};
    fo.connect_timeout_ms = 2000;
    double t0 = mts_clock_seconds();
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_ERR_IO);
    double dt = mts_clock_seconds() - t0;
    CHECKF(t, dt < 2.5, "took %.2f s", dt);
    CHECKF(t, strstr(err.msg, "127.0.0.1") && !strstr(err.msg, "secret"), "message: %s",
           err.msg);

    /* a body without Content-Length over the cap: stopped while streaming */
    static char big[20000];
    int n = snprintf(big, sizeof big, "HTTP/1.0 200 OK\r\nContent-Type: text/plain\r\n\r\n");
    memset(big + n, 'x', sizeof big - (size_t)n);
    pid_t pid = canned_start(big, sizeof big, &port);
    CHECK(t, pid > 0);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/stream.off", port);
    fo = (mts_fetch_options){0};
    fo.max_bytes = 1000;
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_ERR_LIMIT);
    CHECKF(t, strstr(err.msg, "1000 bytes"), "message: %s", err.msg);
    fo.max_bytes = 0;
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_OK && r.size == sizeof big - (size_t)n);
    mts_fetch_result_free(&r);
    /* a download is a mesh file too: max_mesh_bytes caps it when smaller
     * than the download cap */
    mts_catalog_options co = {0};
    co.max_mesh_bytes = 1000;
    mts_catalog *cat = NULL;
    CHECK(t, mts_catalog_create(&co, &cat, &err) == MTS_OK);
    CHECK(t, mts_catalog_add(cat, "stream", url, NULL, &err) == MTS_ERR_LIMIT);
    CHECKF(t, strstr(err.msg, "cap of 1000 bytes") && strstr(err.msg, "stream"), "message: %s",
           err.msg);
    mts_catalog_free(cat);
    canned_stop(pid);

    /* a redirect to another scheme is not followed */
    const char *to_ftp = "HTTP/1.1 302 Found\r\nLocation: ftp://127.0.0.1/x\r\n"
                         "Content-Length: 0\r\nConnection: close\r\n\r\n";
    pid = canned_start(to_ftp, strlen(to_ftp), &port);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/x.off", port);
    CHECK(t, mts_fetch_url(url, NULL, &r, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "ftp") && strstr(err.msg, "only http and https"), "message: %s",
           err.msg);
    canned_stop(pid);
    const char *to_file = "HTTP/1.1 302 Found\r\nLocation: file:///etc/passwd\r\n"
                          "Content-Length: 0\r\nConnection: close\r\n\r\n";
    pid = canned_start(to_file, strlen(to_file), &port);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/x.off", port);
    CHECK(t, mts_fetch_url(url, NULL, &r, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "only http and https"), "message: %s", err.msg);
    CHECK(t, r.data == NULL);
    canned_stop(pid);

    /* a redirect loop ends after max_redirects */
    const char *loop = "HTTP/1.1 302 Found\r\nLocation: /again.off\r\n"
                       "Content-Length: 0\r\nConnection: close\r\n\r\n";
    pid = canned_start(loop, strlen(loop), &port);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/x.off", port);
    fo = (mts_fetch_options){0};
    fo.max_redirects = 3;
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "redirect") && strstr(err.msg, "3"), "message: %s", err.msg);
    canned_stop(pid);

    /* a server that never answers: the total timeout */
    pid = canned_start(NULL, 0, &port);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/x.off", port);
    fo = (mts_fetch_options){0};
    fo.timeout_ms = 500;
    t0 = mts_clock_seconds();
    CHECK(t, mts_fetch_url(url, &fo, &r, &err) == MTS_ERR_IO);
    dt = mts_clock_seconds() - t0;
    CHECKF(t, dt >= 0.4 && dt < 3, "took %.2f s", dt);
    CHECKF(t, strstr(err.msg, "timed out") && strstr(err.msg, "500 ms"), "message: %s", err.msg);
    canned_stop(pid);

    /* a 500 from a server names the status */
    const char *e500 = "HTTP/1.1 500 Internal Server Error\r\nContent-Length: 5\r\n"
                       "Connection: close\r\n\r\noops\n";
    pid = canned_start(e500, strlen(e500), &port);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/x.off", port);
    CHECK(t, mts_fetch_url(url, NULL, &r, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "HTTP status 500"), "message: %s", err.msg);
    canned_stop(pid);
}

/* ------------------------------------------------------------------------ */

static void remove_tree(const char *dir)
{
    char cmd[2200];
    snprintf(cmd, sizeof cmd, "chmod -R u+w '%s' 2>/dev/null; rm -rf '%s'", dir, dir);
    if (system(cmd) != 0)
        fprintf(stderr, "  could not remove %s\n", dir);
}

int main(void)
{
    mts_test t = {0};
    /* loopback only: no proxy may see these requests */
    const char *proxies[] = {"http_proxy", "HTTP_PROXY", "https_proxy", "HTTPS_PROXY",
                             "all_proxy", "ALL_PROXY"};
    for (size_t i = 0; i < sizeof proxies / sizeof proxies[0]; i++)
        unsetenv(proxies[i]);
    setenv("no_proxy", "*", 1);
    signal(SIGPIPE, SIG_IGN);

    mts_error err = {0};
    if (mts_fetch_global_init(&err) != MTS_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    snprintf(work, sizeof work, "%s/mts-catalog-XXXXXX", mts_test_tmpdir());
    if (!mkdtemp(work)) {
        fprintf(stderr, "cannot make a directory under %s\n", mts_test_tmpdir());
        return 1;
    }
    if (!setup_models()) {
        fprintf(stderr, "cannot set up %s\n", models);
        return 1;
    }
    RUN(&t, test_models_dir);
    RUN(&t, test_cache_reuse_and_rebuild);
    RUN(&t, test_cache_from_before_colors);
    RUN(&t, test_cache_dir_option);
    RUN(&t, test_cache_readonly_dir);
    RUN(&t, test_names);
    RUN(&t, test_add_paths);
    RUN(&t, test_file_out_of_memory);
    RUN(&t, test_url_checks);
    RUN(&t, test_url_models);
    RUN(&t, test_url_failures);
    stop_http_server();
    remove_tree(work);
    mts_fetch_global_cleanup();
    return mts_test_end(&t);
}
