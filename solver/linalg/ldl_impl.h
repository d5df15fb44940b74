/* vesica — private: the direct solver object shared by the MUMPS wrapper
 * (ldl.c: analysis, factorization, precision switches, one MUMPS solve) and
 * the single precision solves' refinement (ldl_refine.c: flexible GMRES
 * preconditioned by the single factors). docs/design.md, "Numerical choices
 * and why". */
#ifndef VES_LDL_IMPL_H
#define VES_LDL_IMPL_H

#include <dmumps_c.h>
#include <smumps_c.h>
#include <stddef.h>

#include "ves/ldl.h"

#define LDL_GMRES_M 20      /* single precision: Krylov vectors of the refinement */
#define LDL_GMRES_MAX 60    /* ... and its iterations before the double fallback */
#define LDL_MATVEC_CHUNKS 4 /* the residual's products: fixed chunks of the triplets */

struct ves_ldl {
  int single;                      /* 1: the factors in single precision (SMUMPS), solves refined */
  int spd;                         /* 1: Cholesky (SYM = 1), 0: LDL^T (SYM = 2) */
  DMUMPS_STRUC_C did;              /* the MUMPS instance, double precision */
  SMUMPS_STRUC_C sid;              /* the MUMPS instance, single precision */
  MUMPS_INT *icntl, *infog, *info; /* the live instance's arrays */
  int n;                           /* order */
  int nnz;                         /* triplets */
  int *irn, *jcn;     /* nnz 1-based row and column indices (MUMPS keeps the pointers) */
  const double *a;    /* nnz values of the last factorization (the caller's: borrowed) */
  float *as;          /* single: the values MUMPS factors */
  float *xs;          /* single: n, the right-hand side MUMPS solves */
  double *b, *r;      /* single: n each, the right-hand side and the residual */
  double *V, *Z;      /* single: the refinement's Krylov basis ((LDL_GMRES_M + 1) n) and
                         its preconditioned vectors (LDL_GMRES_M n), allocated when
                         first needed */
  double *yc;         /* single: LDL_MATVEC_CHUNKS n, the products' partial sums */
  int prefer_single;  /* 1: created single; a double fallback lasts one factorization */
  int live;           /* 1 once JOB = -1 succeeded (JOB = -2 needed) */
  int factored;       /* 1 after a successful factorization */
  ves_ldl_info info_; /* diagnostics of the last call */
  void *wk;           /* the factorization's workspace (MUMPS WK_USER), kept across
                         factorizations: MUMPS would free and allocate its own at
                         every one, and the kernel zero the fresh pages (a third of
                         the factorization at eps 0.01: docs/results.md,
                         "Performance and its scaling"); the factors live in it
                         until the next one */
  size_t lwk;         /* its entries */
  double est;         /* the analysis's estimate of it (INFO(8), in entries) */
};

/* One MUMPS solve (JOB = 3) of the live instance, in place on x[n] (ldl.c). */
ves_status ldl_mumps_solve(ves_ldl *f, double *x);

/* The single precision factorization redone in double precision (ldl.c). */
ves_status ldl_to_double(ves_ldl *f);

#endif
