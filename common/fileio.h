/* Writing a whole file safely: to a temporary name beside it, then renamed
 * into place, so a reader never sees half a file (a model, a picture) and a
 * failed write leaves the old one. Reading one safely: only a regular file,
 * only up to a size cap, never blocking on what is not a file. */
#ifndef MTS_FILEIO_H
#define MTS_FILEIO_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

mts_result mts_file_write_atomic(const char *path, const void *data, size_t size,
                                 mts_error *err);

/* Opens path for reading when it is a regular file of at most max_bytes
 * (0: any size), and refuses anything else by name and reason: a directory,
 * FIFO, socket or device, a symbolic link to nothing, a file over the cap
 * ("PATH: N bytes, over the size cap of M bytes (cap_hint)"; cap_hint, e.g.
 * the option that sets the cap, may be NULL). The descriptor is opened with
 * O_NONBLOCK, so that a FIFO swapped in for the file cannot block the
 * caller, and it is fstat on that descriptor, not stat on the path, that
 * decides: what is read is what was checked. On success *fd is open
 * (O_CLOEXEC) and *size is the file's size. */
mts_result mts_file_open_regular(const char *path, uint64_t max_bytes, const char *cap_hint,
                                 int *fd, uint64_t *size, mts_error *err);

/* Reads exactly size bytes from fd into buf; a file that ends sooner (it
 * shrank after it was opened) is an error naming path. */
mts_result mts_file_read_exact(int fd, const char *path, void *buf, size_t size,
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
