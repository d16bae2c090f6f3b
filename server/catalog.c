#include "catalog.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "clock.h"
#include "fileio.h"
#include "mesh.h"
#include "modelfile.h"
#include "wire.h"

struct mts_catalog {
    mts_catalog_options opts;
    char *cache_dir;             /* copy of opts.cache_dir, or NULL */
    mts_catalog_entry **entries; /* sorted by name (byte order) */
    size_t count, cap;
};

/* ------------------------------------------------------------------------ */
/* Names                                                                     */

mts_result mts_catalog_check_name(const char *name, mts_error *err)
{
    if (!name)
        return mts_wire_check_name(NULL, 0, err);
    return mts_wire_check_name(name, strnlen(name, MTS_CATALOG_NAME_MAX + 1), err);
}

int mts_catalog_name_valid(const char *name)
{
    return mts_catalog_check_name(name, NULL) == MTS_OK;
}

/* ------------------------------------------------------------------------ */
/* Small helpers                                                             */

static char *str_dup(const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d)
        memcpy(d, s, n);
    return d;
}

/* malloc'd printf; NULL when out of memory. */
static char *str_printf(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;
static char *str_printf(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0)
        return NULL;
    char *s = malloc((size_t)n + 1);
    if (!s)
        return NULL;
    va_start(ap, fmt);
    vsnprintf(s, (size_t)n + 1, fmt, ap);
    va_end(ap);
    return s;
}

/* The extension after the last '.', not counting a leading '.'; NULL when none. */
static const char *extension(const char *file)
{
    const char *dot = strrchr(file, '.');
    return dot && dot != file ? dot + 1 : NULL;
}

static int is_model_ext(const char *ext)
{
    return ext && mts_ascii_ieq(ext, "mtsm");
}

static int is_mesh_ext(const char *ext)
{
    return ext && (mts_ascii_ieq(ext, "off") || mts_ascii_ieq(ext, "obj") || mts_ascii_ieq(ext, "ply") ||
                   mts_ascii_ieq(ext, "stl") || mts_ascii_ieq(ext, "gltf") ||
                   mts_ascii_ieq(ext, "glb"));
}

static uint64_t fnv1a64(const char *s)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (; *s; s++) {
        h ^= (unsigned char)*s;
        h *= 0x100000001b3ull;
    }
    return h;
}

static void printable(char *s)
{
    for (; *s; s++)
        if ((unsigned char)*s < 0x20 || (unsigned char)*s >= 0x7f)
            *s = '?';
}

