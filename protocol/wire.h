/* The wire format of PROTOCOL.md: frames, and the messages that do not need
 * model state to encode or check (HELLO, LIST, MODEL_INFO, END, MODELS,
 * ERROR). BASE and BATCH are built and applied by the stream module. Every
 * parser checks the payload against its bounds and returns a clear error;
 * nothing read is trusted. */
#ifndef MTS_WIRE_H
#define MTS_WIRE_H

#include <stddef.h>
#include <stdint.h>

#include "bytes.h"
#include "error.h"

/* 4.0: batches entropy-coded, normals only where the source had them;
 * 4.1: the records form, asked for by a HELLO flag; 5.0: the records a
 * client derives follow the corner-table growth (key levels by quality,
 * rings from a vertex's listed corner) and END sums strips in pairs; 6.0:
 * a split's parent is coded against the previous one's; 7.1: vertex
 * colours, under a MODEL_INFO flag a 7.0 client refuses, every other
 * stream byte for byte as in 7.0 (PROTOCOL.md, "Changes"). A peer of
 * another major version is refused at HELLO with ERROR version. */
#define MTS_WIRE_MAJOR 7
#define MTS_WIRE_MINOR 1

/* Each key level costs a client a stripification of the whole mesh there, so
 * a client bounds how many it takes (the builder makes 13 on bunny00 and on
 * a 1.2M-triangle mesh). */
#define MTS_WIRE_MAX_KEYS 256u
#define MTS_WIRE_MAX_FRAME (16u << 20) /* type + payload */
#define MTS_WIRE_MAX_NAME 64
#define MTS_WIRE_HEADER 5 /* u32 length, u8 type */

typedef enum mts_wire_type {
    MTS_MSG_HELLO = 1,
    MTS_MSG_LIST = 2,
    MTS_MSG_MODEL_INFO = 16,
    MTS_MSG_BASE = 17,
    MTS_MSG_BATCH = 18,
    MTS_MSG_END = 19,
    MTS_MSG_MODELS = 20,
    MTS_MSG_ERROR = 31
} mts_wire_type;

typedef enum mts_wire_error_code {
    MTS_WERR_PROTOCOL = 1,
    MTS_WERR_VERSION = 2,
    MTS_WERR_UNKNOWN_MODEL = 3,
    MTS_WERR_BUSY = 4,
    MTS_WERR_STALE = 5,
    MTS_WERR_TIMEOUT = 6,
    MTS_WERR_INTERNAL = 7
} mts_wire_error_code;

typedef enum mts_wire_stop {
    MTS_STOP_FULL = 0,
    MTS_STOP_LEVEL = 1,
    MTS_STOP_TRIANGLES = 2,
    MTS_STOP_FRACTION = 3 /* stop_value in millionths */
} mts_wire_stop;

typedef struct mts_wire_hello {
    uint16_t major, minor;
    char model[MTS_WIRE_MAX_NAME + 1];
    uint8_t stop_kind;
    uint32_t stop_value;
    uint32_t resume_batch;
    uint64_t stream_id;
    uint32_t flags;
} mts_wire_hello;

typedef struct mts_wire_model_info {
    uint16_t minor;
    uint64_t stream_id;
    char model[MTS_WIRE_MAX_NAME + 1];
    uint32_t vertices, base_vertices, levels, triangles, strips;
    uint32_t stop_level, stop_triangles;
    float bbox_min[3], bbox_max[3];
    uint8_t quant_bits;
    uint8_t flags; /* MTS_INFO_* */
    float grid_origin[3], grid_range;
    uint32_t batch_count;
    uint32_t batch_size;    /* splits in every batch but the last, which has
                             * the rest (1..batch_size): mts_wire_batch_splits */
    uint32_t capacity_total; /* the slots' capacities added up (each slot's own
                              * comes with the frame that first uses it) */
    uint32_t key_count;     /* at most MTS_WIRE_MAX_KEYS */
    uint32_t *key_levels;   /* key_count, ascending in 1..levels-1 */
} mts_wire_model_info;

/* Batch k's first split and its splits (k < batch_count; parsing checked
 * that the sizes add up to levels). */
static inline uint32_t mts_wire_batch_first(const mts_wire_model_info *mi, uint32_t k)
{
    return k * mi->batch_size;
}

static inline uint32_t mts_wire_batch_splits(const mts_wire_model_info *mi, uint32_t k)
{
    return k + 1 < mi->batch_count ? mi->batch_size : mi->levels - k * mi->batch_size;
}

/* MODEL_INFO flags: the stream carries per-vertex normals (the source's
 * own); without it a client shades the faces it has. */
#define MTS_INFO_NORMALS 1u
/* MODEL_INFO flags: the batches are in the records form (PROTOCOL.md,
 * "Records form"): each split's record travels, so the client derives none. */
#define MTS_INFO_RECORDS 2u
/* MODEL_INFO flags: the stream carries a colour per vertex (3 bytes, 8-bit
 * sRGB: Draco's COLOR attribute in BASE, a coded residual a split), since
 * 7.1; a stream client holds them in c->model.colors, grown with the
 * vertices that arrived (vertex_room), and MTS_MODEL_COLORS in c->model.flags. */
