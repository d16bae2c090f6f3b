/* Tests of the WebSocket layer (protocol/ws.c): SHA-1 and the accept key
 * against the RFCs' own examples, the opening request as browsers send it
 * and as it must not be, frames through the reader in every split, and the
 * reader's refusals. The server's use of it, over loopback: test_server.c. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sha1.h"
#include "test.h"
#include "ws.h"

static void hex(const uint8_t *d, size_t n, char *out)
{
    for (size_t i = 0; i < n; i++)
        sprintf(out + 2 * i, "%02x", d[i]);
}

static void test_sha1_vectors(mts_test *t)
{
    /* FIPS 180 examples, and the padding's edge: 55, 56 and 64 bytes */
    struct {
        const char *in;
        const char *digest;
    } v[] = {
        {"abc", "a9993e364706816aba3e25717850c26c9cd0d89d"},
        {"", "da39a3ee5e6b4b0d3255bfef95601890afd80709"},
        {"abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq",
         "84983e441c3bd26ebaae4aa1f95129e5e54670f1"},
        {"aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa",
         "c1c8bbdc22796e28c0e15163d20899b65621d65a"},
        {"aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa",
         "c2db330f6083854c99d4b5bfb6e8f29f201be699"},
        {"aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa",
         "0098ba824b5c16427bd7a1122a5a442a25ec644d"},
    };
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++) {
        uint8_t d[MTS_SHA1_SIZE];
        char h[41];
        mts_sha1(v[i].in, strlen(v[i].in), d);
        hex(d, sizeof d, h);
        CHECKF(t, strcmp(h, v[i].digest) == 0, "sha1 of %zu bytes: %s", strlen(v[i].in), h);
    }
    /* RFC 6455 1.3's example key */
    char accept[29];
    mts_ws_accept_key("dGhlIHNhbXBsZSBub25jZQ==", accept);
    CHECKF(t, strcmp(accept, "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=") == 0, "%s", accept);
}

/* What Chromium sends (its headers as of version 120-ish). */
static const char CHROME_REQUEST[] =
    "GET /ws HTTP/1.1\r\n"
    "Host: 127.0.0.1:7448\r\n"
    "Connection: Upgrade\r\n"
    "Pragma: no-cache\r\n"
    "Cache-Control: no-cache\r\n"
    "User-Agent: Mozilla/5.0 (X11; Linux x86_64) AppleWebKit/537.36 (KHTML, like Gecko) "
    "Chrome/120.0.0.0 Safari/537.36\r\n"
    "Upgrade: websocket\r\n"
    "Origin: http://127.0.0.1:7448\r\n"
    "Sec-WebSocket-Version: 13\r\n"
    "Accept-Encoding: gzip, deflate, br\r\n"
    "Accept-Language: en-US,en;q=0.9\r\n"
    "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
    "Sec-WebSocket-Extensions: permessage-deflate; client_max_window_bits\r\n"
    "\r\n";

static void test_request_from_a_browser(mts_test *t)
{
    mts_ws_request req;
    mts_error err = {0};
    size_t n = strlen(CHROME_REQUEST);
    /* every prefix is "more to come", the whole is an upgrade */
    for (size_t k = 0; k < n; k++) {
        mts_result rc = mts_ws_parse_request((const uint8_t *)CHROME_REQUEST, k, &req, &err);
        CHECKF(t, rc == MTS_OK && req.size == 0, "prefix %zu: %s", k, err.msg);
        if (rc != MTS_OK)
            return;
    }
    uint8_t more[sizeof CHROME_REQUEST + 8];
    memcpy(more, CHROME_REQUEST, n);
    memcpy(more + n, "\x82\x80", 2); /* a frame right behind it */
    CHECK(t, mts_ws_parse_request(more, n + 2, &req, &err) == MTS_OK);
    CHECK(t, req.size == n && req.upgrade == 1);
    CHECK(t, strcmp(req.path, "/ws") == 0 && strcmp(req.key, "dGhlIHNhbXBsZSBub25jZQ==") == 0);
    mts_buf b = {0};
    mts_ws_put_accept(&b, &req);
    CHECK(t, !b.failed);
    const char want[] = "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n"
                        "Connection: Upgrade\r\nSec-WebSocket-Accept: "
                        "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n\r\n";
    CHECK(t, b.size == strlen(want) && memcmp(b.data, want, b.size) == 0);
    /* and the client's side takes it */
    size_t size = 0;
    CHECK(t, mts_ws_parse_response(b.data, b.size, req.key, &size, &err) == MTS_OK &&
                 size == b.size);
    CHECK(t, mts_ws_parse_response(b.data, b.size - 1, req.key, &size, &err) == MTS_OK &&
                 size == 0);
    CHECK(t, mts_ws_parse_response(b.data, b.size, "AAAAAAAAAAAAAAAAAAAAAA==", &size, &err) ==
                 MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "Sec-WebSocket-Accept") != NULL, "%s", err.msg);
    mts_buf_free(&b);
    /* our own request parses too, and a plain GET is a page request */
    mts_ws_put_request(&b, "localhost:1", "/", "AAAAAAAAAAAAAAAAAAAAAA==");
    CHECK(t, mts_ws_parse_request(b.data, b.size, &req, &err) == MTS_OK && req.upgrade == 1);
    mts_buf_free(&b);
    const char page[] = "GET /index.html?x=1 HTTP/1.1\r\nHost: a\r\nAccept: */*\r\n\r\n";
    CHECK(t, mts_ws_parse_request((const uint8_t *)page, strlen(page), &req, &err) == MTS_OK);
    CHECK(t, req.size == strlen(page) && req.upgrade == 0 &&
                 strcmp(req.path, "/index.html?x=1") == 0);
}

