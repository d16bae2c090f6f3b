/* The renderer (render.h has the design): its making, the vertices and
 * geomorphs it is given, the frame and reading it back. The strips' index
 * buffers are render_strips.c's (render_state.h says how the two share). */
#include "render.h"
#include "render_internal.h"
#include "render_state.h"

#include <EGL/egl.h>
#include <GLES3/gl32.h>
#include <GLES2/gl2ext.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "camera.h"
#include "clock.h"
#include "follow.h"
#include "glprog.h"
#include "pngwrite.h"

/* ---- renderer --------------------------------------------------------- */

/* The vertex buffer's first room; it doubles as vertices come (a stream's
 * base is usually well under this, a model file's whole mesh over it). */
#define VERTEX_ROOM_START 65536u

static const char *gl_error_name(GLenum e)
{
    switch (e) {
    case GL_NO_ERROR: return "GL_NO_ERROR";
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    }
    return "unknown GL error";
}

/* Returns MTS_OK when GL has no error pending; else names `what`. Drains
 * every pending error so the next check starts clean. */
mts_result mts__render_gl_check(mts_error *err, const char *what)
{
    GLenum first = glGetError();
    if (first == GL_NO_ERROR)
        return MTS_OK;
    for (int i = 0; i < 16 && glGetError() != GL_NO_ERROR; i++)
        ;
    return mts_error_set(err, first == GL_OUT_OF_MEMORY ? MTS_ERR_NOMEM : MTS_ERR_INTERNAL,
                         "GL: %s: %s (0x%04x)", what, gl_error_name(first), (unsigned)first);
}

/* ---- camera ----------------------------------------------------------- */

static float clampf(float x, float lo, float hi)
{
    return x < lo ? lo : x > hi ? hi : x;
}

static void update_camera(mts_renderer *r)
{
    mts_camera_view cv;
    mts_camera_compute(r->bbox_min, r->bbox_max, &r->opts.camera,
                       (float)r->opts.width / (float)r->opts.height, &cv);
    memcpy(r->mvp, cv.mvp, sizeof r->mvp);
    memcpy(r->normal, cv.normal, sizeof r->normal);
    memcpy(r->eye, cv.eye, sizeof r->eye);
    memcpy(r->dir, cv.dir, sizeof r->dir);
}

void mts_render_set_camera(mts_renderer *r, const mts_render_camera *camera)
{
    r->opts.camera = *camera;
    update_camera(r);
}

void mts_render_set_style(mts_renderer *r, const mts_render_style *style)
{
    r->opts.style = *style;
    mts__render_style_defaults(&r->opts.style);
}

void mts_render_eye(const mts_renderer *r, float eye[3], float dir[3])
{
    memcpy(eye, r->eye, sizeof r->eye);
    memcpy(dir, r->dir, sizeof r->dir);
}

/* ---- shader ----------------------------------------------------------- */

static mts_result build_program(mts_renderer *r, int morph, mts_error *err)
{
    struct render_program *pg = &r->prog[morph];
    const char *head[3] = {"#version 300 es\n", morph ? "#define MORPH 1\n" : "#define MORPH 0\n",
                           r->colors ? "#define COLORS 1\n" : "#define COLORS 0\n"};
    const char *vs[4] = {head[0], head[1], head[2], mts_camera_vertex_glsl},
               *fs[4] = {head[0], head[1], head[2], mts_camera_fragment_glsl};
    mts_result rc = mts_glprog_build("render", vs, 4, fs, 4, &pg->id, err);
    if (rc != MTS_OK)
        return rc;
    pg->u_mvp = glGetUniformLocation(pg->id, "u_mvp");
    pg->u_normal = glGetUniformLocation(pg->id, "u_normal");
    pg->u_color = glGetUniformLocation(pg->id, "u_color");
    pg->u_light = glGetUniformLocation(pg->id, "u_light");
    pg->u_ambient = glGetUniformLocation(pg->id, "u_ambient");
    pg->u_flat = glGetUniformLocation(pg->id, "u_flat");
    pg->u_morph = glGetUniformLocation(pg->id, "u_morph");
    pg->u_morph_t = glGetUniformLocation(pg->id, "u_morph_t");
    pg->u_vertex_color = glGetUniformLocation(pg->id, "u_vertex_color");
    return mts__render_gl_check(err, "building the shader program");
}

/* ---- create / destroy ------------------------------------------------- */

