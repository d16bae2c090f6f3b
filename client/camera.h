/* The camera every client draws with, and its colours by strip, GL-free so
 * that the native renderer (render.c) and the browser page (web/) frame
 * and colour a model alike. The camera: perspective,
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
