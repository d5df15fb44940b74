/* vesica — figures of a run (gnuplot: PNG, PDF or SVG through its
 * pngcairo, pdfcairo and svg terminals), read from its HDF5 output:
 *   <stem>_energy.EXT       E* and dt* against t* on a log time axis (the
 *                           paper's Fig. 4)
 *   <stem>_snapshots.EXT    the nodes at chosen times (mirrored across the
 *                           axis: the whole meridian section), coloured by
 *                           phi, with the phi = 0 curve of each (paper Figs.
 *                           3 and 5)
 *   <stem>_constraints.EXT  constraint drift |A/A0 - 1|, |V/V_target - 1|,
 *                           the drift of the sharp interface the nodes show
 *                           (its area and volume against the first
 *                           snapshot's, at every snapshot), and V/V0 against
 *                           t* when the volume target varies
 *   <stem>_flow.EXT         the flow at the nodes as arrows over the nodes
 *                           coloured by phi and the phi = 0 curve, at the
 *                           snapshots' times that store a flow (paper Fig. 5;
 *                           one arrow scale for all panels)
 * gnuplot runs as a child process on a script written to a temporary file;
 * its exit status is checked and its messages returned in err
 * (docs/manual.md; docs/design.md, "The program"). */
#ifndef VES_PLOT_H
#define VES_PLOT_H

#include <stddef.h>
#include <stdio.h>

#include "app/io.h"
#include "ves/level_set.h"
#include "ves/quad.h"
#include "ves/status.h"

#define VES_PLOT_NFIG 4
#define VES_PLOT_MAXTIMES 8 /* snapshot panels at most */
#define VES_PLOT_NFORMAT 3

/* The suffixes of the figures, in the order above ("energy", ...). */
extern const char *const ves_plot_figures[VES_PLOT_NFIG];
/* The figure formats, their file extensions: "png", "pdf", "svg"
 * (ves_plot_params.format indexes it). */
extern const char *const ves_plot_formats[VES_PLOT_NFORMAT];

/* gnuplot text helpers (plot.c, study.c): a single-quoted string written to
 * f ('' stands for '; a line break makes it the expression 'a' . "\n" .
 * 'b'), and s with the control characters of gnuplot's
 * enhanced text escaped into out[n] ("run_1" would print a subscript). */
void ves_plot_gp_quote(FILE *f, const char *s);
void ves_plot_gp_escape(char *out, size_t n, const char *s);
/* Run gnuplot on a script file (plot.c, study.c); its own messages are
 * read back, not printed: on a failure (VES_ERR_IO) err quotes its last
 * message line and the exit status. */
ves_status ves_plot_run_gnuplot(const char *script, char *err, size_t errlen);

typedef struct {
  const char *outdir;              /* existing folder for the figures (borrowed) */
  const char *stem;                /* file-name stem, e.g. "oblate" (borrowed) */
  int ntimes;                      /* number of chosen times (0: automatic, up to 4 spread
                                      over the snapshots on a log time scale) */
  double times[VES_PLOT_MAXTIMES]; /* chosen times (t*): the nearest snapshot each */
  int format;                      /* index into ves_plot_formats (0, the default: PNG) */
  const char *script;              /* NULL, or where the gnuplot script is kept: data
                                      inline, `gnuplot SCRIPT` redraws the figures */
} ves_plot_params;

/* The sharp interface the nodes show at every snapshot k < S of the file:
 * ls[k] = ves_level_set_eval of phi at the nodes on the reference triangles
 * placed at the material positions x (format_version >= 2), ok[k] = 1; ok[k]
 * = 0 where the snapshot has no x and phi (format 1, or a snapshot written
 * with NaN). ls[S] and ok[S] are the caller's (S = ves_io_snapshots). The
 * phase-field A and V are held by the constraints; this geometry is not,
 * and its drift shows a motion the quadrature points no longer resolve
 * (docs/results.md, "Resets and remeshing"). VES_ERR_ALLOC, or the
 * reader's error for an unreadable mesh. */
ves_status ves_plot_interface(ves_io *io, ves_level_set *ls, unsigned char *ok);

/* Write the four figures. VES_ERR_ARG for bad parameters (no rows or no
 * snapshots in the file included: message in err); VES_ERR_IO when a
 * temporary file cannot be written, gnuplot fails (its exit status and
 * first message in err), a figure is not a complete file of its format
 * (gnuplot exits 0 on a full disk) or the kept script cannot be written.
 * Figures are written as NAME.EXT.part and renamed into place only when
 * all four are complete; a failure leaves no .part file, no kept script
 * and the earlier figures unchanged. */
ves_status ves_plot_write(ves_io *io, const ves_plot_params *par, char *err, size_t errlen);

#endif
