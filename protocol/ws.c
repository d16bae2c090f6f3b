/* WebSocket after RFC 6455: section 4 (the opening handshake) and section 5
 * (framing). See ws.h for what is and is not taken. */
#include "ws.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "sha1.h"
#include "utf8.h"

static const char WS_GUID[] = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";
static const char B64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/* ---- text helpers ------------------------------------------------------------ */

static int lower(int c)
{
    return c >= 'A' && c <= 'Z' ? c + 32 : c;
}

/* s[0..n) is word, ignoring case. */
static int ieq(const char *s, size_t n, const char *word)
{
    size_t m = strlen(word);
    if (n != m)
        return 0;
    for (size_t i = 0; i < n; i++) {
        if (lower((unsigned char)s[i]) != lower((unsigned char)word[i]))
            return 0;
    }
    return 1;
}

static int is_ows(char c)
{
    return c == ' ' || c == '\t';
}

/* A comma-separated header value v[0..n) lists tok, ignoring case. */
static int has_token(const char *v, size_t n, const char *tok)
{
    size_t i = 0;
    while (i < n) {
        size_t j = i;
        while (j < n && v[j] != ',')
            j++;
        size_t a = i, b = j;
        while (a < b && is_ows(v[a]))
            a++;
        while (b > a && is_ows(v[b - 1]))
            b--;
        if (ieq(v + a, b - a, tok))
            return 1;
        i = j + 1;
    }
    return 0;
}

/* RFC 9110's token characters, which a header name is made of. */
static int is_tchar(unsigned char c)
{
    return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
           (c && strchr("!#$%&'*+-.^_`|~", c));
}

static int b64_value(char c)
{
    const char *p = c ? strchr(B64, c) : NULL;
    return p ? (int)(p - B64) : -1;
}

/* The offset just past the blank line ending the head in buf[0..len), or 0. */
static size_t head_end(const uint8_t *buf, size_t len)
{
    for (size_t i = 3; i < len; i++) {
        if (buf[i] == '\n' && buf[i - 1] == '\r' && buf[i - 2] == '\n' && buf[i - 3] == '\r')
            return i + 1;
    }
    return 0;
}

/* The next line of head[*at..end) without its CRLF: its length, *at moved
 * past it; -1 when a line ends in a bare LF or CR (not HTTP). */
static long next_line(const char *head, size_t end, size_t *at, const char **line)
{
    size_t i = *at;
    *line = head + i;
    while (i + 1 < end && !(head[i] == '\r' && head[i + 1] == '\n')) {
        if (head[i] == '\r' || head[i] == '\n')
            return -1;
        i++;
    }
    long n = (long)(i - *at);
    *at = i + 2;
    return n;
}

/* ---- the opening handshake --------------------------------------------------- */

static mts_result refuse(mts_ws_request *req, int status, mts_error *err, const char *why)
{
    req->size = 0;
    req->status = status;
    return mts_error_set(err, status == 431 ? MTS_ERR_LIMIT : MTS_ERR_FORMAT,
                         "websocket: %s (HTTP %d)", why, status);
}

