/* mts-server --ws-listen over loopback, with a WebSocket client written
 * here on protocol/ws.c (the browser's part, minus the browser):
 *   - cow streamed over WebSocket ends with the same checksum as over TCP,
 *     at the full level and at a partial stop, and LIST answers too;
 *     every server message is at most 32 KiB (a browser sees a message only
 *     whole); a Ping is answered; the log names the client ws/...;
 *   - hostile clients get an answer that names the problem and a close,
 *     while a TCP client is served meanwhile: garbage instead of HTTP, a
 *     plain GET, a head over 4 KiB, silence before and after the upgrade
 *     (the handshake timeout holds), an unmasked frame, a text message, a
 *     Close in the middle of a stream, and one over --max-clients (503). */
#include <errno.h>
#include <poll.h>
#include <stdint.h>
#include <strings.h>

#include "clock.h"
#include "test.h"
#include "test_proc.h"
#include "wire.h"
#include "ws.h"

static char bin_dir[512], tmp_dir[512], models_dir[600];

typedef struct server {
    pid_t pid;
    int port, ws_port;
    char log[700];
} server;

static int server_start(server *sv, const char *name, const char *const *extra)
{
    snprintf(sv->log, sizeof sv->log, "%s/ws_%s.log", tmp_dir, name);
    mts_test_server ts;
    int up = mts_test_ws_server_start(&ts, bin_dir, models_dir, extra, sv->log, 30);
    sv->pid = ts.pid;
    sv->port = ts.port;
    sv->ws_port = ts.ws_port;
    return up;
}

static int count_lines(const char *text, const char *needle)
{
    int n = 0;
    for (const char *p = text; (p = strstr(p, needle)); p += strlen(needle))
        n++;
    return n;
}

static void put_hello(mts_buf *b, const char *model, uint8_t stop_kind, uint32_t stop_value,
                      uint8_t flags)
{
    mts_wire_hello h = {0};
    h.flags = flags;
    h.major = MTS_WIRE_MAJOR;
    h.minor = MTS_WIRE_MINOR;
    h.stop_kind = stop_kind;
    h.stop_value = stop_value;
    snprintf(h.model, sizeof h.model, "%s", model);
    mts_wire_put_hello(b, &h);
}

/* Everything fd sends until EOF or `seconds` pass, appended to out. */
static void read_all(int fd, mts_buf *out, double seconds)
{
    struct pollfd p = {fd, POLLIN, 0};
    uint8_t buf[8192];
    for (int waited = 0; waited < (int)(seconds * 1000);) {
        int r = poll(&p, 1, 50);
        if (r == 0) {
            waited += 50;
            continue;
        }
        ssize_t n = recv(fd, buf, sizeof buf, 0);
        if (n <= 0)
            return;
        mts_buf_put(out, buf, (size_t)n);
    }
}

/* data[0..n) holds the text s. */
static int contains(const uint8_t *data, size_t n, const char *s)
{
    size_t k = strlen(s);
    for (size_t i = 0; i + k <= n; i++) {
        if (memcmp(data + i, s, k) == 0)
            return 1;
    }
    return 0;
}

static const uint8_t MASK[4] = {0x11, 0x5a, 0xc3, 0x7e};
static const char KEY[] = "bXRzdHJlYW0gdGVzdCBrZQ=="; /* 16 bytes */

/* A WebSocket connection to port's path after its 101 (-1 on failure; the
 * answer, whatever it was, in *answer). */
static int ws_connect_to(int port, const char *path, int rcvbuf, mts_buf *answer)
{
    int fd = mts_test_connect_rcvbuf(port, rcvbuf);
    if (fd < 0)
        return -1;
    mts_buf req = {0};
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    mts_ws_put_request(&req, host, path, KEY);
    int ok = send(fd, req.data, req.size, MSG_NOSIGNAL) == (ssize_t)req.size;
    mts_buf_free(&req);
    /* byte by byte up to the blank line: the frames after it are the caller's */
    uint8_t c;
    size_t size = 0;
    mts_error err = {0};
    while (ok && size == 0 && recv(fd, &c, 1, 0) == 1) {
        mts_buf_put(answer, &c, 1);
        ok = mts_ws_parse_response(answer->data, answer->size, KEY, &size, &err) == MTS_OK;
    }
    if (!ok || size == 0) {
        close(fd);
        return -1;
    }
    return fd;
}

static int ws_connect(const server *sv, mts_buf *answer)
{
    return ws_connect_to(sv->ws_port, "/", 0, answer);
}

