#include "http.h"

#include <curl/curl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "clock.h"
#include "fetch.h"
#include "fileio.h"

#define DEFAULT_MAX_BYTES ((uint64_t)1 << 30)

struct mts_http_pool {
    CURLM *multi;
    mts_loop *loop;
    struct pool_sock **socks; /* by descriptor, made on first use, kept until the pool goes */
    size_t nsocks;
    double due; /* when libcurl's timer is due (mts_clock_seconds); < 0: not set */
};

struct mts_http {
    CURLM *multi; /* its own, or NULL in a pool */
    mts_http_pool *pool;
    CURLSH *share; /* in a pool: its own connection cache */
    CURL *easy;
    char *url;
    char shown[256];
    mts_http_options o;
    char errbuf[CURL_ERROR_SIZE];
    /* the transfer */
    uint64_t from, to;
    int flags;
    mts_http_on_data fn;
    void *user;
    int active;    /* added to the multi handle and not yet finished */
    CURLcode code; /* how libcurl ended it */
    /* the response (of the last hop of a redirect chain) */
    long status;
    int have_range, range_unsatisfied; /* a Content-Range came; "bytes * / N" */
    uint64_t range_first, range_last, range_total;
    int64_t content_length; /* -1: not told */
    int started;   /* the body's first piece was checked */
    uint64_t body; /* bytes of the body so far */
    uint64_t delivered;
    int whole_file, done_early, stopped;
    int failed;
    mts_error fail;
    /* The file as the first answer described it, so that a later range --
     * a resume, a continuation -- never mixes in bytes of a file rebuilt
     * under the same name meanwhile: asked for with If-Range (a server
     * whose file changed answers 200, a new whole file) and checked. */
    char etag_now[128];      /* this response's strong ETag ("" when none) */
    char etag[128];          /* the first response's */
    uint64_t size_seen;      /* the file's size as first told (0: not yet) */
    struct curl_slist *if_range;
};

static int ieq_prefix(const char *s, size_t n, const char *lower)
{
    size_t k = strlen(lower);
    if (n < k)
        return 0;
    for (size_t i = 0; i < k; i++) {
        char c = s[i];
        if (c >= 'A' && c <= 'Z')
            c = (char)(c - 'A' + 'a');
        if (c != lower[i])
            return 0;
    }
    return 1;
}

/* A decimal number at *p (digits only), at most 19 digits. */
static int number(const char **p, const char *end, uint64_t *v)
{
    const char *q = *p;
    uint64_t x = 0;
    int digits = 0;
    while (q < end && *q >= '0' && *q <= '9' && digits < 19) {
        x = x * 10 + (uint64_t)(*q++ - '0');
        digits++;
    }
    if (!digits || (q < end && *q >= '0' && *q <= '9'))
        return 0;
    *p = q;
    *v = x;
    return 1;
}

static void skip_spaces(const char **p, const char *end)
{
    while (*p < end && (**p == ' ' || **p == '\t'))
        (*p)++;
}

/* Content-Range in its three forms: "bytes A-B/TOTAL", "bytes A-B/" and a star (total
 * unknown), and a star then "/TOTAL" (the answer to a range past the end). */
static void parse_content_range(mts_http *h, const char *v, const char *end)
{
    skip_spaces(&v, end);
    if (!ieq_prefix(v, (size_t)(end - v), "bytes"))
        return;
    v += 5;
    skip_spaces(&v, end);
    uint64_t a, b, t = 0;
    if (v < end && *v == '*') {
        v++;
        if (v < end && *v == '/' && (v++, number(&v, end, &t))) {
            h->range_unsatisfied = 1;
            h->range_total = t;
        }
        return;
    }
    if (!number(&v, end, &a) || v >= end || *v++ != '-' || !number(&v, end, &b) || v >= end ||
        *v++ != '/' || b < a)
        return;
    if (v < end && *v == '*')
        t = 0;
    else if (!number(&v, end, &t) || b >= t)
        return;
    h->have_range = 1;
    h->range_first = a;
    h->range_last = b;
    h->range_total = t;
}