void mts_renderer_destroy(mts_renderer *r)
{
    if (!r)
        return;
    if (mts_render_context_make_current(r->ctx, NULL) == MTS_OK) {
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        glBindVertexArray(0);
        if (r->fbo)
            glDeleteFramebuffers(1, &r->fbo);
        GLuint rbs[2] = {r->color_rb, r->depth_rb};
        glDeleteRenderbuffers(2, rbs);
        GLuint bufs[7] = {r->vbo,       r->ibo,       r->wire_ibo,       r->packed_ibo,
                          r->morph_vbo, r->color_vbo, r->morph_color_vbo};
        glDeleteBuffers(7, bufs);
        if (r->vao)
            glDeleteVertexArrays(1, &r->vao);
        for (int i = 0; i < 2; i++)
            if (r->prog[i].id)
                glDeleteProgram(r->prog[i].id);
        glGetError(); /* nothing to report from here */
    }
    free(r->offset);
    free(r->capacity);
    free(r->length);
    free(r->staging);
    free(r->host);
    mts_follow_packed_free(&r->packed);
    free(r);
}

mts_result mts_renderer_create(mts_render_context *ctx, const mts_render_options *opts,
                               const mts_render_layout *layout, mts_renderer **out,
                               mts_error *err)
{
    if (!ctx || !opts || !layout || !out)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to mts_renderer_create");
    *out = NULL;
    mts_result rc = mts__render_check_layout(layout, err);
    if (rc != MTS_OK)
        return rc;
    mts_render_options o = *opts;
    if (o.width == 0 && o.height == 0)
        o.width = o.height = 512;
    if (o.width == 0 || o.height == 0)
        return mts_error_set(err, MTS_ERR_ARG, "render: size %ux%u", o.width, o.height);
    mts__render_style_defaults(&o.style);
    opts = &o;
    rc = mts_render_context_make_current(ctx, err);
    if (rc != MTS_OK)
        return rc;
    glGetError(); /* start clean */

    GLint max_rb = 0;
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
    if (opts->width > (uint32_t)max_rb || opts->height > (uint32_t)max_rb)
        return mts_error_set(err, MTS_ERR_LIMIT, "render: size %ux%u above GL's %d",
                             opts->width, opts->height, max_rb);
    /* the restart index may not be a vertex id; GL must address the largest */
    GLint64 max_index = 0;
    glGetInteger64v(GL_MAX_ELEMENT_INDEX, &max_index);
    if (layout->vertex_capacity == UINT32_MAX ||
        (int64_t)layout->vertex_capacity - 1 > (int64_t)max_index)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "render: %u vertices, GL addresses indices up to %lld",
                             layout->vertex_capacity, (long long)max_index);
    const uint32_t slots_end = layout->slot[layout->strip_count];
    const uint64_t index_limit =
        (uint64_t)(layout->room > slots_end ? layout->room : slots_end) + layout->strip_count;
    if (index_limit > (uint64_t)INT32_MAX) /* glDrawElements takes a GLsizei */
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "render: %llu indices in the strip buffer, at most %d",
                             (unsigned long long)index_limit, INT32_MAX);
    const uint64_t vertex_size = layout->colors ? 28u : 24u;
    if ((uint64_t)layout->vertex_capacity * vertex_size > (uint64_t)PTRDIFF_MAX ||
        index_limit * 4u > (uint64_t)PTRDIFF_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "render: buffers of %llu + %llu bytes",
                             (unsigned long long)layout->vertex_capacity * 24u,
                             (unsigned long long)index_limit * 4u);
    /* the slots laid out so far, and room for the vertices to come at first */
    const uint64_t index_count = (uint64_t)slots_end + layout->strip_count;
    const uint32_t vertex_capacity =
        layout->vertex_capacity < VERTEX_ROOM_START ? layout->vertex_capacity : VERTEX_ROOM_START;
    const uint64_t vbytes = (uint64_t)vertex_capacity * 24u;

    mts_renderer *r = calloc(1, sizeof *r);
    if (!r)
        return mts_error_set(err, MTS_ERR_NOMEM, "render: renderer");
    r->ctx = ctx;
    r->opts = *opts;
    r->vertex_capacity = vertex_capacity;
    r->vertex_limit = layout->vertex_capacity;
    r->colors = layout->colors != 0;
    r->index_limit = index_limit;
    r->strip_count = layout->strip_count;
    r->index_count = index_count;
    memcpy(r->bbox_min, layout->bbox_min, sizeof r->bbox_min);
    memcpy(r->bbox_max, layout->bbox_max, sizeof r->bbox_max);
    size_t n = (size_t)layout->strip_count + 1;
    r->offset = malloc(n * sizeof *r->offset);
    r->capacity = malloc(n * sizeof *r->capacity);
    r->length = calloc(n, sizeof *r->length);
    if (!r->offset || !r->capacity || !r->length) {
        mts_renderer_destroy(r);
        return mts_error_set(err, MTS_ERR_NOMEM, "render: %llu indices",
                             (unsigned long long)index_count);
    }
    for (uint32_t s = 0; s < layout->strip_count; s++) {
        r->offset[s] = layout->slot[s] + s;
        r->capacity[s] = layout->slot[s + 1] - layout->slot[s];
        if (r->capacity[s] > r->max_capacity)
            r->max_capacity = r->capacity[s];
    }
    r->offset[layout->strip_count] = (uint32_t)index_count;
    r->capacity[layout->strip_count] = 0;
    r->staging = malloc(((size_t)r->max_capacity + 1) * sizeof *r->staging);
    r->host = malloc((size_t)(index_count ? index_count : 1) * sizeof *r->host);
    r->packed_kind = -1;
    /* 16-bit indices where every vertex id (and the restart 0xFFFF) fits */
    r->packed_u16 = layout->vertex_capacity <= 0xFFFFu;
    if (!r->staging || !r->host) {
        mts_renderer_destroy(r);
        return mts_error_set(err, MTS_ERR_NOMEM, "render: staging for %u indices",
                             r->max_capacity);
    }

    rc = build_program(r, 0, err);
    if (rc == MTS_OK)
        rc = build_program(r, 1, err);
    if (rc != MTS_OK)
        goto fail;

    glGenVertexArrays(1, &r->vao);
    glGenBuffers(1, &r->vbo);
    glGenBuffers(1, &r->ibo);
    glBindVertexArray(r->vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)vbytes, NULL, GL_DYNAMIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, (const void *)0);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 0,
                          (const void *)(uintptr_t)((uint64_t)r->vertex_capacity * 12u));
    /* the element buffer binding is VAO state */
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(index_count ? index_count * 4u : 4u), NULL,
                 GL_DYNAMIC_DRAW);
    r->slots_stale = 1; /* all restarts, once a slot-reading mode draws */
    if (r->colors) {
        glGenBuffers(1, &r->color_vbo);
        glBindBuffer(GL_ARRAY_BUFFER, r->color_vbo);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((uint64_t)vertex_capacity * 4u), NULL,
                     GL_DYNAMIC_DRAW);
        glEnableVertexAttribArray(4);
        glVertexAttribPointer(4, 4, GL_UNSIGNED_BYTE, GL_TRUE, 0, (const void *)0);
    }
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    rc = mts__render_gl_check(err, "creating the buffers");
    if (rc != MTS_OK)
        goto fail;

    glGenRenderbuffers(1, &r->color_rb);
    glBindRenderbuffer(GL_RENDERBUFFER, r->color_rb);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, (GLsizei)opts->width,
                          (GLsizei)opts->height);
    glGenRenderbuffers(1, &r->depth_rb);
    glBindRenderbuffer(GL_RENDERBUFFER, r->depth_rb);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, (GLsizei)opts->width,
                          (GLsizei)opts->height);
    glGenFramebuffers(1, &r->fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                              r->color_rb);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER,
                              r->depth_rb);
    GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
        rc = mts_error_set(err, MTS_ERR_INTERNAL, "GL: framebuffer %ux%u incomplete (0x%04x)",
                           opts->width, opts->height, (unsigned)status);
        goto fail;
    }
    rc = mts__render_gl_check(err, "creating the framebuffer");
    if (rc != MTS_OK)
        goto fail;

    /* glMultiDrawElementsEXT where the driver has it */
    GLint ext_count = 0;
    glGetIntegerv(GL_NUM_EXTENSIONS, &ext_count);
    for (GLint i = 0; i < ext_count; i++) {
        const char *e = (const char *)glGetStringi(GL_EXTENSIONS, (GLuint)i);
        if (e && strcmp(e, "GL_EXT_multi_draw_arrays") == 0) {
            r->multi_draw = (PFNGLMULTIDRAWELEMENTSEXTPROC)eglGetProcAddress(
                "glMultiDrawElementsEXT");
            break;
        }
    }

    update_camera(r);
    r->stats.width = opts->width;
    r->stats.height = opts->height;
    r->stats.vertex_buffer_bytes = vbytes + (r->colors ? (uint64_t)vertex_capacity * 4u : 0);
    r->stats.colors = r->colors;
    r->stats.index_buffer_bytes = index_count * 4u;
    r->stats.multi_draw_available = r->multi_draw != NULL;
    *out = r;
    return MTS_OK;
