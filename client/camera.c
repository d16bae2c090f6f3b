/* The camera, light, colours and shaders (camera.h): the native
 * renderer's and the browser page's. */
#include "camera.h"

#include <math.h>
#include <string.h>

#define PI_F 3.14159265358979f

static float clampf(float x, float lo, float hi)
{
    return x < lo ? lo : x > hi ? hi : x;
}

/* Column-major 4x4: m[col * 4 + row]. */
static void mat4_mul(float out[16], const float a[16], const float b[16])
{
    float t[16];
    for (int c = 0; c < 4; c++)
        for (int r = 0; r < 4; r++) {
            float s = 0;
            for (int k = 0; k < 4; k++)
                s += a[k * 4 + r] * b[c * 4 + k];
            t[c * 4 + r] = s;
        }
    memcpy(out, t, sizeof t);
}

static void normalize3(float v[3])
{
    float n = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (n > 0) {
        v[0] /= n;
        v[1] /= n;
        v[2] /= n;
    }
}

static void cross3(float o[3], const float a[3], const float b[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

void mts_camera_compute(const float bbox_min[3], const float bbox_max[3],
                        const mts_render_camera *cam, float aspect, mts_camera_view *out)
{
    float center[3], radius = 0;
    for (int i = 0; i < 3; i++) {
        center[i] = 0.5f * (bbox_min[i] + bbox_max[i]);
        float h = 0.5f * (bbox_max[i] - bbox_min[i]);
        radius += h * h;
    }
    radius = sqrtf(radius);
    if (!(radius > 0) || !isfinite(radius))
        radius = 1.0f;
    for (int i = 0; i < 3; i++)
        if (!isfinite(center[i]))
            center[i] = 0;

    float yaw = cam->yaw_deg * PI_F / 180.0f;
    float pitch = clampf(cam->pitch_deg, -89.0f, 89.0f) * PI_F / 180.0f;
    float zoom = cam->zoom > 1e-3f && isfinite(cam->zoom) ? cam->zoom : 1.0f;
    float fovy = clampf(isfinite(cam->fov_y_deg) && cam->fov_y_deg > 0 ? cam->fov_y_deg : 35.0f,
                        1.0f, 170.0f) *
                 PI_F / 180.0f;
    if (!(aspect > 0) || !isfinite(aspect))
        aspect = 1.0f;

    /* the narrower half-angle decides the fit */
    float half = 0.5f * fovy;
    float half_x = atanf(tanf(half) * aspect);
    if (half_x < half)
        half = half_x;
    float dist = 1.1f * radius / sinf(half) / zoom;

    float back[3] = {cosf(pitch) * sinf(yaw), sinf(pitch), cosf(pitch) * cosf(yaw)};
    for (int i = 0; i < 3; i++) {
        out->eye[i] = center[i] + dist * back[i];
        out->dir[i] = -back[i];
    }

    /* view: rows are the camera's right, up and back axes */
    float up0[3] = {0, 1, 0}, right[3], up[3];
    cross3(right, up0, back);
    normalize3(right);
    cross3(up, back, right);
    float view[16] = {0};
    for (int i = 0; i < 3; i++) {
        view[i * 4 + 0] = right[i];
        view[i * 4 + 1] = up[i];
        view[i * 4 + 2] = back[i];
    }
    view[12] = -(right[0] * out->eye[0] + right[1] * out->eye[1] + right[2] * out->eye[2]);
    view[13] = -(up[0] * out->eye[0] + up[1] * out->eye[1] + up[2] * out->eye[2]);
    view[14] = -(back[0] * out->eye[0] + back[1] * out->eye[1] + back[2] * out->eye[2]);
    view[15] = 1;

    float znear = dist - 1.05f * radius;
    if (znear < dist * 1e-3f)
        znear = dist * 1e-3f;
    float zfar = dist + 1.05f * radius;
    float f = 1.0f / tanf(0.5f * fovy);
    float proj[16] = {0};
    proj[0] = f / aspect;
    proj[5] = f;
    proj[10] = (zfar + znear) / (znear - zfar);
    proj[11] = -1;
    proj[14] = 2 * zfar * znear / (znear - zfar);
    mat4_mul(out->mvp, proj, view);

    /* normals: the view's rotation (the model matrix is the identity) */
    for (int c = 0; c < 3; c++)
        for (int rr = 0; rr < 3; rr++)
            out->normal[c * 3 + rr] = view[c * 4 + rr];
}


/* A distinct colour per strip: hue by the golden ratio. */
void mts_camera_strip_color(uint32_t s, float rgb[3])
{
    float h = fmodf((float)s * 0.61803398875f, 1.0f) * 6.0f;
    float sat = 0.6f, val = 0.95f;
    int i = (int)h;
    float f = h - (float)i;
    float p = val * (1 - sat), q = val * (1 - sat * f), t = val * (1 - sat * (1 - f));
    switch (i % 6) {
    case 0: rgb[0] = val; rgb[1] = t; rgb[2] = p; break;
    case 1: rgb[0] = q; rgb[1] = val; rgb[2] = p; break;
    case 2: rgb[0] = p; rgb[1] = val; rgb[2] = t; break;
    case 3: rgb[0] = p; rgb[1] = q; rgb[2] = val; break;
    case 4: rgb[0] = t; rgb[1] = p; rgb[2] = val; break;
    default: rgb[0] = val; rgb[1] = p; rgb[2] = q; break;
    }
}

void mts_camera_light(float l[3])
{
    l[0] = -0.45f;
    l[1] = 0.6f;
    l[2] = 0.66f;
    normalize3(l);
}

void mts_camera_default_style(mts_render_style *s)
{
    memset(s, 0, sizeof *s);
    s->background[0] = 0.12f;
    s->background[1] = 0.14f;
    s->background[2] = 0.18f;
    s->background[3] = 1.0f;
    s->color[0] = 0.85f;
    s->color[1] = 0.82f;
    s->color[2] = 0.76f;
    s->ambient = 0.25f;
    s->color_by_strip = 0;
    s->show_back_faces = 0;
    s->wireframe = 0;
    s->flat_shading = 0;
    s->wire_color[0] = 0.08f;
    s->wire_color[1] = 0.09f;
    s->wire_color[2] = 0.12f;
}

/* ---- shaders (compiled with MORPH 0 and 1, and COLORS 0 or 1) --------- */

const char mts_camera_vertex_glsl[] =
    "layout(location = 0) in vec3 a_position;\n"
    "layout(location = 1) in vec3 a_normal;\n"
    "uniform mat4 u_mvp;\n"
    "uniform mat3 u_normal;\n"
    "out vec3 v_normal;\n"
    "out vec3 v_view;\n" /* rotated into view space: slopes for flat shading */
    "#if COLORS\n"
    "layout(location = 4) in vec4 a_color;\n" /* 8-bit sRGB values, normalized */
    "out vec3 v_color;\n"
    "#endif\n"
    "#if MORPH\n"
    "layout(location = 2) in vec3 a_from_position;\n"
    "layout(location = 3) in vec3 a_from_normal;\n"
    "#if COLORS\n"
    "layout(location = 5) in vec4 a_from_color;\n"
    "#endif\n"
    "uniform uvec2 u_morph;\n" /* the vertex ids morphing: [x, y) */
    "uniform float u_morph_t;\n"
    "#endif\n"
    "void main() {\n"
    "    vec3 p = a_position, n = a_normal;\n"
    "#if COLORS\n"
    "    vec3 c = a_color.rgb;\n"
    "#endif\n"
    "#if MORPH\n"
    "    uint id = uint(gl_VertexID);\n" /* the index fetched */
    "    if (id >= u_morph.x && id < u_morph.y) {\n"
    "        p = mix(a_from_position, a_position, u_morph_t);\n"
    "        n = mix(a_from_normal, a_normal, u_morph_t);\n"
    "#if COLORS\n"
    "        c = mix(a_from_color.rgb, a_color.rgb, u_morph_t);\n"
    "#endif\n"
    "    }\n"
    "#endif\n"
    "#if COLORS\n"
    "    v_color = c;\n"
    "#endif\n"
    "    v_normal = u_normal * n;\n"
    "    v_view = u_normal * p;\n"
    "    gl_Position = u_mvp * vec4(p, 1.0);\n"
    "}\n";

/* The albedo times the light, in the framebuffer's values as they are: the
 * grey and the vertex colours are both taken as the 8-bit sRGB values they
 * are written as, not converted to linear light and back (camera.h says
 * why). */
const char mts_camera_fragment_glsl[] =
    "precision highp float;\n"
    "in vec3 v_normal;\n"
    "in vec3 v_view;\n"
    "uniform bool u_flat;\n"
    "uniform vec3 u_color;\n"
    "uniform vec3 u_light;\n" /* unit, towards the light, view space */
    "uniform float u_ambient;\n"
    "#if COLORS\n"
    "in vec3 v_color;\n"
    "uniform bool u_vertex_color;\n" /* 0: u_color (by strip, the wireframe's edges) */
    "#endif\n"
    "out vec4 o_color;\n"
    "void main() {\n"
    /* screen x and y slopes of a face span its plane; their cross product
     * faces the viewer (derivatives taken in uniform control flow) */
    "    vec3 face = cross(dFdx(v_view), dFdy(v_view));\n"
    "    vec3 n = u_flat ? face : v_normal;\n"
    "    float len = length(n);\n"
    /* a zero normal (a vertex of zero-area faces only) gets half light */
    "    float d = len > 1e-12 ? max(dot(n / len, u_light), 0.0) : 0.5;\n"
    "    vec3 albedo = u_color;\n"
    "#if COLORS\n"
    "    if (u_vertex_color)\n"
    "        albedo = v_color;\n"
    "#endif\n"
    "    o_color = vec4(albedo * (u_ambient + (1.0 - u_ambient) * d), 1.0);\n"
    "}\n";
