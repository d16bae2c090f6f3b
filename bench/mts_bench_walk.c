/* mts-bench-walk: the walkthrough of papers 000 (section 5, Table 2 and
 * Fig. 6) and 002 (section 4.3, Fig. 5), and a rate-distortion series, for
 * each mesh given.
 *
 * Walkthrough: the model moves away from the viewer for --seconds of
 * simulated frames at --hz (frame f shows time f / hz; frames are drawn as
 * fast as they go, the clock is simulated), headless through EGL. The camera
 * distance, in multiples of the framing distance, follows
 *     linear       D(t) = 1 + (far - 1) t / T
 *     exponential  D(t) = far^(t / T)
 * from 1 (the model fills the view) to far, and the distance policy
 * (client/lodpolicy.c: triangles = full (1/D)^2) chooses the level every frame.
 * Three modes draw the same levels:
 *     strips         the runtime moves from the previous frame's level
 *                    (coherence: only the records between them, only the
 *                    changed strips re-uploaded)
 *     strips_nocoh   the runtime goes back to the base and up to the level
 *                    every frame (mts_lod_set_level(0), then the level): no
 *                    use of the previous frame, as paper 000's "without
 *                    coherence"; the strips it touched are re-uploaded
 *     list           the coherent runtime, then an indexed triangle list of
 *                    the level's non-degenerate triangles built from the
 *                    strips and uploaded whole (what a triangle-list LOD such
 *                    as PM does every frame); extraction includes building it
 * Per frame: level, triangles, extraction ms, upload ms, draw ms (clear ..
 * glFinish). Before each run the runtime and buffers are put at the first
 * frame's level untimed (the model was loaded there).
 *
 * Rate-distortion: at about --rd-points batch boundaries along the stream,
 * the bytes a client has received (MODEL_INFO + BASE + the batches so far:
 * the stream's batch offsets), the triangles available and the geometric
 * error of that level against the full input mesh: the RMS of the distances
 * from the full mesh's vertices to the level's surface and from the level's
 * triangle centroids to the full mesh's surface, over both sample sets
 * together (symmetric), divided by the input's bounding-box diagonal; the
 * one-sided parts and the largest distance are kept too. Nearest triangles
 * come from a uniform grid. Draco single-rate's point: the full mesh on the
 * stream's grid (edgebreaker, -cl 7, positions only, as mts-bench-stream
 * reports it); its error is the quantization's alone, which is that of the
 * stream's full level (same grid, same rounding: protocol/draco.h). */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "drawmodes.h"
#include "build.h"
#include "cli.h"
#include "clock.h"
#include "draco.h"
#include "lodpolicy.h"
#include "mesh.h"
#include "render.h"
#include "stream.h"

#include "../tests/color_field.h"

/* ---- walkthrough ------------------------------------------------------- */

enum { MODE_STRIPS, MODE_NOCOH, MODE_LIST, MODE_COUNT };
static const char *const mode_names[MODE_COUNT] = {"strips", "strips_nocoh", "list"};
static const char *const schedule_names[2] = {"linear", "exponential"};

typedef struct walk_cfg {
    double seconds, hz, far;
    uint32_t width, height;
} walk_cfg;

typedef struct series {
    uint32_t frames;
    uint32_t *level, *triangles;
    float *extract_ms, *upload_ms, *draw_ms;
} series;

static double schedule_distance(int exponential, double t, const walk_cfg *c)
{
    double u = t / c->seconds;
    return exponential ? pow(c->far, u) : 1 + (c->far - 1) * u;
}

/* The level's non-degenerate triangles, strip order, 3 indices each. */
static size_t strips_to_list(const mts_lod *lod, uint32_t *list)
{
    size_t n = 0;
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(lod, s, &len);
        for (uint32_t k = 0; k + 2 < len; k++)
            n += 3 * (size_t)mts_strip_window(str, k, list + n);
    }
    return n;
}

