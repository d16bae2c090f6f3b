/* A small Chrome DevTools Protocol client for the browser tests and
 * benchmarks: headless Chromium started with --remote-debugging-port, its
 * page driven over WebSocket with protocol/ws.c's client side (the
 * project's own RFC 6455 layer, text messages allowed), the page's state
 * read through Runtime.evaluate, pictures through Page.captureScreenshot,
 * PNGs read back with libpng to compare. Everything is static inline: a
 * test includes it whole. */
#ifndef MTS_TEST_CDP_H
#define MTS_TEST_CDP_H

#include <png.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "bytes.h"
#include "test_proc.h"
#include "ws.h"

typedef struct mts_cdp {
    pid_t pid;
    int port, fd, next_id;
    mts_ws_reader rd;
    mts_buf in; /* text received, messages one after another */
    char profile[600];
} mts_cdp;

static inline double mts_cdp_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static inline void mts_cdp_sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* Where a header line starts with name (lower case) in an HTTP head, or NULL. */
static inline const char *mts_cdp_find_header(const char *text, const char *name)
{
    size_t n = strlen(name);
    for (const char *p = strstr(text, "\r\n"); p; p = strstr(p + 2, "\r\n")) {
        size_t i = 0;
        while (i < n && p[2 + i] && (p[2 + i] | 0x20) == name[i])
            i++;
        if (i == n)
            return p;
    }
    return NULL;
}

/* A plain HTTP GET on 127.0.0.1:port (the DevTools' /json/list): the body
 * into out, 1 when the answer was 200. Chromium keeps the connection open
 * whatever "Connection: close" says, so the body ends at its
 * Content-Length, and a silent second ends the wait. */
static inline int mts_cdp_http_get(int port, const char *path, mts_buf *out)
{
    int fd = mts_test_connect(port);
    if (fd < 0)
        return 0;
    char req[512];
    int n = snprintf(req, sizeof req, "GET %s HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\n\r\n",
                     path, port);
    mts_buf all = {0};
    int ok = 0;
    if (send(fd, req, (size_t)n, MSG_NOSIGNAL) == n) {
        uint8_t buf[4096];
        for (;;) {
            struct pollfd p = {fd, POLLIN, 0};
            if (poll(&p, 1, 1000) <= 0)
                break;
            ssize_t r = recv(fd, buf, sizeof buf, 0);
            if (r <= 0)
                break;
            mts_buf_put(&all, buf, (size_t)r);
            mts_buf_u8(&all, 0); /* a terminator for the search, not counted */
            all.size--;
            const char *text = (const char *)all.data;
            const char *body = strstr(text, "\r\n\r\n");
            const char *len = body ? mts_cdp_find_header(text, "content-length:") : NULL;
            if (len && len < body &&
                (size_t)(body + 4 - text) + strtoul(len + 17, NULL, 10) <= all.size)
                break;
        }
    }
    close(fd);
    mts_buf_u8(&all, 0);
    const char *text = (const char *)all.data;
    const char *body = text ? strstr(text, "\r\n\r\n") : NULL;
    ok = body && strncmp(text, "HTTP/1.1 200", 12) == 0;
    if (ok)
        mts_buf_put(out, body + 4, strlen(body + 4) + 1);
    mts_buf_free(&all);
    return ok;
}

static inline int mts_cdp_call(mts_cdp *c, const char *method, const char *params,
                               mts_buf *reply, double seconds);

/* Headless Chromium on a free DevTools port, one blank page of width x
 * height CSS pixels, its DevTools WebSocket open, with up to 4 more
 * command-line arguments (extra, NULL-ended; NULL for none). 1 when it is
 * up within `seconds`; the browser's log goes to log. */
