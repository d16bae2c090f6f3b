/* The programs as a user runs them: --help, usage errors (exit 2), bad input
 * (exit 1 with a message naming the file), --json lines with the documented
 * keys, --verify, --obj. The binaries are found beside this test program
 * (build/tests/.. -> build/bin). */
#include <libgen.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#include "build.h"
#include "clock.h"
#include "test.h"
#include "test_proc.h"
#include "modelfile.h"
#include "strips.h"
#include "tunnel.h"

static char bin_dir[512];
static char tmp_dir[512];

/* Runs a shell command, captures stdout and stderr together, returns the exit status. */
static int has_key(const char *json, const char *key)
{
    char k[128];
    snprintf(k, sizeof k, "\"%s\":", key);
    return strstr(json, k) != NULL;
}

static void test_help_and_usage(mts_test *t)
{
    char cmd[8192], out[8192];
    const char *progs[] = {"mts-build", "mts-inspect"};
    for (int i = 0; i < 2; i++) {
        snprintf(cmd, sizeof cmd, "%s/%s --help", bin_dir, progs[i]);
        CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s --help", progs[i]);
        CHECK(t, strstr(out, "usage:") != NULL);
        snprintf(cmd, sizeof cmd, "%s/%s", bin_dir, progs[i]);
        CHECKF(t, mts_test_run(cmd, out, sizeof out) == 2, "%s without arguments should exit 2", progs[i]);
        snprintf(cmd, sizeof cmd, "%s/%s --no-such-option x", bin_dir, progs[i]);
        CHECK(t, mts_test_run(cmd, out, sizeof out) == 2);
        CHECK(t, strstr(out, "--no-such-option") != NULL);
    }
    snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off --base-vertices abc", bin_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2);
    const char *caps[] = {"0", "257", "x"};
    for (size_t i = 0; i < sizeof caps / sizeof caps[0]; i++) {
        snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off --max-strip %s", bin_dir, caps[i]);
        CHECKF(t, mts_test_run(cmd, out, sizeof out) == 2, "--max-strip %s", caps[i]);
        CHECKF(t, strstr(out, "--max-strip"), "message: %s", out);
    }
    snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off --max-strip 16 --tunnel-length 0",
             bin_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2);
    CHECKF(t, strstr(out, "tunnelling"), "message: %s", out);
    const char *efforts[] = {"-1", "abc", "1000001", ""};
    for (size_t i = 0; i < sizeof efforts / sizeof efforts[0]; i++) {
        snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off --strip-effort '%s'", bin_dir,
                 efforts[i]);
        CHECKF(t, mts_test_run(cmd, out, sizeof out) == 2, "--strip-effort '%s'", efforts[i]);
        CHECKF(t, strstr(out, "--strip-effort"), "message: %s", out);
    }
    snprintf(cmd, sizeof cmd, "%s/mts-inspect x.mtsm --fraction 1.5", bin_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2);
}

