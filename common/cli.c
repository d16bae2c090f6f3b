#include "cli.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#if defined(__linux__) && defined(__GLIBC__) && UINTPTR_MAX > 0xffffffffu
#include <limits.h>
#include <malloc.h>
#include <sys/mman.h>
#define CLI_HEAP_HUGE 1
#endif

#include "bigmem.h"
#include "clock.h"
#include "utf8.h"

double cli_now(void)
{
    return mts_clock_seconds();
}

void cli_bar_init(cli_bar *bar, int quiet)
{
    memset(bar, 0, sizeof *bar);
    bar->enabled = !quiet && isatty(STDERR_FILENO);
}

void cli_bar_update(void *p, const char *stage, double done)
{
    cli_bar *bar = p;
    if (!bar->enabled)
        return;
    double now = cli_now();
    int new_stage = strncmp(bar->stage, stage, sizeof bar->stage - 1) != 0;
    if (!new_stage && done < 1.0 && now - bar->last_draw < 0.05)
        return;
    bar->last_draw = now;
    snprintf(bar->stage, sizeof bar->stage, "%s", stage);
    if (!(done >= 0)) /* and NaN, which (int) below could not convert */
        done = 0;
    if (done > 1)
        done = 1;
    const int width = 30;
    int filled = (int)(done * width + 0.5);
    char cells[64];
    for (int i = 0; i < width; i++)
        cells[i] = i < filled ? '#' : '.';
    cells[width] = 0;
    fprintf(stderr, "\r%-10s [%s] %3d%%", stage, cells, (int)(done * 100 + 0.5));
    fflush(stderr);
}

void cli_bar_done(cli_bar *bar)
{
    if (bar->enabled && bar->stage[0]) {
        fprintf(stderr, "\r\033[K");
        fflush(stderr);
    }
    bar->stage[0] = 0;
}

/* strto* skip leading white space and accept a sign after it (" -1" would
 * wrap to a huge unsigned value): a number must start with a digit here. */
int cli_parse_u32(const char *s, uint32_t *out)
{
    if (!s || !isdigit((unsigned char)*s))
        return 0;
    char *end;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 10);
    if (errno || *end || v > UINT32_MAX)
        return 0;
    *out = (uint32_t)v;
    return 1;
}

int cli_parse_bytes(const char *s, uint64_t *out)
{
    if (!s || !isdigit((unsigned char)*s))
        return 0;
    char *end;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 10);
    if (errno)
        return 0;
    unsigned shift = 0;
    if (*end) {
        const char *suffixes = "kmgt";
        const char *at = end[1] ? NULL : strchr(suffixes, tolower((unsigned char)*end));
        if (!at)
            return 0;
        shift = 10 * (unsigned)(at - suffixes + 1);
    }
    if (v > (UINT64_MAX >> shift))
        return 0;
    *out = (uint64_t)v << shift;
    return 1;
}

int cli_option_u32(int argc, char **argv, int *i, const char *prog, uint32_t lo, uint32_t hi,
                   uint32_t *out)
{
    const char *opt = argv[*i];
    uint32_t v;
    if (++*i < argc && cli_parse_u32(argv[*i], &v) && v >= lo && v <= hi) {
        *out = v;
        return 1;
    }
    if (hi == UINT32_MAX)
        fprintf(stderr, "%s: %s needs a whole number of at least %u\n", prog, opt, lo);
    else
        fprintf(stderr, "%s: %s needs a whole number from %u to %u\n", prog, opt, lo, hi);
    return 0;
}

int cli_parse_double(const char *s, double *out)
{
    if (!s || !*s || isspace((unsigned char)*s))
        return 0;
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || *end || !isfinite(v))
        return 0;
    *out = v;
    return 1;
}

static void json_sep(cli_json *j)
{
    if (!j->first[j->depth])
        fputc(',', j->f);
    j->first[j->depth] = 0;
}

void cli_json_begin(cli_json *j, FILE *f)
{
    memset(j, 0, sizeof *j);
    j->f = f;
    j->first[0] = 1;
    fputc('{', f);
}

