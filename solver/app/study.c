/* vesica — studies: the study file, the grid of cells, their names, commands
 * and .result files, the table DIR/study.csv, its figures and the Slurm
 * job-array script. No process is started here (study_run.c runs cells). */
#include "app/study.h"

#include "app/plot.h"

#include <ctype.h>
#include <errno.h>
#include <iniparser/iniparser.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/config.h"
#include "app/io.h"

/* One step "raised E*" above this relative rounding (vesica info's
 * energy_monotone uses the same margin). */
#define STUDY_RISE_TOL 1e-10
/* Longest cell name: NAME.result must fit a file name (255 bytes). */
#define STUDY_NAME_MAX 200

static int ini_quiet(const char *fmt, ...) {
  (void)fmt;
  return 0;
}

/* Copy s without leading and trailing blanks into out[len]; -1 if too long. */
static int trim_copy(char *out, size_t len, const char *s, size_t n) {
  while (n && isspace((unsigned char)*s)) s++, n--;
  while (n && isspace((unsigned char)s[n - 1])) n--;
  if (n >= len) return -1;
  memcpy(out, s, n);
  out[n] = 0;
  return 0;
}

/* The problem table's spelling of "section.key" (case-insensitive match),
 * into out; -1 when no such key. */
static int canonical_key(const char *name, char *out, size_t len) {
  const char *dot = strchr(name, '.');
  if (!dot) return -1;
  ves_config cfg; /* the entries' names do not depend on the values */
  ves_config_default(&cfg);
  for (int i = 0; i < ves_config_count(); i++) {
    ves_config_entry e;
    ves_config_entry_get(&cfg, i, &e);
    if (strlen(e.section) == (size_t)(dot - name) && !strncasecmp(e.section, name, dot - name) &&
        !strcasecmp(e.key, dot + 1)) {
      snprintf(out, len, "%s.%s", e.section, e.key);
      return 0;
    }
  }
  return -1;
}

ves_status ves_study_parse_axis(const char *text, ves_study_axis *ax, char *err, size_t errlen) {
  VES_CHECK(text && ax, VES_ERR_ARG);
  ax->nvalues = 0;
  while (isspace((unsigned char)*text)) text++;
  if (!strncasecmp(text, "log(", 4) || !strncasecmp(text, "lin(", 4)) {
    const int lg = tolower((unsigned char)text[1]) == 'o';
    double a, b, n;
    char close = 0, extra = 0;
    if (sscanf(text + 4, "%lf , %lf , %lf %c %c", &a, &b, &n, &close, &extra) != 4 ||
        close != ')' || !isfinite(a) || !isfinite(b) || n != floor(n)) {
      ves_error_say(err, errlen, "'%s': expected %s(from, to, count)", text, lg ? "log" : "lin");
      return VES_ERR_CONFIG;
    }
    if (n < 2 || n > VES_STUDY_MAX_VALUES) {
      ves_error_say(err, errlen, "'%s': count must lie in [2, %d]", text, VES_STUDY_MAX_VALUES);
      return VES_ERR_CONFIG;
    }
    if (lg && (a <= 0 || b <= 0)) {
      ves_error_say(err, errlen, "'%s': a log range needs from, to > 0", text);
      return VES_ERR_CONFIG;
    }
    if (a == b) {
      ves_error_say(err, errlen, "'%s': from and to are equal", text);
      return VES_ERR_CONFIG;
    }
    for (int i = 0; i < (int)n; i++) { /* 12 digits: 10^-3 prints as 0.001, not 0.00099999... */
      const double f = i / (n - 1);
      const double v = lg ? pow(10, log10(a) + f * (log10(b) - log10(a))) : a + f * (b - a);
      snprintf(ax->values[i], VES_STUDY_VALUE, "%.12g", i == n - 1 ? b : i == 0 ? a : v);
    }
    ax->nvalues = (int)n;
    return VES_OK;
  }
  const char *p = text;
  for (;;) {
    size_t l = strcspn(p, ",");
    if (ax->nvalues == VES_STUDY_MAX_VALUES) {
      ves_error_say(err, errlen, "more than %d values", VES_STUDY_MAX_VALUES);
      return VES_ERR_CONFIG;
    }
    char *v = ax->values[ax->nvalues];
    if (trim_copy(v, VES_STUDY_VALUE, p, l)) {
      ves_error_say(err, errlen, "value '%.*s': longer than %d characters", (int)l, p,
                    VES_STUDY_VALUE - 1);
      return VES_ERR_CONFIG;
    }
    if (!*v) {
      ves_error_say(err, errlen, "%s",
                    ax->nvalues || p[l] ? "an empty value in the list" : "empty axis");
      return VES_ERR_CONFIG;
    }
    for (int j = 0; j < ax->nvalues; j++)
      if (!strcmp(ax->values[j], v)) {
        ves_error_say(err, errlen, "value '%s' given twice", v);
        return VES_ERR_CONFIG;
      }
    ax->nvalues++;
    if (!p[l]) break;
    p += l + 1;
  }
  return VES_OK;
}

void ves_study_cell_index(const ves_study *s, long k, int idx[VES_STUDY_MAX_AXES]) {
  for (int a = s->naxes - 1; a >= 0; a--) { /* mixed radix, the last axis fastest */
    idx[a] = (int)(k % s->axis[a].nvalues);
    k /= s->axis[a].nvalues;
  }
}

/* The name an axis takes in cell names: its key without the section unless
 * another axis has the same key. */
static const char *axis_short(const ves_study *s, int a) {
  const char *dot = strchr(s->axis[a].key, '.'), *k = dot ? dot + 1 : s->axis[a].key;
  for (int b = 0; b < s->naxes; b++) {
    const char *d = strchr(s->axis[b].key, '.');
    if (b != a && !strcmp(d ? d + 1 : s->axis[b].key, k)) return s->axis[a].key;
  }
  return k;
}

static void sanitize_append(char *buf, size_t len, size_t *at, const char *t) {
  for (; *t && *at + 1 < len; t++) {
    const char c = *t;
    buf[(*at)++] = isalnum((unsigned char)c) || c == '.' || c == '+' || c == '-' ? c : '_';
  }
  buf[*at] = 0;
}