static void test_bad_input_exits_1(mts_test *t)
{
    char cmd[8192], out[8192], path[1024];
    snprintf(cmd, sizeof cmd, "%s/mts-build /nonexistent/mesh.off -o %s/x.mtsm", bin_dir, tmp_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 1);
    CHECKF(t, strstr(out, "/nonexistent/mesh.off") != NULL, "message: %s", out);

    snprintf(path, sizeof path, "%s/garbage.off", tmp_dir);
    FILE *f = fopen(path, "w");
    fputs("OFF\n3 1 0\n0 0 0\n1 0 0\n", f); /* ends before its third vertex */
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s/x.mtsm", bin_dir, path, tmp_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 1);
    CHECKF(t, strstr(out, "garbage.off") && strstr(out, "truncated"), "message: %s", out);

    snprintf(path, sizeof path, "%s/not_a_model.mtsm", tmp_dir);
    f = fopen(path, "w");
    fputs("this is not a model file at all", f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s", bin_dir, path);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 1);
    CHECKF(t, strstr(out, "not_a_model.mtsm") && strstr(out, "magic"), "message: %s", out);
}

/* mts-build reads regular files only, and only up to --max-mesh-bytes,
 * checked before reading: a file over it, a 50 GB one (sparse: no disk) and
 * a FIFO (whose open would wait for a writer) are refused by name with exit
 * 1 at once. */
static void test_build_refuses_non_files(mts_test *t)
{
    char cmd[8192], out[8192], dir[700], path[800];
    snprintf(dir, sizeof dir, "%s/programs_files", tmp_dir);
    snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir -p %s && mkfifo %s/fifo.off && truncate -s 50G "
             "%s/huge.off",
             dir, dir, dir, dir);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    const struct {
        const char *file, *option, *want;
    } cases[] = {
        {"tests/data/cow.off", "--max-mesh-bytes 100K",
         "cow.off: 182966 bytes, over the size cap of 102400 bytes (--max-mesh-bytes)"},
        {"huge.off", "", "huge.off: 53687091200 bytes, over the size cap of 4294967296 bytes"},
        {"huge.off", "--max-mesh-bytes 64G", "huge.off: not an OFF file"},
        {"fifo.off", "", "fifo.off: a FIFO, not a regular file"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        if (cases[i].file[0] == 't')
            snprintf(path, sizeof path, "%s", cases[i].file);
        else
            snprintf(path, sizeof path, "%s/%s", dir, cases[i].file);
        /* timeout: a FIFO opened without O_NONBLOCK would wait forever */
        snprintf(cmd, sizeof cmd, "timeout 20 %s/mts-build %s -o %s/x.mtsm %s", bin_dir, path,
                 dir, cases[i].option);
        double t0 = mts_clock_seconds();
        int rc = mts_test_run(cmd, out, sizeof out);
        double dt = mts_clock_seconds() - t0;
        CHECKF(t, rc == 1 && strstr(out, cases[i].want) && dt < 5, "%s %s: exit %d in %.1f s: %s",
               cases[i].file, cases[i].option, rc, dt, out);
    }
    /* the cap's spellings: bytes, K, M, G; anything else is a usage error */
    snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off -o %s/x.mtsm -q --max-mesh-bytes 1M",
             bin_dir, dir);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    snprintf(cmd, sizeof cmd,
             "%s/mts-build tests/data/cow.off -o %s/x.mtsm -q --max-mesh-bytes 182966", bin_dir,
             dir);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    const char *bad[] = {"0", "abc", "1X", "-1", "1MB", "99999999999999999999", ""};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off --max-mesh-bytes '%s'",
                 bin_dir, bad[i]);
        CHECKF(t, mts_test_run(cmd, out, sizeof out) == 2 && strstr(out, "--max-mesh-bytes"),
               "'%s': %s", bad[i], out);
    }
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 0);
}