static void report_to(const mts_catalog_report *rep, mts_catalog_report_kind kind,
                      const char *file, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
static void report_to(const mts_catalog_report *rep, mts_catalog_report_kind kind,
                      const char *file, const char *fmt, ...)
{
    if (!rep || !rep->fn)
        return;
    char msg[1024], shown[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* a file name may hold any byte but '/' and NUL, and reports go to
     * terminals and logs: nothing but printable ASCII gets there */
    printable(msg);
    snprintf(shown, sizeof shown, "%s", file ? file : "");
    printable(shown);
    rep->fn(rep->user, kind, shown, msg);
}

/* Progress with the model's name in front of the stage. */
typedef struct named_progress {
    const mts_progress *to;
    const char *name;
} named_progress;

static void named_progress_fn(void *user, const char *stage, double done)
{
    named_progress *np = user;
    char buf[MTS_CATALOG_NAME_MAX + 64];
    snprintf(buf, sizeof buf, "%s: %s", np->name, stage ? stage : "");
    np->to->fn(np->to->user, buf, done);
}

static mts_progress named(const mts_catalog *cat, named_progress *np, const char *name)
{
    np->to = &cat->opts.progress;
    np->name = name;
    mts_progress p = {0};
    if (cat->opts.progress.fn) {
        p.fn = named_progress_fn;
        p.user = np;
    }
    return p;
}

/* ------------------------------------------------------------------------ */
/* The table                                                                 */

static int cmp_name_n(const char *a, const char *b, size_t blen)
{
    int c = strncmp(a, b, blen);
    if (c)
        return c;
    return a[blen] ? 1 : 0; /* a is longer */
}

/* Index of name, or where it would go (*found = 0). */
static size_t locate(const mts_catalog *cat, const char *name, size_t len, int *found)
{
    size_t lo = 0, hi = cat->count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        int c = cmp_name_n(cat->entries[mid]->name, name, len);
        if (c == 0) {
            *found = 1;
            return mid;
        }
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    *found = 0;
    return lo;
}

const mts_catalog_entry *mts_catalog_find_n(const mts_catalog *cat, const char *name, size_t len)
{
    if (!cat || mts_wire_check_name(name, len, NULL) != MTS_OK)
        return NULL;
    int found;
    size_t i = locate(cat, name, len, &found);
    return found ? cat->entries[i] : NULL;
}

const mts_catalog_entry *mts_catalog_find(const mts_catalog *cat, const char *name)
{
    if (!name)
        return NULL;
    return mts_catalog_find_n(cat, name, strnlen(name, MTS_CATALOG_NAME_MAX + 1));
}

size_t mts_catalog_count(const mts_catalog *cat)
{
    return cat ? cat->count : 0;
}

const mts_catalog_entry *mts_catalog_at(const mts_catalog *cat, size_t i)
{
    return cat && i < cat->count ? cat->entries[i] : NULL;
}

void mts_catalog_release_model(mts_catalog *cat, size_t i)
{
    if (cat && i < cat->count)
        mts_model_free(&cat->entries[i]->model);
}

static void entry_free(mts_catalog_entry *e)
{
    if (!e)
        return;
    mts_model_free(&e->model);
    free((char *)e->source);
    free((char *)e->cache_path);
    free(e);
}

/* Takes ownership of e (freed on failure). The name must be free. */
static mts_result insert(mts_catalog *cat, mts_catalog_entry *e, mts_error *err)
{
    int found;
    size_t at = locate(cat, e->name, strlen(e->name), &found);
    if (found) {
        mts_error_set(err, MTS_ERR_INTERNAL, "model name %s inserted twice", e->name);
        entry_free(e);
        return MTS_ERR_INTERNAL;
    }
    if (cat->count == cat->cap) {
        size_t cap = cat->cap ? cat->cap * 2 : 16;
        mts_catalog_entry **grown = realloc(cat->entries, cap * sizeof *grown);
        if (!grown) {
            entry_free(e);
            return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for the model table");
        }
        cat->entries = grown;
        cat->cap = cap;
    }
    memmove(cat->entries + at + 1, cat->entries + at, (cat->count - at) * sizeof *cat->entries);
    cat->entries[at] = e;
    cat->count++;
    return MTS_OK;
}

static mts_catalog_entry *entry_new(const char *name, const char *source)
{
    mts_catalog_entry *e = calloc(1, sizeof *e);
    if (!e)
        return NULL;
    snprintf(e->name, sizeof e->name, "%s", name);
    e->source = str_dup(source);
    if (!e->source) {
        free(e);
        return NULL;
    }
    return e;
}

/* ------------------------------------------------------------------------ */
/* Create / free                                                             */

mts_result mts_catalog_create(const mts_catalog_options *opts, mts_catalog **out, mts_error *err)
{
    if (!out)
        return mts_error_set(err, MTS_ERR_ARG, "mts_catalog_create: no catalog to fill");
    *out = NULL;
    mts_catalog *cat = calloc(1, sizeof *cat);
    if (!cat)
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for a catalog");
    if (opts)
        cat->opts = *opts;
    if (cat->opts.cache_dir && !cat->opts.no_cache) {
        const char *d = cat->opts.cache_dir;
        if (!*d) {
            free(cat);
            return mts_error_set(err, MTS_ERR_ARG, "the cache directory name is empty");
        }
        if (mkdir(d, 0700) != 0 && errno != EEXIST) {
            mts_error_set(err, MTS_ERR_IO, "cache directory %s: %s", d, strerror(errno));
            free(cat);
            return MTS_ERR_IO;
        }
        struct stat st;
        int bad = stat(d, &st) != 0 ? errno : !S_ISDIR(st.st_mode) ? ENOTDIR : 0;
        if (bad) {
            mts_error_set(err, MTS_ERR_IO, "cache directory %s: %s", d, strerror(bad));
            free(cat);
            return MTS_ERR_IO;
        }
        cat->cache_dir = str_dup(d);
        if (!cat->cache_dir) {
            free(cat);
            return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for a catalog");
        }
    }
    cat->opts.cache_dir = cat->cache_dir;
    *out = cat;
    return MTS_OK;
}

void mts_catalog_free(mts_catalog *cat)
{
    if (!cat)
        return;
    for (size_t i = 0; i < cat->count; i++)
        entry_free(cat->entries[i]);
    free(cat->entries);
    free(cat->cache_dir);
    free(cat);
}

/* ------------------------------------------------------------------------ */
/* Loading one model                                                         */

static uint64_t max_file_bytes(const mts_catalog *cat)
{
    uint64_t cap = cat->opts.max_mesh_bytes ? cat->opts.max_mesh_bytes : MTS_MESH_DEFAULT_MAX_BYTES;
    return cap < SIZE_MAX / 2 ? cap : SIZE_MAX / 2;
}

/* mts_modelfile_load, for files of the folder: only a regular file, only up
 * to the cap (checked on the open descriptor before reading), and a file
 * without the model magic is refused from its first bytes. *bytes gets the
 * file's size. */
static mts_result load_model_file(const mts_catalog *cat, const char *path, mts_model *model,
                                  uint64_t *bytes, mts_error *err)
{
    int fd;
    uint64_t size;
    mts_result r = mts_file_open_regular(path, max_file_bytes(cat), "--max-mesh-bytes", &fd,
                                         &size, err);
    if (r != MTS_OK)
        return r;
    *bytes = size;
    /* the 16-byte header first: a file that is not a model costs no more */
    uint8_t head[16];
    size_t head_size = size < sizeof head ? (size_t)size : sizeof head;
    uint8_t *data = NULL;
    if ((r = mts_file_read_exact(fd, path, head, head_size, err)) != MTS_OK)
        goto done;
    if (head_size < sizeof head || memcmp(head, "MTSM", 4) != 0) {
        r = mts_modelfile_decode(head, head_size, path, model, err); /* its own message */
        goto done;
    }
    data = malloc((size_t)size);
    if (!data) {
        r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for %llu bytes", path,
                          (unsigned long long)size);
        goto done;
    }
    memcpy(data, head, head_size);
    if ((r = mts_file_read_exact(fd, path, data + head_size, (size_t)size - head_size, err)) ==
        MTS_OK)
        r = mts_modelfile_decode(data, (size_t)size, path, model, err);
done:
    close(fd);
    free(data);
    return r;
}

static mts_result add_model_file(mts_catalog *cat, const char *name, const char *path,
                                 const mts_catalog_report *rep, mts_error *err)
{
    mts_catalog_entry *e = entry_new(name, path);
    if (!e)
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
    named_progress np;
    mts_progress p = named(cat, &np, name);
    mts_progress_report(&p, "load", 0);
    uint64_t bytes = 0;
    mts_result r = load_model_file(cat, path, &e->model, &bytes, err);
    if (r != MTS_OK) {
        entry_free(e);
        return r;
    }
    mts_progress_report(&p, "load", 1);
    e->origin = MTS_CATALOG_MODEL_FILE;
    e->source_bytes = bytes;
    uint32_t n = e->model.level_count;
    report_to(rep, MTS_CATALOG_ADDED, path, "%s: loaded (%u vertices, %u triangles, %u levels)",
              name, e->model.vertex_count, e->model.level_triangles[n], n);
    return insert(cat, e, err);
}

/* Makes (when missing) and checks the per-user cache directory under
 * $TMPDIR or /tmp: ours, a real directory, not open to others. */
static int private_tmp_dir(char *buf, size_t size)
{
    const char *t = getenv("TMPDIR");
    if (!t || t[0] != '/')
        t = "/tmp";
    int n = snprintf(buf, size, "%s/mtstream-cache-%lu", t, (unsigned long)geteuid());
    if (n < 0 || (size_t)n >= size)
        return 0;
    if (mkdir(buf, 0700) != 0 && errno != EEXIST)
        return 0;
    struct stat st;
    if (lstat(buf, &st) != 0)
        return 0;
    return S_ISDIR(st.st_mode) && st.st_uid == geteuid() && (st.st_mode & 077) == 0;
}

/* Where the mesh dir/file is cached; NULL when nowhere (why says why, for a
 * note, or stays empty when the cache is off). */
static char *cache_path_for(const mts_catalog *cat, const char *dir, const char *file, char *why,
                            size_t why_size)
{
    why[0] = 0;
    if (cat->opts.no_cache)
        return NULL;
    if (!cat->cache_dir && access(dir, W_OK | X_OK) == 0)
        return str_printf("%s/.%s.mtsm", dir, file);
    char real[PATH_MAX];
    const char *key = realpath(dir, real) ? real : dir;
    unsigned long long h = (unsigned long long)fnv1a64(key);
    if (cat->cache_dir)
        return str_printf("%s/.%s.%016llx.mtsm", cat->cache_dir, file, h);
    char tmp[PATH_MAX];
    if (!private_tmp_dir(tmp, sizeof tmp)) {
        snprintf(why, why_size,
                 "%s is not writable and no private cache directory could be made under "
                 "$TMPDIR or /tmp: not cached",
                 dir);
        return NULL;
    }
    return str_printf("%s/.%s.%016llx.mtsm", tmp, file, h);
}

static int newer(const struct timespec *a, const struct timespec *b)
{
    return a->tv_sec > b->tv_sec || (a->tv_sec == b->tv_sec && a->tv_nsec > b->tv_nsec);
}

/* Builds mesh (or takes it from the cache) into e->model. */
static mts_result build_into(const mts_catalog *cat, mts_catalog_entry *e, const mts_mesh *mesh,
                             const char *source, mts_error *err)
{
    named_progress np;
    mts_build_options bo = {0};
    bo.base_vertices = cat->opts.base_vertices;
    bo.progress = named(cat, &np, e->name);
    return mts_build_model(mesh, source, &bo, &e->model, NULL, err);
}

static mts_result add_mesh_file(mts_catalog *cat, const char *name, const char *path,
                                const mts_catalog_report *rep, mts_error *err)
{
    /* dir and file of path */
    const char *slash = strrchr(path, '/');
    const char *file = slash ? slash + 1 : path;
    char *dir = slash ? str_printf("%.*s", (int)(slash == path ? 1 : slash - path), path)
                      : str_dup(".");
    if (!dir)
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
    mts_result r = MTS_OK;
    mts_catalog_entry *e = NULL;
    mts_mesh mesh = {0};
    char *cache = NULL;

    /* what the file is (for the cache key), from the descriptor that checked
     * it is a regular file within the cap; mts_mesh_load checks again */
    struct stat st;
    int fd;
    uint64_t file_size;
    if ((r = mts_file_open_regular(path, max_file_bytes(cat), "--max-mesh-bytes", &fd,
                                   &file_size, err)) != MTS_OK)
        goto done;
    int stat_errno = fstat(fd, &st) == 0 ? 0 : errno;
    close(fd);
    if (stat_errno) {
        r = mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(stat_errno));
        goto done;
    }
    e = entry_new(name, path);
    if (!e) {
        r = mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
        goto done;
    }
    e->source_bytes = (uint64_t)st.st_size;

    /* The cache key: what the mesh is now and how it is built. The figures
     * come first so that a long file name, cut at the model's 255
     * characters, never hides them. The model file's minor version is in
     * it because a minor version can add what the builder keeps (5.2 keeps
     * vertex colours): a cache from a builder before that must not serve a
     * coloured mesh as grey. */
    char key[sizeof e->model.build_key];
    snprintf(key, sizeof key, "size %llu, mtime %lld.%09ld, base_vertices %u, mtsm %d.%d: %s",
             (unsigned long long)st.st_size, (long long)st.st_mtim.tv_sec,
             (long)st.st_mtim.tv_nsec, cat->opts.base_vertices, MTS_MODELFILE_MAJOR,
             MTS_MODELFILE_MINOR, file);

    char why[512];
    cache = cache_path_for(cat, dir, file, why, sizeof why);
    if (!cache && why[0])
        report_to(rep, MTS_CATALOG_NOTE, path, "%s: %s", name, why);
    if (cache) {
        struct stat cs;
        if (stat(cache, &cs) == 0) {
            if (newer(&st.st_mtim, &cs.st_mtim)) {
                report_to(rep, MTS_CATALOG_NOTE, path,
                          "%s: the mesh is newer than its cache %s: rebuilding", name, cache);
            } else {
                mts_error cerr = {0};
                uint64_t cache_bytes;
                if (load_model_file(cat, cache, &e->model, &cache_bytes, &cerr) != MTS_OK) {
                    report_to(rep, MTS_CATALOG_NOTE, path,
                              "%s: the cache does not load (%s): rebuilding", name, cerr.msg);
                } else if (strcmp(e->model.build_key, key) != 0) {
                    mts_model_free(&e->model);
                    report_to(rep, MTS_CATALOG_NOTE, path,
                              "%s: the cache %s was built from another version of the mesh or "
                              "with other options: rebuilding",
                              name, cache);
                } else {
                    e->origin = MTS_CATALOG_CACHED;
                    e->cache_path = cache;
                    cache = NULL;
                    uint32_t n = e->model.level_count;
                    report_to(rep, MTS_CATALOG_ADDED, path,
                              "%s: from the cache %s (%u vertices, %u triangles, %u levels)",
                              name, e->cache_path, e->model.vertex_count,
                              e->model.level_triangles[n], n);
                    r = insert(cat, e, err);
                    e = NULL;
                    goto done;
                }
            }
        }
    }

    named_progress np;
    mts_progress p = named(cat, &np, name);
    double t0 = mts_clock_seconds();
    mts_progress_report(&p, "load", 0);
    mts_mesh_options mo = {0};
    mo.max_bytes = max_file_bytes(cat);
    if ((r = mts_mesh_load(path, &mo, &mesh, NULL, err)) != MTS_OK)
        goto done;
    mts_progress_report(&p, "load", 1);
    if ((r = build_into(cat, e, &mesh, path, err)) != MTS_OK) {
        mts_error_prefix(err, "%s", path);
        goto done;
    }
    snprintf(e->model.build_key, sizeof e->model.build_key, "%s", key);
    double t1 = mts_clock_seconds();
    e->origin = MTS_CATALOG_BUILT;
    const char *cached_note = "not cached";
    if (cache) {
        mts_error cerr = {0};
        if (mts_modelfile_save(&e->model, cache, NULL, &cerr) != MTS_OK) {
            report_to(rep, MTS_CATALOG_NOTE, path, "%s: could not write the cache: %s", name,
                      cerr.msg);
        } else {
            /* A mesh dated in the future would look newer than its fresh
             * cache on every start: date the cache like the mesh then. */
            struct stat cs;
            if (stat(cache, &cs) == 0 && newer(&st.st_mtim, &cs.st_mtim)) {
                struct timespec ts[2] = {{0, UTIME_OMIT}, st.st_mtim};
                utimensat(AT_FDCWD, cache, ts, 0);
            }
            e->cache_path = cache;
            cache = NULL;
            cached_note = "cached as ";
        }
    }
    uint32_t n = e->model.level_count;
    report_to(rep, MTS_CATALOG_ADDED, path,
              "%s: built in %.2f s (%u vertices, %u triangles, %u levels), %s%s", name, t1 - t0,
              e->model.vertex_count, e->model.level_triangles[n], n, cached_note,
              e->cache_path ? e->cache_path : "");
    r = insert(cat, e, err);
    e = NULL;
done:
    mts_mesh_free(&mesh);
    entry_free(e);
    free(cache);
    free(dir);
    return r;
}