static int walk_run(mts_render_context *ctx, const mts_model *m, const walk_cfg *c,
                    int exponential, int mode, uint32_t *list, series *out, mts_error *err)
{
    mts_lod lod;
    mts_renderer *r = NULL;
    mts_drawmodes dm = {0};
    int ok = 0;
    if (mts_lod_init(&lod, m, MTS_LOD_AT_BASE, err) != MTS_OK)
        return 0;
    mts_render_options ro;
    mts_render_options_default(&ro);
    ro.timed = 1; /* the draw timings read last_draw_seconds */
    ro.width = c->width;
    ro.height = c->height;
    mts_render_layout layout;
    mts_render_layout_from_lod(&lod, &layout);
    if (mts_renderer_create(ctx, &ro, &layout, &r, err) != MTS_OK ||
        mts_render_append_vertices(r, 0, m->vertex_count, m->positions, m->normals,
                                   m->colors, err) !=
            MTS_OK)
        goto done;
    mts_lod_policy_options po = {0};
    po.kind = MTS_LOD_POLICY_DISTANCE;
    mts_lod_policy pol;
    mts_lod_policy_init(&pol, &po, m);
    mts_lod_view view = {1, ro.camera.fov_y_deg * 3.14159265f / 180.0f, (int)c->width,
                         (int)c->height};
    double d_frame = mts_lod_policy_frame_distance(&pol, &view);
    for (int f = -1; f < (int)out->frames; f++) {
        /* f = -1: untimed, at frame 0's level */
        double D = schedule_distance(exponential, f < 0 ? 0 : f / c->hz, c);
        mts_render_camera cam = ro.camera;
        cam.zoom = (float)(1 / D);
        mts_render_set_camera(r, &cam);
        view.distance = (float)(D * d_frame);
        uint32_t level = mts_lod_policy_choose(&pol, m->level_count, &view, 0);
        double t0 = (1e3 * mts_clock_seconds());
        if (mode == MODE_NOCOH && mts_lod_set_level(&lod, 0, err) != MTS_OK)
            goto done;
        if (mts_lod_set_level(&lod, level, err) != MTS_OK)
            goto done;
        size_t n = mode == MODE_LIST ? strips_to_list(&lod, list) : 0;
        double t1 = (1e3 * mts_clock_seconds());
        if (mode == MODE_LIST) {
            if (mts_drawmodes_set_list(&dm, r, list, (uint32_t)n, err) != MTS_OK)
                goto done;
        } else if (mts_render_update_strips(r, &lod, err) != MTS_OK) {
            goto done;
        }
        mts_lod_clear_changed(&lod);
        double t2 = (1e3 * mts_clock_seconds());
        if (mts_drawmodes_draw(&dm, r, mode == MODE_LIST ? MTS_DRAWMODE_LIST : MTS_DRAWMODE_JOINED,
                               err) != MTS_OK)
            goto done;
        mts_render_stats st;
        mts_render_get_stats(r, &st);
        if (f >= 0) {
            out->level[f] = level;
            out->triangles[f] = m->level_triangles[level];
            out->extract_ms[f] = (float)(t1 - t0);
            out->upload_ms[f] = (float)(t2 - t1);
            out->draw_ms[f] = (float)(st.last_draw_seconds * 1e3);
        }
    }
    ok = 1;
done:
    if (r && mts_render_context_make_current(ctx, NULL) == MTS_OK)
        mts_drawmodes_free(&dm);
    mts_renderer_destroy(r);
    mts_lod_free(&lod);
    return ok;
}

typedef struct summary {
    double mean_fps, mean_frame_ms, mean_extract_ms, max_extract_ms, mean_upload_ms,
        mean_draw_ms, mean_triangles;
} summary;

static summary summarize(const series *s)
{
    summary u = {0};
    double total = 0;
    for (uint32_t f = 0; f < s->frames; f++) {
        double ms = (double)s->extract_ms[f] + s->upload_ms[f] + s->draw_ms[f];
        total += ms;
        u.mean_extract_ms += s->extract_ms[f];
        if (s->extract_ms[f] > u.max_extract_ms)
            u.max_extract_ms = s->extract_ms[f];
        u.mean_upload_ms += s->upload_ms[f];
        u.mean_draw_ms += s->draw_ms[f];
        u.mean_triangles += s->triangles[f];
    }
    double n = s->frames ? s->frames : 1;
    u.mean_frame_ms = total / n;
    u.mean_fps = total > 0 ? 1e3 * s->frames / total : 0; /* frames over their total time */
    u.mean_extract_ms /= n;
    u.mean_upload_ms /= n;
    u.mean_draw_ms /= n;
    u.mean_triangles /= n;
    return u;
}

static void json_series_u32(FILE *f, const char *key, const uint32_t *v, uint32_t n)
{
    fprintf(f, "\"%s\":[", key);
    for (uint32_t i = 0; i < n; i++)
        fprintf(f, "%s%u", i ? "," : "", v[i]);
    fputs("]", f);
}

static void json_series_f(FILE *f, const char *key, const float *v, uint32_t n)
{
    fprintf(f, "\"%s\":[", key);
    for (uint32_t i = 0; i < n; i++)
        fprintf(f, "%s%.4f", i ? "," : "", v[i]);
    fputs("]", f);
}

/* ---- rate-distortion ---------------------------------------------------- */

/* Closest point on triangle abc to p (Ericson, Real-Time Collision
 * Detection, 5.1.5), into qout when not NULL; returns the squared
 * distance. */
