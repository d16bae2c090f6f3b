/* A stream file read from a web server (stream_file.h over http.h): the
 * conversation a session has with a URL instead of with mts-server.
 *
 * The first conversation asks for the file's first MTS_SFILE_FIRST_REQUEST
 * bytes (its header, MODEL_INFO and table, and the start of BASE for most
 * models), and for the rest of the prefix only when that was not all of it;
 * then for the range from BASE (or, resuming or continuing, from the first
 * batch the client does not hold) to the end of the stop's last batch. The
 * bytes go to the stream client as they arrive; the caller takes its events
 * (mts_stream_client_next) between polls, and ends the conversation with
 * mts_webfile_end once the range is in, which checks the stop as END would.
 * The index is kept from one conversation to the next: a resume or a
 * continuation is one request.
 *
 * Errors: mts_result and mts_error, nothing printed; MTS_ERR_IO for what a
 * new conversation may cure (a cut, a timeout, a server down or 5xx). */
#ifndef MTS_WEBFILE_H
#define MTS_WEBFILE_H

#include <stdint.h>

#include "error.h"
#include "http.h"
#include "stream.h"
#include "stream_file.h"

typedef struct mts_webfile mts_webfile;

mts_result mts_webfile_create(mts_webfile **wf, const char *url, const mts_http_options *opts,
                              mts_error *err);
void mts_webfile_free(mts_webfile *wf);

/* Starts a conversation for c towards a stop point (MTS_STOP_*, as HELLO's):
 * c is fresh, or readied for it by mts_stream_client_reconnected (after a
 * break) or mts_stream_client_continue (a higher stop). */
mts_result mts_webfile_begin(mts_webfile *wf, mts_stream_client *c, uint8_t stop_kind,
                             uint32_t stop_value, mts_error *err);

/* Reads only the index, waiting for it (its timeouts are the options'), so
 * that a caller can choose its stop from the file's counts before the first
 * conversation, which then asks only for the range. */
mts_result mts_webfile_read_index(mts_webfile *wf, mts_error *err);

/* Waits at most timeout_ms for the network, and hands c what came. 1: the
 * conversation goes on; 0: every byte of it came, or it failed
 * (mts_webfile_result says which). */
int mts_webfile_poll(mts_webfile *wf, mts_stream_client *c, int timeout_ms);
mts_result mts_webfile_result(const mts_webfile *wf, mts_error *err);

/* Once the range is in and c's frames are taken: checks the stop and ends
 * the stream (*event MTS_EV_END), as mts_stream_file_reader_end. */
mts_result mts_webfile_end(mts_webfile *wf, mts_stream_client *c, mts_stream_event *event,
                           mts_error *err);

/* Stops a conversation under way. */
void mts_webfile_cancel(mts_webfile *wf);

/* Bytes received over every conversation (bodies only, HTTP headers apart),
 * and those of the file's header, table and checks among them. */
uint64_t mts_webfile_bytes(const mts_webfile *wf);
const mts_stream_file_index *mts_webfile_index(const mts_webfile *wf);
/* The HTTP version of the last response (1, 2 or 3). */
int mts_webfile_http_version(const mts_webfile *wf);
/* What the last response said and how its transfer ended (http.h), for a
 * caller that counts failures by kind. */
mts_http_info mts_webfile_http_last(const mts_webfile *wf);

#endif