void ves_study_cell_name(const ves_study *s, long k, char *buf, size_t len) {
  int idx[VES_STUDY_MAX_AXES];
  ves_study_cell_index(s, k, idx);
  size_t at = 0;
  buf[0] = 0;
  for (int a = 0; a < s->naxes; a++) {
    if (a) sanitize_append(buf, len, &at, "_");
    sanitize_append(buf, len, &at, axis_short(s, a));
    if (at + 1 < len) buf[at++] = '-', buf[at] = 0;
    sanitize_append(buf, len, &at, s->axis[a].values[idx[a]]);
  }
}

ves_status ves_study_cell_sets(const ves_study *s, long k, char buf[][VES_STUDY_SETLEN], int *nset,
                               char *err, size_t errlen) {
  int idx[VES_STUDY_MAX_AXES], n = 0;
  ves_study_cell_index(s, k, idx);
  for (int i = 0; i < s->nset; i++) snprintf(buf[n++], VES_STUDY_SETLEN, "%s", s->set[i]);
  for (int a = 0; a < s->naxes; a++)
    snprintf(buf[n++], VES_STUDY_SETLEN, "%s=%s", s->axis[a].key, s->axis[a].values[idx[a]]);
  ves_config cfg;
  char msg[1024] = "";
  if (s->mode == VES_STUDY_STEP) { /* one step of dt_initial, constant, no halving */
    char dt[VES_STUDY_SETLEN] = "";
    for (int i = n - 1; i >= 0 && !dt[0]; i--) /* the cell's own dt_initial, else the file's */
      if (!strncmp(buf[i], "time.dt_initial=", 16)) snprintf(dt, sizeof dt, "%s", buf[i] + 16);
    if (!dt[0]) {
      if (ves_config_load(s->problem, 0, NULL, &cfg, msg, sizeof msg) != VES_OK) {
        ves_error_say(err, errlen, "%s", msg);
        *nset = n;
        return VES_ERR_CONFIG;
      }
      ves_config_format_real(cfg.dt_initial, dt, sizeof dt);
    }
    snprintf(buf[n++], VES_STUDY_SETLEN, "time.adaptive=0");
    snprintf(buf[n++], VES_STUDY_SETLEN, "time.dt_min=%.170s", dt);
    snprintf(buf[n++], VES_STUDY_SETLEN, "time.dt_max=%.170s", dt);
    snprintf(buf[n++], VES_STUDY_SETLEN, "time.t_end=%.170s", dt);
  }
  const char *ptr[VES_STUDY_CELL_SETS];
  for (int i = 0; i < n; i++) ptr[i] = buf[i];
  *nset = n;
  if (ves_config_load(s->problem, n, ptr, &cfg, msg, sizeof msg) != VES_OK) {
    ves_error_say(err, errlen, "%s%s", msg,
                  s->mode == VES_STUDY_STEP ? " (one step: dt_min = dt_max = t_end = dt_initial)"
                                            : "");
    return VES_ERR_CONFIG;
  }
  *nset = n;
  return VES_OK;
}

/* The steps a cell's command limits the run to (0: none). */
static long cell_max_steps(const ves_study *s) {
  return s->mode == VES_STUDY_STEP ? 1 : s->mode == VES_STUDY_STEPS ? s->steps : 0;
}

ves_status ves_study_cell_signature(const ves_study *s, long k, char *buf, size_t len) {
  char(*sets)[VES_STUDY_SETLEN] = malloc(VES_STUDY_CELL_SETS * sizeof *sets);
  if (!sets) return VES_ERR_ALLOC;
  int n = 0;
  ves_status st = ves_study_cell_sets(s, k, sets, &n, NULL, 0);
  if (st == VES_OK) {
    size_t at = (size_t)snprintf(buf, len, "run %s", s->problem);
    if (cell_max_steps(s) && at < len)
      at += (size_t)snprintf(buf + at, len - at, " --max-steps %ld", cell_max_steps(s));
    for (int i = 0; i < n && at < len; i++)
      at += (size_t)snprintf(buf + at, len - at, " --set %s", sets[i]);
    if (at >= len) st = VES_ERR_ARG;
  }
  free(sets);
  return st;
}

void ves_study_cell_path(const ves_study *s, long k, const char *dir, const char *suffix, char *buf,
                         size_t len) {
  char name[PATH_MAX / 2];
  ves_study_cell_name(s, k, name, sizeof name);
  snprintf(buf, len, "%s/cells/%s%s", dir, name, suffix);
}

ves_status ves_study_cell_argv(const ves_study *s, long k, const char *program, const char *dir,
                               int *argc, char ***argv, char *err, size_t errlen) {
  VES_CHECK(s && program && dir && argc && argv, VES_ERR_ARG);
  *argv = NULL, *argc = 0;
  char(*sets)[VES_STUDY_SETLEN] = malloc(VES_STUDY_CELL_SETS * sizeof *sets);
  if (!sets) return VES_ERR_ALLOC;
  int n = 0;
  ves_status st = ves_study_cell_sets(s, k, sets, &n, err, errlen);
  if (st != VES_OK) {
    free(sets);
    return st;
  }
  char out[PATH_MAX], steps[32];
  ves_study_cell_path(s, k, dir, ".h5", out, sizeof out);
  snprintf(steps, sizeof steps, "%ld", cell_max_steps(s));
  const char *fixed[] = {program, "run", s->problem, "--out", out, "--quiet"};
  const int nf = sizeof fixed / sizeof fixed[0];
  const int na = nf + (cell_max_steps(s) ? 2 : 0) + 2 * n;
  size_t bytes = (size_t)(na + 1) * sizeof(char *);
  for (int i = 0; i < nf; i++) bytes += strlen(fixed[i]) + 1;
  bytes += sizeof "--max-steps" + strlen(steps) + 1;
  for (int i = 0; i < n; i++) bytes += sizeof "--set" + strlen(sets[i]) + 1;
  char **v = malloc(bytes);
  if (!v) {
    free(sets);
    return VES_ERR_ALLOC;
  }
  char *p = (char *)(v + na + 1);
  int c = 0;
#define PUT(str)                                                                                   \
  do {                                                                                             \
    size_t l_ = strlen(str) + 1;                                                                   \
    memcpy(p, str, l_);                                                                            \
    v[c++] = p;                                                                                    \
    p += l_;                                                                                       \
  } while (0)
  for (int i = 0; i < nf; i++) PUT(fixed[i]);
  if (cell_max_steps(s)) {
    PUT("--max-steps");
    PUT(steps);
  }
  for (int i = 0; i < n; i++) {
    PUT("--set");
    PUT(sets[i]);
  }
#undef PUT
  v[c] = NULL;
  free(sets);
  *argv = v, *argc = c;
  return VES_OK;
}

