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
    snprintf(err->msg, sizeof err->msg, "%s: %s", prefix, old);
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
