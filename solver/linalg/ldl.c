/* vesica — the sparse symmetric direct solver on sequential MUMPS: A = L D L^T
 * (indefinite, 2x2 pivots) or A = L L^T (positive definite) of a matrix given
 * by its lower triplets, factored in double or in single precision (then
 * each solve is refined against the double values: ldl_refine.c), with the
 * workspace kept across factorizations and the fallback from single to
 * double precision. The KKT systems and the L2 projection solve with it
 * (docs/design.md, "Numerical choices and why"). Knows only status codes. */
#include "linalg/ldl_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/mem_impl.h"

/* ---- MUMPS LDL^T ---- */

#define ICNTL(i) icntl[(i)-1] /* MUMPS documents its controls 1-based */
#define INFOG(i) infog[(i)-1]
#define INFO(i) info[(i)-1]
#define JOB_INIT (-1)
#define JOB_END (-2)
#define JOB_ANALYSE 1
#define JOB_FACTOR 2
#define JOB_SOLVE 3
#define USE_COMM_WORLD (-987654) /* the Fortran MPI_COMM_WORLD of the sequential fake MPI */
#define LDL_SINGLE_PIVOT 0.0 /* single precision LDL^T: MUMPS's CNTL(1), no numerical pivoting */

/* Run one MUMPS job and record INFOG(1), INFOG(2). */
static void mumps_run(ves_ldl *f, int job) {
  if (f->single)
    f->sid.job = job, smumps_c(&f->sid);
  else
    f->did.job = job, dmumps_c(&f->did);
  f->info_.infog1 = f->INFOG(1);
  f->info_.infog2 = f->INFOG(2);
}
/* Our status for a MUMPS INFOG(1) (>= 0: ok; warnings are not errors). */
static ves_status mumps_status(int infog1) {
  if (infog1 >= 0) return VES_OK;
  switch (infog1) {
  case -6:  /* structurally singular */
  case -10: /* numerically singular, or (SYM = 1) a non-positive pivot */
    return VES_ERR_SINGULAR;
  case -7:  /* integer allocation failed */
  case -13: /* Fortran ALLOCATE failed */
    return VES_ERR_ALLOC;
  default:
    return VES_ERR_SOLVER;
  }
}

void ves_ldl_destroy(ves_ldl **f) {
  if (!f || !*f) return;
  if ((*f)->live) mumps_run(*f, JOB_END);
  free((*f)->irn), free((*f)->jcn);
  free((*f)->as), free((*f)->xs), free((*f)->b), free((*f)->r);
  free((*f)->V), free((*f)->Z), free((*f)->yc);
  free((*f)->wk);
  free(*f);
  *f = NULL;
}

/* The workspace for the next factorization: INFO(8) of the analysis (its
 * in-core estimate, f->est) with ICNTL(14) percent of room, as MUMPS
 * sizes its own; LWK_USER in entries, or in millions (< 0) beyond an int. */
static ves_status workspace(ves_ldl *f) {
  double want = f->est * (1 + f->ICNTL(14) / 100.0) + 1;
  if (want > 2e9) want = 1e6 * ceil(want / 1e6); /* LWK_USER counted in millions */
  if ((size_t)want <= f->lwk && f->wk) return VES_OK;
  free(f->wk);
  f->lwk = 0;
  f->wk = ves_big_alloc((size_t)want * (f->single ? sizeof(float) : sizeof(double)));
  if (!f->wk) return VES_ERR_ALLOC;
  f->lwk = (size_t)want;
  const int lwk = want > 2e9 ? -(int)(want / 1e6) : (int)want;
  if (f->single)
    f->sid.wk_user = f->wk, f->sid.lwk_user = lwk;
  else
    f->did.wk_user = f->wk, f->did.lwk_user = lwk;
  return VES_OK;
}

/* Set one field of the live MUMPS instance. */
#define ID_SET(f, field, v)                                                                        \
  do {                                                                                             \
    if ((f)->single)                                                                               \
      (f)->sid.field = (v);                                                                        \
    else                                                                                           \
      (f)->did.field = (v);                                                                        \
  } while (0)

/* Start the MUMPS instance of f's precision, set its controls and analyse
 * the pattern (JOB = -1, then 1). */