static size_t on_header(char *line, size_t size, size_t count, void *user)
{
    mts_http *h = user;
    size_t n = size * count;
    const char *end = line + n;
    while (end > line && (end[-1] == '\r' || end[-1] == '\n'))
        end--;
    size_t len = (size_t)(end - line);
    if (ieq_prefix(line, len, "http/")) {
        /* a new response (after a redirect, or a 100 Continue): forget the last */
        h->status = 0;
        h->have_range = h->range_unsatisfied = 0;
        h->content_length = -1;
        h->etag_now[0] = 0;
        const char *sp = memchr(line, ' ', len);
        uint64_t st;
        if (sp && (sp++, number(&sp, end, &st)) && st < 1000)
            h->status = (long)st;
    } else if (ieq_prefix(line, len, "content-range:")) {
        parse_content_range(h, line + 14, end);
    } else if (ieq_prefix(line, len, "etag:")) {
        /* only a strong one: a weak ETag may not be used with If-Range */
        const char *v = line + 5;
        skip_spaces(&v, end);
        size_t k = (size_t)(end - v);
        if (k >= 2 && *v == '"' && k < sizeof h->etag_now) {
            memcpy(h->etag_now, v, k);
            h->etag_now[k] = 0;
        }
    } else if (ieq_prefix(line, len, "content-length:")) {
        const char *v = line + 15;
        skip_spaces(&v, end);
        uint64_t x;
        if (number(&v, end, &x) && x <= INT64_MAX)
            h->content_length = (int64_t)x;
    }
    return n;
}

/* Ends the transfer from a callback with h->fail, set just before, naming the URL. */
static int failed(mts_http *h)
{
    mts_error_prefix(&h->fail, "%s", h->shown);
    h->failed = 1;
    return 0;
}

static uint64_t cap_of(const mts_http *h)
{
    return h->o.max_bytes ? h->o.max_bytes : DEFAULT_MAX_BYTES;
}

/* The first piece of the body: is this the answer to the range asked for? */
static int check_start(mts_http *h)
{
    const uint64_t cap = cap_of(h);
    if (h->status == 206) {
        if (!h->have_range)
            return mts_error_set(&h->fail, MTS_ERR_FORMAT,
                                 "a 206 answer without a valid Content-Range"),
                   failed(h);
        const uint64_t last = h->to - 1;
        int ok = h->range_first == h->from &&
                 (h->range_last == last ||
                  ((h->flags & MTS_HTTP_UP_TO) && h->range_last < last &&
                   h->range_total && h->range_last + 1 == h->range_total));
        if (!ok && h->range_first == h->from && h->range_total &&
            h->range_last + 1 == h->range_total)
            return mts_error_set(&h->fail, MTS_ERR_FORMAT,
                                 "the file ends after %llu bytes, before the end of the range "
                                 "%llu-%llu asked for (cut short?)",
                                 (unsigned long long)h->range_total, (unsigned long long)h->from,
                                 (unsigned long long)last),
                   failed(h);
        if (!ok)
            return mts_error_set(&h->fail, MTS_ERR_FORMAT,
                                 "the server sent bytes %llu-%llu for the range %llu-%llu asked "
                                 "for",
                                 (unsigned long long)h->range_first,
                                 (unsigned long long)h->range_last, (unsigned long long)h->from,
                                 (unsigned long long)last),
                   failed(h);
        if (h->range_total > cap)
            return mts_error_set(&h->fail, MTS_ERR_LIMIT,
                                 "the file is %llu bytes, over the size cap of %llu bytes",
                                 (unsigned long long)h->range_total, (unsigned long long)cap),
                   failed(h);
    } else if (h->status == 200) {
        /* the range was ignored: the whole file comes, and is used */
        h->whole_file = 1;
        if (h->content_length >= 0 && (uint64_t)h->content_length > cap)
            return mts_error_set(&h->fail, MTS_ERR_LIMIT,
                                 "the file is %llu bytes, over the size cap of %llu bytes",
                                 (unsigned long long)h->content_length, (unsigned long long)cap),
                   failed(h);
    } else {
        return mts_error_set(&h->fail, MTS_ERR_IO, "HTTP status %ld", h->status), failed(h);
    }
    /* the same file as the first answer's, or the held bytes mean nothing */
    const uint64_t size = h->status == 206 ? h->range_total
                          : h->content_length >= 0 ? (uint64_t)h->content_length
                                                   : 0;
    if ((h->etag[0] && strcmp(h->etag, h->etag_now) != 0) ||
        (h->size_seen && size && size != h->size_seen))
        return mts_error_set(&h->fail, MTS_ERR_FORMAT,
                             "the file changed on the server since its first bytes were read "
                             "(ETag %s, %llu bytes; now %s, %llu bytes): start again",
                             h->etag[0] ? h->etag : "none", (unsigned long long)h->size_seen,
                             h->etag_now[0] ? h->etag_now : "none", (unsigned long long)size),
               failed(h);
    if (!h->size_seen && !h->etag[0]) {
        memcpy(h->etag, h->etag_now, sizeof h->etag);
        h->size_seen = size;
    }
    h->started = 1;
    return 1;
}

