/* vesica — text of the status codes (from the X-macro list) and the
 * per-thread record of the last error: its origin and the VES_CALL places it
 * passed (status.h; docs/design.md, "Layers and interfaces"). */
#include "ves/status.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

const char *ves_status_str(ves_status s) {
  switch (s) {
#define VES_STATUS_CASE_(name, value, msg)                                                         \
  case name:                                                                                       \
    return msg;
    VES_STATUS_LIST(VES_STATUS_CASE_)
#undef VES_STATUS_CASE_
  }
  return "unknown status";
}

/* One record per thread, and its text: no state shared between threads
 * (status.h). */
static _Thread_local ves_error last;
static _Thread_local char text[1024];

/* The file name without its folders (__FILE__ may carry a build path). */
static const char *base(const char *file) {
  const char *s = file ? strrchr(file, '/') : NULL;
  return s ? s + 1 : file ? file : "?";
}

ves_status ves_error_set(ves_status code, const char *file, int line, const char *func,
                         const char *what) {
  last.code = code;
  last.origin = (ves_error_place){.file = file, .func = func, .line = line};
  snprintf(last.what, sizeof last.what, "%s", what ? what : "");
  last.depth = 0;
  return code;
}

ves_status ves_error_pass(ves_status code, const char *file, int line, const char *func,
                          const char *expr) {
  if (last.code != code) { /* a plain return: the call is the first place known */
    char what[sizeof last.what];
    snprintf(what, sizeof what, "%s returned", expr ? expr : "?");
    return ves_error_set(code, file, line, func, what);
  }
  if (last.depth < VES_ERROR_TRACE)
    last.trace[last.depth++] = (ves_error_place){.file = file, .func = func, .line = line};
  return code;
}

const ves_error *ves_error_last(void) { return &last; }

void ves_error_clear(void) { memset(&last, 0, sizeof last); }

const char *ves_error_format(ves_status code, char *buf, size_t len) {
  if (!buf || !len) return "";
  int w = snprintf(buf, len, "%s", ves_status_str(code));
  if (last.code != code || code == VES_OK) return buf;
  w += snprintf(buf + (w < (int)len ? w : (int)len), w < (int)len ? len - (size_t)w : 0,
                ": %s (%s:%d in %s", last.what, base(last.origin.file), last.origin.line,
                last.origin.func ? last.origin.func : "?");
  for (int i = 0; i < last.depth; i++)
    w += snprintf(buf + (w < (int)len ? w : (int)len), w < (int)len ? len - (size_t)w : 0,
                  "%s%s:%d", i ? ", " : "; via ", base(last.trace[i].file), last.trace[i].line);
  if (w < (int)len) snprintf(buf + w, len - (size_t)w, ")");
  return buf;
}

const char *ves_error_text(ves_status code) { return ves_error_format(code, text, sizeof text); }

void ves_error_say(char *err, size_t errlen, const char *fmt, ...) {
  if (!err || !errlen) return;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(err, errlen, fmt, ap);
  va_end(ap);
}