mts_result mts_ws_parse_request(const uint8_t *buf, size_t len, mts_ws_request *req,
                                mts_error *err)
{
    memset(req, 0, sizeof *req);
    /* garbage shows at once: anything but "GET " */
    size_t m = len < 4 ? len : 4;
    if (memcmp(buf, "GET ", m) != 0) {
        size_t i = 0;
        while (i < len && buf[i] >= 'A' && buf[i] <= 'Z')
            i++;
        if (i > 0 && (i == len || buf[i] == ' '))
            return refuse(req, 405, err, "only GET opens a WebSocket");
        return refuse(req, 400, err, "not an HTTP request");
    }
    size_t scan = len < MTS_WS_MAX_REQUEST ? len : MTS_WS_MAX_REQUEST;
    size_t size = head_end(buf, scan);
    for (size_t i = 0; i < (size ? size : scan); i++) {
        if (buf[i] == 0 || buf[i] >= 0x80 || (buf[i] < 0x20 && buf[i] != '\r' &&
                                               buf[i] != '\n' && buf[i] != '\t'))
            return refuse(req, 400, err, "a request head with a control or non-ASCII byte");
    }
    if (!size) {
        if (len >= MTS_WS_MAX_REQUEST)
            return refuse(req, 431, err, "a request head over 4096 bytes");
        return MTS_OK; /* more to come */
    }
    const char *head = (const char *)buf;
    size_t at = 0;
    const char *line;
    long n = next_line(head, size, &at, &line);
    /* "GET " target " HTTP/1.1": exactly two single spaces */
    const char *sp = n > 4 ? memchr(line + 4, ' ', (size_t)n - 4) : NULL;
    if (n < 0 || !sp || sp == line + 4 || memchr(sp + 1, ' ', (size_t)(line + n - sp - 1)))
        return refuse(req, 400, err, "a malformed request line (GET, a target, a version, "
                                     "each after one space)");
    size_t tlen = (size_t)(sp - (line + 4));
    const char *version = sp + 1;
    size_t vlen = (size_t)(line + n - version);
    if (vlen != 8 || memcmp(version, "HTTP/1.", 7) != 0 || version[7] < '1' || version[7] > '9')
        return refuse(req, memcmp(version, "HTTP/", vlen < 5 ? vlen : 5) == 0 ? 505 : 400, err,
                      "not HTTP/1.1");
    if (tlen == 0 || line[4] != '/' || tlen >= MTS_WS_MAX_PATH)
        return refuse(req, 400, err, "a request target that is not a path under 256 bytes");
    for (size_t i = 0; i < tlen; i++) {
        if (line[4 + i] <= 0x20 || line[4 + i] >= 0x7f)
            return refuse(req, 400, err, "a request target with a space or control byte");
    }
    memcpy(req->path, line + 4, tlen);
    req->path[tlen] = 0;
    int host = 0, upgrade_ws = 0, connection_upgrade = 0, keys = 0;
    const char *ver = NULL, *key = NULL;
    size_t ver_len = 0, key_len = 0;
    while ((n = next_line(head, size, &at, &line)) != 0) {
        if (n < 0)
            return refuse(req, 400, err, "a header line not ended by CRLF");
        if (is_ows(line[0]))
            return refuse(req, 400, err, "a folded header line");
        const char *colon = memchr(line, ':', (size_t)n);
        if (!colon || colon == line)
            return refuse(req, 400, err, "a header line without a name");
        size_t nlen = (size_t)(colon - line);
        for (size_t i = 0; i < nlen; i++) {
            if (!is_tchar((unsigned char)line[i]))
                return refuse(req, 400, err, "a header name with a space or separator");
        }
        const char *v = colon + 1, *ve = line + n;
        while (v < ve && is_ows(*v))
            v++;
        while (ve > v && is_ows(ve[-1]))
            ve--;
        size_t vn = (size_t)(ve - v);
        if (ieq(line, nlen, "host")) {
            host++;
        } else if (ieq(line, nlen, "upgrade")) {
            upgrade_ws |= has_token(v, vn, "websocket");
        } else if (ieq(line, nlen, "connection")) {
            connection_upgrade |= has_token(v, vn, "upgrade");
        } else if (ieq(line, nlen, "sec-websocket-version")) {
            ver = v;
            ver_len = vn;
        } else if (ieq(line, nlen, "sec-websocket-key")) {
            key = v;
            key_len = vn;
            keys++;
        }
    }
    if (host != 1)
        return refuse(req, 400, err, host ? "more than one Host header" : "no Host header");
    req->size = size;
    if (!upgrade_ws)
        return MTS_OK; /* a plain GET */
    if (!connection_upgrade)
        return refuse(req, 400, err, "Upgrade: websocket without Connection: Upgrade");
    if (!ver || !ieq(ver, ver_len, "13"))
        return refuse(req, 426, err, "a WebSocket version other than 13");
    if (keys != 1)
        return refuse(req, 400, err, keys ? "more than one Sec-WebSocket-Key" :
                                            "no Sec-WebSocket-Key");
    /* 16 random bytes in base64: 22 characters and "==" */
    int ok = key_len == 24 && key[22] == '=' && key[23] == '=';
    for (size_t i = 0; ok && i < 22; i++)
        ok = b64_value(key[i]) >= 0;
    if (!ok || (b64_value(key[21]) & 15) != 0)
        return refuse(req, 400, err, "a Sec-WebSocket-Key that is not 16 bytes in base64");
    memcpy(req->key, key, 24);
    req->key[24] = 0;
    req->upgrade = 1;
    return MTS_OK;
}

