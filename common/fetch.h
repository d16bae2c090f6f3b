/* Downloading a model's mesh over http or https into memory (libcurl).
 *
 * Only the schemes "http" and "https" are ever used: the URL's scheme is
 * checked before any I/O, and libcurl is told the same for the request and for
 * every redirect (CURLOPT_PROTOCOLS_STR / CURLOPT_REDIR_PROTOCOLS_STR), so
 * neither "file:///etc/passwd" nor a redirect to "ftp://..." is followed. A
 * download is bounded in size (aborted as soon as the body, or the length the
 * server announces, passes the cap), in redirects, and in time (connect and
 * total timeouts). An HTTP status of 400 or more is an error naming the status.
 * TLS certificates are verified (libcurl's default, never turned off here).
 * Proxies come from the usual environment variables (http_proxy, no_proxy...),
 * as for curl(1).
 *
 * libcurl's global initialisation is not thread-safe, and calling it
 * implicitly from a library would be global state behind the caller's back.
 * So a program calls mts_fetch_global_init() once from main(), before any
 * thread starts and before the first mts_fetch_url(), and
 * mts_fetch_global_cleanup() once at exit. After that, mts_fetch_url() may be
 * called from any thread (each call has its own handle and signals are not
 * used: CURLOPT_NOSIGNAL). */
#ifndef MTS_FETCH_H
#define MTS_FETCH_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"
#include "progress.h"

#define MTS_FETCH_DEFAULT_MAX_BYTES ((uint64_t)256 << 20) /* 256 MiB */
#define MTS_FETCH_DEFAULT_CONNECT_TIMEOUT_MS 10000u
#define MTS_FETCH_DEFAULT_TIMEOUT_MS 60000u
#define MTS_FETCH_DEFAULT_MAX_REDIRECTS 5u

/* Zero-initialised means the defaults. */
typedef struct mts_fetch_options {
    uint64_t max_bytes;          /* size cap of the body; 0: 256 MiB */
    uint32_t connect_timeout_ms; /* 0: 10 s */
    uint32_t timeout_ms;         /* whole transfer; 0: 60 s */
    uint32_t max_redirects;      /* 0: 5 */
    int no_redirects;            /* 1: a redirect is an error */
    mts_progress progress;       /* stage "download", done = received / announced length */
} mts_fetch_options;

typedef struct mts_fetch_result {
    uint8_t *data;       /* the body (malloc'd, plus a terminating 0 not counted in size) */
    size_t size;
    long status;         /* final HTTP status (2xx or 3xx on success) */
    /* The last segment of the requested URL's path, percent-decoded, without
     * query or fragment ("cow.off" for http://h/m/cow.off?x=1), so that the
     * caller can pick the mesh format by extension; "" when the path ends in
     * '/'. Never contains '/' or control characters (replaced by '_'). */
    char file_name[256];
} mts_fetch_result;

/* Once from main(), before any thread starts (see above). */
mts_result mts_fetch_global_init(mts_error *err);
void mts_fetch_global_cleanup(void);

/* 1 when s looks like a URL ("scheme://..."), whatever the scheme; the
 * catalog uses it to tell a URL from a path. */
int mts_fetch_is_url(const char *s);

/* Checks the URL without any I/O: parses it, refuses every scheme but http and
 * https. */
mts_result mts_fetch_check_url(const char *url, mts_error *err);

/* Writes the URL as it may appear in messages and logs (any password
 * removed) into buf; falls back to "(invalid URL)". */
void mts_fetch_display_url(const char *url, char *buf, size_t size);

/* Downloads url into out (zeroed first; free with mts_fetch_result_free, also
 * after a failure). Errors name the URL (password removed) and the cause:
 * the refused scheme, the cap in bytes, the HTTP status, or libcurl's own
 * error text (timeout, connection refused, TLS ...). */
mts_result mts_fetch_url(const char *url, const mts_fetch_options *opts, mts_fetch_result *out,
                         mts_error *err);

void mts_fetch_result_free(mts_fetch_result *r);

#endif
