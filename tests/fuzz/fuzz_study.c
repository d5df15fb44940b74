/* vesica — libFuzzer target: the study-file parser (ves_study_load on a
 * file holding the input, its base problem present) and the Slurm script's
 * quoting (the input as a name). Built and run by `make fuzz` with
 * AddressSanitizer + UBSan; a crash, a sanitizer report or a broken
 * contract aborts. The contract of an accepted study: at least one axis,
 * every axis with 1 to VES_STUDY_MAX_VALUES distinct non-empty values, the
 * cell count the product of the axes' sizes and within the limit, every
 * cell's name distinct, at most 200 characters of letters, digits,
 * . + - _ = , and %XX escapes (two upper-case hex digits), its command and
 * signature built; its Slurm script written, one
 * line per option (a value of the study file cannot add a line). A refused
 * input: a status < 0 and a one-line message naming the file. The quoting:
 * the input as a bash word (sh_word) stays on one line and reads back (by
 * bash's rules for '...' and $'...') as the input up to its first NUL.
 * study_output.c is compiled in for its static sh_word. The geometric
 * checks of a study's cells (ves_setup_check_geometry through the problem's
 * shape) build shapes from the setup's code, which this target does not
 * link: they are stubbed to pass here (fuzz_points covers the shape input,
 * tests/test_study_script.c the checks). */
#include "../../solver/app/study_output.c"

#include "app/problem.h"
#include "ves/setup.h"

#include <stdint.h>
#include <stdio.h>

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define FUZZ_MAX_CELLS 64 /* larger grids are refused: each cell's problem is loaded */

static char root[64], study_path[128], out_dir[128];

ves_status ves_problem_shape(const ves_config *c, ves_shape **out, char *err, size_t errlen) {
  (void)c, (void)err, (void)errlen;
  *out = NULL;
  return VES_OK;
}
ves_status ves_problem_discret(const ves_config *c, ves_discret_params *d, char *err,
                               size_t errlen) {
  (void)c, (void)err, (void)errlen;
  memset(d, 0, sizeof *d);
  return VES_OK;
}
ves_status ves_setup_check_geometry(const ves_discret_params *d, const ves_shape *shape, char *err,
                                    size_t errlen) {
  (void)d, (void)shape, (void)err, (void)errlen;
  return VES_OK;
}
void ves_shape_destroy(ves_shape **s) {
  if (s) *s = NULL;
}

static void die(const char *what, const char *detail) {
  fprintf(stderr, "fuzz_study: contract broken: %s: %s\n", what, detail);
  abort();
}

static void write_text(const char *path, const char *text) {
  FILE *f = fopen(path, "w");
  if (!f || fputs(text, f) < 0 || fclose(f) != 0) die("cannot write", path);
}

/* A folder with the base problems the seeds name: base.ini and, for the
 * seeds of problems/studies/, ../oblate.ini (the defaults: an empty
 * section). The study file goes into root/studies/. */
int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc, (void)argv;
  char path[160];
  snprintf(root, sizeof root, "/tmp/vesica_fuzz_study_%d", (int)getpid());
  snprintf(path, sizeof path, "%s/studies", root);
  if ((mkdir(root, 0777) && errno != EEXIST) || (mkdir(path, 0777) && errno != EEXIST))
    die("cannot create", path);
  snprintf(path, sizeof path, "%s/oblate.ini", root);
  write_text(path, "[geometry]\n");
  snprintf(path, sizeof path, "%s/studies/base.ini", root);
  write_text(path, "[geometry]\n");
  snprintf(study_path, sizeof study_path, "%s/studies/s.ini", root);
  snprintf(out_dir, sizeof out_dir, "%s/out", root);
  return 0;
}

/* The word w as bash reads it back: '...' pieces verbatim ('\'' joins
 * them), $'...' with \\, \' and \xHH; NULL when w is not of that form. */
static char *unquote(const char *w) {
  char *out = malloc(strlen(w) + 1);
  size_t o = 0;
  while (out && *w) {
    if (w[0] == '\'') {
      const char *end = strchr(w + 1, '\'');
      if (!end) break;
      memcpy(out + o, w + 1, (size_t)(end - w - 1));
      o += (size_t)(end - w - 1), w = end + 1;
    } else if (w[0] == '\\' && w[1] == '\'') {
      out[o++] = '\'', w += 2;
    } else if (w[0] == '$' && w[1] == '\'') {
      for (w += 2; *w && *w != '\'';) {
        unsigned x;
        if (w[0] != '\\')
          out[o++] = *w++;
        else if ((w[1] == '\\' || w[1] == '\'') && w[1])
          out[o++] = w[1], w += 2;
        else if (w[1] == 'x' && sscanf(w + 2, "%2x", &x) == 1 && isxdigit((unsigned char)w[3]))
          out[o++] = (char)x, w += 4;
        else
          break;
      }
      if (*w != '\'') break;
      w++;
    } else {
      break;
    }
  }
  if (!out || *w) {
    free(out);
    return NULL;
  }
  out[o] = 0;
  return out;
}

