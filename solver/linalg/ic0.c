/* vesica — the incomplete Cholesky factor IC(0) on the lower pattern of a
 * matrix given by its triplets: row-wise,
 *   L_ij = (M_ij - sum_{k<j} L_ik L_jk) / L_jj   (j < i, (i, j) in the pattern),
 *   L_ii = sqrt(M_ii (1 + alpha) - sum_{k<i} L_ik^2),
 * and the triangular solves with L and L^T (docs/design.md, "Backends"). */
#include "ves/ic0.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void ves_ldl_ic_destroy(ves_ldl_ic **L) {
  if (!L || !*L) return;
  free((*L)->ptr), free((*L)->col), free((*L)->a), free((*L)->l), free((*L)->map);
  free(*L);
  *L = NULL;
}

/* Pattern of the lower triplets (irow >= jcol) in compressed rows, columns
 * ascending, the diagonal forced in, duplicates merged; map[k] the slot of
 * triplet k. */
ves_status ves_ldl_ic_create(int n, int nnz, const int *irow, const int *jcol, ves_ldl_ic **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(n > 0 && nnz >= 0 && (nnz == 0 || (irow && jcol)), VES_ERR_ARG);
  for (int k = 0; k < nnz; k++)
    VES_CHECK(irow[k] >= 0 && irow[k] < n && jcol[k] >= 0 && jcol[k] <= irow[k], VES_ERR_ARG);
  ves_ldl_ic *L = calloc(1, sizeof *L);
  if (!L) return VES_ERR_ALLOC;
  L->n = n, L->nnz = nnz;
  L->ptr = calloc((size_t)n + 1, sizeof(int));
  L->map = malloc((size_t)(nnz > 0 ? nnz : 1) * sizeof(int));
  int *cnt = calloc((size_t)n + 1, sizeof(int));
  int *tmp = malloc((size_t)(nnz + n + 1) * sizeof(int));
  ves_status rc = VES_ERR_ALLOC;
  if (!L->ptr || !L->map || !cnt || !tmp) goto out;
  /* rows with the diagonal forced in: count, fill, sort, merge */
  for (int k = 0; k < nnz; k++) cnt[irow[k] + 1]++;
  for (int i = 0; i < n; i++) cnt[i + 1] += cnt[i] + 1; /* + 1: the diagonal */
  int *pos = L->ptr;                                    /* fill positions */
  for (int i = 0; i < n; i++) pos[i] = cnt[i], tmp[pos[i]++] = i;
  for (int k = 0; k < nnz; k++) tmp[pos[irow[k]]++] = jcol[k];
  int w = 0;
  for (int i = 0; i < n; i++) {
    int b = cnt[i], e = cnt[i + 1];
    for (int p = b + 1; p < e; p++) /* insertion sort (rows are short) */
      for (int q = p; q > b && tmp[q - 1] > tmp[q]; q--) {
        int t = tmp[q];
        tmp[q] = tmp[q - 1], tmp[q - 1] = t;
      }
    L->ptr[i] = w;
    for (int p = b; p < e; p++)
      if (p == b || tmp[p] != tmp[p - 1]) tmp[w++] = tmp[p];
  }
  L->ptr[n] = w;
  L->col = malloc((size_t)w * sizeof(int));
  L->a = malloc((size_t)w * sizeof(double));
  L->l = malloc((size_t)w * sizeof(double));
  if (!L->col || !L->a || !L->l) goto out;
  memcpy(L->col, tmp, (size_t)w * sizeof(int));
  for (int k = 0; k < nnz; k++) { /* binary search of the slot */
    int lo = L->ptr[irow[k]], hi = L->ptr[irow[k] + 1] - 1;
    while (lo < hi) {
      int mid = (lo + hi) / 2;
      if (L->col[mid] < jcol[k])
        lo = mid + 1;
      else
        hi = mid;
    }
    L->map[k] = lo;
  }
  rc = VES_OK;
  *out = L;
  L = NULL;
out:
  free(cnt), free(tmp);
  ves_ldl_ic_destroy(&L);
  return rc;
}

/* a = sum_k val_k at slot map[k] */
void ves_ldl_ic_set(ves_ldl_ic *L, const double *val) {
  memset(L->a, 0, (size_t)L->ptr[L->n] * sizeof(double));
  for (int k = 0; k < L->nnz; k++) L->a[L->map[k]] += val[k];
}

/* Row-wise IC(0) of M + alpha diag(M) (ic0.h). */
ves_status ves_ldl_ic_factor(ves_ldl_ic *L, double alpha) {
  const int *ptr = L->ptr, *col = L->col;
  for (int i = 0; i < L->n; i++) {
    int bi = ptr[i], ei = ptr[i + 1] - 1; /* ei: the diagonal */
    for (int p = bi; p <= ei; p++) {
      int j = col[p];
      double sum = L->a[p] * (j == i ? 1.0 + alpha : 1.0);
      /* sparse dot of rows i and j over columns < j */
      int q = bi, r = ptr[j], er = ptr[j + 1] - 1;
      while (q < p && r < er) {
        if (col[q] == col[r])
          sum -= L->l[q++] * L->l[r++];
        else if (col[q] < col[r])
          q++;
        else
          r++;
      }
      if (j < i) {
        L->l[p] = sum / L->l[er];
      } else {
        if (!(sum > 0.0) || !isfinite(sum)) return VES_ERR_SINGULAR;
        L->l[p] = sqrt(sum);
      }
    }
  }
  return VES_OK;
}

/* v = L^{-1} v (forward substitution, in place). */
void ves_ldl_ic_lsolve(const ves_ldl_ic *L, double *v) {
  for (int i = 0; i < L->n; i++) {
    int e = L->ptr[i + 1] - 1;
    double s = v[i];
    for (int p = L->ptr[i]; p < e; p++) s -= L->l[p] * v[L->col[p]];
    v[i] = s / L->l[e];
  }
}

/* v = L^{-T} v (backward substitution, in place). */
void ves_ldl_ic_ltsolve(const ves_ldl_ic *L, double *v) {
  for (int i = L->n - 1; i >= 0; i--) {
    int e = L->ptr[i + 1] - 1;
    v[i] /= L->l[e];
    for (int p = L->ptr[i]; p < e; p++) v[L->col[p]] -= L->l[p] * v[i];
  }
}
