#include "fetch.h"
#include "fileio.h"

#include <curl/curl.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* URL checks, without I/O                                                   */

int mts_fetch_is_url(const char *s)
{
    if (!s || !((*s >= 'A' && *s <= 'Z') || (*s >= 'a' && *s <= 'z')))
        return 0;
    const char *p = s + 1;
    while ((*p >= 'A' && *p <= 'Z') || (*p >= 'a' && *p <= 'z') || (*p >= '0' && *p <= '9') ||
           *p == '+' || *p == '-' || *p == '.')
        p++;
    return p[0] == ':' && p[1] == '/' && p[2] == '/';
}

/* The scheme as written before ':' (at most size-1 characters, for messages
 * about URLs libcurl could not parse). */
static void scheme_of(const char *url, char *buf, size_t size)
{
    size_t n = 0;
    while (url[n] && url[n] != ':' && url[n] != '/' && n + 1 < size && n < 32)
        n++;
    if (url[n] != ':')
        n = 0;
    for (size_t i = 0; i < n; i++)
        buf[i] = (url[i] >= 0x20 && url[i] < 0x7f) ? url[i] : '?';
    buf[n] = 0;
}

/* Parses url into a new CURLU handle and checks its scheme; *out is NULL on
 * failure. shown is the URL for messages. */
static mts_result parse_url(const char *url, const char *shown, CURLU **out, mts_error *err)
{
    *out = NULL;
    if (!url || !*url)
        return mts_error_set(err, MTS_ERR_ARG, "no URL given");
    CURLU *u = curl_url();
    if (!u)
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory parsing the URL", shown);
    /* CURLU_NON_SUPPORT_SCHEME: parse any scheme, so every refused scheme gets
     * the same message below rather than a parser error. */
    CURLUcode uc = curl_url_set(u, CURLUPART_URL, url, CURLU_NON_SUPPORT_SCHEME);
    if (uc != CURLUE_OK) {
        curl_url_cleanup(u);
        char scheme[40];
        scheme_of(url, scheme, sizeof scheme);
        if (scheme[0] && !mts_ascii_ieq(scheme, "http") && !mts_ascii_ieq(scheme, "https"))
            return mts_error_set(err, MTS_ERR_ARG,
                                 "%s: scheme \"%s\" is not allowed (only http and https)", shown,
                                 scheme);
        return mts_error_set(err, MTS_ERR_ARG, "%s: not a valid http(s) URL (%s)", shown,
                             curl_url_strerror(uc));
    }
    char *scheme = NULL;
    uc = curl_url_get(u, CURLUPART_SCHEME, &scheme, 0);
    if (uc != CURLUE_OK || !scheme) {
        curl_url_cleanup(u);
        return mts_error_set(err, MTS_ERR_ARG, "%s: the URL has no scheme (give http:// or https://)",
                             shown);
    }
    int ok = mts_ascii_ieq(scheme, "http") || mts_ascii_ieq(scheme, "https");
    if (!ok) {
        mts_error_set(err, MTS_ERR_ARG, "%s: scheme \"%.32s\" is not allowed (only http and https)",
                      shown, scheme);
        curl_free(scheme);
        curl_url_cleanup(u);
        return MTS_ERR_ARG;
    }
    curl_free(scheme);
    *out = u;
    return MTS_OK;
}

void mts_fetch_display_url(const char *url, char *buf, size_t size)
{
    if (!buf || size == 0)
        return;
    snprintf(buf, size, "(invalid URL)");
    if (!url)
        return;
    CURLU *u = curl_url();
    if (!u)
        return;
    char *shown = NULL;
    if (curl_url_set(u, CURLUPART_URL, url, CURLU_NON_SUPPORT_SCHEME) == CURLUE_OK &&
        curl_url_set(u, CURLUPART_PASSWORD, NULL, 0) == CURLUE_OK &&
        curl_url_get(u, CURLUPART_URL, &shown, 0) == CURLUE_OK && shown) {
        snprintf(buf, size, "%s", shown);
    } else {
        /* Unparsable: show it up to any '@' (which could follow a password),
         * with control characters replaced. */
        size_t n = 0;
        for (; url[n] && url[n] != '@' && n + 1 < size; n++)
            buf[n] = (url[n] >= 0x20 && url[n] < 0x7f) ? url[n] : '?';
        buf[n] = 0;
    }
    curl_free(shown);
    curl_url_cleanup(u);
}

mts_result mts_fetch_check_url(const char *url, mts_error *err)
{
    char shown[256];
    mts_fetch_display_url(url, shown, sizeof shown);
    CURLU *u;
    mts_result r = parse_url(url, shown, &u, err);
    curl_url_cleanup(u);
    return r;
}