void mts_ws_accept_key(const char *key, char out[29])
{
    char cat[24 + sizeof WS_GUID];
    size_t kn = strnlen(key, 24);
    memcpy(cat, key, kn);
    memcpy(cat + kn, WS_GUID, sizeof WS_GUID - 1);
    uint8_t h[MTS_SHA1_SIZE + 1] = {0};
    mts_sha1(cat, kn + sizeof WS_GUID - 1, h);
    size_t o = 0;
    for (int i = 0; i < 21; i += 3) {
        uint32_t x = (uint32_t)h[i] << 16 | (uint32_t)h[i + 1] << 8 | h[i + 2];
        out[o++] = B64[x >> 18 & 63];
        out[o++] = B64[x >> 12 & 63];
        out[o++] = B64[x >> 6 & 63];
        out[o++] = B64[x & 63];
    }
    out[27] = '='; /* 20 bytes: the last group has two */
    out[28] = 0;
}

void mts_ws_put_accept(mts_buf *b, const mts_ws_request *req)
{
    char accept[29], text[160];
    mts_ws_accept_key(req->key, accept);
    int n = snprintf(text, sizeof text,
                     "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n"
                     "Connection: Upgrade\r\nSec-WebSocket-Accept: %s\r\n\r\n",
                     accept);
    mts_buf_put(b, text, (size_t)n);
}

static const char *reason_phrase(int status)
{
    switch (status) {
    case 400: return "Bad Request";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 408: return "Request Timeout";
    case 426: return "Upgrade Required";
    case 431: return "Request Header Fields Too Large";
    case 503: return "Service Unavailable";
    case 505: return "HTTP Version Not Supported";
    default: return "Internal Server Error";
    }
}

void mts_ws_put_http_error(mts_buf *b, int status, const char *text)
{
    char head[300];
    size_t tn = strlen(text);
    int n = snprintf(head, sizeof head,
                     "HTTP/1.1 %d %s\r\nContent-Type: text/plain; charset=utf-8\r\n"
                     "Content-Length: %zu\r\nConnection: close\r\n%s%s\r\n",
                     status, reason_phrase(status), tn + 1,
                     status == 426 ? "Sec-WebSocket-Version: 13\r\n" : "",
                     status == 405 ? "Allow: GET\r\n" : "");
    mts_buf_put(b, head, (size_t)n);
    mts_buf_put(b, text, tn);
    mts_buf_put(b, "\n", 1);
}

void mts_ws_put_request(mts_buf *b, const char *host, const char *path, const char *key)
{
    char text[700];
    int n = snprintf(text, sizeof text,
                     "GET %s HTTP/1.1\r\nHost: %s\r\nUpgrade: websocket\r\n"
                     "Connection: Upgrade\r\nSec-WebSocket-Key: %.24s\r\n"
                     "Sec-WebSocket-Version: 13\r\n\r\n",
                     path, host, key);
    if (n > 0 && (size_t)n < sizeof text)
        mts_buf_put(b, text, (size_t)n);
    else
        b->failed = 1;
}