static void test_request_refusals(mts_test *t)
{
    struct {
        const char *text;
        int status;
        const char *says;
    } bad[] = {
        {"\x05\x00\x00\x00\x02", 400, "not an HTTP request"}, /* a TCP client's LIST */
        {"POST / HTTP/1.1\r\n", 405, "only GET"},
        {"PUT", 405, "only GET"},
        {"GET / HTTP/1.0\r\nHost: a\r\n\r\n", 505, "HTTP/1.1"},
        {"GET / FTP/1.1\r\nHost: a\r\n\r\n", 400, "HTTP/1.1"},
        {"GET nopath HTTP/1.1\r\nHost: a\r\n\r\n", 400, "target"},
        {"GET  /x HTTP/1.1\r\nHost: a\r\n\r\n", 400, "malformed request line"},
        {"GET /x  HTTP/1.1\r\nHost: a\r\n\r\n", 400, "malformed request line"},
        {"GET /x HTTP/1.1 \r\nHost: a\r\n\r\n", 400, "malformed request line"},
        {"GET / HTTP/1.1\r\n\r\n", 400, "no Host"},
        {"GET / HTTP/1.1\r\nHost: a\r\nHost: b\r\n\r\n", 400, "more than one Host"},
        {"GET / HTTP/1.1\r\nHost: a\r\n folded\r\n\r\n", 400, "folded"},
        {"GET / HTTP/1.1\r\nHost a\r\n\r\n", 400, "without a name"},
        {"GET / HTTP/1.1\r\nBad Name: x\r\nHost: a\r\n\r\n", 400, "header name"},
        {"GET / HTTP/1.1\r\nHost: a\x01\r\n\r\n", 400, "control"},
        {"GET / HTTP/1.1\r\nHost: a\nX: y\r\n\r\n", 400, "CRLF"},
        {"GET / HTTP/1.1\r\nHost: a\r\nUpgrade: websocket\r\n\r\n", 400, "Connection: Upgrade"},
        {"GET / HTTP/1.1\r\nHost: a\r\nUpgrade: websocket\r\nConnection: upgrade\r\n"
         "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 8\r\n\r\n",
         426, "version"},
        {"GET / HTTP/1.1\r\nHost: a\r\nUpgrade: websocket\r\nConnection: upgrade\r\n"
         "Sec-WebSocket-Version: 13\r\n\r\n",
         400, "no Sec-WebSocket-Key"},
        {"GET / HTTP/1.1\r\nHost: a\r\nUpgrade: websocket\r\nConnection: upgrade\r\n"
         "Sec-WebSocket-Key: short==\r\nSec-WebSocket-Version: 13\r\n\r\n",
         400, "16 bytes"},
        {"GET / HTTP/1.1\r\nHost: a\r\nUpgrade: websocket\r\nConnection: upgrade\r\n"
         "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZR==\r\nSec-WebSocket-Version: 13\r\n\r\n",
         400, "16 bytes"}, /* the last character has bits past 16 bytes */
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        mts_ws_request req;
        mts_error err = {0};
        mts_result rc =
            mts_ws_parse_request((const uint8_t *)bad[i].text, strlen(bad[i].text), &req, &err);
        CHECKF(t, rc == MTS_ERR_FORMAT && req.status == bad[i].status && req.size == 0 &&
                      strstr(err.msg, bad[i].says),
               "case %zu: rc %d status %d: %s", i, rc, req.status, err.msg);
    }
    /* a head that never ends: refused at the limit, not before */
    uint8_t *big = malloc(MTS_WS_MAX_REQUEST + 1);
    CHECK(t, big != NULL);
    if (!big)
        return;
    memcpy(big, "GET / HTTP/1.1\r\nX: ", 19);
    memset(big + 19, 'a', MTS_WS_MAX_REQUEST + 1 - 19);
    mts_ws_request req;
    mts_error err = {0};
    CHECK(t, mts_ws_parse_request(big, MTS_WS_MAX_REQUEST - 1, &req, &err) == MTS_OK &&
                 req.size == 0);
    CHECK(t, mts_ws_parse_request(big, MTS_WS_MAX_REQUEST, &req, &err) == MTS_ERR_LIMIT &&
                 req.status == 431);
    free(big);
    /* the error answers are HTTP a browser shows */
    mts_buf b = {0};
    mts_ws_put_http_error(&b, 426, "use WebSocket version 13");
    CHECK(t, b.size > 0 && memcmp(b.data, "HTTP/1.1 426 Upgrade Required\r\n", 31) == 0);
    mts_buf_put(&b, "", 1); /* as a string */
    CHECK(t, !b.failed && strstr((const char *)b.data, "Sec-WebSocket-Version: 13\r\n"));
    b.size--;
    size_t size;
    CHECK(t, mts_ws_parse_response(b.data, b.size, "AAAAAAAAAAAAAAAAAAAAAA==", &size, &err) ==
                 MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "426 Upgrade Required") && strstr(err.msg, "version 13"), "%s",
           err.msg);
    mts_buf_free(&b);
}