fail:
    mts_renderer_destroy(r);
    return rc;
}

/* ---- geometry --------------------------------------------------------- */

/* A buffer of `bytes` bound to target whose first `keep` bytes are old's
 * and whose bytes from `at` are old's from `old_at` (`tail` of them):
 * two halves of a buffer moved apart as it grows, copied on the GPU. */
static GLuint grown_buffer(GLuint old, uint64_t bytes, uint64_t keep, uint64_t old_at,
                           uint64_t at, uint64_t tail)
{
    GLuint b = 0;
    glGenBuffers(1, &b);
    glBindBuffer(GL_COPY_WRITE_BUFFER, b);
    glBufferData(GL_COPY_WRITE_BUFFER, (GLsizeiptr)bytes, NULL, GL_DYNAMIC_DRAW);
    glBindBuffer(GL_COPY_READ_BUFFER, old);
    if (keep)
        glCopyBufferSubData(GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER, 0, 0, (GLsizeiptr)keep);
    if (tail)
        glCopyBufferSubData(GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER, (GLintptr)old_at,
                            (GLintptr)at, (GLsizeiptr)tail);
    glBindBuffer(GL_COPY_READ_BUFFER, 0);
    glBindBuffer(GL_COPY_WRITE_BUFFER, 0);
    glDeleteBuffers(1, &old);
    return b;
}

