/* vesica — studies: parsing the study file (sections [study], [set], [axes],
 * [slurm]) and the command line's --set, the grid of cells, their names,
 * overrides, signatures and commands, the setup's geometric checks of each
 * cell, and the study folder's identity (DIR/study.set). No process is started here (study_run.c
 * runs the cells, study_output.c writes the table, figures and Slurm script). User-facing
 * behaviour: docs/manual.md; docs/design.md, "The program". */
#include "app/study.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/config.h"
#include "app/problem.h"
#include "ves/shape.h"

/* Longest cell name: NAME.result must fit a file name (255 bytes). */
#define STUDY_NAME_MAX 200

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

/* t appended to buf[len] at *at: letters, digits and . _ + - as they are,
 * every other byte as %XX (two upper-case hex digits), so that '=', ',' and
 * '%' never appear unescaped and a name parses back to its keys and values. */
static void name_append(char *buf, size_t len, size_t *at, const char *t) {
  static const char hex[] = "0123456789ABCDEF";
  for (; *t; t++) {
    const unsigned char c = (unsigned char)*t;
    if (isalnum(c) || c == '.' || c == '_' || c == '+' || c == '-') {
      if (*at + 1 >= len) break;
      buf[(*at)++] = (char)c;
    } else {
      if (*at + 3 >= len) break;
      buf[(*at)++] = '%', buf[(*at)++] = hex[c >> 4], buf[(*at)++] = hex[c & 15];
    }
  }
  buf[*at] = 0;
}

void ves_study_cell_name(const ves_study *s, long k, char *buf, size_t len) {
  int idx[VES_STUDY_MAX_AXES];
  ves_study_cell_index(s, k, idx);
  size_t at = 0;
  buf[0] = 0;
  for (int a = 0; a < s->naxes; a++) {
    if (a && at + 1 < len) buf[at++] = ',', buf[at] = 0;
    name_append(buf, len, &at, axis_short(s, a));
    if (at + 1 < len) buf[at++] = '=', buf[at] = 0;
    name_append(buf, len, &at, s->axis[a].values[idx[a]]);
  }
}

/* The name cell k gets in the scheme "key-value" joined by "_" (bytes other
 * than letters, digits, '.', '+', '-' as '_'), which cannot be parsed back
 * (keys hold '_', values '-'): a folder holding such files is recognised
 * and refused rather than run again under other names. */
static void cell_name_dashed(const ves_study *s, long k, char *buf, size_t len) {
  int idx[VES_STUDY_MAX_AXES];
  ves_study_cell_index(s, k, idx);
  size_t at = 0;
  buf[0] = 0;
  for (int a = 0; a < s->naxes; a++) {
    const char *part[3] = {axis_short(s, a), "-", s->axis[a].values[idx[a]]};
    if (a && at + 1 < len) buf[at++] = '_', buf[at] = 0;
    for (int j = 0; j < 3; j++)
      for (const char *t = part[j]; *t && at + 1 < len; t++)
        buf[at++] = isalnum((unsigned char)*t) || strchr(".+-", *t) ? *t : '_', buf[at] = 0;
  }
}

