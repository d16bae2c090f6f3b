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

/* A WebSocket connection to the server after its 101 (-1 on failure; the
 * answer, whatever it was, in *answer). */
static int ws_connect(const server *sv, mts_buf *answer)
{
    int fd = mts_test_connect(sv->ws_port);
    if (fd < 0)
        return -1;
    mts_buf req = {0};
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", sv->ws_port);
    mts_ws_put_request(&req, host, "/", KEY);
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
static void raw_exchange(const server *sv, const void *bytes, size_t n, mts_buf *out)
{
    int fd = mts_test_connect(sv->ws_port);
    if (fd < 0)
        return;
    if (n > 0 && send(fd, bytes, n, MSG_NOSIGNAL) != (ssize_t)n) {
        close(fd);
        return;
    }
    read_all(fd, out, 5);
    close(fd);
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
    CHECK(t, inner.size == 0); /* no data for either */
    /* upgraded, then silent: the handshake timeout's ERROR, inside a frame */
    CHECK(t, frame_close_code(&sv, NULL, 0, &inner) == MTS_WS_CLOSE_NORMAL);
    CHECKF(t, inner.size > 5 && inner.data[4] == MTS_MSG_ERROR &&
                  contains(inner.data, inner.size, "no HELLO in time"),
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
    CHECKF(t, count_lines(logtext, "outcome=error: bad websocket request") == 3, "%s", logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: not a websocket request") == 1, "%s", logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: handshake timeout") == 3, "%s", logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: bad websocket frame") == 2, "%s", logtext);
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
    return mts_test_end(&t);
}
