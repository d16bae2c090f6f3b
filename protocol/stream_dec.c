/* The client's end of a stream (stream.h): frames checked and applied as
 * they arrive, resuming after a break, continuing past a stop level. */
#include "stream.h"

#include "grow.h"
#include "grow_tokens.h"
#include "stream_coding.h"
#include "stream_dec_threads.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "crc32c.h"
#include "lframe.h"
#include "rcoder.h"
#include "reccodec.h"
#include "varint.h"
#include "words.h"

/* ST_SKIP_BASE: a resumed conversation that the server started from batch 0
 * after our base was in; its BASE is the one we hold (same stream_id). */
enum { ST_INFO = 0, ST_BASE, ST_BATCHES, ST_DONE, ST_FAILED, ST_SKIP_BASE };

/* A client reserves room per level and per slot for the counts MODEL_INFO
 * announces before any data arrives (take_info bounds the slots by the
 * vertices), so those counts are capped: 2^24 vertices (a 16M-vertex model
 * holds about 1.2 GB here once it has all come). */
#define CLIENT_MAX_VERTICES (1u << 24)

void mts_stream_client_init(mts_stream_client *c)
{
    memset(c, 0, sizeof *c);
}

void mts_stream_client_free(mts_stream_client *c)
{
    mts__stream_par_free(c->par);
    if (c->have_lod)
        mts_lod_free(&c->lod);
    mts_grow_free(c->grow);
    free(c->models);
    mts_bigmem_free(&c->oct_mem);
    mts_wire_model_info_free(&c->info);
    mts_model_free(&c->model);
    mts_bigmem_free(&c->quantized_mem);
    mts_wire_reader_free(&c->reader);
    memset(c, 0, sizeof *c);
}

static mts_result fail(mts_stream_client *c, mts_result rc)
{
    c->state = ST_FAILED;
    return rc;
}

static int crc_ok(const uint8_t *payload, size_t size)
{
    if (size < 4)
        return 0;
    const uint8_t *t = payload + size - 4;
    uint32_t want = (uint32_t)t[0] | (uint32_t)t[1] << 8 | (uint32_t)t[2] << 16 |
                    (uint32_t)t[3] << 24;
    return mts_crc32c(0, payload, size - 4) == want;
}

/* A frame that failed its CRC: nothing of it applied and the state as it
 * was, so a resumed conversation can bring it again (c->rejected). */
static mts_result reject(mts_stream_client *c, mts_result rc)
{
    c->rejected = 1;
    return rc;
}

static mts_result take_info(mts_stream_client *c, const uint8_t *p, size_t n, mts_error *err)
{
    mts_result rc = mts_wire_parse_model_info(p, n, &c->info, err);
    if (rc != MTS_OK)
        return rc;
    const mts_wire_model_info *mi = &c->info;
    /* Every count here is the server's word, and what the client sizes
     * before data arrives follows from them, so each is held to what the
     * others and the stream's invariants allow (PROTOCOL.md, MODEL_INFO,
     * "What a client checks"), and the claim that cannot be true is named.
     * Vertices are the root: capped here, and what they claim is only
     * reserved, the per-vertex arrays growing as vertices arrive. */
    if (mi->vertices > CLIENT_MAX_VERTICES)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "MODEL_INFO claims %u vertices (%u base, %u levels); this client "
                             "takes at most %u",
                             mi->vertices, mi->base_vertices, mi->levels, CLIENT_MAX_VERTICES);
    /* a builder keeps no vertex outside a triangle (mesh cleaning drops
     * them), so the full level's triangles have every vertex as a corner */
    if ((uint64_t)mi->vertices > 3ull * mi->triangles)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u vertices (%u base, %u levels) for %u "
                             "triangles, which have at most %llu corners",
                             mi->vertices, mi->base_vertices, mi->levels, mi->triangles,
                             3ull * mi->triangles);
    /* no triangle goes away on the way up: every level has at most the
     * full level's */
    if (mi->stop_triangles > mi->triangles)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u triangles at the stop level, more than the "
                             "%u of the full level",
                             mi->stop_triangles, mi->triangles);
    /* A slot holds a strip of a triangle at least at some level (else it
     * would not be one), and growth opens a slot only when every one it has
     * holds a strip: there are never more slots than the triangles of one
     * level, which are at most the full level's (built models: 5.5 to 6.6
     * slots a hundred triangles). */
    if (mi->strips > mi->triangles)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u strips for %u triangles", mi->strips,
                             mi->triangles);
    const uint64_t cap = mi->capacity_total;
    /* every full-level triangle is drawn by a strip no longer than its
     * slot, so the capacities bound the triangles, and with them every
     * count the batches may announce (explicit lists, the full strips) */
    if (mi->triangles > cap)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u triangles, more than strip capacities of "
                             "%llu indices can draw",
                             mi->triangles, (unsigned long long)cap);
    /* a slot's capacity is its longest strip, three indices at least */
    if (3ull * mi->strips > cap)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u strips, but strip capacities of %llu indices "
                             "hold at most %llu (three a strip)",
                             mi->strips, (unsigned long long)cap, (unsigned long long)cap / 3);
    /* A capacity is the longest its slot is at any level, so the slots add
     * up to more than any one level's strips, but not by much: built models
     * hold 4.3 to 4.7 capacity per vertex (cow, bunny00, fandisk_large; 2.4
     * indices per vertex at the full level). 16 per vertex is this client's
     * bound (the one that is a policy, not an invariant), and with the
     * checks above it bounds the triangles and slots too. */
    if (cap > 16ull * mi->vertices)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "MODEL_INFO claims %llu indices of strip capacity for %u vertices "
                             "(this client takes 16 a vertex)",
                             (unsigned long long)cap, mi->vertices);
    mts_model *m = &c->model;
    size_t n1 = (size_t)mi->levels + 1;
    m->vertex_count = mi->vertices;
    m->base_vertex_count = mi->base_vertices;
    m->level_count = mi->levels;
    m->strip_count = mi->strips;
    memcpy(m->bbox_min, mi->bbox_min, 12);
    memcpy(m->bbox_max, mi->bbox_max, 12);
    snprintf(m->source, sizeof m->source, "%s", mi->model);
    /* the per-vertex arrays come with the vertices (reserve_vertices);
     * these are zero, sized by the claim, and stay untouched but for the
     * levels and slots that arrive (reservations past 1 MB, whatever the
     * heap would do with a calloc: bigmem.h) */
    if (mts_bigmem_zeroed(&m->parents_mem, n1 * 4))
        m->parents = m->parents_mem.p;
    if (mts_bigmem_zeroed(&m->offsets_mem, n1 * 4))
        m->record_offsets = m->offsets_mem.p;
    if (mts_bigmem_zeroed(&m->capacity_mem, ((size_t)mi->strips + 1) * 4))
        m->capacity = m->capacity_mem.p;
    c->models = malloc(sizeof *c->models);
    if (mi->flags & MTS_INFO_NORMALS)
        m->flags = MTS_MODEL_NORMALS_GIVEN;
    /* colours grow with the vertices like the rest (reserve_vertices) */
    if (mi->flags & MTS_INFO_COLORS)
        m->flags |= MTS_MODEL_COLORS;
    c->vertex_room = 0;
    if (!m->parents || !m->record_offsets || !m->capacity || !c->models ||
        mts_strips_alloc(&m->full, mi->strips, 0, err) != MTS_OK)
        return mts_error_set(err, MTS_ERR_NOMEM,
                             "MODEL_INFO: out of memory for %u levels and %u strips", mi->levels,
                             mi->strips);
    /* The slots' room is MODEL_INFO's total; each slot's capacity (the
     * longest it is at any level) comes with BASE or the batch that first
     * uses it, and is 0 until then (take_capacities). The full strips never
     * travel: this model's full strips are strip_count empty ones, so it may
     * start runtimes at the base (which reads base and capacity), never at
     * the full level, and is not for mts_model_validate or mts_verify_model. */
    m->capacity_room = cap;
    c->announced = 0;
    c->announced_sum = 0;
    mts__stream_models_init(c->models);
    c->grid.bits = mi->quant_bits;
    memcpy(c->grid.origin, mi->grid_origin, 12);
    c->grid.range = mi->grid_range;
    c->stop_level = mi->stop_level;
    c->records = (mi->flags & MTS_INFO_RECORDS) != 0;
    /* Records that pass mts_lod_split may still be padded (edits that
     * change nothing, runs put back), so what a records-form client keeps
     * is bounded here by the model: a key level's record rewrites every
     * slot (erase and insert at most its capacity, 5 words of header), and
     * 256 words a split on top. Built models use an eighth of it (bunny00:
     * 1.73 M words of 13.7 M; 24 words a split between key levels, 650 at
     * most). */
    c->record_word_limit = 256ull * mi->levels +
                           (mi->key_count + 1ull) * (2 * cap + 5ull * mi->strips);
    return MTS_OK;
}

