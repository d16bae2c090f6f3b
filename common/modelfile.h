/* The .mtsm model file: a versioned, little-endian container with a section
 * table and a CRC-32C per section.
 *
 *   0   "MTSM"                     magic
 *   4   u16 major = 5, u16 minor   a reader accepts its own major version only
 *   8   u32 section_count          at most 64
 *   12  u32 header_crc             CRC-32C of bytes 0..11 and the table
 *   16  section_count x { u32 id, u32 crc32c, u64 offset, u64 size }
 *       sections, each 8-byte aligned
 *
 * Sections (all required but SOURCE, GROWTH, KEY and COLORS; unknown ids
 * are skipped):
 *   1 INFO        u32 vertices, base_vertices, levels, strips, full_indices,
 *                 base_indices, record_words, capacity_total;
 *                 f32 bbox_min[3], bbox_max[3]; u32 flags (model.h's
 *                 MTS_MODEL_*: bit 0, the normals are the source's own;
 *                 bit 1, the model has colours)
 *   2 POSITIONS   f32 x 3 per vertex, stream order
 *   3 NORMALS     f32 x 3 per vertex
 *   4 STRIPS_FULL u32 length per strip, then the indices
 *   5 STRIPS_BASE the same at level 0
 *   6 SPLITS      every split's parent and record, varint-encoded (reccodec.h)
 *   7 LEVELS      per level 0..levels: zigzag varint deltas of triangles,
 *                 strips, indices
 *   8 SOURCE      UTF-8 text: what the model was built from
 *   9 CAPACITY    u32 per strip: its capacity (model.h), adding up to
 *                 capacity_total
 *  10 GROWTH      varint key_count, the key levels as deltas, then every
 *                 split's description (model.h: start, count, sides, and
 *                 the lists of an explicit one), all varints. What a stream
 *                 sends instead of the records; absent only in models made
 *                 by hand, which a server refuses to stream
 *  11 KEY         UTF-8 text: the build key (model.h), written with GROWTH
 *                 (empty when there is none); absent in older files
 *  12 COLORS      u8 red, green, blue per vertex (8-bit sRGB), stream order;
 *                 present exactly when INFO's flags have MTS_MODEL_COLORS
 *                 (bit 1), and then the file says version 5.2 (a model
 *                 without colours is still written as 5.1, byte for byte).
 *                 A 5.1 reader refuses a coloured file by its unknown flag
 *                 rather than stream it grey
 * Fixed-size sections must have exactly the size INFO's counts give; the
 * varint sections must parse to exactly their end, and INFO's counts must
 * fit their sizes (a varint is a byte at least) before anything is allocated.
 * capacity_total may not pass base_indices + record_words: a slot grows only
 * by the indices records insert, so no real model needs more, and a runtime's
 * slots stay as small as the file.
 *
 * Version 2 added erase runs to the records and the CAPACITY section;
 * version 3 the GROWTH section and full strips in the form growth derives;
 * version 4 (this one) INFO's flags, so a stream knows whether the normals
 * are worth sending. Older files are refused with a message to rebuild them.
 *
 * Loading checks the header, the table, every section's bounds, size and
 * checksum, then the whole model (mts_model_validate), so each kind of damage
 * gets its own error: truncated, not a model, unsupported version, checksum,
 * inconsistent sizes, out-of-range index. */
#ifndef MTS_MODELFILE_H
#define MTS_MODELFILE_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"
#include "model.h"

#define MTS_MODELFILE_MAJOR 5
#define MTS_MODELFILE_MINOR 2 /* 5.1: the KEY section; 5.2: the COLORS section */
/* What a model without colours is written as: the file 5.1 wrote, byte for
 * byte, so that nothing changes for the models that have none. */
#define MTS_MODELFILE_MINOR_PLAIN 1

/* Serialises a model into a new buffer (free with free()). */
mts_result mts_modelfile_encode(const mts_model *model, uint8_t **data, size_t *size,
                                mts_error *err);

/* Parses and validates; name is used in messages. */
mts_result mts_modelfile_decode(const void *data, size_t size, const char *name,
                                mts_model *model, mts_error *err);

/* Writes atomically (a temporary file renamed into place). */
mts_result mts_modelfile_save(const mts_model *model, const char *path, uint64_t *bytes,
                              mts_error *err);

mts_result mts_modelfile_load(const char *path, mts_model *model, mts_error *err);

#endif