#define MTS_INFO_COLORS 4u
#define MTS_INFO_KNOWN_FLAGS (MTS_INFO_NORMALS | MTS_INFO_RECORDS | MTS_INFO_COLORS)

/* HELLO flags: the client would rather have the records form (many more
 * bytes, far less work to apply); a server without it sends the splits form,
 * and MODEL_INFO's flags say which came. */
#define MTS_HELLO_RECORDS 1u

typedef struct mts_wire_end {
    uint32_t final_level;
    uint64_t checksum;
    uint32_t stream_bytes;
} mts_wire_end;

typedef struct mts_wire_model_entry {
    char name[MTS_WIRE_MAX_NAME + 1];
    uint32_t vertices, triangles, levels, stream_bytes;
} mts_wire_model_entry;

/* The one rule for a model's name, on the wire, in a models folder and on
 * the command line: 1..64 bytes of [A-Za-z0-9._-], not starting with '.'
 * (no hidden files, no paths). MTS_OK, or MTS_ERR_ARG with what breaks it
 * (the name shown in printable ASCII). */
mts_result mts_wire_check_name(const char *name, size_t len, mts_error *err);

/* 1 when mts_wire_check_name accepts it. */
int mts_wire_valid_name(const char *name, size_t len);

/* Frames: begin writes the header with a placeholder length, end patches it. */
size_t mts_wire_frame_begin(mts_buf *b, uint8_t type);
void mts_wire_frame_end(mts_buf *b, size_t frame_start);

void mts_wire_put_hello(mts_buf *b, const mts_wire_hello *h);
void mts_wire_put_list(mts_buf *b);
void mts_wire_put_model_info(mts_buf *b, const mts_wire_model_info *mi);
/* MODEL_INFO in two parts: the head (ids, counts and the stop point) differs
 * per connection; the tail (box, grid, batch sizes, the capacities' total) is the
 * same for every connection to a stream, so a server encodes it once and
 * sends it from one shared buffer. The head's frame length counts tail_size
 * bytes to follow. */
void mts_wire_put_model_info_head(mts_buf *b, const mts_wire_model_info *mi, size_t tail_size);
void mts_wire_put_model_info_tail(mts_buf *b, const mts_wire_model_info *mi);
void mts_wire_put_end(mts_buf *b, const mts_wire_end *e);
void mts_wire_put_models(mts_buf *b, const mts_wire_model_entry *models, uint32_t count);
void mts_wire_put_error(mts_buf *b, uint16_t code, const char *text);

mts_result mts_wire_parse_hello(const uint8_t *payload, size_t size, mts_wire_hello *h,
                                mts_error *err);
/* Allocates mi's arrays (free with mts_wire_model_info_free). */
mts_result mts_wire_parse_model_info(const uint8_t *payload, size_t size,
                                     mts_wire_model_info *mi, mts_error *err);
void mts_wire_model_info_free(mts_wire_model_info *mi);
mts_result mts_wire_parse_end(const uint8_t *payload, size_t size, mts_wire_end *e,
                              mts_error *err);
/* Calls fn for each model entry. */
mts_result mts_wire_parse_models(const uint8_t *payload, size_t size,
                                 void (*fn)(void *user, const mts_wire_model_entry *m),
                                 void *user, mts_error *err);
/* A peer's text as it may be shown or written: copied into out (out_size
 * bytes with the terminator), each control character and each byte of a
 * sequence that is not well-formed UTF-8 replaced by '?', cut only between
 * characters. Returns the bytes written. */
size_t mts_wire_clean_text(char *out, size_t out_size, const char *in, size_t len);

/* text is copied as mts_wire_clean_text does, at most text_size - 1 bytes. */
mts_result mts_wire_parse_error(const uint8_t *payload, size_t size, uint16_t *code, char *text,
                                size_t text_size, mts_error *err);
const char *mts_wire_error_name(uint16_t code);

/* An incremental frame reader: bytes go in split anywhere (one at a time
 * works), whole frames come out. A frame's length is checked as soon as its
 * header is complete, so an oversized frame is refused before it is buffered. */
typedef struct mts_wire_reader {
    uint8_t *buf;
    size_t len, start, cap;
    uint64_t bytes_in;
} mts_wire_reader;

void mts_wire_reader_free(mts_wire_reader *r);
mts_result mts_wire_reader_feed(mts_wire_reader *r, const void *data, size_t size,
                                mts_error *err);
/* 1: a frame is ready (payload valid until the next feed or next call);
 * 0: more bytes needed; -1: a bad frame header (err says why). */
int mts_wire_reader_next(mts_wire_reader *r, uint8_t *type, const uint8_t **payload,
                         size_t *size, mts_error *err);
/* The frame after the next `skip` ones, left in place for next to take:
 * 1 when it is all there (payload valid until the next feed or next call),
 * 0 when it is not, or a header on the way is bad (next reports that). */
int mts_wire_reader_peek(const mts_wire_reader *r, uint32_t skip, uint8_t *type,
                         const uint8_t **payload, size_t *size);

#endif
