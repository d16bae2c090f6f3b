/* Private to protocol/stream_dec*.c, not installed and not part of the
 * public API (that is stream.h): the client's decoder on more than one
 * thread (c->threads > 1). stream_dec.c decodes each split and calls in
 * here; stream_dec_threads.c holds the pool that grows each key interval,
 * the hand-over between the threads and the fix-up in level order
 * (docs/threads.md, "Threads in the decoder"). */
#ifndef MTS_STREAM_DEC_THREADS_H
#define MTS_STREAM_DEC_THREADS_H

#include <stdint.h>

#include "grow.h"
#include "stream.h"

/* The decode thread catches up (fixes up and applies what the workers have
 * made, mts__stream_par_catch_up) every this many splits, so that a
 * batch's end is left only the records made since. */
#define MTS__STREAM_CATCH_UP_EVERY 64u

/* Appends one derived record, that of split j, to the client's model
 * (stream_dec.c): the one-thread path and the fix-up keep records alike. */
mts_result mts__stream_keep_record(mts_stream_client *c, uint32_t j, const uint32_t *r,
                                   uint32_t words, mts_error *err);

/* Room in the client's model for `words` more record words from word
 * `at` (stream_dec.c): grown by doubling up to the records form's bound. */
mts_result mts__stream_reserve_records(mts_stream_client *c, size_t at, size_t words,
                                       mts_error *err);

/* Sets the threads up after BASE: the log, the intervals, the fix-up, the
 * first worker (a grow from the base, whose slots are the real ones) and
 * the pool. MTS_OK with c->par left NULL where one thread it is (threads
 * below 2, the records form, no key levels listed). */
mts_result mts__stream_par_start(mts_stream_client *c, const mts_grow_options *go,
                                 mts_error *err);

/* Stops and joins the pool and frees everything; NULL is fine. */
void mts__stream_par_free(struct mts__stream_par *p);

/* Split j on the decode thread, in place of one grow's mts_grow_next: a
 * worker made where a key interval starts, the split logged for it (or,
 * the full level's, derived here), and the mesh-only grow (c->grow) split.
 * *lists (an explicit split's, or NULL) passes to the log. */
mts_result mts__stream_par_split(mts_stream_client *c, uint32_t j, const mts_grow_split *sp,
                                 uint32_t **lists, const mts_grow_full *full, mts_error *err);

/* Fixes up and keeps the records below `upto`, in level order, waiting for
 * their workers: a batch's records before it is applied. */
mts_result mts__stream_par_fixup(mts_stream_client *c, uint32_t upto, mts_error *err);

/* Between splits: the records the workers have made so far, below upto,
 * fixed up, kept and applied to the runtime without waiting. */
mts_result mts__stream_par_catch_up(mts_stream_client *c, uint32_t upto, mts_error *err);

/* Decoding ahead (two threads): stream_dec.c decodes the batches the
 * reader holds whole while the pool derives the batch being taken, so that
 * the pool never waits between frames; each is applied only when its own
 * frame is taken.
 *  - apply_upto: the batch being taken ends at split upto; the runtime goes
 *    no further before its frame returns.
 *  - ahead_wanted: whether to decode one more now (the pool has not made
 *    the batch's records yet, or nothing is decoded ahead); *ahead: the
 *    batches decoded ahead so far (the next to decode is that many frames
 *    on in the reader).
 *  - ahead_done: one more decoded ahead with rc (an error is kept for when
 *    that frame is taken, and nothing more is decoded ahead).
 *  - ahead_take: 1 when the frame being taken was decoded ahead (*rc its
 *    result, err filled if it failed), 0 when it is to be decoded now.
 *  - ahead_batches: batches decoded ahead, not yet taken, that did not
 *    fail (one that failed keeps its error for when it comes again).
 *  - ahead_hold: while hold is 1, nothing more is decoded ahead. */
void mts__stream_par_ahead_hold(mts_stream_client *c, int hold);
void mts__stream_par_apply_upto(mts_stream_client *c, uint32_t upto);
int mts__stream_par_ahead_wanted(mts_stream_client *c, uint32_t upto, uint32_t *ahead);
void mts__stream_par_ahead_done(mts_stream_client *c, mts_result rc, const mts_error *e);
int mts__stream_par_ahead_take(mts_stream_client *c, mts_result *rc, mts_error *err);
uint32_t mts__stream_par_ahead_batches(const mts_stream_client *c);

/* Around a splits batch on more than one thread: start samples the wall
 * clock and both threads' CPU clocks; end (after the batch's records are
 * kept) adds the batch to the window, and where two threads ran less than
 * MTS__STREAM_PAR_MIN_OVERLAP at once over two windows in a row (or
 * c->threads_alone_after batches have passed) stops the pool thread and
 * takes its grow, whose records are one grow's, as c->grow: the decoder
 * goes on as with one thread. */
void mts__stream_par_batch_start(mts_stream_client *c);
void mts__stream_par_batch_end(mts_stream_client *c, uint32_t index);

#endif