/* ---- the study file ------------------------------------------------------ */

static int cmp_names(const void *a, const void *b) {
  return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Every cell's problem loads, and the names are distinct. */
static ves_status check_cells(const ves_study *s, char *err, size_t errlen) {
  char(*sets)[VES_STUDY_SETLEN] = malloc(VES_STUDY_CELL_SETS * sizeof *sets);
  char **names = calloc((size_t)s->ncells, sizeof *names);
  ves_status st = sets && names ? VES_OK : VES_ERR_ALLOC;
  for (long k = 0; k < s->ncells && st == VES_OK; k++) {
    char msg[1024] = "", name[PATH_MAX / 2];
    int n = 0;
    ves_study_cell_name(s, k, name, sizeof name);
    if (strlen(name) > STUDY_NAME_MAX) { /* + ".result" within a file name's 255 */
      ves_error_say(err, errlen,
                    "%s: [axes] cell %.40s...: a name of %zu characters, more than %d "
                    "(shorter values or fewer axes)",
                    s->path, name, strlen(name), STUDY_NAME_MAX);
      st = VES_ERR_CONFIG;
      break;
    }
    if ((st = ves_study_cell_sets(s, k, sets, &n, msg, sizeof msg)) != VES_OK) {
      ves_error_say(err, errlen, "%s: [axes] cell %s: %s", s->path, name, msg);
      break;
    }
    if (!(names[k] = strdup(name))) st = VES_ERR_ALLOC;
  }
  if (st == VES_OK) {
    qsort(names, (size_t)s->ncells, sizeof *names, cmp_names);
    for (long k = 1; k < s->ncells; k++)
      if (!strcmp(names[k - 1], names[k])) {
        ves_error_say(
            err, errlen,
            "%s: [axes]: two cells are both named '%s' (values that differ only in characters "
            "a file name cannot hold)",
            s->path, names[k]);
        st = VES_ERR_CONFIG;
        break;
      }
  }
  if (names)
    for (long k = 0; k < s->ncells; k++) free(names[k]);
  free(names), free(sets);
  return st;
}

/* The keys of [study] and [slurm]. */
static const char *const STUDY_KEYS[] = {"problem", "run", "steps", "time_limit"};
static const char *const SLURM_KEYS[] = {"partition", "account", "mem", "cpus_per_task"};

static int in_list(const char *k, const char *const *list, int n) {
  for (int i = 0; i < n; i++)
    if (!strcasecmp(k, list[i])) return 1;
  return 0;
}

/* A number of the study file in [lo, hi] (integer when want_int). */
static ves_status study_number(const ves_study *s, const char *sec, const char *key,
                               const char *val, double lo, double hi, int want_int, double *out,
                               char *err, size_t errlen) {
  char *end;
  errno = 0;
  double v = strtod(val, &end);
  while (isspace((unsigned char)*end)) end++;
  if (end == val || *end || errno || !isfinite(v) || (want_int && v != floor(v)) || v < lo ||
      v > hi) {
    ves_error_say(err, errlen, "%s: [%s] %s = '%s': not %s in [%g, %g]", s->path, sec, key, val,
                  want_int ? "an integer" : "a number", lo, hi);
    return VES_ERR_CONFIG;
  }
  *out = v;
  return VES_OK;
}

/* The sections of the study file into s: one section after the other, each
 * read and checked in place (long, but in the file's order). */
static ves_status read_study(dictionary *d, ves_study *s, char *err, size_t errlen) {
  char problem[PATH_MAX] = "";
  for (ssize_t i = 0; i < d->size; i++)
    if (d->key[i] && d->key[i][0] == ':') {
      ves_error_say(err, errlen, "%s: %s: key outside a section", s->path, d->key[i] + 1);
      return VES_ERR_CONFIG;
    }
  for (int i = 0; i < iniparser_getnsec(d); i++) {
    const char *sec = iniparser_getsecname(d, i);
    if (strcasecmp(sec, "study") && strcasecmp(sec, "set") && strcasecmp(sec, "axes") &&
        strcasecmp(sec, "slurm")) {
      ves_error_say(err, errlen, "%s: [%s]: unknown section (study, set, axes, slurm)", s->path,
                    sec);
      return VES_ERR_CONFIG;
    }
    int nk = iniparser_getsecnkeys(d, sec);
    const char **keys = nk > 0 ? malloc((size_t)nk * sizeof *keys) : NULL;
    if (nk > 0 && !keys) return VES_ERR_ALLOC;
    if (nk > 0) iniparser_getseckeys(d, sec, keys);
    ves_status st = VES_OK;
    for (int j = 0; j < nk && st == VES_OK; j++) {
      const char *full = keys[j], *colon = strchr(full, ':');
      const char *key = colon ? colon + 1 : full;
      const char *val = iniparser_getstring(d, full, "");
      double num;
      if (!strcasecmp(sec, "study")) {
        if (!in_list(key, STUDY_KEYS, 4)) {
          ves_error_say(err, errlen,
                        "%s: [study] %s: unknown key (problem, run, steps, time_limit)", s->path,
                        key);
          st = VES_ERR_CONFIG;
        } else if (!strcasecmp(key, "problem")) {
          if (!*val || strlen(val) >= sizeof problem) {
            ves_error_say(err, errlen, "%s: [study] problem: empty or too long", s->path);
            st = VES_ERR_CONFIG;
          } else
            snprintf(problem, sizeof problem, "%s", val);
        } else if (!strcasecmp(key, "run")) {
          if (!strcasecmp(val, "step"))
            s->mode = VES_STUDY_STEP;
          else if (!strcasecmp(val, "steps"))
            s->mode = VES_STUDY_STEPS;
          else if (!strcasecmp(val, "t_end"))
            s->mode = VES_STUDY_T_END;
          else {
            ves_error_say(err, errlen, "%s: [study] run = '%s': not one of step, steps, t_end",
                          s->path, val);
            st = VES_ERR_CONFIG;
          }
        } else if (!strcasecmp(key, "steps")) {
          if ((st = study_number(s, "study", key, val, 1, 1e9, 1, &num, err, errlen)) == VES_OK)
            s->steps = (long)num;
        } else if ((st = study_number(s, "study", key, val, 0, 1e9, 0, &num, err, errlen)) ==
                   VES_OK) {
          s->time_limit = num;
        }
      } else if (!strcasecmp(sec, "slurm")) {
        if (!in_list(key, SLURM_KEYS, 4)) {
          ves_error_say(err, errlen,
                        "%s: [slurm] %s: unknown key (partition, account, mem, cpus_per_task)",
                        s->path, key);
          st = VES_ERR_CONFIG;
        } else if (!strcasecmp(key, "cpus_per_task")) {
          if ((st = study_number(s, "slurm", key, val, 1, 1024, 1, &num, err, errlen)) == VES_OK)
            s->cpus_per_task = (int)num;
        } else {
          char *dst = !strcasecmp(key, "partition") ? s->partition
                      : !strcasecmp(key, "account") ? s->account
                                                    : s->mem;
          size_t cap = !strcasecmp(key, "mem") ? sizeof s->mem : sizeof s->partition;
          int bad = strlen(val) >= cap;
          for (const char *c = val; *c && !bad; c++) /* goes into a shell script */
            bad = !(isalnum((unsigned char)*c) || strchr("._-,", *c));
          if (bad) {
            ves_error_say(err, errlen,
                          "%s: [slurm] %s = '%s': only letters, digits and . _ - , (at most %zu)",
                          s->path, key, val, cap - 1);
            st = VES_ERR_CONFIG;
          } else
            snprintf(dst, cap, "%s", val);
        }
      } else { /* [set] and [axes]: problem keys */
        char canon[64];
        const int axes = !strcasecmp(sec, "axes");
        if (canonical_key(key, canon, sizeof canon)) {
          ves_error_say(err, errlen, "%s: [%s] %s: unknown problem key (see vesica keys)", s->path,
                        sec, key);
          st = VES_ERR_CONFIG;
        } else if (axes) {
          if (s->naxes == VES_STUDY_MAX_AXES) {
            ves_error_say(err, errlen, "%s: [axes] %s: more than %d axes", s->path, canon,
                          VES_STUDY_MAX_AXES);
            st = VES_ERR_CONFIG;
          } else {
            ves_study_axis *ax = &s->axis[s->naxes];
            char msg[256] = "";
            snprintf(ax->key, sizeof ax->key, "%s", canon);
            if ((st = ves_study_parse_axis(val, ax, msg, sizeof msg)) != VES_OK)
              ves_error_say(err, errlen, "%s: [axes] %s: %s", s->path, canon, msg);
            else
              s->naxes++;
          }
        } else if (s->nset == VES_STUDY_MAX_SET) {
          ves_error_say(err, errlen, "%s: [set] %s: more than %d keys", s->path, canon,
                        VES_STUDY_MAX_SET);
          st = VES_ERR_CONFIG;
        } else if (!*val || strlen(canon) + strlen(val) + 2 > VES_STUDY_SETLEN) {
          ves_error_say(err, errlen, "%s: [set] %s: empty or too long a value", s->path, canon);
          st = VES_ERR_CONFIG;
        } else {
          snprintf(s->set[s->nset++], VES_STUDY_SETLEN, "%s=%s", canon, val);
        }
      }
    }
    free(keys);
    if (st != VES_OK) return st;
  }
  if (!problem[0]) {
    ves_error_say(err, errlen, "%s: [study] problem: missing (the base problem file)", s->path);
    return VES_ERR_CONFIG;
  }
  if (problem[0] == '/') { /* relative to the study file's folder */
    snprintf(s->problem, sizeof s->problem, "%s", problem);
  } else {
    const char *slash = strrchr(s->path, '/');
    snprintf(s->problem, sizeof s->problem, "%.*s%s%s", slash ? (int)(slash - s->path) : 0, s->path,
             slash ? "/" : "", problem);
  }
  char abs[PATH_MAX];
  if (!realpath(s->problem, abs)) {
    ves_error_say(err, errlen, "%s: [study] problem = %s: cannot open %s: %s", s->path, problem,
                  s->problem, strerror(errno));
    return VES_ERR_IO;
  }
  snprintf(s->problem, sizeof s->problem, "%s", abs);
  if (s->naxes == 0) {
    ves_error_say(err, errlen, "%s: [axes]: no axis (at least one key with its values)", s->path);
    return VES_ERR_CONFIG;
  }
  for (int a = 0; a < s->naxes; a++) {
    for (int i = 0; i < s->nset; i++)
      if (!strncmp(s->set[i], s->axis[a].key, strlen(s->axis[a].key)) &&
          s->set[i][strlen(s->axis[a].key)] == '=') {
        ves_error_say(err, errlen, "%s: [axes] %s: also fixed in [set]", s->path, s->axis[a].key);
        return VES_ERR_CONFIG;
      }
    for (int b = 0; b < a; b++)
      if (!strcmp(s->axis[a].key, s->axis[b].key)) {
        ves_error_say(err, errlen, "%s: [axes] %s: given twice", s->path, s->axis[a].key);
        return VES_ERR_CONFIG;
      }
  }
  return VES_OK;
}

ves_status ves_study_load(const char *path, long max_cells, ves_study **out, char *err,
                          size_t errlen) {
  VES_CHECK(path && out, VES_ERR_ARG);
  *out = NULL;
  FILE *f = fopen(path, "r");
  if (!f) {
    ves_error_say(err, errlen, "%s: cannot open: %s", path, strerror(errno));
    return VES_ERR_IO;
  }
  fclose(f);
  ves_study *s = calloc(1, sizeof *s);
  if (!s) return VES_ERR_ALLOC;
  snprintf(s->path, sizeof s->path, "%s", path);
  s->mode = VES_STUDY_T_END, s->steps = 1, s->time_limit = 3600;
  snprintf(s->mem, sizeof s->mem, "4G");
  s->cpus_per_task = 1;
  iniparser_set_error_callback(ini_quiet);
  dictionary *d = iniparser_load(path);
  ves_status st = VES_OK;
  if (!d) {
    ves_error_say(err, errlen, "%s: not a readable INI file", path);
    st = VES_ERR_CONFIG;
  }
  if (st == VES_OK) st = read_study(d, s, err, errlen);
  if (d) iniparser_freedict(d);
  if (st == VES_OK) { /* the grid's size, without overflow */
    s->ncells = 1;
    for (int a = 0; a < s->naxes; a++) {
      s->ncells *= s->axis[a].nvalues;
      if (s->ncells > max_cells) {
        long total = 1;
        for (int b = 0; b < s->naxes && total <= 1000000000L; b++) total *= s->axis[b].nvalues;
        ves_error_say(
            err, errlen,
            "%s: [axes]: the grid has %s%ld cells, more than the limit %ld (raise it with "
            "--max-cells)",
            path, total > 1000000000L ? "over " : "", total > 1000000000L ? 1000000000L : total,
            max_cells);
        st = VES_ERR_CONFIG;
        break;
      }
    }
  }
  if (st == VES_OK) st = check_cells(s, err, errlen);
  if (st != VES_OK) {
    free(s);
    return st;
  }
  *out = s;
  return VES_OK;
}

void ves_study_print_keys(FILE *f) {
  static const char *const rows[][6] = {
      {"study", "problem", "text", "(required)", "a file",
       "the base problem file, relative to the study file's folder"},
      {"study", "run", "text", "t_end", "step\\|steps\\|t_end",
       "what a cell runs: one step of constant dt = time.dt_initial from the initial state "
       "with no halving (time.adaptive = 0, dt_min = dt_max = t_end = dt_initial are added), "
       "`steps` accepted steps, or the problem to its t_end"},
      {"study", "steps", "integer", "1", "1 to 1e9", "run = steps: accepted steps per cell"},
      {"study", "time_limit", "real", "3600", "0 to 1e9",
       "wall seconds per cell (0: none); then SIGTERM, SIGKILL 10 s later: status timeout"},
      {"set", "section.key", "as the key", "", "as the key",
       "a problem key fixed for every cell (as --set section.key=value)"},
      {"axes", "section.key", "list or range", "", "as the key",
       "a problem key swept: `a, b, c`, `log(from, to, count)` (geometric) or "
       "`lin(from, to, count)`; the cells are every combination, the first axis varying "
       "slowest (at most 8 axes, 256 values each)"},
      {"slurm", "partition", "text", "(the cluster's)", "letters, digits, . _ - ,",
       "--emit slurm: #SBATCH --partition"},
      {"slurm", "account", "text", "(none)", "letters, digits, . _ - ,",
       "--emit slurm: #SBATCH --account"},
      {"slurm", "mem", "text", "4G", "letters, digits, . _ - ,", "--emit slurm: #SBATCH --mem"},
      {"slurm", "cpus_per_task", "integer", "1", "1 to 1024",
       "--emit slurm: #SBATCH --cpus-per-task, the cell's OMP_NUM_THREADS"},
  };
  fprintf(f, "| section | key | type | default | allowed | meaning |\n|---|---|---|---|---|---|\n");
  for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++)
    fprintf(f, "| %s | %s | %s | %s | %s | %s |\n", rows[i][0], rows[i][1], rows[i][2], rows[i][3],
            rows[i][4], rows[i][5]);
}