static int hexval(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

/* The last path segment, percent-decoded; '/' and control characters become '_'. */
static void file_name_of(CURLU *u, char *buf, size_t size)
{
    buf[0] = 0;
    char *path = NULL;
    if (curl_url_get(u, CURLUPART_PATH, &path, 0) != CURLUE_OK || !path)
        return;
    const char *seg = strrchr(path, '/');
    seg = seg ? seg + 1 : path;
    size_t n = 0;
    for (const char *p = seg; *p && n + 1 < size; p++) {
        unsigned char c = (unsigned char)*p;
        int hi, lo;
        if (c == '%' && (hi = hexval(p[1])) >= 0 && (lo = hexval(p[2])) >= 0) {
            c = (unsigned char)(hi * 16 + lo);
            p += 2;
        }
        buf[n++] = (c < 0x20 || c == 0x7f || c == '/' || c == '\\') ? '_' : (char)c;
    }
    buf[n] = 0;
    curl_free(path);
}

/* ------------------------------------------------------------------------ */
/* The transfer                                                              */

mts_result mts_fetch_global_init(mts_error *err)
{
    CURLcode c = curl_global_init(CURL_GLOBAL_DEFAULT);
    if (c != CURLE_OK)
        return mts_error_set(err, MTS_ERR_INTERNAL, "libcurl initialisation failed: %s",
                             curl_easy_strerror(c));
    return MTS_OK;
}

void mts_fetch_global_cleanup(void)
{
    curl_global_cleanup();
}

typedef struct sink {
    uint8_t *data;
    size_t size, cap;
    size_t max; /* the cap on size */
    int over;   /* the body passed max */
    int nomem;
    const mts_progress *progress;
} sink;

static size_t on_write(char *ptr, size_t item, size_t count, void *user)
{
    sink *s = user;
    if (item != 0 && count > SIZE_MAX / item) {
        s->over = 1;
        return 0;
    }
    size_t len = item * count;
    if (len > s->max - s->size) { /* size <= max always */
        s->over = 1;
        return 0; /* CURLE_WRITE_ERROR: the transfer stops here */
    }
    size_t need = s->size + len + 1; /* + the terminating 0; max < SIZE_MAX */
    if (need > s->cap) {
        size_t cap = s->cap ? s->cap : 65536;
        while (cap < need)
            cap = cap > SIZE_MAX / 2 ? need : cap * 2;
        if (cap > s->max + 1)
            cap = s->max + 1;
        if (cap < need)
            cap = need;
        uint8_t *grown = realloc(s->data, cap);
        if (!grown) {
            s->nomem = 1;
            return 0;
        }
        s->data = grown;
        s->cap = cap;
    }
    memcpy(s->data + s->size, ptr, len);
    s->size += len;
    s->data[s->size] = 0;
    return len;
}

static int on_progress(void *user, curl_off_t dltotal, curl_off_t dlnow, curl_off_t ultotal,
                       curl_off_t ulnow)
{
    (void)ultotal, (void)ulnow;
    sink *s = user;
    if (dltotal > 0)
        mts_progress_report(s->progress, "download",
                            dlnow >= dltotal ? 1.0 : (double)dlnow / (double)dltotal);
    return 0;
}

void mts_fetch_result_free(mts_fetch_result *r)
{
    if (!r)
        return;
    free(r->data);
    r->data = NULL;
    r->size = 0;
}

#if LIBCURL_VERSION_NUM >= 0x075500 /* 7.85.0: the string forms */
#define SET_PROTOCOLS(h)                                                                   \
    (curl_easy_setopt(h, CURLOPT_PROTOCOLS_STR, "http,https") == CURLE_OK &&               \
     curl_easy_setopt(h, CURLOPT_REDIR_PROTOCOLS_STR, "http,https") == CURLE_OK)
#else
#define SET_PROTOCOLS(h)                                                                   \
    (curl_easy_setopt(h, CURLOPT_PROTOCOLS, (long)(CURLPROTO_HTTP | CURLPROTO_HTTPS)) ==    \
         CURLE_OK &&                                                                       \
     curl_easy_setopt(h, CURLOPT_REDIR_PROTOCOLS, (long)(CURLPROTO_HTTP | CURLPROTO_HTTPS)) == \
         CURLE_OK)
#endif

mts_result mts_fetch_url(const char *url, const mts_fetch_options *opts, mts_fetch_result *out,
                         mts_error *err)
{
    if (!out)
        return mts_error_set(err, MTS_ERR_ARG, "mts_fetch_url: no result to fill");
    *out = (mts_fetch_result){0};
    char shown[256];
    mts_fetch_display_url(url, shown, sizeof shown);

    mts_fetch_options o = opts ? *opts : (mts_fetch_options){0};
    uint64_t max = o.max_bytes ? o.max_bytes : MTS_FETCH_DEFAULT_MAX_BYTES;
    if (max > (uint64_t)SIZE_MAX / 2)
        max = (uint64_t)SIZE_MAX / 2;
    if (max > (uint64_t)INT64_MAX)
        max = (uint64_t)INT64_MAX;
    uint32_t connect_ms = o.connect_timeout_ms ? o.connect_timeout_ms
                                               : MTS_FETCH_DEFAULT_CONNECT_TIMEOUT_MS;
    uint32_t total_ms = o.timeout_ms ? o.timeout_ms : MTS_FETCH_DEFAULT_TIMEOUT_MS;
    uint32_t redirects = o.max_redirects ? o.max_redirects : MTS_FETCH_DEFAULT_MAX_REDIRECTS;
    if (redirects > 100)
        redirects = 100;

    /* The scheme is checked here, before any I/O; libcurl checks it again. */
    CURLU *u;
    mts_result r = parse_url(url, shown, &u, err);
    if (r != MTS_OK)
        return r;
    file_name_of(u, out->file_name, sizeof out->file_name);

    CURL *h = curl_easy_init();
    if (!h) {
        curl_url_cleanup(u);
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: could not create a libcurl handle", shown);
    }
    char errbuf[CURL_ERROR_SIZE];
    errbuf[0] = 0;
    sink s = {0};
    s.max = (size_t)max;
    s.progress = &o.progress;

    int set = curl_easy_setopt(h, CURLOPT_ERRORBUFFER, errbuf) == CURLE_OK && SET_PROTOCOLS(h) &&
              curl_easy_setopt(h, CURLOPT_CURLU, u) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_NOSIGNAL, 1L) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_FOLLOWLOCATION, o.no_redirects ? 0L : 1L) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_MAXREDIRS, (long)redirects) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_CONNECTTIMEOUT_MS, (long)connect_ms) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_TIMEOUT_MS, (long)total_ms) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_MAXFILESIZE_LARGE, (curl_off_t)max) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_FAILONERROR, 1L) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_USERAGENT, "mtstream") == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_WRITEFUNCTION, on_write) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_WRITEDATA, &s) == CURLE_OK;
    if (set && o.progress.fn)
        set = curl_easy_setopt(h, CURLOPT_XFERINFOFUNCTION, on_progress) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_XFERINFODATA, &s) == CURLE_OK &&
              curl_easy_setopt(h, CURLOPT_NOPROGRESS, 0L) == CURLE_OK;
    if (!set) {
        /* Never go on with a handle that might allow more than asked. */
        r = mts_error_set(err, MTS_ERR_INTERNAL, "%s: libcurl refused an option: %s", shown,
                          errbuf[0] ? errbuf : "(no detail)");
        goto done;
    }

    CURLcode c = curl_easy_perform(h);
    long status = 0;
    curl_easy_getinfo(h, CURLINFO_RESPONSE_CODE, &status);
    out->status = status;
    const char *why = errbuf[0] ? errbuf : curl_easy_strerror(c);
    if (s.over || c == CURLE_FILESIZE_EXCEEDED) {
        curl_off_t announced = -1;
        curl_easy_getinfo(h, CURLINFO_CONTENT_LENGTH_DOWNLOAD_T, &announced);
        if (announced > 0 && (uint64_t)announced > max)
            r = mts_error_set(err, MTS_ERR_LIMIT,
                              "%s: the server announces %lld bytes, over the download cap of "
                              "%llu bytes",
                              shown, (long long)announced, (unsigned long long)max);
        else
            r = mts_error_set(err, MTS_ERR_LIMIT,
                              "%s: the body passed the download cap of %llu bytes", shown,
                              (unsigned long long)max);
    } else if (s.nomem) {
        r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory after %zu bytes", shown, s.size);
    } else if (c == CURLE_HTTP_RETURNED_ERROR) {
        r = mts_error_set(err, MTS_ERR_IO, "%s: HTTP status %ld", shown, status);
    } else if (c == CURLE_OPERATION_TIMEDOUT) {
        r = mts_error_set(err, MTS_ERR_IO,
                          "%s: %s (connect timeout %u ms, total timeout %u ms)", shown, why,
                          connect_ms, total_ms);
    } else if (c == CURLE_UNSUPPORTED_PROTOCOL) {
        r = mts_error_set(err, MTS_ERR_IO, "%s: %s (only http and https are allowed, redirects "
                          "included)", shown, why);
    } else if (c == CURLE_TOO_MANY_REDIRECTS) {
        r = mts_error_set(err, MTS_ERR_IO, "%s: %s (at most %u redirects)", shown, why,
                          redirects);
    } else if (c != CURLE_OK) {
        r = mts_error_set(err, MTS_ERR_IO, "%s: %s", shown, why);
    } else if (status < 200 || status >= 300) {
        r = mts_error_set(err, MTS_ERR_IO, "%s: HTTP status %ld%s", shown, status,
                          status >= 300 && status < 400 ? " (redirect not followed)" : "");
    } else {
        if (!s.data) { /* an empty body: still a valid, 0-terminated buffer */
            s.data = malloc(1);
            if (!s.data) {
                r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", shown);
                goto done;
            }
            s.data[0] = 0;
        }
        out->data = s.data;
        out->size = s.size;
        s.data = NULL;
        mts_progress_report(&o.progress, "download", 1.0);
    }
done:
    curl_easy_cleanup(h);
    curl_url_cleanup(u);
    free(s.data);
    return r;
}
