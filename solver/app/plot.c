/* vesica — figures of a run: the series and snapshots of an output file
 * turned into one gnuplot script (data inline as datablocks), run by gnuplot
 * (plot.h; docs/manual.md). */
#include "app/plot.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

const char *const ves_plot_figures[VES_PLOT_NFIG] = {"energy", "snapshots", "constraints", "flow"};

#define PLOT_AUTO 4         /* automatic snapshot panels */
#define PLOT_FLOOR 1e-17    /* drift values below this are drawn at it (log axis) */
#define PLOT_PANEL 560      /* pixels per snapshot panel */
#define PLOT_MIN_WIDTH 640  /* pixels at least (a tall box: room for the titles) */
#define PLOT_INTERFACE 0.1  /* |phi| below this marks an interface node */
#define PLOT_ARROW_ROWS 24  /* flow: cells of the arrow grid over the box's height */
#define PLOT_ARROW_MIN 0.05 /* flow: arrows shorter than this x the longest are left out */

void ves_plot_gp_quote(FILE *f, const char *s) {
  fputc('\'', f);
  for (; *s; s++) {
    if (*s == '\'') fputc('\'', f);
    fputc(*s, f);
  }
  fputc('\'', f);
}

void ves_plot_gp_escape(char *out, size_t n, const char *s) {
  size_t k = 0;
  for (; *s && k + 2 < n; s++) {
    if (strchr("_^@&~{}\\", *s)) out[k++] = '\\';
    out[k++] = *s;
  }
  out[k] = 0;
}

/* Figure fig's file, final (part = 0) or as gnuplot writes it (part = 1:
 * renamed to the final name once checked complete, fig_check). */
static void fig_path(char *path, size_t n, const ves_plot_params *p, int fig, int part) {
  snprintf(path, n, "%s/%s_%s.png%s", p->outdir, p->stem, ves_plot_figures[fig],
           part ? ".part" : "");
}

/* Whether path holds a complete PNG: the signature, and the IEND chunk as
 * its last 12 bytes (gnuplot's cairo terminal exits 0 after a failed write,
 * leaving an empty or truncated file). 0 ok, else errno-like reason in why. */
static int png_complete(const char *path, char *why, size_t n) {
  static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  static const unsigned char iend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
  unsigned char head[8], tail[12];
  FILE *f = fopen(path, "rb");
  if (!f) {
    snprintf(why, n, "not written (%s)", strerror(errno));
    return -1;
  }
  int ok = fread(head, 1, 8, f) == 8 && !memcmp(head, sig, 8) && fseek(f, -12, SEEK_END) == 0 &&
           fread(tail, 1, 12, f) == 12 && !memcmp(tail, iend, 12);
  long size = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  fclose(f);
  if (!ok) snprintf(why, n, "incomplete (%ld bytes; a full disk?)", size);
  return ok ? 0 : -1;
}

static void gp_output(FILE *f, const ves_plot_params *p, int fig) {
  char path[PATH_MAX];
  fig_path(path, sizeof path, p, fig, 1);
  fputs("set output ", f);
  ves_plot_gp_quote(f, path);
  fputc('\n', f);
}

/* The snapshots to draw, sel[*nsel] in increasing order without repeats:
 * the nearest to each chosen time, or (automatic) the first, the last and
 * PLOT_AUTO - 2 between them at log-spaced times. */
static int select_snapshots(const double *T, int S, const ves_plot_params *p, int *sel) {
  double want[VES_PLOT_MAXTIMES];
  int nw = 0;
  if (p->ntimes > 0) {
    for (int i = 0; i < p->ntimes; i++) want[nw++] = p->times[i];
  } else if (S <= PLOT_AUTO) {
    for (int k = 0; k < S; k++) want[nw++] = T[k];
  } else {
    double t1 = T[1] > 0 ? T[1] : T[S - 1] * 1e-3, tl = T[S - 1];
    want[nw++] = T[0];
    for (int j = 1; j < PLOT_AUTO - 1; j++)
      want[nw++] = t1 * pow(tl / t1, (double)j / (PLOT_AUTO - 1));
    want[nw++] = tl;
  }
  int nsel = 0;
  for (int i = 0; i < nw; i++) {
    int best = 0;
    for (int k = 1; k < S; k++)
      if (fabs(T[k] - want[i]) < fabs(T[best] - want[i])) best = k;
    int seen = 0;
    for (int j = 0; j < nsel; j++) seen |= sel[j] == best;
    if (!seen) sel[nsel++] = best;
  }
  for (int i = 1; i < nsel; i++) /* insertion sort: a handful of entries */
    for (int j = i; j > 0 && sel[j - 1] > sel[j]; j--) {
      int tmp = sel[j];
      sel[j] = sel[j - 1], sel[j - 1] = tmp;
    }
  return nsel;
}