/* A resumed conversation's MODEL_INFO against the first one: everything the
 * client's state depends on must be equal, or the batches to come belong to
 * another stream. The minor version may differ (a server upgraded in
 * between speaks the same stream). */
static mts_result check_resumed_info(mts_stream_client *c, const uint8_t *p, size_t n,
                                     mts_error *err)
{
    mts_wire_model_info mi = {0};
    mts_result rc = mts_wire_parse_model_info(p, n, &mi, err);
    if (rc != MTS_OK)
        return rc;
    const mts_wire_model_info *a = &c->info;
    const char *what = NULL;
    if (mi.stream_id != a->stream_id)
        what = "stream_ids";
    else if (strcmp(mi.model, a->model) != 0)
        what = "names";
    else if (mi.vertices != a->vertices || mi.base_vertices != a->base_vertices ||
             mi.levels != a->levels || mi.triangles != a->triangles || mi.strips != a->strips)
        what = "counts";
    else if (!c->continuing &&
             (mi.stop_level != a->stop_level || mi.stop_triangles != a->stop_triangles))
        what = "stop levels";
    else if (c->continuing && (mi.stop_level < c->lod.level || mi.stop_level > a->levels))
        what = "stop levels (a continuation's may only rise)";
    else if (mi.flags != a->flags)
        what = "flags (normals, form)";
    else if (memcmp(mi.bbox_min, a->bbox_min, 12) != 0 ||
             memcmp(mi.bbox_max, a->bbox_max, 12) != 0 || mi.quant_bits != a->quant_bits ||
             memcmp(mi.grid_origin, a->grid_origin, 12) != 0 ||
             memcmp(&mi.grid_range, &a->grid_range, 4) != 0)
        what = "grids";
    else if (mi.batch_count != a->batch_count || mi.batch_size != a->batch_size)
        what = "batches";
    else if (mi.capacity_total != a->capacity_total)
        what = "strip capacities";
    else if (mi.key_count != a->key_count ||
             (a->key_count && memcmp(mi.key_levels, a->key_levels, (size_t)a->key_count * 4) != 0))
        what = "key levels";
    if (!what && c->continuing) {
        /* the new stop: the runtime goes up to it as far as the splits held
         * allow (the last batch decoded may reach past the old stop) */
        c->info.stop_level = c->stop_level = mi.stop_level;
        c->info.stop_triangles = mi.stop_triangles;
        uint32_t target = c->splits < c->stop_level ? c->splits : c->stop_level;
        rc = mts_lod_set_level(&c->lod, target, err);
        if (rc != MTS_OK) {
            mts_wire_model_info_free(&mi);
            return rc;
        }
    }
    if (what)
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "MODEL_INFO on resume: '%s' is now another stream (%s differ: stream "
                           "%016llx, was %016llx) than the one this client holds %u batches of; "
                           "not mixing two streams",
                           mi.model, what, (unsigned long long)mi.stream_id,
                           (unsigned long long)a->stream_id, c->batches);
    mts_wire_model_info_free(&mi);
    return rc;
}

/* Capacities for slots c->announced .. upto-1 (PROTOCOL.md, "Capacities"):
 * announced in order, never more slots than there are, and together never
 * past MODEL_INFO's total, which the client's runtime reserved. They come as
 * varints from cur (BASE, the records form) or coded from d (the splits
 * form's batches). The runtime lays the new slots out once it has started
 * (after BASE). */
static mts_result take_capacities(mts_stream_client *c, mts_cursor *cur, mts_rc_decoder *d,
                                  uint32_t upto, const char *frame, mts_error *err)
{
    mts_model *m = &c->model;
    const uint32_t from = c->announced;
    /* a varint is a byte at least; a coded one is bounded by the total */
    if (upto < from || upto > m->strip_count || (cur && upto - from > mts_cursor_left(cur)))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: capacities for slots up to %u (%u announced, %u slots) are "
                             "malformed",
                             frame, upto, from, m->strip_count);
    uint64_t sum = c->announced_sum;
    uint32_t s = from;
    for (; s < upto && sum <= c->info.capacity_total; s++) {
        m->capacity[s] = cur ? mts_cursor_varint(cur) : mts_rc_decode_uint(d, &c->models->capacity);
        sum += m->capacity[s];
    }
    if ((cur ? !cur->ok : !d->ok) || sum > c->info.capacity_total) {
        for (uint32_t x = from; x < s; x++)
            m->capacity[x] = 0;
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: strip capacities add up to %llu or more, past MODEL_INFO's %u",
                             frame, (unsigned long long)sum, c->info.capacity_total);
    }
    c->announced = upto;
    c->announced_sum = sum;
    if (c->have_lod) {
        mts_result rc = mts_lod_announce(&c->lod, from, err);
        if (rc != MTS_OK)
            return mts_error_prefix(err, "%s", frame);
    }
    return MTS_OK;
}

/* One per-vertex array grown from `was` to `room` vertices of `unit`
 * bytes, its new part cleared where `zero` (normals and colours add up
 * as triangles come). Past a megabyte it moves into a reservation for the
 * vertices MODEL_INFO claims and grows there in place (bigmem.h): only
 * what the vertices that arrive fill is ever touched, and a client that
 * follows another in one process (c->memory) reuses its pages. */