static mts_result add_url(mts_catalog *cat, const char *name, const char *url,
                          const mts_catalog_report *rep, mts_error *err)
{
    char shown[256];
    mts_fetch_display_url(url, shown, sizeof shown);
    mts_result r = mts_fetch_check_url(url, err);
    if (r != MTS_OK)
        return r;
    named_progress np;
    mts_fetch_options fo = cat->opts.fetch;
    fo.progress = named(cat, &np, name);
    /* a download is a mesh file too: the smaller of the two caps */
    uint64_t fetch_cap = fo.max_bytes ? fo.max_bytes : MTS_FETCH_DEFAULT_MAX_BYTES;
    if (fetch_cap > max_file_bytes(cat))
        fo.max_bytes = max_file_bytes(cat);
    mts_fetch_result got = {0};
    mts_mesh mesh = {0};
    mts_catalog_entry *e = NULL;
    double t0 = mts_clock_seconds();
    if ((r = mts_fetch_url(url, &fo, &got, err)) != MTS_OK)
        goto done;
    double t1 = mts_clock_seconds();
    e = entry_new(name, shown);
    if (!e) {
        r = mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
        goto done;
    }
    e->source_bytes = got.size;
    const char *file = got.file_name[0] ? got.file_name : "(download)";
    mts_progress_report(&fo.progress, "load", 0);
    mts_mesh_options mo = {0};
    mo.max_bytes = max_file_bytes(cat);
    if ((r = mts_mesh_load_memory(file, got.data, got.size, &mo, &mesh, NULL, err)) != MTS_OK) {
        mts_error_prefix(err, "%s", shown);
        goto done;
    }
    mts_fetch_result_free(&got);
    mts_progress_report(&fo.progress, "load", 1);
    if ((r = build_into(cat, e, &mesh, shown, err)) != MTS_OK) {
        mts_error_prefix(err, "%s", shown);
        goto done;
    }
    double t2 = mts_clock_seconds();
    e->origin = MTS_CATALOG_BUILT;
    uint32_t n = e->model.level_count;
    report_to(rep, MTS_CATALOG_ADDED, shown,
              "%s: downloaded %llu bytes in %.2f s, built in %.2f s (%u vertices, %u triangles, "
              "%u levels)",
              name, (unsigned long long)e->source_bytes, t1 - t0, t2 - t1, e->model.vertex_count,
              e->model.level_triangles[n], n);
    r = insert(cat, e, err);
    e = NULL;
done:
    mts_fetch_result_free(&got);
    mts_mesh_free(&mesh);
    entry_free(e);
    return r;
}

