/* LOD policies (lodpolicy.h). Paper 000 (Belmonte et al., "Multiresolution
 * triangle strips", section 1) lists the usual criteria for choosing a level
 * of detail after Luebke et al. [14]: the distance of the object from the
 * viewer and the projected area of the object on the display (eccentricity
 * and importance need a scene, not one model), and quotes Clark [5]: "It
 * makes no sense to use 500 polygons in describing an object if it covers
 * only 20 raster units of the display" -- triangles should follow the pixels
 * the object covers. Papers 000 and 002 drive their walkthroughs with
 * distance (the model moving away from the viewer).
 *
 * distance: triangles = full * min(1, (d0 / d)^2). The projected area of an
 * object falls as 1/d^2 under perspective, so keeping triangles per covered
 * pixel constant (Clark) gives the square law; d0 is where the renderer
 * frames the model (render.c: 1.1 * r / sin(narrower half field of view), r
 * the bounding sphere's radius), so the framed model is drawn in full and a
 * model twice as far away with a quarter of the triangles. It ignores the
 * window size on purpose: the same scene, the same levels, on any screen.
 *
 * area: triangles = A / pixels_per_triangle, A the bounding sphere's
 * projected disc, pi * rho^2 with rho = (H / 2) * tan(asin(r / d)) /
 * tan(fov_y / 2) pixels (the exact silhouette radius of a sphere seen from
 * distance d on the view axis), clipped to the window's W * H pixels. A
 * bigger window therefore never asks for fewer triangles.
 *
 * budget: keeps the frame time under 1000/fps ms. Frame time is modelled as
 * a + b * T for T triangles (a: clear, readback, fixed costs). The policy
 * keeps a moving average e of the measured ms per triangle drawn, (a + b T)
 * / T, and asks for T' = h * B / e (B the budget, h the headroom). Without
 * the smoothing that is the iteration T' = hB T / (a + b T), whose fixed
 * point is exactly T* = (hB - a) / b (predicted time hB, inside the budget)
 * and whose slope there is a / (hB) < 1 whenever the budget can be met at
 * all, so it converges without overshoot; when a >= hB no level fits and it
 * falls to level 0. Hysteresis: the level moves only when the new target
 * differs from the current triangles by more than the band, except that a
 * frame over the budget moves down at once. Since h * (1 + band) < 1 with the
 * defaults (0.9 * 1.1 = 0.99), a level left standing inside the band is
 * still predicted within the budget. The first choice, with nothing
 * measured, is what was received. */
#include "lodpolicy.h"

#include <math.h>
#include <string.h>

#include "strips.h"

/* render.c frames the bounding sphere with this margin */
#define MTS_LOD_FRAME_MARGIN 1.1

static const char *const policy_names[] = {"received", "distance", "area", "budget"};

int mts_lod_policy_parse(const char *name, mts_lod_policy_kind *kind)
{
    for (int i = 0; i < 4; i++)
        if (name && !strcmp(name, policy_names[i])) {
            *kind = (mts_lod_policy_kind)i;
            return 1;
        }
    return 0;
}

const char *mts_lod_policy_name(mts_lod_policy_kind kind)
{
    return (unsigned)kind < 4 ? policy_names[kind] : "unknown";
}

void mts_lod_policy_init(mts_lod_policy *p, const mts_lod_policy_options *o, const mts_model *m)
{
    memset(p, 0, sizeof *p);
    if (o)
        p->opt = *o;
    if (!(p->opt.fps > 0) || !isfinite(p->opt.fps))
        p->opt.fps = 60;
    if (!(p->opt.pixels_per_triangle > 0) || !isfinite(p->opt.pixels_per_triangle))
        p->opt.pixels_per_triangle = 2;
    if (!(p->opt.headroom > 0) || p->opt.headroom > 1)
        p->opt.headroom = 0.9;
    if (!(p->opt.hysteresis > 0) || p->opt.hysteresis >= 1)
        p->opt.hysteresis = 0.1;
    if (!(p->opt.smoothing > 0) || p->opt.smoothing > 1)
        p->opt.smoothing = 0.25;
    p->model = m;
    double r2 = 0;
    for (int i = 0; i < 3; i++) {
        double h = 0.5 * ((double)m->bbox_max[i] - m->bbox_min[i]);
        r2 += h * h;
    }
    p->radius = (float)sqrt(r2);
    if (!(p->radius > 0) || !isfinite(p->radius))
        p->radius = 1; /* as render.c does for an empty or broken box */
    if (!m->level_triangles) {
        mts_strip_stats st = {0};
        if (m->base.offsets)
            mts_strips_stats(&m->base, &st);
        uint64_t full = st.triangles + 2ull * m->level_count;
        mts_lod_policy_set_counts(p, (uint32_t)st.triangles,
                                  full > UINT32_MAX ? UINT32_MAX : (uint32_t)full);
    }
}

void mts_lod_policy_set_counts(mts_lod_policy *p, uint32_t base_triangles,
                               uint32_t full_triangles)
{
    p->base_triangles = base_triangles;
    p->full_triangles = full_triangles > base_triangles ? full_triangles : base_triangles;
}

double mts_lod_policy_level_triangles(const mts_lod_policy *p, uint32_t level)
{
    const mts_model *m = p->model;
    if (level > m->level_count)
        level = m->level_count;
    if (m->level_triangles)
        return m->level_triangles[level];
    if (!m->level_count)
        return p->full_triangles;
    return p->base_triangles +
           (double)(p->full_triangles - p->base_triangles) * level / m->level_count;
}

