/* vesica — figures of a run: the series and snapshots of an output file
 * turned into one gnuplot script (data inline as datablocks; the phi = 0
 * curves from ves_level_set_curves_eval), run by gnuplot for PNG, PDF or
 * SVG (plot.h; docs/manual.md). */
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
const char *const ves_plot_formats[VES_PLOT_NFORMAT] = {"png", "pdf", "svg"};

#define PLOT_AUTO 4        /* automatic snapshot panels */
#define PLOT_FLOOR 1e-17   /* drift values below this are drawn at it (log axis) */
#define PLOT_PANEL 540     /* pixels of a panel's longer side (its data area) */
#define PLOT_MIN_WIDTH 900 /* pixels at least (room for the titles) */
#define PLOT_MARGIN                                                                                \
  0.25                       /* the view: the phi = 0 curves' extent and this fraction of          \
                                their larger half extent around them */
#define PLOT_ARROW_CELLS 24  /* flow: cells of the arrow grid along the view's longer side */
#define PLOT_ARROW_MIN 0.05  /* flow: arrows drawn shorter than this x a cell are left out */
#define PLOT_ROUNDING 1e-10  /* a V_target within this of V0 at every step: constant */
#define PLOT_PX_PER_INCH 72. /* PDF: the PNG's pixels as points, the fonts keep their size */