static int grow_vertex_array(mts_stream_client *c, mts_bigmem *mem, size_t unit, size_t was,
                             size_t room, int zero)
{
    mem->cache = c->memory;
    if (!mts_bigmem_room(mem, room * unit, was * unit, (size_t)c->model.vertex_count * unit))
        return 0;
    if (zero)
        memset((uint8_t *)mem->p + was * unit, 0, (room - was) * unit);
    return 1;
}

/* Room in the per-vertex arrays for `count` vertices (at most the model's).
 * They hold the vertices that arrived, the base once decoded and each split
 * as it is decoded, not what MODEL_INFO claims: a server that claims
 * millions of vertices and sends a few thousand costs a few thousand.
 * Doubling keeps the copying to a constant a vertex; the new normals are
 * zero, as a stream without normals leaves them. 0 when out of memory (the
 * arrays that did grow stay valid). */
static int reserve_vertices(mts_stream_client *c, uint32_t count)
{
    mts_model *m = &c->model;
    if (count <= c->vertex_room)
        return 1;
    uint64_t room = 2ull * c->vertex_room;
    if (room < count)
        room = count;
    if (room > m->vertex_count)
        room = m->vertex_count;
    if (room < count)
        return 0;
    const size_t was = c->vertex_room;
    const int ok =
        grow_vertex_array(c, &m->positions_mem, 12, was, room, 0) &&
        grow_vertex_array(c, &m->normals_mem, 12, was, room, 1) &&
        grow_vertex_array(c, &c->quantized_mem, 12, was, room, 0) &&
        (!(m->flags & MTS_MODEL_NORMALS_GIVEN) ||
         grow_vertex_array(c, &c->oct_mem, 4, was, room, 0)) &&
        (!(m->flags & MTS_MODEL_COLORS) || grow_vertex_array(c, &m->colors_mem, 3, was, room, 1));
    /* where one failed, those grown before it may have moved */
    m->positions = m->positions_mem.p;
    m->normals = m->normals_mem.p;
    c->quantized = c->quantized_mem.p;
    c->oct = c->oct_mem.p;
    m->colors = m->colors_mem.p;
    if (ok)
        c->vertex_room = (uint32_t)room;
    return ok;
}

static mts_result take_base(mts_stream_client *c, const uint8_t *p, size_t n, mts_error *err)
{
    /* the CRC has checked out (mts_stream_client_frame) */
    mts_model *m = &c->model;
    const uint32_t nb = m->base_vertex_count;
    mts_cursor cur = mts_cursor_make(p, n - 4);
    uint32_t dsize = mts_cursor_varint(&cur);
    const uint8_t *draco = mts_cursor_bytes(&cur, dsize);
    if (!draco)
        return mts_error_set(err, MTS_ERR_FORMAT, "BASE: Draco mesh runs past the message");
    mts_draco_mesh_out dec = {0};
    mts_result rc = mts_draco_decode(draco, dsize, &dec, err);
    if (rc != MTS_OK)
        return mts_error_prefix(err, "BASE");
    const int carry_normals = (m->flags & MTS_MODEL_NORMALS_GIVEN) != 0;
    const int carry_colors = (m->flags & MTS_MODEL_COLORS) != 0;
    if (dec.vertex_count != nb || (dec.normals != NULL) != carry_normals ||
        (dec.colors != NULL) != carry_colors ||
        dec.grid.bits != c->grid.bits ||
        memcmp(dec.grid.origin, c->grid.origin, 12) != 0 || dec.grid.range != c->grid.range) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "BASE: Draco mesh has %u vertices (expected %u), another grid, or "
                           "normals or colours where MODEL_INFO says %s and %s",
                           dec.vertex_count, nb,
                           carry_normals ? "there are normals" : "there are no normals",
                           carry_colors ? "there are colours" : "there are no colours");
        mts_draco_mesh_out_free(&dec);
        return rc;
    }
    /* no triangle goes away on the way up: the base has at most the
     * triangles of any level */
    if (dec.triangle_count > c->info.stop_triangles) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "BASE: Draco mesh has %u triangles, more than the %u MODEL_INFO "
                           "claims at the stop level",
                           dec.triangle_count, c->info.stop_triangles);
        mts_draco_mesh_out_free(&dec);
        return rc;
    }
    if (!mts__stream_base_in_grid_order(&dec, NULL) || !reserve_vertices(c, nb)) {
        mts_draco_mesh_out_free(&dec);
        return mts_error_set(err, MTS_ERR_NOMEM, "BASE: out of memory for %u vertices", nb);
    }
    memcpy(m->positions, dec.positions, (size_t)nb * 12);
    if (carry_normals) {
        memcpy(m->normals, dec.normals, (size_t)nb * 12);
        for (uint32_t x = 0; x < nb; x++)
            mts__stream_oct_encode(m->normals + 3 * (size_t)x, c->oct + 2 * (size_t)x);
    }
    memcpy(c->quantized, dec.quantized, (size_t)nb * 12);
    if (carry_colors)
        memcpy(m->colors, dec.colors, (size_t)nb * 3);
    mts_draco_mesh_out_free(&dec);

    /* the slots the base uses, their capacities and lengths (each within
     * its capacity); then the indices */
    const uint32_t k0 = mts_cursor_varint(&cur);
    if ((rc = take_capacities(c, &cur, NULL, k0, "BASE", err)) != MTS_OK)
        return rc;
    uint64_t total = 0;
    if (k0 > mts_cursor_left(&cur))
        return mts_error_set(err, MTS_ERR_FORMAT, "BASE: %u strip lengths cannot fit", k0);
    /* the announced slots' lengths: a varint each, so no more than the
     * message holds; the slots after them are empty at level 0 */
    uint32_t *lens = calloc((size_t)k0 + 1, 4);
    if (!lens)
        return mts_error_set(err, MTS_ERR_NOMEM, "BASE: out of memory");
    for (uint32_t s = 0; s < k0; s++) {
        lens[s] = mts_cursor_varint(&cur);
        total += lens[s];
        if (lens[s] > m->capacity[s]) {
            uint32_t len = lens[s];
            free(lens);
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "BASE: strip %u has %u indices, more than its slot's capacity %u",
                                 s, len, m->capacity[s]);
        }
    }
    if (!cur.ok || total > mts_cursor_left(&cur)) {
        free(lens);
        return mts_error_set(err, MTS_ERR_FORMAT, "BASE: strip indices cannot fit the message");
    }
    if ((rc = mts_strips_alloc(&m->base, m->strip_count, (uint32_t)total, err)) != MTS_OK) {
        free(lens);
        return rc;
    }
    uint32_t o = 0;
    for (uint32_t s = 0; s < m->strip_count; s++) {
        m->base.offsets[s] = o;
        uint32_t prev = 0;
        for (uint32_t k = 0; s < k0 && k < lens[s]; k++) {
            prev += mts_unzigzag_u32(mts_cursor_varint(&cur));
            if (prev >= nb) {
                free(lens);
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "BASE: strip %u index %u is not a base vertex (%u)", s, prev,
                                     nb);
            }
            m->base.indices[o++] = prev;
        }
    }
    m->base.offsets[m->strip_count] = o;
    free(lens);
    if (!cur.ok || mts_cursor_left(&cur) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "BASE: malformed strips");
    /* the records form brings every record: nothing to grow */
    mts_grow_options go = {0};
    go.key_levels = c->info.key_levels;
    go.key_count = c->info.key_count;
    go.memory = c->memory;
    if (!c->records && (rc = mts__stream_par_start(c, &go, err)) != MTS_OK)
        return mts_error_prefix(err, "BASE");
    /* with threads, the decode thread's grow keeps the mesh alone */
    if (!c->records &&
        (rc = c->par ? mts_grow_create_mesh(&m->base, nb, m->level_count, &c->grow, err)
                     : mts_grow_create(&m->base, nb, m->level_count, &go, &c->grow, err)) !=
            MTS_OK)
        return mts_error_prefix(err, "BASE");
    if (c->grow)
        mts_grow_use_memory(c->grow, c->memory);
    if ((rc = mts_lod_init_with(&c->lod, m, MTS_LOD_AT_BASE, c->memory, err)) != MTS_OK)
        return rc;
    c->have_lod = 1;
    mts_lod_set_available(&c->lod, 0);
    return MTS_OK;
}

