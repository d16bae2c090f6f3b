/* The HUD (hud.h has the design). */
#include "hud.h"

#include <GLES3/gl3.h>
#include <stdlib.h>
#include <string.h>

#include "glprog.h"

/* The classic 5x7 font, ASCII 32..126, one byte per column, bit 0 the top
 * row; a 96th entry is a full block, used for the background box. */
static const uint8_t font[96][5] = {
    {0x00, 0x00, 0x00, 0x00, 0x00}, {0x00, 0x00, 0x5F, 0x00, 0x00}, /* space ! */
    {0x00, 0x07, 0x00, 0x07, 0x00}, {0x14, 0x7F, 0x14, 0x7F, 0x14}, /* " # */
    {0x24, 0x2A, 0x7F, 0x2A, 0x12}, {0x23, 0x13, 0x08, 0x64, 0x62}, /* $ % */
    {0x36, 0x49, 0x55, 0x22, 0x50}, {0x00, 0x05, 0x03, 0x00, 0x00}, /* & ' */
    {0x00, 0x1C, 0x22, 0x41, 0x00}, {0x00, 0x41, 0x22, 0x1C, 0x00}, /* ( ) */
    {0x08, 0x2A, 0x1C, 0x2A, 0x08}, {0x08, 0x08, 0x3E, 0x08, 0x08}, /* * + */
    {0x00, 0x50, 0x30, 0x00, 0x00}, {0x08, 0x08, 0x08, 0x08, 0x08}, /* , - */
    {0x00, 0x60, 0x60, 0x00, 0x00}, {0x20, 0x10, 0x08, 0x04, 0x02}, /* . / */
    {0x3E, 0x51, 0x49, 0x45, 0x3E}, {0x00, 0x42, 0x7F, 0x40, 0x00}, /* 0 1 */
    {0x42, 0x61, 0x51, 0x49, 0x46}, {0x21, 0x41, 0x45, 0x4B, 0x31}, /* 2 3 */
    {0x18, 0x14, 0x12, 0x7F, 0x10}, {0x27, 0x45, 0x45, 0x45, 0x39}, /* 4 5 */
    {0x3C, 0x4A, 0x49, 0x49, 0x30}, {0x01, 0x71, 0x09, 0x05, 0x03}, /* 6 7 */
    {0x36, 0x49, 0x49, 0x49, 0x36}, {0x06, 0x49, 0x49, 0x29, 0x1E}, /* 8 9 */
    {0x00, 0x36, 0x36, 0x00, 0x00}, {0x00, 0x56, 0x36, 0x00, 0x00}, /* : ; */
    {0x08, 0x14, 0x22, 0x41, 0x00}, {0x14, 0x14, 0x14, 0x14, 0x14}, /* < = */
    {0x00, 0x41, 0x22, 0x14, 0x08}, {0x02, 0x01, 0x51, 0x09, 0x06}, /* > ? */
    {0x32, 0x49, 0x79, 0x41, 0x3E}, {0x7E, 0x11, 0x11, 0x11, 0x7E}, /* @ A */
    {0x7F, 0x49, 0x49, 0x49, 0x36}, {0x3E, 0x41, 0x41, 0x41, 0x22}, /* B C */
    {0x7F, 0x41, 0x41, 0x22, 0x1C}, {0x7F, 0x49, 0x49, 0x49, 0x41}, /* D E */
    {0x7F, 0x09, 0x09, 0x09, 0x01}, {0x3E, 0x41, 0x49, 0x49, 0x7A}, /* F G */
    {0x7F, 0x08, 0x08, 0x08, 0x7F}, {0x00, 0x41, 0x7F, 0x41, 0x00}, /* H I */
    {0x20, 0x40, 0x41, 0x3F, 0x01}, {0x7F, 0x08, 0x14, 0x22, 0x41}, /* J K */
    {0x7F, 0x40, 0x40, 0x40, 0x40}, {0x7F, 0x02, 0x0C, 0x02, 0x7F}, /* L M */
    {0x7F, 0x04, 0x08, 0x10, 0x7F}, {0x3E, 0x41, 0x41, 0x41, 0x3E}, /* N O */
    {0x7F, 0x09, 0x09, 0x09, 0x06}, {0x3E, 0x41, 0x51, 0x21, 0x5E}, /* P Q */
    {0x7F, 0x09, 0x19, 0x29, 0x46}, {0x46, 0x49, 0x49, 0x49, 0x31}, /* R S */
    {0x01, 0x01, 0x7F, 0x01, 0x01}, {0x3F, 0x40, 0x40, 0x40, 0x3F}, /* T U */
    {0x1F, 0x20, 0x40, 0x20, 0x1F}, {0x3F, 0x40, 0x38, 0x40, 0x3F}, /* V W */
    {0x63, 0x14, 0x08, 0x14, 0x63}, {0x07, 0x08, 0x70, 0x08, 0x07}, /* X Y */
    {0x61, 0x51, 0x49, 0x45, 0x43}, {0x00, 0x7F, 0x41, 0x41, 0x00}, /* Z [ */
    {0x02, 0x04, 0x08, 0x10, 0x20}, {0x00, 0x41, 0x41, 0x7F, 0x00}, /* \ ] */
    {0x04, 0x02, 0x01, 0x02, 0x04}, {0x40, 0x40, 0x40, 0x40, 0x40}, /* ^ _ */
    {0x00, 0x01, 0x02, 0x04, 0x00}, {0x20, 0x54, 0x54, 0x54, 0x78}, /* ` a */
    {0x7F, 0x48, 0x44, 0x44, 0x38}, {0x38, 0x44, 0x44, 0x44, 0x20}, /* b c */
    {0x38, 0x44, 0x44, 0x48, 0x7F}, {0x38, 0x54, 0x54, 0x54, 0x18}, /* d e */
    {0x08, 0x7E, 0x09, 0x01, 0x02}, {0x0C, 0x52, 0x52, 0x52, 0x3E}, /* f g */
    {0x7F, 0x08, 0x04, 0x04, 0x78}, {0x00, 0x44, 0x7D, 0x40, 0x00}, /* h i */
    {0x20, 0x40, 0x44, 0x3D, 0x00}, {0x7F, 0x10, 0x28, 0x44, 0x00}, /* j k */
    {0x00, 0x41, 0x7F, 0x40, 0x00}, {0x7C, 0x04, 0x18, 0x04, 0x78}, /* l m */
    {0x7C, 0x08, 0x04, 0x04, 0x78}, {0x38, 0x44, 0x44, 0x44, 0x38}, /* n o */
    {0x7C, 0x14, 0x14, 0x14, 0x08}, {0x08, 0x14, 0x14, 0x18, 0x7C}, /* p q */
    {0x7C, 0x08, 0x04, 0x04, 0x08}, {0x48, 0x54, 0x54, 0x54, 0x20}, /* r s */
    {0x04, 0x3F, 0x44, 0x40, 0x20}, {0x3C, 0x40, 0x40, 0x20, 0x7C}, /* t u */
    {0x1C, 0x20, 0x40, 0x20, 0x1C}, {0x3C, 0x40, 0x30, 0x40, 0x3C}, /* v w */
    {0x44, 0x28, 0x10, 0x28, 0x44}, {0x0C, 0x50, 0x50, 0x50, 0x3C}, /* x y */
    {0x44, 0x64, 0x54, 0x4C, 0x44}, {0x00, 0x08, 0x36, 0x41, 0x00}, /* z { */
    {0x00, 0x00, 0x7F, 0x00, 0x00}, {0x00, 0x41, 0x36, 0x08, 0x00}, /* | } */
    {0x08, 0x04, 0x08, 0x10, 0x08}, {0xFF, 0xFF, 0xFF, 0xFF, 0xFF}, /* ~ block */
};

