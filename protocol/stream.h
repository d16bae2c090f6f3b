/* A model's wire stream (PROTOCOL.md), both ends.
 *
 * Server: mts_stream_build turns a model into an immutable byte stream -- a
 * BASE frame (Draco base mesh + base strips) and BATCH frames (range-coded
 * splits: parent, fan code, vertex position and, where the source had them,
 * normal, each against a prediction from the mesh both ends hold; the last
 * batch also describes the full strips) -- encoded once and shared
 * read-only by every connection; a connection is then an offset range into
 * it plus two small per-connection frames (MODEL_INFO, END). Building runs
 * the growth a client will run (grow.h), to predict as the client will, and
 * fixes the model the stream stands for: positions snapped to the
 * quantization grid, normals as the client will decode them (none where the
 * source had none), base vertices renumbered to grid order (PROTOCOL.md). A
 * client that applies the whole stream holds exactly that model.
 *
 * The records form (s->records_form, PROTOCOL.md "Records form") carries
 * the records themselves instead, for clients that would rather spend bytes
 * than work.
 *
 * Client: mts_stream_client takes frames as they arrive, checks each against
 * its bounds, the CRC and the state so far, derives every split's record
 * with the same growth (or, in the records form, decodes it), and applies
 * every batch through the LOD runtime
 * (mts_lod), so a renderer can follow along. After a broken
 * connection it takes a new conversation that resumes from the last batch it
 * applied (mts_stream_client_resume_point, mts_stream_client_reconnected). */
#ifndef MTS_STREAM_H
#define MTS_STREAM_H

#include <signal.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "bigmem.h"
#include "bytes.h"
#include "draco.h"
#include "error.h"
#include "lod.h"
#include "model.h"
#include "wire.h"

/* Where a splits-form stream's bytes go (the full stream: MODEL_INFO, BASE,
 * every BATCH, END). The range-coded fields are given as the information
 * the coder was handed for them (-log2 of each coded bit's probability),
 * which the coded bytes match to within the coder's flush bytes
 * (coded_bytes - the fields' bits / 8). */
typedef struct mts_stream_breakdown {
    size_t info_bytes;       /* the MODEL_INFO frame, header included */
    size_t info_batch_bytes; /* of it: the batch sizes */
    size_t capacity_bytes;   /* the slot capacities BASE announces (the batches'
                                are a coded field: capacity_bits) */
    size_t base_bytes;       /* the BASE frame */
    size_t base_draco_bytes; /* of it: the Draco base mesh */
    size_t base_strip_bytes; /* of it: the base strips (capacities apart) */
    size_t batch_bytes;      /* every BATCH frame */
    size_t coded_bytes;      /* of them: the range-coded bodies */
    size_t end_bytes;        /* the END frame */
    size_t framing_bytes;    /* frame headers, batch headers (capacities apart) and
                                CRCs of BASE and BATCHes */
    double parent_bits, fan_bits, position_bits, normal_bits, full_strips_bits, capacity_bits;
    double color_bits; /* the splits' colours (the base's are in base_draco_bytes) */
    uint32_t vertices, base_vertices, splits;
} mts_stream_breakdown;

/* Zero-initialised means the defaults. */
typedef struct mts_stream_options {
    int quant_bits;          /* position grid; 0 = 14 */
    uint32_t batch_splits;   /* splits per batch; 0 = levels / 100 within 64..2048 */
    int draco_method;        /* mts_draco_method; 0 = edgebreaker (sequential as fallback) */
    int with_records;        /* also build the records form (s->records_form) */
    /* when not NULL and set (a signal, another thread), building stops
     * early with MTS_ERR_ARG "cancelled"; polled every few thousand splits */
    const atomic_int *cancel; /* lock-free: a signal handler may set it */
    /* when not NULL, filled in with where the bytes go (costs a log2 a
     * coded bit while encoding) */
    mts_stream_breakdown *breakdown;
} mts_stream_options;

typedef struct mts_stream {
    char name[MTS_WIRE_MAX_NAME + 1];
    uint64_t stream_id;
    mts_model model;          /* what the stream stands for (owned) */
    uint32_t *quantized;      /* grid point of every vertex, 3 each */
    mts_draco_grid grid;
    int draco_method;         /* the one used (after any fallback) */
    uint8_t *bytes;           /* BASE frame, then BATCH frames */
    size_t size;
    uint32_t batch_count;
    uint32_t *batch_first;    /* batch_count + 1: first split of each batch */
    uint32_t *announced;      /* batch_count + 1: slots whose capacities have
                                 come after BASE ([0]) and after each batch */
    size_t *batch_offset;     /* batch_count + 1: where each BATCH frame starts in bytes */
    uint64_t *level_checksum; /* levels + 1 */
    uint8_t *info_tail;       /* MODEL_INFO's shared part (mts_wire_put_model_info_tail) */
    size_t info_tail_size;
    /* The records form (PROTOCOL.md, "Records form"): the same model, BASE
     * and batching, but each batch carries its splits' records, so a client
     * applies them without deriving anything; about 16x the bytes. Built
     * when opts->with_records, else NULL. It is an mts_stream of its own,
     * so every call here takes it as it takes the splits form; its model,
     * grid points, batching and checksums are this stream's, borrowed, so
     * it lives and dies with this one. */
    struct mts_stream *records_form;
    uint16_t *oct; /* the normals' codes, where the stream carries normals (a
                      records form sends them as they are) */
    int records;  /* this is a records form */
    int borrowed; /* model, quantized, batch_first, level_checksum are another's */
} mts_stream;