void ves_study_destroy(ves_study **s) {
  if (!s) return;
  free(*s);
  *s = NULL;
}

/* ---- .result files -------------------------------------------------------- */

/* s with newlines, tabs and other control characters as spaces. */
static void one_line(char *s) {
  for (; *s; s++)
    if ((unsigned char)*s < 32) *s = ' ';
}

ves_status ves_study_result_write(const char *path, const ves_study_result *r) {
  char tmp[PATH_MAX + 8];
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  FILE *f = fopen(tmp, "w");
  if (!f) return VES_ERR_IO;
  ves_study_result c = *r;
  one_line(c.reason), one_line(c.signature), one_line(c.outcome);
  fprintf(f,
          "outcome = %s\nreason = %s\nexit_code = %d\nsignal = %d\nwall_seconds = %.3f\n"
          "cpu_seconds = %.3f\npeak_mb = %.1f\nsignature = %s\n",
          c.outcome, c.reason, c.exit_code, c.signal, c.wall_seconds, c.cpu_seconds, c.peak_mb,
          c.signature);
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  if (bad || rename(tmp, path) != 0) {
    remove(tmp);
    return VES_ERR_IO;
  }
  return VES_OK;
}

ves_status ves_study_result_read(const char *path, ves_study_result *r) {
  memset(r, 0, sizeof *r);
  FILE *f = fopen(path, "r");
  if (!f) return VES_ERR_IO;
  char line[8192];
  int seen = 0;
  while (fgets(line, sizeof line, f)) {
    line[strcspn(line, "\n")] = 0;
    char *eq = strstr(line, " = ");
    if (!eq) continue;
    *eq = 0;
    const char *k = line, *v = eq + 3;
    if (!strcmp(k, "outcome"))
      snprintf(r->outcome, sizeof r->outcome, "%s", v), seen |= 1;
    else if (!strcmp(k, "reason"))
      snprintf(r->reason, sizeof r->reason, "%s", v);
    else if (!strcmp(k, "exit_code"))
      r->exit_code = atoi(v);
    else if (!strcmp(k, "signal"))
      r->signal = atoi(v);
    else if (!strcmp(k, "wall_seconds"))
      r->wall_seconds = strtod(v, NULL);
    else if (!strcmp(k, "cpu_seconds"))
      r->cpu_seconds = strtod(v, NULL);
    else if (!strcmp(k, "peak_mb"))
      r->peak_mb = strtod(v, NULL);
    else if (!strcmp(k, "signature"))
      snprintf(r->signature, sizeof r->signature, "%s", v), seen |= 2;
  }
  fclose(f);
  return seen == 3 ? VES_OK : VES_ERR_IO;
}

