/* What the command-line programs share: a progress bar on a terminal, a
 * monotonic clock, strict number parsing for options, and a tiny one-line
 * JSON writer. Programs only; the library never prints. */
#ifndef MTS_CLI_H
#define MTS_CLI_H

#include <stdint.h>
#include <stdio.h>

#include "progress.h"

/* Exit statuses, as usual for command-line tools. */
enum { CLI_EXIT_OK = 0, CLI_EXIT_FAIL = 1, CLI_EXIT_USAGE = 2 };

double cli_now(void); /* seconds, monotonic */

/* A progress bar on stderr, drawn only when stderr is a terminal and the
 * program is not quiet; redrawn at most every 50 ms. */
typedef struct cli_bar {
    int enabled;
    double last_draw;
    char stage[32];
} cli_bar;

void cli_bar_init(cli_bar *bar, int quiet);
void cli_bar_update(void *bar, const char *stage, double done); /* an mts_progress fn */
void cli_bar_done(cli_bar *bar);
static inline mts_progress cli_bar_progress(cli_bar *bar)
{
    mts_progress p = {cli_bar_update, bar};
    return p;
}

/* The process's peak resident memory since the last call (VmHWM, Linux),
 * in bytes, and the peak reset (clear_refs 5) so the next call sees the
 * next stretch's; 0 where /proc says nothing. */
uint64_t cli_peak_rss_reset(void);

/* Strict parsers: the whole string must be a number in range. */
int cli_parse_u32(const char *s, uint32_t *out);
int cli_parse_double(const char *s, double *out);
/* A size in bytes: a whole number, optionally with a binary suffix K, M, G
 * or T (k, m, g, t too: 2^10, 2^20, 2^30, 2^40), as in "512M" or "4G". */
int cli_parse_bytes(const char *s, uint64_t *out);

/* The value of the option argv[*i] as a whole number from lo to hi: *i moves
 * onto the value. A missing or bad value prints "prog: OPTION needs a whole
 * number from lo to hi" to stderr and returns 0, for main() to exit with
 * CLI_EXIT_USAGE. */
int cli_option_u32(int argc, char **argv, int *i, const char *prog, uint32_t lo, uint32_t hi,
                   uint32_t *out);

/* One-line JSON: cli_json_begin, then keys, then cli_json_end (adds '\n'). */
typedef struct cli_json {
    FILE *f;
    int depth;
    int first[8];
} cli_json;

void cli_json_begin(cli_json *j, FILE *f);
void cli_json_key(cli_json *j, const char *key); /* before a value or object */
void cli_json_object_begin(cli_json *j, const char *key);
void cli_json_object_end(cli_json *j);
void cli_json_str(cli_json *j, const char *key, const char *value);
/* A JSON string's body (no quotes): quotes, backslashes and control bytes
 * escaped, any byte of a sequence that is not UTF-8 written as U+FFFD, so a
 * peer's or a file system's bytes never break the line. */
void cli_json_text(FILE *f, const char *s);
void cli_json_u64(cli_json *j, const char *key, uint64_t value);
void cli_json_num(cli_json *j, const char *key, double value, int decimals);
void cli_json_bool(cli_json *j, const char *key, int value);
void cli_json_end(cli_json *j);

/* HOST[:PORT], [V6]:PORT or a bare IPv6 address into host and port; port is
 * left as it was (the default) when none is given. 0 when malformed. */
int cli_parse_server(const char *server, char *host, size_t host_size, char *port,
                     size_t port_size);

/* Raises the open-file soft limit toward need, as far as the hard limit
 * allows; returns 1 when it raised it. now and hard get the limits after. */
int cli_raise_nofile(uint64_t need, uint64_t *now, uint64_t *hard);

/* Puts the process's malloc heap on huge pages, for a program that builds
 * one large model from nothing (mts-client). Such a process touches every
 * page of its heap once, and on the virtual machines this project runs on
 * a 4 KB page's first touch (a fault and its zeroing) costs some 10 us,
 * a large share of a fresh client's time even with its large arrays on
 * huge pages (common/bigmem.h; docs/threads.md, "The heap on huge pages").
 * So the heap is grown by `bytes`
 * at once and that stretch advised as huge pages (a hint; memory still
 * follows what is touched, in 2 MB steps), every thread allocates from it
 * (one malloc arena: another thread's arena is a mapping of malloc's own,
 * which nothing here can advise), and freed memory stays in it, not handed
 * back to the kernel and faulted in again. malloc then carves even large
 * blocks from that free stretch, and calloc clears them: an array sized by
 * a count a peer claims must be mts_bigmem_zeroed's, not calloc's, for
 * memory to follow what arrived. glibc on 64-bit Linux only; call
 * before any thread starts. 1: done; 0: not here (under a sanitizer's or
 * another malloc, a refused extension), the heap as it was. */
int cli_heap_on_huge_pages(size_t bytes);

/* The stop options every streaming program takes: --level L, --triangles N,
 * --fraction F. 1: it was one (kind and value set, as in mts_wire_stop);
 * 0: opt is another option; -1: its value is missing or malformed. */
int cli_parse_stop(const char *opt, const char *value, uint8_t *kind, uint32_t *stop_value);

/* What a stop option's value must be, for the usage message: "a whole
 * number" (--level, --triangles) or "a number from 0 to 1" (--fraction). */
const char *cli_stop_value_kind(const char *opt);

/* cli_parse_stop on the option argv[*i] and the word after it: 1 it was a
 * stop option (*i moves onto its value), 0 another option, -1 a missing or
 * bad value, said on stderr as "prog: OPTION needs ..." for main() to exit
 * with CLI_EXIT_USAGE. */
int cli_option_stop(int argc, char **argv, int *i, const char *prog, uint8_t *kind,
                    uint32_t *stop_value);

/* "name" from "dir/name.ext". */
void cli_stem(const char *path, char *out, size_t size);

#endif
