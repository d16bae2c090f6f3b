/* The fuzz targets' entry code (tests/fuzz/fuzz_*.c) in the ordinary builds:
 * every input a fuzzer found a bug with, kept in tests/fuzz/regressions/
 * <target>/ after the fix, every input of the corpus `make fuzz-long` keeps
 * in tests/fuzz/corpus/<target>/, and every seed (tests/fuzz/fuzz_seeds.h)
 * goes through the same function LLVMFuzzerTestOneInput calls. A target checks its
 * own promises and aborts when one breaks, so a regression ends this program
 * (and the ASan build catches what a plain build would not). */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include "test.h"

#define MTS_FUZZ_NO_ENTRY
#include "fuzz/fuzz_draco.c"
#include "fuzz/fuzz_gltf.c"
#include "fuzz/fuzz_modelfile.c"
#include "fuzz/fuzz_request.c"
#include "fuzz/fuzz_seeds.h"
#include "fuzz/fuzz_stream_client.c"
#include "fuzz/fuzz_stream_file.c"
#include "fuzz/fuzz_ws.c"

/* Some kept inputs once made the library ask for many GB (one made Draco
 * fill 24 GB until the kernel killed it). Should one regress, the allocation
 * must fail here, not take the machine: the plain build runs under an address
 * space limit, the ASan build (whose shadow memory needs terabytes of address
 * space) with a cap on one allocation; either way the target sees
 * MTS_ERR_NOMEM and its checks fail. */
#if defined(__SANITIZE_ADDRESS__)
const char *__asan_default_options(void);
const char *__asan_default_options(void)
{
    return "max_allocation_size_mb=1024:allocator_may_return_null=1";
}
#endif

static void limit_memory(void)
{
#if !defined(__SANITIZE_ADDRESS__)
    struct rlimit rl = {4ull << 30, 4ull << 30};
    setrlimit(RLIMIT_AS, &rl);
#endif
}

typedef struct target {
    const char *name;
    int (*run)(const uint8_t *data, size_t size);
} target;

static const target targets[] = {
    {"stream_client", mts_fuzz_stream_client},
    {"request", mts_fuzz_request},
    {"modelfile", mts_fuzz_modelfile},
    {"draco", mts_fuzz_draco},
    {"ws", mts_fuzz_ws},
    {"stream_file", mts_fuzz_stream_file},
    {"gltf", mts_fuzz_gltf},
};

static const target *find_target(const char *name)
{
    for (size_t i = 0; i < sizeof targets / sizeof targets[0]; i++)
        if (strcmp(targets[i].name, name) == 0)
            return &targets[i];
    return NULL;
}

typedef struct seed_count {
    unsigned per_target[sizeof targets / sizeof targets[0]];
    unsigned unknown;
} seed_count;

static void run_seed(void *user, const char *target_name, const char *name, const uint8_t *data,
                     size_t size)
{
    seed_count *n = user;
    const target *t = find_target(target_name);
    if (!t) {
        n->unknown++;
        return;
    }
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  seed %s/%s (%zu bytes)\n", target_name, name, size);
    t->run(data, size);
    /* every prefix of the small seeds too: streams and files cut anywhere */
    if (size <= 2048)
        for (size_t k = 0; k < size; k++)
            t->run(data, k);
    n->per_target[t - targets]++;
}