static int ws_send(int fd, mts_ws_opcode op, const void *data, size_t len)
{
    mts_buf b = {0};
    mts_ws_put_frame(&b, op, data, len, MASK);
    int ok = !b.failed && send(fd, b.data, b.size, MSG_NOSIGNAL) == (ssize_t)b.size;
    mts_buf_free(&b);
    return ok;
}

/* What a server's frames in raw[0..n) carry: the payload appended to out,
 * the controls in ctl; each message at most max_message bytes. */
static mts_result ws_unwrap(const mts_buf *raw, uint64_t max_message, mts_buf *out,
                            mts_ws_control *ctl, mts_error *err)
{
    mts_ws_reader r = {0};
    r.client = 1;
    r.max_message = max_message;
    mts_buf copy = {0};
    mts_buf_put(&copy, raw->data, raw->size);
    size_t p = 0;
    mts_result rc = mts_ws_reader_feed(&r, copy.data, copy.size, &p, ctl, err);
    mts_buf_put(out, copy.data, p);
    mts_buf_free(&copy);
    return rc;
}

/* The data frames (binary, continuation) among the server's frames in raw;
 * -1 where one runs past the end. */
static long data_frames(const mts_buf *raw)
{
    long count = 0;
    size_t at = 0;
    while (at + 2 <= raw->size) {
        const uint8_t op = raw->data[at] & 0x0f;
        uint64_t len = raw->data[at + 1] & 0x7f;
        size_t head = 2;
        if (len >= 126) {
            const size_t ext = len == 126 ? 2 : 8;
            if (at + 2 + ext > raw->size)
                return -1;
            len = 0;
            for (size_t k = 0; k < ext; k++)
                len = len << 8 | raw->data[at + 2 + k];
            head += ext;
        }
        if (len > raw->size - at - head)
            return -1;
        count += op == MTS_WS_BINARY || op == MTS_WS_CONTINUATION;
        at += head + (size_t)len;
    }
    return count;
}

/* The client's checksums after the stream in data[0..n); 0 when it did not
 * end well. */
static int stream_checksums(const mts_buf *data, uint64_t *ours, uint64_t *theirs)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_test_events ev = {0};
    mts_error err = {0};
    int ok = mts_test_feed(&c, data->data, data->size, 1, 1u << 20, &ev, &err) == MTS_OK &&
             ev.end == 1 && ev.error == 0;
    *ours = c.checksum;
    *theirs = c.end_checksum;
    mts_stream_client_free(&c);
    return ok;
}

/* cow's stream to a stop over TCP. */
static int tcp_stream(const server *sv, uint8_t kind, uint32_t value, uint8_t flags,
                      mts_buf *out)
{
    int fd = mts_test_connect(sv->port);
    if (fd < 0)
        return 0;
    mts_buf h = {0};
    put_hello(&h, "cow", kind, value, flags);
    int ok = send(fd, h.data, h.size, MSG_NOSIGNAL) == (ssize_t)h.size;
    mts_buf_free(&h);
    if (ok)
        read_all(fd, out, 10);
    close(fd);
    return ok;
}