#define CELL_W 6 /* 5 columns + 1 of spacing */
#define CELL_H 9 /* 7 rows + 2 of leading */
#define BLOCK 95 /* the full-block cell */

const uint8_t *mts_hud_glyph(unsigned char c)
{
    return font[c >= 32 && c <= 126 ? c - 32 : '?' - 32];
}

struct mts_hud {
    mts_render_context *ctx;
    GLuint program, vao, vbo, tex;
    GLint u_size, u_font;
    float *verts;
    size_t vert_cap; /* quads */
};

static const char *vs_src =
    "#version 300 es\n"
    "layout(location = 0) in vec2 a_pos;\n" /* pixels, top left origin */
    "layout(location = 1) in vec2 a_uv;\n"  /* atlas texels */
    "layout(location = 2) in vec4 a_color;\n"
    "uniform vec2 u_size;\n"
    "out vec2 v_uv;\n"
    "out vec4 v_color;\n"
    "void main() {\n"
    "    v_uv = a_uv;\n"
    "    v_color = a_color;\n"
    "    vec2 ndc = a_pos / u_size * 2.0 - 1.0;\n"
    "    gl_Position = vec4(ndc.x, -ndc.y, 0.0, 1.0);\n"
    "}\n";

/* texelFetch: exact font pixels at any scale, no filtering to tune */
static const char *fs_src =
    "#version 300 es\n"
    "precision mediump float;\n"
    "in vec2 v_uv;\n"
    "in vec4 v_color;\n"
    "uniform sampler2D u_font;\n"
    "out vec4 o_color;\n"
    "void main() {\n"
    "    float a = texelFetch(u_font, ivec2(floor(v_uv)), 0).r;\n"
    "    o_color = vec4(v_color.rgb, v_color.a * a);\n"
    "}\n";

