#include "error.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

mts_result mts_error_set(mts_error *err, mts_result code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
        err->code = code;
    }
    return code;
}

mts_result mts_error_prefix(mts_error *err, const char *fmt, ...)
{
    if (!err)
        return MTS_ERR_INTERNAL;
    char prefix[MTS_ERROR_MSG_SIZE];
    char old[MTS_ERROR_MSG_SIZE];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, err->msg, sizeof old);
    /* truncation is fine: the message stays a valid, if shortened, string */
    size_t n = strnlen(prefix, sizeof prefix - 1);
    size_t room = sizeof err->msg - 1;
    if (n > room)
        n = room;
    memcpy(err->msg, prefix, n);
    size_t at = n;
    for (const char *s = ": "; *s && at < room; s++)
        err->msg[at++] = *s;
    size_t m = strnlen(old, sizeof old - 1);
    if (m > room - at)
        m = room - at;
    memcpy(err->msg + at, old, m);
    err->msg[at + m] = 0;
    return err->code;
}

const char *mts_result_name(mts_result code)
{
    switch (code) {
    case MTS_OK: return "ok";
    case MTS_ERR_ARG: return "argument";
    case MTS_ERR_IO: return "io";
    case MTS_ERR_FORMAT: return "format";
    case MTS_ERR_VERSION: return "version";
    case MTS_ERR_CHECKSUM: return "checksum";
    case MTS_ERR_RANGE: return "range";
    case MTS_ERR_NOMEM: return "nomem";
    case MTS_ERR_LIMIT: return "limit";
    case MTS_ERR_INVARIANT: return "invariant";
    case MTS_ERR_INTERNAL: return "internal";
    }
    return "unknown";
}