static ves_status mumps_setup(ves_ldl *f) {
  if (f->single)
    f->icntl = f->sid.icntl, f->infog = f->sid.infog, f->info = f->sid.info;
  else
    f->icntl = f->did.icntl, f->infog = f->did.infog, f->info = f->did.info;
  ID_SET(f, sym, f->spd ? 1 : 2); /* 1: SPD (Cholesky), 2: general symmetric (LDL^T, 2x2 pivots) */
  ID_SET(f, par, 1);              /* the host works */
  ID_SET(f, comm_fortran, USE_COMM_WORLD);
  mumps_run(f, JOB_INIT);
  ves_status s = mumps_status(f->info_.infog1);
  if (s != VES_OK) return s;
  f->live = 1;
  f->ICNTL(1) = -1; /* no error messages */
  f->ICNTL(2) = -1; /* no diagnostics */
  f->ICNTL(3) = -1; /* no global information */
  f->ICNTL(4) = 0;  /* print level: nothing */
  f->info_.icntl14 = f->ICNTL(14);
  /* ordering: approximate minimum fill. On the projection matrix at eps =
   * 0.01 (21k nodes, 2.9M entries) its analysis takes 0.15 s against 2.5 s for
   * the default choice (SCOTCH), and the factors come out 8% smaller
   * (docs/results.md, "Performance and its scaling"). */
  f->ICNTL(7) = 2;
  /* symmetric indefinite (the KKT matrices): no maximum weighted matching
   * (ICNTL(6) = 0) and the plain ordering of the graph (ICNTL(12) = 1)
   * instead of the compressed one built on the matching. On the Newton KKT
   * matrix at eps = 0.02 (25k unknowns) the analysis takes 0.7 s against
   * 3-4 s, the factorization ~15% less, the factors are the same size
   * (docs/results.md, "Performance and its scaling"); the pivoting within the fronts,
   * and so the inertia, are unaffected. */
  if (!f->spd) {
    f->ICNTL(6) = 0;
    f->ICNTL(12) = 1;
  }
  /* single precision LDL^T without numerical pivoting (CNTL(1) = 0, MUMPS's
   * default being 0.01): the KKT matrices are K/dt + Hess E (positive
   * definite on the constraints' null space, mostly positive definite)
   * bordered by the two dense constraint rows, which the ordering puts last,
   * where their pivots are the Schur complement -J H^-1 J^T. Without the
   * pivot searches the factorization of the eps 0.02 KKT matrix takes 0.77 s
   * against 0.97 s with them (docs/results.md, "Performance and its
   * scaling"); the inertia is still the pivots' signs (Sylvester), and a
   * factorization that meets a zero pivot, or whose solve cannot be refined
   * against the double values, is redone in double precision, with pivoting
   * (ldl_to_double). */
  if (!f->spd && f->single) f->sid.cntl[0] = (float)LDL_SINGLE_PIVOT;
  ID_SET(f, n, f->n);
  ID_SET(f, nnz, f->nnz);
  ID_SET(f, nz, f->nnz); /* the deprecated 32-bit count, kept consistent */
  ID_SET(f, irn, f->irn);
  ID_SET(f, jcn, f->jcn);
  /* values for the analysis: the last factorization's (a switch of
   * precision), else zeros for the while (none is read without a matching
   * or scaling at analysis, but MUMPS is given an array) */
  double *zero = NULL;
  if (f->single)
    f->sid.a = f->as;
  else if (f->a)
    f->did.a = (double *)f->a;
  else if (!(f->did.a = zero = calloc((size_t)f->nnz, sizeof *zero)))
    return VES_ERR_ALLOC;
  mumps_run(f, JOB_ANALYSE);
  if (zero) f->did.a = NULL, free(zero);
  if ((s = mumps_status(f->info_.infog1)) != VES_OK) return s;
  f->est = f->INFO(8) >= 0 ? (double)f->INFO(8) : -1e6 * f->INFO(8); /* < 0: millions */
  return VES_OK;
}

ves_status ves_ldl_create(int n, int nnz, const int *irow, const int *jcol, int spd,
                          ves_ldl **out) {
  return ves_ldl_create_prec(n, nnz, irow, jcol, spd, 0, out);
}

ves_status ves_ldl_create_prec(int n, int nnz, const int *irow, const int *jcol, int spd,
                               int single, ves_ldl **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(n > 0 && nnz > 0 && irow && jcol, VES_ERR_ARG);
  for (int k = 0; k < nnz; k++)
    VES_CHECK(irow[k] >= 0 && irow[k] < n && jcol[k] >= 0 && jcol[k] <= irow[k], VES_ERR_ARG);
  ves_status s = VES_ERR_ALLOC;
  ves_ldl *f = calloc(1, sizeof *f);
  if (!f) return VES_ERR_ALLOC;
  f->single = f->prefer_single = single != 0, f->spd = spd != 0;
  f->n = n, f->nnz = nnz;
  f->irn = malloc((size_t)nnz * sizeof *f->irn);
  f->jcn = malloc((size_t)nnz * sizeof *f->jcn);
  if (!f->irn || !f->jcn) goto fail;
  if (f->single) {
    f->as = ves_big_calloc((size_t)nnz, sizeof *f->as);
    f->xs = malloc((size_t)n * sizeof *f->xs);
    f->b = malloc((size_t)n * sizeof *f->b);
    f->r = malloc((size_t)n * sizeof *f->r);
    f->yc = malloc((size_t)LDL_MATVEC_CHUNKS * n * sizeof *f->yc);
    if (!f->as || !f->xs || !f->b || !f->r || !f->yc) goto fail;
  }
  for (int k = 0; k < nnz; k++) f->irn[k] = irow[k] + 1, f->jcn[k] = jcol[k] + 1; /* 1-based */
  if ((s = mumps_setup(f)) != VES_OK) goto fail;
  *out = f;
  return VES_OK;
fail:
  ves_ldl_destroy(&f);
  return s;
}