mts_result mts_ws_parse_response(const uint8_t *buf, size_t len, const char *key, size_t *size,
                                 mts_error *err)
{
    *size = 0;
    size_t scan = len < MTS_WS_MAX_REQUEST ? len : MTS_WS_MAX_REQUEST;
    size_t end = head_end(buf, scan);
    if (!end) {
        if (len >= MTS_WS_MAX_REQUEST)
            return mts_error_set(err, MTS_ERR_FORMAT, "websocket: an answer head over 4096 bytes");
        if (len >= 5 && memcmp(buf, "HTTP/", 5) != 0)
            return mts_error_set(err, MTS_ERR_FORMAT, "websocket: the answer is not HTTP");
        return MTS_OK;
    }
    const char *head = (const char *)buf;
    size_t at = 0;
    const char *line;
    long n = next_line(head, end, &at, &line);
    if (n < 13 || memcmp(line, "HTTP/1.1 101 ", 13) != 0) {
        /* quote the status line and what the body says */
        int sl = n < 0 ? 0 : n > 80 ? 80 : (int)n;
        size_t body = len - end > 200 ? 200 : len - end;
        while (body > 0 && (buf[end + body - 1] == '\n' || buf[end + body - 1] == '\r'))
            body--;
        return mts_error_set(err, MTS_ERR_FORMAT, "websocket: the server answered \"%.*s\"%s%.*s",
                             sl, line, body ? ": " : "", (int)body, head + end);
    }
    char accept[29];
    mts_ws_accept_key(key, accept);
    int upgrade = 0, connection = 0, accepted = 0;
    while ((n = next_line(head, end, &at, &line)) > 0) {
        const char *colon = memchr(line, ':', (size_t)n);
        if (!colon)
            return mts_error_set(err, MTS_ERR_FORMAT, "websocket: a header line without ':'");
        size_t nlen = (size_t)(colon - line);
        const char *v = colon + 1, *ve = line + n;
        while (v < ve && is_ows(*v))
            v++;
        while (ve > v && is_ows(ve[-1]))
            ve--;
        size_t vn = (size_t)(ve - v);
        if (ieq(line, nlen, "upgrade"))
            upgrade |= has_token(v, vn, "websocket");
        else if (ieq(line, nlen, "connection"))
            connection |= has_token(v, vn, "upgrade");
        else if (ieq(line, nlen, "sec-websocket-accept"))
            accepted = vn == 28 && memcmp(v, accept, 28) == 0;
        else if (ieq(line, nlen, "sec-websocket-extensions") ||
                 ieq(line, nlen, "sec-websocket-protocol"))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "websocket: the server chose an extension or protocol "
                                 "not asked for");
    }
    if (n < 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "websocket: a header line not ended by CRLF");
    if (!upgrade || !connection || !accepted)
        return mts_error_set(err, MTS_ERR_FORMAT, "websocket: a 101 answer without %s",
                             !upgrade      ? "Upgrade: websocket"
                             : !connection ? "Connection: Upgrade"
                                           : "the Sec-WebSocket-Accept of our key");
    *size = end;
    return MTS_OK;
}

/* ---- frames -------------------------------------------------------------------- */

size_t mts_ws_header(uint8_t out[MTS_WS_MAX_HEADER], mts_ws_opcode op, uint64_t len,
                     const uint8_t *mask)
{
    size_t n = 0;
    uint8_t m = mask ? 0x80 : 0;
    out[n++] = (uint8_t)(0x80 | op);
    if (len < 126) {
        out[n++] = (uint8_t)(m | len);
    } else if (len <= 0xFFFF) {
        out[n++] = m | 126;
        out[n++] = (uint8_t)(len >> 8);
        out[n++] = (uint8_t)len;
    } else {
        out[n++] = m | 127;
        for (int i = 7; i >= 0; i--)
            out[n++] = (uint8_t)(len >> (8 * i));
    }
    if (mask) {
        memcpy(out + n, mask, 4);
        n += 4;
    }
    return n;
}

