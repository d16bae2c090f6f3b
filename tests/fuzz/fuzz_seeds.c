/* Writes the fuzz targets' seed corpora (fuzz_seeds.h) as files:
 *
 *   fuzz-seeds OUTDIR [COW.off]
 *
 * makes OUTDIR/<target>/<seed name> for each target; `make fuzz` runs it into
 * build/fuzz/seeds and copies each folder into the target's working corpus. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

#include "fuzz_seeds.h"

typedef struct seed_writer {
    const char *dir;
    int failed;
    unsigned count;
} seed_writer;

static void write_seed(void *user, const char *target, const char *name, const uint8_t *data,
                       size_t size)
{
    seed_writer *w = user;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", w->dir, target);
    if (mkdir(path, 0755) != 0 && errno != EEXIST) {
        fprintf(stderr, "fuzz-seeds: %s: %s\n", path, strerror(errno));
        w->failed = 1;
        return;
    }
    snprintf(path, sizeof path, "%s/%s/%s", w->dir, target, name);
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(data, 1, size, f) != size || fclose(f) != 0) {
        fprintf(stderr, "fuzz-seeds: cannot write %s\n", path);
        w->failed = 1;
        return;
    }
    w->count++;
}

int main(int argc, char **argv)
{
    if (argc < 2 || argc > 3) {
        fprintf(stderr, "usage: fuzz-seeds OUTDIR [COW.off]\n");
        return 2;
    }
    seed_writer w = {argv[1], 0, 0};
    if (mkdir(w.dir, 0755) != 0 && errno != EEXIST) {
        fprintf(stderr, "fuzz-seeds: %s: %s\n", w.dir, strerror(errno));
        return 1;
    }
    mts_error err = {0};
    if (mts_fuzz_make_seeds(argc > 2 ? argv[2] : NULL, 0, write_seed, &w, &err) != MTS_OK) {
        fprintf(stderr, "fuzz-seeds: %s\n", err.msg);
        return 1;
    }
    if (w.failed)
        return 1;
    printf("fuzz-seeds: %u seeds in %s\n", w.count, w.dir);
    return 0;
}