/* E* and dt* against t* (log time), as the paper's Fig. 4. */
static void fig_energy(FILE *f, const ves_plot_params *p, const ves_io_info *in, long R,
                       const double *t, const double *dt, const double *E) {
  fprintf(f, "$series << EOD\n");
  for (long i = 0; i < R; i++) fprintf(f, "%.10g %.10g %.12g\n", t[i], dt[i], E[i]);
  fprintf(f, "EOD\n");
  fprintf(f, "reset\nset terminal pngcairo size 900,900 font ',12'\n");
  gp_output(f, p, 0);
  fprintf(f, "set multiplot layout 2,1 title ");
  char title[256];
  char stem[96]; /* a long name is cut: it is a title */
  ves_plot_gp_escape(stem, sizeof stem, p->stem);
  snprintf(title, sizeof title, "%s: %d nodes, %s backend, %ld steps", stem, in->n, in->backend, R);
  ves_plot_gp_quote(f, title);
  fprintf(f,
          "\nset logscale x\nset format x '10^{%%L}'\nset grid\nset key top right\n"
          "set lmargin 12\nset ylabel 'E* = E/k'\n"
          "plot $series using 1:3 with linespoints pt 7 ps 0.6 lw 2 lc rgb '#b40426' "
          "title 'E*'\n"
          "set logscale y\nset format y '10^{%%L}'\nset xlabel 't* = t k / ({/Symbol m} R_0^3)'\n"
          "set ylabel '{/Symbol D}t*'\n"
          "plot $series using 1:2 with linespoints pt 7 ps 0.6 lw 2 lc rgb '#3b4cc0' "
          "title '{/Symbol D}t*'\n"
          "unset multiplot\n");
}

/* The box's half extents: the largest R and |Z| of the reference mesh's
 * nodes (the walls). */
static ves_status box_extent(ves_io *io, double *LR, double *LZ) {
  const int n = ves_io_get_info(io)->n;
  double *X = malloc(2 * (size_t)n * sizeof *X);
  ves_status st = X ? ves_io_read_mesh(io, X, NULL) : VES_ERR_ALLOC;
  *LR = 0, *LZ = 0;
  for (int a = 0; st == VES_OK && a < n; a++)
    *LR = fmax(*LR, X[2 * a]), *LZ = fmax(*LZ, fabs(X[2 * a + 1]));
  free(X);
  return st;
}

/* The axes of the node panels (snapshots, flow): the meridian plane
 * mirrored, [-LR, LR] x [-LZ, LZ] at equal scale, phi's palette. */
static void panel_axes(FILE *f, double LR, double LZ) {
  fprintf(f,
          "\nset size ratio -1\nset xrange [%g:%g]\nset yrange [%g:%g]\n"
          "set palette defined (-1 '#3b4cc0', 0 '#dddddd', 1 '#b40426')\nset cbrange [-1:1]\n"
          "set cblabel '{/Symbol f}'\nset xlabel 'r / R_0'\nset ylabel 'z / R_0'\n"
          "unset key\n",
          -LR, LR, -LZ, LZ);
}