static inline int mts_cdp_start_with(mts_cdp *c, const char *tmp_dir, const char *log, int width,
                                     int height, double seconds, const char *const *extra)
{
    memset(c, 0, sizeof *c);
    c->fd = -1;
    c->port = mts_test_free_port();
    snprintf(c->profile, sizeof c->profile, "%.500s/cdp-profile-%d", tmp_dir, (int)getpid());
    char port_arg[64], profile_arg[700], size_arg[64];
    snprintf(port_arg, sizeof port_arg, "--remote-debugging-port=%d", c->port);
    snprintf(size_arg, sizeof size_arg, "--window-size=%d,%d", width, height);
    snprintf(profile_arg, sizeof profile_arg, "--user-data-dir=%s", c->profile);
    char *argv[20] = {"chromium", "--headless", "--no-sandbox", "--use-angle=swiftshader",
                      "--enable-unsafe-swiftshader", size_arg, "--hide-scrollbars",
                      "--no-first-run", "--disable-gpu-vsync", "--mute-audio", port_arg,
                      profile_arg};
    int n = 12;
    for (int i = 0; extra && extra[i] && i < 4; i++)
        argv[n++] = (char *)extra[i];
    argv[n++] = "about:blank";
    argv[n] = NULL;
    c->pid = mts_test_spawn(argv, log);
    if (c->pid <= 0)
        return 0;
    double until = mts_cdp_now() + seconds;
    char path[256] = "";
    while (!path[0] && mts_cdp_now() < until) {
        mts_buf list = {0};
        if (mts_cdp_http_get(c->port, "/json/list", &list)) {
            /* "webSocketDebuggerUrl": "ws://127.0.0.1:PORT/devtools/page/ID" of a page */
            const char *p = strstr((const char *)list.data, "\"type\": \"page\"");
            const char *u = p ? strstr((const char *)list.data, "/devtools/page/") : NULL;
            if (u) {
                size_t k = strcspn(u, "\"");
                if (k < sizeof path)
                    snprintf(path, sizeof path, "%.*s", (int)k, u);
            }
        }
        mts_buf_free(&list);
        if (!path[0])
            mts_cdp_sleep_ms(100);
    }
    if (!path[0])
        return 0;
    c->fd = mts_test_connect(c->port);
    if (c->fd < 0)
        return 0;
    static const char key[] = "bXRzdHJlYW0gY2RwIGtleQ==";
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", c->port);
    mts_buf req = {0};
    mts_ws_put_request(&req, host, path, key);
    int ok = !req.failed && send(c->fd, req.data, req.size, MSG_NOSIGNAL) == (ssize_t)req.size;
    mts_buf_free(&req);
    mts_buf answer = {0};
    size_t size = 0;
    mts_error err = {0};
    uint8_t ch;
    while (ok && size == 0 && recv(c->fd, &ch, 1, 0) == 1) {
        mts_buf_put(&answer, &ch, 1);
        ok = mts_ws_parse_response(answer.data, answer.size, key, &size, &err) == MTS_OK;
    }
    mts_buf_free(&answer);
    c->rd.client = 1;
    c->rd.text = 1;
    c->rd.max_message = 64u << 20; /* screenshots */
    if (!ok || size == 0)
        return 0;
    /* --window-size is the window's, not the page's: the page gets
     * width x height exactly, for pictures the size of mts-client's */
    char metrics[160];
    snprintf(metrics, sizeof metrics,
             "{\"width\":%d,\"height\":%d,\"deviceScaleFactor\":1,\"mobile\":false}", width,
             height);
    mts_buf reply = {0};
    ok = mts_cdp_call(c, "Emulation.setDeviceMetricsOverride", metrics, &reply, 10) &&
         !strstr((const char *)reply.data, "\"error\"");
    mts_buf_free(&reply);
    return ok;
}

static inline int mts_cdp_start(mts_cdp *c, const char *tmp_dir, const char *log, int width,
                                int height, double seconds)
{
    return mts_cdp_start_with(c, tmp_dir, log, width, height, seconds, NULL);
}

static inline void mts_cdp_stop(mts_cdp *c)
{
    if (c->fd >= 0)
        close(c->fd);
    c->fd = -1;
    if (c->pid > 0) {
        kill(c->pid, SIGTERM);
        for (int i = 0; i < 50; i++) {
            if (waitpid(c->pid, NULL, WNOHANG) == c->pid) {
                c->pid = 0;
                break;
            }
            mts_cdp_sleep_ms(50);
        }
        if (c->pid > 0) {
            kill(c->pid, SIGKILL);
            waitpid(c->pid, NULL, 0);
        }
    }
    c->pid = 0;
    mts_buf_free(&c->in);
    if (c->profile[0]) {
        char cmd[700];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", c->profile);
        if (system(cmd) != 0) {
        }
    }
}

