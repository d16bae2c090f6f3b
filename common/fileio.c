#include "fileio.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

mts_result mts_file_write_atomic(const char *path, const void *data, size_t size,
                                 mts_error *err)
{
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid()) >= (int)sizeof tmp)
        return mts_error_set(err, MTS_ERR_ARG, "%s: path too long", path);
    FILE *f = fopen(tmp, "wb");
    if (!f)
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(errno));
    int ok = fwrite(data, 1, size, f) == size;
    int e = ok ? 0 : errno;
    if (fclose(f) != 0 && ok) {
        ok = 0;
        e = errno;
    }
    if (ok && rename(tmp, path) != 0) {
        ok = 0;
        e = errno;
    }
    if (!ok) {
        unlink(tmp);
        return mts_error_set(err, MTS_ERR_IO, "%s: write failed: %s", path,
                             strerror(e ? e : EIO));
    }
    return MTS_OK;
}
