#include "tls.h"

#include <curl/curl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fileio.h"
#include "net.h"

struct mts_tls {
    CURLM *multi;
    CURL *easy;
    int ready, failed, in_multi;
    char shown[300];
    char errbuf[CURL_ERROR_SIZE];
};

void mts_tls_free(mts_tls *t)
{
    if (!t)
        return;
    if (t->in_multi)
        curl_multi_remove_handle(t->multi, t->easy);
    if (t->easy)
        curl_easy_cleanup(t->easy);
    if (t->multi)
        curl_multi_cleanup(t->multi);
    free(t);
}

mts_result mts_tls_start(mts_tls **out, const char *host, const char *port,
                         const mts_tls_options *opts, mts_error *err)
{
    *out = NULL;
    mts_tls_options o = {0};
    if (opts)
        o = *opts;
    /* only what a host name or address holds: the URL below is ours */
    for (const char *p = host; *p; p++)
        if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') ||
              *p == '.' || *p == '-' || *p == ':'))
            return mts_error_set(err, MTS_ERR_ARG, "'%s' is not a host name or address", host);
    char *end;
    long pn = strtol(port, &end, 10);
    if (!*port || *end || pn < 1 || pn > 65535)
        return mts_error_set(err, MTS_ERR_ARG, "'%s' is not a port", port);
    if (!*host || strlen(host) > 253)
        return mts_error_set(err, MTS_ERR_ARG, "'%s' is not a host name or address", host);
    if (o.cacert) {
        /* a CA file that cannot be read is named here, not as a TLS failure later */
        int fd;
        uint64_t size;
        mts_result rc = mts_file_open_regular(o.cacert, 1u << 24, NULL, &fd, &size, err);
        if (rc != MTS_OK)
            return mts_error_prefix(err, "CA certificates");
        close(fd);
    }
    mts_tls *t = calloc(1, sizeof *t);
    if (!t || !(t->multi = curl_multi_init()) || !(t->easy = curl_easy_init())) {
        mts_tls_free(t);
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for a TLS connection");
    }
    const int v6 = strchr(host, ':') != NULL;
    char url[300];
    snprintf(url, sizeof url, "https://%s%s%s:%ld/", v6 ? "[" : "", host, v6 ? "]" : "", pn);
    snprintf(t->shown, sizeof t->shown, "%s%s%s:%ld", v6 ? "[" : "", host, v6 ? "]" : "", pn);
    const long cto = (long)(1e3 * (o.connect_timeout > 0 ? o.connect_timeout : 10));
    CURL *e = t->easy;
    int set = curl_easy_setopt(e, CURLOPT_ERRORBUFFER, t->errbuf) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_URL, url) == CURLE_OK &&
              /* connect and handshake, then the channel is ours: no HTTP */
              curl_easy_setopt(e, CURLOPT_CONNECT_ONLY, 1L) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_NOSIGNAL, 1L) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_CONNECTTIMEOUT_MS, cto) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_SSL_VERIFYPEER, 1L) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_SSL_VERIFYHOST, 2L) == CURLE_OK &&
              /* the terminator speaks our protocol, not HTTP/2 or 1.1 */
              curl_easy_setopt(e, CURLOPT_SSL_ENABLE_ALPN, 0L) == CURLE_OK &&
              curl_easy_setopt(e, CURLOPT_TCP_NODELAY, 1L) == CURLE_OK;
    if (set && o.cacert)
        set = curl_easy_setopt(e, CURLOPT_CAINFO, o.cacert) == CURLE_OK;
    if (!set) {
        mts_error_set(err, MTS_ERR_INTERNAL, "%s: libcurl refused an option: %s", t->shown,
                      t->errbuf[0] ? t->errbuf : "(no detail)");
        mts_tls_free(t);
        return MTS_ERR_INTERNAL;
    }
    if (curl_multi_add_handle(t->multi, e) != CURLM_OK) {
        mts_tls_free(t);
        return mts_error_set(err, MTS_ERR_INTERNAL, "libcurl could not start a connection");
    }
    t->in_multi = 1;
    int running;
    curl_multi_perform(t->multi, &running);
    *out = t;
    return MTS_OK;
}