static void test_stream_matches_tcp(mts_test *t)
{
    const char *extra[] = {"--rate-limit", "200000", NULL}; /* several messages, a few a tick */
    server sv;
    CHECK(t, server_start(&sv, "stream", extra));
    struct {
        uint8_t kind;
        uint32_t value;
        uint8_t flags;
    } stops[] = {{MTS_STOP_FULL, 0, 0},
                 {MTS_STOP_LEVEL, 500, 0},
                 {MTS_STOP_FRACTION, 250000, 0},
                 /* the records form: 230 KB, so several 32 KiB messages */
                 {MTS_STOP_FULL, 0, MTS_HELLO_RECORDS}};
    for (int k = 0; k < 4; k++) {
        mts_buf tcp = {0}, answer = {0}, raw = {0}, inner = {0};
        CHECK(t, tcp_stream(&sv, stops[k].kind, stops[k].value, stops[k].flags, &tcp));
        int fd = ws_connect(&sv, &answer);
        CHECKF(t, fd >= 0, "no 101: %.*s", (int)answer.size, (const char *)answer.data);
        if (fd < 0)
            break;
        /* a Ping first, and the HELLO split over two frames of one message */
        CHECK(t, ws_send(fd, MTS_WS_PING, "p1", 2));
        mts_buf h = {0};
        put_hello(&h, "cow", stops[k].kind, stops[k].value, stops[k].flags);
        uint8_t hdr[MTS_WS_MAX_HEADER];
        size_t hn = mts_ws_header(hdr, MTS_WS_BINARY, 3, MASK);
        hdr[0] &= 0x7f; /* not FIN: a continuation follows */
        mts_buf frag = {0};
        mts_buf_put(&frag, hdr, hn);
        size_t at = frag.size;
        mts_buf_put(&frag, h.data, 3);
        mts_ws_mask(frag.data + at, 3, MASK, 0);
        hn = mts_ws_header(hdr, MTS_WS_CONTINUATION, h.size - 3, MASK);
        mts_buf_put(&frag, hdr, hn);
        at = frag.size;
        mts_buf_put(&frag, h.data + 3, h.size - 3);
        mts_ws_mask(frag.data + at, h.size - 3, MASK, 0);
        CHECK(t, send(fd, frag.data, frag.size, MSG_NOSIGNAL) == (ssize_t)frag.size);
        mts_buf_free(&frag);
        mts_buf_free(&h);
        read_all(fd, &raw, 10);
        close(fd);
        mts_ws_control ctl = {0};
        mts_error err = {0};
        CHECKF(t, ws_unwrap(&raw, 32u << 10, &inner, &ctl, &err) == MTS_OK, "%s", err.msg);
        CHECK(t, ctl.close && ctl.close_code == MTS_WS_CLOSE_NORMAL);
        CHECK(t, ctl.ping == 0); /* the server does not ping */
        /* the pong came first, before any data frame */
        CHECK(t, raw.size > 4 && raw.data[0] == (0x80 | MTS_WS_PONG) && raw.data[2] == 'p');
        CHECKF(t, inner.size == tcp.size && memcmp(inner.data, tcp.data, tcp.size) == 0,
               "stop %d: %zu bytes over WebSocket, %zu over TCP", k, inner.size, tcp.size);
        /* paced, a message is a quantum (4 KiB here) but where the stream
         * or a 32 KiB message ends: not the few bytes a microsecond of the
         * rate allows, each an event for a page */
        const long frames = data_frames(&raw), most = (long)(inner.size / 4096) * 2 + 4;
        CHECKF(t, frames > 0 && frames <= most, "stop %d: %zu bytes in %ld messages (at most %ld)",
               k, inner.size, frames, most);
        uint64_t ours = 0, theirs = 0;
        CHECK(t, stream_checksums(&inner, &ours, &theirs) && ours == theirs && ours != 0);
        mts_buf_free(&tcp);
        mts_buf_free(&answer);
        mts_buf_free(&raw);
        mts_buf_free(&inner);
    }
    /* LIST */
    mts_buf answer = {0}, raw = {0}, inner = {0};
    int fd = ws_connect(&sv, &answer);
    mts_buf l = {0};
    mts_wire_put_list(&l);
    CHECK(t, fd >= 0 && ws_send(fd, MTS_WS_BINARY, l.data, l.size));
    mts_buf_free(&l);
    read_all(fd, &raw, 5);
    close(fd);
    mts_ws_control ctl = {0};
    mts_error err = {0};
    CHECK(t, ws_unwrap(&raw, 32u << 10, &inner, &ctl, &err) == MTS_OK);
    CHECK(t, inner.size > 5 && inner.data[4] == MTS_MSG_MODELS);
    CHECK(t, contains(inner.data, inner.size, "cow"));
    mts_buf_free(&answer);
    mts_buf_free(&raw);
    mts_buf_free(&inner);
    CHECK(t, mts_test_stop(sv.pid) == 0);
    char logtext[1 << 16];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECKF(t, count_lines(logtext, "peer=ws/127.0.0.1:") == 5, "%s", logtext);
    CHECKF(t, count_lines(logtext, "outcome=ok") == 9, "%s", logtext);
    CHECK(t, strstr(logtext, "WebSocket clients on 127.0.0.1:") != NULL);
}

/* What the server answers a raw connection to its WebSocket port that
 * sends `bytes` (n of them) and then waits: everything until it closes. */
static void port_exchange(int port, const void *bytes, size_t n, mts_buf *out)
{
    int fd = mts_test_connect(port);
    if (fd < 0)
        return;
    if (n > 0 && send(fd, bytes, n, MSG_NOSIGNAL) != (ssize_t)n) {
        close(fd);
        return;
    }
    read_all(fd, out, 5);
    close(fd);
}

static void raw_exchange(const server *sv, const void *bytes, size_t n, mts_buf *out)
{
    port_exchange(sv->ws_port, bytes, n, out);
}

