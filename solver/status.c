/* vesica — text of the status codes, generated from the X-macro list. */
#include "ves/status.h"

const char *ves_status_str(ves_status s) {
  switch (s) {
#define VES_STATUS_CASE_(name, value, msg)                                     \
  case name:                                                                   \
    return msg;
    VES_STATUS_LIST(VES_STATUS_CASE_)
#undef VES_STATUS_CASE_
  }
  return "unknown status";
}
