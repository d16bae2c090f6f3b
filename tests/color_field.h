/* A smooth colour field for tests and benches of coloured streams: each
 * vertex's colour a function of its position in the model's box (three
 * sines of different directions and periods), the kind of field a scan's
 * or a painted mesh's colours are locally, without a coloured file. */
#ifndef MTS_TEST_COLOR_FIELD_H
#define MTS_TEST_COLOR_FIELD_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "model.h"

/* Gives m a colour per vertex (replacing any) and MTS_MODEL_COLORS; 0 when
 * out of memory. */
static inline int mts_test_color_field(mts_model *m)
{
    uint8_t *c = malloc((size_t)m->vertex_count * 3 + 1);
    if (!c)
        return 0;
    float side = 0;
    for (int a = 0; a < 3; a++)
        if (m->bbox_max[a] - m->bbox_min[a] > side)
            side = m->bbox_max[a] - m->bbox_min[a];
    if (!(side > 0))
        side = 1;
    for (uint32_t x = 0; x < m->vertex_count; x++) {
        const float *p = m->positions + 3 * (size_t)x;
        const float u = (p[0] - m->bbox_min[0]) / side, v = (p[1] - m->bbox_min[1]) / side,
                    w = (p[2] - m->bbox_min[2]) / side;
        uint8_t *o = c + 3 * (size_t)x;
        o[0] = (uint8_t)lrintf(127.5f + 127.5f * sinf(6.2831853f * (1.5f * u + 0.3f * w)));
        o[1] = (uint8_t)lrintf(127.5f + 127.5f * sinf(6.2831853f * (1.1f * v + 0.7f * u) + 1.f));
        o[2] = (uint8_t)lrintf(127.5f + 127.5f * cosf(6.2831853f * (0.8f * w + 0.5f * v)));
    }
    free(m->colors);
    m->colors = c;
    m->flags |= MTS_MODEL_COLORS;
    return 1;
}

#endif