static double point_tri_d2(const double p[3], const float *a, const float *b, const float *c,
                           double *qout)
{
    double ab[3], ac[3], ap[3], q[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = (double)b[i] - a[i];
        ac[i] = (double)c[i] - a[i];
        ap[i] = p[i] - a[i];
    }
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        for (int i = 0; i < 3; i++)
            q[i] = a[i];
        goto out;
    }
    double bp[3];
    for (int i = 0; i < 3; i++)
        bp[i] = p[i] - b[i];
    double d3 = DOT(ab, bp), d4 = DOT(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        for (int i = 0; i < 3; i++)
            q[i] = b[i];
        goto out;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double v = d1 / (d1 - d3);
        for (int i = 0; i < 3; i++)
            q[i] = a[i] + v * ab[i];
        goto out;
    }
    double cp[3];
    for (int i = 0; i < 3; i++)
        cp[i] = p[i] - c[i];
    double d5 = DOT(ab, cp), d6 = DOT(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        for (int i = 0; i < 3; i++)
            q[i] = c[i];
        goto out;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double w = d2 / (d2 - d6);
        for (int i = 0; i < 3; i++)
            q[i] = a[i] + w * ac[i];
        goto out;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int i = 0; i < 3; i++)
            q[i] = b[i] + w * ((double)c[i] - b[i]);
        goto out;
    }
    {
        double den = 1 / (va + vb + vc);
        double v = vb * den, w = vc * den;
        for (int i = 0; i < 3; i++)
            q[i] = a[i] + ab[i] * v + ac[i] * w;
    }
out:;
    if (qout)
        memcpy(qout, q, sizeof q);
    double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
    return DOT(d, d);
#undef DOT
}

/* Triangles binned by their boxes into a uniform grid over a given box. */
typedef struct tri_grid {
    const float *pos;
    const uint32_t *tri;
    uint32_t ntri;
    double lo[3], h; /* cell size */
    int dim[3];
    uint32_t *start, *items; /* CSR: cell -> triangles */
    uint32_t *stamp, query;
} tri_grid;

static int cell_of(const tri_grid *g, double x, int axis)
{
    int c = (int)floor((x - g->lo[axis]) / g->h);
    return c < 0 ? 0 : c >= g->dim[axis] ? g->dim[axis] - 1 : c;
}

static int grid_build(tri_grid *g, const float *pos, const uint32_t *tri, uint32_t ntri,
                      const double lo[3], const double hi[3])
{
    memset(g, 0, sizeof *g);
    g->pos = pos;
    g->tri = tri;
    g->ntri = ntri;
    double ext[3], vol = 1;
    for (int i = 0; i < 3; i++) {
        ext[i] = hi[i] - lo[i];
        if (!(ext[i] > 1e-9))
            ext[i] = 1e-9;
        g->lo[i] = lo[i];
        vol *= ext[i];
    }
    /* about one triangle per cell */
    g->h = cbrt(vol / (ntri ? ntri : 1));
    double maxe = fmax(ext[0], fmax(ext[1], ext[2]));
    if (g->h < maxe / 256)
        g->h = maxe / 256;
    for (int i = 0; i < 3; i++)
        g->dim[i] = (int)(ext[i] / g->h) + 1;
    size_t cells = (size_t)g->dim[0] * g->dim[1] * g->dim[2];
    g->start = calloc(cells + 1, sizeof(uint32_t));
    g->stamp = calloc(ntri ? ntri : 1, sizeof(uint32_t));
    if (!g->start || !g->stamp)
        return 0;
    for (int pass = 0; pass < 2; pass++) {
        for (uint32_t t = 0; t < ntri; t++) {
            int c0[3], c1[3];
            for (int i = 0; i < 3; i++) {
                float a = pos[3 * tri[3 * t] + i], b = pos[3 * tri[3 * t + 1] + i],
                      c = pos[3 * tri[3 * t + 2] + i];
                c0[i] = cell_of(g, fmin(a, fmin(b, c)), i);
                c1[i] = cell_of(g, fmax(a, fmax(b, c)), i);
            }
            for (int z = c0[2]; z <= c1[2]; z++)
                for (int y = c0[1]; y <= c1[1]; y++)
                    for (int x = c0[0]; x <= c1[0]; x++) {
                        size_t cell = ((size_t)z * g->dim[1] + y) * g->dim[0] + x;
                        if (pass == 0)
                            g->start[cell + 1]++;
                        else
                            g->items[g->start[cell]++] = t;
                    }
        }
        if (pass == 0) {
            for (size_t k = 0; k < cells; k++)
                g->start[k + 1] += g->start[k];
            g->items = malloc(((size_t)g->start[cells] + 1) * sizeof(uint32_t));
            if (!g->items)
                return 0;
        } else {
            for (size_t k = cells; k > 0; k--) /* start[] was advanced to the ends */
                g->start[k] = g->start[k - 1];
            g->start[0] = 0;
        }
    }
    return 1;
}

static void grid_free(tri_grid *g)
{
    free(g->start);
    free(g->items);
    free(g->stamp);
}

/* Squared distance from p to the nearest triangle: cells in growing shells
 * around p's cell until the best distance is inside the shell searched.
 * With tout, the triangle and (qout) the closest point on it. */