/* Node snapshots coloured by phi, mirrored across the axis. */
static ves_status fig_snapshots(FILE *f, ves_io *io, const ves_plot_params *p, const int *sel,
                                int nsel) {
  const ves_io_info *in = ves_io_get_info(io);
  int n = in->n, nmax = in->n; /* snapshots after a remeshing have their own count */
  for (int j = 0; j < nsel; j++)
    if (ves_io_snapshot_nodes(io, sel[j]) > nmax) nmax = ves_io_snapshot_nodes(io, sel[j]);
  double *y = malloc(2 * (size_t)nmax * sizeof *y), *phi = malloc((size_t)nmax * sizeof *phi);
  double LR = 0, LZ = 0, ts[VES_PLOT_MAXTIMES];
  ves_status st = y && phi ? box_extent(io, &LR, &LZ) : VES_ERR_ALLOC;
  for (int j = 0; j < nsel && st == VES_OK; j++) {
    ves_io_snapinfo si;
    n = ves_io_snapshot_nodes(io, sel[j]);
    /* x: where the material at the nodes is (format 1 files: the coefficients) */
    if ((st = ves_io_read_snapshot_n(io, sel[j], n, NULL, y, phi, &si)) != VES_OK) break;
    ts[j] = si.state.t;
    fprintf(f, "$snap%d << EOD\n", j);
    for (int a = 0; a < n; a++) fprintf(f, "%.7g %.7g %.5g\n", y[2 * a], y[2 * a + 1], phi[a]);
    fprintf(f, "EOD\n");
    if (j == 0) { /* the first panel's interface nodes, drawn over the later ones */
      fprintf(f, "$ref << EOD\n");
      for (int a = 0; a < n; a++)
        if (fabs(phi[a]) < PLOT_INTERFACE) fprintf(f, "%.7g %.7g\n", y[2 * a], y[2 * a + 1]);
      fprintf(f, "EOD\n");
    }
  }
  free(y), free(phi);
  VES_CALL(st);
  int cols = nsel <= 2 ? nsel : nsel <= 4 ? 2 : (nsel + 1) / 2, rows = (nsel + cols - 1) / cols;
  double ps = fmin(0.6, 0.35 * sqrt(1500.0 / n)); /* points shrink as nodes multiply */
  fprintf(f, "reset\nset terminal pngcairo size %d,%d font ',11'\n",
          (int)fmax(PLOT_PANEL * cols * LR / LZ + 120, PLOT_MIN_WIDTH), PLOT_PANEL * rows + 60);
  gp_output(f, p, 1);
  fprintf(f, "set multiplot layout %d,%d title ", rows, cols);
  char title[256];
  char stem[96]; /* a long name is cut: it is a title */
  ves_plot_gp_escape(stem, sizeof stem, p->stem);
  snprintf(
      title, sizeof title, "%s: %s coloured by {/Symbol f} (%d nodes, mirrored at r = 0)", stem,
      in->format_version >= 2 ? "material at the nodes, y(X_a, t)," : "nodal coefficients y^a(t)",
      n);
  ves_plot_gp_quote(f, title);
  panel_axes(f, LR, LZ);
  for (int j = 0; j < nsel; j++) {
    if (j == 0)
      fprintf(f, "set title 't* = %.4g'\n", ts[j]);
    else
      fprintf(f, "set title 't* = %.4g   (black: interface nodes at t* = %.4g)'\n", ts[j], ts[0]);
    fprintf(f,
            "plot $snap%d using 1:2:3 with points pt 7 ps %.3f lc palette, "
            "$snap%d using (-$1):2:3 with points pt 7 ps %.3f lc palette",
            j, ps, j, ps);
    if (j > 0)
      fprintf(f,
              ", $ref using 1:2 with points pt 7 ps %.3f lc rgb 'black', "
              "$ref using (-$1):2 with points pt 7 ps %.3f lc rgb 'black'",
              0.5 * ps, 0.5 * ps);
    fputc('\n', f);
  }
  fprintf(f, "unset multiplot\n");
  return VES_OK;
}

/* The node of each arrow cell (nr x PLOT_ARROW_ROWS cells of side cell
 * over [0, nr cell] x [-LZ, LZ]): the one nearest the cell's centre among
 * the n nodes at x with a finite velocity v, or -1, into pick. */
static void flow_pick(const double *x, const double *v, int n, int nr, double cell, double LZ,
                      int *pick) {
  const int nc = nr * PLOT_ARROW_ROWS;
  for (int c = 0; c < nc; c++) pick[c] = -1;
  for (int a = 0; a < n; a++) {
    const double r = x[2 * a], z = x[2 * a + 1];
    if (!(r >= 0 && r < nr * cell && z >= -LZ && z < LZ) || !isfinite(v[2 * a]) ||
        !isfinite(v[2 * a + 1]))
      continue;
    const int ir = (int)(r / cell), iz = (int)((z + LZ) / cell), c = iz * nr + ir;
    const double cr = (ir + 0.5) * cell, cz = -LZ + (iz + 0.5) * cell;
    if (pick[c] < 0 || hypot(r - cr, z - cz) < hypot(x[2 * pick[c]] - cr, x[2 * pick[c] + 1] - cz))
      pick[c] = a;
  }
}

