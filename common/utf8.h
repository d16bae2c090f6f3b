/* UTF-8 well-formedness (RFC 3629): what a peer's text and a JSON line must
 * be before anyone shows or parses them. Header-only: the wire's text
 * cleaning and the programs' JSON writer share it. */
#ifndef MTS_UTF8_H
#define MTS_UTF8_H

#include <stddef.h>
#include <stdint.h>

/* The length (1..4) of the well-formed UTF-8 sequence that starts s, with n
 * bytes there (n >= 1), or 0 when none does: a stray continuation byte, a
 * sequence cut short, an overlong form, a surrogate or past U+10FFFF. */
static inline size_t mts_utf8_seq_len(const unsigned char *s, size_t n)
{
    const unsigned c = s[0];
    if (c < 0x80)
        return 1;
    size_t k;
    uint32_t cp, min;
    if (c >= 0xc2 && c <= 0xdf) {
        k = 2, cp = c & 0x1f, min = 0x80;
    } else if (c >= 0xe0 && c <= 0xef) {
        k = 3, cp = c & 0x0f, min = 0x800;
    } else if (c >= 0xf0 && c <= 0xf4) {
        k = 4, cp = c & 0x07, min = 0x10000;
    } else {
        return 0;
    }
    if (n < k)
        return 0;
    for (size_t i = 1; i < k; i++) {
        if ((s[i] & 0xc0) != 0x80)
            return 0;
        cp = cp << 6 | (s[i] & 0x3fu);
    }
    if (cp < min || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff))
        return 0;
    return k;
}

#endif