/* A new MUMPS instance of the other precision on the same pattern (JOB =
 * -2 for the old one, then -1 and the analysis); the workspace is
 * reallocated at the next factorization. */
static ves_status switch_precision(ves_ldl *f, int single) {
  mumps_run(f, JOB_END);
  f->live = 0, f->single = single, f->factored = 0;
  free(f->wk), f->wk = NULL, f->lwk = 0;
  return mumps_setup(f);
}

/* Factor the values in f->a (JOB = 2), more workspace on INFOG(1) = -8/-9. */
static ves_status factor_values(ves_ldl *f) {
  if (f->single)
    for (int k = 0; k < f->nnz; k++) f->as[k] = (float)f->a[k];
  f->factored = 0;
  f->info_.retries = 0;
  for (;;) {
    VES_CALL(workspace(f));
    mumps_run(f, JOB_FACTOR);
    int e = f->info_.infog1;
    if ((e != -8 && e != -9) || f->info_.retries == VES_LDL_MAX_RETRIES) break;
    f->ICNTL(14) = 2 * f->ICNTL(14) + 20; /* relaxation percent: 20 -> 60 -> 140 -> 300 */
    f->info_.icntl14 = f->ICNTL(14);
    f->info_.retries++;
  }
  ves_status s = mumps_status(f->info_.infog1);
  f->info_.neg_pivots = f->INFOG(12);
  /* SYM = 1 is an LDL^T without pivoting: an indefinite matrix factors
   * "successfully" with negative pivots. Not SPD counts as singular here. */
  if (s == VES_OK && f->spd && f->info_.neg_pivots > 0) s = VES_ERR_SINGULAR;
  int e29 = f->INFOG(29); /* real entries in the factors; < 0: millions */
  f->info_.factor_entries = s == VES_OK ? (e29 >= 0 ? (double)e29 : -1e6 * e29) : 0.0;
  f->factored = s == VES_OK;
  return s;
}

/* The single precision factors failed (float values singular or
 * overflowing) or could not give |b - A x| <= tol |b| in a solve: this
 * factorization is redone in double precision (a new analysis); the next
 * one is single again (ves_ldl_factor). */
ves_status ldl_to_double(ves_ldl *f) {
  f->info_.fallbacks++;
  VES_CALL(switch_precision(f, 0));
  return factor_values(f);
}

ves_status ves_ldl_factor(ves_ldl *f, const double *val) {
  VES_CHECK(f && val, VES_ERR_ARG);
  f->a = val;
  if (!f->single) f->did.a = (double *)val; /* MUMPS reads, never writes, A */
  if (f->prefer_single && !f->single) VES_CALL(switch_precision(f, 1)); /* after a fallback */
  ves_status s = factor_values(f);
  if (s == VES_OK || s == VES_ERR_ALLOC || !f->single) return s;
  return ldl_to_double(f); /* the values rounded to float are singular or overflow */
}

/* One MUMPS solve (JOB = 3) of the live instance, in place on x[n]. */
ves_status ldl_mumps_solve(ves_ldl *f, double *x) {
  ID_SET(f, nrhs, 1);
  ID_SET(f, lrhs, f->n);
  f->ICNTL(20) = 0; /* dense right-hand side */
  f->ICNTL(21) = 0; /* solution centralized, overwriting rhs */
  if (f->single) {
    for (int i = 0; i < f->n; i++) f->xs[i] = (float)x[i];
    f->sid.rhs = f->xs;
  } else {
    f->did.rhs = x;
  }
  mumps_run(f, JOB_SOLVE);
  ID_SET(f, rhs, NULL); /* borrowed for this call only */
  if (f->single)
    for (int i = 0; i < f->n; i++) x[i] = f->xs[i];
  ves_status s = mumps_status(f->info_.infog1);
  return s == VES_ERR_SINGULAR ? VES_ERR_SOLVER : s;
}

int ves_ldl_size(const ves_ldl *f) { return f ? f->n : 0; }

void ves_ldl_get_info(const ves_ldl *f, ves_ldl_info *info) {
  if (f && info) *info = f->info_, info->single = f->single;
}