static int handshake_failed(mts_tls *t, CURLcode code, mts_error *err)
{
    const char *why = t->errbuf[0] ? t->errbuf : curl_easy_strerror(code);
    t->failed = 1;
    switch (code) {
    case CURLE_PEER_FAILED_VERIFICATION:
#if LIBCURL_VERSION_NUM < 0x073e00
    case CURLE_SSL_CACERT:
#endif
    case CURLE_SSL_CACERT_BADFILE:
        mts_error_set(err, MTS_ERR_ARG,
                      "%s: the server's TLS certificate did not verify: %s (a private CA: "
                      "--cacert FILE)",
                      t->shown, why);
        return -1;
    case CURLE_SSL_CONNECT_ERROR:
        mts_error_set(err, MTS_ERR_ARG, "%s: the TLS handshake failed: %s (is this a TLS port?)",
                      t->shown, why);
        return -1;
    default:
        mts_error_set(err, MTS_ERR_IO, "cannot connect to %s over TLS: %s", t->shown, why);
        return -1;
    }
}

int mts_tls_step(mts_tls *t, int timeout_ms, mts_error *err)
{
    if (t->ready)
        return 1;
    if (t->failed)
        return mts_error_set(err, MTS_ERR_IO, "%s: the connection failed", t->shown), -1;
    for (int pass = 0; pass < 2; pass++) {
        CURLMsg *m;
        int left;
        while ((m = curl_multi_info_read(t->multi, &left)) != NULL) {
            if (m->msg != CURLMSG_DONE || m->easy_handle != t->easy)
                continue;
            /* the handle stays in the multi handle: taken out, its
             * connection would go back to the pool and the channel with it */
            CURLcode code = m->data.result;
            if (code != CURLE_OK)
                return handshake_failed(t, code, err);
            t->ready = 1;
            return 1;
        }
        if (pass == 0) {
            int running;
            curl_multi_poll(t->multi, NULL, 0, timeout_ms < 0 ? 1000 : timeout_ms, NULL);
            curl_multi_perform(t->multi, &running);
        }
    }
    return 0;
}

int mts_tls_fd(const mts_tls *t)
{
    curl_socket_t s = CURL_SOCKET_BAD;
    if (!t->ready || curl_easy_getinfo(t->easy, CURLINFO_ACTIVESOCKET, &s) != CURLE_OK)
        return -1;
    return s == CURL_SOCKET_BAD ? -1 : (int)s;
}

mts_result mts_tls_send_all(mts_tls *t, const void *data, size_t size, double timeout,
                            mts_error *err)
{
    const unsigned char *p = data;
    while (size > 0) {
        size_t n = 0;
        CURLcode code = curl_easy_send(t->easy, p, size, &n);
        if (code == CURLE_OK) {
            p += n;
            size -= n;
            continue;
        }
        if (code == CURLE_AGAIN) {
            struct pollfd pf = {mts_tls_fd(t), POLLOUT, 0};
            if (pf.fd >= 0 && poll(&pf, 1, (int)(timeout * 1000)) == 1)
                continue;
            return mts_error_set(err, MTS_ERR_IO, "%s: sending the request timed out", t->shown);
        }
        return mts_error_set(err, MTS_ERR_IO, "%s: sending the request: %s", t->shown,
                             curl_easy_strerror(code));
    }
    return MTS_OK;
}

ssize_t mts_tls_read(mts_tls *t, void *buf, size_t cap, mts_error *err)
{
    size_t n = 0;
    CURLcode code = curl_easy_recv(t->easy, buf, cap, &n);
    if (code == CURLE_AGAIN)
        return MTS_NET_AGAIN;
    if (code == CURLE_OK)
        return (ssize_t)n; /* 0: the server closed the connection */
    mts_error_set(err, MTS_ERR_IO, "%s: %s", t->shown, curl_easy_strerror(code));
    return MTS_NET_FAILED;
}
