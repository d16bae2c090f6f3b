/* A stream file (PROTOCOL.md, "Stream files"): a model's stream as one
 * static file that any web server can hand out with HTTP range requests.
 *
 * The stream is encoded once and never changes, and what mts-server does
 * per connection -- send the base and the batches up to a stop, or from a
 * batch on -- is a byte range of it given an index of where each batch
 * starts. The file is laid out so that the first picture costs a client
 * little more than over TCP, and so that every fetch is one contiguous
 * range:
 *
 *   header      32 bytes: magic, version, the sizes of the next two parts
 *   MODEL_INFO  the frame as the wire carries it, stop level = the full one
 *   table       per batch: its frame's size and the triangle counts the LOD
 *               policies need to turn a triangle budget into a range
 *   BASE        the frame as the wire carries it
 *   checks      the mesh checksum (END's) at level 0 and after each batch
 *   BATCH ...   the frames as the wire carries them
 *
 * A client reads the prefix (header, MODEL_INFO, table) with one request,
 * then the BASE, the checks and the batches up to its stop with a second;
 * a resume or a continuation asks for the batches from the first it does
 * not hold. The checks sit after BASE, not in the prefix, so that they are
 * not in the way of the first picture; they reach a client in the same
 * range as the batches they check. A stop inside a batch is verified at
 * the end of that batch (the client holds its splits anyway) and settled
 * back down to the stop: the state at any level is a function of the level
 * alone, so that is END's check.
 *
 * Nothing here trusts the file: sizes, counts and offsets are checked
 * against each other and against the bytes that came before anything is
 * allocated or fed on. No I/O: the caller fetches (libcurl, fetch(), a
 * local read) and hands the bytes in. */
#ifndef MTS_STREAM_FILE_H
#define MTS_STREAM_FILE_H

#include <stddef.h>
#include <stdint.h>

#include "bytes.h"
#include "error.h"
#include "stream.h"
#include "wire.h"

#define MTS_SFILE_MAGIC "MTSF"
#define MTS_SFILE_MAJOR 1
#define MTS_SFILE_MINOR 0
#define MTS_SFILE_HEADER_SIZE 32
/* What a client asks for first: in one request, the prefix of nearly every
 * model (bunny00's is under 1 KB) and the start of its BASE. */
#define MTS_SFILE_FIRST_REQUEST 4096

/* Writes s (a splits form or a records form) as a stream file into out. */
mts_result mts_stream_file_write(const mts_stream *s, mts_buf *out, mts_error *err);

/* What a stream file's prefix says. */
typedef struct mts_stream_file_index {
    uint16_t major, minor;
    uint64_t file_size;
    uint64_t prefix_size;       /* header, MODEL_INFO and table */
    mts_wire_model_info info;   /* MODEL_INFO, its stop at the full level */
    uint32_t batch_count;
    uint64_t base_offset, base_size;
    uint64_t checks_offset, checks_size;
    uint64_t *batch_offset;     /* batch_count + 1: where BATCH k starts; the last is
                                   file_size */
    uint64_t *level_triangles_first; /* batch_count: triangles after batch k's first split */
    uint64_t *boundary_triangles;    /* batch_count + 1: at level 0 and after each batch */
} mts_stream_file_index;

/* From the first MTS_SFILE_HEADER_SIZE bytes: the prefix's size (header,
 * MODEL_INFO and table), so that a caller that fetched less fetches the rest.
 * MTS_ERR_FORMAT when the bytes are not a stream file of a version this reads
 * (the message says which), MTS_ERR_RANGE when the file is over max_bytes
 * (0: no cap). */
mts_result mts_stream_file_prefix_size(const uint8_t *header, size_t size, uint64_t max_bytes,
                                       uint64_t *prefix_size, mts_error *err);

/* Parses the prefix (at least prefix_size bytes from the start of the file;
 * more are ignored). idx is zeroed first; free it with
 * mts_stream_file_index_free, also after a failure. */
mts_result mts_stream_file_index_parse(const uint8_t *data, size_t size, uint64_t max_bytes,
                                       mts_stream_file_index *idx, mts_error *err);
void mts_stream_file_index_free(mts_stream_file_index *idx);

/* Where a stop lies in the file. */
typedef struct mts_stream_file_plan {
    uint32_t stop_level;    /* the level the stream ends at; for a triangle stop,
                               the boundary until the batches are in */
    int by_triangles;       /* the exact level is found once they are */
    uint64_t max_triangles; /* ... the largest level with at most these */
    uint32_t batches;       /* batches 0..batches-1 are needed */
    uint32_t boundary;      /* the level after them: where the checks verify */
    uint64_t from, to;      /* the bytes to fetch, [from, to) */
} mts_stream_file_plan;

/* The plan for a stop point (MTS_STOP_* and its value, as in HELLO),
 * fetching from batch first_batch on (0: from BASE, a fresh start; else the
 * batches a client does not hold, as a resume or a continuation asks).
 * MTS_ERR_RANGE when first_batch is past the batches the stop needs. */
mts_result mts_stream_file_plan_stop(const mts_stream_file_index *idx, uint8_t stop_kind,
                                     uint32_t stop_value, uint32_t first_batch,
                                     mts_stream_file_plan *plan, mts_error *err);

/* Reads the bytes of a plan into a stream client as they arrive, in order:
 * the frames go to the client (mts_stream_client_feed), the checks are kept.
 * Zero it before the first use; free it with mts_stream_file_reader_free. */
typedef struct mts_stream_file_reader {
    const mts_stream_file_index *idx;
    mts_stream_file_plan plan;
    uint64_t at;       /* the file offset of the next byte expected */
    uint8_t *checks;   /* idx->checks_size bytes once they came */
    uint64_t checks_have;
    int checks_ok;     /* whole and their CRC checked */
} mts_stream_file_reader;

/* Starts a range: feeds c the MODEL_INFO of the plan's stop (c must be
 * fresh, or readied by mts_stream_client_reconnected or _continue), after
 * which the caller fetches [plan->from, plan->to) and hands the bytes to
 * mts_stream_file_reader_feed. */
mts_result mts_stream_file_reader_begin(mts_stream_file_reader *r,
                                        const mts_stream_file_index *idx,
                                        const mts_stream_file_plan *plan, mts_stream_client *c,
                                        mts_error *err);

/* Takes the next bytes of the range (the caller then takes the client's
 * events with mts_stream_client_next). Bytes past the range are refused:
 * a caller whose server ignored the range cuts the body to it itself. */
mts_result mts_stream_file_reader_feed(mts_stream_file_reader *r, mts_stream_client *c,
                                       const uint8_t *data, size_t size, mts_error *err);

/* 1 once every byte of the range came. */
int mts_stream_file_reader_done(const mts_stream_file_reader *r);

/* Once the range is in and every frame of it taken: verifies the mesh at the
 * plan's boundary against the checks, settles at the stop level (for a
 * triangle stop, the largest level with at most that many triangles) and
 * ends the stream as END does (*event MTS_EV_END, c->checksum that level's).
 * A mismatch is MTS_ERR_CHECKSUM naming the level. */
mts_result mts_stream_file_reader_end(mts_stream_file_reader *r, mts_stream_client *c,
                                      mts_stream_event *event, mts_error *err);

void mts_stream_file_reader_free(mts_stream_file_reader *r);

#endif
