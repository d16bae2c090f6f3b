#include "fileio.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

mts_result mts_file_write_atomic(const char *path, const void *data, size_t size,
                                 mts_error *err)
{
    /* a unique temporary name (mkstemp), not one made from the pid: two
     * servers in two containers are both pid 1, and may share the folder */
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s.tmp.XXXXXX", path) >= (int)sizeof tmp)
        return mts_error_set(err, MTS_ERR_ARG, "%s: path too long", path);
    int fd = mkstemp(tmp);
    FILE *f = fd >= 0 ? fdopen(fd, "wb") : NULL;
    if (!f) {
        int e = errno;
        if (fd >= 0) {
            close(fd);
            unlink(tmp);
        }
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(e));
    }
    /* mkstemp makes it 0600; a model file is for every server to read (the
     * umask is not asked: reading it means setting it, process-wide) */
    fchmod(fd, 0644);
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
