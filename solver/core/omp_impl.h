/* vesica — private: the OpenMP queries the threaded modules share (model,
 * quad, sparse), with their one-thread values when built without OpenMP
 * (docs/design.md, "Layers and interfaces"). */
#ifndef VES_OMP_IMPL_H
#define VES_OMP_IMPL_H

#ifdef _OPENMP
#include <omp.h>
#endif

/* Threads a parallel region will get: omp_get_max_threads() (1 without OpenMP). */
static inline int ves_omp_threads(void) {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

/* This thread's number in its team (0 without OpenMP). */
static inline int ves_omp_tid(void) {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

/* The size of the current team (1 without OpenMP). */
static inline int ves_omp_nteam(void) {
#ifdef _OPENMP
  return omp_get_num_threads();
#else
  return 1;
#endif
}

#endif