static mts_result gl_failed(mts_error *err, const char *what)
{
    GLenum e = glGetError();
    if (e == GL_NO_ERROR)
        return MTS_OK;
    while (glGetError() != GL_NO_ERROR)
        ;
    return mts_error_set(err, MTS_ERR_INTERNAL, "HUD: GL error 0x%04x %s", (unsigned)e, what);
}

void mts_hud_destroy(mts_hud *h)
{
    if (!h)
        return;
    if (mts_render_context_make_current(h->ctx, NULL) == MTS_OK) {
        if (h->program)
            glDeleteProgram(h->program);
        if (h->vao)
            glDeleteVertexArrays(1, &h->vao);
        if (h->vbo)
            glDeleteBuffers(1, &h->vbo);
        if (h->tex)
            glDeleteTextures(1, &h->tex);
        glGetError();
    }
    free(h->verts);
    free(h);
}

mts_result mts_hud_create(mts_render_context *ctx, mts_hud **out, mts_error *err)
{
    *out = NULL;
    mts_result rc = mts_render_context_make_current(ctx, err);
    if (rc != MTS_OK)
        return rc;
    mts_hud *h = calloc(1, sizeof *h);
    if (!h)
        return mts_error_set(err, MTS_ERR_NOMEM, "HUD");
    h->ctx = ctx;
    glGetError();
    if ((rc = mts_glprog_build("HUD", &vs_src, 1, &fs_src, 1, &h->program, err)) != MTS_OK)
        goto fail;
    h->u_size = glGetUniformLocation(h->program, "u_size");
    h->u_font = glGetUniformLocation(h->program, "u_font");

    /* the atlas: one row of 96 cells, 255 where a font pixel is lit */
    enum { AW = 96 * CELL_W, AH = CELL_H };
    static uint8_t atlas[AH][AW];
    memset(atlas, 0, sizeof atlas);
    for (int g = 0; g < 96; g++)
        for (int c = 0; c < CELL_W; c++)
            for (int r = 0; r < CELL_H; r++) {
                int lit = g == BLOCK || (c < 5 && r < 8 && (font[g][c] >> r & 1));
                atlas[r][g * CELL_W + c] = lit ? 255 : 0;
            }
    glGenTextures(1, &h->tex);
    glBindTexture(GL_TEXTURE_2D, h->tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R8, AW, AH, 0, GL_RED, GL_UNSIGNED_BYTE, atlas);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glBindTexture(GL_TEXTURE_2D, 0);

    glGenVertexArrays(1, &h->vao);
    glGenBuffers(1, &h->vbo);
    glBindVertexArray(h->vao);
    glBindBuffer(GL_ARRAY_BUFFER, h->vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 8 * sizeof(float), (const void *)0);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, 8 * sizeof(float),
                          (const void *)(2 * sizeof(float)));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, 8 * sizeof(float),
                          (const void *)(4 * sizeof(float)));
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    if ((rc = gl_failed(err, "creating the HUD")) != MTS_OK)
        goto fail;
    *out = h;
    return MTS_OK;
