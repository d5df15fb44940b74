/* vesica — the KKT matrix of a step problem (step.h), factorized by MUMPS
 * (ldl.h), shared by the newton and euler backends and the analysis of the
 * linearized flow (spectrum.h):
 *
 *   [ H + delta K   J^T ] [ dx ]   [ r1 ]
 *   [ J             D   ] [ dl ] = [ r2 ]
 *
 * over nvar + 2 unknowns, H in the step Hessian pattern (lower triplets), two
 * dense constraint rows always present, D = 0 on a held constraint's row and
 * D = -1 (with a zero J row) on an unused one, so the structure does not
 * depend on which constraints a step holds and the MUMPS analysis is done once.
 * The inertia of a good KKT matrix is then always (nvar, 2 negative, 0):
 * a held row contributes one negative eigenvalue (J of full row rank, H
 * positive definite on its null space), an unused row its -1.
 * docs/design.md, "Backends". */
#ifndef VES_KKT_H
#define VES_KKT_H

#include "ves/ldl.h"
#include "ves/status.h"
#include "ves/step.h"

#define VES_KKT_NROWS 2 /* constraint rows in the structure (area, volume) */

/* A KKT system: its structure, the values the caller fills (the (1,1)
 * block directly, as H + delta K, or by ves_kkt_fill) and the factorization. */
typedef struct {
  int nvar;     /* free dofs */
  int nh;       /* triplets of the (1,1) block (the step Hessian pattern) */
  int nnz;      /* all triplets: nh + VES_KKT_NROWS (nvar + 1) */
  int *irow;    /* nnz triplet rows (lower triangle) */
  int *jcol;    /* nnz triplet columns */
  double *val;  /* nnz values of the current matrix: the first nh the (1,1) block */
  ves_ldl *ldl; /* MUMPS LDL^T, analysed at create */
  int neg;      /* negative pivots of the last factorization */
} ves_kkt;

/* Structure of s's KKT system into *k: H triplets first, then for each
 * constraint row q = nvar + i the entries (q, 0..nvar-1) and (q, q).
 * Analysis (symmetric indefinite) once; single: the factors in single
 * precision, the solves refined (ldl.h). On failure *k is left zeroed. */
ves_status ves_kkt_create(const ves_step *s, int single, ves_kkt *k);
/* Frees k's arrays and factorization (a zeroed k too) and zeroes it. */
void ves_kkt_destroy(ves_kkt *k);
/* The constraint rows' values: J[ncon x nvar] row-major for the held
 * constraints, D as above; the (1,1) block untouched. */
void ves_kkt_fill_rows(ves_kkt *k, const double *J, int ncon);
/* Values: (1,1) = H + delta K (K may be NULL when delta = 0), the rows as
 * ves_kkt_fill_rows. */
void ves_kkt_fill(ves_kkt *k, const double *H, double delta, const double *K, const double *J,
                  int ncon);
/* Factorize; VES_OK with k->neg the negative pivots, or the ves_ldl error. */
ves_status ves_kkt_factor(ves_kkt *k);
/* Solve in place: rhs[nvar + VES_KKT_NROWS]. */
ves_status ves_kkt_solve(ves_kkt *k, double *rhs);
/* As ves_kkt_solve, single precision factors refined only to
 * |b - A x| <= tol |b| (ves_ldl_solve_tol). */
ves_status ves_kkt_solve_tol(ves_kkt *k, double *rhs, double tol);

#endif