int ves_study_cell_done(const ves_study *s, long k, const char *dir, int retry_failed) {
  char path[PATH_MAX], sig[sizeof((ves_study_result *)0)->signature];
  ves_study_result r;
  ves_study_cell_path(s, k, dir, ".result", path, sizeof path);
  if (ves_study_result_read(path, &r) != VES_OK) return 0;
  if (ves_study_cell_signature(s, k, sig, sizeof sig) != VES_OK || strcmp(sig, r.signature))
    return 0; /* made by another version of the study: stale */
  return !retry_failed || !strcmp(r.outcome, "converged");
}

void ves_study_classify(int exit_code, int sig, int timed_out, double time_limit,
                        const char *log_path, ves_study_result *r) {
  char last[512] = "", line[512];
  FILE *f = log_path ? fopen(log_path, "r") : NULL;
  while (f && fgets(line, sizeof line, f)) { /* the last line the program wrote about itself */
    line[strcspn(line, "\n")] = 0;
    if (!strncmp(line, "vesica", 6)) snprintf(last, sizeof last, "%s", line);
  }
  if (f) fclose(f);
  const char *why = last;
  if (!strncmp(why, "vesica run: ", 12)) why += 12;
  const char *cause = strstr(why, "no acceptable step"); /* a failed run: its cause, not paths */
  char buf[512];
  if (cause) { /* up to the first ';' outside parentheses (the solver's reason may hold one) */
    int len = 0, depth = 0;
    for (; cause[len] && !(cause[len] == ';' && depth == 0); len++)
      depth += cause[len] == '(' ? 1 : cause[len] == ')' && depth > 0 ? -1 : 0;
    snprintf(buf, sizeof buf, "%.*s", len, cause);
    why = buf;
  }
  r->exit_code = sig ? -1 : exit_code;
  r->signal = sig;
  if (timed_out) {
    snprintf(r->outcome, sizeof r->outcome, "timeout");
    snprintf(r->reason, sizeof r->reason, "time limit %g s", time_limit);
  } else if (sig) {
    snprintf(r->outcome, sizeof r->outcome, "crashed");
    snprintf(r->reason, sizeof r->reason, "killed by signal %d (%s)", sig, strsignal(sig));
  } else if (exit_code == 0) {
    snprintf(r->outcome, sizeof r->outcome, "converged");
    r->reason[0] = 0;
  } else if (exit_code == 2) {
    snprintf(r->outcome, sizeof r->outcome, "bad_input");
    snprintf(r->reason, sizeof r->reason, "%.200s", why);
  } else if (exit_code == 3) {
    snprintf(r->outcome, sizeof r->outcome, "failed");
    snprintf(r->reason, sizeof r->reason, "%.200s", why);
  } else {
    snprintf(r->outcome, sizeof r->outcome, "crashed");
    snprintf(r->reason, sizeof r->reason, "exit code %d%s%.200s", exit_code, *why ? ": " : "", why);
  }
}

