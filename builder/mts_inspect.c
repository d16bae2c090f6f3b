/* mts-inspect: a model file's figures, a level's figures and mesh, and
 * verification of the invariants at every (or sampled) level. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "lod.h"
#include "model.h"
#include "modelfile.h"
#include "verify.h"

static void usage(FILE *f)
{
    fputs("usage: mts-inspect MODEL.mtsm [--verify] [--sample N] [--level L | --fraction F]\n"
          "                   [--obj OUT.obj] [--json]\n"
          "\n"
          "Prints a model's figures (and whether it has vertex colours). Loading always\n"
          "checks the file's checksums and replays every record once.\n"
          "\n"
          "  --verify          check invariants 1 (strips draw exactly the mesh\n"
          "                    at each level, with its winding) and 2 (refining up and\n"
          "                    coarsening down agree) at every level; exit 1 at the first\n"
          "                    failure, naming the level and strip; and that every\n"
          "                    record follows from the split descriptions a stream sends\n"
          "  --sample N        verify N levels spread evenly instead of all\n"
          "  --level L         figures at level L (0 = base mesh, levels = full mesh)\n"
          "  --fraction F      the level with F x the full vertex count (0..1)\n"
          "  --obj FILE        write the mesh at that level (default: full) as OBJ\n"
          "                    (with the vertex colours, v x y z r g b, where the model\n"
          "                    has them)\n"
          "  --json            one line of JSON\n"
          "  -h, --help        this help\n"
          "\n"
          "Exit status: 0 fine, 1 unreadable model or failed verification, 2 bad usage.\n",
          f);
}

typedef struct level_figures {
    uint32_t level, vertices, strips;
    uint64_t indices, triangles, degenerate;
} level_figures;

static void figures_at(const mts_lod *lod, level_figures *lf)
{
    mts_strip_stats st = {0};
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(lod, s, &len);
        mts_strip_stats_add(&st, str, len);
    }
    lf->level = lod->level;
    lf->vertices = lod->model->base_vertex_count + lod->level;
    lf->strips = st.strips;
    lf->indices = mts_strip_stats_draw_indices(&st);
    lf->triangles = st.triangles;
    lf->degenerate = st.degenerate;
}

static mts_result write_obj(const mts_lod *lod, const char *path, mts_error *err)
{
    const mts_model *m = lod->model;
    FILE *f = fopen(path, "w");
    if (!f)
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(errno));
    uint32_t nv = m->base_vertex_count + lod->level;
    fprintf(f, "# mtstream model %s at level %u of %u\n", m->source, lod->level, m->level_count);
    for (uint32_t v = 0; v < nv; v++) {
        fprintf(f, "v %.9g %.9g %.9g", m->positions[3 * v], m->positions[3 * v + 1],
                m->positions[3 * v + 2]);
        /* OBJ's common colour extension, 0..1, as the mesh readers take it */
        if (m->colors)
            fprintf(f, " %.6g %.6g %.6g", m->colors[3 * v] / 255.0, m->colors[3 * v + 1] / 255.0,
                    m->colors[3 * v + 2] / 255.0);
        fputc('\n', f);
    }
    for (uint32_t v = 0; v < nv; v++)
        fprintf(f, "vn %.6g %.6g %.6g\n", m->normals[3 * v], m->normals[3 * v + 1],
                m->normals[3 * v + 2]);
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len, t[3];
        const uint32_t *str = mts_lod_strip(lod, s, &len);
        for (uint32_t k = 0; k + 2 < len; k++) {
            if (mts_strip_window(str, k, t))
                fprintf(f, "f %u//%u %u//%u %u//%u\n", t[0] + 1, t[0] + 1, t[1] + 1, t[1] + 1,
                        t[2] + 1, t[2] + 1);
        }
    }
    int failed = ferror(f);
    if (fclose(f) != 0 || failed)
        return mts_error_set(err, MTS_ERR_IO, "%s: write failed: %s", path, strerror(errno));
    return MTS_OK;
}