/* An upgraded connection that sends frame[0..n), and the Close it gets. */
static int frame_close_code(const server *sv, const uint8_t *frame, size_t n, mts_buf *inner)
{
    mts_buf answer = {0}, raw = {0};
    int fd = ws_connect(sv, &answer);
    mts_buf_free(&answer);
    if (fd < 0)
        return -1;
    int sent = send(fd, frame, n, MSG_NOSIGNAL) == (ssize_t)n;
    read_all(fd, &raw, 5);
    close(fd);
    mts_ws_control ctl = {0};
    mts_error err = {0};
    mts_result rc = ws_unwrap(&raw, 1u << 20, inner, &ctl, &err);
    mts_buf_free(&raw);
    return sent && rc == MTS_OK && ctl.close ? ctl.close_code : -1;
}

static void test_hostile_clients(mts_test *t)
{
    const char *extra[] = {"--handshake-timeout", "1", "--rate-limit", "20000", NULL};
    server sv;
    CHECK(t, server_start(&sv, "hostile", extra));
    /* a TCP client streaming meanwhile (cow at 20 KB/s: about a second) */
    int good = mts_test_connect(sv.port);
    mts_buf h = {0};
    put_hello(&h, "cow", MTS_STOP_FULL, 0, 0);
    CHECK(t, good >= 0 && send(good, h.data, h.size, MSG_NOSIGNAL) == (ssize_t)h.size);
    struct {
        const char *what;
        const char *bytes;
        const char *answer;
    } http[] = {
        {"a TCP client's HELLO", NULL, "HTTP/1.1 400 Bad Request"},
        {"a plain GET", "GET / HTTP/1.1\r\nHost: x\r\n\r\n", "HTTP/1.1 426 Upgrade Required"},
        {"silence", "", "HTTP/1.1 408 Request Timeout"},
        {"silence, said so", "", "no WebSocket opening request in time"},
        {"two spaces", "GET  /x HTTP/1.1\r\nHost: x\r\n\r\n", "malformed request line"},
        {"half a request, then silence", "GET / HTTP/1.1\r\nHost", "HTTP/1.1 408"},
        {"version 8", "GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                      "Sec-WebSocket-Key: bXRzdHJlYW0gdGVzdCBrZQ==\r\nSec-WebSocket-Version: 8\r\n\r\n",
         "Sec-WebSocket-Version: 13"},
    };
    for (size_t i = 0; i < sizeof http / sizeof http[0]; i++) {
        mts_buf out = {0};
        if (http[i].bytes)
            raw_exchange(&sv, http[i].bytes, strlen(http[i].bytes), &out);
        else
            raw_exchange(&sv, h.data, h.size, &out);
        CHECKF(t, contains(out.data, out.size, http[i].answer), "%s: %.*s", http[i].what,
               (int)out.size, (const char *)out.data);
        mts_buf_free(&out);
    }
    /* a head that never ends */
    char big[5000];
    memcpy(big, "GET / HTTP/1.1\r\nX: ", 19);
    memset(big + 19, 'a', sizeof big - 19);
    mts_buf out = {0};
    raw_exchange(&sv, big, sizeof big, &out);
    CHECKF(t, contains(out.data, out.size, "HTTP/1.1 431"), "%.*s", (int)out.size,
           (const char *)out.data);
    mts_buf_free(&out);
    /* frames the protocol forbids: closed with the code that says why */
    mts_buf inner = {0};
    const uint8_t unmasked[] = {0x82, 0x02, 1, 2};
    CHECK(t, frame_close_code(&sv, unmasked, sizeof unmasked, &inner) == MTS_WS_CLOSE_PROTOCOL);
    mts_buf text = {0};
    mts_ws_put_frame(&text, MTS_WS_TEXT, "hello", 5, MASK);
    CHECK(t, frame_close_code(&sv, text.data, text.size, &inner) == MTS_WS_CLOSE_UNSUPPORTED);
    mts_buf_free(&text);
    /* a Close whose reason is not UTF-8 (RFC 6455: 1007) */
    mts_buf bad_close = {0};
    const uint8_t bad_reason[] = {0x03, 0xe8, 'o', 'k', 0xc3, 0x28};
    mts_ws_put_frame(&bad_close, MTS_WS_CLOSE, bad_reason, sizeof bad_reason, MASK);
    CHECK(t, frame_close_code(&sv, bad_close.data, bad_close.size, &inner) ==
                 MTS_WS_CLOSE_INVALID_DATA);
    mts_buf_free(&bad_close);
    CHECK(t, inner.size == 0); /* no data for either */
    /* upgraded, then silent: the handshake timeout's ERROR, inside a frame */
    CHECK(t, frame_close_code(&sv, NULL, 0, &inner) == MTS_WS_CLOSE_NORMAL);
    CHECKF(t, inner.size > 5 && inner.data[4] == MTS_MSG_ERROR &&
                  contains(inner.data, inner.size, "no HELLO or LIST in time"),
           "%zu bytes", inner.size);
    mts_buf_free(&inner);
    /* a Close in the middle of a stream: answered, and the stream stops */
    mts_buf answer = {0}, raw = {0};
    int fd = ws_connect(&sv, &answer);
    CHECK(t, fd >= 0 && ws_send(fd, MTS_WS_BINARY, h.data, h.size));
    uint8_t first[2048];
    CHECK(t, recv(fd, first, sizeof first, 0) > 0);
    mts_buf cl = {0};
    mts_ws_put_close(&cl, MTS_WS_CLOSE_GOING_AWAY, "tab closed", MASK);
    CHECK(t, send(fd, cl.data, cl.size, MSG_NOSIGNAL) == (ssize_t)cl.size);
    mts_buf_free(&cl);
    read_all(fd, &raw, 5);
    close(fd);
    /* the rest ends with the server's Close, long before cow's 19 KB are in */
    CHECKF(t, raw.size >= 4 && raw.size < 8000 && raw.data[raw.size - 4] == 0x88,
           "%zu bytes after the Close", raw.size);
    mts_buf_free(&answer);
    mts_buf_free(&raw);
    /* the TCP client got its whole stream */
    mts_buf tcp = {0};
    read_all(good, &tcp, 10);
    close(good);
    uint64_t ours = 0, theirs = 0;
    CHECK(t, stream_checksums(&tcp, &ours, &theirs) && ours == theirs);
    mts_buf_free(&tcp);
    mts_buf_free(&h);
    CHECK(t, mts_test_stop(sv.pid) == 0);
    char logtext[1 << 16];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: bad websocket request") == 4, "%s", logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: not a websocket request") == 1, "%s", logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: handshake timeout") == 4, "%s", logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: bad websocket frame") == 3, "%s", logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: closed by client") == 1, "%s", logtext);
    CHECKF(t, !strstr(logtext, "Sanitizer"), "%s", logtext);
}