/* A stream of frames as a client sends them: binary messages (some
 * fragmented), a ping, then a close. */
static void client_frames(mts_buf *b, uint8_t *payload, size_t *payload_len)
{
    const uint8_t mask[4] = {0x37, 0xfa, 0x21, 0x3d};
    size_t n = 0;
    uint8_t data[70000];
    for (size_t i = 0; i < sizeof data; i++)
        data[i] = (uint8_t)(i * 7 + (i >> 8));
    mts_ws_put_frame(b, MTS_WS_BINARY, data, 5, mask);
    memcpy(payload + n, data, 5);
    n += 5;
    mts_ws_put_frame(b, MTS_WS_BINARY, data, 0, mask); /* empty: legal */
    mts_ws_put_frame(b, MTS_WS_PING, "hi", 2, mask);
    /* a message in three fragments, a pong between them */
    uint8_t h[MTS_WS_MAX_HEADER];
    size_t parts[3] = {300, 200, 60000};
    size_t at = 0;
    for (int k = 0; k < 3; k++) {
        size_t hn = mts_ws_header(h, k == 0 ? MTS_WS_BINARY : MTS_WS_CONTINUATION, parts[k], mask);
        if (k < 2)
            h[0] &= 0x7f; /* FIN off */
        mts_buf_put(b, h, hn);
        size_t from = b->size;
        mts_buf_put(b, data + at, parts[k]);
        mts_ws_mask(b->data + from, parts[k], mask, 0);
        memcpy(payload + n, data + at, parts[k]);
        n += parts[k];
        at += parts[k];
        if (k == 0)
            mts_ws_put_frame(b, MTS_WS_PONG, "x", 1, mask);
    }
    mts_ws_put_close(b, MTS_WS_CLOSE_GOING_AWAY, "bye", mask);
    mts_ws_put_frame(b, MTS_WS_BINARY, data, 9, mask); /* after the close: not read */
    *payload_len = n;
}