static void test_build_inspect_verify(mts_test *t)
{
    char cmd[8192], out[16384], model[1024], obj[1024];
    snprintf(model, sizeof model, "%s/cow_programs.mtsm", tmp_dir);
    snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off -o %s --json", bin_dir, model);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    const char *keys[] = {"vertices", "triangles", "levels", "base_vertices", "base_triangles",
                          "strips_full", "indices_full", "file_bytes", "seconds", "load",
                          "stripify", "simplify", "records", "write"};
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
        CHECKF(t, has_key(out, keys[i]), "mts-build --json lacks %s: %s", keys[i], out);
    CHECK(t, strstr(out, "\"vertices\":2904") != NULL);
    CHECK(t, strstr(out, "\"triangles\":5804") != NULL);
    CHECKF(t, strstr(out, "\"strip_effort\":" MTS_TUNNEL_DEFAULT_ANNEAL_STR ","), "%s", out);
    char *ipt = strstr(out, "\"indices_per_triangle_full\":");
    double ipt_default = ipt ? atof(ipt + strlen("\"indices_per_triangle_full\":")) : 0;

    /* --strip-effort reaches the tunnelling pass: none gives other strips
     * (the greedy ones, tunnelled), as the JSON says */
    char model0[1024];
    snprintf(model0, sizeof model0, "%s/cow_effort0.mtsm", tmp_dir);
    snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off -o %s --strip-effort 0 --json",
             bin_dir, model0);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "\"strip_effort\":0,"), "%s", out);
    ipt = strstr(out, "\"indices_per_triangle_full\":");
    double ipt_none = ipt ? atof(ipt + strlen("\"indices_per_triangle_full\":")) : 0;
    CHECKF(t, ipt_default > 1 && ipt_none > ipt_default, "idx/tri %.4f without annealing, %.4f with",
           ipt_none, ipt_default);

    /* --max-strip: every full-level strip within it, the model still valid
     * at every level */
    snprintf(cmd, sizeof cmd, "%s/mts-build tests/data/cow.off -o %s --max-strip 16 --json",
             bin_dir, model0);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "\"max_strip\":16,"), "%s", out);
    mts_model capped = {0};
    mts_error err = {0};
    CHECKF(t, mts_modelfile_load(model0, &capped, &err) == MTS_OK, "%s", err.msg);
    uint64_t longest = 0, drawn = 0;
    for (uint32_t s = 0; s < capped.full.strip_count; s++) {
        mts_strip_stats one = {0};
        mts_strip_stats_add(&one, capped.full.indices + capped.full.offsets[s],
                            capped.full.offsets[s + 1] - capped.full.offsets[s]);
        longest = one.triangles > longest ? one.triangles : longest;
        drawn += one.triangles;
    }
    CHECKF(t, drawn == 5804 && longest == 16, "%llu triangles, the longest strip %llu",
           (unsigned long long)drawn, (unsigned long long)longest);
    mts_model_free(&capped);
    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s --verify --json", bin_dir, model0);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0 && strstr(out, "\"verified\":true"), "%s",
           out);
    /* one line */
    char *nl = strchr(out, '\n');
    CHECK(t, nl && nl[1] == 0);

    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s --verify --json", bin_dir, model);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECK(t, strstr(out, "\"verified\":true") != NULL);
    CHECK(t, strstr(out, "\"levels_verified\":2876") != NULL);

    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s --sample 50", bin_dir, model);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECK(t, strstr(out, "at 50 levels") != NULL);

    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s --level 99999", bin_dir, model);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2);

    /* --obj at the base level: as many faces as the level table says */
    snprintf(obj, sizeof obj, "%s/cow_base.obj", tmp_dir);
    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s --level 0 --obj %s --json", bin_dir, model, obj);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    const char *tri = strstr(out, "\"level\":{");
    unsigned long want = 0;
    CHECK(t, tri && sscanf(strstr(tri, "\"triangles\":"), "\"triangles\":%lu", &want) == 1);
    FILE *f = fopen(obj, "r");
    CHECK(t, f != NULL);
    unsigned long faces = 0, verts = 0;
    char line[256];
    while (f && fgets(line, sizeof line, f)) {
        faces += line[0] == 'f' && line[1] == ' ';
        verts += line[0] == 'v' && line[1] == ' ';
    }
    if (f)
        fclose(f);
    CHECKF(t, faces == want && faces > 0, "obj has %lu faces, level says %lu", faces, want);
    CHECK(t, verts == 29);
    /* the OBJ is a mesh our own loader reads back */
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s/cow_base_again.mtsm --json", bin_dir, obj,
             tmp_dir);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);

    /* a model damaged after the fact is refused with its name */
    f = fopen(model, "r+b");
    CHECK(t, f != NULL);
    if (f) {
        fseek(f, 200, SEEK_SET);
        fputc(0x5a, f);
        fclose(f);
    }
    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s", bin_dir, model);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 1);
    CHECKF(t, strstr(out, "checksum"), "message: %s", out);
    remove(model);
    remove(obj);
}

static int same_file(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int same = fa && fb;
    while (same) {
        int ca = getc(fa), cb = getc(fb);
        same = ca == cb;
        if (ca == EOF || cb == EOF)
            break;
    }
    if (fa)
        fclose(fa);
    if (fb)
        fclose(fb);
    return same;
}