/* Room for `need` vertices (at most vertex_limit): the vertex buffer, and
 * the geomorph's sources where there are any, at least doubled, what was
 * uploaded kept, the attributes pointed at the new halves. */
static mts_result grow_vertices(mts_renderer *r, uint32_t need, mts_error *err)
{
    uint64_t cap = 2ull * r->vertex_capacity;
    if (cap < need)
        cap = need;
    if (cap > r->vertex_limit)
        cap = r->vertex_limit;
    const uint64_t used = r->stats.vertices, old_cap = r->vertex_capacity;
    r->vbo = grown_buffer(r->vbo, cap * 24u, used * 12u, old_cap * 12u, cap * 12u, used * 12u);
    glBindVertexArray(r->vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->vbo);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, (const void *)0);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 0, (const void *)(uintptr_t)(cap * 12u));
    r->stats.vertex_buffer_bytes += (cap - old_cap) * 24u;
    if (r->morph_vbo) {
        /* positions (12 bytes a vertex), then normals in 4 */
        r->morph_vbo = grown_buffer(r->morph_vbo, cap * 16u, used * 12u, old_cap * 12u,
                                    cap * 12u, used * 4u);
        glBindBuffer(GL_ARRAY_BUFFER, r->morph_vbo);
        glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, 0, (const void *)0);
        glVertexAttribPointer(3, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 0,
                              (const void *)(uintptr_t)(cap * 12u));
        r->stats.vertex_buffer_bytes += (cap - old_cap) * 16u;
    }
    if (r->color_vbo) {
        r->color_vbo = grown_buffer(r->color_vbo, cap * 4u, used * 4u, 0, 0, 0);
        glBindBuffer(GL_ARRAY_BUFFER, r->color_vbo);
        glVertexAttribPointer(4, 4, GL_UNSIGNED_BYTE, GL_TRUE, 0, (const void *)0);
        r->stats.vertex_buffer_bytes += (cap - old_cap) * 4u;
    }
    if (r->morph_color_vbo) {
        r->morph_color_vbo = grown_buffer(r->morph_color_vbo, cap * 4u, used * 4u, 0, 0, 0);
        glBindBuffer(GL_ARRAY_BUFFER, r->morph_color_vbo);
        glVertexAttribPointer(5, 4, GL_UNSIGNED_BYTE, GL_TRUE, 0, (const void *)0);
        r->stats.vertex_buffer_bytes += (cap - old_cap) * 4u;
    }
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    r->vertex_capacity = (uint32_t)cap;
    return mts__render_gl_check(err, "growing the vertex buffer");
}

/* count colours of 3 bytes (the model's) as RGBA8 with alpha 255 into the
 * buffer bound to GL_ARRAY_BUFFER, from vertex `first` (4 bytes each);
 * MTS_ERR_NOMEM when the staging cannot be had. */
static mts_result upload_colors(uint32_t first, uint32_t count, const uint8_t *rgb,
                                mts_error *err)
{
    uint8_t *rgba = malloc((size_t)count * 4u);
    if (!rgba)
        return mts_error_set(err, MTS_ERR_NOMEM, "render: colours of %u vertices", count);
    for (size_t i = 0; i < count; i++) {
        rgba[4 * i] = rgb[3 * i];
        rgba[4 * i + 1] = rgb[3 * i + 1];
        rgba[4 * i + 2] = rgb[3 * i + 2];
        rgba[4 * i + 3] = 255;
    }
    glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)((uint64_t)first * 4u),
                    (GLsizeiptr)((uint64_t)count * 4u), rgba);
    free(rgba);
    return MTS_OK;
}

