/* The draw paths the renderer is measured against (drawmodes.h). */
#include "drawmodes.h"

#include <GLES3/gl32.h>
#include <GLES2/gl2ext.h>
#include <stdlib.h>
#include <string.h>

#include "render_internal.h"

mts_result mts_drawmodes_set_list(mts_drawmodes *d, mts_renderer *r, const uint32_t *indices,
                                  uint32_t count, mts_error *err)
{
    if (!d || !r || (count && !indices) || count % 3 != 0 || count > (uint32_t)INT32_MAX)
        return mts_error_set(err, MTS_ERR_ARG, "drawmodes: a triangle list of %u indices", count);
    uint32_t vertices = mts_render_vertex_count(r);
    for (uint32_t i = 0; i < count; i++)
        if (indices[i] >= vertices)
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "drawmodes: list index %u is past the %u vertices uploaded",
                                 indices[i], vertices);
    mts_result rc = mts_render_context_make_current(mts__render_context(r), err);
    if (rc != MTS_OK)
        return rc;
    if (!d->list_ibo)
        glGenBuffers(1, &d->list_ibo);
    glBindVertexArray(0);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, d->list_ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)count * 4, indices, GL_STATIC_DRAW);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
    d->list_count = count;
    GLenum e = glGetError();
    return e == GL_NO_ERROR ? MTS_OK
                            : mts_error_set(err, e == GL_OUT_OF_MEMORY ? MTS_ERR_NOMEM
                                                                       : MTS_ERR_INTERNAL,
                                            "GL: uploading a triangle list (0x%04x)",
                                            (unsigned)e);
}

static int multi_room(mts_drawmodes *d, uint32_t n)
{
    if (n <= d->multi_cap)
        return 1;
    int32_t *c = realloc(d->multi_count, (size_t)n * sizeof *c);
    if (c)
        d->multi_count = c;
    const void **o = realloc(d->multi_offset, (size_t)n * sizeof *o);
    if (o)
        d->multi_offset = o;
    if (!c || !o)
        return 0;
    d->multi_cap = n;
    return 1;
}

mts_result mts_drawmodes_draw(mts_drawmodes *d, mts_renderer *r, mts_drawmode mode,
                              mts_error *err)
{
    if (mode == MTS_DRAWMODE_JOINED)
        return mts_render_draw(r, err);
    const int slots = mode == MTS_DRAWMODE_RESTART || mode == MTS_DRAWMODE_PER_STRIP ||
                      mode == MTS_DRAWMODE_MULTI;
    mts__render_frame f;
    mts_result rc = mts__render_frame_begin(r, mode != MTS_DRAWMODE_LIST, slots, &f, err);
    if (rc != MTS_OK)
        return rc;
    uint32_t calls = 0;
    uint64_t indices = 0, bytes = 0;
    PFNGLMULTIDRAWELEMENTSEXTPROC multi = (PFNGLMULTIDRAWELEMENTSEXTPROC)f.multi_draw;
    if (mode == MTS_DRAWMODE_MULTI && !multi)
        mode = MTS_DRAWMODE_PER_STRIP;
    switch (mode) {
    case MTS_DRAWMODE_RESTART:
        if (f.slot_indices) {
            glDrawElements(GL_TRIANGLE_STRIP, (GLsizei)f.slot_indices, GL_UNSIGNED_INT,
                           (const void *)0);
            calls = 1;
            indices = f.slot_indices;
        }
        bytes = indices * 4u;
        break;
    case MTS_DRAWMODE_PER_STRIP:
        for (uint32_t s = 0; s < f.strip_count; s++) {
            if (f.length[s] < 3)
                continue;
            glDrawElements(GL_TRIANGLE_STRIP, (GLsizei)f.length[s], GL_UNSIGNED_INT,
                           (const void *)(uintptr_t)((uint64_t)f.offset[s] * 4u));
            calls++;
            indices += f.length[s];
        }
        bytes = indices * 4u;
        break;
    case MTS_DRAWMODE_MULTI: {
        if (!multi_room(d, f.strip_count + 1)) {
            mts__render_frame_end(r, &f, 0, 0, 0, NULL);
            return mts_error_set(err, MTS_ERR_NOMEM, "drawmodes: %u strips", f.strip_count);
        }
        GLsizei n = 0;
        for (uint32_t s = 0; s < f.strip_count; s++) {
            if (f.length[s] < 3)
                continue;
            d->multi_count[n] = (GLsizei)f.length[s];
            d->multi_offset[n] = (const void *)(uintptr_t)((uint64_t)f.offset[s] * 4u);
            indices += f.length[s];
            n++;
        }
        if (n) {
            multi(GL_TRIANGLE_STRIP, d->multi_count, GL_UNSIGNED_INT, d->multi_offset, n);
            calls = 1;
        }
        bytes = indices * 4u;
        break;
    }
    case MTS_DRAWMODE_COMPACT:
        if ((rc = mts__render_draw_packed(r, 1, &calls, &indices, &bytes, err)) != MTS_OK) {
            mts__render_frame_end(r, &f, 0, 0, 0, NULL);
            return rc;
        }
        break;
    case MTS_DRAWMODE_LIST:
        if (d->list_count) {
            glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, d->list_ibo);
            glDrawElements(GL_TRIANGLES, (GLsizei)d->list_count, GL_UNSIGNED_INT,
                           (const void *)0);
            calls = 1;
            indices = d->list_count;
            bytes = indices * 4u;
        }
        break;
    default:
        break;
    }
    return mts__render_frame_end(r, &f, calls, indices, bytes, err);
}

void mts_drawmodes_free(mts_drawmodes *d)
{
    if (!d)
        return;
    if (d->list_ibo)
        glDeleteBuffers(1, &d->list_ibo);
    free(d->multi_count);
    free(d->multi_offset);
    memset(d, 0, sizeof *d);
}
