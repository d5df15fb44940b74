/* vesica — what a study writes and reads besides running its cells: the
 * .result files (how each cell ended) and the classification of an ended
 * cell, the table DIR/study.csv collected from them and the cells' .h5
 * files, its figures, and the Slurm job-array script. No process is started
 * here. User-facing behaviour: docs/manual.md; docs/design.md, "The program". */
#include "app/study.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/io.h"
#include "app/plot.h"

/* One step "raised E*" above this relative rounding (vesica info's
 * energy_monotone uses the same margin). */
#define STUDY_RISE_TOL 1e-10

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

/* The label of axis key on a figure: the key with its unit (lengths in R0,
 * times in t*, widths in eps, C0 in 1/R0), as the key table gives them. */
static void axis_label(const char *key, char *buf, size_t len) {
  static const char *const unit[][2] = {{"time.t_end", "t*"},
                                        {"time.dt_initial", "t*"},
                                        {"time.dt_max", "t*"},
                                        {"time.dt_min", "t*"},
                                        {"geometry.epsilon", "R0"},
                                        {"geometry.box_r", "R0"},
                                        {"geometry.box_z", "R0"},
                                        {"geometry.h_far", "R0"},
                                        {"geometry.band", "eps"},
                                        {"geometry.h_band", "eps"},
                                        {"shape.radius", "R0"},
                                        {"material.c0", "1/R0"},
                                        {"shape.reduced_volume", "dimensionless"}};
  char e[128];
  ves_plot_gp_escape(e, sizeof e, key);
  for (size_t i = 0; i < sizeof unit / sizeof unit[0]; i++)
    if (!strcmp(key, unit[i][0])) {
      snprintf(buf, len, "%s (%s)", e, unit[i][1]);
      return;
    }
  snprintf(buf, len, "%s", e);
}

/* Whether every value of axis a reads as a finite number (*lo, *hi: the
 * smallest and largest). */
static int axis_numeric(const ves_study_axis *ax, double *lo, double *hi) {
  *lo = INFINITY, *hi = -INFINITY;
  for (int i = 0; i < ax->nvalues; i++) {
    char *end;
    const double v = strtod(ax->values[i], &end);
    if (end == ax->values[i] || *end || !isfinite(v)) return 0;
    *lo = fmin(*lo, v), *hi = fmax(*hi, v);
  }
  return 1;
}

/* The figure of any sweep, DIR/study_sweep.png: E*_final, accepted steps
 * and wall seconds of every done cell against the first numeric axis (or
 * the first axis, as categories named on the x axis), one curve per value
 * of the other axes; log x when the values span more than a decade; the
 * cells that did not converge crossed in red (at the bottom of a panel when
 * the value is unknown). Its gnuplot script into f. */
