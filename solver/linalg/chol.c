/* vesica — the exact sparse Cholesky factor with half solves (chol.h), on
 * CHOLMOD: P M P^T = L L^T, G = P^T L, v -> G^{-1} v, v -> G^{-T} v; or the
 * dense factor of M + sum s_i w_i w_i^T (docs/design.md, "Backends").
 * The pattern goes to CHOLMOD once, as a lower (stype -1) packed
 * column matrix with sorted rows; map[k] is the slot of triplet k, so each
 * factorization only sums the values into A->x. CHOLMOD's own ordering
 * (AMD, METIS when AMD's fill is poor) and supernodal/simplicial choice are
 * kept; final_ll asks for L L^T in both, which the half solves need.
 * The dense variant (ves_chol_factor_dense) factors M + sum s_i w_i w_i^T
 * with LAPACK's dpotrf on an n x n column-major array: a dense rank-m term
 * would fill the sparse factor completely, and no sparse route reaches it
 * when M itself is indefinite (an update needs a positive definite factor to
 * start from). The half solves then go to BLAS's dtrsv / dtrsm. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>
#include <lapacke.h>
#include <suitesparse/cholmod.h>

#include "ves/chol.h"

struct ves_chol {
  int n, nnz;
  int *map;          /* nnz: slot of triplet k in A->x */
  cholmod_common c;  /* CHOLMOD's parameters and workspace */
  cholmod_sparse *A; /* the pattern, values of the last factorization */
  cholmod_factor *L; /* P M P^T = L L^T (L->Perm = P) */
  cholmod_dense *X;  /* solve2's result (reused) */
  cholmod_dense *Y;  /* solve2's workspace */
  cholmod_dense *E;  /* solve2's workspace */
  double *w;         /* n wcols: the permuted vectors */
  int wcols;         /* columns w holds */
  double *D;         /* n n column-major: the dense factor (ves_chol_factor_dense) */
  int dense;         /* the factor in use is D, not L */
  int factored;      /* the last factorization succeeded */
  int started;       /* cholmod_start was called */
};

void ves_chol_destroy(ves_chol **f) {
  if (!f || !*f) return;
  ves_chol *F = *f;
  if (F->started) {
    cholmod_free_dense(&F->X, &F->c);
    cholmod_free_dense(&F->Y, &F->c);
    cholmod_free_dense(&F->E, &F->c);
    cholmod_free_factor(&F->L, &F->c);
    cholmod_free_sparse(&F->A, &F->c);
    cholmod_finish(&F->c);
  }
  free(F->map), free(F->w), free(F->D);
  free(F);
  *f = NULL;
}

/* Columns of the lower triplets with the diagonal first (rows ascending,
 * duplicates merged) into A; map[k] the slot of triplet k. */
static ves_status chol_pattern(ves_chol *F, const int *irow, const int *jcol) {
  const int n = F->n, nnz = F->nnz;
  int *cnt = calloc((size_t)n + 1, sizeof(int));
  int *tmp = malloc((size_t)(nnz + n) * sizeof(int));
  ves_status rc = VES_ERR_ALLOC;
  if (!cnt || !tmp) goto out;
  for (int k = 0; k < nnz; k++) cnt[jcol[k] + 1]++;
  for (int j = 0; j < n; j++) cnt[j + 1] += cnt[j] + 1; /* + 1: the diagonal */
  int *pos = malloc((size_t)n * sizeof(int));
  if (!pos) goto out;
  for (int j = 0; j < n; j++) pos[j] = cnt[j], tmp[pos[j]++] = j;
  for (int k = 0; k < nnz; k++) tmp[pos[jcol[k]]++] = irow[k];
  free(pos);
  int w = 0;
  for (int j = 0; j < n; j++) {
    const int b = cnt[j], e = cnt[j + 1];
    for (int p = b + 1; p < e; p++) /* insertion sort (columns are short) */
      for (int q = p; q > b && tmp[q - 1] > tmp[q]; q--) {
        const int t = tmp[q];
        tmp[q] = tmp[q - 1], tmp[q - 1] = t;
      }
    cnt[j] = w;
    for (int p = b; p < e; p++)
      if (p == b || tmp[p] != tmp[p - 1]) tmp[w++] = tmp[p];
  }
  cnt[n] = w;
  F->A = cholmod_allocate_sparse((size_t)n, (size_t)n, (size_t)w, 1, 1, -1, CHOLMOD_REAL, &F->c);
  if (!F->A) goto out;
  int *Ap = F->A->p, *Ai = F->A->i;
  memcpy(Ap, cnt, ((size_t)n + 1) * sizeof(int));
  memcpy(Ai, tmp, (size_t)w * sizeof(int));
  memset(F->A->x, 0, (size_t)w * sizeof(double));
  for (int k = 0; k < nnz; k++) { /* binary search of the slot */
    int lo = Ap[jcol[k]], hi = Ap[jcol[k] + 1] - 1;
    while (lo < hi) {
      const int mid = (lo + hi) / 2;
      if (Ai[mid] < irow[k])
        lo = mid + 1;
      else
        hi = mid;
    }
    F->map[k] = lo;
  }
  rc = VES_OK;
out:
  free(cnt), free(tmp);
  return rc;
}

