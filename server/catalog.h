/* The server's models, each under a short name.
 *
 * Names: 1..64 characters of [A-Za-z0-9._-], not starting with '.'. A name
 * asked for by a client is looked up in the in-memory table only
 * (mts_catalog_find): no model name ever reaches the filesystem.
 *
 * mts_catalog_add_dir (`--models DIR`) adds, from DIR itself (no
 * subdirectories, no hidden files):
 *   - every NAME.mtsm, loaded as is;
 *   - every mesh file NAME.off/.obj/.ply/.stl (extension in any case), built
 *     with mts_build_model and cached as a model file (below).
 * The name is the file name without its last extension. When a .mtsm and a
 * mesh share a name, the .mtsm wins and the mesh is reported as a note; two
 * meshes with one name (cow.off, cow.ply): the first in byte order of the file
 * names wins, the others are skipped with a reason. A file whose name is not a
 * valid model name is skipped with a reason; a file that fails to load or
 * build is reported with its message; neither stops the others. Failing to
 * load includes not being a regular file (a directory, a FIFO, a device, a
 * symbolic link to nothing or to one of those: never opened so as to block),
 * being over max_mesh_bytes (refused before it is read), not being a mesh
 * (refused from its first bytes where the format allows), and running out
 * of memory for it. The messages never quote a file's contents, and file
 * names reach the report with every byte outside printable ASCII as '?'.
 *
 * The cache. A mesh D/F is cached as
 *   D/.F.mtsm                          when no cache_dir is given and D is writable,
 *   CACHE/.F.<hash of D's real path>.mtsm   in opts.cache_dir when given, else in
 *                                      ${TMPDIR:-/tmp}/mtstream-cache-UID (created 0700,
 *                                      used only when it is ours, no symlink, not
 *                                      writable by others).
 * Cache files start with '.', so a later scan never takes them for models.
 * A cache is used only when its build key (model.build_key, the model file's
 * KEY section; model.source is only the mesh's path) is exactly the key
 * of the mesh as it is now: "size S, mtime SEC.NSEC, base_vertices B,
 * mtsm MAJOR: F". So a mesh that changed in any way (newer, or replaced by
 * an older file, or another size) or other build options mean a rebuild, and
 * a mesh newer than its cache is rebuilt without even reading the cache: a
 * stale cache is never served. A cache that fails to load is rebuilt too (a
 * note); a cache that cannot be written is a note, the model is still served.
 *
 * mts_catalog_add (`--model NAME=PATH|URL`) adds one model from a .mtsm, a mesh
 * file (cached as above) or an http(s) URL (downloaded with mts_fetch_url,
 * loaded with mts_mesh_load_memory by the URL's file name, built, not cached).
 *
 * A catalog is filled at start-up from one thread; after that, find, count and
 * at only read it and may be called from any number of threads (and
 * release_model changes only its own entry). */
#ifndef MTS_CATALOG_H
#define MTS_CATALOG_H

#include <stddef.h>
#include <stdint.h>

#include "build.h"
#include "error.h"
#include "fetch.h"
#include "model.h"
#include "progress.h"
#include "wire.h"

/* a model's name follows the wire's one rule (mts_wire_check_name) */
#define MTS_CATALOG_NAME_MAX MTS_WIRE_MAX_NAME

typedef struct mts_catalog mts_catalog;

/* Zero-initialised means the defaults. */
typedef struct mts_catalog_options {
    const char *cache_dir; /* NULL: beside each mesh when writable, else a per-user temp dir;
                              created (one level, 0700) when missing */
    int no_cache;          /* 1: build meshes in memory only, never read or write a cache */
    uint32_t base_vertices; /* for builds (mts_build_options); 0: the builder's default */
    /* The largest mesh or model file read, caches included, and the largest
     * download (with fetch.max_bytes, the smaller cap applies); a larger
     * one fails by name before it is read. 0: MTS_MESH_DEFAULT_MAX_BYTES */
    uint64_t max_mesh_bytes;
    mts_fetch_options fetch; /* for URL models (its progress is replaced by progress below) */
    /* Progress of downloads and builds; the stage is "NAME: stage" (stages
     * "download", "load", then the builder's). */
    mts_progress progress;
} mts_catalog_options;