/* ---- the table ------------------------------------------------------------- */

/* Everything a row of the table holds for one done cell. */
typedef struct {
  ves_study_result res; /* how the process ended */
  char status[16];      /* res.outcome, or energy_rose / no_output */
  char reason[320];
  int have; /* the .h5 was read */
  long steps;
  int nodes;
  double t_final, dt_first, iterations, f_evals, g_evals, h_evals, retries, violation;
  double E0, E1, area_drift, volume_drift, setup, loop;
} cell_row;

/* The row of cell k from its .result and .h5; 0 when the cell is not done
 * (no .result of this study). */
static int read_row(const ves_study *s, long k, const char *dir, cell_row *row) {
  char path[PATH_MAX], sig[sizeof row->res.signature], err[512];
  memset(row, 0, sizeof *row);
  ves_study_cell_path(s, k, dir, ".result", path, sizeof path);
  if (ves_study_result_read(path, &row->res) != VES_OK) return 0;
  if (ves_study_cell_signature(s, k, sig, sizeof sig) != VES_OK || strcmp(sig, row->res.signature))
    return 0;
  snprintf(row->status, sizeof row->status, "%s", row->res.outcome);
  snprintf(row->reason, sizeof row->reason, "%s", row->res.reason);
  ves_study_cell_path(s, k, dir, ".h5", path, sizeof path);
  ves_io *io = NULL;
  if (access(path, R_OK) == 0 && ves_io_open(path, 0, &io, err, sizeof err) == VES_OK) {
    const ves_io_info *in = ves_io_get_info(io);
    const long R = ves_io_rows(io);
    const char *names[] = {"t",        "dt",         "E",           "A",       "V",
                           "V_target", "iterations", "f_evals",     "g_evals", "h_evals",
                           "retries",  "violation",  "wall_seconds"};
    enum { NC = sizeof names / sizeof names[0] };
    double *col[NC] = {0};
    int ok = 1;
    for (int c = 0; c < NC && ok; c++) {
      col[c] = malloc((size_t)(R > 0 ? R : 1) * sizeof *col[c]);
      ok = col[c] && ves_io_read_series(io, names[c], col[c]) == VES_OK;
    }
    if (ok) {
      row->have = 1, row->steps = R, row->nodes = in->n, row->setup = in->setup_seconds;
      row->E0 = in->E0, row->E1 = R ? col[2][R - 1] : in->E0;
      row->t_final = R ? col[0][R - 1] : 0.0, row->dt_first = R ? col[1][0] : NAN;
      row->loop = R ? col[12][R - 1] : NAN;
      for (long i = 0; i < R; i++) {
        row->area_drift = fmax(row->area_drift, fabs(col[3][i] / in->A0 - 1));
        row->volume_drift = fmax(row->volume_drift, fabs(col[4][i] / col[5][i] - 1));
        row->iterations += col[6][i], row->f_evals += col[7][i], row->g_evals += col[8][i];
        row->h_evals += col[9][i], row->retries += col[10][i];
        row->violation = fmax(row->violation, col[11][i]);
      }
    }
    for (int c = 0; c < NC; c++) free(col[c]);
    ves_io_close(&io);
  }
  if (!strcmp(row->status, "converged")) {
    if (!row->have || (s->mode != VES_STUDY_T_END && row->steps == 0)) {
      snprintf(row->status, sizeof row->status, "no_output");
      snprintf(row->reason, sizeof row->reason, "exit 0 but no step in a readable %.200s", path);
    } else if (s->mode == VES_STUDY_STEP && row->E1 > row->E0 + STUDY_RISE_TOL * fabs(row->E0)) {
      /* explicit Euler is not checked by the integrator: a step that
       * raises E* is its instability, not a solution */
      snprintf(row->status, sizeof row->status, "energy_rose");
      snprintf(row->reason, sizeof row->reason, "E* %.6f -> %.6f", row->E0, row->E1);
    }
  }
  return 1;
}

/* A CSV field: quoted (quotes doubled) when it holds a comma, quote or blank. */
static void csv_text(FILE *f, const char *t) {
  if (!t[strcspn(t, ",\" \t")]) {
    fputs(t, f);
    return;
  }
  fputc('"', f);
  for (; *t; t++) {
    if (*t == '"') fputc('"', f);
    fputc(*t, f);
  }
  fputc('"', f);
}

/* A number (empty when not finite or unknown). */
static void csv_num(FILE *f, int known, const char *fmt, double v) {
  fputc(',', f);
  if (known && isfinite(v)) fprintf(f, fmt, v);
}

