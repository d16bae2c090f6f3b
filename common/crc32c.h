/* CRC-32C (Castagnoli), the checksum of every .mtsm section and, later, of
 * every wire batch: the polynomial with hardware support on x86 and ARM, and
 * better error detection than CRC-32 on the short messages we send. */
#ifndef MTS_CRC32C_H
#define MTS_CRC32C_H

#include <stddef.h>
#include <stdint.h>

/* Continues a CRC: start with crc = 0. crc32c("123456789") == 0xE3069283. */
uint32_t mts_crc32c(uint32_t crc, const void *data, size_t size);

#endif