static size_t on_body(char *data, size_t size, size_t count, void *user)
{
    mts_http *h = user;
    size_t n = size * count;
    if (!h->started && !check_start(h))
        return 0;
    /* where this piece lies in the file */
    const uint64_t at = (h->whole_file ? 0 : h->from) + h->body;
    h->body += n;
    if (h->whole_file && h->body > cap_of(h))
        return mts_error_set(&h->fail, MTS_ERR_LIMIT, "the body passed the size cap of %llu bytes",
                             (unsigned long long)cap_of(h)),
               (size_t)failed(h);
    if (!h->whole_file && at + n > h->to)
        return mts_error_set(&h->fail, MTS_ERR_FORMAT,
                             "the server sent more than the %llu bytes of the range %llu-%llu",
                             (unsigned long long)(h->to - h->from), (unsigned long long)h->from,
                             (unsigned long long)(h->to - 1)),
               (size_t)failed(h);
    uint64_t lo = at > h->from ? at : h->from, hi = at + n < h->to ? at + n : h->to;
    if (lo < hi) {
        if (h->fn(h->user, lo, (const uint8_t *)data + (lo - at), (size_t)(hi - lo))) {
            h->stopped = 1;
            return 0;
        }
        h->delivered += hi - lo;
    }
    if (h->whole_file && at + n >= h->to) {
        h->done_early = 1; /* the rest of the file is not wanted */
        return 0;
    }
    return n;
}

#if LIBCURL_VERSION_NUM >= 0x075500 /* 7.85.0: the string forms */
#define SET_PROTOCOLS(e)                                                                   \
    (curl_easy_setopt(e, CURLOPT_PROTOCOLS_STR, "http,https") == CURLE_OK &&               \
     curl_easy_setopt(e, CURLOPT_REDIR_PROTOCOLS_STR, "http,https") == CURLE_OK)
#else
#define SET_PROTOCOLS(e)                                                                   \
    (curl_easy_setopt(e, CURLOPT_PROTOCOLS, (long)(CURLPROTO_HTTP | CURLPROTO_HTTPS)) ==    \
         CURLE_OK &&                                                                       \
     curl_easy_setopt(e, CURLOPT_REDIR_PROTOCOLS, (long)(CURLPROTO_HTTP | CURLPROTO_HTTPS)) == \
         CURLE_OK)
#endif

static int pooled_setup(mts_http *h);
static CURLM *multi_of(const mts_http *h);

