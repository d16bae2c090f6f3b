#include "fileio.h"

#include <errno.h>
#include <fcntl.h>
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

static mts_result not_regular(const char *path, mode_t mode, mts_error *err)
{
    const char *kind = S_ISDIR(mode)    ? "a directory, "
                       : S_ISFIFO(mode) ? "a FIFO, "
                       : S_ISSOCK(mode) ? "a socket, "
                       : S_ISCHR(mode)  ? "a character device, "
                       : S_ISBLK(mode)  ? "a block device, "
                                        : "";
    return mts_error_set(err, MTS_ERR_IO, "%s: %snot a regular file", path, kind);
}

mts_result mts_file_open_regular(const char *path, uint64_t max_bytes, const char *cap_hint,
                                 int *fd, uint64_t *size, mts_error *err)
{
    *fd = -1;
    *size = 0;
    /* A look at the path first, so that a device is not even opened (opening
     * some has effects of its own); the fstat below is what counts. */
    struct stat st;
    if (stat(path, &st) != 0) {
        int e = errno;
        struct stat lst;
        if (e == ENOENT && lstat(path, &lst) == 0 && S_ISLNK(lst.st_mode))
            return mts_error_set(err, MTS_ERR_IO, "%s: a symbolic link to nothing", path);
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode))
        return not_regular(path, st.st_mode, err);
    int f = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (f < 0)
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(errno));
    if (fstat(f, &st) != 0) {
        int e = errno;
        close(f);
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(f);
        return not_regular(path, st.st_mode, err);
    }
    uint64_t n = st.st_size > 0 ? (uint64_t)st.st_size : 0;
    if (max_bytes && n > max_bytes) {
        close(f);
        if (cap_hint)
            return mts_error_set(err, MTS_ERR_LIMIT,
                                 "%s: %llu bytes, over the size cap of %llu bytes (%s)", path,
                                 (unsigned long long)n, (unsigned long long)max_bytes, cap_hint);
        return mts_error_set(err, MTS_ERR_LIMIT, "%s: %llu bytes, over the size cap of %llu bytes",
                             path, (unsigned long long)n, (unsigned long long)max_bytes);
    }
    *fd = f;
    *size = n;
    return MTS_OK;
}

mts_result mts_file_read_exact(int fd, const char *path, void *buf, size_t size,
                               mts_error *err)
{
    size_t got = 0;
    while (got < size) {
        /* Linux reads at most about 2 GiB at a time */
        size_t want = size - got < ((size_t)1 << 30) ? size - got : (size_t)1 << 30;
        ssize_t r = read(fd, (char *)buf + got, want);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(errno));
        if (r == 0)
            return mts_error_set(err, MTS_ERR_IO,
                                 "%s: the file ended after %zu of its %zu bytes (it changed "
                                 "while being read)",
                                 path, got, size);
        got += (size_t)r;
    }
    return MTS_OK;
}