/* sh_word on the input (up to its first NUL): one line that reads back. */
static void check_quoting(const uint8_t *data, size_t size) {
  char *name = malloc(size + 1);
  if (!name) return;
  memcpy(name, data, size);
  name[size] = 0;
  char *buf = NULL;
  size_t len = 0;
  FILE *f = open_memstream(&buf, &len);
  if (!f) die("open_memstream", "");
  sh_word(f, name);
  fclose(f);
  if (memchr(buf, '\n', len) || memchr(buf, '\r', len)) die("a quoted word spans lines", buf);
  for (size_t i = 0; i < len; i++)
    if ((unsigned char)buf[i] < 0x20 || buf[i] == 0x7f) die("a control byte in a word", buf);
  char *back = unquote(buf);
  if (!back || strcmp(back, name)) die("the word does not read back", buf);
  free(back), free(buf), free(name);
}

/* The whole contract of an accepted study. */
static void check_accepted(const ves_study *s) {
  char name[PATH_MAX / 2], err[1024] = "";
  long cells = 1;
  if (s->naxes < 1 || s->naxes > VES_STUDY_MAX_AXES) die("axes", s->path);
  for (int a = 0; a < s->naxes; a++) {
    const ves_study_axis *ax = &s->axis[a];
    if (ax->nvalues < 1 || ax->nvalues > VES_STUDY_MAX_VALUES) die("values of an axis", ax->key);
    for (int i = 0; i < ax->nvalues; i++) {
      if (!ax->values[i][0] || strnlen(ax->values[i], VES_STUDY_VALUE) >= VES_STUDY_VALUE)
        die("an empty or unterminated value", ax->key);
      for (int j = 0; j < i; j++)
        if (!strcmp(ax->values[i], ax->values[j])) die("a value given twice", ax->values[i]);
    }
    cells *= ax->nvalues;
  }
  if (cells != s->ncells || cells < 1 || cells > FUZZ_MAX_CELLS) die("cell count", s->path);
  char **names = calloc((size_t)cells, sizeof *names);
  if (!names) return;
  for (long k = 0; k < cells; k++) {
    ves_study_cell_name(s, k, name, sizeof name);
    if (!name[0] || strlen(name) > 200) die("cell name length", name);
    for (const char *c = name; *c; c++)
      if (*c == '%') {
        if (!strchr("0123456789ABCDEF", c[1]) || !c[1] || !strchr("0123456789ABCDEF", c[2]) ||
            !c[2])
          die("cell name escape", name);
      } else if (!isalnum((unsigned char)*c) && !strchr(".+-_=,", *c))
        die("cell name character", name);
    for (long j = 0; j < k; j++)
      if (!strcmp(names[j], name)) die("two cells of one name", name);
    names[k] = strdup(name);
    int argc = 0;
    char **argv = NULL;
    if (ves_study_cell_argv(s, k, "vesica", out_dir, &argc, &argv, err, sizeof err) != VES_OK)
      die("cell command", err);
    free(argv);
    char sig[sizeof((ves_study_result *)0)->signature];
    if (ves_study_cell_signature(s, k, sig, sizeof sig) != VES_OK) die("cell signature", name);
  }
  for (long k = 0; k < cells; k++) free(names[k]);
  free(names);
  /* the Slurm script: its lines are the ones vesica writes, whatever [slurm] holds */
  long ntasks = 0;
  ves_status st = ves_study_write_sbatch(s, "/bin/vesica", out_dir, 0, &ntasks, err, sizeof err);
  if (st == VES_ERR_CONFIG) { /* a [slurm] value sbatch cannot carry */
    if (!err[0] || strchr(err, '\n')) die("sbatch refusal message", err);
    return;
  }
  if (st != VES_OK || ntasks != cells) die("sbatch", err);
  char path[PATH_MAX], line[4096];
  snprintf(path, sizeof path, "%s/study.sbatch", out_dir);
  FILE *f = fopen(path, "r");
  if (!f) die("no script", path);
  int lines = 0, want = 13 + (s->time_limit > 0) + !!s->partition[0] + !!s->account[0];
  while (fgets(line, sizeof line, f)) lines++;
  fclose(f);
  if (lines != want) die("the script's lines", s->path);
  remove(path);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  check_quoting(data, size);
  FILE *f = fopen(study_path, "wb");
  if (!f) return 0;
  fwrite(data, 1, size, f);
  fclose(f);
  ves_study *s = NULL;
  char err[1024] = "";
  ves_status st = ves_study_load(study_path, FUZZ_MAX_CELLS, &s, err, sizeof err);
  if (st == VES_OK) {
    if (!s) die("accepted without a study", study_path);
    check_accepted(s);
  } else {
    if (st >= 0 || s) die("status of a refusal", ves_status_str(st));
    if (!err[0] || strchr(err, '\n') || !strstr(err, study_path)) die("refusal message", err);
  }
  ves_study_destroy(&s);
  return 0;
}