mts_result mts_http_create(mts_http **out, const char *url, const mts_http_options *opts,
                           mts_error *err)
{
    *out = NULL;
    mts_result rc = mts_fetch_check_url(url, err);
    if (rc != MTS_OK)
        return rc;
    mts_http *h = calloc(1, sizeof *h);
    if (h && opts && opts->pool)
        h->pool = opts->pool;
    if (!h || !(h->url = strdup(url)) || !(h->pool || (h->multi = curl_multi_init())) ||
        !(h->easy = curl_easy_init())) {
        mts_http_free(h);
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for an HTTP transfer");
    }
    mts_fetch_display_url(url, h->shown, sizeof h->shown);
    if (opts)
        h->o = *opts;
    if (h->o.cacert) {
        /* a CA file that cannot be read is named here, not as a TLS failure later */
        int fd;
        uint64_t size;
        if ((rc = mts_file_open_regular(h->o.cacert, 1u << 24, NULL, &fd, &size, err)) != MTS_OK) {
            mts_http_free(h);
            return mts_error_prefix(err, "CA certificates");
        }
        close(fd);
    }
    const long connect_ms = (long)(1e3 * (h->o.connect_timeout > 0 ? h->o.connect_timeout : 10));
    const long io_s = (long)(h->o.io_timeout > 0 ? h->o.io_timeout + 0.999 : 30);
    const long redirects = h->o.max_redirects ? (long)h->o.max_redirects : 5;
    CURL *e = h->easy;
    int set = curl_easy_setopt(e, CURLOPT_ERRORBUFFER, h->errbuf) == CURLE_OK &&
              SET_PROTOCOLS(e) && curl_easy_setopt(e, CURLOPT_URL, url) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_NOSIGNAL, 1L) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_FOLLOWLOCATION, 1L) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_MAXREDIRS, redirects) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_CONNECTTIMEOUT_MS, connect_ms) == CURLE_OK &&
              /* no byte for io_s seconds: the same rule as the TCP client's */
              curl_easy_setopt(e, CURLOPT_LOW_SPEED_LIMIT, 1L) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_LOW_SPEED_TIME, io_s) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_TIMEOUT_MS,
                               (long)(h->o.max_time > 0 ? 1e3 * h->o.max_time : 0)) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_FAILONERROR, 1L) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_HTTP_VERSION, (long)CURL_HTTP_VERSION_2TLS) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_USERAGENT, "mtstream") == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_HEADERFUNCTION, on_header) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_HEADERDATA, h) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_WRITEFUNCTION, on_body) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_WRITEDATA, h) == CURLE_OK;
    if (set && h->o.cacert)
        set = curl_easy_setopt(e, CURLOPT_CAINFO, h->o.cacert) == CURLE_OK;
    if (set && h->pool)
        set = pooled_setup(h);
    if (!set) {
        /* never go on with a handle that might allow more than asked */
        mts_error_set(err, MTS_ERR_INTERNAL, "%s: libcurl refused an option: %s", h->shown,
                      h->errbuf[0] ? h->errbuf : "(no detail)");
        mts_http_free(h);
        return MTS_ERR_INTERNAL;
    }
    *out = h;
    return MTS_OK;
}

void mts_http_cancel(mts_http *h)
{
    if (h && h->active) {
        curl_multi_remove_handle(multi_of(h), h->easy);
        h->active = 0;
        h->code = CURLE_ABORTED_BY_CALLBACK;
        h->stopped = 1;
    }
}

void mts_http_free(mts_http *h)
{
    if (!h)
        return;
    mts_http_cancel(h);
    if (h->easy)
        curl_easy_cleanup(h->easy);
    if (h->multi)
        curl_multi_cleanup(h->multi);
    if (h->share)
        curl_share_cleanup(h->share); /* after the handle: it closes the connections */
    curl_slist_free_all(h->if_range);
    free(h->url);
    free(h);
}

mts_result mts_http_get(mts_http *h, uint64_t from, uint64_t to, int flags, mts_http_on_data fn,
                        void *user, mts_error *err)
{
    if (h->active)
        return mts_error_set(err, MTS_ERR_ARG, "%s: a range is still being fetched", h->shown);
    if (to <= from || to - 1 > INT64_MAX)
        return mts_error_set(err, MTS_ERR_ARG, "%s: an empty or impossible range", h->shown);
    h->from = from;
    h->to = to;
    h->flags = flags;
    h->fn = fn;
    h->user = user;
    h->code = CURLE_OK;
    h->status = 0;
    h->have_range = h->range_unsatisfied = 0;
    h->content_length = -1;
    h->started = 0;
    h->body = h->delivered = 0;
    h->whole_file = h->done_early = h->stopped = h->failed = 0;
    h->errbuf[0] = 0;
    char range[64];
    snprintf(range, sizeof range, "%llu-%llu", (unsigned long long)from,
             (unsigned long long)(to - 1));
    if (h->etag[0] && !h->if_range) {
        char line[160];
        snprintf(line, sizeof line, "If-Range: %s", h->etag);
        if (!(h->if_range = curl_slist_append(NULL, line)) ||
            curl_easy_setopt(h->easy, CURLOPT_HTTPHEADER, h->if_range) != CURLE_OK)
            return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for a header", h->shown);
    }
    if (curl_easy_setopt(h->easy, CURLOPT_RANGE, range) != CURLE_OK ||
        curl_multi_add_handle(multi_of(h), h->easy) != CURLM_OK)
        return mts_error_set(err, MTS_ERR_INTERNAL, "%s: libcurl could not start a transfer",
                             h->shown);
    h->active = 1;
    if (h->pool)
        return MTS_OK; /* libcurl's timer asks the pool's loop to start it */
    int running;
    curl_multi_perform(h->multi, &running);
    return MTS_OK;
}

