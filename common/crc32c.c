/* Table-driven slicing-by-8 (Kounavis and Berry, "A Systematic Approach to
 * Building High Performance Software-Based CRC Generators", 2005): eight
 * bytes per step without the SSE4.2 instruction, so it runs everywhere.
 * The tables in crc32c_table.h come from:
 *   t0[i] = i, shifted right 8 times with ^0x82F63B78 on carry;
 *   tk[i] = (tk-1[i] >> 8) ^ t0[tk-1[i] & 0xff]. */
#include "crc32c.h"

#include <string.h>

#include "crc32c_table.h"

uint32_t mts_crc32c(uint32_t crc, const void *data, size_t size)
{
    const uint8_t *p = data;
    const uint32_t(*t)[256] = mts_crc32c_table;
    crc = ~crc;
    while (size >= 8) {
        uint32_t lo = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
                      (uint32_t)p[3] << 24;
        uint32_t hi = (uint32_t)p[4] | (uint32_t)p[5] << 8 | (uint32_t)p[6] << 16 |
                      (uint32_t)p[7] << 24;
        lo ^= crc;
        crc = t[7][lo & 0xff] ^ t[6][(lo >> 8) & 0xff] ^ t[5][(lo >> 16) & 0xff] ^
              t[4][lo >> 24] ^ t[3][hi & 0xff] ^ t[2][(hi >> 8) & 0xff] ^
              t[1][(hi >> 16) & 0xff] ^ t[0][hi >> 24];
        p += 8;
        size -= 8;
    }
    while (size--)
        crc = (crc >> 8) ^ t[0][(crc ^ *p++) & 0xff];
    return ~crc;
}