mts_result mts_catalog_add(mts_catalog *cat, const char *name, const char *path_or_url,
                           const mts_catalog_report *report, mts_error *err)
{
    if (!cat || !path_or_url)
        return mts_error_set(err, MTS_ERR_ARG, "mts_catalog_add: no %s",
                             cat ? "path or URL" : "catalog");
    mts_result r = mts_catalog_check_name(name, err);
    if (r != MTS_OK)
        return r;
    const mts_catalog_entry *old = mts_catalog_find(cat, name);
    if (old)
        return mts_error_set(err, MTS_ERR_ARG, "model name %s is already used (by %s)", name,
                             old->source);
    if (!*path_or_url)
        return mts_error_set(err, MTS_ERR_ARG, "model %s: no path or URL given", name);
    if (mts_fetch_is_url(path_or_url))
        r = add_url(cat, name, path_or_url, report, err);
    else if (is_model_ext(extension(path_or_url)))
        r = add_model_file(cat, name, path_or_url, report, err);
    else
        r = add_mesh_file(cat, name, path_or_url, report, err);
    if (r != MTS_OK && r != MTS_ERR_NOMEM)
        mts_error_prefix(err, "model %s", name);
    return r;
}

mts_result mts_catalog_add_spec(mts_catalog *cat, const char *spec,
                                const mts_catalog_report *report, mts_error *err)
{
    if (!spec)
        return mts_error_set(err, MTS_ERR_ARG, "no model given (NAME=PATH or NAME=URL)");
    const char *eq = strchr(spec, '=');
    if (!eq)
        return mts_error_set(err, MTS_ERR_ARG,
                             "\"%.100s\": give a model as NAME=PATH or NAME=URL", spec);
    size_t len = (size_t)(eq - spec);
    mts_result r = mts_wire_check_name(spec, len, err);
    if (r != MTS_OK)
        return r;
    char name[MTS_CATALOG_NAME_MAX + 1];
    memcpy(name, spec, len);
    name[len] = 0;
    return mts_catalog_add(cat, name, eq + 1, report, err);
}

