/* mts error reporting: every library call returns an mts_result and, on
 * failure, fills an mts_error whose message names the problem (the file, the
 * offset, the limit that was crossed). Library code never prints or exits;
 * only a program's main() decides what the user sees. */
#ifndef MTS_ERROR_H
#define MTS_ERROR_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum mts_result {
    MTS_OK = 0,
    MTS_ERR_ARG,      /* the caller passed an invalid argument or option */
    MTS_ERR_IO,       /* open/read/write failed (errno text in the message) */
    MTS_ERR_FORMAT,   /* input is malformed, truncated or inconsistent */
    MTS_ERR_VERSION,  /* input is of an unsupported version */
    MTS_ERR_CHECKSUM, /* a checksum did not match */
    MTS_ERR_RANGE,    /* an index, count or position is out of range */
    MTS_ERR_NOMEM,    /* an allocation failed */
    MTS_ERR_LIMIT,    /* input exceeds a documented limit */
    MTS_ERR_INVARIANT, /* a model breaks an invariant of docs/architecture.md (verification) */
    MTS_ERR_INTERNAL  /* a consistency check failed: a bug, not bad input */
} mts_result;

#define MTS_ERROR_MSG_SIZE 512

typedef struct mts_error {
    mts_result code;
    char msg[MTS_ERROR_MSG_SIZE];
} mts_error;

/* Fills err (when not NULL) and returns code, so callers can write
 * `return mts_error_set(err, MTS_ERR_FORMAT, "%s: ...", path);`. */
mts_result mts_error_set(mts_error *err, mts_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Prepends "prefix: " to an existing message, for context added on the way up. */
mts_result mts_error_prefix(mts_error *err, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* A short stable name for a result code ("format", "checksum", ...). */
const char *mts_result_name(mts_result code);

#ifdef __cplusplus
}
#endif

#endif