void mts_ws_mask(uint8_t *data, size_t len, const uint8_t mask[4], uint64_t at)
{
    for (size_t i = 0; i < len; i++)
        data[i] ^= mask[(at + i) & 3];
}

void mts_ws_put_frame(mts_buf *b, mts_ws_opcode op, const void *data, size_t len,
                      const uint8_t *mask)
{
    uint8_t h[MTS_WS_MAX_HEADER];
    mts_buf_put(b, h, mts_ws_header(h, op, len, mask));
    size_t at = b->size;
    mts_buf_put(b, data, len);
    if (mask && !b->failed)
        mts_ws_mask(b->data + at, len, mask, 0);
}

void mts_ws_put_close(mts_buf *b, uint16_t code, const char *reason, const uint8_t *mask)
{
    uint8_t p[125];
    size_t rn = reason ? strnlen(reason, 123) : 0;
    p[0] = (uint8_t)(code >> 8);
    p[1] = (uint8_t)code;
    if (rn)
        memcpy(p + 2, reason, rn);
    mts_ws_put_frame(b, MTS_WS_CLOSE, p, rn + 2, mask);
}

static mts_result fail(mts_ws_reader *r, mts_ws_control *ctl, uint16_t code, mts_error *err,
                       const char *fmt, ...) __attribute__((format(printf, 5, 6)));
static mts_result fail(mts_ws_reader *r, mts_ws_control *ctl, uint16_t code, mts_error *err,
                       const char *fmt, ...)
{
    r->failed = 1;
    ctl->fail_code = code;
    char text[160];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    return mts_error_set(err, code == MTS_WS_CLOSE_TOO_BIG ? MTS_ERR_LIMIT : MTS_ERR_FORMAT,
                         "websocket: %s", text);
}

/* A close code a peer may send (RFC 6455 7.4). */
static int valid_close_code(unsigned c)
{
    return (c >= 1000 && c <= 1003) || (c >= 1007 && c <= 1014) || (c >= 3000 && c <= 4999);
}

/* A Close's reason must be valid text (RFC 6455 5.5.1). */
static int valid_utf8(const uint8_t *p, size_t n)
{
    for (size_t i = 0, k; i < n; i += k) {
        if ((k = mts_utf8_seq_len(p + i, n - i)) == 0)
            return 0;
    }
    return 1;
}

/* A whole header is in r->hdr: check it and start the frame. */
static mts_result begin_frame(mts_ws_reader *r, mts_ws_control *ctl, mts_error *err)
{
    const uint8_t *h = r->hdr;
    unsigned op = h[0] & 15, l7 = h[1] & 127;
    r->fin = h[0] >> 7;
    r->masked = h[1] >> 7;
    if (h[0] & 0x70)
        return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err,
                    "reserved bits set (%u): no extension was agreed",
                    (unsigned)(h[0] >> 4 & 7));
    if (r->masked == r->client)
        return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err,
                    r->client ? "a masked frame from the server"
                              : "an unmasked frame from the client");
    uint64_t len = l7;
    size_t at = 2;
    if (l7 == 126) {
        len = (uint64_t)h[2] << 8 | h[3];
        at = 4;
    } else if (l7 == 127) {
        len = 0;
        for (int i = 0; i < 8; i++)
            len = len << 8 | h[2 + i];
        at = 10;
        if (len >> 63)
            return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err, "a frame length with its top bit set");
    }
    if (r->masked)
        memcpy(r->mask, h + at, 4);
    if (op >= 8) {
        if (op > MTS_WS_PONG)
            return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err, "unknown control opcode %u", op);
        if (!r->fin)
            return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err,
                        "a fragmented control frame (opcode %u)", op);
        if (len > 125)
            return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err,
                        "a control frame of %llu bytes (at most 125)", (unsigned long long)len);
    } else {
        uint64_t max = r->max_message ? r->max_message : MTS_WS_MAX_MESSAGE;
        if (op > MTS_WS_BINARY)
            return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err, "unknown opcode %u", op);
        if (op == MTS_WS_TEXT && !r->text)
            return fail(r, ctl, MTS_WS_CLOSE_UNSUPPORTED, err,
                        "a text message: this protocol's messages are binary");
        if (op == MTS_WS_CONTINUATION && !r->in_message)
            return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err,
                        "a continuation frame outside a message");
        if (op == MTS_WS_BINARY && r->in_message)
            return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err,
                        "a new message inside a fragmented one");
        if (op == MTS_WS_BINARY)
            r->message = 0;
        if (len > max - r->message)
            return fail(r, ctl, MTS_WS_CLOSE_TOO_BIG, err, "a message of more than %llu bytes",
                        (unsigned long long)max);
        r->message += len;
        r->in_message = !r->fin;
    }
    r->opcode = (uint8_t)op;
    r->left = len;
    r->at = 0;
    r->ctl_len = 0;
    r->in_frame = 1;
    r->hdr_len = 0;
    return MTS_OK;
}