static double grid_nearest_d2(tri_grid *g, const double p[3], uint32_t *tout, double qout[3])
{
    if (!g->ntri)
        return 0;
    double q[3];
    int c[3];
    for (int i = 0; i < 3; i++)
        c[i] = cell_of(g, p[i], i);
    double best = DBL_MAX;
    int maxr = g->dim[0] + g->dim[1] + g->dim[2];
    g->query++;
    for (int r = 0; r <= maxr; r++) {
        for (int z = c[2] - r; z <= c[2] + r; z++) {
            if (z < 0 || z >= g->dim[2])
                continue;
            for (int y = c[1] - r; y <= c[1] + r; y++) {
                if (y < 0 || y >= g->dim[1])
                    continue;
                int edge = z == c[2] - r || z == c[2] + r || y == c[1] - r || y == c[1] + r;
                /* inside the shell's faces only its two x ends are new */
                int step = edge || r == 0 ? 1 : 2 * r;
                for (int x = c[0] - r; x <= c[0] + r; x += step) {
                    if (x < 0 || x >= g->dim[0])
                        continue;
                    size_t cell = ((size_t)z * g->dim[1] + y) * g->dim[0] + x;
                    for (uint32_t k = g->start[cell]; k < g->start[cell + 1]; k++) {
                        uint32_t t = g->items[k];
                        if (g->stamp[t] == g->query)
                            continue;
                        g->stamp[t] = g->query;
                        const uint32_t *v = g->tri + 3 * (size_t)t;
                        double d2 = point_tri_d2(p, g->pos + 3 * (size_t)v[0],
                                                 g->pos + 3 * (size_t)v[1],
                                                 g->pos + 3 * (size_t)v[2], tout ? q : NULL);
                        if (d2 < best) {
                            best = d2;
                            if (tout) {
                                *tout = t;
                                memcpy(qout, q, sizeof q);
                            }
                        }
                    }
                }
            }
        }
        /* every cell of shell r+1 is at least r * h away from p (a point
         * outside the grid, clamped to a border cell, only farther) */
        double reach = r * g->h;
        if (best < DBL_MAX && best <= reach * reach)
            break;
    }
    return best;
}

typedef struct rd_error {
    double rms, rms_full_to_level, rms_level_to_full, max;
    /* with colours: sRGB 0..255 units, RMS over the three channels */
    double color_rms, color_rms_full_to_level, color_rms_level_to_full;
} rd_error;

/* The colour at q on triangle t of (pos, tri, col): the corners' colours
 * weighted by q's barycentric coordinates, as a rasterizer interpolates
 * them (on the stored sRGB values, as the renderer shades them). */
static void color_at(const float *pos, const uint32_t *tri, const uint8_t *col, uint32_t t,
                     const double q[3], double out[3])
{
    const uint32_t *v = tri + 3 * (size_t)t;
    const float *a = pos + 3 * (size_t)v[0], *b = pos + 3 * (size_t)v[1],
                *c = pos + 3 * (size_t)v[2];
    double e0[3], e1[3], e2[3];
    for (int i = 0; i < 3; i++) {
        e0[i] = (double)b[i] - a[i];
        e1[i] = (double)c[i] - a[i];
        e2[i] = q[i] - a[i];
    }
#define DOT(u, w) ((u)[0] * (w)[0] + (u)[1] * (w)[1] + (u)[2] * (w)[2])
    double d00 = DOT(e0, e0), d01 = DOT(e0, e1), d11 = DOT(e1, e1), d20 = DOT(e2, e0),
           d21 = DOT(e2, e1), den = d00 * d11 - d01 * d01;
#undef DOT
    double wb = 1.0 / 3, wc = 1.0 / 3;
    if (fabs(den) > 1e-30) {
        wb = (d11 * d20 - d01 * d21) / den;
        wc = (d00 * d21 - d01 * d20) / den;
    }
    double wa = 1 - wb - wc;
    for (int i = 0; i < 3; i++)
        out[i] = wa * col[3 * (size_t)v[0] + i] + wb * col[3 * (size_t)v[1] + i] +
                 wc * col[3 * (size_t)v[2] + i];
}

/* Symmetric sampled error of (lpos, ltri) against (fpos, ftri), whose grid
 * is fgrid; both in model units. With fcol and lcol (the two meshes' vertex
 * colours), the colour error at the same samples: a full-mesh vertex's
 * colour against the level's colour interpolated at the closest point of
 * the level's surface, and a level triangle's centroid colour against the
 * full mesh's interpolated at the closest point of the full surface. */
