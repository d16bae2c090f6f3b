/* mts-server over a models folder of hostile files, as a user runs it: beside
 * cow.off, a 50 GB file and a 2 GB one of zeros (sparse: no disk), a FIFO, a
 * directory named like a mesh, a dangling symbolic link, links to
 * /etc/passwd and to a file holding a secret, 50 GB and garbage model files,
 * a file name with terminal escapes. The server starts at once and within
 * little memory, logs one line per bad file naming it and the reason and
 * quoting none of the files' contents, and serves cow to mts-client with the
 * checksum of cow's own stream. --max-mesh-bytes refuses a file over it by
 * name; with no file servable at all the server exits 1 and says so. */
#include <fcntl.h>
#include <stdint.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "build.h"
#include "clock.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "test_proc.h"

static char bin_dir[512], tmp_dir[512];

#define SECRET "SECRET-7f3a9c-MARKER"

/* A fresh models folder: cow.off, and each bad file the setup names. */
static int make_dir(mts_test *t, const char *dir, const char *setup)
{
    char cmd[4096], out[4096];
    snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir -p %s && cd %s && %s", dir, dir, dir, setup);
    int rc = mts_test_run(cmd, out, sizeof out);
    CHECKF(t, rc == 0, "setup of %s: %s", dir, out);
    return rc == 0;
}

/* The lines of log that name file ("/file"); the last of them in line. */
static int lines_naming(const char *log, const char *file, char *line, size_t size)
{
    char needle[128];
    snprintf(needle, sizeof needle, "/%s", file);
    int n = 0;
    line[0] = 0;
    for (const char *p = log; *p;) {
        size_t len = strcspn(p, "\n");
        const char *hit = strstr(p, needle);
        if (hit && hit < p + len) {
            n++;
            snprintf(line, size, "%.*s", (int)len, p);
        }
        p += len + (p[len] == '\n');
    }
    return n;
}

/* Nothing but printable ASCII and line ends: no file's bytes reached it. */
static int printable_log(const char *log)
{
    for (const unsigned char *p = (const unsigned char *)log; *p; p++)
        if (*p != '\n' && (*p < 0x20 || *p >= 0x7f))
            return 0;
    return 1;
}

static long peak_rss_kb(pid_t pid)
{
    char path[64], status[8192];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    mts_test_read_file(path, status, sizeof status);
    const char *p = strstr(status, "VmHWM:");
    return p ? strtol(p + 6, NULL, 10) : -1;
}

/* Waits up to `seconds` for pid to exit: its status, or -2 (then killed). */
static int wait_exit(pid_t pid, double seconds)
{
    double t0 = mts_clock_seconds();
    int st = 0;
    while (waitpid(pid, &st, WNOHANG) == 0) {
        if (mts_clock_seconds() - t0 > seconds) {
            kill(pid, SIGKILL);
            waitpid(pid, NULL, 0);
            return -2;
        }
        usleep(20000);
    }
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* The checksum of cow's full level, from its stream built here. */
static int cow_checksum(mts_test *t, char *out, size_t size)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m = {0};
    mts_stream s = {0};
    int ok = mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK &&
             mts_build_model(&mesh, "cow", NULL, &m, NULL, &err) == MTS_OK &&
             mts_stream_build(&m, "cow", NULL, &s, &err) == MTS_OK;
    CHECKF(t, ok, "%s", err.msg);
    if (ok)
        snprintf(out, size, "\"%016llx\"", (unsigned long long)s.level_checksum[s.model.level_count]);
    mts_stream_free(&s);
    mts_model_free(&m);
    mts_mesh_free(&mesh);
    return ok;
}

/* Serves dir (extra: one more option pair, or NULLs), checks cow streams
 * whole to mts-client, stops; the log into log. */
