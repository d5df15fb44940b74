/* vesica — libFuzzer target: the problem-file parser (ves_config_load on a
 * file holding the input) and the --set overrides (every input line that
 * looks like section.key=value, applied to the defaults). Built and run by
 * `make fuzz` with AddressSanitizer + UBSan; a crash, a sanitizer report or
 * a broken contract aborts. The contract of an accepted configuration:
 * every key finite and inside its declared range (integers integral, texts
 * one of their choices), ves_config_validate accepts it, and its text
 * (ves_config_to_text) reads back to the identical configuration. A refused
 * input: a status < 0 and a one-line message naming the file (or --set).
 * config.c is compiled in so the checks read its key table (KEYS). */
#include "../../solver/app/config.c"

#include <stdint.h>
#include <stdio.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void die(const char *what, const char *detail) {
  fprintf(stderr, "fuzz_config: contract broken: %s: %s\n", what, detail);
  abort();
}

/* Every key of an accepted configuration inside its declared range. */
static void check_ranges(const ves_config *c) {
  for (int i = 0; i < NKEYS; i++) {
    const key_spec *k = &KEYS[i];
    const void *f = (const char *)c + k->offset;
    char msg[400];
    if (k->type == KEY_DOUBLE) {
      double v = *(const double *)f;
      snprintf(msg, sizeof msg, "[%s] %s = %.17g (allowed %g to %g)", k->section, k->key, v, k->min,
               k->max);
      if (!isfinite(v) || v < k->min || v > k->max) die("real out of range", msg);
    } else if (k->type == KEY_INT) {
      int v = *(const int *)f;
      snprintf(msg, sizeof msg, "[%s] %s = %d (allowed %g to %g)", k->section, k->key, v, k->min,
               k->max);
      if (v < k->min || v > k->max) die("integer out of range", msg);
    } else {
      const char *s = f;
      size_t len = strnlen(s, VES_CONFIG_STR);
      snprintf(msg, sizeof msg, "[%s] %s (length %zu)", k->section, k->key, len);
      if (len == 0 || len >= VES_CONFIG_STR) die("text empty or unterminated", msg);
      if (k->choice) {
        int ok = 0;
        for (const char *ch = k->choice; *ch;) {
          size_t l = strcspn(ch, "|");
          if (l == len && !strncasecmp(ch, s, l)) ok = 1;
          ch += l + (ch[l] == '|');
        }
        if (!ok) die("text not one of its choices", msg);
      }
    }
  }
}

/* The whole contract of an accepted configuration. */
static void check_accepted(const ves_config *c) {
  char err[1024] = "";
  check_ranges(c);
  if (ves_config_validate(c, err, sizeof err) != VES_OK) die("accepted but not valid", err);
  char *text = NULL;
  if (ves_config_to_text(c, &text) != VES_OK) die("to_text failed", "");
  ves_config back;
  ves_status st =
      ves_config_load_text(text, c->source[0] ? c->source : "x.ini", &back, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "%s\n", text);
    die("its text does not read back", err);
  }
  for (int i = 0; i < NKEYS; i++) {
    ves_config_entry a, b;
    ves_config_entry_get(c, i, &a);
    ves_config_entry_get(&back, i, &b);
    int same = a.type == VES_KEY_REAL  ? a.real == b.real
               : a.type == VES_KEY_INT ? a.integer == b.integer
                                       : !strcmp(a.text, b.text);
    if (!same) {
      fprintf(stderr, "%s\n", text);
      die("text round trip changed a key", a.key);
    }
  }
  free(text);
}

static void check_refused(ves_status st, const char *err, const char *name) {
  if (st >= 0) die("status of a refusal", ves_status_str(st));
  if (!err[0] || strchr(err, '\n') || !strstr(err, name)) die("refusal message", err);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static char path[64];
  if (!path[0]) snprintf(path, sizeof path, "/tmp/vesica_fuzz_config_%d.ini", (int)getpid());
  FILE *f = fopen(path, "wb");
  if (!f) return 0;
  fwrite(data, 1, size, f);
  fclose(f);
  ves_config c;
  char err[1024] = "";
  ves_status st = ves_config_load(path, 0, NULL, &c, err, sizeof err);
  if (st == VES_OK)
    check_accepted(&c);
  else
    check_refused(st, err, path);

  /* --set: lines holding '.' before '=' (at most 8), on the defaults */
  char *copy = malloc(size + 1);
  if (!copy) return 0;
  memcpy(copy, data, size);
  copy[size] = 0;
  const char *set[8];
  int nset = 0;
  for (char *ln = copy; ln && nset < 8;) {
    char *nl = strchr(ln, '\n');
    if (nl) *nl = 0;
    char *dot = strchr(ln, '.'), *eq = strchr(ln, '=');
    if (dot && eq && dot < eq) set[nset++] = ln;
    ln = nl ? nl + 1 : NULL;
  }
  if (nset) {
    err[0] = 0;
    st = ves_config_load(NULL, nset, set, &c, err, sizeof err);
    if (st == VES_OK)
      check_accepted(&c);
    else if (st >= 0 || !err[0])
      die("refused --set", err);
  }
  free(copy);
  return 0;
}
