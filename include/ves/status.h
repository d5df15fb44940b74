/* vesica — the project's single status enum and the error-propagation
 * macros, with a per-thread record of where an error arose and the calls it
 * passed (docs/design.md, "Layers and interfaces"). */
#ifndef VES_STATUS_H
#define VES_STATUS_H

#include <stddef.h>

/* X-macro list: name, value, message. 0 is success, < 0 an error, > 0 a
 * non-error outcome (step rejected, iteration limit, end time reached) the
 * caller may act on. */
#define VES_STATUS_LIST(X)                                                                         \
  X(VES_OK, 0, "ok")                                                                               \
  X(VES_ERR_ALLOC, -1, "out of memory")                                                            \
  X(VES_ERR_ARG, -2, "invalid argument")                                                           \
  X(VES_ERR_NOCONV, -3, "iteration did not converge")                                              \
  X(VES_ERR_GEOM, -4, "geometry error")                                                            \
  X(VES_ERR_DOMAIN, -5, "point outside the domain (det F <= 0 or r <= 0)")                         \
  X(VES_ERR_SINGULAR, -6, "singular matrix")                                                       \
  X(VES_ERR_IO, -7, "input/output error")                                                          \
  X(VES_ERR_CONFIG, -8, "invalid configuration")                                                   \
  X(VES_ERR_INTERNAL, -9, "internal error")                                                        \
  X(VES_ERR_SOLVER, -10, "solver failure")                                                         \
  X(VES_STEP_REJECTED, 1, "step rejected")                                                         \
  X(VES_MAXITER, 2, "iteration limit reached")                                                     \
  X(VES_DONE, 3, "end time reached")

typedef enum {
#define VES_STATUS_ENUM_(name, value, msg) name = value,
  VES_STATUS_LIST(VES_STATUS_ENUM_)
#undef VES_STATUS_ENUM_
} ves_status;

#ifdef __cplusplus
extern "C" {
#endif

/* Human-readable text of a status ("unknown status" for values not listed). */
const char *ves_status_str(ves_status s);

/* The last error of this thread, PETSc-style: the code, the place that
 * detected it (file, line, function), the condition or call that failed as
 * written in the source, and the places it was propagated through by
 * VES_CALL. VES_CHECK starts a record; VES_CALL extends the record of the
 * status it propagates, or starts one naming the call when the status comes
 * from a plain `return VES_ERR_...`. The record is per thread (C11
 * _Thread_local), so the library stays free of shared state: an error found
 * on an OpenMP worker shows at the VES_CALL that receives it on the calling
 * thread. The program clears it before a call whose failure it reports
 * (ves_error_clear) and prints it after (ves_error_format). */
#define VES_ERROR_TRACE 6 /* VES_CALL places kept after the origin */
typedef struct {
  const char *file, *func; /* source file and function (static strings) */
  int line;                /* source line */
} ves_error_place;

typedef struct {
  ves_status code;                        /* VES_OK: nothing recorded */
  ves_error_place origin;                 /* where the failure was detected */
  char what[192];                         /* the failed condition or call, or a message */
  int depth;                              /* places in trace (at most VES_ERROR_TRACE) */
  ves_error_place trace[VES_ERROR_TRACE]; /* the VES_CALLs it passed, innermost first */
} ves_error;

/* Start a record (overwriting this thread's last); returns code. */
ves_status ves_error_set(ves_status code, const char *file, int line, const char *func,
                         const char *what);
/* At a VES_CALL that receives code < 0: extend the record when it holds
 * code, else start one naming expr. Returns code. */
ves_status ves_error_pass(ves_status code, const char *file, int line, const char *func,
                          const char *expr);
/* This thread's last error (code VES_OK when none since the last clear). */
const ves_error *ves_error_last(void);
void ves_error_clear(void);
/* "what (file:line in func, via f:l, ...)" of the last error when it holds
 * code, else ves_status_str(code) alone; into buf, which is returned. */
const char *ves_error_format(ves_status code, char *buf, size_t len);
/* The same in this thread's text buffer (valid until the next call). */
const char *ves_error_text(ves_status code);
/* printf into a caller's message buffer err[errlen] (the err/errlen pair of
 * the functions that explain a refusal); nothing when err is NULL or errlen 0. */
void ves_error_say(char *err, size_t errlen, const char *fmt, ...);

#ifdef __cplusplus
}
#endif

/* Propagate a failing status (anything < 0) to the caller, adding this
 * place to the error record. */
#define VES_CALL(expr)                                                                             \
  do {                                                                                             \
    ves_status ves_call_s_ = (expr);                                                               \
    if (ves_call_s_ < 0) return ves_error_pass(ves_call_s_, __FILE__, __LINE__, __func__, #expr);  \
  } while (0)

/* Validate an input condition; always on (not an assert). The failed
 * condition's text and place go to the error record. */
#define VES_CHECK(cond, code)                                                                      \
  do {                                                                                             \
    if (!(cond)) return ves_error_set((code), __FILE__, __LINE__, __func__, "failed: " #cond);     \
  } while (0)

/* Fail with code and a message (a string literal) instead of a condition. */
#define VES_FAIL(code, msg) return ves_error_set((code), __FILE__, __LINE__, __func__, (msg))

#endif
