/* Writing a whole file safely: to a temporary name beside it, then renamed
 * into place, so a reader never sees half a file (a model, a picture) and a
 * failed write leaves the old one. */
#ifndef MTS_FILEIO_H
#define MTS_FILEIO_H

#include <stddef.h>

#include "error.h"

mts_result mts_file_write_atomic(const char *path, const void *data, size_t size,
                                 mts_error *err);

/* ASCII case-insensitive equality with an all-lower-case b (file extensions,
 * URL schemes): locale-independent, unlike strcasecmp. */
static inline int mts_ascii_ieq(const char *a, const char *lower_b)
{
    for (; *a && *lower_b; a++, lower_b++) {
        char x = *a >= 'A' && *a <= 'Z' ? (char)(*a | 0x20) : *a;
        if (x != *lower_b)
            return 0;
    }
    return !*a && !*lower_b;
}

#endif