/* Room in the client's model for `words` more record words from word `at`.
 * A whole model's records run to megabytes (bunny00: 1.7 M words, the 1.2M
 * mesh 28 M): past a megabyte they move into a reservation for the records
 * form's bound and grow there in place, on huge pages (bigmem.h). */
mts_result mts__stream_reserve_records(mts_stream_client *c, size_t at, size_t words,
                                        mts_error *err)
{
    mts_model *m = &c->model;
    if (words > UINT32_MAX - 1 - at)
        return mts_error_set(err, MTS_ERR_LIMIT, "BATCH: records past 2^32 words");
    if (at + words + 1 <= c->record_capacity)
        return MTS_OK;
    size_t cap = c->record_capacity ? c->record_capacity : 4096;
    while (cap < at + words + 1)
        cap *= 2;
    /* doubling stops at the records form's bound: memory stays within it */
    if (c->record_word_limit && cap > c->record_word_limit + 1 &&
        at + words + 1 <= c->record_word_limit + 1)
        cap = (size_t)c->record_word_limit + 1;
    const size_t most = c->record_word_limit ? ((size_t)c->record_word_limit + 1) * 4 : 0;
    m->record_mem.cache = c->memory;
    if (!mts_bigmem_room(&m->record_mem, cap * 4, at * 4, most))
        return mts_error_set(err, MTS_ERR_NOMEM, "BATCH: out of memory for %zu record words",
                             cap);
    m->record_data = m->record_mem.p;
    /* a reservation is rounded up to huge pages; what is used stays within
     * the bound */
    c->record_capacity = m->record_mem.room / 4;
    if (c->record_word_limit && c->record_capacity > c->record_word_limit + 1)
        c->record_capacity = (size_t)c->record_word_limit + 1;
    return MTS_OK;
}

/* Appends one derived record to the client's model. */
mts_result mts__stream_keep_record(mts_stream_client *c, uint32_t j, const uint32_t *r,
                                   uint32_t words, mts_error *err)
{
    mts_model *m = &c->model;
    size_t at = m->record_offsets[j];
    mts_result rc = mts__stream_reserve_records(c, at, words, err);
    if (rc != MTS_OK)
        return rc;
    memcpy(m->record_data + at, r, (size_t)words * 4);
    m->record_offsets[j + 1] = (uint32_t)(at + words);
    m->record_word_count = (uint32_t)(at + words);
    return MTS_OK;
}

/* Where a client's full-level walk takes each strip's start and its swap
 * bits from: the batch's coder, as the walk goes (grow.h, mts_grow_full). */
typedef struct full_source {
    mts_rc_decoder *d;
    struct mts__stream_models *md;
    unsigned id_bits;
} full_source;

static unsigned swap_from_coder(void *user, unsigned previous)
{
    full_source *x = user;
    return mts_rc_decode_bit(x->d, &x->md->swap[previous & 1]);
}

static int start_from_coder(void *user, const uint32_t *near, uint32_t near_count,
                            uint32_t *near_at, uint32_t *first, uint32_t *rotation)
{
    full_source *x = user;
    (void)near;
    if (near_count && mts_rc_decode_bit(x->d, &x->md->full_near)) {
        const uint32_t k = mts_rc_decode_uint(x->d, &x->md->full_near_at);
        if (k >= near_count)
            return 0;
        *near_at = k;
    } else {
        *first = mts_rc_decode_direct(x->d, x->id_bits);
    }
    *rotation = mts_rc_decode_tree(x->d, &x->md->rotation);
    return x->d->ok;
}

/* The full strips' description, after the last split's fan code: per slot
 * its triangle count; each strip's start and the swap bits the walk does
 * not force follow as the last split resolves them, read through `src`.
 * The counts are bounded by the full level's triangles, which MODEL_INFO
 * gave, before anything is allocated. */
static mts_result decode_full(mts_stream_client *c, mts_rc_decoder *d, mts_grow_full *full,
                              full_source *src, mts_error *err)
{
    struct mts__stream_models *md = c->models;
    const uint32_t slots = c->model.strip_count, triangles = c->info.triangles;
    mts_grow_full_path *paths = calloc((size_t)slots + 1, sizeof *paths);
    if (!paths)
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for the full strips");
    uint64_t tris = 0;
    for (uint32_t st = 0; st < slots && d->ok && tris <= triangles; st++) {
        paths[st].triangles = mts_rc_decode_uint(d, &md->full_triangles);
        tris += paths[st].triangles;
    }
    if (!d->ok || tris > triangles) {
        free(paths);
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "the full strips are malformed (%llu triangles of %u)",
                             (unsigned long long)tris, triangles);
    }
    *src = (full_source){d, md, mts__stream_triangle_id_bits(triangles)};
    full->paths = paths;
    full->swap_bit = swap_from_coder;
    full->start = start_from_coder;
    full->user = src;
    return MTS_OK;
}

/* A batch's splits: each one's parent, fan code (or explicit lists) and
 * vertex, its record derived on the way (grow.h). The CRC has checked out,
 * so a malformed split means a broken server: the client stops there. */
