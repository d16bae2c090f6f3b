/* mts-build: mesh file in, multiresolution strip model (.mtsm) out. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "build.h"
#include "cli.h"
#include "fileio.h"
#include "mesh.h"
#include "model.h"
#include "modelfile.h"
#include "stream.h"
#include "stream_file.h"
#include "wire.h"

static void usage(FILE *f)
{
    fputs("usage: mts-build MESH [-o MODEL.mtsm] [--stream FILE.mts [--records]]\n"
          "                 [--base-vertices N] [--tunnel-length K]\n"
          "                 [--strip-effort E] [--max-strip M] [--key-ratio R]\n"
          "                 [--reorder-window W] [--threads N] [--max-mesh-bytes N]\n"
          "                 [--no-colors] [--color-cost W] [--json] [--quiet]\n"
          "\n"
          "Builds a multiresolution triangle-strip model from a mesh (OFF, OBJ, PLY, STL, glTF/GLB):\n"
          "strips at full resolution, a quadric edge-collapse sequence down to a base mesh,\n"
          "and per-collapse strip records, written to a .mtsm model file. Vertex colours\n"
          "(PLY red green blue, OBJ v x y z r g b, COFF, glTF COLOR_0) are kept as 8-bit\n"
          "sRGB, opaque: alpha is dropped with a warning, as are the colours of a mesh\n"
          "where only some vertices have one.\n"
          "\n"
          "       mts-build MODEL.mtsm --stream FILE.mts [--records] [--no-colors]\n"
          "\n"
          "  -o, --output FILE     model file to write (default: MESH's name with .mtsm,\n"
          "                        in the current directory; with --stream, only when\n"
          "                        given)\n"
          "  --stream FILE         write the model's stream as one static file that any web\n"
          "                        server can serve (mts-client http(s)://.../FILE reads it\n"
          "                        with range requests); its name without .mts is the\n"
          "                        model's name. MESH may be a model file already built\n"
          "  --records             the stream file in the records form: about 16x the\n"
          "                        bytes, far less work for the client\n"
          "  --base-vertices N     stop simplifying at N vertices (default: max(4, 1%))\n"
          "  --tunnel-length K     after the greedy strips, complement alternating tunnels\n"
          "                        of up to K dual-graph edges (paper 004) and order the\n"
          "                        strips for the vertex cache; 0: off (default: "
          MTS_TUNNEL_DEFAULT_LENGTH_STR ", most "
          MTS_TUNNEL_MAX_LENGTH_STR ")\n"
          "  --strip-effort E      simulated-annealing moves per triangle after the\n"
          "                        tunnels: more gives fewer indices, slowly (bunny00:\n"
          "                        96 -> 1.216 idx/tri in about 1.5 s, 16384 -> 1.198 in\n"
          "                        minutes); 0: none (default: " MTS_TUNNEL_DEFAULT_ANNEAL_STR ")\n"
          "  --max-strip M         at most M triangles in a full-level strip (1 to " MTS_STRIPIFY_MAX_STRIP_STR ",\n"
          "                        the default): shorter strips suit a vertex cache and\n"
          "                        cost restarts (bunny00: 48 -> ACMR-32 0.754 at 1.227\n"
          "                        idx/tri; 256 -> 0.801 at 1.216); needs the tunnelling\n"
          "                        pass\n"
          "  --key-ratio R         strips are grown upward from the base split by split\n"
          "                        and stripified afresh once they draw " MTS_LODBUILD_KEY_QUALITY_STR " indices a\n"
          "                        triangle, or at the latest once the triangles grow by\n"
          "                        R (R > 1; default " MTS_LODBUILD_DEFAULT_KEY_RATIO_STR "); 0: only at the base\n"
          "                        and the full level\n"
          "  --reorder-window W    sort the splits by parent within windows of W splits,\n"
          "                        as far as splits that share vertices allow, so a\n"
          "                        stream codes parents in fewer bits (bunny00: 5.8 bits\n"
          "                        a split, not 13.6); 1: the decimation's order (default:\n"
          "                        a quarter of the vertices there are at its start)\n"
          "  --threads N           the full-level strips beside the simplification on a\n"
          "                        second thread; 1: one after the other (the model is\n"
          "                        the same; default: the processors online)\n"
          "  --max-mesh-bytes N    refuse a mesh file over N bytes before reading it (bytes,\n"
          "                        or with K, M, G: 512M; default 4G); only a regular file\n"
          "                        is read, never a FIFO or a device\n"
          "  --no-colors           leave the mesh's vertex colours out of the model (and a\n"
          "                        model's out of its stream file): the model is then the\n"
          "                        one an uncoloured mesh gives, byte for byte\n"
          "  --color-cost W        a coloured mesh's collapses also weigh the colour error\n"
          "                        they leave: a whole-range colour mismatch weighs as a\n"
          "                        displacement of sqrt(W) of the bounding-box diagonal;\n"
          "                        0: geometry alone (default " MTS_BUILD_DEFAULT_COLOR_COST_STR ")\n"
          "  --json                print one line of JSON with the figures (\"colors\":\n"
          "                        whether the model keeps vertex colours)\n"
          "  -q, --quiet           no progress bar, no summary\n"
          "  -h, --help            this help\n"
          "\n"
          "Exit status: 0 built, 1 the mesh or the output failed, 2 bad usage.\n",
          f);
}

/* Peak memory by stage: the bar's progress passes through here, and a
 * new stage name closes the last one's peak. With threads the two sides'
 * stages run at once and are named together ("tunnel+simplify"). */