/* The flow at the selected snapshots (paper Fig. 5): the nodes coloured by
 * phi as in fig_snapshots, and arrows of the velocity at the nodes
 * (ves_io_read_snapshot_velocity) on a grid of square cells, PLOT_ARROW_ROWS
 * over the box's height: in each cell the node nearest its centre, so the
 * arrows are evenly spread however the nodes are graded. Each panel is
 * scaled to its own fastest arrow (the speeds of a relaxation span decades;
 * the title states it), drawn 0.9 of a cell long; arrows under
 * PLOT_ARROW_MIN of it are left out. Mirrored at r = 0 as the points (v_r
 * changes sign). A snapshot without a velocity (the first; a file that
 * stores none) shows the points alone, and says so. The points are
 * fig_snapshots' datablocks $snapJ (the same snapshots and x, phi), so this
 * figure follows it in the script. */
static ves_status fig_flow(FILE *f, ves_io *io, const ves_plot_params *p, const int *sel,
                           int nsel) {
  const ves_io_info *in = ves_io_get_info(io);
  int n = in->n, nmax = in->n;
  for (int j = 0; j < nsel; j++)
    if (ves_io_snapshot_nodes(io, sel[j]) > nmax) nmax = ves_io_snapshot_nodes(io, sel[j]);
  double *x = malloc(2 * (size_t)nmax * sizeof *x), *v = malloc(2 * (size_t)nmax * sizeof *v);
  int *pick = NULL;
  double LR = 0, LZ = 0, ts[VES_PLOT_MAXTIMES], vmax[VES_PLOT_MAXTIMES];
  ves_status st = x && v ? box_extent(io, &LR, &LZ) : VES_ERR_ALLOC;
  int has[VES_PLOT_MAXTIMES];
  const double cell = 2 * LZ / PLOT_ARROW_ROWS;
  const int nr = st == VES_OK ? (int)ceil(LR / cell) : 0, nc = nr * PLOT_ARROW_ROWS;
  if (st == VES_OK && !(pick = malloc((size_t)(nc > 0 ? nc : 1) * sizeof *pick)))
    st = VES_ERR_ALLOC;
  for (int j = 0; j < nsel && st == VES_OK; j++) {
    ves_io_snapinfo si;
    n = ves_io_snapshot_nodes(io, sel[j]);
    if ((st = ves_io_read_snapshot_n(io, sel[j], n, NULL, x, NULL, &si)) != VES_OK) break;
    const int got = ves_io_read_snapshot_velocity(io, sel[j], n, v);
    if (got < 0) {
      st = (ves_status)got;
      break;
    }
    ts[j] = si.state.t, has[j] = got, vmax[j] = 0;
    if (!got) continue;
    flow_pick(x, v, n, nr, cell, LZ, pick);
    for (int c = 0; c < nc; c++)
      if (pick[c] >= 0) vmax[j] = fmax(vmax[j], hypot(v[2 * pick[c]], v[2 * pick[c] + 1]));
    const double scale = vmax[j] > 0 ? 0.9 * cell / vmax[j] : 0;
    if (!(vmax[j] > 0)) { /* at rest: no arrow to draw (gnuplot refuses empty data) */
      has[j] = 2;
      continue;
    }
    fprintf(f, "$flowv%d << EOD\n", j);
    for (int c = 0; c < nc; c++) {
      const int a = pick[c];
      if (a < 0 || hypot(v[2 * a], v[2 * a + 1]) < PLOT_ARROW_MIN * vmax[j]) continue;
      fprintf(f, "%.5g %.5g %.3g %.3g\n", x[2 * a], x[2 * a + 1], scale * v[2 * a],
              scale * v[2 * a + 1]); /* a drawing's precision */
    }
    fprintf(f, "EOD\n");
  }
  free(x), free(v), free(pick);
  VES_CALL(st);
  int cols = nsel <= 2 ? nsel : nsel <= 4 ? 2 : (nsel + 1) / 2, rows = (nsel + cols - 1) / cols;
  double ps = 0.6 * fmin(0.6, 0.35 * sqrt(1500.0 / n)); /* fainter: the arrows are the figure */
  fprintf(f, "reset\nset terminal pngcairo size %d,%d font ',11'\n",
          (int)fmax(PLOT_PANEL * cols * LR / LZ + 120, PLOT_MIN_WIDTH), PLOT_PANEL * rows + 60);
  gp_output(f, p, 3);
  fprintf(f, "set multiplot layout %d,%d title ", rows, cols);
  char title[256], stem[96];
  ves_plot_gp_escape(stem, sizeof stem, p->stem);
  snprintf(title, sizeof title, "%s: flow at the nodes (arrows), {/Symbol f} (colour), mirrored",
           stem);
  ves_plot_gp_quote(f, title);
  panel_axes(f, LR, LZ);
  for (int j = 0; j < nsel; j++) {
    if (has[j] == 1)
      fprintf(f, "set title \"t* = %.4g\\narrows up to %.3g R_0 per t*\"\n", ts[j], vmax[j]);
    else if (has[j] == 2)
      fprintf(f, "set title \"t* = %.4g\\nat rest (v = 0)\"\n", ts[j]);
    else
      fprintf(f, "set title \"t* = %.4g\\nno flow (first snapshot, or none stored)\"\n", ts[j]);
    fprintf(f, /* the points: fig_snapshots' datablocks (a reset keeps them) */
            "plot $snap%d using 1:2:3 with points pt 7 ps %.3f lc palette, "
            "$snap%d using (-$1):2:3 with points pt 7 ps %.3f lc palette",
            j, ps, j, ps);
    if (has[j] == 1)
      fprintf(f,
              ", $flowv%d using 1:2:3:4 with vectors head filled size screen 0.006,20 "
              "lw 1.2 lc rgb 'black', $flowv%d using (-$1):2:(-$3):4 with vectors head filled "
              "size screen 0.006,20 lw 1.2 lc rgb 'black'",
              j, j);
    fputc('\n', f);
  }
  fprintf(f, "unset multiplot\n");
  return VES_OK;
}

