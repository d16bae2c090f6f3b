/* The local frame (protocol/lframe.h): exactly invertible on integers over
 * the whole range a stream uses, and a rotation in fact -- the normal it was
 * made from lands on the third axis, lengths are kept -- for normals of
 * every direction and scale. */
#include <math.h>
#include <stdint.h>

#include "lframe.h"
#include "test.h"

static uint64_t next(uint64_t *s)
{
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return *s >> 11;
}

static int64_t signed_below(uint64_t *s, int64_t bound)
{
    return (int64_t)(next(s) % (uint64_t)(2 * bound + 1)) - bound;
}

static void test_exact_inverse(mts_test *t)
{
    uint64_t seed = 12345;
    uint32_t bad = 0;
    for (int i = 0; i < 200000; i++) {
        /* normals from tiny to far beyond 2^26, residuals up to 2^30 */
        int64_t scale = (int64_t)1 << (next(&seed) % 45);
        int64_t n[3] = {signed_below(&seed, scale), signed_below(&seed, scale),
                        signed_below(&seed, scale)};
        int64_t rs = (int64_t)1 << (next(&seed) % 31);
        int64_t r[3] = {signed_below(&seed, rs), signed_below(&seed, rs), signed_below(&seed, rs)};
        int64_t x[3] = {r[0], r[1], r[2]};
        mts_lframe f;
        mts_lframe_make(n, &f);
        mts_lframe_forward(&f, x);
        for (int a = 0; a < 3; a++)
            CHECKF(t, x[a] > -((int64_t)1 << 32) && x[a] < ((int64_t)1 << 32),
                   "a frame coordinate of %lld", (long long)x[a]);
        mts_lframe_inverse(&f, x);
        bad += x[0] != r[0] || x[1] != r[1] || x[2] != r[2];
    }
    CHECKF(t, bad == 0, "%u of 200000 residuals did not come back", bad);
}

static void test_is_a_rotation(mts_test *t)
{
    uint64_t seed = 99;
    double worst_axis = 0, worst_len = 0;
    for (int i = 0; i < 20000; i++) {
        int64_t n[3] = {signed_below(&seed, 1 << 20), signed_below(&seed, 1 << 20),
                        signed_below(&seed, 1 << 20)};
        mts_lframe f;
        mts_lframe_make(n, &f);
        double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (len < 1000)
            continue;
        int64_t x[3] = {n[0], n[1], n[2]};
        mts_lframe_forward(&f, x);
        /* off the third axis, relative to the length */
        double off = sqrt((double)x[0] * x[0] + (double)x[1] * x[1]) / len;
        double l2 = sqrt((double)x[0] * x[0] + (double)x[1] * x[1] + (double)x[2] * x[2]);
        worst_axis = off > worst_axis ? off : worst_axis;
        worst_len = fabs(l2 / len - 1) > worst_len ? fabs(l2 / len - 1) : worst_len;
        CHECKF(t, x[2] > 0, "normal (%lld %lld %lld) lands on %lld", (long long)n[0],
               (long long)n[1], (long long)n[2], (long long)x[2]);
        if (t->case_failed)
            break;
    }
    /* 16-bit factors: a few 1e-5 */
    CHECKF(t, worst_axis < 1e-3 && worst_len < 1e-3, "off the axis %.2e, length %.2e", worst_axis,
           worst_len);
}

static void test_degenerate_normals(mts_test *t)
{
    const int64_t cases[][3] = {{0, 0, 0}, {0, 0, 5}, {0, 0, -5}, {7, 0, 0}, {-7, 0, 0},
                                {0, 9, 0}, {0, -9, 0}, {1, 1, 1}, {-1, -1, -1},
                                {INT64_MAX / 4, -INT64_MAX / 4, INT64_MAX / 4}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mts_lframe f;
        mts_lframe_make(cases[i], &f);
        int64_t r[3] = {1000003, -77, 65536}, x[3] = {r[0], r[1], r[2]};
        mts_lframe_forward(&f, x);
        mts_lframe_inverse(&f, x);
        CHECKF(t, x[0] == r[0] && x[1] == r[1] && x[2] == r[2], "normal case %zu", i);
    }
    /* no normal: the identity */
    mts_lframe f;
    const int64_t zero[3] = {0, 0, 0};
    mts_lframe_make(zero, &f);
    int64_t x[3] = {3, -4, 5};
    mts_lframe_forward(&f, x);
    CHECK(t, x[0] == 3 && x[1] == -4 && x[2] == 5);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_exact_inverse);
    RUN(&t, test_is_a_rotation);
    RUN(&t, test_degenerate_normals);
    return mts_test_end(&t);
}
