/* vesica — the project's single status enum and the error-propagation macros. */
#ifndef VES_STATUS_H
#define VES_STATUS_H

/* X-macro list: name, value, message. 0 is success, < 0 an error, > 0 a
 * non-error outcome (step rejected, iteration limit) the caller may act on. */
#define VES_STATUS_LIST(X)                                                     \
  X(VES_OK, 0, "ok")                                                           \
  X(VES_ERR_ALLOC, -1, "out of memory")                                        \
  X(VES_ERR_ARG, -2, "invalid argument")                                       \
  X(VES_ERR_NOCONV, -3, "iteration did not converge")                          \
  X(VES_ERR_GEOM, -4, "geometry error")                                        \
  X(VES_ERR_DOMAIN, -5, "point outside the domain (det F <= 0 or r <= 0)")     \
  X(VES_ERR_SINGULAR, -6, "singular matrix")                                   \
  X(VES_ERR_IO, -7, "input/output error")                                      \
  X(VES_ERR_CONFIG, -8, "invalid configuration")                               \
  X(VES_ERR_INTERNAL, -9, "internal error")                                    \
  X(VES_ERR_SOLVER, -10, "solver failure")                                     \
  X(VES_STEP_REJECTED, 1, "step rejected")                                     \
  X(VES_MAXITER, 2, "iteration limit reached")

typedef enum {
#define VES_STATUS_ENUM_(name, value, msg) name = value,
  VES_STATUS_LIST(VES_STATUS_ENUM_)
#undef VES_STATUS_ENUM_
} ves_status;

/* Human-readable text of a status ("unknown status" for values not listed). */
const char *ves_status_str(ves_status s);

/* Propagate a failing status (anything < 0) to the caller. */
#define VES_CALL(expr)                                                         \
  do {                                                                         \
    ves_status ves_call_s_ = (expr);                                           \
    if (ves_call_s_ < 0) return ves_call_s_;                                   \
  } while (0)

/* Validate an input condition; always on (not an assert). */
#define VES_CHECK(cond, code)                                                  \
  do {                                                                         \
    if (!(cond)) return (code);                                                \
  } while (0)

#endif