static mts_result take_splits(mts_stream_client *c, mts_rc_decoder *d, mts_grow_full *full,
                              uint32_t index, uint32_t first, uint32_t count, uint32_t maxq,
                              mts_error *err)
{
    struct mts__stream_models *md = c->models;
    mts_model *m = &c->model;
    const uint32_t nb = m->base_vertex_count;
    mts_result rc;
    full_source src;
    for (uint32_t i = 0; i < count; i++) {
        const uint32_t j = first + i, v = nb + j, before = j ? m->parents[j - 1] : 0;
        if (!reserve_vertices(c, v + 1))
            return mts_error_set(err, MTS_ERR_NOMEM, "BATCH %u: out of memory for %u vertices",
                                 index, v + 1);
        /* up: u = before + gap, below v; else u = v - 1 - back, below before */
        const unsigned up = mts_rc_decode_bit(d, &md->parent_up);
        const uint32_t x = mts_rc_decode_uint(d, up ? &md->parent_gap : &md->parent);
        const int bad = up ? x > v - 1 - before : x >= v || v - 1 - x >= before;
        unsigned sides = mts_rc_decode_tree(d, &md->sides);
        if (!d->ok || bad || sides > MTS_GROWTH_EXPLICIT)
            return mts_error_set(err, MTS_ERR_FORMAT, "BATCH %u: split %u malformed", index, j);
        mts_grow_split sp = {0};
        sp.parent = up ? before + x : v - 1 - x;
        m->parents[j] = sp.parent;
        const uint32_t *r = NULL;
        uint32_t rw = 0;
        if (sides == MTS_GROWTH_EXPLICIT) {
            /* a split moves at most the triangles there are, and no
             * triangle ever goes away on the way up, so it brings back at
             * most those still to come: that bounds the lists (by the
             * capacities, take_info) before anything is allocated */
            sp.left = sp.right = MTS_GROW_NONE;
            sp.moved_count = mts_rc_decode_uint(d, &md->lists);
            sp.born_count = mts_rc_decode_uint(d, &md->lists);
            mts_grow_figures fig;
            mts_grow_get_figures(c->grow, &fig);
            uint64_t words = (uint64_t)sp.moved_count + 3ull * sp.born_count;
            if (!d->ok || words == 0 || words > SIZE_MAX / 4 || sp.moved_count > fig.triangles ||
                fig.triangles > c->info.triangles ||
                sp.born_count > c->info.triangles - fig.triangles)
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "BATCH %u: split %u lists %u moved and %u new triangles "
                                     "(%u there, %u at the full level)",
                                     index, j, sp.moved_count, sp.born_count, fig.triangles,
                                     c->info.triangles);
            uint32_t *lists = malloc((size_t)words * 4);
            if (!lists)
                return mts_error_set(err, MTS_ERR_NOMEM, "BATCH %u: out of memory", index);
            for (uint64_t q = 0; q < words && d->ok; q++)
                lists[q] = mts_rc_decode_uint(d, &md->lists);
            sp.moved = lists;
            sp.born = lists + sp.moved_count;
            rc = !d->ok ? mts_error_set(err, MTS_ERR_FORMAT, "BATCH %u: split %u truncated",
                                        index, j)
                 : j + 1 == m->level_count ? decode_full(c, d, full, &src, err)
                                           : MTS_OK;
            if (rc == MTS_OK)
                rc = c->par ? mts__stream_par_split(c, j, &sp, &lists, full, err)
                            : mts_grow_next(c->grow, &sp, full, &r, &rw, err);
            free(lists);
        } else {
            mts_grow_fan_code fc = {0, 0, sides};
            const unsigned fctx = mts__stream_fan_context(c->grow, sp.parent);
            /* the new vertex's position is predicted from these: asked for
             * now, they come while the fan is decoded and the split made */
            uint32_t near[16];
            const uint32_t near_count = mts_grow_ring_vertices(c->grow, sp.parent, near, 16);
            for (uint32_t i = 0; i < near_count; i++)
                __builtin_prefetch(c->quantized + 3 * (size_t)near[i]);
            fc.start = mts_rc_decode_uint(d, &md->start[fctx]);
            fc.count = mts_rc_decode_uint(d, &md->count[fctx]);
            if (!d->ok || !mts_grow_fan_decode(c->grow, sp.parent, &fc, &sp.left, &sp.right))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "BATCH %u: split %u names no fan of vertex %u (start %u, "
                                     "count %u, sides %u)",
                                     index, j, sp.parent, fc.start, fc.count, fc.sides);
            rc = j + 1 == m->level_count ? decode_full(c, d, full, &src, err) : MTS_OK;
            uint32_t *none = NULL;
            if (rc == MTS_OK)
                rc = c->par ? mts__stream_par_split(c, j, &sp, &none, full, err)
                            : mts_grow_next(c->grow, &sp, full, &r, &rw, err);
        }
        /* with threads the records are kept in order as they are fixed up */
        if (rc == MTS_OK && !c->par)
            rc = mts__stream_keep_record(c, j, r, rw, err);
        if (rc != MTS_OK)
            return mts_error_prefix(err, "BATCH %u", index);
        const uint32_t *around;
        uint32_t k;
        if ((rc = mts_grow_around_newest(c->grow, &around, &k, err)) != MTS_OK)
            return mts_error_prefix(err, "BATCH %u", index);
        int64_t pred[3], local[3];
        mts_lframe frame;
        unsigned ctx = mts__stream_predict_position(around, k, c->quantized, sp.parent,
                                                    c->grid.bits, pred, &frame);
        local[0] = mts_rc_decode_sint(d, &md->tangent[ctx]);
        local[1] = mts_rc_decode_sint(d, &md->tangent[ctx]);
        local[2] = mts_rc_decode_uint(d, &md->normal_part[ctx]);
        if (local[2] && mts_rc_decode_bit(d, &md->normal_sign[ctx]))
            local[2] = -local[2];
        mts_lframe_inverse(&frame, local);
        uint32_t *q = c->quantized + 3 * (size_t)v;
        for (int a = 0; a < 3; a++) {
            int64_t x = pred[a] + local[a];
            if (x < 0 || x > maxq)
                return mts_error_set(err, MTS_ERR_RANGE, "BATCH %u: vertex %u is off the grid",
                                     index, v);
            q[a] = (uint32_t)x;
        }
        mts_draco_dequantize(&c->grid, q, m->positions + 3 * (size_t)v);
        if (c->oct) {
            uint16_t *o = c->oct + 2 * (size_t)v, ou[2];
            mts__stream_predict_normal(around, k, c->quantized, v, c->grid.bits,
                                       c->oct + 2 * (size_t)sp.parent, ou);
            for (int a = 0; a < 2; a++) {
                int64_t x = (int64_t)ou[a] + mts_rc_decode_sint(d, &md->normal[a]);
                if (x < 0 || x > MTS__STREAM_NORMAL_MAX)
                    return mts_error_set(err, MTS_ERR_RANGE,
                                         "BATCH %u: vertex %u's normal is off its code", index,
                                         v);
                o[a] = (uint16_t)x;
            }
            mts__stream_oct_decode(o, m->normals + 3 * (size_t)v);
        }
        if (m->colors) {
            int32_t cp[3], t[3] = {0, 0, 0}, r[3];
            const unsigned cctx = mts__stream_predict_color(around, k, m->colors, sp.parent, cp);
            for (int a = 0; a < 3; a++)
                t[a] = mts_rc_decode_sint(
                    d, &md->color[a][mts__stream_color_context(cctx, a, t[0])]);
            /* no true residual is past +-510 (mts__stream_color_forward):
             * a larger one is malformed, and kept from overflowing the
             * inverse */
            int bad_color = !d->ok;
            for (int a = 0; a < 3; a++)
                bad_color |= t[a] < -510 || t[a] > 510;
            if (!bad_color) {
                mts__stream_color_inverse(t, r);
                for (int a = 0; a < 3; a++) {
                    const int32_t x = cp[a] + r[a];
                    bad_color |= x < 0 || x > 255;
                    m->colors[3 * (size_t)v + a] = (uint8_t)x;
                }
            }
            if (bad_color)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "BATCH %u: vertex %u's colour is off the 0..255 range", index,
                                     v);
        }
        if (c->par && (j + 1) % MTS__STREAM_CATCH_UP_EVERY == 0 &&
            (rc = mts__stream_par_catch_up(c, j + 1, err)) != MTS_OK)
            return mts_error_prefix(err, "BATCH %u", index);
    }
    if (!d->ok || !mts_rc_decoder_finished(d))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "BATCH %u: the coded splits %s", index,
                             d->ok ? "end before the message does"
                                   : "are malformed or run past the message");
    return MTS_OK;
}