void ves_plot_gp_quote(FILE *f, const char *s) {
  fputc('\'', f);
  for (; *s; s++) {
    if (*s == '\n') { /* a line break: a string expression, 'a' . "\n" . 'b' */
      fputs("' . \"\\n\" . '", f);
      continue;
    }
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
 * renamed to the final name once checked complete, figures_commit). */
static void fig_path(char *path, size_t n, const ves_plot_params *p, int fig, int part) {
  snprintf(path, n, "%s/%s_%s.%s%s", p->outdir, p->stem, ves_plot_figures[fig],
           ves_plot_formats[p->format], part ? ".part" : "");
}

/* The last len bytes of f (fewer when it is shorter) into buf, NUL-ended;
 * their count. */
static long tail_of(FILE *f, char *buf, long len) {
  if (fseek(f, 0, SEEK_END) != 0) return 0;
  const long size = ftell(f), k = size < len ? size : len;
  if (k <= 0 || fseek(f, size - k, SEEK_SET) != 0) return 0;
  const long got = (long)fread(buf, 1, (size_t)k, f);
  buf[got] = 0;
  return got;
}

/* Whether path holds a complete figure of the format (gnuplot's cairo and
 * svg terminals exit 0 after a failed write, leaving an empty or truncated
 * file): PNG its signature and the IEND chunk as its last 12 bytes, PDF
 * "%PDF-" and the "%%EOF" of its trailer, SVG the XML declaration and
 * "</svg>" as its last text. 0 ok, else the reason in why. */
static int fig_complete(const char *path, int format, char *why, size_t n) {
  static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  static const unsigned char iend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
  char head[8], tail[64];
  FILE *f = fopen(path, "rb");
  if (!f) {
    snprintf(why, n, "not written (%s)", strerror(errno));
    return -1;
  }
  int ok = fread(head, 1, 8, f) == 8;
  const long k = tail_of(f, tail, (long)sizeof tail - 1);
  long size = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  fclose(f);
  if (format == 0) {
    ok = ok && !memcmp(head, sig, 8) && k >= 12 && !memcmp(tail + k - 12, iend, 12);
  } else if (format == 1) {
    ok = ok && !memcmp(head, "%PDF-", 5) && strstr(tail, "%%EOF");
  } else {
    long e = k;
    while (e > 0 && strchr(" \t\r\n", tail[e - 1])) e--;
    ok = ok && !memcmp(head, "<?xml", 5) && e >= 6 && !memcmp(tail + e - 6, "</svg>", 6);
  }
  if (!ok)
    snprintf(why, n, "incomplete %s (%ld bytes; a full disk?)", ves_plot_formats[format], size);
  return ok ? 0 : -1;
}

/* The terminal of the format for a figure of w x h pixels (PDF: as many
 * points) with the font at pt points, and its output (the .part). */
static void gp_terminal(FILE *f, const ves_plot_params *p, int fig, int w, int h, int pt) {
  char path[PATH_MAX];
  fig_path(path, sizeof path, p, fig, 0);
  fputs("reset\n", f);
  if (p->format == 1)
    fprintf(f, "set terminal pdfcairo enhanced size %.2fin,%.2fin font ',%d'\n",
            w / PLOT_PX_PER_INCH, h / PLOT_PX_PER_INCH, pt);
  else if (p->format == 2)
    fprintf(f, "set terminal svg enhanced size %d,%d font ',%d' background '#ffffff'\n", w, h, pt);
  else
    fprintf(f, "set terminal pngcairo enhanced size %d,%d font ',%d'\n", w, h, pt);
  fputs("set output ", f); /* part: '.part' while vesica plot runs, '' in a kept script */
  ves_plot_gp_quote(f, path);
  fputs(" . part\n", f);
}

/* The file's stem escaped for a title (a long name is cut: it is a title). */
static void title_stem(char *out, size_t n, const ves_plot_params *p) {
  ves_plot_gp_escape(out, n < 96 ? n : 96, p->stem);
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

/* The rows at t > 0 of a log time axis (a t = 0 row has no place on it):
 * the time axis fitted to them, [t_first, t_last]. */
static void time_axis(FILE *f, long R, const double *t) {
  double lo = INFINITY, hi = -INFINITY;
  for (long i = 0; i < R; i++)
    if (t[i] > 0) lo = fmin(lo, t[i]), hi = fmax(hi, t[i]);
  fprintf(f, "set logscale x\nset format x '10^{%%L}'\nset grid\n");
  if (lo < hi)
    fprintf(f, "set xrange [%.10g:%.10g]\n", lo, hi);
  else
    fprintf(f, "set autoscale xfix\n");
}

/* E* and dt* against t* (log time), as the paper's Fig. 4: one curve a
 * panel, named by its axis (no legend). */
static void fig_energy(FILE *f, const ves_plot_params *p, const ves_io_info *in, long R,
                       const double *t, const double *dt, const double *E) {
  fprintf(f, "$series << EOD\n");
  for (long i = 0; i < R; i++)
    if (t[i] > 0) fprintf(f, "%.10g %.10g %.12g\n", t[i], dt[i], E[i]);
  fprintf(f, "EOD\n");
  gp_terminal(f, p, 0, 900, 900, 12);
  fprintf(f, "set multiplot layout 2,1 title ");
  char title[256], stem[96];
  title_stem(stem, sizeof stem, p);
  snprintf(title, sizeof title, "%s: %d nodes, %s backend, %ld steps", stem, in->n, in->backend, R);
  ves_plot_gp_quote(f, title);
  fputc('\n', f);
  time_axis(f, R, t);
  fprintf(f, "unset key\nset lmargin 12\nset offsets 0, 0, graph 0.05, graph 0.05\n"
             "set ylabel 'E* = E / k'\n"
             "plot $series using 1:3 with linespoints pt 7 ps 0.6 lw 2 lc rgb '#b40426'\n"
             "set logscale y\nset format y '10^{%%L}'\nset offsets 0, 0, 0, 0\n"
             "set xlabel 't* = t k / ({/Symbol m} R_0^3)'\n"
             "set ylabel 'time step {/Symbol D}t*'\n"
             "plot $series using 1:2 with linespoints pt 7 ps 0.6 lw 2 lc rgb '#3b4cc0'\n"
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

/* The shape panels (snapshots, flow): the selected snapshots, their times,
 * node counts, whether each has a phi = 0 curve, and the view all panels
 * share: r in [-VR, VR], z in [Z0, Z1] (R0). */
typedef struct {
  int nsel, sel[VES_PLOT_MAXTIMES], n[VES_PLOT_MAXTIMES], curve[VES_PLOT_MAXTIMES];
  double t[VES_PLOT_MAXTIMES], VR, Z0, Z1, LR, LZ;
} panels;

/* The triangles in use at snapshot k into tri (the reference mesh's, or
 * the last remeshing's at or before it: ves_io_snapshot_mesh), unless
 * *cur says they are there; its node and triangle counts. */
static ves_status snapshot_triangles(ves_io *io, int k, int *tri, int *cur, int *nk, int *tk) {
  const int j = ves_io_snapshot_mesh(io, k, nk, tk);
  if (j == *cur) return VES_OK;
  *cur = j;
  return j < 0 ? ves_io_read_mesh(io, NULL, tri) : ves_io_read_remesh_triangles(io, j, tri);
}

/* The shape panels' data as datablocks: $curveJ the phi = 0 curve of
 * panel J (ves_level_set_curves_eval on the triangles in use at the
 * snapshot, at the material positions x; its pieces apart by a blank
 * line), then $snapJ its nodes inside the view (r, z, phi). The view: the
 * curves' extent over all panels and PLOT_MARGIN of it around, within the
 * box; the box when no panel has a curve (format 1 files hold no x). */
static ves_status panels_write(FILE *f, ves_io *io, const int *sel, int nsel, panels *pn) {
  const ves_io_info *in = ves_io_get_info(io);
  int nmax = in->n, tmax = in->ntri;
  memset(pn, 0, sizeof *pn);
  pn->nsel = nsel;
  for (int j = 0; j < nsel; j++) {
    int nk, tk;
    ves_io_snapshot_mesh(io, sel[j], &nk, &tk);
    nmax = nk > nmax ? nk : nmax, tmax = tk > tmax ? tk : tmax;
    pn->sel[j] = sel[j];
  }
  double *x = malloc(2 * (size_t)nmax * sizeof *x), *phi = malloc((size_t)nmax * sizeof *phi);
  int *tri = malloc(3 * (size_t)tmax * sizeof *tri), cur = -2;
  ves_status st = x && phi && tri ? box_extent(io, &pn->LR, &pn->LZ) : VES_ERR_ALLOC;
  double rmax = 0, zlo = INFINITY, zhi = -INFINITY;
  for (int j = 0; j < nsel && st == VES_OK; j++) {
    ves_io_snapinfo si;
    int nk, tk;
    if ((st = snapshot_triangles(io, sel[j], tri, &cur, &nk, &tk)) != VES_OK ||
        (st = ves_io_read_snapshot_n(io, sel[j], nk, NULL, x, phi, &si)) != VES_OK)
      break;
    pn->t[j] = si.state.t, pn->n[j] = nk;
    ves_level_set_curves c = {0};
    if (in->format_version < 2 || ves_level_set_curves_eval(nk, tk, tri, x, phi, &c) != VES_OK ||
        c.npieces < 1) {
      ves_level_set_curves_free(&c); /* no x, or NaN in it: no curve */
      continue;
    }
    pn->curve[j] = 1;
    fprintf(f, "$curve%d << EOD\n", j);
    for (int i = 0; i < c.npieces; i++) {
      if (i) fputc('\n', f);
      for (int q = c.start[i]; q < c.start[i + 1]; q++) {
        const double r = c.rz[2 * q], z = c.rz[2 * q + 1];
        fprintf(f, "%.6g %.6g\n", r, z);
        rmax = fmax(rmax, fabs(r)), zlo = fmin(zlo, z), zhi = fmax(zhi, z);
      }
    }
    fprintf(f, "EOD\n");
    ves_level_set_curves_free(&c);
  }
  if (st == VES_OK && rmax > 0 && zhi >= zlo) {
    const double m = PLOT_MARGIN * fmax(rmax, 0.5 * (zhi - zlo));
    pn->VR = fmin(pn->LR, rmax + m), pn->Z0 = fmax(-pn->LZ, zlo - m);
    pn->Z1 = fmin(pn->LZ, zhi + m);
  } else {
    pn->VR = pn->LR, pn->Z0 = -pn->LZ, pn->Z1 = pn->LZ;
  }
  for (int j = 0; j < nsel && st == VES_OK; j++) {
    if ((st = ves_io_read_snapshot_n(io, sel[j], pn->n[j], NULL, x, phi, NULL)) != VES_OK) break;
    const double dr = 0.02 * pn->VR, dz = 0.02 * (pn->Z1 - pn->Z0); /* points on the border */
    fprintf(f, "$snap%d << EOD\n", j);
    for (int a = 0; a < pn->n[j]; a++)
      if (fabs(x[2 * a]) <= pn->VR + dr && x[2 * a + 1] >= pn->Z0 - dz &&
          x[2 * a + 1] <= pn->Z1 + dz)
        fprintf(f, "%.6g %.6g %.4g\n", x[2 * a], x[2 * a + 1], phi[a]);
    fprintf(f, "NaN NaN NaN\nEOD\n"); /* never empty: an empty datablock stops gnuplot */
  }
  free(x), free(phi), free(tri);
  return st;
}

/* A multiplot of np shape panels: its layout and canvas (PLOT_PANEL
 * pixels on the view's longer side, room for the labels and the colour
 * bar) and the axes: the meridian plane mirrored at r = 0, at equal scale,
 * phi's palette with its colour bar labelled. The pixels of a panel's
 * height (its data area). */
static int panels_begin(FILE *f, const ves_plot_params *p, int fig, const panels *pn, int np,
                        const char *title, int extra_top) {
  const int cols = np <= 3 ? np : np == 4 ? 2 : (np + 1) / 2, rows = (np + cols - 1) / cols;
  const double a = 2 * pn->VR / (pn->Z1 - pn->Z0); /* the view's width / height */
  const int pw = a >= 1 ? PLOT_PANEL : (int)(PLOT_PANEL * a),
            ph = a >= 1 ? (int)(PLOT_PANEL / a) : PLOT_PANEL;
  const int w = cols * (pw + 190) > PLOT_MIN_WIDTH ? cols * (pw + 190) : PLOT_MIN_WIDTH;
  gp_terminal(f, p, fig, w, rows * (ph + 120 + extra_top) + 50, 11);
  fprintf(f, "set multiplot layout %d,%d title ", rows, cols);
  ves_plot_gp_quote(f, title);
  fprintf(f,
          "\nset size ratio -1\nset xrange [%.6g:%.6g]\nset yrange [%.6g:%.6g]\n"
          "set palette defined (-1 '#3b4cc0', 0 '#aaaaaa', 1 '#b40426')\nset cbrange [-1:1]\n"
          "set cbtics 0.5\nset cblabel '{/Symbol f} at the nodes'\n"
          "set xlabel 'r / R_0'\nset ylabel 'z / R_0'\nunset key\n",
          -pn->VR, pn->VR, pn->Z0, pn->Z1);
  return ph;
}

/* The plot command's node points and phi = 0 curve of panel j (the
 * first panel's curve dashed under it when ref), mirrored at r = 0. */
static void panel_layers(FILE *f, const panels *pn, int j, double ps, int ref) {
  fprintf(f,
          "plot $snap%d using 1:2:3 with points pt 7 ps %.3f lc palette, "
          "$snap%d using (-$1):2:3 with points pt 7 ps %.3f lc palette",
          j, ps, j, ps);
  if (ref && pn->curve[0])
    fprintf(f, ", $curve0 using 1:2 with lines dt 2 lw 1.5 lc rgb '#606060', "
               "$curve0 using (-$1):2 with lines dt 2 lw 1.5 lc rgb '#606060'");
  if (pn->curve[j])
    fprintf(f,
            ", $curve%d using 1:2 with lines lw 2 lc rgb 'black', "
            "$curve%d using (-$1):2 with lines lw 2 lc rgb 'black'",
            j, j);
}

/* The nodes' points: smaller as the nodes in view multiply. */
static double point_size(const panels *pn, int j) {
  const double box = 4 * pn->LR * pn->LZ, view = 2 * pn->VR * (pn->Z1 - pn->Z0);
  return fmin(0.5, 0.3 * sqrt(1500.0 / (pn->n[j] * view / box)));
}

/* Node snapshots coloured by phi with their phi = 0 curve (black; the
 * first snapshot's dashed grey over the later ones), mirrored at r = 0. */
static void fig_snapshots(FILE *f, const ves_plot_params *p, const ves_io_info *in,
                          const panels *pn) {
  char title[512], stem[96], ref[96] = "";
  title_stem(stem, sizeof stem, p);
  if (pn->nsel > 1 && pn->curve[0])
    snprintf(ref, sizeof ref, "; dashed grey: {/Symbol f} = 0 at t* = %.4g", pn->t[0]);
  snprintf(title, sizeof title,
           "%s: %s coloured by {/Symbol f} (%d nodes, mirrored at r = 0)\nblack: {/Symbol f} = 0%s",
           stem,
           in->format_version >= 2 ? "material at the nodes, y(X_a, t),"
                                   : "nodal coefficients y^a(t)",
           pn->n[pn->nsel - 1], ref);
  (void)panels_begin(f, p, 1, pn, pn->nsel, title, 0);
  for (int j = 0; j < pn->nsel; j++) {
    fprintf(f, "set title 't* = %.4g%s'\n", pn->t[j],
            pn->curve[j] ? "" : " (no {/Symbol f} = 0 curve)");
    panel_layers(f, pn, j, point_size(pn, j), j > 0);
    fputc('\n', f);
  }
  fprintf(f, "unset multiplot\n");
}

/* The node of each arrow cell (nr x nz cells of side cell over [0, nr
 * cell] x [z0, z0 + nz cell]): the one nearest the cell's centre among the
 * n nodes at x with a finite velocity v, or -1, into pick. */
static void flow_pick(const double *x, const double *v, int n, int nr, int nz, double cell,
                      double z0, int *pick) {
  const int nc = nr * nz;
  for (int c = 0; c < nc; c++) pick[c] = -1;
  for (int a = 0; a < n; a++) {
    const double r = x[2 * a], z = x[2 * a + 1];
    if (!(r >= 0 && r < nr * cell && z >= z0 && z < z0 + nz * cell) || !isfinite(v[2 * a]) ||
        !isfinite(v[2 * a + 1]))
      continue;
    const int ir = (int)(r / cell), iz = (int)((z - z0) / cell), c = iz * nr + ir;
    if (ir >= nr || iz >= nz) continue;
    const double cr = (ir + 0.5) * cell, cz = z0 + (iz + 0.5) * cell;
    if (pick[c] < 0 || hypot(r - cr, z - cz) < hypot(x[2 * pick[c]] - cr, x[2 * pick[c] + 1] - cz))
      pick[c] = a;
  }
}

/* The largest of 1, 2, 5 x 10^k not above v (> 0): the scale arrow's speed. */
static double nice_below(double v) {
  const double d = pow(10, floor(log10(v)));
  return v >= 5 * d ? 5 * d : v >= 2 * d ? 2 * d : d;
}

/* The flow at the selected snapshots that store one (paper Fig. 5): the
 * nodes and phi = 0 curve as fig_snapshots, and arrows of the velocity at
 * the nodes (ves_io_read_snapshot_velocity) on a grid of square cells,
 * PLOT_ARROW_CELLS along the view's longer side: in each cell the node
 * nearest its centre, so the arrows are evenly spread however the nodes
 * are graded. One scale for all panels: the fastest arrow of the figure
 * is 0.9 of a cell long; a scale arrow above each panel states it in R0
 * per t*; arrows under PLOT_ARROW_MIN of a cell are left out (a panel
 * whose flow is all slower says so). Mirrored at r = 0 as the points (v_r
 * changes sign). A snapshot without a velocity (the first; a file that
 * stores none) has no panel; when none of the selected has one, the last
 * of them is drawn alone, titled so. The points and curves are
 * panels_write's datablocks. */
static ves_status fig_flow(FILE *f, ves_io *io, const ves_plot_params *p, const panels *pn) {
  int nmax = ves_io_get_info(io)->n;
  for (int j = 0; j < pn->nsel; j++) nmax = pn->n[j] > nmax ? pn->n[j] : nmax;
  const double cell = fmax(2 * pn->VR, pn->Z1 - pn->Z0) / PLOT_ARROW_CELLS;
  const int nr = (int)ceil(pn->VR / cell), nz = (int)ceil((pn->Z1 - pn->Z0) / cell), nc = nr * nz;
  double *x = malloc(2 * (size_t)nmax * sizeof *x), *v = malloc(2 * (size_t)nmax * sizeof *v);
  double *arrows = malloc(4 * (size_t)VES_PLOT_MAXTIMES * (nc > 0 ? nc : 1) * sizeof *arrows);
  int *pick = malloc((size_t)(nc > 0 ? nc : 1) * sizeof *pick);
  int panel[VES_PLOT_MAXTIMES], narrow[VES_PLOT_MAXTIMES], np = 0;
  double vmax[VES_PLOT_MAXTIMES], vall = 0;
  ves_status st = x && v && arrows && pick ? VES_OK : VES_ERR_ALLOC;
  for (int j = 0; j < pn->nsel && st == VES_OK; j++) {
    const int got = ves_io_read_snapshot_velocity(io, pn->sel[j], pn->n[j], v);
    if (got < 0) st = (ves_status)got;
    if (got <= 0) continue;
    if ((st = ves_io_read_snapshot_n(io, pn->sel[j], pn->n[j], NULL, x, NULL, NULL)) != VES_OK)
      break;
    double *w = arrows + 4 * (size_t)np * nc;
    flow_pick(x, v, pn->n[j], nr, nz, cell, pn->Z0, pick);
    vmax[np] = 0, narrow[np] = 0;
    for (int c = 0; c < nc; c++) {
      const int a = pick[c];
      if (a < 0) continue;
      w[4 * narrow[np]] = x[2 * a], w[4 * narrow[np] + 1] = x[2 * a + 1];
      w[4 * narrow[np] + 2] = v[2 * a], w[4 * narrow[np] + 3] = v[2 * a + 1];
      vmax[np] = fmax(vmax[np], hypot(v[2 * a], v[2 * a + 1])), narrow[np]++;
    }
    vall = fmax(vall, vmax[np]);
    panel[np++] = j;
  }
  free(x), free(v), free(pick);
  if (st != VES_OK) {
    free(arrows);
    return st;
  }
  /* the arrows, scaled alike: 0.9 cell for the fastest of all panels */
  const double scale = vall > 0 ? 0.9 * cell / vall : 0, ref = vall > 0 ? nice_below(vall) : 0;
  int drawn[VES_PLOT_MAXTIMES];
  for (int i = 0; i < np; i++) {
    const double *w = arrows + 4 * (size_t)i * nc;
    drawn[i] = 0;
    for (int q = 0; q < narrow[i]; q++)
      if (scale * hypot(w[4 * q + 2], w[4 * q + 3]) >= PLOT_ARROW_MIN * cell) {
        if (!drawn[i]++) fprintf(f, "$flowv%d << EOD\n", panel[i]);
        fprintf(f, "%.5g %.5g %.3g %.3g\n", w[4 * q], w[4 * q + 1], scale * w[4 * q + 2],
                scale * w[4 * q + 3]); /* a drawing's precision */
      }
    if (drawn[i]) fprintf(f, "EOD\n");
  }
  free(arrows);
  char title[512], stem[96];
  title_stem(stem, sizeof stem, p);
  if (np == 0) { /* no selected snapshot stores a flow: the last one, said so */
    snprintf(title, sizeof title,
             "%s: no flow stored at the chosen snapshots (at t* = 0 none is; a file may store "
             "none)\n{/Symbol f} (colour), {/Symbol f} = 0 (black)",
             stem);
    (void)panels_begin(f, p, 3, pn, 1, title, 0);
    fprintf(f, "set title 't* = %.4g'\n", pn->t[pn->nsel - 1]);
    panel_layers(f, pn, pn->nsel - 1, 0.6 * point_size(pn, pn->nsel - 1), 0);
    fprintf(f, "\nunset multiplot\n");
    return VES_OK;
  }
  snprintf(title, sizeof title,
           "%s: flow at the nodes (arrows), {/Symbol f} (colour), {/Symbol f} = 0 (black)\n"
           "one arrow scale for all panels: length 0.1 R_0 = speed %.3g R_0/t*; "
           "slower than %.2g R_0/t*: not drawn",
           stem, scale > 0 ? 0.1 / scale : 0, PLOT_ARROW_MIN * cell / (scale > 0 ? scale : 1));
  /* above each panel its title, then the scale arrow: placed in graph units
   * from the panel's height in pixels (character offsets differ between
   * the terminals) */
  const int ph = panels_begin(f, p, 3, pn, np, title, 40);
  const double above = 1 + 14.0 / ph, up = 40.0 / ph;
  fprintf(f, "set tmargin 6\n");
  const double L = scale * ref; /* the scale arrow's length (R0) */
  for (int i = 0; i < np; i++) {
    const int j = panel[i];
    if (vall > 0) {
      fprintf(f,
              "set arrow 1 from first %.6g, graph %.4f rto first %.6g, first 0 head filled "
              "size screen 0.006,20 lw 1.2 lc rgb 'black'\n"
              "set label 1 'scale: %.3g R_0/t*' at first %.6g, graph %.4f left offset 1,0\n",
              -pn->VR, above, L, ref, -pn->VR + L, above);
    }
    if (drawn[i])
      fprintf(f, "set title \"t* = %.4g, fastest node %.3g R_0/t*\" offset graph 0,%.4f\n",
              pn->t[j], vmax[i], up);
    else
      fprintf(f,
              "set title \"t* = %.4g, fastest node %.3g R_0/t*\\n(slower than the arrows "
              "show)\" offset graph 0,%.4f\n",
              pn->t[j], vmax[i], up);
    panel_layers(f, pn, j, 0.6 * point_size(pn, j), 0);
    if (drawn[i])
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

/* The volume target at time tk: V_target of the series row nearest to it
 * (a snapshot's time is its step's), V0 at t* = 0 without a row there. */
static double target_at(long R, const double *t, const double *Vt, double V0, double tk) {
  long best = 0;
  for (long i = 1; i < R; i++)
    if (fabs(t[i] - tk) < fabs(t[best] - tk)) best = i;
  return tk <= 0 && t[best] > 0 ? V0 : Vt[best];
}

/* Constraint drift and the drift of the nodes' sharp interface (ls, ok at
 * the S snapshots at times T) against t*, and the volume
 * protocol V/V0 with its target when the target varies; a target constant
 * to rounding (PLOT_ROUNDING) leaves that panel out and the title says so
 * (the drift panel shows |V/V0 - 1| then). The interface's volume follows
 * the target: its drift is |V_I/V_I(0) - V_target/V_0| (V_target of the
 * snapshot's step; V0 at step 0). Legends below the panels. */
static void fig_constraints(FILE *f, const ves_plot_params *p, const ves_io_info *in, long R,
                            const double *t, const double *A, const double *V, const double *Vt,
                            int S, const double *T, const ves_level_set *ls,
                            const unsigned char *ok) {
  double dvt = 0, dv = 0, da = 0;
  fprintf(f, "$drift << EOD\n");
  for (long i = 0; i < R; i++) {
    dvt = fmax(dvt, fabs(Vt[i] / in->V0 - 1));
    dv = fmax(dv, fabs(V[i] / Vt[i] - 1)), da = fmax(da, fabs(A[i] / in->A0 - 1));
    if (t[i] > 0) /* t* = 0 has no place on the log axis */
      fprintf(f, "%.10g %.6e %.6e %.12g %.12g\n", t[i], fmax(fabs(A[i] / in->A0 - 1), PLOT_FLOOR),
              fmax(fabs(V[i] / Vt[i] - 1), PLOT_FLOOR), V[i] / in->V0, Vt[i] / in->V0);
  }
  fprintf(f, "NaN NaN NaN NaN NaN\nEOD\n$iface << EOD\n");
  int k0 = 0; /* the first snapshot with an interface is the reference */
  while (k0 < S && !ok[k0]) k0++;
  const double vt0 = k0 < S ? target_at(R, t, Vt, in->V0, T[k0]) / in->V0 : 1;
  for (int k = k0 + 1; k < S; k++)
    if (ok[k] && T[k] > 0) {
      const double vt = target_at(R, t, Vt, in->V0, T[k]) / in->V0;
      fprintf(f, "%.10g %.6e %.6e\n", T[k], fmax(fabs(ls[k].area / ls[k0].area - 1), PLOT_FLOOR),
              fmax(fabs(ls[k].volume / ls[k0].volume - vt / vt0), PLOT_FLOOR));
    }
  fprintf(f, "NaN NaN NaN\nEOD\n"); /* never empty: an empty datablock stops gnuplot */
  const int vpanel = dvt > PLOT_ROUNDING;
  gp_terminal(f, p, 2, 900, vpanel ? 1000 : 640, 12);
  fprintf(f, "set multiplot layout %d,1 title ", vpanel ? 2 : 1);
  char title[512], stem[96];
  title_stem(stem, sizeof stem, p);
  if (vpanel)
    snprintf(title, sizeof title, "%s: constraints (values below %g drawn at %g)", stem, PLOT_FLOOR,
             PLOT_FLOOR);
  else
    snprintf(title, sizeof title,
             "%s: constraints (values below %g drawn at %g)\nV_{target} = V_0 at every step%s: "
             "no V/V_0 panel; max |V/V_0 - 1| = %.1e, max |A/A_0 - 1| = %.1e",
             stem, PLOT_FLOOR, PLOT_FLOOR, dvt > 0 ? " (to rounding)" : "", dv, da);
  ves_plot_gp_quote(f, title);
  fputc('\n', f);
  time_axis(f, R, t);
  fprintf(f, "set lmargin 12\nset logscale y\nset format y '10^{%%L}'\n"
             "set ylabel 'relative drift'\nset key below horizontal maxcols 2 width -4\n");
  if (!vpanel) fprintf(f, "set xlabel 't* = t k / ({/Symbol m} R_0^3)'\n");
  fprintf(f, "plot $drift using 1:2 with linespoints pt 7 ps 0.5 lc rgb '#b40426' "
             "title '|A/A_0 - 1|', "
             "$drift using 1:3 with linespoints pt 5 ps 0.5 lc rgb '#3b4cc0' "
             "title '|V/V_{target} - 1|', "
             "$iface using 1:2 with points pt 6 ps 1 lc rgb '#b40426' "
             "title 'interface area: |A_I/A_I(0) - 1|', "
             "$iface using 1:3 with points pt 4 ps 1 lc rgb '#3b4cc0' "
             "title 'interface volume: |V_I/V_I(0) - V_{target}/V_0|'\n");
  if (vpanel)
    fprintf(f,
            "unset logscale y\nset format y '%%g'\nset ylabel 'V / V_0'\n"
            "set offsets 0, 0, graph 0.05, graph 0.05\n"
            "set xlabel 't* = t k / ({/Symbol m} R_0^3)'\nset key below horizontal width 2\n"
            "plot $drift using 1:4 with linespoints pt 7 ps 0.5 lc rgb '#3b4cc0' title 'V/V_0', "
            "$drift using 1:5 with lines dt 2 lw 2 lc rgb 'black' title 'target V_{target}/V_0'\n");
  fprintf(f, "unset multiplot\n");
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
    if (fig_complete(part, p->format, why, sizeof why)) {
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

/* The script to keep, at p->script: the one gnuplot runs, its first line
 * (part = '.part') made part = '' so that it writes the figures' own
 * names. Written to SCRIPT.part, renamed by ves_plot_write once the
 * figures are in place. */
static ves_status script_copy(const char *script, const ves_plot_params *p, char *err,
                              size_t errlen) {
  char part[PATH_MAX + 8], buf[65536];
  snprintf(part, sizeof part, "%s.part", p->script);
  errno = 0;
  FILE *in = fopen(script, "r"), *out = in ? fopen(part, "w") : NULL;
  int bad = !in || !out;
  if (!bad) {
    bad = !fgets(buf, sizeof buf, in) || fputs("part = ''\n", out) < 0;
    for (size_t k; !bad && (k = fread(buf, 1, sizeof buf, in)) > 0;)
      bad = fwrite(buf, 1, k, out) != k;
    bad |= ferror(in);
  }
  if (in) fclose(in);
  if (out) bad |= fclose(out) != 0;
  if (bad) {
    ves_error_say(err, errlen, "--script %s: cannot write: %s", p->script,
                  errno ? strerror(errno) : "a write failed");
    unlink(part);
    return VES_ERR_IO;
  }
  return VES_OK;
}

ves_status ves_plot_write(ves_io *io, const ves_plot_params *p, char *err, size_t errlen) {
  VES_CHECK(io && p && p->outdir && p->stem && p->ntimes >= 0 && p->ntimes <= VES_PLOT_MAXTIMES &&
                p->format >= 0 && p->format < VES_PLOT_NFORMAT,
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
  /* the first line names the figures' suffix while they are written
   * (script_keep rewrites it) */
  fprintf(f, "part = '.part'\n# vesica plot: the figures of %s (gnuplot; data inline)\n", p->stem);
  fig_energy(f, p, in, R, t, dt, E);
  panels pn;
  if ((st = panels_write(f, io, sel, nsel, &pn)) != VES_OK) goto done;
  fig_snapshots(f, p, in, &pn);
  fig_constraints(f, p, in, R, t, A, V, Vt, S, T, ls, ok);
  if ((st = fig_flow(f, io, p, &pn)) != VES_OK) goto done;
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  f = NULL;
  if (bad) {
    ves_error_say(err, errlen, "cannot write the gnuplot script %s", script);
    st = VES_ERR_IO;
    goto done;
  }
  if ((st = ves_plot_run_gnuplot(script, err, errlen)) != VES_OK) goto done;
  if (p->script && (st = script_copy(script, p, err, errlen)) != VES_OK) goto done;
  if ((st = figures_commit(p, err, errlen)) != VES_OK) goto done;
  if (p->script) {
    char part[PATH_MAX + 8];
    snprintf(part, sizeof part, "%s.part", p->script);
    if (rename(part, p->script) != 0) {
      ves_error_say(err, errlen, "--script: cannot rename %s to %s: %s", part, p->script,
                    strerror(errno));
      st = VES_ERR_IO;
    }
  }
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
  if (p->script) { /* nor a partial script */
    char part[PATH_MAX + 8];
    snprintf(part, sizeof part, "%s.part", p->script);
    unlink(part);
  }
  if (f) fclose(f);
  if (script[0]) unlink(script);
  free(buf), free(T), free(ls), free(ok);
  return st;
}