ves_status ves_plot_interface(ves_io *io, ves_level_set *ls, unsigned char *ok) {
  VES_CHECK(io && ls && ok, VES_ERR_ARG);
  const ves_io_info *in = ves_io_get_info(io);
  const int S = ves_io_snapshots(io);
  memset(ok, 0, (size_t)S);
  if (in->format_version < 2 || S < 1) return VES_OK;
  int n = in->n, nt = in->ntri, cur = -2; /* cur: the node set in tri (-1 the initial mesh) */
  for (int k = 0; k < S; k++) {           /* room for the largest node set (remeshings) */
    int nk, tk;
    ves_io_snapshot_mesh(io, k, &nk, &tk);
    n = nk > n ? nk : n, nt = tk > nt ? tk : nt;
  }
  double *x = malloc(2 * (size_t)n * sizeof *x), *phi = malloc((size_t)n * sizeof *phi);
  int *tri = malloc(3 * (size_t)nt * sizeof *tri);
  if (!x || !phi || !tri) {
    free(x), free(phi), free(tri);
    return VES_ERR_ALLOC;
  }
  ves_status st = VES_OK;
  for (int k = 0; k < S && st == VES_OK; k++) {
    int nk, tk;
    const int j = ves_io_snapshot_mesh(io, k, &nk, &tk);
    if (j != cur) {
      st = j < 0 ? ves_io_read_mesh(io, NULL, tri) : ves_io_read_remesh_triangles(io, j, tri);
      cur = j;
    }
    ok[k] = st == VES_OK && ves_io_read_snapshot_n(io, k, nk, NULL, x, phi, NULL) == VES_OK &&
            ves_level_set_eval(nk, tk, tri, x, phi, ls + k) == VES_OK;
  }
  free(x), free(phi), free(tri);
  return st;
}

/* Constraint drift, the drift of the nodes' sharp interface (ls, ok at the
 * S snapshots at times T) and the volume protocol against t*. */