/* Takes the transfer's DONE message, if libcurl has queued it. */
static void harvest(mts_http *h)
{
    CURLMsg *m;
    int left;
    while ((m = curl_multi_info_read(h->multi, &left)) != NULL) {
        if (m->msg == CURLMSG_DONE && m->easy_handle == h->easy) {
            h->code = m->data.result;
            curl_multi_remove_handle(h->multi, h->easy);
            h->active = 0;
        }
    }
}

int mts_http_poll(mts_http *h, int timeout_ms)
{
    /* a transfer can end inside the perform of mts_http_get or of the last
     * poll: waiting on the sockets first would then sleep the whole timeout
     * on a connection that has nothing more to say */
    if (h->pool)
        return h->active; /* the pool's loop moves it, and ends it */
    harvest(h);
    if (!h->active)
        return 0;
    int running = 0;
    curl_multi_poll(h->multi, NULL, 0, timeout_ms < 0 ? 1000 : timeout_ms, NULL);
    curl_multi_perform(h->multi, &running);
    harvest(h);
    return h->active;
}

mts_result mts_http_result(mts_http *h, mts_error *err)
{
    if (h->active)
        return mts_error_set(err, MTS_ERR_ARG, "%s: the range is still being fetched", h->shown);
    if (h->failed) {
        *err = h->fail;
        return h->fail.code;
    }
    if (h->stopped)
        return mts_error_set(err, MTS_ERR_ARG, "%s: stopped by the caller", h->shown);
    const char *why = h->errbuf[0] ? h->errbuf : curl_easy_strerror(h->code);
    switch (h->code) {
    case CURLE_OK:
        break;
    case CURLE_WRITE_ERROR:
        if (h->done_early)
            return MTS_OK;
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", h->shown, why);
    case CURLE_HTTP_RETURNED_ERROR:
        if (h->status == 416)
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "%s: HTTP status 416, range not satisfiable: bytes %llu-%llu "
                                 "asked of a file of %llu bytes",
                                 h->shown, (unsigned long long)h->from,
                                 (unsigned long long)h->to - 1,
                                 (unsigned long long)h->range_total);
        /* a server that is down or overloaded (5xx, 408, 429) may answer
         * later; anything else is the request's fault and would fail again */
        return mts_error_set(err,
                             h->status >= 500 || h->status == 408 || h->status == 429
                                 ? MTS_ERR_IO
                                 : MTS_ERR_ARG,
                             "%s: HTTP status %ld", h->shown, h->status);
    case CURLE_TOO_MANY_REDIRECTS:
        return mts_error_set(err, MTS_ERR_IO, "%s: %s (at most %u redirects)", h->shown, why,
                             h->o.max_redirects ? h->o.max_redirects : 5);
    case CURLE_UNSUPPORTED_PROTOCOL:
        return mts_error_set(err, MTS_ERR_IO,
                             "%s: %s (only http and https are allowed, redirects included)",
                             h->shown, why);
    case CURLE_PEER_FAILED_VERIFICATION:
#if LIBCURL_VERSION_NUM < 0x073e00
    case CURLE_SSL_CACERT:
#endif
    case CURLE_SSL_CACERT_BADFILE:
        return mts_error_set(err, MTS_ERR_IO,
                             "%s: the server's TLS certificate does not verify (%s); a server "
                             "with a private CA needs that CA's certificate",
                             h->shown, why);
    case CURLE_OPERATION_TIMEDOUT:
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", h->shown, why);
    default:
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", h->shown, why);
    }
    if (h->status >= 300)
        return mts_error_set(err, MTS_ERR_IO, "%s: HTTP status %ld%s", h->shown, h->status,
                             h->status < 400 ? " (a redirect not followed)" : "");
    if (!h->started && h->to > h->from)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: an empty answer to bytes %llu-%llu",
                             h->shown, (unsigned long long)h->from,
                             (unsigned long long)h->to - 1);
    const uint64_t want = h->to - h->from;
    const int short_ok = (h->flags & MTS_HTTP_UP_TO) &&
                         ((h->have_range && h->range_total &&
                           h->from + h->delivered == h->range_total) ||
                          (h->whole_file && h->from + h->delivered == h->body));
    if (h->delivered != want && !short_ok)
        return mts_error_set(err, MTS_ERR_IO,
                             "%s: the transfer ended after %llu of the %llu bytes of the range "
                             "%llu-%llu",
                             h->shown, (unsigned long long)h->delivered,
                             (unsigned long long)want, (unsigned long long)h->from,
                             (unsigned long long)h->to - 1);
    return MTS_OK;
}