static void test_reader_any_split(mts_test *t)
{
    mts_buf b = {0};
    static uint8_t want[70000], got[70000];
    size_t want_len;
    client_frames(&b, want, &want_len);
    CHECK(t, !b.failed);
    uint8_t *copy = malloc(b.size);
    CHECK(t, copy != NULL);
    if (!copy)
        return;
    /* pieces of 1, 2, 3, 7, 13 and 4096 bytes, and all at once */
    size_t steps[] = {1, 2, 3, 7, 13, 4096, b.size};
    for (size_t si = 0; si < sizeof steps / sizeof steps[0]; si++) {
        memcpy(copy, b.data, b.size);
        mts_ws_reader r = {0};
        mts_ws_control ctl = {0};
        mts_error err = {0};
        size_t n = 0, at = 0;
        int ok = 1;
        while (at < b.size && ok) {
            size_t piece = steps[si] < b.size - at ? steps[si] : b.size - at;
            size_t p = 0;
            ok = mts_ws_reader_feed(&r, copy + at, piece, &p, &ctl, &err) == MTS_OK;
            memcpy(got + n, copy + at, p);
            n += p;
            at += piece;
        }
        CHECKF(t, ok, "step %zu: %s", steps[si], err.msg);
        CHECKF(t, n == want_len && memcmp(got, want, n) == 0, "step %zu: %zu of %zu bytes",
               steps[si], n, want_len);
        CHECK(t, ctl.ping && ctl.pong_len == 2 && memcmp(ctl.pong, "hi", 2) == 0);
        CHECK(t, ctl.close && ctl.close_code == MTS_WS_CLOSE_GOING_AWAY && r.closed);
        CHECK(t, r.payload_in == want_len);
    }
    free(copy);
    mts_buf_free(&b);
}