static void test_busy(mts_test *t)
{
    const char *extra[] = {"--max-clients", "1", NULL};
    server sv;
    CHECK(t, server_start(&sv, "busy", extra));
    /* an upgraded client takes the one place (tried again while the start
     * probe's connection may still hold it) */
    int hold = -1;
    for (int i = 0; i < 40 && hold < 0; i++) {
        mts_buf answer = {0};
        hold = ws_connect(&sv, &answer);
        mts_buf_free(&answer);
        struct timespec ts = {0, 50 * 1000 * 1000};
        if (hold < 0)
            nanosleep(&ts, NULL);
    }
    CHECK(t, hold >= 0);
    mts_buf out = {0};
    const char *req = "GET / HTTP/1.1\r\nHost: x\r\n\r\n";
    raw_exchange(&sv, req, strlen(req), &out);
    CHECKF(t, contains(out.data, out.size, "HTTP/1.1 503 Service Unavailable") &&
                  contains(out.data, out.size, "server busy"),
           "%.*s", (int)out.size, (const char *)out.data);
    mts_buf_free(&out);
    close(hold);
    CHECK(t, mts_test_stop(sv.pid) == 0);
}

/* A plain GET is answered once, 426 and no file whatever it names (the
 * page is a web server's to hand out): what the client sends after it is
 * read and dropped, never parsed as another request. And --web-root says
 * where files went instead of serving them. */