mts_result mts_render_append_vertices(mts_renderer *r, uint32_t first, uint32_t count,
                                      const float *positions, const float *normals,
                                      const uint8_t *colors, mts_error *err)
{
    if (!r || (count && (!positions || !normals)))
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to append_vertices");
    if (count && r->colors && !colors)
        return mts_error_set(err, MTS_ERR_ARG,
                             "render: vertices %u..%llu appended without the colours the "
                             "layout said they have",
                             first, (unsigned long long)first + count - 1);
    if (first > r->stats.vertices)
        return mts_error_set(err, MTS_ERR_RANGE,
                             "render: vertices from %u appended, but only %u are there "
                             "(appending leaves no gap)",
                             first, r->stats.vertices);
    if ((uint64_t)first + count > r->vertex_limit)
        return mts_error_set(err, MTS_ERR_RANGE,
                             "render: vertices %u..%llu beyond the capacity of %u", first,
                             (unsigned long long)first + count - 1, r->vertex_limit);
    if (count == 0)
        return MTS_OK;
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    if ((uint64_t)first + count > r->vertex_capacity &&
        (rc = grow_vertices(r, first + count, err)) != MTS_OK)
        return rc;
    glBindBuffer(GL_ARRAY_BUFFER, r->vbo);
    glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)((uint64_t)first * 12u),
                    (GLsizeiptr)((uint64_t)count * 12u), positions);
    glBufferSubData(GL_ARRAY_BUFFER,
                    (GLintptr)((uint64_t)r->vertex_capacity * 12u + (uint64_t)first * 12u),
                    (GLsizeiptr)((uint64_t)count * 12u), normals);
    if (r->colors) {
        glBindBuffer(GL_ARRAY_BUFFER, r->color_vbo);
        rc = upload_colors(first, count, colors, err);
    }
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    if (rc != MTS_OK)
        return rc;
    rc = mts__render_gl_check(err, "uploading vertices");
    if (rc != MTS_OK)
        return rc;
    if (first + count > r->stats.vertices)
        r->stats.vertices = first + count;
    r->stats.vertex_bytes_uploaded += (uint64_t)count * (r->colors ? 28u : 24u);
    return MTS_OK;
}