ves_status ves_study_collect(const ves_study *s, const char *dir, ves_study_table *t, char *err,
                             size_t errlen) {
  VES_CHECK(s && dir && t, VES_ERR_ARG);
  memset(t, 0, sizeof *t);
  t->cells = s->ncells;
  char path[PATH_MAX], tmp[PATH_MAX + 8];
  snprintf(path, sizeof path, "%s/study.csv", dir);
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  FILE *f = fopen(tmp, "w");
  if (!f) {
    ves_error_say(err, errlen, "%s: cannot write: %s", tmp, strerror(errno));
    return VES_ERR_IO;
  }
  fputs("cell", f);
  for (int a = 0; a < s->naxes; a++) fprintf(f, ",%s", s->axis[a].key);
  fputs(",status,reason,exit_code,steps,t_final,dt_first,iterations,f_evals,g_evals,h_evals,"
        "retries,violation_max,energy_initial,energy_final,area_drift_max,volume_drift_max,"
        "nodes,setup_seconds,loop_seconds,seconds_per_step,wall_seconds,cpu_seconds,peak_mb\n",
        f);
  for (long k = 0; k < s->ncells; k++) {
    cell_row r;
    if (!read_row(s, k, dir, &r)) continue;
    t->rows++;
    t->converged += !strcmp(r.status, "converged");
    char name[PATH_MAX / 2];
    int idx[VES_STUDY_MAX_AXES];
    ves_study_cell_name(s, k, name, sizeof name);
    ves_study_cell_index(s, k, idx);
    csv_text(f, name);
    for (int a = 0; a < s->naxes; a++) {
      fputc(',', f);
      csv_text(f, s->axis[a].values[idx[a]]);
    }
    fputc(',', f);
    csv_text(f, r.status);
    fputc(',', f);
    csv_text(f, r.reason);
    fputc(',', f);
    if (!r.res.signal) fprintf(f, "%d", r.res.exit_code);
    const int h = r.have;
    csv_num(f, h, "%.0f", (double)r.steps);
    csv_num(f, h, "%.12g", r.t_final);
    csv_num(f, h && r.steps, "%.12g", r.dt_first);
    csv_num(f, h, "%.0f", r.iterations);
    csv_num(f, h, "%.0f", r.f_evals);
    csv_num(f, h, "%.0f", r.g_evals);
    csv_num(f, h, "%.0f", r.h_evals);
    csv_num(f, h, "%.0f", r.retries);
    csv_num(f, h && r.steps, "%.3e", r.violation);
    csv_num(f, h, "%.9f", r.E0);
    csv_num(f, h && r.steps, "%.9f", r.E1);
    csv_num(f, h && r.steps, "%.3e", r.area_drift);
    csv_num(f, h && r.steps, "%.3e", r.volume_drift);
    csv_num(f, h, "%.0f", (double)r.nodes);
    csv_num(f, h, "%.3f", r.setup);
    csv_num(f, h && r.steps, "%.3f", r.loop);
    csv_num(f, h && r.steps, "%.4g", r.loop / (double)r.steps);
    csv_num(f, 1, "%.3f", r.res.wall_seconds);
    csv_num(f, 1, "%.3f", r.res.cpu_seconds);
    csv_num(f, 1, "%.1f", r.res.peak_mb);
    fputc('\n', f);
  }
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  if (bad || rename(tmp, path) != 0) {
    ves_error_say(err, errlen, "%s: cannot write: %s", path, strerror(errno));
    remove(tmp);
    return VES_ERR_IO;
  }
  return VES_OK;
}

/* ---- figures ---------------------------------------------------------------- */

/* The study figures' data block $d into f: a row a cell (group, dt,
 * converged 1/0, seconds per step), the groups being the values of the
 * axes other than ad (the dt axis); front[g] the largest converged dt of
 * group g (NaN: none), label[g] its axes' values. */
static void frontier_data(FILE *f, const ves_study *s, const char *dir, int ad, long G,
                          double *front, char (*label)[256]) {
  fprintf(f, "$d << EOD\n");
  for (long g = 0; g < G; g++) front[g] = NAN, label[g][0] = 0;
  for (long k = 0; k < s->ncells; k++) {
    int idx[VES_STUDY_MAX_AXES];
    ves_study_cell_index(s, k, idx);
    long g = 0;
    size_t at = 0;
    for (int a = 0; a < s->naxes; a++) {
      if (a == ad) continue;
      g = g * s->axis[a].nvalues + idx[a];
    }
    const int named = label[g][0] != 0;
    for (int a = 0; a < s->naxes && !named; a++) {
      if (a == ad) continue;
      char e[128];
      ves_plot_gp_escape(e, sizeof e, s->axis[a].values[idx[a]]);
      at += (size_t)snprintf(label[g] + at, sizeof label[g] - at, "%s%s", at ? " " : "", e);
      if (at >= sizeof label[g]) at = sizeof label[g] - 1;
    }
    if (!label[g][0]) snprintf(label[g], sizeof label[g], "all");
    cell_row r;
    if (!read_row(s, k, dir, &r)) continue;
    const double dt = strtod(s->axis[ad].values[idx[ad]], NULL);
    const int conv = !strcmp(r.status, "converged");
    if (conv && !(front[g] >= dt)) front[g] = dt;
    fprintf(f, "%ld %.9g %d %.6g\n", g, dt, conv, conv && r.steps ? r.loop / (double)r.steps : NAN);
  }
}

