/* The one monotonic clock every module times with: seconds since an
 * arbitrary point, never going back (CLOCK_MONOTONIC). Library code uses it
 * for timeouts and figures, programs through cli_now. */
#ifndef MTS_CLOCK_H
#define MTS_CLOCK_H

#include <time.h>

static inline double mts_clock_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

#endif