static int copy_file(const char *from, const char *to)
{
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "cp %s %s", from, to);
    return system(cmd) == 0;
}

/* Vertex colours as a user sees them: kept and said so, left out with
 * --no-colors (the model an uncoloured mesh gives, byte for byte), weighed
 * in the collapses unless --color-cost 0, warned
 * of when only some vertices have one, shown by mts-inspect and written
 * by its --obj. */
static void test_build_colors(mts_test *t)
{
    char cmd[8192], out[16384], mesh[1024], colored[1024], plain[1024], dropped[1024], obj[1024];
    /* one path for both meshes, no extension (the content says the format),
     * so that the models' source names are the same */
    snprintf(mesh, sizeof mesh, "%s/colors_mesh", tmp_dir);
    snprintf(colored, sizeof colored, "%s/colors_kept.mtsm", tmp_dir);
    snprintf(plain, sizeof plain, "%s/colors_plain.mtsm", tmp_dir);
    snprintf(dropped, sizeof dropped, "%s/colors_dropped.mtsm", tmp_dir);
    snprintf(obj, sizeof obj, "%s/colors.obj", tmp_dir);

    CHECK(t, copy_file("tests/data/cow.off", mesh));
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s --json", bin_dir, mesh, plain);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "\"colors\":false"), "%s", out);

    CHECK(t, copy_file("tests/data/cow_colors.ply", mesh));
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s --json", bin_dir, mesh, colored);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "\"colors\":true"), "%s", out);
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s --no-colors --json", bin_dir, mesh, dropped);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "\"colors\":false"), "%s", out);
    CHECK(t, same_file(plain, dropped));
    CHECK(t, !same_file(plain, colored));
    /* --color-cost: 0 leaves the collapses to the geometry, which the
     * default colour term changes; the default is the weight it names */
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s --color-cost 0 --quiet", bin_dir, mesh,
             dropped);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECK(t, !same_file(dropped, colored));
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s --color-cost " MTS_BUILD_DEFAULT_COLOR_COST_STR
             " --quiet", bin_dir, mesh, dropped);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECK(t, same_file(dropped, colored));
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s --color-cost -1 2>&1", bin_dir, mesh, dropped);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) != 0 && strstr(out, "--color-cost"), "%s", out);

    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s --obj %s", bin_dir, colored, obj);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "vertex colours: yes"), "%s", out);
    snprintf(cmd, sizeof cmd, "%s/mts-inspect %s --json", bin_dir, plain);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "\"colors\":false"), "%s", out);
    /* the OBJ's colours read back as colours */
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s --json", bin_dir, obj, dropped);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "\"colors\":true"), "%s", out);

    /* --no-colors on a model's stream file is accepted */
    snprintf(cmd, sizeof cmd, "%s/mts-build %s --stream %s/colors.mts --no-colors --json", bin_dir,
             colored, tmp_dir);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "\"colors\":false"), "%s", out);

    /* some vertices coloured, one not: warned, and no colours */
    FILE *f = fopen(obj, "w");
    if (f) {
        fputs("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0\nv 0 0 1 0 0 1 0.5\n"
              "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n", f);
        fclose(f);
    }
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s --json", bin_dir, obj, dropped);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(t, strstr(out, "1 vertices have no colour while the others have one"), "%s", out);
    CHECKF(t, strstr(out, "\"colors\":false") && strstr(out, "\"colors_missing\":1"), "%s", out);
    remove(mesh);
    remove(colored);
    remove(plain);
    remove(dropped);
    remove(obj);
    snprintf(cmd, sizeof cmd, "%s/colors.mts", tmp_dir);
    remove(cmd);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    mts_test t = {0};
    RUN(&t, test_help_and_usage);
    RUN(&t, test_bad_input_exits_1);
    RUN(&t, test_build_refuses_non_files);
    RUN(&t, test_build_inspect_verify);
    RUN(&t, test_build_colors);
    return mts_test_end(&t);
}