mts_http_info mts_http_last(const mts_http *h)
{
    mts_http_info i = {0};
    i.status = h->status;
    i.body_bytes = h->body;
    i.whole_file = h->whole_file;
    i.timed_out = h->code == CURLE_OPERATION_TIMEDOUT;
    i.no_connection = h->code == CURLE_COULDNT_CONNECT || h->code == CURLE_COULDNT_RESOLVE_HOST ||
                      h->code == CURLE_SSL_CONNECT_ERROR ||
                      h->code == CURLE_PEER_FAILED_VERIFICATION ||
                      h->code == CURLE_SSL_CACERT_BADFILE;
    i.file_size = h->have_range ? h->range_total
                  : h->whole_file && h->content_length >= 0 ? (uint64_t)h->content_length
                  : h->range_unsatisfied ? h->range_total
                                         : 0;
    long v = 0;
    if (curl_easy_getinfo(h->easy, CURLINFO_HTTP_VERSION, &v) == CURLE_OK)
        i.http_version = v == CURL_HTTP_VERSION_2_0 ? 2 : v == CURL_HTTP_VERSION_3 ? 3 : 1;
    return i;
}

const char *mts_http_url(const mts_http *h)
{
    return h->shown;
}

/* ---- the pool (http.h): one multi handle on an mts_loop ----------------- */

/* A descriptor libcurl asked the loop to watch. Records are made per
 * descriptor number and kept until the pool is freed: the loop may still
 * hold an event for one whose socket was closed during its round. */
typedef struct pool_sock {
    mts_loop_io io;
    int watched;
} pool_sock;

static CURLM *multi_of(const mts_http *h)
{
    return h->pool ? h->pool->multi : h->multi;
}

/* A pooled handle: a connection cache of its own, so that it is one user
 * with its own connection rather than one of many sharing the multi
 * handle's; found from libcurl's messages by its private pointer. */
static int pooled_setup(mts_http *h)
{
    if (!(h->share = curl_share_init()))
        return 0;
    return curl_share_setopt(h->share, CURLSHOPT_SHARE, CURL_LOCK_DATA_CONNECT) == CURLSHE_OK &&
           curl_easy_setopt(h->easy, CURLOPT_SHARE, h->share) == CURLE_OK &&
           curl_easy_setopt(h->easy, CURLOPT_PRIVATE, (char *)h) == CURLE_OK;
}

/* The transfers libcurl finished: each handle is told, from here, outside
 * libcurl, so that it may start its next range at once. */
static void pool_harvest(mts_http_pool *p)
{
    CURLMsg *m;
    int left;
    while ((m = curl_multi_info_read(p->multi, &left)) != NULL) {
        if (m->msg != CURLMSG_DONE)
            continue;
        char *priv = NULL;
        curl_easy_getinfo(m->easy_handle, CURLINFO_PRIVATE, &priv);
        mts_http *h = (mts_http *)(void *)priv;
        const CURLcode code = m->data.result;
        curl_multi_remove_handle(p->multi, m->easy_handle); /* m is not read after this */
        if (!h || !h->active)
            continue;
        h->code = code;
        h->active = 0;
        if (h->o.on_end)
            h->o.on_end(h->o.end_user, h);
    }
}

static void pool_on_socket(mts_loop *loop, mts_loop_io *io, unsigned events)
{
    (void)loop;
    mts_http_pool *p = io->user;
    pool_sock *ps = (pool_sock *)(void *)io; /* io is its first member */
    if (!ps->watched)
        return; /* closed earlier in this round */
    int what = (events & MTS_LOOP_IN ? CURL_CSELECT_IN : 0) |
               (events & MTS_LOOP_OUT ? CURL_CSELECT_OUT : 0) |
               (events & MTS_LOOP_ERR ? CURL_CSELECT_ERR : 0);
    int running;
    curl_multi_socket_action(p->multi, io->fd, what, &running);
    pool_harvest(p);
}