/* ------------------------------------------------------------------------ */
/* A directory                                                               */

typedef struct dir_item {
    char *file;    /* file name in the directory */
    char *stem;    /* the model name it would give */
    int is_model;  /* .mtsm (1) or mesh (0) */
} dir_item;

static int cmp_item(const void *pa, const void *pb)
{
    const dir_item *a = pa, *b = pb;
    int c = strcmp(a->stem, b->stem);
    if (c)
        return c;
    if (a->is_model != b->is_model)
        return a->is_model ? -1 : 1; /* the .mtsm first: it wins */
    return strcmp(a->file, b->file);
}

mts_result mts_catalog_add_dir(mts_catalog *cat, const char *dir,
                               const mts_catalog_report *report, unsigned *failed,
                               mts_error *err)
{
    if (failed)
        *failed = 0;
    if (!cat || !dir || !*dir)
        return mts_error_set(err, MTS_ERR_ARG, "mts_catalog_add_dir: no %s",
                             cat ? "directory" : "catalog");
    DIR *d = opendir(dir);
    if (!d)
        return mts_error_set(err, MTS_ERR_IO, "models directory %s: %s", dir, strerror(errno));

    mts_result r = MTS_OK;
    dir_item *items = NULL;
    uint8_t *added = NULL; /* per item: it got its name */
    size_t count = 0, cap = 0;
    unsigned nfailed = 0;
    for (;;) {
        errno = 0;
        struct dirent *de = readdir(d);
        if (!de) {
            if (errno)
                r = mts_error_set(err, MTS_ERR_IO, "models directory %s: %s", dir,
                                  strerror(errno));
            break;
        }
        const char *f = de->d_name;
        if (f[0] == '.') /* hidden files, our caches, "." and ".." */
            continue;
        const char *ext = extension(f);
        int is_model = is_model_ext(ext);
        if (!is_model && !is_mesh_ext(ext))
            continue;
        if (count == cap) {
            size_t ncap = cap ? cap * 2 : 64;
            dir_item *grown = realloc(items, ncap * sizeof *grown);
            if (!grown) {
                r = mts_error_set(err, MTS_ERR_NOMEM, "out of memory listing %s", dir);
                break;
            }
            items = grown;
            cap = ncap;
        }
        dir_item *it = &items[count];
        it->file = str_dup(f);
        it->stem = str_printf("%.*s", (int)(ext - 1 - f), f);
        it->is_model = is_model;
        if (!it->file || !it->stem) {
            free(it->file);
            free(it->stem);
            r = mts_error_set(err, MTS_ERR_NOMEM, "out of memory listing %s", dir);
            break;
        }
        count++;
    }
    closedir(d);
    if (r != MTS_OK)
        goto done;
    if (count > 1)
        qsort(items, count, sizeof *items, cmp_item);

    /* Equal stems are now next to each other, the preferred first (a model
     * file before meshes); the name goes to the first of them that loads, so
     * a broken .mtsm does not hide a good mesh of its name. */
    const char *sep = dir[strlen(dir) - 1] == '/' ? "" : "/";
    added = calloc(count + 1, 1);
    if (!added) {
        r = mts_error_set(err, MTS_ERR_NOMEM, "out of memory listing %s", dir);
        goto done;
    }
    for (size_t i = 0; i < count; i++) {
        dir_item *it = &items[i];
        char *path = str_printf("%s%s%s", dir, sep, it->file);
        if (!path) {
            r = mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
            goto done;
        }
        mts_error e1 = {0};
        const dir_item *winner = NULL, *failed_first = NULL;
        for (size_t j = i; j-- > 0 && !strcmp(items[j].stem, it->stem);) {
            if (added[j])
                winner = &items[j];
            else
                failed_first = &items[j];
        }
        const mts_catalog_entry *old;
        if (mts_catalog_check_name(it->stem, &e1) != MTS_OK) {
            report_to(report, MTS_CATALOG_SKIPPED, path, "skipped: %s", e1.msg);
        } else if (winner && winner->is_model && !it->is_model) {
            report_to(report, MTS_CATALOG_NOTE, path,
                      "%s: not built: %s has the same name and is served instead", it->stem,
                      winner->file);
        } else if (winner) {
            report_to(report, MTS_CATALOG_SKIPPED, path,
                      "skipped: the name %s is already taken by %s", it->stem, winner->file);
        } else if ((old = mts_catalog_find(cat, it->stem)) != NULL) {
            report_to(report, MTS_CATALOG_SKIPPED, path,
                      "skipped: the name %s is already used by %s", it->stem, old->source);
        } else {
            /* what is not a regular file, is over the cap or is not a model
             * fails here, by name; so does one too big for the memory left,
             * which need not stop the others */
            mts_result ar = it->is_model ? add_model_file(cat, it->stem, path, report, &e1)
                                         : add_mesh_file(cat, it->stem, path, report, &e1);
            if (ar != MTS_OK) {
                nfailed++;
                report_to(report, MTS_CATALOG_FAILED, path, "%s", e1.msg);
            } else {
                added[i] = 1;
                /* said once it is true: this one may fail as well */
                if (failed_first)
                    report_to(report, MTS_CATALOG_NOTE, path,
                              "%s: %s did not load; this file is served under its name instead",
                              it->stem, failed_first->file);
            }
        }
        free(path);
    }
done:
    for (size_t i = 0; i < count; i++) {
        free(items[i].file);
        free(items[i].stem);
    }
    free(items);
    free(added);
    if (failed)
        *failed = nfailed;
    return r;
}
