/* What a renderer is given (render.h): the options' defaults and the
 * layout, from a runtime and as checked before any GL is made. No GL here. */
#include "render.h"
#include "render_internal.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "camera.h"

void mts_render_options_default(mts_render_options *o)
{
    memset(o, 0, sizeof *o);
    o->width = 512;
    o->height = 512;
    o->camera.yaw_deg = 30.0f;
    o->camera.pitch_deg = 20.0f;
    o->camera.zoom = 1.0f;
    o->camera.fov_y_deg = 35.0f;
    mts_camera_default_style(&o->style);
}

static int all_zero(const float *v, int n)
{
    for (int i = 0; i < n; i++)
        if (v[i] != 0)
            return 0;
    return 1;
}

/* A zeroed field where zero is no usable value takes the default (render.h,
 * mts_render_options_default). */
void mts__render_style_defaults(mts_render_style *s)
{
    mts_render_options d;
    mts_render_options_default(&d);
    if (all_zero(s->background, 4))
        memcpy(s->background, d.style.background, sizeof s->background);
    if (all_zero(s->color, 3))
        memcpy(s->color, d.style.color, sizeof s->color);
    if (all_zero(s->wire_color, 3))
        memcpy(s->wire_color, d.style.wire_color, sizeof s->wire_color);
    if (s->ambient == 0)
        s->ambient = d.style.ambient;
    else if (s->ambient < 0)
        s->ambient = 0;
}

void mts_render_layout_from_lod(const mts_lod *lod, mts_render_layout *l)
{
    memset(l, 0, sizeof *l);
    l->vertex_capacity = lod->model->vertex_count;
    l->strip_count = lod->strip_count;
    l->slot = lod->slot;
    l->room = lod->room;
    memcpy(l->bbox_min, lod->model->bbox_min, sizeof l->bbox_min);
    memcpy(l->bbox_max, lod->model->bbox_max, sizeof l->bbox_max);
    l->colors = (lod->model->flags & MTS_MODEL_COLORS) != 0;
}

mts_result mts__render_check_layout(const mts_render_layout *l, mts_error *err)
{
    if (!l->slot)
        return mts_error_set(err, MTS_ERR_ARG, "render: layout without slots");
    if (l->vertex_capacity == 0)
        return mts_error_set(err, MTS_ERR_ARG, "render: layout with no vertices");
    if (l->slot[0] != 0)
        return mts_error_set(err, MTS_ERR_ARG, "render: layout slot[0] is %u, not 0", l->slot[0]);
    for (uint32_t s = 0; s < l->strip_count; s++)
        if (l->slot[s + 1] < l->slot[s])
            return mts_error_set(err, MTS_ERR_ARG, "render: layout slot %u ends before it starts",
                                 s);
    for (int i = 0; i < 3; i++)
        if (!isfinite(l->bbox_min[i]) || !isfinite(l->bbox_max[i]) ||
            l->bbox_min[i] > l->bbox_max[i])
            return mts_error_set(err, MTS_ERR_ARG, "render: layout bounding box is not a box");
    return MTS_OK;
}
