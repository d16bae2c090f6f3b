/* The follower: a LOD runtime kept in step with a source, and the level's
 * strips packed for a draw, GL-free -- what the native view (view.h, which
 * adds a GL renderer) and the browser page (web/mts_web.c, which hands the
 * arrays to WebGL2) both draw from.
 *
 * A source is a runtime that a stream client (or any caller) moves, and the
 * vertices and slots it has so far. mts_follow_sync takes the vertices that
 * came (they make levels available), lays out the slots announced since,
 * moves to the level asked for, through a geomorph where asked (morph.h),
 * and says what changed for a renderer to upload: the vertex range that
 * came, whether the strips changed (the runtime's changed list says which,
 * so a renderer touches only those), whether the morph's range changed.
 *
 * Two ways to hold the level:
 *   - the source's own runtime (own_runtime 0): the follower moves it, so a
 *     caller that steps below what came (a PNG of an earlier level) steps
 *     back up before the stream goes on. Headless, one runtime is enough.
 *   - a runtime of the follower's own on the source's model (own_runtime 1):
 *     it may stand anywhere up to what came while the stream goes on, as a
 *     window's level keys or the page's slider need.
 *
 * Geomorphs (own runtime, morph_ms > 0): a level change does not pop; the
 * vertices a level adds slide from their ancestors' places. While a morph
 * runs the level holds, so a fast stream shows a step every morph_ms
 * instead of one a frame (which also bounds the packed arrays' rebuilds).
 *
 * Packing (mts_follow_pack, and mts_follow_pack_strips under it, which the
 * GL renderer packs its own copy of the strips with): the live strips
 * joined into one strip as render.h's "The draw" says -- each strip of 3 or
 * more indices after the one before, joined by repeated indices so that
 * every strip starts at an even position and each window across a joint
 * draws nothing -- plus, per strip drawn, where it begins, its length and
 * its colour, for a draw strip by strip out of the same buffer.
 *
 * Errors: mts_result and mts_error, nothing printed. One thread. */
#ifndef MTS_FOLLOW_H
#define MTS_FOLLOW_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"
#include "lod.h"
#include "model.h"
#include "morph.h"

struct mts_stream_client;

/* The level asked for by mts_follow_sync: the newest the source has. */
#define MTS_FOLLOW_NEWEST UINT32_MAX

typedef struct mts_follow_options {
    int own_runtime; /* see the top; 0 moves the source's runtime */
    double morph_ms; /* geomorph time; 0 (the default): levels change at once */
    /* with morph_ms: the first level shown is set at once rather than slid
     * to from the base (the page: the first picture waits for no morph
     * program to compile) */
    int first_at_once;
} mts_follow_options;

/* What the follower follows. */
typedef struct mts_follow_source {
    mts_lod *lod;             /* the source's runtime */
    const mts_model *model;   /* its model (positions, normals, parents, capacities) */
    uint32_t vertices;        /* vertices present: base + the splits that came */
    uint32_t levels;          /* the highest level to show: a stream's stop level, where
                                 the last batch may bring splits past it */
    uint32_t announced;       /* slots laid out in lod (all of them for a whole model) */
} mts_follow_source;

/* A stream client's runtime and what it has received. */
mts_follow_source mts_follow_source_of_stream(struct mts_stream_client *c);
/* A whole model's runtime (every level present). */
mts_follow_source mts_follow_source_of_model(mts_lod *lod, const mts_model *model);

typedef struct mts_follow_figures {
    uint32_t level, triangles, strips;
    uint64_t indices; /* restarts not counted */
} mts_follow_figures;

/* What one mts_follow_sync changed. */
typedef struct mts_follow_changes {
    /* vertices that came since the last sync: ids first .. first+count-1
     * (the model's positions and normals) */
    uint32_t vertex_first, vertex_count;
    /* the strips changed (lod's changed list and relayout_from say how),
     * or this is the first sync, or mts_follow_touch asked: a renderer
     * takes them, then mts_follow_clear_changed */
    int strips;
    int morph_range; /* morph.first, .count or .from changed */
} mts_follow_changes;

/* A level's strips packed: flat arrays the packer owns (grown, never
 * shrunk), valid until the next pack. */
typedef struct mts_follow_packed {
    void *indices;     /* count entries: uint16_t with u16, else uint32_t */
    uint64_t count;
    int u16;
    /* with per_strip, one entry a strip drawn (3 or more indices), in slot order */
    uint32_t strips;
    uint32_t *strip_first;  /* where it begins in indices */
    uint32_t *strip_length; /* its length */
    float *strip_rgb;       /* its colour, 3 floats (mts_camera_strip_color of its slot) */
    /* internal */
    size_t cap; /* bytes indices holds */
    uint32_t strip_cap;
} mts_follow_packed;

typedef struct mts_follow {
    mts_lod *lod;               /* the runtime followed: the follower's own or the source's */
    mts_follow_figures shown;   /* of the level the strips are at */
    int have_figures;           /* shown is filled (after the first sync) */
    mts_morph morph;            /* .active: a geomorph runs, sync again next frame;
                                   .t: how far it is, 0..1 (towards the higher level) */
    uint32_t morph_serial;      /* counts the changes of the morph's range */
    mts_follow_packed packed;   /* the last mts_follow_pack (lod's level, 32-bit, per strip) */
    mts_follow_options opts;
    /* internal */
    mts_lod own;
    int have_own, moved, stale, pack_stale;
    uint32_t vertices, announced;
} mts_follow;

/* Takes the source (the own runtime made at the base where asked). The
 * struct is the caller's; this fills it. MTS_ERR_ARG for a morph time
 * outside 0..1e6 ms, or a morph without a runtime of the follower's own. */
mts_result mts_follow_init(mts_follow *f, const mts_follow_source *src,
                           const mts_follow_options *opts, mts_error *err);
void mts_follow_free(mts_follow *f);

/* Brings the follower up to the source and towards `level` (at most what
 * the source has; MTS_FOLLOW_NEWEST for that), now_ms on a monotonic clock
 * for the geomorphs; *changes (may be NULL) says what changed. */
mts_result mts_follow_sync(mts_follow *f, const mts_follow_source *src, uint32_t level,
                           double now_ms, mts_follow_changes *changes, mts_error *err);

/* The strips' changes taken (lod's changed list cleared): after a renderer
 * uploaded them. */
void mts_follow_clear_changed(mts_follow *f);

/* The next sync says the strips changed, though they may not have: for a
 * caller whose own derived state (a wireframe) is to be rebuilt. */
void mts_follow_touch(mts_follow *f);

/* Packs lod's level into f->packed (32-bit, per strip), unless the strips
 * have not changed since the last pack. */
mts_result mts_follow_pack(mts_follow *f, mts_error *err);

/* The packing under it: strip s of strip_count is length[s] indices at
 * data + offset[s]; joined (restart 0, see the top) or with that restart
 * index between strips; 16-bit indices with u16 (every index below
 * 0xFFFF); per_strip fills strips, strip_first, strip_length, strip_rgb.
 * MTS_ERR_LIMIT past what one draw may take (INT32_MAX indices). */
mts_result mts_follow_pack_strips(mts_follow_packed *p, const uint32_t *data,
                                  const uint32_t *offset, const uint32_t *length,
                                  uint32_t strip_count, uint32_t restart, int u16, int per_strip,
                                  mts_error *err);
void mts_follow_packed_free(mts_follow_packed *p);

#endif
