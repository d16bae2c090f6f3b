/* SHA-1 (FIPS 180-4), for the WebSocket opening handshake (RFC 6455 4.2.2):
 * the only place mtstream needs it, and not for security. */
#ifndef MTS_SHA1_H
#define MTS_SHA1_H

#include <stddef.h>
#include <stdint.h>

#define MTS_SHA1_SIZE 20

/* The digest of data[0..len). */
void mts_sha1(const void *data, size_t len, uint8_t out[MTS_SHA1_SIZE]);

#endif