mts_result mts_render_set_morph(mts_renderer *r, uint32_t first, uint32_t count,
                                const float *from_positions, const float *from_normals,
                                const uint8_t *from_colors, mts_error *err)
{
    if (!r || (count && (!from_positions || !from_normals || (r->colors && !from_colors))))
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to set_morph");
    if ((uint64_t)first + count > r->vertex_capacity)
        return mts_error_set(err, MTS_ERR_RANGE,
                             "render: morph of vertices %u..%llu beyond the capacity of %u",
                             first, (unsigned long long)first + count - 1, r->vertex_capacity);
    r->morph_t = 0;
    if (count == 0) {
        r->morph_first = r->morph_end = 0;
        return MTS_OK;
    }
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    /* positions as they are (the morph's first frame must be the old
     * level's surface), normals in 10 bits a component
     * (GL_INT_2_10_10_10_REV): 16 bytes a vertex instead of 24 */
    uint64_t half = (uint64_t)r->vertex_capacity * 12u;
    uint32_t *packed = malloc((size_t)count * sizeof *packed);
    if (!packed)
        return mts_error_set(err, MTS_ERR_NOMEM, "render: a morph of %u vertices", count);
    for (uint32_t i = 0; i < count; i++) {
        uint32_t w = 0;
        for (int c = 0; c < 3; c++) {
            float x = from_normals[3 * (size_t)i + c];
            x = isfinite(x) ? clampf(x, -1.0f, 1.0f) : 0.0f;
            int q = (int)lrintf(x * 511.0f);
            w |= ((uint32_t)q & 0x3FFu) << (10 * c);
        }
        packed[i] = w;
    }
    if (!r->morph_vbo) {
        glGenBuffers(1, &r->morph_vbo);
        glBindBuffer(GL_ARRAY_BUFFER, r->morph_vbo);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(half + (uint64_t)r->vertex_capacity * 4u),
                     NULL, GL_DYNAMIC_DRAW);
        glBindVertexArray(r->vao);
        glEnableVertexAttribArray(2);
        glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, 0, (const void *)0);
        glEnableVertexAttribArray(3);
        glVertexAttribPointer(3, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 0,
                              (const void *)(uintptr_t)half);
        glBindVertexArray(0);
        r->stats.vertex_buffer_bytes += half + (uint64_t)r->vertex_capacity * 4u;
    }
    glBindBuffer(GL_ARRAY_BUFFER, r->morph_vbo);
    glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)((uint64_t)first * 12u),
                    (GLsizeiptr)((uint64_t)count * 12u), from_positions);
    glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)(half + (uint64_t)first * 4u),
                    (GLsizeiptr)((uint64_t)count * 4u), packed);
    free(packed);
    if (r->colors) {
        if (!r->morph_color_vbo) {
            glGenBuffers(1, &r->morph_color_vbo);
            glBindBuffer(GL_ARRAY_BUFFER, r->morph_color_vbo);
            glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((uint64_t)r->vertex_capacity * 4u), NULL,
                         GL_DYNAMIC_DRAW);
            glBindVertexArray(r->vao);
            glEnableVertexAttribArray(5);
            glVertexAttribPointer(5, 4, GL_UNSIGNED_BYTE, GL_TRUE, 0, (const void *)0);
            glBindVertexArray(0);
            r->stats.vertex_buffer_bytes += (uint64_t)r->vertex_capacity * 4u;
        }
        glBindBuffer(GL_ARRAY_BUFFER, r->morph_color_vbo);
        rc = upload_colors(first, count, from_colors, err);
    }
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    if (rc == MTS_OK)
        rc = mts__render_gl_check(err, "uploading a morph's sources");
    if (rc != MTS_OK) {
        r->morph_first = r->morph_end = 0;
        return rc;
    }
    r->morph_first = first;
    r->morph_end = first + count;
    const uint64_t size = r->colors ? 20u : 16u;
    r->stats.vertex_bytes_uploaded += (uint64_t)count * size;
    r->stats.morph_bytes_uploaded += (uint64_t)count * size;
    return MTS_OK;
}

void mts_render_set_morph_t(mts_renderer *r, float t)
{
    r->morph_t = t < 0 ? 0 : t > 1 ? 1 : t;
}

uint32_t mts_render_vertex_count(const mts_renderer *r)
{
    return r->stats.vertices;
}

/* ---- drawing ---------------------------------------------------------- */

mts_render_context *mts__render_context(const mts_renderer *r)
{
    return r->ctx;
}

mts_result mts__render_frame_begin(mts_renderer *r, int wireframe, int slots,
                                   mts__render_frame *f, mts_error *err)
{
    if (!r)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL renderer");
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    const mts_render_style *st = &r->opts.style;
    memset(f, 0, sizeof *f);
    f->t0 = mts_clock_seconds();

    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glViewport(0, 0, (GLsizei)r->opts.width, (GLsizei)r->opts.height);
    glClearColor(st->background[0], st->background[1], st->background[2], st->background[3]);
    glClearDepthf(1.0f);
    glDepthMask(GL_TRUE);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glFrontFace(GL_CCW);
    glCullFace(GL_BACK);
    if (!st->show_back_faces)
        glEnable(GL_CULL_FACE);
    else
        glDisable(GL_CULL_FACE);
    glEnable(GL_PRIMITIVE_RESTART_FIXED_INDEX);
    f->wire = wireframe && st->wireframe && r->wire_count;
    if (f->wire) { /* the surface a little behind its edges */
        glEnable(GL_POLYGON_OFFSET_FILL);
        glPolygonOffset(1.0f, 1.0f);
    } else {
        glDisable(GL_POLYGON_OFFSET_FILL);
    }

    /* at t = 1 every vertex is at its own place: the plain program draws
     * that exactly (mix() may round on the way) */
    const int morph = r->morph_end > r->morph_first && r->morph_t < 1;
    const struct render_program *pg = &r->prog[morph];
    f->program = morph;
    glUseProgram(pg->id);
    glUniformMatrix4fv(pg->u_mvp, 1, GL_FALSE, r->mvp);
    glUniformMatrix3fv(pg->u_normal, 1, GL_FALSE, r->normal);
    /* towards the light, view space: above-left of the camera, in front */
    float light[3];
    mts_camera_light(light);
    glUniform3fv(pg->u_light, 1, light);
    glUniform1f(pg->u_ambient, clampf(st->ambient, 0.0f, 1.0f));
    glUniform3fv(pg->u_color, 1, st->color);
    glUniform1i(pg->u_flat, st->flat_shading != 0);
    if (r->colors) /* colour by strip draws each strip in its own */
        glUniform1i(pg->u_vertex_color, !st->color_by_strip);
    if (morph) {
        glUniform2ui(pg->u_morph, r->morph_first, r->morph_end);
        glUniform1f(pg->u_morph_t, r->morph_t);
    }
    glBindVertexArray(r->vao);
    if (slots && r->slots_stale && !mts__render_upload_slots(r)) {
        glBindVertexArray(0);
        return mts_error_set(err, MTS_ERR_NOMEM, "render: %llu indices",
                             (unsigned long long)r->index_count);
    }
    f->strip_count = r->strip_count;
    f->offset = r->offset;
    f->length = r->length;
    f->slot_indices = r->index_count;
    f->multi_draw = (void (*)(void))r->multi_draw;
    f->u_color = pg->u_color;
    return MTS_OK;
}