/* The end of the JSON value starting at text[0] ('{'), or 0 while it is
 * not all in. */
static inline size_t mts_cdp_json_end(const char *text, size_t n)
{
    int depth = 0, in_string = 0;
    for (size_t i = 0; i < n; i++) {
        char ch = text[i];
        if (in_string) {
            if (ch == '\\')
                i++;
            else if (ch == '"')
                in_string = 0;
        } else if (ch == '"') {
            in_string = 1;
        } else if (ch == '{') {
            depth++;
        } else if (ch == '}' && --depth == 0) {
            return i + 1;
        }
    }
    return 0;
}

/* Calls method with params (a JSON object's text, or NULL) and waits for
 * its answer, the whole message into reply (NUL-terminated). 1 on an answer
 * within `seconds`. Events in between are dropped. */
static inline int mts_cdp_call(mts_cdp *c, const char *method, const char *params,
                               mts_buf *reply, double seconds)
{
    int id = ++c->next_id;
    mts_buf msg = {0}, frame = {0};
    char head[160];
    snprintf(head, sizeof head, "{\"id\":%d,\"method\":\"%s\",\"params\":", id, method);
    mts_buf_put(&msg, head, strlen(head));
    const char *pj = params ? params : "{}";
    mts_buf_put(&msg, pj, strlen(pj));
    mts_buf_put(&msg, "}", 1);
    static const uint8_t mask[4] = {0x5c, 0x13, 0xa7, 0x42};
    mts_ws_put_frame(&frame, MTS_WS_TEXT, msg.data, msg.size, mask);
    int ok = !frame.failed && send(c->fd, frame.data, frame.size, MSG_NOSIGNAL) == (ssize_t)frame.size;
    mts_buf_free(&msg);
    mts_buf_free(&frame);
    char want[32];
    int wn = snprintf(want, sizeof want, "{\"id\":%d,", id);
    double until = mts_cdp_now() + seconds;
    while (ok) {
        /* whole messages first */
        size_t end;
        while (c->in.size > 0 && (end = mts_cdp_json_end((const char *)c->in.data, c->in.size))) {
            int mine = end >= (size_t)wn && memcmp(c->in.data, want, (size_t)wn) == 0;
            if (mine) {
                reply->size = 0;
                mts_buf_put(reply, c->in.data, end);
                mts_buf_u8(reply, 0);
            }
            memmove(c->in.data, c->in.data + end, c->in.size - end);
            c->in.size -= end;
            if (mine)
                return !reply->failed;
        }
        double left = until - mts_cdp_now();
        if (left <= 0)
            return 0;
        struct pollfd p = {c->fd, POLLIN, 0};
        if (poll(&p, 1, (int)(left * 1000) + 1) <= 0)
            continue;
        uint8_t buf[65536];
        ssize_t r = recv(c->fd, buf, sizeof buf, 0);
        if (r <= 0)
            return 0;
        mts_ws_control ctl = {0};
        mts_error err = {0};
        size_t pl = 0;
        if (mts_ws_reader_feed(&c->rd, buf, (size_t)r, &pl, &ctl, &err) != MTS_OK)
            return 0;
        mts_buf_put(&c->in, buf, pl);
    }
    return 0;
}

/* The JSON string after "key":" in text, unescaped into out (non-ASCII
 * \u escapes as '?'). 1 when found. */
static inline int mts_cdp_string(const char *text, const char *key, mts_buf *out)
{
    char pat[80];
    snprintf(pat, sizeof pat, "\"%s\":\"", key);
    const char *p = strstr(text, pat);
    if (!p)
        return 0;
    out->size = 0;
    for (p += strlen(pat); *p && *p != '"'; p++) {
        char ch = *p;
        if (ch == '\\' && p[1]) {
            ch = *++p;
            if (ch == 'n')
                ch = '\n';
            else if (ch == 't')
                ch = '\t';
            else if (ch == 'u') {
                unsigned v = 0;
                if (sscanf(p + 1, "%4x", &v) == 1)
                    p += 4;
                ch = v < 128 ? (char)v : '?';
            }
        }
        mts_buf_u8(out, (uint8_t)ch);
    }
    mts_buf_u8(out, 0);
    return !out->failed;
}