/* A records-form batch's body (PROTOCOL.md, "Records form"): the splits'
 * parents and records, then each new vertex against its parent. The records
 * are only decoded here, into the client's model; mts_lod_split checks each
 * against the strips as it applies it, as it would a derived one. */
static mts_result take_records(mts_stream_client *c, const uint8_t *p, size_t n, uint32_t index,
                               uint32_t first, uint32_t count, uint32_t maxq, mts_error *err)
{
    mts_model *m = &c->model;
    const uint32_t nb = m->base_vertex_count;
    /* a split's words never outnumber its bytes (reccodec.h), so n more
     * words hold the batch whatever it says */
    size_t at = m->record_offsets[first];
    if (at > c->record_word_limit)
        return mts_error_set(err, MTS_ERR_LIMIT, "BATCH %u: records past the model's bound",
                             index);
    size_t room = c->record_word_limit - at < n ? (size_t)(c->record_word_limit - at) : n;
    mts_result rc = mts__stream_reserve_records(c, at, room, err);
    if (rc != MTS_OK)
        return mts_error_prefix(err, "BATCH %u", index);
    /* reccodec refuses to write past room: more words than the model's
     * bound allows (MTS_ERR_LIMIT) */
    mts_reccodec_out out = {m->parents + first, m->record_offsets + first, m->record_data + at,
                            room, (uint32_t)at};
    size_t used = 0, words = 0;
    rc = mts_reccodec_decode(p, n, nb, first, count, &out, &used, &words, err);
    if (rc != MTS_OK)
        return mts_error_prefix(err, "BATCH %u", index);
    m->record_word_count = (uint32_t)(at + words);
    mts_cursor cur = mts_cursor_make(p + used, n - used);
    for (uint32_t i = 0; i < count; i++) {
        const uint32_t v = nb + first + i, u = m->parents[first + i];
        if (!reserve_vertices(c, v + 1))
            return mts_error_set(err, MTS_ERR_NOMEM, "BATCH %u: out of memory for %u vertices",
                                 index, v + 1);
        uint32_t *q = c->quantized + 3 * (size_t)v;
        for (int a = 0; a < 3; a++) {
            int64_t x = (int64_t)c->quantized[3 * (size_t)u + a] +
                        (int32_t)mts_unzigzag_u32(mts_cursor_varint(&cur));
            if (!cur.ok || x < 0 || x > maxq)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "BATCH %u: vertex %u is %s", index, v,
                                     cur.ok ? "off the grid" : "cut short");
            q[a] = (uint32_t)x;
        }
        mts_draco_dequantize(&c->grid, q, m->positions + 3 * (size_t)v);
        if (c->oct) {
            uint16_t *o = c->oct + 2 * (size_t)v;
            for (int a = 0; a < 2; a++) {
                int64_t x = (int64_t)c->oct[2 * (size_t)u + a] +
                            (int32_t)mts_unzigzag_u32(mts_cursor_varint(&cur));
                if (!cur.ok || x < 0 || x > MTS__STREAM_NORMAL_MAX)
                    return mts_error_set(err, MTS_ERR_RANGE,
                                         "BATCH %u: vertex %u's normal is %s", index, v,
                                         cur.ok ? "off its code" : "cut short");
                o[a] = (uint16_t)x;
            }
            mts__stream_oct_decode(o, m->normals + 3 * (size_t)v);
        }
        for (int a = 0; a < 3 && m->colors; a++) {
            int64_t x = (int64_t)m->colors[3 * (size_t)u + a] +
                        (int32_t)mts_unzigzag_u32(mts_cursor_varint(&cur));
            if (!cur.ok || x < 0 || x > 255)
                return mts_error_set(err, MTS_ERR_RANGE, "BATCH %u: vertex %u's colour is %s",
                                     index, v, cur.ok ? "off the 0..255 range" : "cut short");
            m->colors[3 * (size_t)v + a] = (uint8_t)x;
        }
    }
    if (mts_cursor_left(&cur) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "BATCH %u: %zu bytes after its records", index,
                             mts_cursor_left(&cur));
    return MTS_OK;
}

/* A batch's header: its index (`expect`), the slots it announces, its splits. */
typedef struct batch_head {
    uint32_t index, more, first, count;
    mts_cursor cur; /* past the header */
} batch_head;

static mts_result take_head(mts_stream_client *c, const uint8_t *p, size_t n, uint32_t expect,
                            uint32_t splits, batch_head *h, mts_error *err)
{
    /* the CRC has checked out (mts_stream_client_frame) */
    h->cur = mts_cursor_make(p, n - 4);
    h->index = mts_cursor_varint(&h->cur);
    h->more = mts_cursor_varint(&h->cur);
    if (!h->cur.ok)
        return mts_error_set(err, MTS_ERR_FORMAT, "BATCH: truncated header");
    if (h->index != expect || h->index >= c->info.batch_count)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "BATCH %u out of order: expected batch %u of %u", h->index, expect,
                             c->info.batch_count);
    /* MODEL_INFO's sizes add up to the levels (mts_wire_parse_model_info) */
    h->first = mts_wire_batch_first(&c->info, h->index);
    h->count = mts_wire_batch_splits(&c->info, h->index);
    if (h->first != splits || h->count > c->model.level_count - h->first)
        return mts_error_set(err, MTS_ERR_INTERNAL, "BATCH %u: the client is at split %u, not %u",
                             h->index, splits, h->first);
    if (h->more > c->model.strip_count - c->announced)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "BATCH %u announces %u slots, past the %u there are (%u so far)",
                             h->index, h->more, c->model.strip_count, c->announced);
    return MTS_OK;
}

/* A splits batch's body after its header: the capacities, then the coded
 * splits (with the full strips' description in the last batch), each
 * split's record derived (one thread) or the split logged for the pool. */
static mts_result take_coded(mts_stream_client *c, batch_head *h, mts_error *err)
{
    char what[32];
    snprintf(what, sizeof what, "BATCH %u", h->index);
    mts_rc_decoder d;
    if (!mts_rc_decoder_init(&d, h->cur.p, mts_cursor_left(&h->cur)))
        return mts_error_set(err, MTS_ERR_FORMAT, "BATCH %u: no coded splits", h->index);
    mts_result rc = take_capacities(c, NULL, &d, c->announced + h->more, what, err);
    if (rc != MTS_OK)
        return rc;
    mts_grow_full full = {.slot_count = c->model.strip_count};
    rc = take_splits(c, &d, &full, h->index, h->first, h->count,
                     (uint32_t)((1ull << c->grid.bits) - 1), err);
    free((void *)full.paths);
    return rc;
}