static void test_answered_once(mts_test *t)
{
    server sv;
    CHECK(t, server_start(&sv, "once", NULL));
    int fd = mts_test_connect(sv.ws_port);
    CHECK(t, fd >= 0);
    const char *req = "GET /index.html HTTP/1.1\r\nHost: x\r\n\r\n";
    CHECK(t, send(fd, req, strlen(req), MSG_NOSIGNAL) == (ssize_t)strlen(req));
    mts_buf out = {0};
    /* more requests and a trickle after the answer */
    for (int i = 0; i < 5; i++) {
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
        const char *again = i % 2 ? "x" : "GET /mts_web.wasm HTTP/1.1\r\nHost: x\r\n\r\n";
        send(fd, again, strlen(again), MSG_NOSIGNAL);
    }
    read_all(fd, &out, 5);
    close(fd);
    mts_buf_put(&out, "", 1);
    const char *text = (const char *)out.data;
    CHECKF(t, count_lines(text, "HTTP/1.1 ") == 1 && strstr(text, "HTTP/1.1 426 "), "%s", text);
    mts_buf_free(&out);
    CHECK(t, mts_test_stop(sv.pid) == 0);
    char logtext[1 << 16];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: not a websocket request") == 1, "%s", logtext);

    char cmd[1200], msg[4096];
    snprintf(cmd, sizeof cmd, "%s/mts-server --models %s --ws-listen 127.0.0.1:0 --web-root /tmp",
             bin_dir, models_dir);
    int rc = mts_test_run(cmd, msg, sizeof msg);
    CHECKF(t, rc == 2 && strstr(msg, "web server") && strstr(msg, "web/nginx.conf"),
           "exit %d: %s", rc, msg);
}

/* Idle means not reading: WebSocket clients that ask for a stream, never
 * read it and keep sending (empty frames) are dropped at --idle-timeout as
 * TCP ones are, and the places they held go to a TCP client. */