#define MAX_STAGES 16
typedef struct stage_memory {
    cli_bar *bar;
    char current[48];
    int count;
    char name[MAX_STAGES][48];
    uint64_t peak[MAX_STAGES];
} stage_memory;

static void stage_memory_close(stage_memory *sm)
{
    if (!sm->current[0])
        return;
    uint64_t peak = cli_peak_rss_reset();
    int k = 0;
    while (k < sm->count && strcmp(sm->name[k], sm->current) != 0)
        k++;
    if (k == sm->count && sm->count < MAX_STAGES)
        snprintf(sm->name[sm->count++], sizeof sm->name[0], "%s", sm->current);
    if (k < sm->count && peak > sm->peak[k])
        sm->peak[k] = peak;
}

static void stage_memory_update(void *user, const char *stage, double done)
{
    stage_memory *sm = user;
    if (strncmp(sm->current, stage, sizeof sm->current - 1) != 0) {
        stage_memory_close(sm);
        snprintf(sm->current, sizeof sm->current, "%s", stage);
    }
    cli_bar_update(sm->bar, stage, done);
}

static int has_model_extension(const char *path)
{
    size_t n = strlen(path);
    return n > 5 && mts_ascii_ieq(path + n - 5, ".mtsm");
}

typedef struct stream_figures {
    uint64_t file_bytes;  /* the stream file */
    uint64_t index_bytes; /* of it: header, table and checks */
    uint64_t frame_bytes; /* of it: MODEL_INFO, BASE and the batches */
    uint32_t batches;
    double seconds;
} stream_figures;

/* The stream file of a model: the same encoder mts-server runs, so that its
 * frames are byte for byte what a connection to mts-server carries. The
 * model's name on the wire is the file's name without .mts. */