/* The server's frames as the client's side reads them: unmasked, any size. */
static void test_server_frames(mts_test *t)
{
    uint8_t h[MTS_WS_MAX_HEADER];
    CHECK(t, mts_ws_header(h, MTS_WS_BINARY, 125, NULL) == 2 && h[0] == 0x82 && h[1] == 125);
    CHECK(t, mts_ws_header(h, MTS_WS_BINARY, 126, NULL) == 4 && h[1] == 126 && h[3] == 126);
    CHECK(t, mts_ws_header(h, MTS_WS_BINARY, 65535, NULL) == 4 && h[2] == 0xff);
    CHECK(t, mts_ws_header(h, MTS_WS_BINARY, 65536, NULL) == 10 && h[1] == 127 && h[7] == 1);
    uint8_t mask[4] = {1, 2, 3, 4};
    CHECK(t, mts_ws_header(h, MTS_WS_PING, 0, mask) == 6 && h[1] == 0x80);
    mts_buf b = {0};
    static uint8_t big[200000];
    for (size_t i = 0; i < sizeof big; i++)
        big[i] = (uint8_t)(i ^ (i >> 9));
    mts_ws_put_frame(&b, MTS_WS_BINARY, big, sizeof big, NULL);
    mts_ws_put_close(&b, MTS_WS_CLOSE_NORMAL, NULL, NULL);
    mts_ws_reader r = {0};
    r.client = 1;
    r.max_message = 1u << 20;
    mts_ws_control ctl = {0};
    mts_error err = {0};
    size_t p = 0;
    CHECKF(t, mts_ws_reader_feed(&r, b.data, b.size, &p, &ctl, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, p == sizeof big && memcmp(b.data, big, p) == 0);
    CHECK(t, ctl.close && ctl.close_code == MTS_WS_CLOSE_NORMAL);
    mts_buf_free(&b);
}

static void test_reader_refusals(mts_test *t)
{
    const uint8_t m[4] = {9, 8, 7, 6};
    struct {
        const char *what;
        uint8_t bytes[16];
        size_t n;
        uint16_t code;
        const char *says;
    } bad[] = {
        {"unmasked", {0x82, 0x01, 'x'}, 3, 1002, "unmasked"},
        {"rsv1 (deflate)", {0xc2, 0x81, 9, 8, 7, 6, 'x'}, 7, 1002, "reserved"},
        {"opcode 3", {0x83, 0x80, 9, 8, 7, 6}, 6, 1002, "unknown opcode"},
        {"opcode 11", {0x8b, 0x80, 9, 8, 7, 6}, 6, 1002, "unknown control"},
        {"text", {0x81, 0x81, 9, 8, 7, 6, 'x'}, 7, 1003, "text"},
        {"fragmented ping", {0x09, 0x80, 9, 8, 7, 6}, 6, 1002, "fragmented control"},
        {"long ping", {0x89, 0xfe, 0, 126, 9, 8, 7, 6}, 8, 1002, "at most 125"},
        {"lone continuation", {0x80, 0x80, 9, 8, 7, 6}, 6, 1002, "continuation"},
        {"message in message", {0x02, 0x80, 9, 8, 7, 6, 0x82, 0x80, 9, 8, 7, 6}, 12, 1002,
         "inside"},
        {"2^63 bytes", {0x82, 0xff, 0x80, 0, 0, 0, 0, 0, 0, 0, 9, 8, 7, 6}, 14, 1002, "top bit"},
        {"too big", {0x82, 0xff, 0, 0, 0, 0, 0, 1, 0, 1, 9, 8, 7, 6}, 14, 1009, "more than"},
        {"close of 1 byte", {0x88, 0x81, 9, 8, 7, 6, 1}, 7, 1002, "1 byte"},
        {"close code 1005", {0x88, 0x82, 9, 8, 7, 6, 0x03 ^ 9, 0xed ^ 8}, 8, 1002, "code 1005"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        mts_ws_reader r = {0};
        mts_ws_control ctl = {0};
        mts_error err = {0};
        size_t p = 0;
        mts_result rc = mts_ws_reader_feed(&r, bad[i].bytes, bad[i].n, &p, &ctl, &err);
        CHECKF(t, rc != MTS_OK && ctl.fail_code == bad[i].code && strstr(err.msg, bad[i].says),
               "%s: rc %d code %u: %s", bad[i].what, rc, ctl.fail_code, err.msg);
        /* and it reads nothing more */
        uint8_t ok[7] = {0x82, 0x81, 9, 8, 7, 6, 'x'};
        CHECK(t, mts_ws_reader_feed(&r, ok, 7, &p, &ctl, &err) != MTS_OK && p == 0);
    }
    (void)m;
    /* a Close's reason must be UTF-8 (1007 otherwise): overlong forms,
     * surrogates, code points past U+10FFFF and cut sequences are not */
    struct {
        const char *what;
        const char *reason;
        int valid;
    } reasons[] = {
        {"ascii", "tab closed", 1},
        {"two-byte", "caf\xc3\xa9", 1},
        {"three-byte", "\xe2\x82\xac", 1},
        {"four-byte", "\xf0\x9f\x98\x80", 1},
        {"lone continuation", "\x80", 0},
        {"overlong slash", "\xc0\xaf", 0},
        {"overlong three", "\xe0\x80\xaf", 0},
        {"surrogate", "\xed\xa0\x80", 0},
        {"past U+10FFFF", "\xf4\x90\x80\x80", 0},
        {"cut", "ok\xe2\x82", 0},
        {"bad follower", "\xc3\x28", 0},
    };
    for (size_t i = 0; i < sizeof reasons / sizeof reasons[0]; i++) {
        mts_buf b = {0};
        mts_ws_put_close(&b, MTS_WS_CLOSE_GOING_AWAY, reasons[i].reason, m);
        mts_ws_reader r = {0};
        mts_ws_control ctl = {0};
        mts_error err = {0};
        size_t p = 0;
        mts_result rc = mts_ws_reader_feed(&r, b.data, b.size, &p, &ctl, &err);
        if (reasons[i].valid)
            CHECKF(t, rc == MTS_OK && ctl.close && ctl.close_code == MTS_WS_CLOSE_GOING_AWAY,
                   "%s: %s", reasons[i].what, err.msg);
        else
            CHECKF(t, rc != MTS_OK && ctl.fail_code == MTS_WS_CLOSE_INVALID_DATA &&
                          strstr(err.msg, "UTF-8"),
                   "%s: rc %d code %u", reasons[i].what, rc, ctl.fail_code);
        mts_buf_free(&b);
    }
    /* the limit holds across fragments */
    mts_ws_reader r = {0};
    r.max_message = 10;
    mts_ws_control ctl = {0};
    mts_error err = {0};
    mts_buf b = {0};
    uint8_t h[MTS_WS_MAX_HEADER];
    size_t hn = mts_ws_header(h, MTS_WS_BINARY, 6, m);
    h[0] &= 0x7f;
    mts_buf_put(&b, h, hn);
    mts_buf_put(&b, "abcdef", 6);
    hn = mts_ws_header(h, MTS_WS_CONTINUATION, 6, m);
    mts_buf_put(&b, h, hn);
    mts_buf_put(&b, "ghijkl", 6);
    size_t p = 0;
    CHECK(t, mts_ws_reader_feed(&r, b.data, b.size, &p, &ctl, &err) == MTS_ERR_LIMIT);
    CHECK(t, p == 6 && ctl.fail_code == MTS_WS_CLOSE_TOO_BIG); /* what came before is kept */
    mts_buf_free(&b);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_sha1_vectors);
    RUN(&t, test_request_from_a_browser);
    RUN(&t, test_request_refusals);
    RUN(&t, test_reader_any_split);
    RUN(&t, test_server_frames);
    RUN(&t, test_reader_refusals);
    return mts_test_end(&t);
}