ves_status ves_chol_create(int n, int nnz, const int *irow, const int *jcol, ves_chol **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(n > 0 && nnz >= 0 && (nnz == 0 || (irow && jcol)), VES_ERR_ARG);
  for (int k = 0; k < nnz; k++)
    VES_CHECK(irow[k] >= 0 && irow[k] < n && jcol[k] >= 0 && jcol[k] <= irow[k], VES_ERR_ARG);
  ves_chol *F = calloc(1, sizeof *F);
  if (!F) return VES_ERR_ALLOC;
  F->n = n, F->nnz = nnz;
  F->map = malloc((size_t)(nnz > 0 ? nnz : 1) * sizeof(int));
  F->w = malloc((size_t)n * sizeof(double));
  F->wcols = 1;
  ves_status rc = VES_ERR_ALLOC;
  if (!F->map || !F->w) goto fail;
  if (!cholmod_start(&F->c)) {
    rc = VES_ERR_SOLVER;
    goto fail;
  }
  F->started = 1;
  F->c.print = 0;    /* no messages: the status says it */
  F->c.final_ll = 1; /* L L^T also from a simplicial factorization */
  /* A failed factorization's partial factor is never used: without this,
   * CHOLMOD refactors the failing supernode so that L(:,1:minor) is valid,
   * which doubles the cost of a late failure (the nlopt backend's shifts:
   * 0.27 s against 0.14 s at 2.8k unknowns, docs/results.md, "The backends
   * compared"). */
  F->c.quick_return_if_not_posdef = 1;
  if ((rc = chol_pattern(F, irow, jcol)) != VES_OK) goto fail;
  F->L = cholmod_analyze(F->A, &F->c);
  if (!F->L) {
    rc = F->c.status == CHOLMOD_OUT_OF_MEMORY ? VES_ERR_ALLOC : VES_ERR_SOLVER;
    goto fail;
  }
  *out = F;
  return VES_OK;
fail:
  ves_chol_destroy(&F);
  return rc;
}

/* The triplets val summed into A->x, the diagonal times 1 + alpha; 0 if a
 * diagonal entry is not finite. */
static int chol_values(ves_chol *f, const double *val, double alpha) {
  double *x = f->A->x;
  const int *Ap = f->A->p;
  memset(x, 0, (size_t)Ap[f->n] * sizeof(double));
  for (int k = 0; k < f->nnz; k++) x[f->map[k]] += val[k];
  for (int j = 0; j < f->n; j++) {
    x[Ap[j]] *= 1.0 + alpha; /* the diagonal: a column's first slot */
    if (!isfinite(x[Ap[j]])) return 0;
  }
  return 1;
}

ves_status ves_chol_factor(ves_chol *f, const double *val, double alpha) {
  VES_CHECK(f && (f->nnz == 0 || val) && alpha >= 0.0 && isfinite(alpha), VES_ERR_ARG);
  f->factored = 0, f->dense = 0;
  if (!chol_values(f, val, alpha)) return VES_ERR_SINGULAR;
  if (!cholmod_factorize(f->A, f->L, &f->c))
    return f->c.status == CHOLMOD_OUT_OF_MEMORY ? VES_ERR_ALLOC : VES_ERR_SOLVER;
  if (f->c.status == CHOLMOD_NOT_POSDEF || f->L->minor < f->L->n) return VES_ERR_SINGULAR;
  if (f->c.status != CHOLMOD_OK || !f->L->is_ll) return VES_ERR_SOLVER;
  f->factored = 1;
  return VES_OK;
}