mts_result mts_stream_build(const mts_model *model, const char *name,
                            const mts_stream_options *opts, mts_stream *stream, mts_error *err);

/* Builds s->records_form when s has none (mts_stream_build's with_records
 * does it at once; a server may do it after publishing s, for clients that
 * can wait: it must then not read s->records_form meanwhile). */
mts_result mts_stream_add_records_form(mts_stream *s, mts_error *err);

/* The form a HELLO's flags ask for: s->records_form when it asks for
 * records and s has them, else s. */
const mts_stream *mts_stream_for_hello(const mts_stream *s, uint32_t hello_flags);
void mts_stream_free(mts_stream *stream);

/* The level a HELLO's stop point resolves to (PROTOCOL.md, HELLO). */
uint32_t mts_stream_stop_level(const mts_stream *s, uint8_t stop_kind, uint32_t stop_value);

/* The bytes of s->bytes a connection is sent: the BASE frame unless it
 * resumes (resume_batch > 0), then batches from resume_batch through the one
 * that reaches stop_level. MTS_ERR_RANGE when resume_batch is past them. */
mts_result mts_stream_range(const mts_stream *s, uint32_t resume_batch, uint32_t stop_level,
                            size_t *offset, size_t *length, mts_error *err);

void mts_stream_put_model_info(const mts_stream *s, uint32_t stop_level, mts_buf *out);
/* Only MODEL_INFO's per-connection head; s->info_tail must follow it on the
 * wire (a server sends it from the stream's buffer, not a copy). */
void mts_stream_put_model_info_head(const mts_stream *s, uint32_t stop_level, mts_buf *out);
void mts_stream_put_end(const mts_stream *s, uint32_t stop_level, uint32_t bytes_before_end,
                        mts_buf *out);

/* The mesh checksum of PROTOCOL.md's END at the runtime's current level:
 * strips and the grid points of the vertices present. */
uint64_t mts_stream_checksum(const mts_lod *lod, const uint32_t *quantized);
/* The same for a stream with colours (colors: 3 bytes a vertex present),
 * which END sums too; NULL for none, which is mts_stream_checksum. */
uint64_t mts_stream_checksum_colors(const mts_lod *lod, const uint32_t *quantized,
                                    const uint8_t *colors);

/* ---- client ---- */

typedef enum mts_stream_event {
    MTS_EV_NONE = 0,
    MTS_EV_INFO,   /* MODEL_INFO taken: c->info is valid */
    MTS_EV_BASE,   /* base mesh and strips in place: c->lod at level 0 */
    MTS_EV_BATCH,  /* a batch applied: c->lod moved up */
    MTS_EV_END,    /* END checked: the stream is complete */
    MTS_EV_ERROR,  /* the server sent ERROR: c->error_code, c->error_text */
    MTS_EV_MODELS, /* a MODELS listing (c->listing_count entries, via callback) */
    MTS_EV_RESUMED /* a resumed conversation's MODEL_INFO matched the first:
                      batches go on from c->batches */
} mts_stream_event;