static double full_triangles(const mts_lod_policy *p)
{
    return mts_lod_policy_level_triangles(p, p->model->level_count);
}

static int view_usable(const mts_lod_view *v)
{
    return v && isfinite(v->distance) && v->fov_y > 0 && v->fov_y < 3.1f && v->width > 0 &&
           v->height > 0;
}

double mts_lod_policy_frame_distance(const mts_lod_policy *p, const mts_lod_view *v)
{
    if (!view_usable(v))
        return 0;
    double half = 0.5 * v->fov_y;
    double half_x = atan(tan(half) * v->width / v->height);
    if (half_x < half)
        half = half_x;
    return MTS_LOD_FRAME_MARGIN * p->radius / sin(half);
}

double mts_lod_policy_view_triangles(const mts_lod_policy *p, const mts_lod_view *v)
{
    double full = full_triangles(p);
    if (!view_usable(v) || !(v->distance > p->radius))
        return full; /* no camera, or the eye inside the bounding sphere */
    if (p->opt.kind == MTS_LOD_POLICY_DISTANCE) {
        double d0 = mts_lod_policy_frame_distance(p, v);
        double k = d0 / v->distance;
        /* a view at d0 in float must still draw everything */
        return k >= 1 - 1e-5 ? full : full * k * k;
    }
    if (p->opt.kind == MTS_LOD_POLICY_AREA) {
        double theta = asin(p->radius / v->distance);
        double rho = 0.5 * v->height * tan(theta) / tan(0.5 * v->fov_y);
        double area = 3.14159265358979 * rho * rho;
        double window = (double)v->width * v->height;
        if (area > window)
            area = window;
        double t = area / p->opt.pixels_per_triangle;
        return t > full ? full : t;
    }
    return full;
}

static uint32_t level_for(const mts_lod_policy *p, double triangles, uint32_t available)
{
    if (!(triangles > 0))
        return 0;
    const mts_model *m = p->model;
    uint32_t l;
    if (m->level_triangles) {
        uint64_t t = triangles >= 1e18 ? (uint64_t)1e18 : (uint64_t)triangles;
        l = mts_model_level_for_triangles(m, t);
    } else { /* the largest level at most that many, as above */
        double span = (double)p->full_triangles - p->base_triangles;
        double x = span > 0 ? (triangles - p->base_triangles) / span * m->level_count
                            : m->level_count;
        l = x <= 0 ? 0 : x >= m->level_count ? m->level_count : (uint32_t)x;
    }
    return l < available ? l : available;
}

static uint32_t choose_budget(mts_lod_policy *p, uint32_t available, double last_frame_ms)
{
    uint32_t cur = p->level < available ? p->level : available;
    if (!p->chosen)
        return available;
    if (!(last_frame_ms > 0) || !isfinite(last_frame_ms))
        return cur; /* nothing measured: stay */
    double drawn = mts_lod_policy_level_triangles(p, p->level);
    if (drawn < 1)
        drawn = 1;
    double sample = last_frame_ms / drawn;
    p->ms_per_triangle = p->ms_per_triangle > 0
                             ? (1 - p->opt.smoothing) * p->ms_per_triangle +
                                   p->opt.smoothing * sample
                             : sample;
    double budget = 1000.0 / p->opt.fps;
    double want = p->opt.headroom * budget / p->ms_per_triangle;
    uint32_t cand = level_for(p, want, available);
    double cur_t = mts_lod_policy_level_triangles(p, cur);
    double cand_t = mts_lod_policy_level_triangles(p, cand);
    if (cand < cur && last_frame_ms > budget)
        return cand; /* over the budget: down at once */
    if (cand_t > cur_t * (1 + p->opt.hysteresis) || cand_t < cur_t * (1 - p->opt.hysteresis))
        return cand;
    return cur;
}

uint32_t mts_lod_policy_choose(mts_lod_policy *p, uint32_t available, const mts_lod_view *view,
                               double last_frame_ms)
{
    if (available > p->model->level_count)
        available = p->model->level_count;
    uint32_t l;
    switch (p->opt.kind) {
    case MTS_LOD_POLICY_DISTANCE:
    case MTS_LOD_POLICY_AREA:
        l = level_for(p, mts_lod_policy_view_triangles(p, view), available);
        break;
    case MTS_LOD_POLICY_BUDGET:
        l = choose_budget(p, available, last_frame_ms);
        break;
    default:
        l = available;
        break;
    }
    p->level = l;
    p->chosen = 1;
    return l;
}

double mts_lod_policy_stop_triangles(const mts_lod_policy_options *o, double distance,
                                     float fov_y, int width, int height,
                                     uint32_t full_triangles)
{
    if (!o || (o->kind != MTS_LOD_POLICY_DISTANCE && o->kind != MTS_LOD_POLICY_AREA) ||
        !(distance > 0) || !isfinite(distance))
        return 0;
    /* a stand-in model: a unit box, no levels, the listing's full count */
    mts_model m;
    memset(&m, 0, sizeof m);
    for (int i = 0; i < 3; i++) {
        m.bbox_min[i] = -1;
        m.bbox_max[i] = 1;
    }
    m.level_triangles = &full_triangles;
    mts_lod_policy p;
    mts_lod_policy_init(&p, o, &m);
    mts_lod_view v = {1, fov_y, width, height};
    v.distance = (float)(distance * mts_lod_policy_frame_distance(&p, &v));
    return mts_lod_policy_view_triangles(&p, &v);
}