ves_status ves_chol_factor_dense(ves_chol *f, const double *val, int m, const double *w,
                                 const double *s, int *fail) {
  VES_CHECK(f && (f->nnz == 0 || val) && m >= 0 && (m == 0 || (w && s)), VES_ERR_ARG);
  for (int i = 0; i < m; i++) VES_CHECK(s[i] >= 0.0 && isfinite(s[i]), VES_ERR_ARG);
  const size_t n = (size_t)f->n;
  f->factored = 0, f->dense = 0;
  if (fail) *fail = 0;
  if (!f->D && !(f->D = malloc(n * n * sizeof(double)))) return VES_ERR_ALLOC;
  if (!chol_values(f, val, 0.0)) return VES_ERR_SINGULAR;
  double *D = f->D;
  const double *x = f->A->x;
  const int *Ap = f->A->p, *Ai = f->A->i;
  for (size_t j = 0; j < n; j++) { /* the lower triangle of column j */
    memset(D + j * n + j, 0, (n - j) * sizeof(double));
    for (int p = Ap[j]; p < Ap[j + 1]; p++) D[j * n + (size_t)Ai[p]] = x[p];
  }
  for (int i = 0; i < m; i++)
    cblas_dsyr(CblasColMajor, CblasLower, (int)n, s[i], w + (size_t)i * n, 1, D, (int)n);
  for (size_t j = 0; j < n; j++)
    if (!isfinite(D[j * n + j])) return VES_ERR_SINGULAR;
  const lapack_int info = LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', (lapack_int)n, D, (lapack_int)n);
  if (info > 0) {
    if (fail) *fail = (int)info;
    return VES_ERR_SINGULAR;
  }
  if (info < 0) return VES_ERR_SOLVER;
  f->factored = 1, f->dense = 1;
  return VES_OK;
}

/* v = L^{-1} v (sys CHOLMOD_L) or L^{-T} v (CHOLMOD_Lt) for the k columns
 * of v (n k, column-major), through solve2's reused workspaces: the factor is
 * read once for all k. */
static ves_status chol_tri(ves_chol *f, int sys, int k, double *v) {
  cholmod_dense B = {.nrow = (size_t)f->n,
                     .ncol = (size_t)k,
                     .nzmax = (size_t)f->n * (size_t)k,
                     .d = (size_t)f->n,
                     .x = v,
                     .z = NULL,
                     .xtype = CHOLMOD_REAL,
                     .dtype = CHOLMOD_DOUBLE};
  if (!cholmod_solve2(sys, f->L, &B, NULL, &f->X, NULL, &f->Y, &f->E, &f->c)) return VES_ERR_SOLVER;
  memcpy(v, f->X->x, (size_t)f->n * (size_t)k * sizeof(double));
  return VES_OK;
}

/* G^{-1} v = L^{-1} P v, (P v)_i = v_{Perm[i]}, column by column. */
ves_status ves_chol_lsolve_cols(ves_chol *f, int k, double *v) {
  VES_CHECK(f && f->factored && v && k >= 1, VES_ERR_ARG);
  if (f->dense) {
    if (k == 1)
      cblas_dtrsv(CblasColMajor, CblasLower, CblasNoTrans, CblasNonUnit, f->n, f->D, f->n, v, 1);
    else
      cblas_dtrsm(CblasColMajor, CblasLeft, CblasLower, CblasNoTrans, CblasNonUnit, f->n, k, 1.0,
                  f->D, f->n, v, f->n);
    return VES_OK;
  }
  const size_t n = (size_t)f->n;
  if (k > f->wcols) {
    double *w = realloc(f->w, n * (size_t)k * sizeof(double));
    if (!w) return VES_ERR_ALLOC;
    f->w = w, f->wcols = k;
  }
  const int *perm = f->L->Perm;
  for (int c = 0; c < k; c++)
    for (size_t i = 0; i < n; i++) f->w[c * n + i] = v[c * n + (size_t)perm[i]];
  VES_CALL(chol_tri(f, CHOLMOD_L, k, f->w));
  memcpy(v, f->w, n * (size_t)k * sizeof(double));
  return VES_OK;
}

ves_status ves_chol_lsolve(ves_chol *f, double *v) { return ves_chol_lsolve_cols(f, 1, v); }

/* G^{-T} v = P^T L^{-T} v. */
ves_status ves_chol_ltsolve(ves_chol *f, double *v) {
  VES_CHECK(f && f->factored && v, VES_ERR_ARG);
  if (f->dense) {
    cblas_dtrsv(CblasColMajor, CblasLower, CblasTrans, CblasNonUnit, f->n, f->D, f->n, v, 1);
    return VES_OK;
  }
  const int *perm = f->L->Perm;
  VES_CALL(chol_tri(f, CHOLMOD_Lt, 1, v));
  memcpy(f->w, v, (size_t)f->n * sizeof(double));
  for (int i = 0; i < f->n; i++) v[perm[i]] = f->w[i];
  return VES_OK;
}

size_t ves_chol_factor_entries(const ves_chol *f) {
  if (!f || !f->factored) return 0;
  if (f->dense) return (size_t)f->n * ((size_t)f->n + 1) / 2;
  const cholmod_factor *L = f->L;
  if (L->is_super) return L->xsize;
  return L->nzmax;
}

double ves_chol_fill(const ves_chol *f) {
  if (!f) return 0.0;
  return f->c.lnz / (0.5 * f->n * (f->n + 1.0));
}