static int rd_measure(const float *fpos, const uint8_t *fcol, uint32_t fverts, tri_grid *fgrid,
                      const float *lpos, const uint8_t *lcol, const uint32_t *ltri,
                      uint32_t lntri, const double lo[3], const double hi[3], rd_error *e)
{
    tri_grid lg;
    if (!grid_build(&lg, lpos, ltri, lntri, lo, hi)) {
        grid_free(&lg);
        return 0;
    }
    const int colors = fcol && lcol;
    double sa = 0, sb = 0, mx = 0, ca = 0, cb = 0;
    for (uint32_t v = 0; v < fverts; v++) {
        double p[3] = {fpos[3 * v], fpos[3 * v + 1], fpos[3 * v + 2]}, q[3], c[3];
        uint32_t t = 0;
        double d2 = grid_nearest_d2(&lg, p, colors ? &t : NULL, q);
        sa += d2;
        mx = fmax(mx, d2);
        if (colors && lntri) {
            color_at(lpos, ltri, lcol, t, q, c);
            for (int i = 0; i < 3; i++)
                ca += (c[i] - fcol[3 * (size_t)v + i]) * (c[i] - fcol[3 * (size_t)v + i]);
        }
    }
    for (uint32_t t = 0; t < lntri; t++) {
        double p[3] = {0, 0, 0}, own[3] = {0, 0, 0}, q[3], c[3];
        for (int k = 0; k < 3; k++)
            for (int i = 0; i < 3; i++) {
                p[i] += lpos[3 * (size_t)ltri[3 * t + k] + i] / 3.0;
                if (colors)
                    own[i] += lcol[3 * (size_t)ltri[3 * t + k] + i] / 3.0;
            }
        uint32_t ft = 0;
        double d2 = grid_nearest_d2(fgrid, p, colors ? &ft : NULL, q);
        sb += d2;
        mx = fmax(mx, d2);
        if (colors && fgrid->ntri) {
            color_at(fgrid->pos, fgrid->tri, fcol, ft, q, c);
            for (int i = 0; i < 3; i++)
                cb += (c[i] - own[i]) * (c[i] - own[i]);
        }
    }
    grid_free(&lg);
    e->rms_full_to_level = sqrt(sa / (fverts ? fverts : 1));
    e->rms_level_to_full = sqrt(sb / (lntri ? lntri : 1));
    double samples = (double)fverts + lntri;
    e->rms = sqrt((sa + sb) / (samples > 0 ? samples : 1));
    e->max = sqrt(mx);
    e->color_rms_full_to_level = sqrt(ca / (3.0 * (fverts ? fverts : 1)));
    e->color_rms_level_to_full = sqrt(cb / (3.0 * (lntri ? lntri : 1)));
    e->color_rms = sqrt((ca + cb) / (3 * (samples > 0 ? samples : 1)));
    return 1;
}