static void serve_and_stream(mts_test *t, const char *name, const char *dir, const char *opt,
                             const char *val, char *log, size_t log_size)
{
    char listen[64], server_bin[600], log_path[700], out[8192], cmd[2048], want[64];
    snprintf(listen, sizeof listen, "127.0.0.1:%d", mts_test_free_port());
    snprintf(server_bin, sizeof server_bin, "%s/mts-server", bin_dir);
    snprintf(log_path, sizeof log_path, "%s/models_dir_%s.log", tmp_dir, name);
    char *argv[] = {server_bin, "--models", (char *)dir, "--listen", listen,
                    (char *)opt, (char *)val, NULL};
    double t0 = mts_clock_seconds();
    pid_t pid = mts_test_spawn(argv, log_path);
    int up = mts_test_wait_models(bin_dir, listen, "cow", 300, out, sizeof out);
    double dt = mts_clock_seconds() - t0;
    long rss = peak_rss_kb(pid);
    CHECKF(t, up, "%s: the server did not list cow within 30 s (%s)", name, log_path);
    /* before: one file it could not hold ended start-up (exit 1); cow builds
     * in well under a second, in a few under ASan */
    CHECKF(t, dt < 15, "%s: up after %.1f s", name, dt);
#ifndef __SANITIZE_ADDRESS__
    CHECKF(t, rss > 0 && rss < 200 * 1024, "%s: peak resident memory %ld kB", name, rss);
#endif
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  %s: listing cow after %.2f s, peak resident %ld kB\n", name, dt, rss);
    if (up && cow_checksum(t, want, sizeof want)) {
        snprintf(cmd, sizeof cmd, "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --no-render --json",
                 bin_dir, listen);
        int rc = mts_test_run(cmd, out, sizeof out);
        char sum[64];
        mts_test_json(out, "checksum", sum, sizeof sum);
        CHECKF(t, rc == 0 && strstr(out, "\"complete\":true") &&
                      mts_test_json_long(out, "triangles") == 5804 && !strcmp(sum, want),
               "%s: exit %d, want checksum %s: %s", name, rc, want, out);
    }
    CHECKF(t, mts_test_stop(pid) == 0, "%s: the server did not stop cleanly (%s)", name,
           log_path);
    mts_test_read_file(log_path, log, log_size);
}

