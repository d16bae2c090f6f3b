/* LOD policies: which level to draw, from what was received, the camera or
 * the measured frame time (paper 000, section 1: "the distance of the object
 * from the viewer; the projected area of the object on the display"; and a
 * frame-time budget). Pure: no GL, no I/O, no allocation; the caller measures
 * and draws. Formulas are at the top of lodpolicy.c.
 *
 *   received  the highest level received (what mts-client always drew)
 *   distance  triangles = full * min(1, (d0 / d)^2), d0 the distance at which
 *             the renderer frames the model (its bounding sphere fills the
 *             narrower field of view with the renderer's 10% margin)
 *   area      triangles = projected area of the bounding sphere in pixels
 *             (clipped to the window) / pixels_per_triangle
 *   budget    the largest level whose predicted frame time fits 1000/fps ms,
 *             from a moving estimate of the measured frame time, with
 *             hysteresis
 *
 * Every choice is a level in [0, available]; triangles map to levels with
 * mts_model_level_for_triangles (model->level_triangles rises with the level:
 * every split adds triangles). A streaming client's model has no
 * level_triangles (MODEL_INFO carries only the full and stop counts): the
 * policy then counts triangles linearly between the base and the full level
 * (a split of an interior vertex adds exactly two), from the base strips and
 * base + 2 * levels until mts_lod_policy_set_counts gives the real ends. */
#ifndef MTS_LODPOLICY_H
#define MTS_LODPOLICY_H

#include <stdint.h>

#include "model.h"

typedef enum mts_lod_policy_kind {
    MTS_LOD_POLICY_RECEIVED = 0,
    MTS_LOD_POLICY_DISTANCE,
    MTS_LOD_POLICY_AREA,
    MTS_LOD_POLICY_BUDGET
} mts_lod_policy_kind;

/* Zero-initialised means the defaults. */
typedef struct mts_lod_policy_options {
    mts_lod_policy_kind kind;
    double fps;                 /* budget: target frames per second; 0 = 60 */
    double pixels_per_triangle; /* area: target screen pixels per triangle; 0 = 2 */
    double headroom;            /* budget: aim at this share of 1000/fps ms; 0 = 0.9 */
    double hysteresis;          /* budget: relative triangle change needed to move up
                                   (and, within budget, down); 0 = 0.1 */
    double smoothing;           /* budget: weight of the newest frame in the moving
                                   estimate, (0, 1]; 0 = 0.25 */
} mts_lod_policy_options;

/* The camera as the policies see it. */
typedef struct mts_lod_view {
    float distance; /* eye to the model's bounding-sphere centre, model units */
    float fov_y;    /* vertical field of view, radians */
    int width, height; /* window in pixels */
} mts_lod_view;

typedef struct mts_lod_policy {
    mts_lod_policy_options opt; /* defaults filled in */
    const mts_model *model;
    float radius;               /* bounding sphere: half the box diagonal */
    /* without model->level_triangles: triangles(l) = base + (full - base) l / n */
    uint32_t base_triangles, full_triangles;
    /* budget state */
    double ms_per_triangle;     /* moving estimate of frame ms / triangles drawn; 0 = none */
    uint32_t level;             /* the last level chosen */
    int chosen;                 /* a level has been chosen before */
} mts_lod_policy;

void mts_lod_policy_init(mts_lod_policy *p, const mts_lod_policy_options *o,
                         const mts_model *m);

/* The triangle counts at the base and the full level, for a model without
 * level_triangles (e.g. a streaming client's: MODEL_INFO's triangles); a
 * model with them ignores this. */
void mts_lod_policy_set_counts(mts_lod_policy *p, uint32_t base_triangles,
                               uint32_t full_triangles);

/* Triangles at a level as the policy counts them. */
double mts_lod_policy_level_triangles(const mts_lod_policy *p, uint32_t level);

/* The level to draw next, in [0, available] (available is clamped to the
 * model's level count). view may be NULL for received and budget (distance
 * and area then choose available). last_frame_ms is the time of the frame
 * drawn at the previous choice (<= 0: none measured); only budget uses it. */
uint32_t mts_lod_policy_choose(mts_lod_policy *p, uint32_t available, const mts_lod_view *view,
                               double last_frame_ms);

/* Triangles the camera policies ask for at a view (full when the eye is in
 * the bounding sphere); for tests and reports. */
double mts_lod_policy_view_triangles(const mts_lod_policy *p, const mts_lod_view *view);

/* The distance (model units) at which the renderer frames the model for a
 * view's field of view and window shape: d0 of the distance policy. */
double mts_lod_policy_frame_distance(const mts_lod_policy *p, const mts_lod_view *view);

/* Before a stream, so that its stop point can be asked for: the triangles
 * distance and area want with the camera at `distance` times the framing
 * distance, for a model of full_triangles (a MODELS listing gives it), a
 * view of this field of view (radians) and window. The framed bounding
 * sphere's size cancels, so no model is needed: these are the triangles
 * mts_lod_policy_view_triangles gives once the model is in, at the same
 * view. 0 for received and budget, which need what comes (or its frame
 * times). */
double mts_lod_policy_stop_triangles(const mts_lod_policy_options *o, double distance,
                                     float fov_y, int width, int height,
                                     uint32_t full_triangles);

/* "received", "distance", "area", "budget" -> kind; 0 when unknown. */
int mts_lod_policy_parse(const char *name, mts_lod_policy_kind *kind);
const char *mts_lod_policy_name(mts_lod_policy_kind kind);

#endif