static void fig_constraints(FILE *f, const ves_plot_params *p, const ves_io_info *in, long R,
                            const double *t, const double *A, const double *V, const double *Vt,
                            int S, const double *T, const ves_level_set *ls,
                            const unsigned char *ok) {
  fprintf(f, "$drift << EOD\n");
  for (long i = 0; i < R; i++)
    fprintf(f, "%.10g %.6e %.6e %.12g %.12g\n", t[i], fmax(fabs(A[i] / in->A0 - 1), PLOT_FLOOR),
            fmax(fabs(V[i] / Vt[i] - 1), PLOT_FLOOR), V[i] / in->V0, Vt[i] / in->V0);
  fprintf(f, "EOD\n$iface << EOD\n");
  int k0 = 0, nif = 0; /* the first snapshot with an interface is the reference */
  while (k0 < S && !ok[k0]) k0++;
  for (int k = k0 + 1; k < S; k++)
    if (ok[k] && T[k] > 0) /* t* = 0 has no place on the log axis */
      fprintf(f, "%.10g %.6e %.6e\n", T[k], fmax(fabs(ls[k].area / ls[k0].area - 1), PLOT_FLOOR),
              fmax(fabs(ls[k].volume / ls[k0].volume - 1), PLOT_FLOOR)),
          nif++;
  if (!nif) fprintf(f, "NaN NaN NaN\n"); /* an empty datablock would stop gnuplot */
  fprintf(f, "EOD\n");
  fprintf(f, "reset\nset terminal pngcairo size 900,900 font ',12'\n");
  gp_output(f, p, 2);
  fprintf(f, "set multiplot layout 2,1 title ");
  char title[256];
  char stem[96]; /* a long name is cut: it is a title */
  ves_plot_gp_escape(stem, sizeof stem, p->stem);
  snprintf(title, sizeof title, "%s: constraints (values below %g drawn at %g)", stem, PLOT_FLOOR,
           PLOT_FLOOR);
  ves_plot_gp_quote(f, title);
  fprintf(f, "\nset logscale x\nset format x '10^{%%L}'\nset grid\nset lmargin 12\n"
             "set logscale y\nset format y '10^{%%L}'\nset ylabel 'relative drift'\n"
             "set key right center\n"
             "plot $drift using 1:2 with linespoints pt 7 ps 0.5 lc rgb '#b40426' "
             "title '|A/A_0 - 1|', "
             "$drift using 1:3 with linespoints pt 5 ps 0.5 lc rgb '#3b4cc0' "
             "title '|V/V_{target} - 1|', "
             "$iface using 1:2 with points pt 6 ps 1 lc rgb '#b40426' "
             "title 'interface area: |A_I/A_I(0) - 1|', "
             "$iface using 1:3 with points pt 4 ps 1 lc rgb '#3b4cc0' "
             "title 'interface volume: |V_I/V_I(0) - 1|'\n"
             "unset logscale y\nset format y '%%g'\nset ylabel 'V / V_0'\n"
             "set xlabel 't* = t k / ({/Symbol m} R_0^3)'\nset key bottom left\n"
             "plot $drift using 1:4 with linespoints pt 7 ps 0.5 lc rgb '#3b4cc0' title 'V/V_0', "
             "$drift using 1:5 with lines dt 2 lw 2 lc rgb 'black' title 'target'\n"
             "unset multiplot\n");
}

ves_status ves_plot_run_gnuplot(const char *script, char *err, size_t errlen) {
  char cmd[PATH_MAX + 32], msg[512] = "";
  snprintf(cmd, sizeof cmd, "gnuplot %s 2>&1", script);
  FILE *g = popen(cmd, "r");
  if (!g) {
    ves_error_say(err, errlen, "cannot run gnuplot: %s", strerror(errno));
    return VES_ERR_IO;
  }
  char line[512];
  while (fgets(line, sizeof line, g)) /* keep the last message line: gnuplot's reason */
    if (strspn(line, " \t\n^") < strlen(line)) snprintf(msg, sizeof msg, "%s", line);
  int rc = pclose(g), code = rc != -1 && WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  if (code != 0) {
    msg[strcspn(msg, "\n")] = 0;
    if (msg[0])
      ves_error_say(err, errlen, "gnuplot failed (exit status %d): %s", code, msg);
    else
      ves_error_say(err, errlen, "gnuplot failed (exit status %d)", code);
    return VES_ERR_IO;
  }
  return VES_OK;
}

/* Every figure of the run checked complete (the .part files gnuplot
 * wrote), then all renamed into place: a failed plot leaves the earlier
 * figures as they were. */