typedef enum mts_catalog_origin {
    MTS_CATALOG_MODEL_FILE = 1, /* a .mtsm, loaded as is */
    MTS_CATALOG_CACHED,         /* a mesh whose cached model was fresh: no build */
    MTS_CATALOG_BUILT           /* a mesh (file or URL) built now */
} mts_catalog_origin;

typedef struct mts_catalog_entry {
    char name[MTS_CATALOG_NAME_MAX + 1];
    mts_model model;
    const char *source;     /* the file path or the URL (password removed) */
    const char *cache_path; /* the cached model read or written; NULL when none */
    uint64_t source_bytes;  /* bytes of the .mtsm, mesh file or download */
    mts_catalog_origin origin;
} mts_catalog_entry;

/* What add_dir and add tell about single files, for the caller to print. */
typedef enum mts_catalog_report_kind {
    MTS_CATALOG_ADDED = 1, /* a model was added; message: how (loaded, from cache, built) */
    MTS_CATALOG_NOTE,      /* worth knowing, nothing lost: a mesh shadowed by its .mtsm,
                              a cache rebuilt or not writable */
    MTS_CATALOG_SKIPPED,   /* a file not served on purpose: bad name, name taken */
    MTS_CATALOG_FAILED     /* a file that could not be loaded or built; message: the error */
} mts_catalog_report_kind;

typedef struct mts_catalog_report {
    /* file: the path of the file concerned (or the URL); message: one line,
     * without the file name unless part of an error text. */
    void (*fn)(void *user, mts_catalog_report_kind kind, const char *file, const char *message);
    void *user;
} mts_catalog_report;

/* 1 when name is a valid model name. */
int mts_catalog_name_valid(const char *name);
/* The same with a reason in err (MTS_ERR_ARG) naming the rule broken. */
mts_result mts_catalog_check_name(const char *name, mts_error *err);

mts_result mts_catalog_create(const mts_catalog_options *opts, mts_catalog **out, mts_error *err);
void mts_catalog_free(mts_catalog *cat);

/* Adds every model of dir (see above). Fails only when dir cannot be read or
 * memory runs out listing it; single files' problems, their memory included,
 * go to report (may be NULL). failed
 * (may be NULL) gets the number of FAILED reports. */
mts_result mts_catalog_add_dir(mts_catalog *cat, const char *dir,
                               const mts_catalog_report *report, unsigned *failed,
                               mts_error *err);

/* Adds one model named name from a path or an http(s) URL. A bad name, a name
 * already used, a refused URL, or a file that fails are errors; notes (cache)
 * go to report (may be NULL). */
mts_result mts_catalog_add(mts_catalog *cat, const char *name, const char *path_or_url,
                           const mts_catalog_report *report, mts_error *err);

/* Parses "NAME=PATH|URL" (the --model argument) and adds it. */
mts_result mts_catalog_add_spec(mts_catalog *cat, const char *spec,
                                const mts_catalog_report *report, mts_error *err);

/* Looks name up in the table (NULL when absent or not a valid name). find_n
 * takes a name of len bytes, not 0-terminated (from a wire message). */
const mts_catalog_entry *mts_catalog_find(const mts_catalog *cat, const char *name);
const mts_catalog_entry *mts_catalog_find_n(const mts_catalog *cat, const char *name, size_t len);

/* Entries in byte order of their names, for listing. */
size_t mts_catalog_count(const mts_catalog *cat);
const mts_catalog_entry *mts_catalog_at(const mts_catalog *cat, size_t i);

/* Frees entry i's model (a stream holds its own copy once encoded); the
 * name and source stay. Entries are separate: threads may release
 * different ones at once. */
void mts_catalog_release_model(mts_catalog *cat, size_t i);

#endif