static void sweep_script(FILE *f, const ves_study *s, const char *dir, const char *title) {
  int xa = -1;
  double lo = 0, hi = 0;
  for (int a = 0; a < s->naxes && xa < 0; a++)
    if (axis_numeric(&s->axis[a], &lo, &hi)) xa = a;
  const int numeric = xa >= 0;
  if (!numeric) xa = 0;
  const ves_study_axis *ax = &s->axis[xa];
  const long G = s->ncells / ax->nvalues; /* curves: the other axes' values */
  int order[VES_STUDY_MAX_VALUES];        /* the axis's values in increasing order */
  for (int i = 0; i < ax->nvalues; i++) order[i] = i;
  for (int i = 1; i < ax->nvalues && numeric; i++)
    for (int j = i;
         j > 0 && strtod(ax->values[order[j]], NULL) < strtod(ax->values[order[j - 1]], NULL);
         j--) {
      const int t = order[j];
      order[j] = order[j - 1], order[j - 1] = t;
    }
  long stride = 1; /* cell k of group g and value i: mixed radix, xa's digit */
  for (int a = s->naxes - 1; a > xa; a--) stride *= s->axis[a].nvalues;
  typedef struct {
    long g;
    double x, v[3];
    int conv;
  } point;
  point *pt = malloc((size_t)s->ncells * sizeof *pt);
  long np = 0;
  double ymin[3] = {INFINITY, INFINITY, INFINITY}, ymax[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (long g = 0; g < G && pt; g++) {
    const long hi_part = g / stride, lo_part = g % stride;
    for (int i = 0; i < ax->nvalues; i++) {
      const long k = (hi_part * ax->nvalues + order[i]) * stride + lo_part;
      cell_row r;
      if (!read_row(s, k, dir, &r)) continue;
      point *q = &pt[np++];
      q->g = g, q->conv = !strcmp(r.status, "converged");
      /* categories: the groups' points side by side around their category */
      q->x = numeric ? strtod(ax->values[order[i]], NULL)
                     : order[i] + (G > 1 ? 0.3 * ((double)g / (double)(G - 1) - 0.5) : 0.0);
      q->v[0] = r.have && r.steps ? r.E1 : NAN, q->v[1] = r.have ? (double)r.steps : NAN;
      q->v[2] = r.res.wall_seconds;
      for (int m = 0; m < 3; m++)
        if (isfinite(q->v[m])) ymin[m] = fmin(ymin[m], q->v[m]), ymax[m] = fmax(ymax[m], q->v[m]);
    }
  }
  /* $s: group, x, E*, steps, wall (a blank line between groups); $x: the
   * cells that did not converge, an unknown value below the panel's known
   * ones (by a tenth of their range) */
  fprintf(f, "$s << EOD\n");
  for (long i = 0; i < np; i++) {
    if (i && pt[i].g != pt[i - 1].g) fputc('\n', f);
    fprintf(f, "%ld %.12g", pt[i].g, pt[i].x);
    for (int m = 0; m < 3; m++)
      isfinite(pt[i].v[m]) ? fprintf(f, " %.12g", pt[i].v[m]) : fprintf(f, " NaN");
    fputc('\n', f);
  }
  fprintf(f, "NaN NaN NaN NaN NaN\nEOD\n$x << EOD\n");
  long nfailed = 0;
  for (long i = 0; i < np; i++) {
    if (pt[i].conv) continue;
    nfailed++;
    fprintf(f, "%ld %.12g", pt[i].g, pt[i].x);
    for (int m = 0; m < 3; m++) {
      const double span = isfinite(ymin[m]) && ymax[m] > ymin[m] ? ymax[m] - ymin[m] : 1.0;
      fprintf(f, " %.12g",
              isfinite(pt[i].v[m]) ? pt[i].v[m]
              : isfinite(ymin[m])  ? ymin[m] - 0.1 * span
                                   : 0.0);
    }
    fputc('\n', f);
  }
  fprintf(f, "NaN NaN NaN NaN NaN\nEOD\n");
  free(pt);
  char path[PATH_MAX + 32], xl[256];
  snprintf(path, sizeof path, "%s/study_sweep.png", dir);
  axis_label(ax->key, xl, sizeof xl);
  fprintf(f, "set terminal pngcairo size 1000,1100 font ',10'\nset output ");
  ves_plot_gp_quote(f, path);
  fprintf(f, "\nset grid\nset key outside right top\nset offsets graph 0.04, graph 0.04, "
             "graph 0.08, graph 0.08\n");
  if (numeric && lo > 0 && hi / lo > 10) fprintf(f, "set logscale x\nset format x '10^{%%L}'\n");
  if (!numeric) {
    fprintf(f, "set xrange [-0.5:%d.5]\nset xtics (", ax->nvalues - 1);
    for (int i = 0; i < ax->nvalues; i++) {
      char e[128];
      ves_plot_gp_escape(e, sizeof e, ax->values[i]);
      fprintf(f, "%s", i ? ", " : "");
      ves_plot_gp_quote(f, e);
      fprintf(f, " %d", i);
    }
    fprintf(f, ")\n");
  }
  fprintf(f, "set multiplot layout 3,1 title ");
  char t[PATH_MAX + 512];
  snprintf(t, sizeof t,
           "%.2000s: every done cell against %s (red x: not converged; below the others "
           "when it has no value)",
           title, xl);
  ves_plot_gp_quote(f, t);
  fprintf(f, "\n");
  static const char *const ylab[3] = {"E*_{final} (units of k)", "accepted steps",
                                      "wall time of the cell (s)"};
  for (int m = 0; m < 3; m++) {
    fprintf(f, "set ylabel '%s'\nset xlabel ", ylab[m]);
    ves_plot_gp_quote(f, m == 2 ? xl : "");
    fprintf(f, "\nplot ");
    for (long g = 0; g < G; g++) {
      char label[256] = "";
      size_t at = 0;
      int idx[VES_STUDY_MAX_AXES];
      ves_study_cell_index(s, (g / stride) * ax->nvalues * stride + g % stride, idx);
      for (int a = 0; a < s->naxes; a++) {
        if (a == xa) continue;
        char e[128];
        ves_plot_gp_escape(e, sizeof e, s->axis[a].values[idx[a]]);
        const char *dot = strchr(s->axis[a].key, '.');
        at += (size_t)snprintf(label + at, sizeof label - at, "%s%s=%s", at ? ", " : "",
                               dot ? dot + 1 : s->axis[a].key, e);
        if (at >= sizeof label) at = sizeof label - 1;
      }
      if (!label[0]) snprintf(label, sizeof label, "cells");
      fprintf(f, "%s$s u ($1 == %ld ? $2 : NaN):%d w %s pt 7 ps 1.2 t ", g ? ", \\\n  " : "", g,
              3 + m, numeric ? "lp" : "p");
      ves_plot_gp_quote(f, label);
    }
    if (nfailed)
      fprintf(f, ", \\\n  $x u 2:%d w p pt 2 ps 2.5 lw 2 lc rgb '#d73027' t 'not converged'",
              3 + m);
    fputc('\n', f);
  }
  fprintf(f, "unset multiplot\n");
}

ves_status ves_study_plot(const ves_study *s, const char *dir, char *err, size_t errlen) {
  VES_CHECK(s && dir, VES_ERR_ARG);
  int ad = -1;
  for (int a = 0; a < s->naxes; a++)
    if (!strcmp(s->axis[a].key, "time.dt_initial")) ad = a;
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
  char title[PATH_MAX + 64], path[PATH_MAX];
  const char *base = strrchr(s->path, '/') ? strrchr(s->path, '/') + 1 : s->path;
  ves_plot_gp_escape(title, sizeof title, base);
  sweep_script(f, s, dir, title);
  if (ad >= 0) { /* the robustness frontier and the cost against dt */
    const long G = s->ncells / s->axis[ad].nvalues; /* groups: the other axes' values */
    double *front = malloc((size_t)G * sizeof *front);
    char(*label)[256] = malloc((size_t)G * sizeof *label);
    if (!front || !label) {
      fclose(f), unlink(script), free(front), free(label);
      return VES_ERR_ALLOC;
    }
    frontier_data(f, s, dir, ad, G, front, label);
    fprintf(f, "NaN NaN NaN NaN\nEOD\n$front << EOD\n");
    for (long g = 0; g < G; g++) fprintf(f, "%ld %.9g\n", g, front[g]);
    fprintf(f, "EOD\nreset\n");
    fprintf(f,
            "set terminal pngcairo size 900,%ld font ',10'\nset logscale x\nset format x "
            "'10^{%%L}'\n",
            480 + 24 * (G > 8 ? G - 8 : 0));
    fprintf(f, "set grid\nset key outside right top\nset offsets graph 0.04, graph 0.04\n");
    snprintf(path, sizeof path, "%s/study_frontier.png", dir);
    fputs("set output ", f), ves_plot_gp_quote(f, path), fputc('\n', f);
    fprintf(f, "set title 'robustness frontier: %s (circled: the largest converged dt*)'\n", title);
    fprintf(f, "set xlabel 'dt* (t*)'\nset ylabel ''\nset yrange [-0.5:%ld.5]\nset ytics (", G - 1);
    for (long g = 0; g < G; g++) {
      fprintf(f, "%s", g ? ", " : "");
      ves_plot_gp_quote(f, label[g]);
      fprintf(f, " %ld", g);
    }
    fprintf(f, ")\nplot $d u 2:($3 == 1 ? $1 : NaN) w p pt 7 ps 1.5 lc rgb '#1a9850' "
               "t 'converged', \\\n  $d u 2:($3 == 0 ? $1 : NaN) w p pt 2 ps 1.5 lc rgb "
               "'#d73027' t 'not converged', \\\n  $front u 2:1 w p pt 6 ps 3 lc rgb 'black' "
               "t 'largest'\n");
    snprintf(path, sizeof path, "%s/study_cost.png", dir);
    fputs("set output ", f), ves_plot_gp_quote(f, path), fputc('\n', f);
    fprintf(f,
            "set title 'cost: %s (converged cells)'\nset ytics auto\nset autoscale y\n"
            "set logscale y\nset ylabel 'seconds per step (s)'\nplot ",
            title);
    for (long g = 0; g < G; g++) {
      fprintf(f, "%s$d u ($1 == %ld ? $2 : NaN):4 w lp pt 7 t ", g ? ", \\\n  " : "", g);
      ves_plot_gp_quote(f, label[g]);
    }
    fputc('\n', f);
    free(front), free(label);
  }
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

/* The length of the UTF-8 sequence at p (1 to 4), or 0 when it is not one
 * (a stray continuation byte, an overlong form, a surrogate, past U+10FFFF). */
static int utf8_len(const unsigned char *p) {
  if (p[0] < 0x80) return 1;
  int n = p[0] >= 0xc2 && p[0] <= 0xdf   ? 2
          : p[0] >= 0xe0 && p[0] <= 0xef ? 3
          : p[0] >= 0xf0 && p[0] <= 0xf4 ? 4
                                         : 0;
  for (int i = 1; i < n; i++)
    if ((p[i] & 0xc0) != 0x80) return 0;
  if ((p[0] == 0xe0 && p[1] < 0xa0) || (p[0] == 0xed && p[1] > 0x9f) ||
      (p[0] == 0xf0 && p[1] < 0x90) || (p[0] == 0xf4 && p[1] > 0x8f))
    return 0;
  return n;
}

/* Whether s holds only printable characters (no control byte) in valid UTF-8. */
static int plain_text(const char *s) {
  for (const unsigned char *p = (const unsigned char *)s; *p;) {
    int n = utf8_len(p);
    if (!n || *p < 0x20 || *p == 0x7f) return 0;
    p += n;
  }
  return 1;
}

/* s as one bash word on one line: '...' ('\'' for a quote) when s is plain
 * text, else $'...' with \xHH for every control byte and every byte of an
 * invalid UTF-8 sequence: a newline in a name can end neither a comment nor
 * a command, and nothing in it is expanded. */
static void sh_word(FILE *f, const char *s) {
  if (plain_text(s)) {
    fputc('\'', f);
    for (; *s; s++)
      if (*s == '\'')
        fputs("'\\''", f);
      else
        fputc(*s, f);
    fputc('\'', f);
    return;
  }
  fputs("$'", f);
  for (const unsigned char *p = (const unsigned char *)s; *p;) {
    int n = utf8_len(p);
    if (*p == '\\' || *p == '\'') {
      fprintf(f, "\\%c", *p++);
    } else if (n == 0 || *p < 0x20 || *p == 0x7f) {
      fprintf(f, "\\x%02x", *p++);
    } else {
      fwrite(p, 1, (size_t)n, f);
      p += n;
    }
  }
  fputc('\'', f);
}

/* Why v cannot be a value of an #SBATCH line in double quotes, or NULL when
 * it can. sbatch reads those lines itself, not through a shell: a newline
 * ends the line, '\\' and '"' are its own escape and quote inside the
 * quotes, and a line naming packjob or hetjob starts another component of a
 * heterogeneous job (sbatch's opt.c, _get_argument and
 * _opt_batch_script); a control character or a byte that is not UTF-8 has
 * no place in a job's options. */
static const char *sbatch_unsafe(const char *v) {
  if (!plain_text(v)) return "a control character (newline, tab, ...) or a byte that is not UTF-8";
  if (strpbrk(v, "\"\\")) return "a '\"' or '\\' (sbatch's own quoting)";
  for (const char *c = v; *c; c++)
    if (!strncasecmp(c, "packjob", 7) || !strncasecmp(c, "hetjob", 6))
      return "the word packjob or hetjob (sbatch's separator of heterogeneous jobs)";
  return NULL;
}

/* s in buf[len] with '?' for every control byte and byte that is not
 * UTF-8 (for a one-line message). */
static void printable(const char *s, char *buf, size_t len) {
  size_t at = 0;
  for (const unsigned char *p = (const unsigned char *)s; *p && at + 5 < len;) {
    int n = utf8_len(p);
    if (!n || *p < 0x20 || *p == 0x7f) {
      buf[at++] = '?', p++;
    } else {
      memcpy(buf + at, p, (size_t)n);
      at += (size_t)n, p += n;
    }
  }
  buf[at] = 0;
}

/* dir as an absolute path in abs[PATH_MAX] (*exists: whether it exists):
 * its real path, or when missing its parent's real path and its last name.
 * -1 (errno set) when neither resolves. */
static int abs_dir(const char *dir, char *abs, int *exists) {
  char d[PATH_MAX], parent[PATH_MAX];
  *exists = realpath(dir, abs) != NULL;
  if (*exists) return 0;
  if (errno != ENOENT || snprintf(d, sizeof d, "%s", dir) >= (int)sizeof d) return -1;
  size_t l = strlen(d);
  while (l > 1 && d[l - 1] == '/') d[--l] = 0;
  char *slash = strrchr(d, '/');
  const char *name = slash ? slash + 1 : d;
  if (slash == d)
    snprintf(parent, sizeof parent, "/");
  else if (slash) {
    *slash = 0;
    if (!realpath(d, parent)) return -1;
  } else if (!getcwd(parent, sizeof parent))
    return -1;
  if (!*name || !strcmp(name, ".") || !strcmp(name, "..") ||
      snprintf(abs, PATH_MAX, "%s/%s", strcmp(parent, "/") ? parent : "", name) >= PATH_MAX) {
    errno = ENOENT;
    return -1;
  }
  return 0;
}

/* The pending cells' indices as Slurm's --array list ("0-3,7,9-12") in
 * buf[len]; their number. */
static long pending_array(const ves_study *s, const char *dir, int exists, int retry_failed,
                          char *buf, size_t len) {
  long n = 0, from = -1;
  size_t at = 0;
  buf[0] = 0;
  for (long k = 0; k <= s->ncells; k++) {
    const int pend = k < s->ncells && (!exists || !ves_study_cell_done(s, k, dir, retry_failed));
    if (pend) {
      n++;
      if (from < 0) from = k;
    } else if (from >= 0) { /* the run from..k-1 ends */
      if (at < len)
        at += (size_t)(from == k - 1
                           ? snprintf(buf + at, len - at, "%s%ld", at ? "," : "", from)
                           : snprintf(buf + at, len - at, "%s%ld-%ld", at ? "," : "", from, k - 1));
      from = -1;
    }
  }
  return at < len ? n : -1;
}

ves_status ves_study_write_sbatch(const ves_study *s, const char *program, const char *dir,
                                  int retry_failed, long *ntasks, char *err, size_t errlen) {
  VES_CHECK(s && program && dir && ntasks, VES_ERR_ARG);
  *ntasks = 0;
  char path[PATH_MAX + 16], logs[PATH_MAX + 8], study[PATH_MAX], adir[PATH_MAX];
  char tmp[PATH_MAX + 24], out[2 * PATH_MAX + 16], job[64];
  int exists = 0;
  if (abs_dir(dir, adir, &exists) != 0 || !realpath(s->path, study)) {
    ves_error_say(err, errlen, "%s: cannot resolve: %s", dir, strerror(errno));
    return VES_ERR_IO;
  }
  snprintf(logs, sizeof logs, "%s/slurm", adir);
  snprintf(path, sizeof path, "%s/study.sbatch", adir);
  const char *base = strrchr(study, '/') + 1;
  snprintf(job, sizeof job, "vesica-%.*s", (int)strcspn(base, "."), base);
  for (char *c = job; *c; c++)
    if (!isalnum((unsigned char)*c) && *c != '-' && *c != '_') *c = '_';
  size_t o = 0; /* --output: the logs' folder, '%' doubled (a file-name pattern) */
  for (const char *c = logs; *c && o + 3 < sizeof out; c++) {
    if (*c == '%') out[o++] = '%';
    out[o++] = *c;
  }
  snprintf(out + o, sizeof out - o, "/%%A_%%a.out");
  const char *const name[] = {"--out folder", "job name", "[slurm] partition", "[slurm] account",
                              "[slurm] mem"};
  const char *const value[] = {adir, job, s->partition, s->account, s->mem};
  for (int i = 0; i < 5; i++) {
    const char *why = sbatch_unsafe(value[i]);
    if (why) {
      char shown[PATH_MAX];
      printable(value[i], shown, sizeof shown);
      ves_error_say(err, errlen,
                    "--emit slurm: the %s '%s' holds %s: it cannot go into an #SBATCH line",
                    name[i], shown, why);
      return VES_ERR_CONFIG;
    }
  }
  char *array = malloc(16 * (size_t)s->ncells + 16);
  if (!array) return VES_ERR_ALLOC;
  *ntasks = pending_array(s, adir, exists, retry_failed, array, 16 * (size_t)s->ncells + 16);
  if (*ntasks <= 0) { /* every cell has its result: nothing to submit, and a script of an
                         earlier emit is removed so that it is not submitted by mistake */
    free(array);
    *ntasks = 0;
    if (exists && remove(path) != 0 && errno != ENOENT) {
      ves_error_say(err, errlen, "%s: cannot remove: %s", path, strerror(errno));
      return VES_ERR_IO;
    }
    return VES_OK;
  }
  if ((!exists && mkdir(adir, 0777) != 0) || (mkdir(logs, 0777) != 0 && errno != EEXIST)) {
    ves_error_say(err, errlen, "%s: cannot create: %s", exists ? logs : adir, strerror(errno));
    free(array);
    return VES_ERR_IO;
  }
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  FILE *f = fopen(tmp, "w");
  if (!f) {
    ves_error_say(err, errlen, "%s: cannot write: %s", tmp, strerror(errno));
    free(array);
    return VES_ERR_IO;
  }
  /* the comments: every name quoted as for the shell, so each stays one line */
  fprintf(f, "#!/bin/bash\n# vesica study ");
  sh_word(f, study);
  fprintf(f, ": %ld of %ld cells to run, one per array task.\n# Submit: sbatch ", *ntasks,
          s->ncells);
  sh_word(f, path);
  fputs("\n# Then: vesica study ", f);
  sh_word(f, study);
  for (int i = 0; i < s->ncli; i++) { /* a --collect must give the study's --set too */
    fputs(" --set ", f);
    sh_word(f, s->cli[i]);
  }
  fputs(" --out ", f);
  sh_word(f, adir);
  fputs(" --collect\n", f);
  fprintf(f, "#SBATCH --job-name=%s\n#SBATCH --array=%s", job, array);
  if (s->throttle > 0) fprintf(f, "%%%ld", s->throttle); /* at most N tasks at a time */
  fprintf(f, "\n#SBATCH --ntasks=1\n");
  fprintf(f, "#SBATCH --cpus-per-task=%d\n#SBATCH --mem=%s\n", s->cpus_per_task, s->mem);
  if (s->time_limit > 0) /* the cell's own limit stops it first */
    fprintf(f, "#SBATCH --time=%ld\n", (long)ceil(s->time_limit / 60) + 5);
  fprintf(f, "#SBATCH --output=\"%s\"\n", out);
  if (s->partition[0]) fprintf(f, "#SBATCH --partition=%s\n", s->partition);
  if (s->account[0]) fprintf(f, "#SBATCH --account=%s\n", s->account);
  fprintf(f, "export OMP_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-%d}\"\n", s->cpus_per_task);
  fprintf(f, "export OPENBLAS_NUM_THREADS=1\n");
  if (s->setup[0]) /* the site's set-up, verbatim: shell run by the job ([slurm] setup) */
    fprintf(f, "# [slurm] setup\n%s\n", s->setup);
  fputs("exec ", f);
  sh_word(f, program);
  fputs(" study ", f);
  sh_word(f, study);
  fputs(" --out ", f);
  sh_word(f, adir);
  for (int i = 0; i < s->ncli; i++) { /* the command line's overrides: part of the study */
    fputs(" --set ", f);
    sh_word(f, s->cli[i]);
  }
  fprintf(f, " --max-cells %ld%s --cell \"${SLURM_ARRAY_TASK_ID:?not a Slurm array task}\"\n",
          s->ncells > VES_STUDY_MAX_CELLS ? s->ncells : (long)VES_STUDY_MAX_CELLS,
          retry_failed ? " --retry-failed" : "");
  free(array);
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  if (bad || rename(tmp, path) != 0 || chmod(path, 0755) != 0) {
    ves_error_say(err, errlen, "%s: cannot write: %s", path, strerror(errno));
    remove(tmp);
    return VES_ERR_IO;
  }
  return VES_OK;
}