static ves_status figures_commit(const ves_plot_params *p, char *err, size_t errlen) {
  ves_status st = VES_OK;
  for (int k = 0; k < VES_PLOT_NFIG && st == VES_OK; k++) {
    char part[PATH_MAX], why[128];
    fig_path(part, sizeof part, p, k, 1);
    if (png_complete(part, why, sizeof why)) {
      ves_error_say(err, errlen, "figure %s: %s", part, why);
      st = VES_ERR_IO;
    }
  }
  for (int k = 0; k < VES_PLOT_NFIG && st == VES_OK; k++) {
    char part[PATH_MAX], final[PATH_MAX];
    fig_path(part, sizeof part, p, k, 1);
    fig_path(final, sizeof final, p, k, 0);
    if (rename(part, final) != 0) {
      ves_error_say(err, errlen, "cannot rename %s to %s: %s", part, final, strerror(errno));
      st = VES_ERR_IO;
    }
  }
  return st;
}

ves_status ves_plot_write(ves_io *io, const ves_plot_params *p, char *err, size_t errlen) {
  VES_CHECK(io && p && p->outdir && p->stem && p->ntimes >= 0 && p->ntimes <= VES_PLOT_MAXTIMES,
            VES_ERR_ARG);
  const ves_io_info *in = ves_io_get_info(io);
  if (err && errlen) err[0] = 0;
  long R = ves_io_rows(io);
  int S = ves_io_snapshots(io);
  if (R < 1 || S < 1) {
    ves_error_say(err, errlen, "nothing to plot: %ld steps, %d snapshots", R, S);
    return VES_ERR_ARG;
  }
  ves_status st = VES_ERR_ALLOC;
  double *buf = malloc(6 * (size_t)R * sizeof *buf), *T = malloc((size_t)S * sizeof *T);
  ves_level_set *ls = malloc((size_t)S * sizeof *ls);
  unsigned char *ok = malloc((size_t)S);
  FILE *f = NULL;
  char script[PATH_MAX] = "";
  if (!buf || !T || !ls || !ok) goto done;
  double *t = buf, *dt = buf + R, *E = buf + 2 * R, *A = buf + 3 * R, *V = buf + 4 * R,
         *Vt = buf + 5 * R;
  const char *names[6] = {"t", "dt", "E", "A", "V", "V_target"};
  for (int i = 0; i < 6; i++)
    if ((st = ves_io_read_series(io, names[i], buf + i * R)) != VES_OK) goto done;
  for (int k = 0; k < S; k++) {
    ves_io_snapinfo si;
    if ((st = ves_io_read_snapshot(io, k, NULL, NULL, NULL, &si)) != VES_OK) goto done;
    T[k] = si.state.t;
  }
  int sel[VES_PLOT_MAXTIMES], nsel = select_snapshots(T, S, p, sel);
  if ((st = ves_plot_interface(io, ls, ok)) != VES_OK) goto done;

  const char *dir = getenv("TMPDIR");
  snprintf(script, sizeof script, "%s/vesica_plot_XXXXXX", dir && *dir ? dir : "/tmp");
  int fd = mkstemp(script);
  if (fd < 0 || !(f = fdopen(fd, "w"))) {
    if (fd >= 0) close(fd);
    ves_error_say(err, errlen, "cannot create a temporary file %s: %s", script, strerror(errno));
    script[0] = 0;
    st = VES_ERR_IO;
    goto done;
  }
  fig_energy(f, p, in, R, t, dt, E);
  if ((st = fig_snapshots(f, io, p, sel, nsel)) != VES_OK) goto done;
  fig_constraints(f, p, in, R, t, A, V, Vt, S, T, ls, ok);
  if ((st = fig_flow(f, io, p, sel, nsel)) != VES_OK) goto done;
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  f = NULL;
  if (bad) {
    ves_error_say(err, errlen, "cannot write the gnuplot script %s", script);
    st = VES_ERR_IO;
    goto done;
  }
  if ((st = ves_plot_run_gnuplot(script, err, errlen)) != VES_OK) goto done;
  st = figures_commit(p, err, errlen);
done:
  if (st != VES_OK && st != VES_ERR_ALLOC && err && errlen && !err[0]) { /* a read failed */
    const char *c = ves_io_corruption(io);
    ves_error_say(err, errlen, "corrupt: %s",
                  c[0] ? c : "a dataset does not read (missing, or of another shape or type)");
    st = VES_ERR_CONFIG;
  }
  for (int k = 0; k < VES_PLOT_NFIG; k++) { /* no partial figure stays behind */
    char part[PATH_MAX];
    fig_path(part, sizeof part, p, k, 1);
    unlink(part);
  }
  if (f) fclose(f);
  if (script[0]) unlink(script);
  free(buf), free(T), free(ls), free(ok);
  return st;
}
