/* What the programs share (common/cli.c): strict option parsing, the one-line
 * JSON writer (escaping, nesting), file stems. */
#include <math.h>
#include <stdint.h>

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
    return mts_test_end(&t);
}