static mts_result write_stream_file(const mts_model *model, const char *path, int records,
                                    stream_figures *sf, mts_error *err)
{
    double t0 = cli_now();
    char name[1024];
    cli_stem(path, name, sizeof name);
    if (mts_wire_check_name(name, strlen(name), err) != MTS_OK)
        return mts_error_prefix(err, "%s: the stream file's name is the model's name", path);
    mts_stream_options so = {0};
    so.with_records = records;
    mts_stream s = {0};
    mts_buf b = {0};
    mts_result rc = mts_stream_build(model, name, &so, &s, err);
    if (rc == MTS_OK) {
        const mts_stream *form = records ? s.records_form : &s;
        rc = mts_stream_file_write(form, &b, err);
        if (rc == MTS_OK)
            rc = mts_file_write_atomic(path, b.data, b.size, err);
        if (rc == MTS_OK) {
            mts_buf info = {0};
            mts_stream_put_model_info(form, model->level_count, &info);
            sf->file_bytes = b.size;
            sf->frame_bytes = info.size + form->size;
            sf->index_bytes = b.size - sf->frame_bytes;
            sf->batches = form->batch_count;
            mts_buf_free(&info);
        }
    }
    mts_buf_free(&b);
    mts_stream_free(&s);
    sf->seconds = cli_now() - t0;
    return rc;
}

static void json_stream(cli_json *j, const char *path, const stream_figures *sf)
{
    cli_json_object_begin(j, "stream_file");
    cli_json_str(j, "path", path);
    cli_json_u64(j, "bytes", sf->file_bytes);
    cli_json_u64(j, "index_bytes", sf->index_bytes);
    cli_json_u64(j, "frame_bytes", sf->frame_bytes);
    cli_json_u64(j, "batches", sf->batches);
    cli_json_num(j, "seconds", sf->seconds, 4);
    cli_json_object_end(j);
}

static void print_stream(const char *path, const stream_figures *sf)
{
    printf("  wrote %s: %llu bytes, %u batches; header, table and checks %llu bytes "
           "(%.2f%% of the frames) in %.2f s\n",
           path, (unsigned long long)sf->file_bytes, sf->batches,
           (unsigned long long)sf->index_bytes,
           sf->frame_bytes ? 100.0 * sf->index_bytes / sf->frame_bytes : 0, sf->seconds);
}

/* mts-build MODEL.mtsm --stream FILE: the stream file of a model built before. */
static int stream_from_model(const char *input, const char *path, int records, int no_colors,
                             int json, int quiet)
{
    mts_error err = {0};
    mts_model model = {0};
    stream_figures sf = {0};
    int status = CLI_EXIT_FAIL;
    mts_result rc = mts_modelfile_load(input, &model, &err);
    if (rc == MTS_OK && no_colors) {
        free(model.colors);
        model.colors = NULL;
        model.flags &= ~MTS_MODEL_COLORS;
    }
    if (rc == MTS_OK && write_stream_file(&model, path, records, &sf, &err) == MTS_OK) {
        status = CLI_EXIT_OK;
        if (json) {
            cli_json j;
            cli_json_begin(&j, stdout);
            cli_json_str(&j, "input", input);
            cli_json_u64(&j, "vertices", model.vertex_count);
            cli_json_u64(&j, "levels", model.level_count);
            cli_json_bool(&j, "colors", model.colors != NULL);
            json_stream(&j, path, &sf);
            cli_json_end(&j);
        } else if (!quiet) {
            printf("%s: %u vertices, %u levels%s\n", input, model.vertex_count,
                   model.level_count, model.colors ? ", vertex colours" : "");
            print_stream(path, &sf);
        }
    } else {
        fprintf(stderr, "mts-build: %s\n", err.msg);
    }
    mts_model_free(&model);
    return status;
}