void cli_json_text(FILE *f, const char *s)
{
    const unsigned char *u = (const unsigned char *)s;
    size_t n = strlen(s);
    for (size_t i = 0; i < n;) {
        const unsigned char c = u[i];
        const size_t k = mts_utf8_seq_len(u + i, n - i);
        if (c == '"' || c == '\\')
            fprintf(f, "\\%c", c);
        else if (c == '\n')
            fputs("\\n", f);
        else if (c < 0x20 || c == 0x7f)
            fprintf(f, "\\u%04x", c);
        else if (k == 0)
            fputs("\\ufffd", f); /* not UTF-8: a JSON parser would refuse the line */
        else
            fwrite(u + i, 1, k, f);
        i += k ? k : 1;
    }
}

static void json_string(FILE *f, const char *s)
{
    fputc('"', f);
    cli_json_text(f, s);
    fputc('"', f);
}

void cli_json_key(cli_json *j, const char *key)
{
    json_sep(j);
    json_string(j->f, key);
    fputc(':', j->f);
}

void cli_json_object_begin(cli_json *j, const char *key)
{
    cli_json_key(j, key);
    fputc('{', j->f);
    if (j->depth < 7)
        j->depth++;
    j->first[j->depth] = 1;
}

void cli_json_object_end(cli_json *j)
{
    fputc('}', j->f);
    if (j->depth > 0)
        j->depth--;
}

void cli_json_str(cli_json *j, const char *key, const char *value)
{
    cli_json_key(j, key);
    json_string(j->f, value);
}

void cli_json_u64(cli_json *j, const char *key, uint64_t value)
{
    cli_json_key(j, key);
    fprintf(j->f, "%llu", (unsigned long long)value);
}

void cli_json_num(cli_json *j, const char *key, double value, int decimals)
{
    cli_json_key(j, key);
    if (isfinite(value))
        fprintf(j->f, "%.*f", decimals, value);
    else
        fputs("null", j->f);
}

void cli_json_bool(cli_json *j, const char *key, int value)
{
    cli_json_key(j, key);
    fputs(value ? "true" : "false", j->f);
}

void cli_json_end(cli_json *j)
{
    fputs("}\n", j->f);
    fflush(j->f);
}

void cli_stem(const char *path, char *out, size_t size)
{
    if (size == 0)
        return;
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    size_t n = dot && dot != base ? (size_t)(dot - base) : strlen(base);
    if (n >= size)
        n = size - 1;
    memcpy(out, base, n);
    out[n] = 0;
}

int cli_parse_server(const char *server, char *host, size_t host_size, char *port,
                     size_t port_size)
{
    const char *colon = strrchr(server, ':');
    if (server[0] == '[') { /* [v6]:port */
        const char *close = strchr(server, ']');
        if (!close || (close[1] && close[1] != ':') || (size_t)(close - server - 1) >= host_size)
            return 0;
        snprintf(host, host_size, "%.*s", (int)(close - server - 1), server + 1);
        if (close[1] == ':')
            snprintf(port, port_size, "%s", close + 2);
    } else if (colon && strchr(server, ':') != colon) {
        /* more than one ':' without brackets: a bare IPv6 address */
        snprintf(host, host_size, "%s", server);
    } else if (colon) {
        if ((size_t)(colon - server) >= host_size)
            return 0;
        snprintf(host, host_size, "%.*s", (int)(colon - server), server);
        snprintf(port, port_size, "%s", colon + 1);
    } else {
        snprintf(host, host_size, "%s", server);
    }
    return host[0] != 0 && port[0] != 0;
}

int cli_raise_nofile(uint64_t need, uint64_t *now, uint64_t *hard)
{
    struct rlimit rl;
    *now = *hard = 0;
    if (getrlimit(RLIMIT_NOFILE, &rl) != 0)
        return 0;
    *now = rl.rlim_cur;
    *hard = rl.rlim_max == RLIM_INFINITY ? UINT64_MAX : rl.rlim_max;
    if ((uint64_t)rl.rlim_cur >= need)
        return 0;
    rlim_t to = *hard >= need ? (rlim_t)need : rl.rlim_max;
    rl.rlim_cur = to;
    if (setrlimit(RLIMIT_NOFILE, &rl) != 0)
        return 0;
    *now = to;
    return 1;
}