/* Threads, while the pool derives batch `index`'s records: the batches
 * after it that the reader already holds whole, decoded now (their splits
 * logged for the pool) rather than when their frames are taken, so that
 * the pool never waits for the caller between two frames. Each is still
 * applied only once its own frame is taken (take_batch); a frame that fails
 * its CRC or is no batch stops this and is taken as it comes. */
static void decode_ahead(mts_stream_client *c, uint32_t index, uint32_t upto)
{
    uint32_t ahead;
    while (mts__stream_par_ahead_wanted(c, upto, &ahead)) {
        uint8_t type;
        const uint8_t *p;
        size_t n;
        if (!mts_wire_reader_peek(&c->reader, ahead, &type, &p, &n) || type != MTS_MSG_BATCH ||
            !crc_ok(p, n))
            return;
        const uint32_t expect = index + 1 + ahead;
        if (expect >= c->info.batch_count)
            return; /* more batches than announced: refused when taken */
        batch_head h;
        mts_error e = {0};
        mts_result rc =
            take_head(c, p, n, expect, mts_wire_batch_first(&c->info, expect), &h, &e);
        if (rc == MTS_OK)
            rc = take_coded(c, &h, &e);
        mts__stream_par_ahead_done(c, rc, &e);
        if (rc != MTS_OK)
            return;
    }
}

/* A batch: its header, then either (splits form) the full strips'
 * description in the last batch and the splits, all range-coded, or
 * (records form) the records and vertices. */
static mts_result take_batch(mts_stream_client *c, const uint8_t *p, size_t n, mts_error *err)
{
    batch_head h;
    mts_result rc = MTS_OK;
    if (c->par)
        mts__stream_par_batch_start(c);
    /* threads: decoded already while the batch before was derived */
    const int ahead = c->par ? mts__stream_par_ahead_take(c, &rc, err) : 0;
    if (ahead && rc != MTS_OK)
        return rc;
    if (ahead) {
        /* the frame decode_ahead peeked at, now taken in its turn (a
         * caller that hands frames in itself past the reader is refused) */
        mts_cursor cur = mts_cursor_make(p, n - 4);
        h.index = mts_cursor_varint(&cur);
        if (!cur.ok || h.index != c->batches)
            return mts_error_set(err, MTS_ERR_INTERNAL,
                                 "BATCH: batch %u was decoded ahead, not this frame",
                                 c->batches);
        h.first = mts_wire_batch_first(&c->info, h.index);
        h.count = mts_wire_batch_splits(&c->info, h.index);
    } else if ((rc = take_head(c, p, n, c->batches, c->splits, &h, err)) != MTS_OK) {
        return rc;
    }
    const uint32_t index = h.index, first = h.first, count = h.count;
    /* the runtime goes no further than this batch before it returns */
    if (c->par)
        mts__stream_par_apply_upto(c, first + count);
    if (c->records) {
        const uint32_t maxq = (uint32_t)((1ull << c->grid.bits) - 1);
        char what[32];
        snprintf(what, sizeof what, "BATCH %u", index);
        if ((rc = take_capacities(c, &h.cur, NULL, c->announced + h.more, what, err)) != MTS_OK ||
            (rc = take_records(c, h.cur.p, mts_cursor_left(&h.cur), index, first, count, maxq,
                               err)) != MTS_OK)
            return rc;
        goto applied;
    }
    rc = ahead ? MTS_OK : take_coded(c, &h, err);
    if (rc == MTS_OK && c->par) {
        decode_ahead(c, index, first + count);
        /* the batch's records, in order, before it is applied */
        if ((rc = mts__stream_par_fixup(c, first + count, err)) != MTS_OK)
            rc = mts_error_prefix(err, "BATCH %u", index);
    }
    if (rc != MTS_OK && c->par && c->lod.level > first && !c->lod.broken) {
        /* the runtime went up with the splits (mts__stream_par_catch_up):
         * a batch that fails leaves it where the batch before did, as one
         * thread does */
        mts_error ignored;
        mts_lod_set_available(&c->lod, first);
        (void)mts_lod_set_level(&c->lod, first, &ignored);
    }
    /* where two threads share a core, the rest of the stream on one */
    if (rc == MTS_OK && c->par)
        mts__stream_par_batch_end(c, index);
    if (rc != MTS_OK)
        return rc;
applied:
    c->batches++;
    c->splits += count;
    mts_lod_set_available(&c->lod, c->splits);
    uint32_t target = c->splits < c->stop_level ? c->splits : c->stop_level;
    if ((rc = mts_lod_set_level(&c->lod, target, err)) != MTS_OK)
        return mts_error_prefix(err, "BATCH %u", index);
    return MTS_OK;
}

static mts_result take_end(mts_stream_client *c, const uint8_t *p, size_t n, mts_error *err)
{
    mts_wire_end e;
    mts_result rc = mts_wire_parse_end(p, n, &e, err);
    if (rc != MTS_OK)
        return rc;
    if (e.final_level != c->stop_level || c->lod.level != c->stop_level)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "END at level %u, but the client is at %u of the %u it asked for",
                             e.final_level, c->lod.level, c->stop_level);
    c->end_checksum = e.checksum;
    c->checksum = mts_stream_checksum_colors(&c->lod, c->quantized, c->model.colors);
    if (c->checksum != e.checksum)
        return mts_error_set(err, MTS_ERR_CHECKSUM,
                             "END: the mesh at level %u differs from the server's (checksum "
                             "%016llx, server %016llx)",
                             e.final_level, (unsigned long long)c->checksum,
                             (unsigned long long)e.checksum);
    return MTS_OK;
}

static void skip_model(void *user, const mts_wire_model_entry *m)
{
    (void)user;
    (void)m;
}

