/* vesica — private to the programs (cli, benchmarks): OpenBLAS's kernel choice.
 *
 * OpenBLAS 0.3.21 (Debian 12) picks its kernels from the CPUID model when the
 * library loads, before main. On a CPU whose model it does not know (virtual
 * Xeons that report "Intel(R) Xeon(R) Processor" with AVX-512) it falls back
 * to its generic "Prescott" kernels: dgemm at ~9 GFLOP/s on one core against
 * ~50 with the SkylakeX kernels on the same machine (docs/results.md,
 * "Performance and its scaling"). MUMPS's dense fronts (the KKT factorization, the phi0
 * projection) run on those kernels. The choice can only be made through the
 * environment variable OPENBLAS_CORETYPE, read at load time, so a program
 * that finds the fallback on a CPU with AVX2 or AVX-512 re-executes itself
 * once with the variable set. Left alone: an OPENBLAS_CORETYPE set by the
 * user (also the way to turn this off), a run under valgrind (its client
 * would leave the tool at exec; valgrind's CPU has no AVX-512 anyway), and
 * any core OpenBLAS did recognize. */
#ifndef VES_BLAS_CORE_IMPL_H
#define VES_BLAS_CORE_IMPL_H

#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

char *openblas_get_corename(void); /* OpenBLAS's own API (cblas.h is not on every include path) */

/* The kernel family this CPU can run, or NULL when no better one than the
 * generic fallback applies. */
static inline const char *ves_blas_core_wanted(void) {
#if defined(__GNUC__) && defined(__x86_64__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl"))
    return "SkylakeX";
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "Haswell";
#endif
  return NULL;
}

/* Re-execute argv with OPENBLAS_CORETYPE set when OpenBLAS fell back to a
 * generic core on a CPU that has better kernels. Returns only when nothing
 * is to be done or the exec failed (the run then goes on, slower). */
static inline void ves_blas_core_fix(char **argv) {
  static const char *const generic[] = {"Prescott",   "Core2",   "Penryn",
                                        "Dunnington", "Nehalem", "Sandybridge"};
  if (getenv("OPENBLAS_CORETYPE")) return;
  const char *pre = getenv("LD_PRELOAD");
  if (pre && strstr(pre, "vgpreload")) return;
  const char *cur = openblas_get_corename(), *want = ves_blas_core_wanted();
  if (!cur || !want) return;
  int weak = 0;
  for (size_t i = 0; i < sizeof generic / sizeof *generic; i++)
    weak |= !strcasecmp(cur, generic[i]);
  if (!weak) return;
  if (setenv("OPENBLAS_CORETYPE", want, 1) != 0) return;
  execv("/proc/self/exe", argv);
}

#endif