static void test_hostile_folder(mts_test *t)
{
    char dir[700], log[65536], line[1024];
    snprintf(dir, sizeof dir, "%s/models_dir_hostile", tmp_dir);
    char setup[3000], cwd[900];
    snprintf(setup, sizeof setup,
             "cp %s/tests/data/cow.off . && truncate -s 50G huge.off && truncate -s 2G zeros.off "
             "&& (printf '" SECRET " line one\\n'; head -c 100000 /dev/zero) > secret.txt "
             "&& truncate -s 1G secret.txt && ln -s secret.txt secret.off "
             "&& ln -s secret.txt secret.ply && ln -s secret.txt secret.stl "
             "&& ln -s secret.txt secret.obj && printf '" SECRET "\\n' > small.txt "
             "&& ln -s small.txt small.off && ln -s /etc/passwd passwd.off "
             "&& mkfifo fifo.off && mkdir dir.off && ln -s nowhere dangling.off "
             "&& truncate -s 50G huge.mtsm && truncate -s 2G junk.mtsm "
             "&& printf '" SECRET "' > \"$(printf 'esc\\033[2J')\".off",
             getcwd(cwd, sizeof cwd) ? cwd : ".");
    if (!make_dir(t, dir, setup))
        return;
    serve_and_stream(t, "hostile", dir, NULL, NULL, log, sizeof log);

    static const struct {
        const char *file, *reason;
    } bad[] = {
        {"huge.off", "53687091200 bytes, over the size cap of 4294967296 bytes (--max-mesh-bytes)"},
        {"zeros.off", "not an OFF file"},
        {"secret.off", "not an OFF file"},
        {"secret.ply", "not a PLY file"},
        {"secret.stl", "no triangles"},
        {"secret.obj", "not an OBJ file"},
        {"small.off", "not an OFF file"},
        {"passwd.off", "not an OFF file"},
        {"fifo.off", "a FIFO, not a regular file"},
        {"dir.off", "a directory, not a regular file"},
        {"dangling.off", "a symbolic link to nothing"},
        {"huge.mtsm", "53687091200 bytes, over the size cap"},
        {"junk.mtsm", "not an mtstream model"},
        {"esc?[2J.off", "model name"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        int n = lines_naming(log, bad[i].file, line, sizeof line);
        CHECKF(t, n == 1 && strstr(line, bad[i].reason), "%s: %d lines, the last: %s",
               bad[i].file, n, line);
    }
    CHECKF(t, lines_naming(log, "cow.off", line, sizeof line) == 1 && strstr(line, "added"),
           "cow.off: %s", line);
    /* none of the files' contents: the secret, /etc/passwd's first line, the
     * escape sequence in a file name */
    CHECKF(t, !strstr(log, SECRET) && !strstr(log, "root:"), "a file's text in the log:\n%s", log);
    CHECKF(t, printable_log(log), "bytes a terminal acts on in the log:\n%s", log);
    char cmd[800], out[256];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    mts_test_run(cmd, out, sizeof out);
}

/* --max-mesh-bytes: a mesh over it is skipped by name, the others served. */
static void test_cap_option(mts_test *t)
{
    char dir[700], log[65536], line[1024], setup[2000], cwd[900];
    snprintf(dir, sizeof dir, "%s/models_dir_cap", tmp_dir);
    /* big.off: cow with 150 kB of comments, over a cap of 200K that cow is under */
    snprintf(setup, sizeof setup,
             "cp %s/tests/data/cow.off . && (cat cow.off; for i in $(seq 3000); do "
             "echo '# a comment line to make the file bigger than the cap'; done) > big.off",
             getcwd(cwd, sizeof cwd) ? cwd : ".");
    if (!make_dir(t, dir, setup))
        return;
    serve_and_stream(t, "cap", dir, "--max-mesh-bytes", "200K", log, sizeof log);
    CHECKF(t, lines_naming(log, "big.off", line, sizeof line) == 1 &&
                  strstr(line, "bytes, over the size cap of 204800 bytes (--max-mesh-bytes)"),
           "big.off: %s", line);
    char cmd[1600], out[4096];
    snprintf(cmd, sizeof cmd, "%s/mts-server --models %s --max-mesh-bytes 2X", bin_dir, dir);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 2 && strstr(out, "--max-mesh-bytes"), "%s",
           out);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    mts_test_run(cmd, out, sizeof out);
}

/* Start-up fails only when nothing at all can be served: a folder of bad
 * files, or an empty one, is exit 1 with a reason, at once. */
static void test_nothing_servable(mts_test *t)
{
    char dir[700], log_path[800], log[16384], line[1024];
    snprintf(dir, sizeof dir, "%s/models_dir_none", tmp_dir);
    for (int empty = 0; empty < 2; empty++) {
        if (!make_dir(t, dir, empty ? "true" : "truncate -s 50G huge.off && mkfifo fifo.off"))
            return;
        char server_bin[600], listen[64];
        snprintf(server_bin, sizeof server_bin, "%s/mts-server", bin_dir);
        snprintf(listen, sizeof listen, "127.0.0.1:%d", mts_test_free_port());
        snprintf(log_path, sizeof log_path, "%s/models_dir_none.log", tmp_dir);
        char *argv[] = {server_bin, "--models", dir, "--listen", listen, NULL};
        pid_t pid = mts_test_spawn(argv, log_path);
        int rc = wait_exit(pid, 20);
        mts_test_read_file(log_path, log, sizeof log);
        CHECKF(t, rc == 1 && strstr(log, "no model to serve"), "%s folder: exit %d: %s",
               empty ? "empty" : "bad", rc, log);
        if (!empty)
            CHECKF(t, lines_naming(log, "huge.off", line, sizeof line) == 1 &&
                          lines_naming(log, "fifo.off", line, sizeof line) == 1,
                   "%s", log);
    }
    char cmd[800], out[256];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    mts_test_run(cmd, out, sizeof out);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    mts_test t = {0};
    RUN(&t, test_hostile_folder);
    RUN(&t, test_cap_option);
    RUN(&t, test_nothing_servable);
    return mts_test_end(&t);
}