int cli_heap_on_huge_pages(size_t bytes)
{
#ifdef CLI_HEAP_HUGE
    const uintptr_t huge = (uintptr_t)2 << 20;
    if (bytes < 2 * huge || bytes > (size_t)INT_MAX - huge)
        return 0;
    /* a threshold past `bytes` for the extension below to come from the
     * heap (a sanitizer's malloc refuses these and leaves the heap alone) */
    if (!mallopt(M_ARENA_MAX, 1) || !mallopt(M_TRIM_THRESHOLD, INT_MAX) ||
        !mallopt(M_MMAP_THRESHOLD, (int)(bytes + huge)))
        return 0;
    const uintptr_t start = (uintptr_t)sbrk(0);
    char *p = malloc(bytes);
    const uintptr_t end = (uintptr_t)sbrk(0);
    const uintptr_t at = (uintptr_t)p;
    int ok = 0;
    /* from the heap: the break moved, and the block lies below it (it may
     * begin below the old break, in the free top the heap had) */
    if (p && end > start && at + bytes <= end) {
        /* the whole 2 MB pages inside the block; freeing it leaves them at
         * the heap's top, where the next allocations come from */
        const uintptr_t lo = (at + huge - 1) & ~(huge - 1), hi = (at + bytes) & ~(huge - 1);
        ok = hi > lo && madvise((void *)lo, hi - lo, MADV_HUGEPAGE) == 0;
    }
    free(p);
    /* Once the stretch is used up, blocks from MTS_BIGMEM_FROM on are
     * mappings of their own again (the large growing arrays are bigmem's
     * anyway). While free heap memory holds a block malloc takes it from
     * there, whatever the threshold, and calloc clears it: so an array
     * sized by what a stream claims is a zeroed reservation
     * (mts_bigmem_zeroed), never a calloc block. */
    mallopt(M_MMAP_THRESHOLD, (int)MTS_BIGMEM_FROM);
    return ok;
#else
    (void)bytes;
    return 0;
#endif
}

const char *cli_stop_value_kind(const char *opt)
{
    const char *dash = strrchr(opt, '-');
    return dash && !strcmp(dash, "-fraction") ? "a number from 0 to 1" : "a whole number";
}

int cli_option_stop(int argc, char **argv, int *i, const char *prog, uint8_t *kind,
                    uint32_t *stop_value)
{
    const char *opt = argv[*i], *v = *i + 1 < argc ? argv[*i + 1] : NULL;
    int r = cli_parse_stop(opt, v, kind, stop_value);
    if (r < 0)
        fprintf(stderr, "%s: %s needs %s\n", prog, opt, cli_stop_value_kind(opt));
    else if (r > 0)
        ++*i;
    return r;
}

int cli_parse_stop(const char *opt, const char *value, uint8_t *kind, uint32_t *stop_value)
{
    if (!strcmp(opt, "--level") || !strcmp(opt, "--triangles")) {
        if (!value || !cli_parse_u32(value, stop_value))
            return -1;
        *kind = !strcmp(opt, "--level") ? 1 : 2; /* MTS_STOP_LEVEL, MTS_STOP_TRIANGLES */
        return 1;
    }
    if (!strcmp(opt, "--fraction")) {
        double f;
        if (!value || !cli_parse_double(value, &f) || f < 0 || f > 1)
            return -1;
        *kind = 3; /* MTS_STOP_FRACTION, in millionths */
        *stop_value = (uint32_t)(f * 1e6 + 0.5);
        return 1;
    }
    return 0;
}

uint64_t cli_peak_rss_reset(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    if (!f)
        return 0;
    char line[256];
    unsigned long long kb = 0;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "VmHWM: %llu kB", &kb) == 1)
            break;
    fclose(f);
    f = fopen("/proc/self/clear_refs", "w");
    if (f) {
        fputs("5", f); /* resets the peak to the present size */
        fclose(f);
    }
    return (uint64_t)kb * 1024u;
}
