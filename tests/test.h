/* A small test harness: each tests/test_*.c is one program that runs its
 * cases and prints "N passed, N failed, N skipped"; tests/run.sh adds them up.
 *
 *   static void test_something(mts_test *t) { CHECK(t, 1 + 1 == 2); }
 *   int main(void) { mts_test t = {0}; RUN(&t, test_something); return mts_test_end(&t); }
 */
#ifndef MTS_TEST_H
#define MTS_TEST_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>

typedef struct mts_test {
    int passed, failed, skipped;
    int case_failed, case_skipped;
    const char *case_name;
} mts_test;

#define CHECK(t, cond)                                                                 \
    do {                                                                               \
        if (!(cond)) {                                                                 \
            fprintf(stderr, "  FAIL %s:%d: %s\n", __FILE__, __LINE__, #cond);          \
            (t)->case_failed = 1;                                                      \
        }                                                                              \
    } while (0)

#define CHECKF(t, cond, ...)                                                           \
    do {                                                                               \
        if (!(cond)) {                                                                 \
            fprintf(stderr, "  FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond);          \
            fprintf(stderr, __VA_ARGS__);                                              \
            fputc('\n', stderr);                                                       \
            (t)->case_failed = 1;                                                      \
        }                                                                              \
    } while (0)

/* Marks the current case skipped, with a reason that is printed. */
#define SKIP(t, ...)                                                                   \
    do {                                                                               \
        fprintf(stderr, "  SKIP %s: ", (t)->case_name);                                \
        fprintf(stderr, __VA_ARGS__);                                                  \
        fputc('\n', stderr);                                                           \
        (t)->case_skipped = 1;                                                         \
        return;                                                                        \
    } while (0)

#define RUN(t, fn)                                                                     \
    do {                                                                               \
        (t)->case_name = #fn;                                                          \
        (t)->case_failed = 0;                                                          \
        (t)->case_skipped = 0;                                                         \
        fn(t);                                                                         \
        if ((t)->case_failed) {                                                        \
            (t)->failed++;                                                             \
            fprintf(stderr, "not ok %s\n", #fn);                                       \
        } else if ((t)->case_skipped) {                                                \
            (t)->skipped++;                                                            \
        } else {                                                                       \
            (t)->passed++;                                                             \
            if (getenv("MTS_TEST_VERBOSE"))                                            \
                fprintf(stderr, "ok %s\n", #fn);                                       \
        }                                                                              \
    } while (0)

static inline int mts_test_end(mts_test *t)
{
    printf("%d passed, %d failed, %d skipped\n", t->passed, t->failed, t->skipped);
    return t->failed ? 1 : 0;
}

/* Path of a shared model (../shared/models/NAME, or $MTS_MODELS/NAME), or NULL
 * when it is not there: callers SKIP with the path they looked at. */
static inline const char *mts_test_model(const char *name, char *buf, size_t size)
{
    const char *dir = getenv("MTS_MODELS");
    if (!dir || !*dir)
        dir = "../shared/models";
    snprintf(buf, size, "%s/%s", dir, name);
    struct stat st;
    return stat(buf, &st) == 0 ? buf : NULL;
}

/* Runs a shell command with stdout and stderr captured together into out;
 * returns its exit status (-1 when it did not exit normally). */
static inline int mts_test_run(const char *cmd, char *out, size_t size)
{
    char full[8192];
    snprintf(full, sizeof full, "(%.8000s) 2>&1", cmd);
    FILE *p = popen(full, "r");
    if (!p)
        return -1;
    size_t n = fread(out, 1, size - 1, p);
    out[n] = 0;
    int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* A scratch directory for files a test writes; MTS_TEST_TMP is created if
 * it does not exist yet (a test that wrote into a missing one failed in ways
 * that looked like anything but that). */
static inline const char *mts_test_tmpdir(void)
{
    const char *d = getenv("MTS_TEST_TMP");
    if (!d || !*d)
        return "/tmp";
    (void)mkdir(d, 0755);
    return d;
}

#endif