ves_status ves_study_plot(const ves_study *s, const char *dir, char *err, size_t errlen) {
  VES_CHECK(s && dir, VES_ERR_ARG);
  int ad = -1;
  for (int a = 0; a < s->naxes; a++)
    if (!strcmp(s->axis[a].key, "time.dt_initial")) ad = a;
  if (ad < 0) {
    ves_error_say(err, errlen, "no time.dt_initial axis: no figures");
    return VES_STEP_REJECTED;
  }
  const long G = s->ncells / s->axis[ad].nvalues; /* groups: the other axes' values */
  char script[PATH_MAX];
  const char *tdir = getenv("TMPDIR");
  snprintf(script, sizeof script, "%s/vesica_study_XXXXXX", tdir && *tdir ? tdir : "/tmp");
  int fd = mkstemp(script);
  FILE *f = fd >= 0 ? fdopen(fd, "w") : NULL;
  if (!f) {
    if (fd >= 0) close(fd), unlink(script);
    ves_error_say(err, errlen, "cannot create a temporary file %s: %s", script, strerror(errno));
    return VES_ERR_IO;
  }
  double *front = malloc((size_t)G * sizeof *front);
  char(*label)[256] = malloc((size_t)G * sizeof *label);
  if (!front || !label) {
    fclose(f), unlink(script), free(front), free(label);
    return VES_ERR_ALLOC;
  }
  frontier_data(f, s, dir, ad, G, front, label);
  fprintf(f, "NaN NaN NaN NaN\nEOD\n$front << EOD\n");
  for (long g = 0; g < G; g++) fprintf(f, "%ld %.9g\n", g, front[g]);
  fprintf(f, "EOD\n");
  char title[PATH_MAX + 64], path[PATH_MAX];
  const char *base = strrchr(s->path, '/') ? strrchr(s->path, '/') + 1 : s->path;
  ves_plot_gp_escape(title, sizeof title, base);
  fprintf(
      f, "set terminal pngcairo size 900,%ld font ',10'\nset logscale x\nset format x '10^{%%L}'\n",
      480 + 24 * (G > 8 ? G - 8 : 0));
  fprintf(f, "set grid\nset key outside right top\nset offsets graph 0.04, graph 0.04\n");
  snprintf(path, sizeof path, "%s/study_frontier.png", dir);
  fputs("set output ", f), ves_plot_gp_quote(f, path), fputc('\n', f);
  fprintf(f, "set title 'robustness frontier: %s (circled: the largest converged dt*)'\n", title);
  fprintf(f, "set xlabel 'dt*'\nset ylabel ''\nset yrange [-0.5:%ld.5]\nset ytics (", G - 1);
  for (long g = 0; g < G; g++) {
    fprintf(f, "%s", g ? ", " : "");
    ves_plot_gp_quote(f, label[g]);
    fprintf(f, " %ld", g);
  }
  fprintf(f, ")\nplot $d u 2:($3 == 1 ? $1 : NaN) w p pt 7 ps 1.5 lc rgb '#1a9850' "
             "t 'converged', \\\n  $d u 2:($3 == 0 ? $1 : NaN) w p pt 2 ps 1.5 lc rgb '#d73027' "
             "t 'not converged', \\\n  $front u 2:1 w p pt 6 ps 3 lc rgb 'black' t 'largest'\n");
  snprintf(path, sizeof path, "%s/study_cost.png", dir);
  fputs("set output ", f), ves_plot_gp_quote(f, path), fputc('\n', f);
  fprintf(f,
          "set title 'cost: %s (converged cells)'\nset ytics auto\nset autoscale y\n"
          "set logscale y\nset ylabel 'seconds per step'\nplot ",
          title);
  for (long g = 0; g < G; g++) {
    fprintf(f, "%s$d u ($1 == %ld ? $2 : NaN):4 w lp pt 7 t ", g ? ", \\\n  " : "", g);
    ves_plot_gp_quote(f, label[g]);
  }
  fputc('\n', f);
  free(front), free(label);
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  if (bad) {
    unlink(script);
    ves_error_say(err, errlen, "cannot write the gnuplot script %s", script);
    return VES_ERR_IO;
  }
  ves_status st = ves_plot_run_gnuplot(script, err, errlen);
  unlink(script);
  return st;
}

/* ---- Slurm ------------------------------------------------------------------- */

/* A shell single-quoted word ('\'' for '). */
static void sh_quote(FILE *f, const char *s) {
  fputc('\'', f);
  for (; *s; s++) {
    if (*s == '\'')
      fputs("'\\''", f);
    else
      fputc(*s, f);
  }
  fputc('\'', f);
}

ves_status ves_study_write_sbatch(const ves_study *s, const char *program, const char *dir,
                                  char *err, size_t errlen) {
  VES_CHECK(s && program && dir, VES_ERR_ARG);
  char path[PATH_MAX + 16], logs[PATH_MAX + 8], study[PATH_MAX], adir[PATH_MAX];
  char tmp[PATH_MAX + 24];
  if (!realpath(dir, adir) || !realpath(s->path, study)) {
    ves_error_say(err, errlen, "%s: cannot resolve: %s", dir, strerror(errno));
    return VES_ERR_IO;
  }
  snprintf(logs, sizeof logs, "%s/slurm", adir);
  if (mkdir(logs, 0777) != 0 && errno != EEXIST) {
    ves_error_say(err, errlen, "%s: cannot create: %s", logs, strerror(errno));
    return VES_ERR_IO;
  }
  snprintf(path, sizeof path, "%s/study.sbatch", adir);
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  FILE *f = fopen(tmp, "w");
  if (!f) {
    ves_error_say(err, errlen, "%s: cannot write: %s", tmp, strerror(errno));
    return VES_ERR_IO;
  }
  const char *base = strrchr(study, '/') + 1;
  char job[64];
  snprintf(job, sizeof job, "vesica-%.*s", (int)strcspn(base, "."), base);
  for (char *c = job; *c; c++)
    if (!isalnum((unsigned char)*c) && *c != '-' && *c != '_') *c = '_';
  fprintf(f, "#!/bin/bash\n# vesica study %s: %ld cells, one per array task.\n", study, s->ncells);
  fprintf(f, "# Submit: sbatch %s\n# Then: vesica study %s --out %s --collect\n", path, study,
          adir);
  fprintf(f, "#SBATCH --job-name=%s\n#SBATCH --array=0-%ld\n#SBATCH --ntasks=1\n", job,
          s->ncells - 1);
  fprintf(f, "#SBATCH --cpus-per-task=%d\n#SBATCH --mem=%s\n", s->cpus_per_task, s->mem);
  if (s->time_limit > 0) /* the cell's own limit stops it first */
    fprintf(f, "#SBATCH --time=%ld\n", (long)ceil(s->time_limit / 60) + 5);
  fprintf(f, "#SBATCH --output=%s/%%A_%%a.out\n", logs);
  if (s->partition[0]) fprintf(f, "#SBATCH --partition=%s\n", s->partition);
  if (s->account[0]) fprintf(f, "#SBATCH --account=%s\n", s->account);
  fprintf(f, "export OMP_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-%d}\"\n", s->cpus_per_task);
  fprintf(f, "export OPENBLAS_NUM_THREADS=1\nexec ");
  sh_quote(f, program);
  fputs(" study ", f);
  sh_quote(f, study);
  fputs(" --out ", f);
  sh_quote(f, adir);
  fprintf(f, " --max-cells %ld --cell \"${SLURM_ARRAY_TASK_ID:?not a Slurm array task}\"\n",
          s->ncells > VES_STUDY_MAX_CELLS ? s->ncells : (long)VES_STUDY_MAX_CELLS);
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  if (bad || rename(tmp, path) != 0 || chmod(path, 0755) != 0) {
    ves_error_say(err, errlen, "%s: cannot write: %s", path, strerror(errno));
    remove(tmp);
    return VES_ERR_IO;
  }
  return VES_OK;
}