/* libcurl says what to watch a socket for. A watch the kernel refuses
 * leaves the transfer to libcurl's own timeouts, which then fail it. */
static int pool_socket_fn(CURL *easy, curl_socket_t s, int what, void *user, void *sockp)
{
    (void)easy;
    mts_http_pool *p = user;
    if (s < 0)
        return 0;
    if ((size_t)s >= p->nsocks) {
        if (what == CURL_POLL_REMOVE)
            return 0;
        size_t n = p->nsocks ? p->nsocks : 64;
        while (n <= (size_t)s)
            n *= 2;
        pool_sock **grown = realloc(p->socks, n * sizeof *grown);
        if (!grown)
            return -1;
        memset(grown + p->nsocks, 0, (n - p->nsocks) * sizeof *grown);
        p->socks = grown;
        p->nsocks = n;
    }
    pool_sock *ps = p->socks[s];
    if (what == CURL_POLL_REMOVE) {
        if (ps && ps->watched) {
            mts_loop_unwatch(p->loop, &ps->io);
            ps->watched = 0;
        }
        return 0;
    }
    if (!ps && !(ps = p->socks[s] = calloc(1, sizeof *ps)))
        return -1;
    const unsigned ev = (what & CURL_POLL_IN ? MTS_LOOP_IN : 0) |
                        (what & CURL_POLL_OUT ? MTS_LOOP_OUT : 0);
    if (sockp && ps->watched)
        return mts_loop_set(p->loop, &ps->io, ev) == 0 ? 0 : -1;
    /* a socket new to libcurl (no pointer assigned yet): its number may
     * have been watched for an earlier socket that was closed without a
     * word (which took it off epoll), so it is watched afresh */
    if (ps->watched)
        mts_loop_unwatch(p->loop, &ps->io);
    ps->watched = mts_loop_watch(p->loop, &ps->io, s, ev, pool_on_socket, p) == 0;
    if (ps->watched)
        curl_multi_assign(p->multi, s, ps);
    return ps->watched ? 0 : -1;
}

static int pool_timer_fn(CURLM *multi, long timeout_ms, void *user)
{
    (void)multi;
    mts_http_pool *p = user;
    p->due = timeout_ms < 0 ? -1 : mts_clock_seconds() + (double)timeout_ms / 1e3;
    return 0;
}

mts_result mts_http_pool_create(mts_http_pool **out, mts_loop *loop, mts_error *err)
{
    *out = NULL;
    mts_http_pool *p = calloc(1, sizeof *p);
    if (!p || !(p->multi = curl_multi_init())) {
        free(p);
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for an HTTP pool");
    }
    p->loop = loop;
    p->due = -1;
    if (curl_multi_setopt(p->multi, CURLMOPT_SOCKETFUNCTION, pool_socket_fn) != CURLM_OK ||
        curl_multi_setopt(p->multi, CURLMOPT_SOCKETDATA, p) != CURLM_OK ||
        curl_multi_setopt(p->multi, CURLMOPT_TIMERFUNCTION, pool_timer_fn) != CURLM_OK ||
        curl_multi_setopt(p->multi, CURLMOPT_TIMERDATA, p) != CURLM_OK) {
        mts_http_pool_free(p);
        return mts_error_set(err, MTS_ERR_INTERNAL, "libcurl refused the pool's callbacks");
    }
    *out = p;
    return MTS_OK;
}

void mts_http_pool_free(mts_http_pool *p)
{
    if (!p)
        return;
    curl_multi_cleanup(p->multi);
    for (size_t i = 0; i < p->nsocks; i++) {
        if (p->socks[i] && p->socks[i]->watched)
            mts_loop_unwatch(p->loop, &p->socks[i]->io);
        free(p->socks[i]);
    }
    free(p->socks);
    free(p);
}

int mts_http_pool_tick(mts_http_pool *p)
{
    if (p->due < 0)
        return -1;
    double now = mts_clock_seconds();
    if (now >= p->due) {
        p->due = -1;
        int running;
        curl_multi_socket_action(p->multi, CURL_SOCKET_TIMEOUT, 0, &running);
        pool_harvest(p);
        if (p->due < 0)
            return -1;
        now = mts_clock_seconds();
    }
    double ms = (p->due - now) * 1e3;
    return ms <= 0 ? 0 : (int)ms + 1;
}