static void test_seeds(mts_test *t)
{
    seed_count n = {{0}, 0};
    mts_error err = {0};
    mts_result rc = mts_fuzz_make_seeds("tests/data/cow.off", 1, run_seed, &n, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    CHECK(t, n.unknown == 0);
    for (size_t i = 0; i < sizeof targets / sizeof targets[0]; i++)
        CHECKF(t, n.per_target[i] >= 3, "%s: %u seeds", targets[i].name, n.per_target[i]);
}

/* The stream seeds that are whole streams (not cut short for good) reach
 * END through the target's entry code, broken connections and all: seeds
 * that stop early would leave the fuzzer shallow. */
static void check_stream_seed(void *user, const char *target_name, const char *name,
                              const uint8_t *data, size_t size)
{
    mts_test *t = user;
    if (strcmp(target_name, "stream_client") != 0 || strstr(name, "-cut-half") ||
        strstr(name, "-cut-before-end") || strstr(name, "-backlog") ||
        strcmp(name, "error") == 0)
        return;
    int ended = 0;
    mts_fuzz_stream_client_ended(data, size, &ended);
    CHECKF(t, ended, "stream seed %s did not reach its end", name);
}

static void test_stream_seeds_end(mts_test *t)
{
    mts_error err = {0};
    mts_result rc = mts_fuzz_make_seeds(NULL, 0, check_stream_seed, t, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
}

/* Every stream-file seed is a whole file: each of its stops is read to END,
 * breaks and resumes included, or the fuzzer would start shallow. */
static void check_stream_file_seed(void *user, const char *target_name, const char *name,
                                   const uint8_t *data, size_t size)
{
    mts_test *t = user;
    if (strcmp(target_name, "stream_file") != 0)
        return;
    int ends = 0, tried = 0;
    mts_fuzz_stream_file_ends(data, size, &ends, &tried);
    CHECKF(t, tried == 4 && ends == tried, "stream file seed %s: %d of %d stops ended", name,
           ends, tried);
}

static void test_stream_file_seeds_end(mts_test *t)
{
    mts_error err = {0};
    mts_result rc = mts_fuzz_make_seeds(NULL, 0, check_stream_file_seed, t, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
}

/* Every glTF seed is a whole model the reader loads: the torus, each
 * instance of it whole, with its colours where the seed has them (a seed
 * the reader refused would leave the fuzzer in the error paths). */
static void check_gltf_seed(void *user, const char *target_name, const char *name,
                            const uint8_t *data, size_t size)
{
    mts_test *t = user;
    if (strcmp(target_name, "gltf") != 0)
        return;
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result rc = mts_mesh_load_memory(name, data, size, NULL, &m, &st, &err);
    CHECKF(t, rc == MTS_OK, "glTF seed %s: %s", name, err.msg);
    if (rc != MTS_OK)
        return;
    const uint32_t instances = strstr(name, "-nodes") ? 2 : 1;
    CHECKF(t, m.vertex_count == 30 * instances && m.triangle_count == 60 * instances,
           "glTF seed %s: %u vertices, %u triangles", name, m.vertex_count, m.triangle_count);
    const int colored = strstr(name, "-colors") || strstr(name, "-sparse");
    CHECKF(t, (m.colors != NULL) == colored, "glTF seed %s: colours %s", name,
           m.colors ? "kept" : "none");
    if (strstr(name, "-ubyte"))
        CHECKF(t, st.colors_alpha && st.colors_translucent == 8,
               "glTF seed %s: alpha %d, %u translucent", name, st.colors_alpha,
               st.colors_translucent);
    mts_mesh_free(&m);
}

static void test_gltf_seeds_load(mts_test *t)
{
    mts_error err = {0};
    mts_result rc = mts_fuzz_make_seeds(NULL, 0, check_gltf_seed, t, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
}

static uint8_t *read_all(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    mts_buf b = {0};
    uint8_t chunk[4096];
    size_t got;
    while ((got = fread(chunk, 1, sizeof chunk, f)) > 0)
        mts_buf_put(&b, chunk, got);
    int bad = ferror(f) || b.failed;
    fclose(f);
    if (bad) {
        mts_buf_free(&b);
        return NULL;
    }
    *size = b.size;
    return b.data ? b.data : malloc(1); /* an empty input is an input */
}

/* Every file in root/<target>/ through its target's entry code. */
static void run_folders(mts_test *t, const char *root, const char *what)
{
    unsigned total = 0;
    for (size_t i = 0; i < sizeof targets / sizeof targets[0]; i++) {
        char dir[256];
        snprintf(dir, sizeof dir, "%s/%s", root, targets[i].name);
        DIR *d = opendir(dir);
        if (!d)
            continue; /* no bug found in this target yet */
        struct dirent *e;
        while ((e = readdir(d)) != NULL) {
            if (e->d_name[0] == '.')
                continue;
            char path[512];
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            struct stat st;
            if (stat(path, &st) != 0 || !S_ISREG(st.st_mode))
                continue;
            size_t size = 0;
            uint8_t *data = read_all(path, &size);
            CHECKF(t, data != NULL, "cannot read %s", path);
            if (!data)
                continue;
            if (getenv("MTS_TEST_VERBOSE"))
                fprintf(stderr, "  %s %s (%zu bytes)\n", what, path, size);
            targets[i].run(data, size);
            free(data);
            total++;
        }
        closedir(d);
    }
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  %u %s inputs\n", total, what);
}

static void test_regressions(mts_test *t)
{
    run_folders(t, "tests/fuzz/regressions", "regression");
}

/* The corpus make fuzz-long keeps (only inputs that reached new coverage):
 * each one again, so a change that breaks what once held shows here. */
static void test_corpus(mts_test *t)
{
    run_folders(t, "tests/fuzz/corpus", "corpus");
}

int main(void)
{
    mts_test t = {0};
    limit_memory();
    RUN(&t, test_seeds);
    RUN(&t, test_stream_seeds_end);
    RUN(&t, test_stream_file_seeds_end);
    RUN(&t, test_gltf_seeds_load);
    RUN(&t, test_regressions);
    RUN(&t, test_corpus);
    return mts_test_end(&t);
}