fail:
    mts_hud_destroy(h);
    return rc;
}

/* Appends a quad: pixels x0,y0..x1,y1, atlas texels u0,v0..u1,v1. */
static float *quad(float *v, float x0, float y0, float x1, float y1, float u0, float v0,
                   float u1, float v1, const float rgba[4])
{
    const float c[6][4] = {{x0, y0, u0, v0}, {x1, y0, u1, v0}, {x1, y1, u1, v1},
                           {x0, y0, u0, v0}, {x1, y1, u1, v1}, {x0, y1, u0, v1}};
    for (int i = 0; i < 6; i++) {
        memcpy(v, c[i], 4 * sizeof(float));
        memcpy(v + 4, rgba, 4 * sizeof(float));
        v += 8;
    }
    return v;
}

mts_result mts_hud_draw(mts_hud *h, const char *text, uint32_t fb_w, uint32_t fb_h, int scale,
                        mts_error *err)
{
    if (!h || !text || fb_w == 0 || fb_h == 0)
        return mts_error_set(err, MTS_ERR_ARG, "HUD: nothing to draw on");
    if (scale < 1)
        scale = 1;
    if (scale > 8)
        scale = 8;
    mts_result rc = mts_render_context_make_current(h->ctx, err);
    if (rc != MTS_OK)
        return rc;
    size_t chars = strlen(text), lines = 1, cols = 0, col = 0;
    for (size_t i = 0; i < chars; i++) {
        if (text[i] == '\n') {
            lines++;
            col = 0;
        } else if (++col > cols) {
            cols = col;
        }
    }
    size_t need = chars + 1; /* + the box */
    if (need > h->vert_cap) {
        float *nv = realloc(h->verts, need * 6 * 8 * sizeof(float));
        if (!nv)
            return mts_error_set(err, MTS_ERR_NOMEM, "HUD: %zu characters", chars);
        h->verts = nv;
        h->vert_cap = need;
    }
    const float box[4] = {0.0f, 0.0f, 0.0f, 0.55f}, ink[4] = {1.0f, 1.0f, 0.85f, 1.0f};
    float s = (float)scale, pad = 4.0f * s;
    float *v = h->verts;
    /* the block cell's middle texel: lit everywhere */
    float bu = (float)(BLOCK * CELL_W) + 2.5f, bv = 4.5f;
    v = quad(v, 0, 0, 2 * pad + (float)(cols * CELL_W) * s, 2 * pad + (float)(lines * CELL_H) * s,
             bu, bv, bu, bv, box);
    float x = pad, y = pad;
    for (size_t i = 0; i < chars; i++) {
        unsigned char ch = (unsigned char)text[i];
        if (ch == '\n') {
            x = pad;
            y += CELL_H * s;
            continue;
        }
        int g = ch >= 32 && ch <= 126 ? ch - 32 : '?' - 32;
        if (ch != ' ') {
            float u0 = (float)(g * CELL_W);
            v = quad(v, x, y, x + 5 * s, y + 7 * s, u0, 0, u0 + 5, 7, ink);
        }
        x += CELL_W * s;
    }
    GLsizei count = (GLsizei)((v - h->verts) / 8);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(h->program);
    glUniform2f(h->u_size, (float)fb_w, (float)fb_h);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, h->tex);
    glUniform1i(h->u_font, 0);
    glBindVertexArray(h->vao);
    glBindBuffer(GL_ARRAY_BUFFER, h->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)count * 8 * sizeof(float)), h->verts,
                 GL_STREAM_DRAW);
    glDrawArrays(GL_TRIANGLES, 0, count);
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    glBindTexture(GL_TEXTURE_2D, 0);
    glDisable(GL_BLEND);
    return gl_failed(err, "drawing the HUD");
}

mts_result mts_hud_clear(mts_hud *h, const float rgb[3], uint32_t fb_w, uint32_t fb_h,
                         mts_error *err)
{
    mts_result rc = mts_render_context_make_current(h->ctx, err);
    if (rc != MTS_OK)
        return rc;
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, (GLsizei)fb_w, (GLsizei)fb_h);
    glClearColor(rgb[0], rgb[1], rgb[2], 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    return gl_failed(err, "clearing the window");
}