/* The frame's payload is all in. */
static mts_result end_frame(mts_ws_reader *r, mts_ws_control *ctl, mts_error *err)
{
    r->in_frame = 0;
    if (r->opcode == MTS_WS_PING) {
        ctl->ping = 1;
        memcpy(ctl->pong, r->ctl, r->ctl_len);
        ctl->pong_len = r->ctl_len;
    } else if (r->opcode == MTS_WS_CLOSE) {
        unsigned code = MTS_WS_CLOSE_NONE;
        if (r->ctl_len == 1)
            return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err, "a Close frame of 1 byte");
        if (r->ctl_len >= 2) {
            code = (unsigned)r->ctl[0] << 8 | r->ctl[1];
            if (!valid_close_code(code))
                return fail(r, ctl, MTS_WS_CLOSE_PROTOCOL, err, "a Close with code %u", code);
            if (!valid_utf8(r->ctl + 2, r->ctl_len - 2))
                return fail(r, ctl, MTS_WS_CLOSE_INVALID_DATA, err,
                            "a Close whose reason is not UTF-8");
        }
        ctl->close = 1;
        ctl->close_code = (uint16_t)code;
        r->closed = 1;
    }
    return MTS_OK;
}

mts_result mts_ws_reader_feed(mts_ws_reader *r, uint8_t *buf, size_t len, size_t *payload,
                              mts_ws_control *ctl, mts_error *err)
{
    size_t in = 0, out = 0;
    mts_result rc = MTS_OK;
    *payload = 0;
    if (r->failed)
        return mts_error_set(err, MTS_ERR_FORMAT, "websocket: read after a protocol error");
    while (rc == MTS_OK && !r->closed && in < len) {
        if (!r->in_frame) {
            r->hdr[r->hdr_len++] = buf[in++];
            if (r->hdr_len < 2)
                continue;
            unsigned l7 = r->hdr[1] & 127;
            unsigned need = 2 + (l7 == 126 ? 2 : l7 == 127 ? 8 : 0) + (r->hdr[1] & 128 ? 4 : 0);
            if (r->hdr_len < need)
                continue;
            if ((rc = begin_frame(r, ctl, err)) != MTS_OK)
                break;
        }
        size_t take = r->left < len - in ? (size_t)r->left : len - in;
        if (r->opcode < 8) {
            memmove(buf + out, buf + in, take);
            if (r->masked)
                mts_ws_mask(buf + out, take, r->mask, r->at);
            out += take;
            r->payload_in += take;
        } else {
            memcpy(r->ctl + r->ctl_len, buf + in, take);
            if (r->masked)
                mts_ws_mask(r->ctl + r->ctl_len, take, r->mask, r->at);
            r->ctl_len += (unsigned)take;
        }
        in += take;
        r->left -= take;
        r->at += take;
        if (r->left == 0)
            rc = end_frame(r, ctl, err);
    }
    *payload = out;
    return rc;
}