static int rd_model(FILE *jf, const char *name, const mts_mesh *mesh, const mts_model *m,
                    uint32_t points, mts_error *err)
{
    /* colour error where both the input and the stream have colours */
    const uint8_t *fcol = (m->flags & MTS_MODEL_COLORS) && m->colors ? mesh->colors : NULL;
    mts_stream s;
    if (mts_stream_build(m, name, NULL, &s, err) != MTS_OK)
        return 0;
    int ok = 0;
    uint32_t *ltri = NULL;
    tri_grid fg = {0};
    mts_lod lod;
    int have_lod = 0;
    double lo[3], hi[3], diag = 0;
    for (int i = 0; i < 3; i++) {
        lo[i] = DBL_MAX;
        hi[i] = -DBL_MAX;
    }
    for (uint32_t v = 0; v < mesh->vertex_count; v++)
        for (int i = 0; i < 3; i++) {
            lo[i] = fmin(lo[i], mesh->positions[3 * v + i]);
            hi[i] = fmax(hi[i], mesh->positions[3 * v + i]);
        }
    for (int i = 0; i < 3; i++) {
        diag += (hi[i] - lo[i]) * (hi[i] - lo[i]);
        /* room for the grid's rounding and the coarse levels' bulges */
        double pad = 0.02 * (hi[i] - lo[i]) + 1e-6;
        lo[i] -= pad;
        hi[i] += pad;
    }
    diag = sqrt(diag);
    /* Draco single-rate of the full mesh on the stream's grid */
    size_t draco = 0, draco_n = 0, draco_c = 0;
    for (int k = 0; k < 3; k++) {
        if (k == 2 && !fcol)
            break;
        mts_draco_mesh dm = {mesh->vertex_count, mesh->triangle_count, mesh->positions,
                             k == 1 ? mesh->normals : NULL, mesh->triangles,
                             k == 2 ? fcol : NULL, NULL};
        mts_draco_options o = {0};
        o.grid = s.grid;
        o.normal_bits = k == 1 ? 10 : -1;
        o.compression_level = 7;
        uint8_t *out = NULL;
        size_t sz = 0;
        if (mts_draco_encode(&dm, &o, &out, &sz, err) != MTS_OK)
            sz = 0;
        free(out);
        *(k == 2 ? &draco_c : k ? &draco_n : &draco) = sz;
    }
    ltri = malloc(((size_t)m->level_triangles[m->level_count] + 1) * 12);
    if (!ltri || !grid_build(&fg, mesh->positions, mesh->triangles, mesh->triangle_count, lo, hi))
        goto done;
    if (mts_lod_init(&lod, &s.model, MTS_LOD_AT_BASE, err) != MTS_OK)
        goto done;
    have_lod = 1;
    mts_buf info = {0};
    fprintf(jf, "\"%s\":{\"diagonal\":%.6g,\"full_triangles\":%u,\"levels\":%u,"
                "\"batches\":%u,\"metric\":\"symmetric RMS: full-mesh vertices to the level's "
                "surface and level triangle centroids to the full surface, / bbox diagonal\",%s"
                "\"points\":[",
            name, diag, m->level_triangles[m->level_count], m->level_count, s.batch_count,
            fcol ? "\"color_metric\":\"symmetric RMS in sRGB 0..255 units over the three "
                   "channels, same samples: a full-mesh vertex's colour against the level's "
                   "interpolated at the closest point of its surface, a level centroid's "
                   "colour against the full mesh's at the closest point\"," : "");
    uint32_t nb = s.batch_count, np = points < nb + 1 ? points : nb + 1;
    uint32_t prev = UINT32_MAX;
    rd_error full_err = {0};
    for (uint32_t i = 0; i < np; i++) {
        /* batches received: 0 (the base alone) .. nb, spread evenly */
        uint32_t k = np > 1 ? (uint32_t)((uint64_t)i * nb / (np - 1)) : nb;
        if (k == prev)
            continue;
        prev = k;
        uint32_t level = s.batch_first[k];
        info.size = 0;
        mts_stream_put_model_info(&s, level, &info);
        size_t bytes = info.size + s.batch_offset[k];
        if (mts_lod_set_level(&lod, level, err) != MTS_OK) {
            mts_buf_free(&info);
            goto done;
        }
        size_t n = strips_to_list(&lod, ltri);
        rd_error e;
        if (!rd_measure(mesh->positions, fcol, mesh->vertex_count, &fg, s.model.positions,
                        fcol ? s.model.colors : NULL, ltri, (uint32_t)(n / 3), lo, hi, &e)) {
            mts_buf_free(&info);
            goto done;
        }
        if (level == m->level_count)
            full_err = e;
        fprintf(jf, "%s{\"batches\":%u,\"level\":%u,\"bytes\":%zu,\"triangles\":%u,"
                    "\"rms\":%.6g,\"rms_full_to_level\":%.6g,\"rms_level_to_full\":%.6g,"
                    "\"max\":%.6g",
                i ? "," : "", k, level, bytes, m->level_triangles[level], e.rms / diag,
                e.rms_full_to_level / diag, e.rms_level_to_full / diag, e.max / diag);
        if (fcol)
            fprintf(jf, ",\"color_rms\":%.6g,\"color_rms_full_to_level\":%.6g,"
                        "\"color_rms_level_to_full\":%.6g",
                    e.color_rms, e.color_rms_full_to_level, e.color_rms_level_to_full);
        fputc('}', jf);
        printf("  %-12s %4u/%u batches  level %7u  %9zu B  %8u triangles  rms %.3e  max %.3e",
               name, k, nb, level, bytes, m->level_triangles[level], e.rms / diag,
               e.max / diag);
        if (fcol)
            printf("  colour rms %6.2f", e.color_rms);
        putchar('\n');
    }
    mts_buf_free(&info);
    if (fcol)
        fprintf(jf, "],\"draco_with_colors\":{\"bytes\":%zu,\"color_rms\":0,\"how\":\"edgebreaker "
                    "-cl 7, positions on the stream's grid and byte colours (lossless)\"}",
                draco_c);
    fprintf(jf, "%s\"draco\":{\"bytes\":%zu,\"bytes_with_normals\":%zu,\"triangles\":%u,"
                "\"rms\":%.6g,\"max\":%.6g,\"how\":\"edgebreaker -cl 7 on the stream's %d-bit "
                "grid; error = quantization only (the stream's full level)\"}}",
            fcol ? "," : "],", draco, draco_n, m->level_triangles[m->level_count], full_err.rms / diag,
            full_err.max / diag, s.grid.bits);
    printf("  %-12s Draco single-rate (cl 7, positions): %zu B, %u triangles, rms %.3e\n", name,
           draco, m->level_triangles[m->level_count], full_err.rms / diag);
    if (fcol)
        printf("  %-12s Draco single-rate (cl 7, positions and colours): %zu B\n", name, draco_c);
    ok = 1;
done:
    if (have_lod)
        mts_lod_free(&lod);
    grid_free(&fg);
    free(ltri);
    mts_stream_free(&s);
    return ok;
}

/* ---- main ---------------------------------------------------------------- */

static void usage(FILE *f)
{
    fputs("usage: mts-bench-walk MESH... [--json FILE] [--rd-json FILE] [--seconds S] [--hz H]\n"
          "                      [--far D] [--size WxH] [--rd-points N] [--no-walk] [--no-rd]\n"
          "                      [--colors [--color-field smooth|patches|curvature] [--color-cost W]]\n"
          "Walkthrough (model moving away, linear and exponential) through EGL with the\n"
          "distance LOD policy: strips with and without coherence and a triangle list; and\n"
          "the rate-distortion series of each stream beside Draco single-rate.\n"
          "--colors: the series with a colour error beside the geometric one; a mesh\n"
          "without its own colours gets a field (tests/color_field.h, default smooth)\n"
          "before it is built; --color-cost W builds with that colour weight in the\n"
          "collapse cost (mts_build_options.color_cost; 0: none).\n",
          f);
}

