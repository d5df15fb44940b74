/* vesica — private: wall-clock time for the timings the library reports
 * (monotonic seconds; docs/design.md, "Layers and interfaces"). */
#ifndef VES_CLOCK_IMPL_H
#define VES_CLOCK_IMPL_H

#include <time.h>

/* Seconds on the monotonic clock (differences only are meaningful). */
static inline double ves_wall_seconds(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

#endif