typedef struct mts_stream_client {
    int state;
    mts_wire_model_info info;
    mts_model model;       /* filled as the stream arrives; its slot capacities
                              come with BASE and the batches, its full strips
                              are empty (they never travel), see take_info */
    uint32_t announced;    /* slots 0..announced-1 have their capacities */
    uint64_t announced_sum; /* those capacities added up */
    uint32_t *quantized;
    /* vertices the per-vertex arrays (the model's positions and normals,
     * quantized, oct) have room for: the vertices that arrived, grown as
     * the base and the splits are decoded, never what MODEL_INFO claims */
    uint32_t vertex_room;
    size_t record_capacity;
    uint64_t record_word_limit; /* the most record words a records form may bring (take_info) */
    struct mts_grow *grow; /* derives each split's record (grow.h) */
    struct mts__stream_models *models; /* the batches' coding models (stream_coding.h) */
    uint16_t *oct; /* per vertex its normal's code, when the stream has normals */
    mts_bigmem quantized_mem, oct_mem; /* where quantized and oct live (bigmem.h) */
    mts_lod lod;
    int have_lod;
    mts_draco_grid grid;
    uint32_t batches, splits; /* received and applied */
    uint32_t stop_level;
    int records; /* the batches carry records (MODEL_INFO flags MTS_INFO_RECORDS) */
    uint64_t end_checksum, checksum; /* the server's, and ours at the end */
    uint16_t error_code;
    char error_text[256];
    int resuming;       /* in a conversation after a broken one (see reconnected) */
    int continuing;     /* ... that goes on past the stop level (see continue) */
    int rejected;       /* the last frame failed its CRC: rejected whole, nothing of it
                         * applied, and the client can go on: a resume asks for that
                         * frame again (PROTOCOL.md, "Split coding") */
    uint32_t resumes;   /* conversations that resumed (MTS_EV_RESUMED) */
    void (*on_model)(void *user, const mts_wire_model_entry *m); /* for LIST */
    void *user;
    /* Threads that decode a splits-form stream, the caller's included; set
     * after mts_stream_client_init, before BASE (0 or 1: the caller's alone).
     * With two, the caller's thread decodes the splits and the vertices
     * while the other derives the records (docs/threads.md);
     * the records, strips and events are the same whatever the count, and a
     * batch is still applied before its frame returns. With two, the batches
     * the client holds whole are decoded while the one before is derived
     * (mts_stream_client_reconnected applies those first). A stream whose
     * MODEL_INFO lists no key levels, and the records form, use one. More
     * than two decode as two unless threads_at_keys is set: the layout that
     * gives a third thread work (a grow per key interval, its records fixed
     * up on the caller's thread) leaves that thread alone some 0.85x of one
     * thread's work, where two threads leave each 0.55x to 0.7x, so it is
     * slower than two on any number of cores (docs/threads.md, "Three
     * threads or more"). threads_at_keys: that layout all the same, for
     * the bench's curve and the tests. */
    uint32_t threads;
    int threads_at_keys;
    /* Two threads pay only where each has a core: sharing one (another
     * process holds the rest) they take longer than one thread alone. So
     * after each batch the decoder reads how long its pool thread waited
     * for a core (Linux), and where that passes 15% of three windows of
     * batches in a row while no core it may use idled, it goes on alone
     * for the rest of the stream (with the same records). Two threads do;
     * three or more (key intervals, threads_at_keys) keep theirs.
     * threads_alone_after (tests) makes two do so after that many batches
     * instead, measuring nothing; 0: by measure. */
    uint32_t threads_alone_after;
    /* Two threads: the decode thread makes a key's paths for the pool where
     * the pool is well behind (a tenth of the key's splits) and the ids of
     * the key before are known; threads_hand_key_paths (tests) makes it so
     * at every key whatever the pace, the pool waiting for them, and the two
     * never go on alone. threads_key_paths_handed: at the full level, the
     * pool took the last key's. */
    int threads_hand_key_paths, threads_key_paths_handed;
    /* Where the large arrays' reservations come from (bigmem.h), set after
     * mts_stream_client_init by a caller that runs client after client in
     * one process; it outlives this client and its model. NULL: the kernel. */
    mts_bigmem_cache *memory;
    uint32_t threads_alone_from; /* the level from which one thread decoded; 0: it did not */
    uint32_t threads_ran;        /* the most threads that decoded (mts_stream_client_threads_used) */
    struct mts__stream_par *par; /* those threads' state (stream_dec_threads.c), NULL with one */
    mts_wire_reader reader; /* bytes fed, not yet taken as frames (mts_stream_client_feed) */
} mts_stream_client;

void mts_stream_client_init(mts_stream_client *c);
void mts_stream_client_free(mts_stream_client *c);

/* The most threads that decoded this stream, the caller's included: 1
 * until BASE, and after it for the records form, a stream without key
 * levels, or where no thread could be started; otherwise two, or with
 * threads_at_keys `threads` or as many as have work (threads_alone_from
 * says whether it went on alone). */
uint32_t mts_stream_client_threads_used(const mts_stream_client *c);

/* Bytes to events, for a caller that holds bytes rather than frames: a
 * socket's reads, WebSocket messages, an HTTP download's write callback.
 * feed buffers bytes of the conversation in the order they came, split
 * anywhere (one at a time works); next takes the next whole frame they hold
 * through mts_stream_client_frame. Feed what came, then call next until it
 * returns 0:
 *
 *     if (mts_stream_client_feed(c, data, size, err) != MTS_OK) ...
 *     while ((got = mts_stream_client_next(c, &ev, err)) > 0)
 *         ... ev ...
 *     if (got < 0) ... err ...
 *
 * A frame cut between two feeds is joined again, whatever carried the
 * pieces (reads of one connection, or ranges of a file holding the frames
 * fetched one after another): only a new conversation drops the start of a
 * frame left incomplete (mts_stream_client_reconnected and
 * mts_stream_client_continue do), as that frame comes again whole.
 *
 * feed fails with MTS_ERR_LIMIT when fed while more than two of the
 * largest frames (MTS_WIRE_MAX_FRAME) wait untaken -- a caller calls next
 * between feeds -- and with MTS_ERR_NOMEM. The bytes are copied: the
 * caller's may be reused as soon as feed returns. */
