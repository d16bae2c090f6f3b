/* The look every client draws with -- the camera, the light, the colours
 * (by strip too) and the shaders' GLSL -- GL-free, so that the native
 * renderer (render.c) and the browser page (web/) frame, light and colour
 * a model alike. The camera: perspective,
 * looking at the bounding box's centre from the direction given by yaw
 * (about +Y, 0 = from +Z, positive turns towards +X) and pitch (positive
 * looks from above), at the distance where the box's bounding sphere fits
 * the narrower field of view with a 10% margin, divided by zoom. */
#ifndef MTS_CAMERA_H
#define MTS_CAMERA_H

#include <stdint.h>

typedef struct mts_render_camera {
    float yaw_deg, pitch_deg; /* pitch is clamped to [-89, 89] */
    float zoom;               /* > 0; 1 frames the bounding sphere */
    float fov_y_deg;          /* vertical field of view, in (1, 170) */
} mts_render_camera;

/* Column-major matrices, as GL takes them. */
typedef struct mts_camera_view {
    float mvp[16];   /* projection x view (the model matrix is the identity) */
    float normal[9]; /* the view's rotation, for normals */
    float eye[3], dir[3];
} mts_camera_view;

typedef struct mts_render_style {
    float background[4]; /* RGBA in [0,1] */
    float color[3];      /* the surface colour */
    float ambient;       /* [0,1]: ambient share of the lighting */
    int color_by_strip;  /* each strip its own colour (draws strip by strip) */
    int show_back_faces; /* 0: clockwise triangles are culled */
    /* Draw the triangles' edges over the surface (hidden-line wireframe):
     * the edges given by mts_render_update_wireframe as GL_LINES, the
     * surface pushed back with polygon offset so that visible edges win the
     * depth test. GLES has no polygon mode, and a barycentric shader needs
     * per-corner attributes that shared strip vertices cannot carry. */
    int wireframe;
    float wire_color[3];
    /* Shade each triangle by its own plane, from the screen-space slopes of
     * its positions, ignoring the vertex normals: for a model whose stream
     * carries none (its source had none; PROTOCOL.md, MODEL_INFO flags), so
     * every level is lit as the faces it has. */
    int flat_shading;
} mts_render_style;

/* The defaults: dark blue-grey background, light grey surface, ambient
 * 0.25, culling on, no wireframe (dark edges when turned on), smooth. */
void mts_camera_default_style(mts_render_style *s);

/* The shaders' GLSL ES 3.00 bodies, to follow "#version 300 es", a
 * "#define MORPH 0" or 1 line and a "#define COLORS 0" or 1 line (both
 * defined: GLSL ES has no 0 for an undefined name). Attributes: 0 position,
 * 1 normal (2, 3 the morph's from-position and from-normal), with COLORS 4
 * the vertex's colour (and 5 its morph's from-colour), RGBA8 normalized.
 * Uniforms: u_mvp, u_normal (the camera's matrices), u_color, u_light
 * (mts_camera_light), u_ambient, u_flat (shade by face slopes, for streams
 * without normals), with MORPH u_morph (the vertex ids morphing, [x, y))
 * and u_morph_t, with COLORS u_vertex_color (1: the vertex colour is the
 * albedo; 0: u_color is, for colour by strip and the wireframe's edges).
 *
 * Shading treats colours as they are stored: the grey (u_color) and a
 * vertex colour (8-bit sRGB) are multiplied by the Lambert-plus-ambient
 * factor and written to an RGBA8 framebuffer that does no sRGB encoding,
 * so a fully lit vertex shows its file's bytes, a colour equal to the grey
 * draws the grey's picture, and the page (a WebGL2 canvas, also unencoded)
 * draws the same values. Converting to linear light for the product and
 * back would brighten every shadow and change every existing picture, the
 * grey's included; colours between vertices are interpolated in the same
 * stored values, as most mesh viewers do. */
extern const char mts_camera_vertex_glsl[];
extern const char mts_camera_fragment_glsl[];

/* The view of the box bbox_min..bbox_max for a viewport of aspect
 * width / height (non-positive: 1). Out-of-range camera values take the
 * defaults or are clamped, as render.h says. */
void mts_camera_compute(const float bbox_min[3], const float bbox_max[3],
                        const mts_render_camera *cam, float aspect, mts_camera_view *out);

/* The direction towards the light, in view space, unit length: above-left
 * of the camera, in front. */
void mts_camera_light(float l[3]);

/* Strip s's colour when drawn by strip: hue by the golden ratio. */
void mts_camera_strip_color(uint32_t s, float rgb[3]);

#endif
