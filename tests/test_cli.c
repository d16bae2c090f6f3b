/* What the programs share (common/cli.c): strict option parsing, the one-line
 * JSON writer (escaping, nesting), file stems, the heap on huge pages. */
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "test.h"

static void test_parse_u32(mts_test *t)
{
    uint32_t x = 7;
    CHECK(t, cli_parse_u32("0", &x) && x == 0);
    CHECK(t, cli_parse_u32("4294967295", &x) && x == 4294967295u);
    const char *bad[] = {"", "-1", "+1", " 1", "1 ", "4294967296", "12a", "0x10", "1e3"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        CHECKF(t, !cli_parse_u32(bad[i], &x), "'%s' accepted", bad[i]);
    CHECK(t, !cli_parse_u32(NULL, &x));
}

/* An option's value, its range checked; the index moves onto the value. The
 * failing cases print their usage line to stderr, as the programs do. */
static void test_option_u32(mts_test *t)
{
    char *argv[] = {"prog", "--n", "5", "--n", "9", "--n", "x", "--n"};
    int argc = (int)(sizeof argv / sizeof argv[0]), i = 1;
    uint32_t v = 7;
    CHECK(t, cli_option_u32(argc, argv, &i, "prog", 0, 8, &v) && v == 5 && i == 2);
    i = 3;
    CHECK(t, !cli_option_u32(argc, argv, &i, "prog", 0, 8, &v) && v == 5); /* over hi */
    i = 3;
    CHECK(t, cli_option_u32(argc, argv, &i, "prog", 9, UINT32_MAX, &v) && v == 9 && i == 4);
    i = 3;
    CHECK(t, !cli_option_u32(argc, argv, &i, "prog", 10, UINT32_MAX, &v) && v == 9); /* under lo */
    i = 5;
    CHECK(t, !cli_option_u32(argc, argv, &i, "prog", 0, 8, &v) && v == 9); /* not a number */
    i = 7;
    CHECK(t, !cli_option_u32(argc, argv, &i, "prog", 0, 8, &v) && v == 9); /* no value */
}

static void test_parse_double(mts_test *t)
{
    double d = 0;
    CHECK(t, cli_parse_double("0.25", &d) && d == 0.25);
    CHECK(t, cli_parse_double("1e-3", &d) && d == 1e-3);
    const char *bad[] = {"", "abc", "1.5x", "nan", "inf", " 2", "1e999"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        CHECKF(t, !cli_parse_double(bad[i], &d), "'%s' accepted", bad[i]);
}

static void test_json_line(mts_test *t)
{
    char buf[1024] = {0};
    FILE *f = fmemopen(buf, sizeof buf - 1, "w");
    CHECK(t, f != NULL);
    if (!f)
        return;
    cli_json j;
    cli_json_begin(&j, f);
    cli_json_str(&j, "name", "a \"quoted\"\\path\n\x01 \xff\xc3\xa9");
    cli_json_u64(&j, "n", 18446744073709551615ull);
    cli_json_object_begin(&j, "inner");
    cli_json_num(&j, "x", 1.5, 2);
    cli_json_bool(&j, "ok", 1);
    cli_json_object_end(&j);
    cli_json_num(&j, "nan", NAN, 2);
    cli_json_end(&j);
    fclose(f);
    /* a byte that is not UTF-8 becomes U+FFFD; a character that is stays */
    const char *want = "{\"name\":\"a \\\"quoted\\\"\\\\path\\n\\u0001 \\ufffd\xc3\xa9\","
                       "\"n\":18446744073709551615,"
                       "\"inner\":{\"x\":1.50,\"ok\":true},\"nan\":null}\n";
    CHECKF(t, strcmp(buf, want) == 0, "got %s", buf);
}

static void test_stem(mts_test *t)
{
    char out[64];
    cli_stem("dir/sub/bunny00.off", out, sizeof out);
    CHECK(t, strcmp(out, "bunny00") == 0);
    cli_stem("noext", out, sizeof out);
    CHECK(t, strcmp(out, "noext") == 0);
    cli_stem(".hidden", out, sizeof out);
    CHECK(t, strcmp(out, ".hidden") == 0);
    cli_stem("a.b.c", out, sizeof out);
    CHECK(t, strcmp(out, "a.b") == 0);
    cli_stem("long_name.off", out, 5);
    CHECK(t, strcmp(out, "long") == 0);
    out[0] = 'x';
    cli_stem("a.off", out, 0); /* no room: nothing written */
    CHECK(t, out[0] == 'x');
}

static void test_parse_server(mts_test *t)
{
    char host[64] = "127.0.0.1", port[16] = "7447";
    CHECK(t, cli_parse_server("example.org", host, sizeof host, port, sizeof port));
    CHECK(t, !strcmp(host, "example.org") && !strcmp(port, "7447"));
    CHECK(t, cli_parse_server("10.0.0.1:9000", host, sizeof host, port, sizeof port));
    CHECK(t, !strcmp(host, "10.0.0.1") && !strcmp(port, "9000"));
    CHECK(t, cli_parse_server("[::1]:8000", host, sizeof host, port, sizeof port));
    CHECK(t, !strcmp(host, "::1") && !strcmp(port, "8000"));
    CHECK(t, cli_parse_server("fe80::1", host, sizeof host, port, sizeof port));
    CHECK(t, !strcmp(host, "fe80::1"));
    CHECK(t, !cli_parse_server("[::1", host, sizeof host, port, sizeof port));
    CHECK(t, !cli_parse_server(":7447", host, sizeof host, port, sizeof port));
    CHECK(t, !cli_parse_server("[::1]x", host, sizeof host, port, sizeof port));
}

static void test_parse_stop(mts_test *t)
{
    uint8_t kind = 0;
    uint32_t value = 0;
    CHECK(t, cli_parse_stop("--level", "12", &kind, &value) == 1 && kind == 1 && value == 12);
    CHECK(t, cli_parse_stop("--triangles", "500", &kind, &value) == 1 && kind == 2 && value == 500);
    CHECK(t, cli_parse_stop("--fraction", "0.25", &kind, &value) == 1 && kind == 3 &&
                 value == 250000);
    CHECK(t, cli_parse_stop("--fraction", "1.5", &kind, &value) == -1);
    CHECK(t, cli_parse_stop("--level", "-1", &kind, &value) == -1);
    CHECK(t, cli_parse_stop("--level", NULL, &kind, &value) == -1);
    CHECK(t, cli_parse_stop("--png", "x.png", &kind, &value) == 0);
}

/* what cli_heap_on_huge_pages can do in this build: 1 where it applies */
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define HEAP_CASE 0 /* a sanitizer's malloc */
#elif defined(__linux__) && defined(__GLIBC__) && UINTPTR_MAX > 0xffffffffu
#define HEAP_CASE 1
#else
#define HEAP_CASE 2
#endif

#if HEAP_CASE == 1
/* Whether [at, at + bytes) lies in one mapping advised as huge pages ("hg"
 * among its VmFlags in /proc/self/smaps): -1 where smaps cannot be read. */
static int advised_huge(const void *at, size_t bytes)
{
    FILE *f = fopen("/proc/self/smaps", "r");
    if (!f)
        return -1;
    const uintptr_t a = (uintptr_t)at, b = a + bytes;
    char line[512];
    int inside = 0, found = 0;
    while (fgets(line, sizeof line, f)) {
        unsigned long lo, hi;
        if (sscanf(line, "%lx-%lx ", &lo, &hi) == 2) {
            inside = a >= lo && b <= hi;
        } else if (inside && !strncmp(line, "VmFlags:", 8)) {
            found = strstr(line, " hg") != NULL;
            break;
        }
    }
    fclose(f);
    return found;
}

static void *malloc_elsewhere(void *bytes)
{
    return malloc(*(size_t *)bytes);
}
#endif

/* After cli_heap_on_huge_pages, blocks of every thread come from the heap
 * (below the break), the heap's stretch is advised as huge pages, and a
 * freed block stays in the heap (the break does not move back). Under a
 * sanitizer's malloc it declines and changes nothing. */
static void test_heap_on_huge_pages(mts_test *t)
{
    const size_t bytes = (size_t)32 << 20;
    const int done = cli_heap_on_huge_pages(bytes);
#if HEAP_CASE == 0
    CHECK(t, !done);
    SKIP(t, "a sanitizer's malloc: the heap is its own");
#elif HEAP_CASE == 1
    if (!done && access("/sys/kernel/mm/transparent_hugepage", F_OK) != 0)
        SKIP(t, "a kernel without transparent huge pages");
    CHECK(t, done == 1);
    if (!done)
        return;
    size_t size = (size_t)4 << 20;
    char *p = malloc(size);
    CHECK(t, p != NULL);
    if (!p)
        return;
    memset(p, 1, size);
    const uintptr_t brk_now = (uintptr_t)sbrk(0);
    CHECKF(t, (uintptr_t)p + size <= brk_now, "a 4 MB block at %p, the break at %p", (void *)p,
           (void *)brk_now);
    /* its whole 2 MB pages: the block itself may begin in the heap's first
     * stretch, below the advised one */
    const uintptr_t huge = (uintptr_t)2 << 20;
    const uintptr_t lo = ((uintptr_t)p + huge - 1) & ~(huge - 1);
    const int hg = advised_huge((void *)lo, huge);
    if (hg < 0)
        SKIP(t, "/proc/self/smaps not readable");
    CHECK(t, hg == 1);
    free(p);
    CHECK(t, (uintptr_t)sbrk(0) == brk_now);
    pthread_t th;
    void *q = NULL;
    size = (size_t)1 << 20;
    CHECK(t, pthread_create(&th, NULL, malloc_elsewhere, &size) == 0 && pthread_join(th, &q) == 0);
    CHECKF(t, q && (uintptr_t)q + size <= (uintptr_t)sbrk(0), "another thread's block at %p", q);
    free(q);
#else
    CHECK(t, !done);
    SKIP(t, "not glibc on 64-bit Linux");
#endif
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_parse_u32);
    RUN(&t, test_option_u32);
    RUN(&t, test_parse_double);
    RUN(&t, test_json_line);
    RUN(&t, test_stem);
    RUN(&t, test_parse_server);
    RUN(&t, test_parse_stop);
    RUN(&t, test_heap_on_huge_pages);
    return mts_test_end(&t);
}