mts_result mts_stream_client_feed(mts_stream_client *c, const void *data, size_t size,
                                  mts_error *err);

/* 1: a frame was taken and *ev says what it brought (MTS_EV_NONE for a
 * frame that brings nothing new: the BASE a resumed conversation repeats,
 * checked and skipped); 0: no whole frame is buffered, feed more; -1: an
 * error, err says what and err->code is its mts_result. Either the bytes
 * are not frames (a frame length out of 1..MTS_WIRE_MAX_FRAME, which
 * also ends the client, as nothing after it can be framed) or
 * mts_stream_client_frame refused the frame, and then, as there,
 * c->rejected says whether it only failed its CRC. */
int mts_stream_client_next(mts_stream_client *c, mts_stream_event *ev, mts_error *err);

/* Bytes fed and not yet taken: whole frames next has not taken yet, then
 * the start of one still coming. */
size_t mts_stream_client_buffered(const mts_stream_client *c);

/* Takes one frame. Errors name the message and the problem; a client that
 * returned an error is not fed again, but for a frame that failed its CRC
 * (c->rejected): nothing of it was applied, and a resumed conversation
 * (mts_stream_client_reconnected) brings it again. A batch is applied only after its CRC,
 * its header and its encoding have checked out; each split's record is then
 * checked against the strips as it is applied (mts_lod_split), so a record
 * that fails leaves c->lod broken part-way through that batch (lod.broken). */
mts_result mts_stream_client_frame(mts_stream_client *c, uint8_t type, const uint8_t *payload,
                                   size_t size, mts_stream_event *event, mts_error *err);

/* Resuming after a broken connection (PROTOCOL.md, HELLO). A batch is
 * applied only once it is whole and its CRC checks, so a break loses nothing
 * that arrived intact: the client holds the base and batches 0..batches-1.
 *
 * resume_point says what the next HELLO asks for: *resume_batch is
 * c->batches once the base is in (0 before: that is a fresh start), plus
 * the batches two threads decoded ahead, which reconnected applies, and
 * *stream_id the first MODEL_INFO's when *resume_batch > 0 (else 0). Returns
 * 0 when a new conversation would not help: the stream ended (END, ERROR or
 * MODELS) or failed (a frame refused past its CRC, or bytes that are not
 * frames; c->lod may be broken). A frame rejected only for its CRC
 * (c->rejected) left the state as it was, so that returns 1 and the resume
 * asks for that frame again. */
int mts_stream_client_resume_point(const mts_stream_client *c, uint32_t *resume_batch,
                                   uint64_t *stream_id);

/* Readies c for the frames of a new conversation, started with the HELLO
 * that resume_point described; the bytes fed and not taken are dropped,
 * the partial frame of the broken one among them. Before the base was in,
 * c starts over (the next MODEL_INFO gives MTS_EV_INFO again). After it, the
 * new MODEL_INFO must describe the same stream as the first -- stream_id,
 * counts, grid, batches, stop level -- or it is rejected (MTS_ERR_FORMAT):
 * two streams are never mixed. It gives MTS_EV_RESUMED; a BASE that follows
 * (a resume from batch 0 is a fresh start for the server) is checked and
 * skipped, and BATCH frames go on from c->batches. MTS_ERR_ARG when
 * resume_point returns 0. */
mts_result mts_stream_client_reconnected(mts_stream_client *c, mts_error *err);

/* Continuing a stream that ended at its stop level towards a higher one
 * (PROTOCOL.md, "Continuing"): a preview that zooms in asks for more. Call
 * after END was checked; it readies c for a new conversation (dropping the
 * bytes fed and not taken, as after a break) whose HELLO asks for the new
 * stop point with *resume_batch (c->batches: every batch the client
 * decoded, including the splits of the last one past the old stop) and
 * *stream_id. The MODEL_INFO
 * must describe the same stream in everything but its stop level, which
 * may not fall below the level the client is at (MTS_ERR_FORMAT); the
 * runtime then moves up to the new stop as far as the splits held allow,
 * the batches that follow take it the rest of the way, and END is checked
 * at the new stop. It gives MTS_EV_RESUMED. MTS_ERR_ARG when the stream did
 * not end with a checked END (an ERROR, a failure, or still going). */
mts_result mts_stream_client_continue(mts_stream_client *c, uint32_t *resume_batch,
                                      uint64_t *stream_id, mts_error *err);

#endif