mts_result mts_stream_client_frame(mts_stream_client *c, uint8_t type, const uint8_t *payload,
                                   size_t size, mts_stream_event *event, mts_error *err)
{
    *event = MTS_EV_NONE;
    c->rejected = 0;
    mts_result rc;
    if (c->state == ST_FAILED || c->state == ST_DONE)
        return mts_error_set(err, MTS_ERR_ARG, "stream: frame after the end of the stream");
    if (type == MTS_MSG_ERROR) {
        if ((rc = mts_wire_parse_error(payload, size, &c->error_code, c->error_text,
                                       sizeof c->error_text, err)) != MTS_OK)
            return fail(c, rc);
        c->state = ST_DONE;
        *event = MTS_EV_ERROR;
        return MTS_OK;
    }
    switch (c->state) {
    case ST_INFO:
        if (c->resuming) {
            if (type != MTS_MSG_MODEL_INFO)
                break;
            if ((rc = check_resumed_info(c, payload, size, err)) != MTS_OK)
                return fail(c, rc);
            c->state = c->batches == 0 ? ST_SKIP_BASE : ST_BATCHES;
            c->resumes++;
            *event = MTS_EV_RESUMED;
            return MTS_OK;
        }
        if (type == MTS_MSG_MODELS) {
            /* the whole listing is checked before any entry is handed on:
             * a caller that prints them must not print half a bad frame */
            if ((rc = mts_wire_parse_models(payload, size, skip_model, NULL, err)) != MTS_OK ||
                (rc = mts_wire_parse_models(payload, size, c->on_model ? c->on_model : skip_model,
                                            c->user, err)) != MTS_OK)
                return fail(c, rc);
            c->state = ST_DONE;
            *event = MTS_EV_MODELS;
            return MTS_OK;
        }
        if (type != MTS_MSG_MODEL_INFO)
            break;
        if ((rc = take_info(c, payload, size, err)) != MTS_OK)
            return fail(c, rc);
        c->state = ST_BASE;
        *event = MTS_EV_INFO;
        return MTS_OK;
    case ST_BASE:
        if (type != MTS_MSG_BASE)
            break;
        if (!crc_ok(payload, size))
            return reject(c, mts_error_set(err, MTS_ERR_CHECKSUM,
                                           "BASE: checksum mismatch; not applied"));
        if ((rc = take_base(c, payload, size, err)) != MTS_OK)
            return fail(c, rc);
        c->state = ST_BATCHES;
        *event = MTS_EV_BASE;
        return MTS_OK;
    case ST_SKIP_BASE:
        /* the same stream_id means the same bytes: this BASE is the one in
         * place; the CRC still guards against a corrupted frame */
        if (type != MTS_MSG_BASE)
            break;
        if (!crc_ok(payload, size))
            return reject(c, mts_error_set(err, MTS_ERR_CHECKSUM,
                                           "BASE (resumed): checksum mismatch; not applied"));
        c->state = ST_BATCHES;
        return MTS_OK;
    case ST_BATCHES:
        if (type == MTS_MSG_BATCH) {
            if (!crc_ok(payload, size))
                return reject(c, mts_error_set(err, MTS_ERR_CHECKSUM,
                                               "BATCH %u: checksum mismatch; rejected, not "
                                               "applied",
                                               c->batches));
            if ((rc = take_batch(c, payload, size, err)) != MTS_OK)
                return fail(c, rc);
            *event = MTS_EV_BATCH;
            return MTS_OK;
        }
        if (type != MTS_MSG_END)
            break;
        if ((rc = take_end(c, payload, size, err)) != MTS_OK)
            return fail(c, rc);
        c->state = ST_DONE;
        *event = MTS_EV_END;
        return MTS_OK;
    }
    return fail(c, mts_error_set(err, MTS_ERR_FORMAT, "stream: unexpected message type %u",
                                 type));
}

mts_result mts_stream_client_feed(mts_stream_client *c, const void *data, size_t size,
                                  mts_error *err)
{
    return mts_wire_reader_feed(&c->reader, data, size, err);
}

int mts_stream_client_next(mts_stream_client *c, mts_stream_event *ev, mts_error *err)
{
    *ev = MTS_EV_NONE;
    uint8_t type;
    const uint8_t *p;
    size_t n;
    int got = mts_wire_reader_next(&c->reader, &type, &p, &n, err);
    if (got < 0) {
        /* a length that cannot be leaves no way to find the next frame; a
         * stream that had ended stays ended (it may still continue) */
        c->rejected = 0;
        if (c->state != ST_DONE)
            c->state = ST_FAILED;
        return -1;
    }
    if (got == 0)
        return 0;
    mts_result rc = mts_stream_client_frame(c, type, p, n, ev, err);
    if (rc != MTS_OK) {
        if (err)
            err->code = rc; /* what a caller of next has for the result */
        return -1;
    }
    return 1;
}

size_t mts_stream_client_buffered(const mts_stream_client *c)
{
    return c->reader.len - c->reader.start;
}

int mts_stream_client_resume_point(const mts_stream_client *c, uint32_t *resume_batch,
                                   uint64_t *stream_id)
{
    *resume_batch = 0;
    *stream_id = 0;
    if (c->state == ST_DONE || c->state == ST_FAILED)
        return 0;
    if (c->have_lod && c->batches > 0) {
        /* with those decoded ahead, which reconnected applies */
        *resume_batch = c->batches + mts__stream_par_ahead_batches(c);
        *stream_id = c->info.stream_id;
    }
    return 1;
}

mts_result mts_stream_client_continue(mts_stream_client *c, uint32_t *resume_batch,
                                      uint64_t *stream_id, mts_error *err)
{
    if (c->state != ST_DONE || !c->have_lod || !c->end_checksum || c->lod.broken)
        return mts_error_set(err, MTS_ERR_ARG,
                             "stream: only a stream that ended with a checked END continues");
    *resume_batch = c->batches;
    *stream_id = c->info.stream_id;
    c->state = ST_INFO;
    c->resuming = 1;
    c->continuing = 1;
    c->end_checksum = 0;
    mts_wire_reader_free(&c->reader);
    return MTS_OK;
}

mts_result mts_stream_client_reconnected(mts_stream_client *c, mts_error *err)
{
    if (c->state == ST_DONE || c->state == ST_FAILED)
        return mts_error_set(err, MTS_ERR_ARG, "stream: cannot resume a stream that %s",
                             c->state == ST_DONE ? "ended" : "failed");
    if (!c->have_lod) {
        /* nothing applied yet: start over, keeping only the caller's hooks */
        void (*on_model)(void *, const mts_wire_model_entry *) = c->on_model;
        void *user = c->user;
        uint32_t resumes = c->resumes, threads = c->threads, alone = c->threads_alone_after;
        const int hand = c->threads_hand_key_paths, at_keys = c->threads_at_keys;
        mts_bigmem_cache *memory = c->memory;
        mts_stream_client_free(c);
        mts_stream_client_init(c);
        c->on_model = on_model;
        c->user = user;
        c->threads = threads;
        c->threads_alone_after = alone;
        c->threads_hand_key_paths = hand;
        c->threads_at_keys = at_keys;
        c->memory = memory;
        c->resumes = resumes;
        return MTS_OK;
    }
    /* batches decoded ahead (threads) are in the decoder already: they are
     * taken now, so that the resume asks for what comes after them (their
     * frames are whole in the reader, which is about to go) */
    mts__stream_par_ahead_hold(c, 1); /* those alone, not the whole frames after them */
    while (mts__stream_par_ahead_batches(c)) {
        mts_stream_event ev;
        int got = mts_stream_client_next(c, &ev, err);
        if (got < 0)
            return err ? err->code : MTS_ERR_FORMAT;
        if (got == 0)
            return fail(c, mts_error_set(err, MTS_ERR_INTERNAL,
                                         "stream: a batch decoded ahead is no longer buffered"));
    }
    mts__stream_par_ahead_hold(c, 0);
    /* from ST_BATCHES, ST_SKIP_BASE, or ST_INFO of a resume broken again */
    c->state = ST_INFO;
    c->resuming = 1;
    mts_wire_reader_free(&c->reader);
    return MTS_OK;
}