int main(int argc, char **argv)
{
    const char *path = NULL, *obj = NULL;
    int verify = 0, json = 0, have_level = 0, have_fraction = 0;
    uint32_t samples = 0, level = 0;
    double fraction = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return CLI_EXIT_OK;
        } else if (!strcmp(a, "--verify")) {
            verify = 1;
        } else if (!strcmp(a, "--json")) {
            json = 1;
        } else if (!strcmp(a, "--sample")) {
            if (!cli_option_u32(argc, argv, &i, "mts-inspect", 2, UINT32_MAX, &samples))
                return CLI_EXIT_USAGE;
            verify = 1;
        } else if (!strcmp(a, "--level")) {
            if (!cli_option_u32(argc, argv, &i, "mts-inspect", 0, UINT32_MAX, &level))
                return CLI_EXIT_USAGE;
            have_level = 1;
        } else if (!strcmp(a, "--fraction")) {
            if (++i >= argc || !cli_parse_double(argv[i], &fraction) || fraction < 0 ||
                fraction > 1) {
                fprintf(stderr, "mts-inspect: --fraction needs a number from 0 to 1\n");
                return CLI_EXIT_USAGE;
            }
            have_fraction = 1;
        } else if (!strcmp(a, "--obj")) {
            if (++i >= argc) {
                fprintf(stderr, "mts-inspect: --obj needs a file name\n");
                return CLI_EXIT_USAGE;
            }
            obj = argv[i];
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "mts-inspect: unknown option %s (see --help)\n", a);
            return CLI_EXIT_USAGE;
        } else if (!path) {
            path = a;
        } else {
            fprintf(stderr, "mts-inspect: one model at a time\n");
            return CLI_EXIT_USAGE;
        }
    }
    if (!path) {
        usage(stderr);
        return CLI_EXIT_USAGE;
    }
    if (have_level && have_fraction) {
        fprintf(stderr, "mts-inspect: give --level or --fraction, not both\n");
        return CLI_EXIT_USAGE;
    }

    mts_error err = {0};
    mts_model m;
    mts_lod lod = {0};
    int status = CLI_EXIT_FAIL;
    double t0 = cli_now();
    if (mts_modelfile_load(path, &m, &err) != MTS_OK) {
        fprintf(stderr, "mts-inspect: %s\n", err.msg);
        return CLI_EXIT_FAIL;
    }
    double t_load = cli_now() - t0;
    struct stat st;
    uint64_t file_bytes = stat(path, &st) == 0 ? (uint64_t)st.st_size : 0;
    const uint32_t n = m.level_count;
    if (have_level && level > n) {
        fprintf(stderr, "mts-inspect: level %u is past the full level %u\n", level, n);
        mts_model_free(&m);
        return CLI_EXIT_USAGE;
    }
    if (have_fraction)
        level = mts_model_level_for_fraction(&m, fraction);
    else if (!have_level)
        level = n;

    if (mts_lod_init(&lod, &m, MTS_LOD_AT_BASE, &err) != MTS_OK ||
        mts_lod_set_level(&lod, level, &err) != MTS_OK)
        goto fail;
    level_figures lf;
    figures_at(&lod, &lf);
    if (obj && write_obj(&lod, obj, &err) != MTS_OK)
        goto fail;

    mts_verify_report vr = {0};
    int verified = 0;
    double t_verify = 0;
    if (verify) {
        cli_bar bar;
        cli_bar_init(&bar, json);
        mts_verify_options vo = {0};
        vo.samples = samples;
        vo.progress = cli_bar_progress(&bar);
        double tv = cli_now();
        mts_result rc = mts_verify_model(&m, &vo, &vr, &err);
        /* and what a stream's client derives: every record, from the
         * split descriptions alone */
        mts_verify_report gr = {0};
        if (rc == MTS_OK && (rc = mts_verify_growth(&m, &gr, &err)) != MTS_OK)
            vr = gr;
        t_verify = cli_now() - tv;
        cli_bar_done(&bar);
        if (rc != MTS_OK) {
            if (json) {
                cli_json j;
                cli_json_begin(&j, stdout);
                cli_json_str(&j, "model", path);
                cli_json_bool(&j, "verified", 0);
                cli_json_u64(&j, "failed_level", vr.failed_level);
                if (vr.failed_strip != UINT32_MAX)
                    cli_json_u64(&j, "failed_strip", vr.failed_strip);
                cli_json_str(&j, "error", err.msg);
                cli_json_end(&j);
            }
            goto fail;
        }
        verified = 1;
    }

    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_str(&j, "model", path);
        cli_json_str(&j, "source", m.source);
        cli_json_u64(&j, "file_bytes", file_bytes);
        cli_json_u64(&j, "vertices", m.vertex_count);
        cli_json_u64(&j, "triangles", m.level_triangles[n]);
        cli_json_u64(&j, "levels", n);
        cli_json_u64(&j, "base_vertices", m.base_vertex_count);
        cli_json_u64(&j, "base_triangles", m.level_triangles[0]);
        cli_json_u64(&j, "strip_slots", m.strip_count);
        cli_json_u64(&j, "record_words", m.record_word_count);
        cli_json_bool(&j, "colors", (m.flags & MTS_MODEL_COLORS) != 0);
        cli_json_num(&j, "seconds_load", t_load, 4);
        cli_json_object_begin(&j, "level");
        cli_json_u64(&j, "level", lf.level);
        cli_json_u64(&j, "vertices", lf.vertices);
        cli_json_u64(&j, "triangles", lf.triangles);
        cli_json_u64(&j, "strips", lf.strips);
        cli_json_u64(&j, "indices", lf.indices);
        cli_json_num(&j, "indices_per_triangle", lf.triangles ? (double)lf.indices / lf.triangles : 0, 4);
        cli_json_num(&j, "degenerate_share",
                     lf.triangles + lf.degenerate ? (double)lf.degenerate / (lf.triangles + lf.degenerate) : 0, 4);
        cli_json_object_end(&j);
        if (verify) {
            cli_json_bool(&j, "verified", verified);
            cli_json_u64(&j, "levels_verified", vr.levels_checked);
            cli_json_num(&j, "seconds_verify", t_verify, 3);
        }
        cli_json_end(&j);
    } else {
        printf("%s: built from %s\n", path, m.source[0] ? m.source : "?");
        printf("  %u vertices, %u triangles at the full level; base %u vertices, %u triangles\n",
               m.vertex_count, m.level_triangles[n], m.base_vertex_count, m.level_triangles[0]);
        printf("  %u levels, %u strip slots, %u record words in memory, file %llu bytes\n", n,
               m.strip_count, m.record_word_count, (unsigned long long)file_bytes);
        printf("  vertex colours: %s\n",
               m.flags & MTS_MODEL_COLORS ? "yes (8-bit sRGB, one per vertex)" : "none");
        printf("  level %u: %u vertices, %llu triangles, %u strips, %llu indices with restarts "
               "(%.3f per triangle), %.1f%% degenerate windows\n",
               lf.level, lf.vertices, (unsigned long long)lf.triangles, lf.strips,
               (unsigned long long)lf.indices, lf.triangles ? (double)lf.indices / lf.triangles : 0,
               lf.triangles + lf.degenerate ? 100.0 * lf.degenerate / (lf.triangles + lf.degenerate) : 0);
        if (obj)
            printf("  wrote %s\n", obj);
        if (verify)
            printf("  verified invariants 1 and 2 at %u levels, and every record from the split "
                   "descriptions, in %.2f s\n",
                   vr.levels_checked, t_verify);
    }
    status = CLI_EXIT_OK;
    goto done;
fail:
    fprintf(stderr, "mts-inspect: %s\n", err.msg);
done:
    mts_lod_free(&lod);
    mts_model_free(&m);
    return status;
}