mts_result mts__render_draw_packed(mts_renderer *r, int compact, uint32_t *calls,
                                   uint64_t *indices, uint64_t *index_bytes, mts_error *err)
{
    unsigned ibo;
    uint64_t count;
    int u16;
    mts_result rc = mts__render_packed(r, compact, &ibo, &count, &u16, err);
    if (rc != MTS_OK)
        return rc;
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ibo);
    *calls = 0;
    *indices = *index_bytes = 0;
    if (count) {
        glDrawElements(GL_TRIANGLE_STRIP, (GLsizei)count, u16 ? GL_UNSIGNED_SHORT : GL_UNSIGNED_INT,
                       (const void *)0);
        *calls = 1;
        *indices = count;
        *index_bytes = count * (u16 ? 2u : 4u);
    }
    return MTS_OK;
}

mts_result mts__render_frame_end(mts_renderer *r, const mts__render_frame *f, uint32_t calls,
                                 uint64_t indices, uint64_t index_bytes, mts_error *err)
{
    const mts_render_style *st = &r->opts.style;
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->ibo); /* the VAO's own again */
    if (f->wire) {
        const struct render_program *pg = &r->prog[f->program];
        glDisable(GL_POLYGON_OFFSET_FILL);
        glDepthFunc(GL_LEQUAL);
        glUniform1f(pg->u_ambient, 1.0f); /* flat: the edge colour as it is */
        glUniform3fv(pg->u_color, 1, st->wire_color);
        if (r->colors)
            glUniform1i(pg->u_vertex_color, 0);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->wire_ibo);
        glDrawElements(GL_LINES, (GLsizei)r->wire_count, GL_UNSIGNED_INT, (const void *)0);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->ibo);
        glDepthFunc(GL_LESS);
        calls++;
        indices += r->wire_count;
        index_bytes += r->wire_count * 4u;
    }
    glBindVertexArray(0);
    if (r->opts.timed)
        glFinish();
    double t1 = mts_clock_seconds();
    mts_result rc = mts__render_gl_check(err, "drawing");
    if (rc != MTS_OK)
        return rc;
    r->stats.last_draw_seconds = r->opts.timed ? t1 - f->t0 : 0;
    r->stats.last_draw_calls = calls;
    r->stats.last_draw_indices = indices;
    r->stats.last_draw_index_bytes = index_bytes;
    return MTS_OK;
}

/* The frame: the live strips joined into one packed strip (see the top),
 * or, with color_by_strip, each strip of the slot buffer in its colour. */
mts_result mts_render_draw(mts_renderer *r, mts_error *err)
{
    mts__render_frame f;
    const int per_strip = r && r->opts.style.color_by_strip;
    mts_result rc = mts__render_frame_begin(r, 1, per_strip, &f, err);
    if (rc != MTS_OK)
        return rc;
    uint32_t calls = 0;
    uint64_t indices = 0, index_bytes = 0;
    if (per_strip) {
        for (uint32_t s = 0; s < r->strip_count; s++) {
            if (r->length[s] < 3)
                continue;
            float c[3];
            mts_camera_strip_color(s, c);
            glUniform3fv(f.u_color, 1, c);
            glDrawElements(GL_TRIANGLE_STRIP, (GLsizei)r->length[s], GL_UNSIGNED_INT,
                           (const void *)(uintptr_t)((uint64_t)r->offset[s] * 4u));
            calls++;
            indices += r->length[s];
        }
        index_bytes = indices * 4u;
    } else if ((rc = mts__render_draw_packed(r, 0, &calls, &indices, &index_bytes, err)) !=
               MTS_OK) {
        mts__render_frame_end(r, &f, 0, 0, 0, NULL);
        return rc;
    }
    return mts__render_frame_end(r, &f, calls, indices, index_bytes, err);
}