int main(int argc, char **argv)
{
    const char *json_path = NULL, *rd_path = NULL;
    const char *paths[16];
    int np = 0, do_walk = 1, do_rd = 1, colors = 0, field = MTS_TEST_FIELD_SMOOTH;
    mts_build_options bo = {0};
    walk_cfg cfg = {20, 60, 10, 1024, 768};
    uint32_t rd_points = 50;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--json") && v) {
            json_path = v;
            i++;
        } else if (!strcmp(a, "--rd-json") && v) {
            rd_path = v;
            i++;
        } else if (!strcmp(a, "--seconds") && v && atof(v) > 0) {
            cfg.seconds = atof(v);
            i++;
        } else if (!strcmp(a, "--hz") && v && atof(v) > 0) {
            cfg.hz = atof(v);
            i++;
        } else if (!strcmp(a, "--far") && v && atof(v) > 1) {
            cfg.far = atof(v);
            i++;
        } else if (!strcmp(a, "--size") && v &&
                   sscanf(v, "%ux%u", &cfg.width, &cfg.height) == 2 && cfg.width >= 16 &&
                   cfg.height >= 16 && cfg.width <= 8192 && cfg.height <= 8192) {
            i++;
        } else if (!strcmp(a, "--rd-points") && v && cli_parse_u32(v, &rd_points) &&
                   rd_points >= 2) {
            i++;
        } else if (!strcmp(a, "--no-walk")) {
            do_walk = 0;
        } else if (!strcmp(a, "--no-rd")) {
            do_rd = 0;
        } else if (!strcmp(a, "--colors")) {
            colors = 1;
        } else if (!strcmp(a, "--color-field") && v &&
                   (!strcmp(v, "smooth") || !strcmp(v, "patches") || !strcmp(v, "curvature"))) {
            field = !strcmp(v, "smooth")    ? MTS_TEST_FIELD_SMOOTH
                    : !strcmp(v, "patches") ? MTS_TEST_FIELD_PATCHES
                                            : MTS_TEST_FIELD_CURVATURE;
            i++;
        } else if (!strcmp(a, "--color-cost") && v && atof(v) >= 0) {
            bo.color_cost = atof(v) > 0 ? atof(v) : -1;
            i++;
        } else if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return 0;
        } else if (a[0] == '-') {
            fprintf(stderr, "mts-bench-walk: bad option %s\n", a);
            usage(stderr);
            return 2;
        } else if (np < 16) {
            paths[np++] = a;
        }
    }
    uint32_t frames = (uint32_t)(cfg.seconds * cfg.hz + 0.5);
    mts_render_context *ctx = NULL;
    mts_error cerr = {0};
    int have_gl = do_walk && mts_render_context_create_headless(&ctx, &cerr) == MTS_OK;
    FILE *wf = do_walk && json_path ? fopen(json_path, "w") : NULL;
    FILE *rf = do_rd && rd_path ? fopen(rd_path, "w") : NULL;
    if (wf) {
        if (have_gl)
            fprintf(wf, "{\"renderer\":\"%s\",\"seconds\":%g,\"hz\":%g,\"frames\":%u,\"far\":%g,"
                        "\"width\":%u,\"height\":%u,\"policy\":\"distance\",\"models\":{",
                    mts_render_context_description(ctx), cfg.seconds, cfg.hz, frames, cfg.far,
                    cfg.width, cfg.height);
        else
            fprintf(wf, "{\"skipped\":\"no EGL: %s\",\"models\":{", cerr.msg);
    }
    if (rf)
        fputs("{\"models\":{", rf);
    if (do_walk && have_gl)
        printf("\nWalkthrough (papers 000/002): %u frames (%g s at %g Hz) moving away to %gx the "
               "framing distance, %ux%u, distance policy, on %s\n",
               frames, cfg.seconds, cfg.hz, cfg.far, cfg.width, cfg.height,
               mts_render_context_description(ctx));
    else if (do_walk)
        printf("\nWalkthrough: skipped (no EGL: %s)\n", cerr.msg);
    int first_w = 1, first_r = 1, status = 0;
    for (int pi = 0; pi < np; pi++) {
        char name[64];
        struct stat st;
        cli_stem(paths[pi], name, sizeof name);
        if (stat(paths[pi], &st) != 0) {
            printf("%-14s skipped: %s not found\n", name, paths[pi]);
            continue;
        }
        mts_error err = {0};
        mts_mesh mesh = {0};
        mts_model m;
        if (mts_mesh_load(paths[pi], NULL, &mesh, NULL, &err) != MTS_OK ||
            (colors && !mesh.colors && !mts_test_mesh_color_field(&mesh, field)) ||
            (!colors && (free(mesh.colors), mesh.colors = NULL, 0)) ||
            mts_build_model(&mesh, paths[pi], &bo, &m, NULL, &err) != MTS_OK) {
            printf("%-14s FAILED: %s\n", name, err.msg);
            mts_mesh_free(&mesh);
            status = 1;
            continue;
        }
        if (do_walk && have_gl) {
            series runs[2][MODE_COUNT];
            memset(runs, 0, sizeof runs);
            uint32_t *list = malloc(((size_t)m.level_triangles[m.level_count] + 1) * 12);
            int ok = list != NULL;
            for (int sc = 0; sc < 2 && ok; sc++)
                for (int md = 0; md < MODE_COUNT && ok; md++) {
                    series *s = &runs[sc][md];
                    s->frames = frames;
                    s->level = calloc(frames, 4);
                    s->triangles = calloc(frames, 4);
                    s->extract_ms = calloc(frames, 4);
                    s->upload_ms = calloc(frames, 4);
                    s->draw_ms = calloc(frames, 4);
                    ok = s->level && s->triangles && s->extract_ms && s->upload_ms &&
                         s->draw_ms && walk_run(ctx, &m, &cfg, sc, md, list, s, &err);
                }
            if (!ok) {
                printf("%-14s walkthrough FAILED: %s\n", name, err.msg);
                status = 1;
            } else {
                printf("%-14s %-12s %-13s %8s %9s %9s %9s %9s %10s\n", name, "schedule", "mode",
                       "fps", "extr ms", "max extr", "upload", "draw ms", "triangles");
                if (wf)
                    fprintf(wf, "%s\"%s\":{\"full_triangles\":%u,\"levels\":%u,\"runs\":{",
                            first_w ? "" : ",", name, m.level_triangles[m.level_count],
                            m.level_count);
                first_w = 0;
                for (int sc = 0; sc < 2; sc++) {
                    if (wf)
                        fprintf(wf, "%s\"%s\":{", sc ? "," : "", schedule_names[sc]);
                    for (int md = 0; md < MODE_COUNT; md++) {
                        series *s = &runs[sc][md];
                        summary u = summarize(s);
                        printf("%-14s %-12s %-13s %8.1f %9.3f %9.3f %9.3f %9.3f %10.0f\n", "",
                               schedule_names[sc], mode_names[md], u.mean_fps,
                               u.mean_extract_ms, u.max_extract_ms, u.mean_upload_ms,
                               u.mean_draw_ms, u.mean_triangles);
                        if (!wf)
                            continue;
                        fprintf(wf,
                                "%s\"%s\":{\"summary\":{\"mean_fps\":%.3f,\"mean_frame_ms\":%.4f,"
                                "\"mean_extract_ms\":%.4f,\"max_extract_ms\":%.4f,"
                                "\"mean_upload_ms\":%.4f,\"mean_draw_ms\":%.4f,"
                                "\"mean_triangles\":%.1f},",
                                md ? "," : "", mode_names[md], u.mean_fps, u.mean_frame_ms,
                                u.mean_extract_ms, u.max_extract_ms, u.mean_upload_ms,
                                u.mean_draw_ms, u.mean_triangles);
                        json_series_u32(wf, "level", s->level, frames);
                        fputc(',', wf);
                        json_series_u32(wf, "triangles", s->triangles, frames);
                        fputc(',', wf);
                        json_series_f(wf, "extract_ms", s->extract_ms, frames);
                        fputc(',', wf);
                        json_series_f(wf, "upload_ms", s->upload_ms, frames);
                        fputc(',', wf);
                        json_series_f(wf, "draw_ms", s->draw_ms, frames);
                        fputc('}', wf);
                    }
                    if (wf)
                        fputc('}', wf);
                }
                if (wf)
                    fputs("}}", wf);
            }
            for (int sc = 0; sc < 2; sc++)
                for (int md = 0; md < MODE_COUNT; md++) {
                    series *s = &runs[sc][md];
                    free(s->level);
                    free(s->triangles);
                    free(s->extract_ms);
                    free(s->upload_ms);
                    free(s->draw_ms);
                }
            free(list);
        }
        if (do_rd) {
            if (first_r)
                printf("\nRate-distortion: bytes received vs triangles and geometric error "
                       "(symmetric RMS / bbox diagonal), %u points\n",
                       rd_points);
            /* a model's JSON goes to memory first: a failure part-way leaves
             * the file whole */
            char *buf = NULL;
            size_t len = 0;
            FILE *mf = open_memstream(&buf, &len);
            int ok = mf && rd_model(mf, name, &mesh, &m, rd_points, &err);
            if (mf)
                fclose(mf);
            if (!ok) {
                printf("%-14s rate-distortion FAILED: %s\n", name, mf ? err.msg : "no memory");
                status = 1;
            } else if (rf) {
                fprintf(rf, "%s%s", first_r ? "" : ",", buf);
            }
            first_r = 0;
            free(buf);
        }
        mts_model_free(&m);
        mts_mesh_free(&mesh);
    }
    if (wf) {
        fputs("}}\n", wf);
        fclose(wf);
    }
    if (rf) {
        fputs("}}\n", rf);
        fclose(rf);
    }
    mts_render_context_destroy(ctx);
    return status;
}
