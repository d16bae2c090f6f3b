#include "lframe.h"

#include <math.h>
#include <string.h>

/* a / b rounded to nearest, halves away from zero (b != 0) */
static int64_t div_round(int64_t a, int64_t b)
{
    int64_t q = a / b, r = a % b;
    if (2 * (r < 0 ? -r : r) >= (b < 0 ? -b : b))
        q += (a < 0) != (b < 0) ? -1 : 1;
    return q;
}

/* floor((c v + 2^15) / 2^16), spelled out: >> of a negative number is
 * implementation-defined in C */
static int64_t mul16(int64_t c, int64_t v)
{
    int64_t x = c * v + 32768;
    return x >= 0 ? x >> 16 : -((-x + 65535) >> 16);
}

/* floor(sqrt(x)) for x < 2^53: IEEE 754 rounds sqrt correctly and x is
 * exact as a double, so the estimate is off by at most one, which the
 * integer checks mend (the same answer on every platform) */
static int64_t isqrt(uint64_t x)
{
    int64_t r = (int64_t)sqrt((double)x);
    while (r > 0 && (uint64_t)r * (uint64_t)r > x)
        r--;
    while ((uint64_t)(r + 1) * (uint64_t)(r + 1) <= x)
        r++;
    return r;
}

/* The step that turns (a, b) to (length, 0): negate both first when a < 0
 * (a half turn, so the angle left is within a quarter turn and |p| <= 1),
 * then rotate by -atan2(b, a): p = (r - a) / b, s = -b / r. Returns the
 * length r. */
static int64_t step(mts_lframe *f, int k, int64_t a, int64_t b)
{
    if (a < 0) {
        f->neg[k] = 1;
        a = -a;
        b = -b;
    }
    int64_t r = isqrt((uint64_t)(a * a + b * b));
    if (b != 0) { /* r > 0 then */
        f->on[k] = 1;
        f->p[k] = (int32_t)div_round((r - a) * 65536, b);
        f->s[k] = (int32_t)div_round(-b * 65536, r);
    }
    return r;
}

void mts_lframe_make(const int64_t n_in[3], mts_lframe *f)
{
    memset(f, 0, sizeof *f);
    int64_t n[3] = {n_in[0], n_in[1], n_in[2]};
    /* under 2^26 a component (halving toward zero keeps the direction), so
     * the squares' sums fit */
    for (;;) {
        int64_t m = 0;
        for (int a = 0; a < 3; a++) {
            int64_t x = n[a] < 0 ? -n[a] : n[a];
            m = x > m ? x : m;
        }
        if (m < ((int64_t)1 << 26))
            break;
        for (int a = 0; a < 3; a++)
            n[a] /= 2;
    }
    int64_t r = step(f, 0, n[0], n[1]);
    step(f, 1, n[2], r);
}

/* the rotation of (x, y) by the step's angle as three shears, and back */
static void shear(int64_t *x, int64_t *y, int64_t p, int64_t s)
{
    *x += mul16(p, *y);
    *y += mul16(s, *x);
    *x += mul16(p, *y);
}

static void unshear(int64_t *x, int64_t *y, int64_t p, int64_t s)
{
    *x -= mul16(p, *y);
    *y -= mul16(s, *x);
    *x -= mul16(p, *y);
}

/* step k works on axes (i, j): (0, 1), then (2, 0) */
static const int AX[2][2] = {{0, 1}, {2, 0}};

void mts_lframe_forward(const mts_lframe *f, int64_t r[3])
{
    for (int k = 0; k < 2; k++) {
        int64_t *x = &r[AX[k][0]], *y = &r[AX[k][1]];
        if (f->neg[k]) {
            *x = -*x;
            *y = -*y;
        }
        if (f->on[k])
            shear(x, y, f->p[k], f->s[k]);
    }
}

void mts_lframe_inverse(const mts_lframe *f, int64_t r[3])
{
    for (int k = 1; k >= 0; k--) {
        int64_t *x = &r[AX[k][0]], *y = &r[AX[k][1]];
        if (f->on[k])
            unshear(x, y, f->p[k], f->s[k]);
        if (f->neg[k]) {
            *x = -*x;
            *y = -*y;
        }
    }
}