ves_status ves_study_cell_sets(const ves_study *s, long k, char buf[][VES_STUDY_SETLEN], int *nset,
                               char *err, size_t errlen) {
  int idx[VES_STUDY_MAX_AXES], n = 0;
  ves_study_cell_index(s, k, idx);
  for (int i = 0; i < s->nset; i++) {
    const size_t kl = strcspn(s->set[i], "=");
    int replaced = 0; /* a [set] key the command line sets again */
    for (int j = 0; j < s->ncli && !replaced; j++)
      replaced = !strncmp(s->cli[j], s->set[i], kl + 1);
    if (!replaced) snprintf(buf[n++], VES_STUDY_SETLEN, "%s", s->set[i]);
  }
  for (int i = 0; i < s->ncli; i++) snprintf(buf[n++], VES_STUDY_SETLEN, "%s", s->cli[i]);
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

/* ---- the study folder ---------------------------------------------------- */

static int cmp_text(const void *a, const void *b) {
  return strcmp((const char *)a, (const char *)b);
}

/* The overrides of list[n] sorted and joined by " --set " into buf[len]
 * ("(none)" when n = 0), for a message. */
static void sets_text(char (*list)[VES_STUDY_SETLEN], int n, char *buf, size_t len) {
  qsort(list, (size_t)n, sizeof *list, cmp_text);
  size_t at = 0;
  buf[0] = 0;
  if (!n) snprintf(buf, len, "no --set");
  for (int i = 0; i < n && at < len; i++)
    at += (size_t)snprintf(buf + at, len - at, "%s--set %s", i ? " " : "", list[i]);
}

/* Whether dir/cells holds any file (a folder with cells run or started). */
static int folder_has_cells(const char *dir) {
  char path[PATH_MAX + 8];
  snprintf(path, sizeof path, "%s/cells", dir);
  DIR *d = opendir(path);
  struct dirent *e;
  int any = 0;
  while (d && !any && (e = readdir(d))) any = strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
  if (d) closedir(d);
  return any;
}

ves_status ves_study_check_folder(const ves_study *s, const char *dir, int write_record, char *err,
                                  size_t errlen) {
  VES_CHECK(s && dir, VES_ERR_ARG);
  char path[PATH_MAX + 16], name[PATH_MAX / 2];
  struct stat sb;
  for (long k = 0; k < s->ncells; k++) { /* cells named key-value_key-value */
    cell_name_dashed(s, k, name, sizeof name);
    const char *ext[] = {".result", ".h5"};
    for (int e = 0; e < 2; e++) {
      snprintf(path, sizeof path, "%s/cells/%s%s", dir, name, ext[e]);
      if (stat(path, &sb) == 0) {
        char now[PATH_MAX / 2];
        ves_study_cell_name(s, k, now, sizeof now);
        ves_error_say(err, errlen,
                      "%s: a cell named in the scheme key-value_key-value, which does not parse "
                      "back; this vesica names it %s: rename its files (.h5, .xdmf, .log, "
                      ".result) to that name to keep them, or use another --out",
                      path, now);
        return VES_ERR_CONFIG;
      }
    }
  }
  char(*had)[VES_STUDY_SETLEN] = malloc(2 * VES_STUDY_MAX_SET * sizeof *had);
  if (!had) return VES_ERR_ALLOC;
  char(*want)[VES_STUDY_SETLEN] = had + VES_STUDY_MAX_SET;
  int nhad = 0, same;
  snprintf(path, sizeof path, "%s/study.set", dir);
  FILE *f = fopen(path, "r");
  const int recorded = f != NULL;
  char line[VES_STUDY_SETLEN + 8];
  while (f && fgets(line, sizeof line, f) && nhad < VES_STUDY_MAX_SET) {
    line[strcspn(line, "\n")] = 0;
    if (line[0] && line[0] != '#') snprintf(had[nhad++], VES_STUDY_SETLEN, "%.191s", line);
  }
  if (f) fclose(f);
  for (int i = 0; i < s->ncli; i++) snprintf(want[i], VES_STUDY_SETLEN, "%s", s->cli[i]);
  qsort(had, (size_t)nhad, sizeof *had, cmp_text);
  qsort(want, (size_t)s->ncli, sizeof *want, cmp_text);
  same = nhad == s->ncli || (!recorded && !folder_has_cells(dir)); /* a fresh folder */
  for (int i = 0; i < nhad && same && nhad == s->ncli; i++) same = !strcmp(had[i], want[i]);
  ves_status st = VES_OK;
  if (!same) {
    char a[2048], b[2048];
    sets_text(had, nhad, a, sizeof a);
    sets_text(want, s->ncli, b, sizeof b);
    ves_error_say(err, errlen,
                  "%s: the study in this folder was made with %s%s; this call gives %s: one "
                  "folder holds one study (the same --set continues it; another --out for "
                  "another)",
                  dir, a, recorded ? " (its study.set)" : " (the folder has no study.set)", b);
    st = VES_ERR_CONFIG;
  } else if (!recorded && write_record) {
    char tmp[PATH_MAX + 48];
    snprintf(tmp, sizeof tmp, "%s.%ld.tmp", path, (long)getpid());
    f = fopen(tmp, "w");
    if (f) {
      fprintf(f, "# vesica study: the command line's --set of the study in this folder\n");
      for (int i = 0; i < s->ncli; i++) fprintf(f, "%s\n", s->cli[i]);
    }
    if (!f || ferror(f) | (fclose(f) != 0) || rename(tmp, path) != 0) {
      ves_error_say(err, errlen, "%s: cannot write: %s", path, strerror(errno));
      remove(tmp);
      st = VES_ERR_IO;
    }
  }
  free(had);
  return st;
}

/* ---- the setup's geometric checks ------------------------------------------ */

/* The geometry of cfg that the checks below depend on, as text (cells with
 * the same text pass or fail them together). */
static void geometry_key(const ves_config *c, char *buf, size_t len) {
  snprintf(buf, len, "%s|%s|%.17g|%.17g|%s|%d|%.17g|%.17g|%.17g|%.17g|%.17g|%.17g|%d",
           c->shape_type, c->points, c->radius, c->reduced_volume, c->orientation, c->mode,
           c->delta, c->epsilon, c->box_r, c->box_z, c->band, c->h_band, c->band_layers);
}

/* The checks of ves_setup_nodes that come before any node is made
 * (ves_setup_check_geometry): what vesica check refuses with exit 2 as
 * "bad input" although every key is in range; milliseconds, not a setup. */
static ves_status geometry_check(const ves_config *c, char *err, size_t errlen) {
  ves_shape *shape = NULL;
  ves_discret_params d;
  char msg[1024] = "";
  ves_status st = ves_problem_shape(c, &shape, msg, sizeof msg);
  if (st == VES_OK) st = ves_problem_discret(c, &d, msg, sizeof msg);
  if (st == VES_OK) st = ves_setup_check_geometry(&d, shape, msg, sizeof msg);
  ves_shape_destroy(&shape);
  if (st == VES_ERR_CONFIG) {
    ves_error_say(err, errlen, "%s", msg);
    return st;
  }
  return VES_OK; /* a shape that fails otherwise is the run's to report */
}

ves_status ves_study_cell_check(const ves_study *s, long k, char *err, size_t errlen) {
  char(*sets)[VES_STUDY_SETLEN] = malloc(VES_STUDY_CELL_SETS * sizeof *sets);
  if (!sets) return VES_ERR_ALLOC;
  const char *ptr[VES_STUDY_CELL_SETS];
  int n = 0;
  ves_config cfg;
  ves_status st = ves_study_cell_sets(s, k, sets, &n, err, errlen);
  for (int i = 0; i < n; i++) ptr[i] = sets[i];
  if (st == VES_OK) st = ves_config_load(s->problem, n, ptr, &cfg, err, errlen);
  free(sets);
  if (st == VES_OK) st = geometry_check(&cfg, err, errlen);
  return st;
}

/* Every cell through the geometric checks, each distinct geometry once:
 * when every cell fails them, the study is refused (VES_ERR_CONFIG, the
 * first cell's message); when some do, those cells are recorded as
 * bad_input without running (ves_study_run). */
static ves_status check_geometry(const ves_study *s, char *err, size_t errlen) {
  enum { MEMO = 64 };
  char(*key)[4 * VES_CONFIG_STR + 256] = malloc(MEMO * sizeof *key), cur[4 * VES_CONFIG_STR + 256],
                                  msg[1024] = "", first[1024] = "";
  int *ok = malloc(MEMO * sizeof *ok), nmemo = 0, geometric = 0;
  if (!key || !ok) {
    free(key), free(ok);
    return VES_ERR_ALLOC;
  }
  for (int a = 0; a < s->naxes; a++) /* does any axis change what the checks read? */
    geometric |= !strncmp(s->axis[a].key, "geometry.", 9) || !strncmp(s->axis[a].key, "shape.", 6);
  long fails = 0, k;
  for (k = 0; k < s->ncells && fails == k; k++) { /* until one cell passes */
    char(*sets)[VES_STUDY_SETLEN] = malloc(VES_STUDY_CELL_SETS * sizeof *sets);
    const char *ptr[VES_STUDY_CELL_SETS];
    int n = 0, m, pass;
    ves_config cfg;
    if (!sets || ves_study_cell_sets(s, k, sets, &n, NULL, 0) != VES_OK) {
      free(sets);
      break;
    }
    for (int i = 0; i < n; i++) ptr[i] = sets[i];
    ves_status st = ves_config_load(s->problem, n, ptr, &cfg, NULL, 0);
    free(sets);
    if (st != VES_OK) break;
    geometry_key(&cfg, cur, sizeof cur);
    for (m = 0; m < nmemo && strcmp(key[m], cur); m++) {
    }
    if (m < nmemo) {
      pass = ok[m];
    } else {
      pass = geometry_check(&cfg, msg, sizeof msg) == VES_OK;
      if (!first[0] && !pass) snprintf(first, sizeof first, "%s", msg);
      if (nmemo < MEMO) snprintf(key[nmemo], sizeof key[nmemo], "%s", cur), ok[nmemo++] = pass;
    }
    fails += !pass;
    if (!geometric) break; /* one geometry for every cell */
  }
  free(key), free(ok);
  if (fails && (fails == s->ncells || !geometric)) {
    char name[PATH_MAX / 2];
    ves_study_cell_name(s, 0, name, sizeof name);
    ves_error_say(err, errlen, "%s: %s: %s (vesica check refuses %s; no cell is run)", s->path,
                  s->problem, first,
                  geometric ? "every cell's problem" : "the problem with the study's overrides");
    return VES_ERR_CONFIG;
  }
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
        ves_error_say(err, errlen, "%s: [axes]: two cells are both named '%s'", s->path, names[k]);
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
static const char *const SLURM_KEYS[] = {"partition",     "account",  "mem",
                                         "cpus_per_task", "throttle", "setup"};

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

/* A key of [study]; problem[PATH_MAX] gets the base problem as written. */
static ves_status study_key_study(ves_study *s, const char *key, const char *val, char *problem,
                                  char *err, size_t errlen) {
  double num;
  ves_status st = VES_OK;
  if (!in_list(key, STUDY_KEYS, 4)) {
    ves_error_say(err, errlen, "%s: [study] %s: unknown key (problem, run, steps, time_limit)",
                  s->path, key);
    st = VES_ERR_CONFIG;
  } else if (!strcasecmp(key, "problem")) {
    if (!*val || strlen(val) >= PATH_MAX) {
      ves_error_say(err, errlen, "%s: [study] problem: empty or too long", s->path);
      st = VES_ERR_CONFIG;
    } else
      snprintf(problem, PATH_MAX, "%s", val);
  } else if (!strcasecmp(key, "run")) {
    if (!strcasecmp(val, "step"))
      s->mode = VES_STUDY_STEP;
    else if (!strcasecmp(val, "steps"))
      s->mode = VES_STUDY_STEPS;
    else if (!strcasecmp(val, "t_end"))
      s->mode = VES_STUDY_T_END;
    else {
      ves_error_say(err, errlen, "%s: [study] run = '%s': not one of step, steps, t_end", s->path,
                    val);
      st = VES_ERR_CONFIG;
    }
  } else if (!strcasecmp(key, "steps")) {
    if ((st = study_number(s, "study", key, val, 1, 1e9, 1, &num, err, errlen)) == VES_OK)
      s->steps = (long)num;
  } else if ((st = study_number(s, "study", key, val, 0, 1e9, 0, &num, err, errlen)) == VES_OK) {
    s->time_limit = num;
  }
  return st;
}

/* A key of [slurm]. */
static ves_status study_key_slurm(ves_study *s, const char *key, const char *val, char *err,
                                  size_t errlen) {
  double num;
  ves_status st = VES_OK;
  if (!in_list(key, SLURM_KEYS, 6)) {
    ves_error_say(err, errlen,
                  "%s: [slurm] %s: unknown key (partition, account, mem, cpus_per_task, throttle, "
                  "setup)",
                  s->path, key);
    st = VES_ERR_CONFIG;
  } else if (!strcasecmp(key, "cpus_per_task")) {
    if ((st = study_number(s, "slurm", key, val, 1, 1024, 1, &num, err, errlen)) == VES_OK)
      s->cpus_per_task = (int)num;
  } else if (!strcasecmp(key, "throttle")) {
    if ((st = study_number(s, "slurm", key, val, 1, 1e9, 1, &num, err, errlen)) == VES_OK)
      s->throttle = (long)num;
  } else if (!strcasecmp(key, "setup")) {
    /* shell text run by the job: any printable text on one line; a control
     * byte (a NUL, a newline or carriage return that would start another
     * line of the script) is refused */
    int bad = !*val || strlen(val) >= sizeof s->setup;
    for (const unsigned char *c = (const unsigned char *)val; *c && !bad; c++)
      bad = *c < 0x20 || *c == 0x7f;
    if (bad) {
      ves_error_say(err, errlen,
                    "%s: [slurm] setup: empty, longer than %zu characters, or holding a control "
                    "character (one line of shell commands, e.g. module load hdf5)",
                    s->path, sizeof s->setup - 1);
      st = VES_ERR_CONFIG;
    } else
      snprintf(s->setup, sizeof s->setup, "%s", val);
  } else {
    char *dst = !strcasecmp(key, "partition") ? s->partition
                : !strcasecmp(key, "account") ? s->account
                                              : s->mem;
    size_t cap = !strcasecmp(key, "mem") ? sizeof s->mem : sizeof s->partition;
    int bad = strlen(val) >= cap || (dst == s->mem && !*val); /* mem: never empty */
    for (const char *c = val; *c && !bad; c++)                /* goes into a shell script */
      bad = !(isalnum((unsigned char)*c) || strchr("._-,", *c));
    if (bad) {
      ves_error_say(err, errlen,
                    "%s: [slurm] %s = '%s': only letters, digits and . _ - , (at most %zu)",
                    s->path, key, val, cap - 1);
      st = VES_ERR_CONFIG;
    } else
      snprintf(dst, cap, "%s", val);
  }
  return st;
}

/* A key of [set] or [axes] (sec): a problem key, fixed or swept. */
static ves_status study_key_problem(ves_study *s, const char *sec, const char *key, const char *val,
                                    char *err, size_t errlen) {
  char canon[64];
  const int axes = !strcasecmp(sec, "axes");
  ves_status st = VES_OK;
  if (canonical_key(key, canon, sizeof canon)) {
    ves_error_say(err, errlen, "%s: [%s] %s: unknown problem key (see vesica keys)", s->path, sec,
                  key);
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
  return st;
}

/* After the sections: the base problem (as written, relative to the study
 * file's folder) resolved, at least one axis, no axis fixed in [set] or
 * given twice. */
static ves_status study_check(ves_study *s, const char *problem, char *err, size_t errlen) {
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

/* The state of reading a study file: the study and its base problem as
 * written. */
typedef struct {
  ves_study *s;
  char problem[PATH_MAX];
} study_reader;

/* A section or key of the study file (ves_ini_scan has refused a repeated
 * one), read and checked in place, in the file's order. */
static ves_status study_item(void *ctx, const char *name, int line, const char *sec,
                             const char *key, const char *v, size_t vn, char *err, size_t errlen) {
  study_reader *r = ctx;
  if (!key) {
    if (!strcmp(sec, "study") || !strcmp(sec, "set") || !strcmp(sec, "axes") ||
        !strcmp(sec, "slurm"))
      return VES_OK;
    ves_error_say(err, errlen, "%s: line %d: [%s]: unknown section (study, set, axes, slurm)", name,
                  line, sec);
    return VES_ERR_CONFIG;
  }
  char *val = malloc(vn + 1);
  if (!val) return VES_ERR_ALLOC;
  memcpy(val, v, vn);
  val[vn] = 0;
  ves_status st;
  if (!strcmp(sec, "study"))
    st = study_key_study(r->s, key, val, r->problem, err, errlen);
  else if (!strcmp(sec, "slurm"))
    st = study_key_slurm(r->s, key, val, err, errlen);
  else
    st = study_key_problem(r->s, sec, key, val, err, errlen);
  free(val);
  return st;
}

/* Two values of one axis that give the same problem (1 and 1.0, 1e-3 and
 * 0.001, newton and Newton: one case run twice) are refused: every value's
 * cell with the other axes at their first value, compared as problem text
 * (ves_config_to_text: the parsed values, not their spelling), without
 * regard to case as the choices of a key are read (two points files whose
 * names differ only in case count as one too). */
static ves_status check_axis_values(const ves_study *s, char *err, size_t errlen) {
  char(*sets)[VES_STUDY_SETLEN] = malloc(VES_STUDY_CELL_SETS * sizeof *sets);
  char **text = calloc(VES_STUDY_MAX_VALUES, sizeof *text);
  ves_status st = sets && text ? VES_OK : VES_ERR_ALLOC;
  long stride = 1;
  for (int a = s->naxes - 1; a >= 0 && st == VES_OK; a--) {
    for (int i = 0; i < s->axis[a].nvalues && st == VES_OK; i++) {
      const char *ptr[VES_STUDY_CELL_SETS];
      int n = 0;
      ves_config cfg;
      if ((st = ves_study_cell_sets(s, i * stride, sets, &n, NULL, 0)) != VES_OK) break;
      for (int j = 0; j < n; j++) ptr[j] = sets[j];
      if ((st = ves_config_load(s->problem, n, ptr, &cfg, NULL, 0)) != VES_OK ||
          (st = ves_config_to_text(&cfg, &text[i])) != VES_OK)
        break;
      for (int j = 0; j < i; j++)
        if (!strcasecmp(text[j], text[i])) {
          ves_error_say(err, errlen,
                        "%s: [axes] %s: values '%s' and '%s' are the same value (one case run "
                        "twice)",
                        s->path, s->axis[a].key, s->axis[a].values[j], s->axis[a].values[i]);
          st = VES_ERR_CONFIG;
          break;
        }
    }
    for (int i = 0; i < VES_STUDY_MAX_VALUES; i++) free(text[i]), text[i] = NULL;
    stride *= s->axis[a].nvalues;
  }
  free(text), free(sets);
  return st;
}

/* The command line's overrides into s->cli: "section.key=value" with a
 * problem key that no axis sweeps (the values are checked with every
 * cell's problem). */
static ves_status study_cli_sets(ves_study *s, int nset, const char *const *set, char *err,
                                 size_t errlen) {
  if (nset > VES_STUDY_MAX_SET) {
    ves_error_say(err, errlen, "--set: more than %d overrides", VES_STUDY_MAX_SET);
    return VES_ERR_CONFIG;
  }
  for (int i = 0; i < nset; i++) {
    const char *eq = strchr(set[i], '=');
    char key[64], canon[64], val[VES_STUDY_SETLEN];
    if (!eq || trim_copy(key, sizeof key, set[i], (size_t)(eq - set[i])) ||
        trim_copy(val, sizeof val, eq + 1, strlen(eq + 1)) || !*val) {
      ves_error_say(err, errlen, "--set %s: expected section.key=value", set[i]);
      return VES_ERR_CONFIG;
    }
    if (canonical_key(key, canon, sizeof canon)) {
      ves_error_say(err, errlen, "--set: %s: unknown key (see vesica keys)", key);
      return VES_ERR_CONFIG;
    }
    for (int a = 0; a < s->naxes; a++)
      if (!strcmp(s->axis[a].key, canon)) {
        ves_error_say(err, errlen, "--set %s: %s is an axis of %s (its values are the cells')",
                      set[i], canon, s->path);
        return VES_ERR_CONFIG;
      }
    for (int j = 0; j < s->ncli; j++)
      if (!strncmp(s->cli[j], canon, strlen(canon)) && s->cli[j][strlen(canon)] == '=') {
        ves_error_say(err, errlen, "--set %s: %s given twice", set[i], canon);
        return VES_ERR_CONFIG;
      }
    if (strlen(val) > 127) {
      ves_error_say(err, errlen, "--set %s: a value longer than 127 characters", set[i]);
      return VES_ERR_CONFIG;
    }
    snprintf(s->cli[s->ncli++], VES_STUDY_SETLEN, "%.63s=%.127s", canon, val);
  }
  return VES_OK;
}

ves_status ves_study_load(const char *path, long max_cells, ves_study **out, char *err,
                          size_t errlen) {
  return ves_study_load_set(path, max_cells, 0, NULL, out, err, errlen);
}

ves_status ves_study_load_set(const char *path, long max_cells, int nset, const char *const *set,
                              ves_study **out, char *err, size_t errlen) {
  VES_CHECK(path && out && (nset == 0 || set), VES_ERR_ARG);
  *out = NULL;
  ves_study *s = calloc(1, sizeof *s);
  if (!s) return VES_ERR_ALLOC;
  snprintf(s->path, sizeof s->path, "%s", path);
  s->mode = VES_STUDY_T_END, s->steps = 1, s->time_limit = 3600;
  snprintf(s->mem, sizeof s->mem, "4G");
  s->cpus_per_task = 1;
  study_reader r = {.s = s, .problem = ""};
  ves_status st = ves_ini_load(path, path, "study file", study_item, &r, err, errlen);
  if (st == VES_OK) st = study_check(s, r.problem, err, errlen);
  if (st == VES_OK) st = study_cli_sets(s, nset, set, err, errlen);
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
  if (st == VES_OK) st = check_axis_values(s, err, errlen);
  if (st == VES_OK) st = check_geometry(s, err, errlen);
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
      {"slurm", "mem", "text", "4G", "letters, digits, . _ - , (not empty)",
       "--emit slurm: #SBATCH --mem"},
      {"slurm", "cpus_per_task", "integer", "1", "1 to 1024",
       "--emit slurm: #SBATCH --cpus-per-task, the cell's OMP_NUM_THREADS"},
      {"slurm", "throttle", "integer", "(none)", "1 to 1e9",
       "--emit slurm: at most N array tasks at a time, #SBATCH --array=...%N (--throttle N "
       "overrides it)"},
      {"slurm", "setup", "text", "(none)", "one line, no control characters",
       "--emit slurm: shell commands each task runs before its cell, placed verbatim in the "
       "script (e.g. `module load hdf5`)"},
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