int main(int argc, char **argv)
{
    const char *input = NULL, *output = NULL;
    uint32_t base_vertices = 0, tunnel_length = MTS_TUNNEL_DEFAULT_LENGTH,
             strip_effort = MTS_TUNNEL_DEFAULT_ANNEAL, max_strip = 0, reorder_window = 0,
             threads = 0;
    double key_ratio = MTS_LODBUILD_DEFAULT_KEY_RATIO, color_cost = MTS_BUILD_DEFAULT_COLOR_COST;
    int json = 0, quiet = 0, records = 0;
    const char *stream_path = NULL;
    mts_mesh_options mo = {0};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return CLI_EXIT_OK;
        } else if (!strcmp(a, "-o") || !strcmp(a, "--output")) {
            if (++i >= argc) {
                fprintf(stderr, "mts-build: %s needs a file name\n", a);
                return CLI_EXIT_USAGE;
            }
            output = argv[i];
        } else if (!strcmp(a, "--base-vertices")) {
            if (!cli_option_u32(argc, argv, &i, "mts-build", 1, UINT32_MAX, &base_vertices))
                return CLI_EXIT_USAGE;
        } else if (!strcmp(a, "--tunnel-length")) {
            if (!cli_option_u32(argc, argv, &i, "mts-build", 0, MTS_TUNNEL_MAX_LENGTH,
                                &tunnel_length))
                return CLI_EXIT_USAGE;
        } else if (!strcmp(a, "--strip-effort")) {
            if (!cli_option_u32(argc, argv, &i, "mts-build", 0, MTS_TUNNEL_MAX_ANNEAL,
                                &strip_effort))
                return CLI_EXIT_USAGE;
        } else if (!strcmp(a, "--max-strip")) {
            if (!cli_option_u32(argc, argv, &i, "mts-build", 1, MTS_STRIPIFY_MAX_STRIP, &max_strip))
                return CLI_EXIT_USAGE;
        } else if (!strcmp(a, "--key-ratio")) {
            if (++i >= argc || !cli_parse_double(argv[i], &key_ratio) ||
                !(key_ratio == 0 || (key_ratio > 1 && key_ratio <= 1000))) {
                fprintf(stderr, "mts-build: --key-ratio needs 0 or a number above 1\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--color-cost")) {
            if (++i >= argc || !cli_parse_double(argv[i], &color_cost) ||
                !(color_cost >= 0 && color_cost <= 1e6)) {
                fprintf(stderr, "mts-build: --color-cost needs a number from 0 to 1e6\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--reorder-window")) {
            if (!cli_option_u32(argc, argv, &i, "mts-build", 1, UINT32_MAX, &reorder_window))
                return CLI_EXIT_USAGE;
        } else if (!strcmp(a, "--threads")) {
            if (!cli_option_u32(argc, argv, &i, "mts-build", 1, 1024, &threads))
                return CLI_EXIT_USAGE;
        } else if (!strcmp(a, "--max-mesh-bytes")) {
            if (++i >= argc || !cli_parse_bytes(argv[i], &mo.max_bytes) || mo.max_bytes == 0) {
                fprintf(stderr, "mts-build: --max-mesh-bytes needs a size in bytes above 0 "
                                "(512M, 4G)\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--stream")) {
            if (++i >= argc) {
                fprintf(stderr, "mts-build: %s needs a file name\n", a);
                return CLI_EXIT_USAGE;
            }
            stream_path = argv[i];
        } else if (!strcmp(a, "--records")) {
            records = 1;
        } else if (!strcmp(a, "--no-colors")) {
            mo.no_colors = 1;
        } else if (!strcmp(a, "--json")) {
            json = 1;
        } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
            quiet = 1;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "mts-build: unknown option %s (see --help)\n", a);
            return CLI_EXIT_USAGE;
        } else if (!input) {
            input = a;
        } else {
            fprintf(stderr, "mts-build: one mesh at a time (got %s and %s)\n", input, a);
            return CLI_EXIT_USAGE;
        }
    }
    if (!input) {
        usage(stderr);
        return CLI_EXIT_USAGE;
    }
    if (records && !stream_path) {
        fprintf(stderr, "mts-build: --records is the form of a stream file: give --stream FILE\n");
        return CLI_EXIT_USAGE;
    }
    if (has_model_extension(input)) {
        if (!stream_path) {
            fprintf(stderr, "mts-build: %s is a model already; give --stream FILE.mts to write "
                            "its stream file\n", input);
            return CLI_EXIT_USAGE;
        }
        return stream_from_model(input, stream_path, records, mo.no_colors, json, quiet);
    }
    if (max_strip && tunnel_length == 0) {
        fprintf(stderr, "mts-build: --max-strip needs the tunnelling pass (--tunnel-length 0 "
                        "turns it off)\n");
        return CLI_EXIT_USAGE;
    }
    char out_buf[4096];
    if (!output && !stream_path) {
        char stem[1024];
        cli_stem(input, stem, sizeof stem);
        snprintf(out_buf, sizeof out_buf, "%s.mtsm", stem);
        output = out_buf;
    }

    cli_bar bar;
    cli_bar_init(&bar, quiet || json);
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_mesh_stats ms = {0};
    mts_model model = {0};
    mts_build_report rep;
    uint64_t file_bytes = 0;
    int status = CLI_EXIT_FAIL;

    stage_memory sm = {0};
    sm.bar = &bar;
    uint64_t rss_start = cli_peak_rss_reset(); /* the program itself, before the mesh */
    double t0 = cli_now();
    stage_memory_update(&sm, "load", 0);
    if (mts_mesh_load(input, &mo, &mesh, &ms, &err) != MTS_OK)
        goto fail;
    /* the loader read past lines it did not know; the user should know
     * which, in case one of them mattered (on stderr, --quiet or not, so
     * that --json's stdout stays one line) */
    if (ms.skipped_header_lines)
        fprintf(stderr, "mts-build: warning: %s: skipped %u header line%s that %s no %s "
                        "keyword (line %u%s)\n",
                input, ms.skipped_header_lines, ms.skipped_header_lines == 1 ? "" : "s",
                ms.skipped_header_lines == 1 ? "is" : "are", mts_mesh_format_name(ms.format),
                ms.first_skipped_header_line, ms.skipped_header_lines == 1 ? "" : " first");
    if (ms.colors_missing)
        fprintf(stderr, "mts-build: warning: %s: %u vertices have no colour while the others "
                        "have one: the model keeps no colours\n",
                input, ms.colors_missing);
    if (ms.colors_from_file && ms.colors_translucent)
        fprintf(stderr, "mts-build: warning: %s: alpha dropped: %u vertices were not opaque, "
                        "and the model is drawn opaque\n",
                input, ms.colors_translucent);
    if (ms.colors_from_file && ms.colors_clamped)
        fprintf(stderr, "mts-build: warning: %s: %u colour values outside their range, "
                        "clamped\n",
                input, ms.colors_clamped);
    double t1 = cli_now();
    mts_build_options bo = {0};
    bo.base_vertices = base_vertices;
    bo.tunnel_length = tunnel_length == 0 ? -1 : (int)tunnel_length;
    bo.strip_effort = strip_effort == 0 ? -1 : (int)strip_effort;
    bo.max_strip = max_strip;
    bo.reorder_window = reorder_window;
    bo.threads = threads;
    bo.key_ratio = key_ratio == 0 ? -1 : key_ratio;
    bo.color_cost = color_cost == 0 ? -1 : color_cost;
    bo.progress = (mts_progress){stage_memory_update, &sm};
    if (mts_build_model(&mesh, input, &bo, &model, &rep, &err) != MTS_OK)
        goto fail;
    double t2 = cli_now();
    stage_memory_update(&sm, "write", 0);
    if (output && mts_modelfile_save(&model, output, &file_bytes, &err) != MTS_OK)
        goto fail;
    stream_figures sf = {0};
    if (stream_path) {
        stage_memory_update(&sm, "stream", 0);
        if (write_stream_file(&model, stream_path, records, &sf, &err) != MTS_OK)
            goto fail;
    }
    double t3 = cli_now();
    stage_memory_close(&sm);
    cli_bar_done(&bar);

    uint32_t n = model.level_count;
    double ipt_full = (double)(model.level_indices[n] + model.level_strips[n] - 1) /
                      model.level_triangles[n];
    /* the worst level a client may draw, restarts counted */
    double ipt_worst = 0;
    uint32_t worst_level = 0;
    for (uint32_t l = 0; l <= n; l++) {
        double ipt = model.level_triangles[l]
                         ? (double)(model.level_indices[l] + model.level_strips[l] - 1) /
                               model.level_triangles[l]
                         : 0;
        if (ipt > ipt_worst) {
            ipt_worst = ipt;
            worst_level = l;
        }
    }
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_str(&j, "input", input);
        if (output)
            cli_json_str(&j, "output", output);
        if (stream_path)
            json_stream(&j, stream_path, &sf);
        cli_json_str(&j, "format", mts_mesh_format_name(ms.format));
        cli_json_bool(&j, "colors", model.colors != NULL);
        cli_json_u64(&j, "vertices", model.vertex_count);
        cli_json_u64(&j, "triangles", model.level_triangles[n]);
        cli_json_u64(&j, "levels", n);
        cli_json_u64(&j, "base_vertices", model.base_vertex_count);
        cli_json_u64(&j, "base_triangles", model.level_triangles[0]);
        cli_json_u64(&j, "strips_full", model.level_strips[n]);
        cli_json_u64(&j, "indices_full", model.level_indices[n]);
        cli_json_num(&j, "indices_per_triangle_full", ipt_full, 4);
        cli_json_u64(&j, "swaps", rep.tunnel.swaps_after);
        cli_json_u64(&j, "tunnel_length", (uint64_t)rep.tunnel_length);
        cli_json_u64(&j, "strip_effort", rep.tunnel.anneal);
        cli_json_u64(&j, "max_strip", max_strip ? max_strip : MTS_STRIPIFY_MAX_STRIP);
        cli_json_u64(&j, "key_levels", rep.records.key_levels);
        cli_json_u64(&j, "explicit_splits", rep.records.explicit_splits);
        cli_json_u64(&j, "reorder_window", rep.reorder.window);
        cli_json_u64(&j, "reorder_runs", rep.reorder.runs);
        cli_json_u64(&j, "threads", rep.threads);
        cli_json_num(&j, "indices_per_triangle_worst", ipt_worst, 4);
        cli_json_u64(&j, "worst_level", worst_level);
        cli_json_object_begin(&j, "greedy");
        cli_json_u64(&j, "strips", rep.tunnel.strips_before);
        cli_json_u64(&j, "swaps", rep.tunnel.swaps_before);
        cli_json_u64(&j, "restarts", rep.tunnel.strips_before ? rep.tunnel.strips_before - 1 : 0);
        cli_json_num(&j, "indices_per_triangle",
                     (double)rep.tunnel.draw_indices_before / model.level_triangles[n], 4);
        cli_json_object_end(&j);
        cli_json_u64(&j, "restarts_full", model.level_strips[n] ? model.level_strips[n] - 1 : 0);
        cli_json_u64(&j, "file_bytes", file_bytes);
        cli_json_object_begin(&j, "dropped");
        cli_json_u64(&j, "degenerate_faces", ms.degenerate_faces);
        cli_json_u64(&j, "duplicate_faces", ms.duplicate_faces);
        cli_json_u64(&j, "nonmanifold_faces", ms.nonmanifold_faces);
        cli_json_u64(&j, "unreferenced_vertices", ms.unreferenced_vertices);
        cli_json_u64(&j, "header_lines", ms.skipped_header_lines);
        /* the colours of a mesh some of whose vertices have none: how many lack one */
        cli_json_u64(&j, "colors_missing", ms.colors_missing);
        cli_json_bool(&j, "alpha", ms.colors_from_file && ms.colors_alpha);
        cli_json_u64(&j, "alpha_translucent", ms.colors_from_file ? ms.colors_translucent : 0);
        cli_json_u64(&j, "colors_clamped", ms.colors_from_file ? ms.colors_clamped : 0);
        cli_json_object_end(&j);
        cli_json_object_begin(&j, "seconds");
        cli_json_num(&j, "load", t1 - t0, 4);
        cli_json_num(&j, "stripify", rep.seconds_stripify, 4);
        cli_json_num(&j, "tunnel", rep.seconds_tunnel, 4);
        cli_json_num(&j, "simplify", rep.seconds_simplify, 4);
        cli_json_num(&j, "reorder", rep.seconds_reorder, 4);
        cli_json_num(&j, "records", rep.seconds_records, 4);
        cli_json_num(&j, "write", t3 - t2, 4);
        cli_json_num(&j, "total", t3 - t0, 4);
        cli_json_object_end(&j);
        uint64_t peak = 0;
        cli_json_object_begin(&j, "peak_mb"); /* resident, by stage */
        for (int k = 0; k < sm.count; k++) {
            cli_json_num(&j, sm.name[k], sm.peak[k] / 1048576.0, 1);
            peak = sm.peak[k] > peak ? sm.peak[k] : peak;
        }
        cli_json_object_end(&j);
        /* the mesh's share: the peak less what the program held before it */
        cli_json_num(&j, "peak_bytes_per_triangle",
                     model.level_triangles[n] && peak > rss_start
                         ? (double)(peak - rss_start) / model.level_triangles[n]
                         : 0,
                     1);
        cli_json_end(&j);
    } else if (!quiet) {
        printf("%s: %u vertices, %u triangles (%s)\n", input, model.vertex_count,
               model.level_triangles[n], mts_mesh_format_name(ms.format));
        if (ms.degenerate_faces || ms.duplicate_faces || ms.nonmanifold_faces ||
            ms.unreferenced_vertices || ms.polygons_triangulated)
            printf("  cleaned: %u polygons triangulated, dropped %u degenerate, %u duplicate, "
                   "%u non-manifold faces, %u unreferenced vertices\n",
                   ms.polygons_triangulated, ms.degenerate_faces, ms.duplicate_faces,
                   ms.nonmanifold_faces, ms.unreferenced_vertices);
        if (model.colors)
            printf("  colours: one per vertex, 8-bit sRGB%s\n",
                   ms.colors_alpha ? ", alpha dropped" : "");
        else if (ms.colors_missing)
            printf("  colours: none kept (%u vertices had none)\n", ms.colors_missing);
        printf("  strips: %u at full resolution, %u indices, %.3f indices/triangle with "
               "restarts (%u swaps)\n",
               model.level_strips[n], model.level_indices[n], ipt_full, (unsigned)rep.tunnel.swaps_after);
        if (rep.tunnel_length > 0)
            printf("  tunnelling (length %d): %u strips, %llu swaps, %.3f indices/triangle "
                   "before; %u changes kept\n",
                   rep.tunnel_length, rep.tunnel.strips_before,
                   (unsigned long long)rep.tunnel.swaps_before,
                   (double)rep.tunnel.draw_indices_before / model.level_triangles[n],
                   rep.tunnel.changes);
        printf("  levels: %u splits from a base of %u vertices / %u triangles; %u key levels; "
               "worst %.3f indices/triangle (level %u); %llu splits described explicitly\n",
               n, model.base_vertex_count, model.level_triangles[0], rep.records.key_levels,
               ipt_worst, worst_level, (unsigned long long)rep.records.explicit_splits);
        if (stream_path)
            print_stream(stream_path, &sf);
        printf("  %s%s: %llu bytes in %.2f s (load %.2f, stripify %.2f, tunnel %.2f, "
               "simplify %.2f%s, records %.2f, write %.2f)\n",
               output ? "wrote " : "built", output ? output : "",
               (unsigned long long)file_bytes, t3 - t0, t1 - t0, rep.seconds_stripify,
               rep.seconds_tunnel, rep.seconds_simplify,
               rep.threads > 1 ? " beside them" : "", rep.seconds_records, t3 - t2);
    }
    status = CLI_EXIT_OK;
    goto done;
fail:
    cli_bar_done(&bar);
    fprintf(stderr, "mts-build: %s\n", err.msg);
done:
    mts_model_free(&model);
    mts_mesh_free(&mesh);
    return status;
}