/* ---- size, window, read-back ------------------------------------------ */

mts_result mts_render_resize(mts_renderer *r, uint32_t width, uint32_t height, mts_error *err)
{
    if (!r || width == 0 || height == 0)
        return mts_error_set(err, MTS_ERR_ARG, "render: resize to %ux%u", width, height);
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    GLint max_rb = 0;
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
    if (width > (uint32_t)max_rb || height > (uint32_t)max_rb)
        return mts_error_set(err, MTS_ERR_LIMIT, "render: size %ux%u above GL's %d", width,
                             height, max_rb);
    glBindRenderbuffer(GL_RENDERBUFFER, r->color_rb);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, (GLsizei)width, (GLsizei)height);
    glBindRenderbuffer(GL_RENDERBUFFER, r->depth_rb);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, (GLsizei)width,
                          (GLsizei)height);
    glBindRenderbuffer(GL_RENDERBUFFER, 0);
    rc = mts__render_gl_check(err, "resizing the framebuffer");
    if (rc != MTS_OK)
        return rc;
    r->opts.width = r->stats.width = width;
    r->opts.height = r->stats.height = height;
    update_camera(r);
    return MTS_OK;
}

mts_result mts_render_blit(mts_renderer *r, mts_error *err)
{
    if (!r)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL renderer");
    if (!mts_render_context_has_window(r->ctx))
        return mts_error_set(err, MTS_ERR_ARG, "render: blit on a context without a window");
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    uint32_t ww, wh;
    mts_render_context_surface_size(r->ctx, &ww, &wh);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, r->fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    GLenum back = GL_BACK;
    glDrawBuffers(1, &back);
    int same = ww == r->opts.width && wh == r->opts.height;
    glBlitFramebuffer(0, 0, (GLint)r->opts.width, (GLint)r->opts.height, 0, 0, (GLint)ww,
                      (GLint)wh, GL_COLOR_BUFFER_BIT, same ? GL_NEAREST : GL_LINEAR);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, (GLsizei)ww, (GLsizei)wh);
    return mts__render_gl_check(err, "blitting the frame to the window");
}

mts_result mts_render_present(mts_renderer *r, mts_error *err)
{
    mts_result rc = mts_render_blit(r, err);
    return rc != MTS_OK ? rc : mts_render_context_swap(r->ctx, err);
}

/* glReadPixels of the framebuffer: GL's row order, bottom row first. */
static mts_result read_raw(mts_renderer *r, uint8_t *rgba, mts_error *err)
{
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, (GLsizei)r->opts.width, (GLsizei)r->opts.height, GL_RGBA,
                 GL_UNSIGNED_BYTE, rgba);
    return mts__render_gl_check(err, "glReadPixels");
}

mts_result mts_render_read_rgba(mts_renderer *r, uint8_t *rgba, mts_error *err)
{
    if (!r || !rgba)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to read_rgba");
    mts_result rc = read_raw(r, rgba, err);
    if (rc != MTS_OK)
        return rc;
    uint32_t w = r->opts.width, h = r->opts.height;
    size_t row = (size_t)w * 4u;
    for (uint32_t y = 0; y < h / 2; y++) {
        uint8_t *a = rgba + (size_t)y * row, *b = rgba + (size_t)(h - 1 - y) * row;
        for (size_t i = 0; i < row; i++) {
            uint8_t t = a[i];
            a[i] = b[i];
            b[i] = t;
        }
    }
    return MTS_OK;
}

mts_result mts_render_write_png(mts_renderer *r, const char *path, mts_error *err)
{
    if (!r || !path)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to write_png");
    uint8_t *buf = malloc((size_t)r->opts.width * r->opts.height * 4u);
    if (!buf)
        return mts_error_set(err, MTS_ERR_NOMEM, "render: %ux%u frame", r->opts.width,
                             r->opts.height);
    mts_result rc = read_raw(r, buf, err);
    if (rc == MTS_OK) /* libpng flips: bottom_up */
        rc = mts_png_write_rgba(path, r->opts.width, r->opts.height, buf, 1, err);
    free(buf);
    return rc;
}

void mts_render_get_stats(const mts_renderer *r, mts_render_stats *stats)
{
    *stats = r->stats;
}

void mts_render_reset_counters(mts_renderer *r)
{
    r->stats.vertex_bytes_uploaded = 0;
    r->stats.index_bytes_uploaded = 0;
    r->stats.strip_uploads = 0;
    r->stats.full_uploads = 0;
    r->stats.packed_builds = 0;
}