static void test_idle_sender(mts_test *t)
{
    enum { HOLDERS = 3 };
    /* a small fixed send buffer and the records form (230 KB): the stream
     * cannot fit in the socket buffers, so a client that does not read
     * stalls it */
    const char *extra[] = {"--idle-timeout", "1", "--sndbuf", "16384", "--max-clients", "3", NULL};
    server sv;
    CHECK(t, server_start(&sv, "idle", extra));
    /* the records form follows the splits form; a HELLO before it is ready
     * gets the 15 KB splits form, which the socket buffers hold whole */
    char logtext[1 << 16];
    for (int i = 0; i < 300; i++) {
        mts_test_read_file(sv.log, logtext, sizeof logtext);
        if (strstr(logtext, "records form ready"))
            break;
        struct timespec ts = {0, 20 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    CHECKF(t, strstr(logtext, "records form ready") != NULL, "%s", logtext);
    mts_buf h = {0}, empty = {0};
    put_hello(&h, "cow", MTS_STOP_FULL, 0, MTS_HELLO_RECORDS);
    mts_ws_put_frame(&empty, MTS_WS_BINARY, NULL, 0, MASK);
    int fds[HOLDERS];
    for (int i = 0; i < HOLDERS; i++) {
        mts_buf answer = {0};
        fds[i] = -1;
        /* the start probe's connection may still hold a place: again */
        for (int k = 0; k < 40 && fds[i] < 0; k++) {
            fds[i] = ws_connect_to(sv.ws_port, "/", 4096, &answer);
            if (fds[i] < 0) {
                struct timespec ts = {0, 50 * 1000 * 1000};
                nanosleep(&ts, NULL);
            }
        }
        CHECK(t, fds[i] >= 0 && ws_send(fds[i], MTS_WS_BINARY, h.data, h.size));
        mts_buf_free(&answer);
    }
    /* an empty frame from each every 100 ms, bytes in and none out, until
     * the server has closed all three (a send then fails) or 15 s pass: a
     * server that counts what a client sends as progress never does */
    int closed = 0, gone[HOLDERS] = {0};
    for (int round = 0; round < 150 && closed < HOLDERS; round++) {
        struct timespec ts = {0, 100 * 1000 * 1000};
        nanosleep(&ts, NULL);
        for (int i = 0; i < HOLDERS; i++) {
            if (fds[i] >= 0 && !gone[i] &&
                send(fds[i], empty.data, empty.size, MSG_NOSIGNAL | MSG_DONTWAIT) < 0 &&
                (errno == EPIPE || errno == ECONNRESET)) {
                gone[i] = 1;
                closed++;
            }
        }
    }
    CHECKF(t, closed == HOLDERS, "%d of %d non-reading senders were dropped", closed, HOLDERS);
    /* their places are free: a TCP client gets its whole stream */
    mts_buf tcp = {0};
    CHECK(t, tcp_stream(&sv, MTS_STOP_FULL, 0, 0, &tcp));
    uint64_t ours = 0, theirs = 0;
    CHECKF(t, stream_checksums(&tcp, &ours, &theirs) && ours == theirs, "%zu bytes", tcp.size);
    mts_buf_free(&tcp);
    for (int i = 0; i < HOLDERS; i++) {
        if (fds[i] >= 0)
            close(fds[i]);
    }
    mts_buf_free(&h);
    mts_buf_free(&empty);
    CHECK(t, mts_test_stop(sv.pid) == 0);
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: idle timeout") == HOLDERS, "%s", logtext);
}

/* An HTTP answer's status line, a header's value ("" when absent) and the
 * body's size, from out. */
static int http_status(const mts_buf *out)
{
    int code = 0;
    if (out->size > 12 && memcmp(out->data, "HTTP/1.", 7) == 0)
        code = atoi((const char *)out->data + 9);
    return code;
}

static void http_header(const mts_buf *out, const char *name, char *value, size_t size)
{
    value[0] = 0;
    char key[80];
    snprintf(key, sizeof key, "\r\n%s: ", name);
    const char *p = (const char *)out->data;
    const char *end = p + out->size;
    size_t k = strlen(key);
    for (; p + k <= end; p++) {
        if (strncasecmp(p, key, k) == 0) {
            p += k;
            size_t n = 0;
            while (p + n < end && p[n] != '\r' && n + 1 < size)
                n++;
            memcpy(value, p, n);
            value[n] = 0;
            return;
        }
    }
}

static size_t http_body(const mts_buf *out)
{
    for (size_t i = 0; i + 4 <= out->size; i++) {
        if (memcmp(out->data + i, "\r\n\r\n", 4) == 0)
            return out->size - i - 4;
    }
    return 0;
}

/* The page's web server as users run it: nginx with web/nginx.conf in
 * front of mts-server. Its files come out with the types, validators and
 * methods a browser expects, nothing outside its folder (no symbolic link
 * out, no "..") and no special file is handed out or holds it up, and the
 * stream at /stream is mts-server's, byte for byte. */
static void test_behind_nginx(mts_test *t)
{
    char nginx[512];
    if (!mts_test_find_nginx(nginx, sizeof nginx)) {
        int required = getenv("MTS_TEST_REQUIRE_NGINX") != NULL;
        CHECKF(t, !required, "MTS_TEST_REQUIRE_NGINX is set and there is no nginx");
        if (!required)
            SKIP(t, "no nginx (scripts/deps.sh installs it): the page's web server is not run");
        return;
    }
    char root[800], front[800], cmd[4096], out[4096], nlog[800];
    snprintf(root, sizeof root, "%s/ws_front_root", tmp_dir);
    snprintf(front, sizeof front, "%s/ws_front", tmp_dir);
    snprintf(nlog, sizeof nlog, "%s/ws_front_nginx.log", tmp_dir);
    /* a page folder with what a careless operator leaves in it */
    snprintf(cmd, sizeof cmd,
             "rm -rf '%s' '%s' && mkdir -p '%s/sub' && cd '%s' && "
             "printf '<!doctype html><title>page</title>' > index.html && "
             "printf '\\0asm\\1\\0\\0\\0' > mts_web.wasm && printf 'x' > sub/a.js && "
             "printf 'secret-outside' > ../ws_front_secret.txt && "
             "ln -s /etc etcdir && ln -s ../ws_front_secret.txt leak.txt && "
             "ln -s nowhere dangling.js && mkfifo fifo.js && truncate -s 50G huge.bin",
             root, front, root, root);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    server sv;
    CHECK(t, server_start(&sv, "front", NULL));
    int port = 0;
    pid_t ng = mts_test_front_start(nginx, front, root, sv.ws_port, &port, nlog, 30);
    if (ng < 0) {
        mts_test_read_file(nlog, out, sizeof out);
        CHECKF(t, 0, "nginx with web/nginx.conf did not start: %s", out);
        mts_test_stop(sv.pid);
        return;
    }
    struct {
        const char *req;
        int status;          /* 0: anything but 200 */
        const char *type;    /* Content-Type, or NULL */
        long body;           /* body bytes, -1: any */
    } cases[] = {
        {"GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 200, "text/html", 34},
        {"HEAD /mts_web.wasm HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 200,
         "application/wasm", 0},
        {"GET /mts_web.wasm HTTP/1.0\r\n\r\n", 200, "application/wasm", 8},
        {"GET /sub/a.js HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 200, NULL, 1},
        /* a 50 GB file costs nothing to describe or to take a range of */
        {"HEAD /huge.bin HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 200, NULL, 0},
        {"GET /huge.bin HTTP/1.1\r\nHost: x\r\nRange: bytes=53687091100-53687091199\r\n"
         "Connection: close\r\n\r\n", 206, NULL, 100},
        {"GET /etcdir/passwd HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 0, NULL, -1},
        {"GET /leak.txt HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 0, NULL, -1},
        {"GET /dangling.js HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 0, NULL, -1},
        {"GET /fifo.js HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 0, NULL, -1},
        {"GET /../ws_front_secret.txt HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 0, NULL,
         -1},
        {"GET /%2e%2e/ws_front_secret.txt HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 0,
         NULL, -1},
        /* and after all of it, still serving */
        {"GET /index.html HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 200, "text/html", 34},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mts_buf ans = {0};
        double t0 = mts_clock_seconds();
        port_exchange(port, cases[i].req, strlen(cases[i].req), &ans);
        double secs = mts_clock_seconds() - t0;
        int st = http_status(&ans);
        char type[200], etag[200], modified[200];
        http_header(&ans, "Content-Type", type, sizeof type);
        http_header(&ans, "ETag", etag, sizeof etag);
        http_header(&ans, "Last-Modified", modified, sizeof modified);
        const char *what = cases[i].req;
        CHECKF(t, cases[i].status ? st == cases[i].status : st >= 400,
               "%.40s: status %d", what, st);
        CHECKF(t, secs < 4, "%.40s: %.1f s", what, secs);
        CHECKF(t, !contains(ans.data, ans.size, "secret-outside") &&
                      !contains(ans.data, ans.size, "root:"),
               "%.40s: a file from outside the page's folder", what);
        if (cases[i].type)
            CHECKF(t, strstr(type, cases[i].type) != NULL, "%.40s: type %s", what, type);
        if (cases[i].body >= 0)
            CHECKF(t, (long)http_body(&ans) == cases[i].body, "%.40s: %zu body bytes", what,
                   http_body(&ans));
        if (cases[i].status == 200 || cases[i].status == 206)
            CHECKF(t, etag[0] && modified[0], "%.40s: ETag '%s', Last-Modified '%s'", what, etag,
                   modified);
        mts_buf_free(&ans);
    }
    /* the stream through /stream is mts-server's, byte for byte */
    mts_buf tcp = {0}, answer = {0}, raw = {0}, inner = {0};
    CHECK(t, tcp_stream(&sv, MTS_STOP_FULL, 0, 0, &tcp));
    int fd = ws_connect_to(port, "/stream", 0, &answer);
    CHECKF(t, fd >= 0, "no 101 through nginx: %.*s", (int)answer.size, (const char *)answer.data);
    mts_buf h = {0};
    put_hello(&h, "cow", MTS_STOP_FULL, 0, 0);
    if (fd >= 0) {
        CHECK(t, ws_send(fd, MTS_WS_BINARY, h.data, h.size));
        read_all(fd, &raw, 10);
        close(fd);
    }
    mts_ws_control ctl = {0};
    mts_error err = {0};
    CHECKF(t, ws_unwrap(&raw, 32u << 10, &inner, &ctl, &err) == MTS_OK, "%s", err.msg);
    CHECKF(t, inner.size == tcp.size && tcp.size > 0 && memcmp(inner.data, tcp.data, tcp.size) == 0,
           "%zu bytes through nginx, %zu over TCP", inner.size, tcp.size);
    mts_buf_free(&h);
    mts_buf_free(&tcp);
    mts_buf_free(&answer);
    mts_buf_free(&raw);
    mts_buf_free(&inner);
    mts_test_stop(ng);
    CHECK(t, mts_test_stop(sv.pid) == 0);
    if (!t->case_failed) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s' '%s' '%s/ws_front_secret.txt'", root, front,
                 tmp_dir);
        mts_test_run(cmd, out, sizeof out);
    }
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    snprintf(models_dir, sizeof models_dir, "%s/ws_models", tmp_dir);
    signal(SIGPIPE, SIG_IGN);
    mts_test t = {0};
    char cmd[2048], out[8192];
    snprintf(cmd, sizeof cmd,
             "mkdir -p %s && %s/mts-build tests/data/cow.off -o %s/cow.mtsm --quiet", models_dir,
             bin_dir, models_dir);
    if (mts_test_run(cmd, out, sizeof out) != 0) {
        fprintf(stderr, "cannot build cow: %s\n", out);
        return 1;
    }
    RUN(&t, test_stream_matches_tcp);
    RUN(&t, test_hostile_clients);
    RUN(&t, test_busy);
    RUN(&t, test_answered_once);
    RUN(&t, test_idle_sender);
    RUN(&t, test_behind_nginx);
    return mts_test_end(&t);
}