/* The value of a JavaScript expression that gives a string (e.g.
 * JSON.stringify(...)), into out. */
static inline int mts_cdp_eval(mts_cdp *c, const char *expr, mts_buf *out)
{
    mts_buf params = {0}, reply = {0};
    mts_buf_put(&params, "{\"returnByValue\":true,\"expression\":\"", 36);
    for (const char *p = expr; *p; p++) {
        if (*p == '"' || *p == '\\')
            mts_buf_u8(&params, '\\');
        mts_buf_u8(&params, (uint8_t)*p);
    }
    mts_buf_put(&params, "\"}", 3); /* with the NUL */
    int ok = mts_cdp_call(c, "Runtime.evaluate", (const char *)params.data, &reply, 10) &&
             mts_cdp_string((const char *)reply.data, "value", out);
    mts_buf_free(&params);
    mts_buf_free(&reply);
    return ok;
}

static inline int mts_cdp_navigate(mts_cdp *c, const char *url)
{
    char params[1200];
    snprintf(params, sizeof params, "{\"url\":\"%s\"}", url);
    mts_buf reply = {0};
    int ok = mts_cdp_call(c, "Page.navigate", params, &reply, 10) &&
             !strstr((const char *)reply.data, "errorText");
    mts_buf_free(&reply);
    return ok;
}

static inline int mts_cdp_b64(int ch)
{
    if (ch >= 'A' && ch <= 'Z')
        return ch - 'A';
    if (ch >= 'a' && ch <= 'z')
        return ch - 'a' + 26;
    if (ch >= '0' && ch <= '9')
        return ch - '0' + 52;
    return ch == '+' ? 62 : ch == '/' ? 63 : -1;
}

/* The page as a PNG file. */
static inline int mts_cdp_screenshot(mts_cdp *c, const char *path)
{
    mts_buf reply = {0}, b64 = {0}, png = {0};
    int ok = mts_cdp_call(c, "Page.captureScreenshot", "{\"format\":\"png\"}", &reply, 20) &&
             mts_cdp_string((const char *)reply.data, "data", &b64);
    uint32_t acc = 0;
    int bits = 0;
    for (size_t i = 0; ok && i + 1 < b64.size; i++) {
        int v = mts_cdp_b64(b64.data[i]);
        if (v < 0)
            continue; /* '=' padding */
        acc = acc << 6 | (uint32_t)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            mts_buf_u8(&png, (uint8_t)(acc >> bits));
        }
    }
    FILE *f = ok ? fopen(path, "wb") : NULL;
    ok = f && png.size > 8 && fwrite(png.data, 1, png.size, f) == png.size;
    if (f)
        ok = fclose(f) == 0 && ok;
    mts_buf_free(&reply);
    mts_buf_free(&b64);
    mts_buf_free(&png);
    return ok;
}

/* How far two PNGs of the same size are apart: the share of pixels whose
 * largest channel difference is over `tolerance`. -1 when they cannot be
 * read or differ in size. */
static inline double mts_cdp_png_diff(const char *a, const char *b, int tolerance)
{
    png_image im[2];
    uint8_t *px[2] = {NULL, NULL};
    const char *paths[2] = {a, b};
    int ok = 1;
    for (int k = 0; k < 2; k++) {
        memset(&im[k], 0, sizeof im[k]);
        im[k].version = PNG_IMAGE_VERSION;
        if (!ok || !png_image_begin_read_from_file(&im[k], paths[k])) {
            ok = 0;
            continue;
        }
        im[k].format = PNG_FORMAT_RGB;
        px[k] = malloc(PNG_IMAGE_SIZE(im[k]));
        ok = px[k] && png_image_finish_read(&im[k], NULL, px[k], 0, NULL);
    }
    double share = -1;
    if (ok && im[0].width == im[1].width && im[0].height == im[1].height) {
        size_t n = (size_t)im[0].width * im[0].height, over = 0;
        for (size_t i = 0; i < n; i++) {
            int d = 0;
            for (int ch = 0; ch < 3; ch++) {
                int x = abs((int)px[0][3 * i + ch] - (int)px[1][3 * i + ch]);
                d = x > d ? x : d;
            }
            over += d > tolerance;
        }
        share = (double)over / (double)n;
    }
    free(px[0]);
    free(px[1]);
    return share;
}

#endif
