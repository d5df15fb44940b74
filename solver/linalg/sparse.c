/* vesica — the node-level block pattern of the model's matrices (plain data,
 * built from a quadrature by ves_pattern_create in project.c): lookup, values
 * as triplets, y = A x with A symmetric from its lower triplets, and the
 * compressed-row form over the free degrees of freedom (docs/design.md,
 * "Discretization"). */
#include "ves/sparse.h"

#include <stdlib.h>
#include <string.h>

void ves_pattern_destroy(ves_pattern **p) {
  if (!p || !*p) return;
  free((*p)->ptr);
  free((*p)->col);
  free((*p)->dof);
  free((*p)->irow);
  free((*p)->jcol);
  free((*p)->src);
  free(*p);
  *p = NULL;
}

long ves_pattern_find(const ves_pattern *p, int a, int b) {
  int lo = p->ptr[a], hi = p->ptr[a + 1] - 1;
  while (lo <= hi) { /* binary search in the sorted row */
    int mid = (lo + hi) / 2;
    if (p->col[mid] == b) return mid;
    if (p->col[mid] < b)
      lo = mid + 1;
    else
      hi = mid - 1;
  }
  return -1;
}

/* v_k = blk[src_k]: the free-dof entries of the blocks. */
void ves_pattern_extract(const ves_pattern *p, const double *blk, double *v) {
  for (int k = 0; k < p->nnz; k++) v[k] = blk[p->src[k]];
}

/* y = A x with A = L + L^T - diag(L), L the lower triplets v. */
void ves_pattern_symv(const ves_pattern *p, const double *v, const double *x, double *y) {
  for (int i = 0; i < p->nfree; i++) y[i] = 0.0;
  for (int k = 0; k < p->nnz; k++) {
    int i = p->irow[k], j = p->jcol[k];
    y[i] += v[k] * x[j];
    if (i != j) y[j] += v[k] * x[i]; /* the mirrored upper entry */
  }
}

/* Counting sort of the triplets and their mirror images into rows; the
 * triplets of one row arrive with ascending columns only per source, so each
 * row is sorted at the end (rows hold a few hundred entries). */
ves_status ves_pattern_csr(const ves_pattern *p, const double *v, int **ptr, int **col,
                           double **val) {
  VES_CHECK(p && v && ptr && col && val, VES_ERR_ARG);
  *ptr = NULL, *col = NULL, *val = NULL;
  int nf = p->nfree;
  int *rp = calloc((size_t)nf + 1, sizeof *rp), *fill = malloc(((size_t)nf + 1) * sizeof *fill);
  long nnz = 0;
  for (int k = 0; k < p->nnz; k++) {
    rp[p->irow[k] + 1]++;
    if (p->irow[k] != p->jcol[k]) rp[p->jcol[k] + 1]++;
  }
  for (int i = 0; i < nf; i++) rp[i + 1] += rp[i];
  nnz = rp[nf];
  int *c = malloc((size_t)(nnz ? nnz : 1) * sizeof *c);
  double *x = malloc((size_t)(nnz ? nnz : 1) * sizeof *x);
  if (!rp || !fill || !c || !x) {
    free(rp), free(fill), free(c), free(x);
    return VES_ERR_ALLOC;
  }
  memcpy(fill, rp, ((size_t)nf + 1) * sizeof *fill);
  for (int k = 0; k < p->nnz; k++) {
    int i = p->irow[k], j = p->jcol[k];
    c[fill[i]] = j, x[fill[i]++] = v[k];
    if (i != j) c[fill[j]] = i, x[fill[j]++] = v[k]; /* the upper mirror */
  }
  for (int i = 0; i < nf; i++) /* insertion sort of row i by column */
    for (int a = rp[i] + 1; a < rp[i + 1]; a++) {
      int cj = c[a];
      double xv = x[a];
      int b = a - 1;
      while (b >= rp[i] && c[b] > cj) c[b + 1] = c[b], x[b + 1] = x[b], b--;
      c[b + 1] = cj, x[b + 1] = xv;
    }
  free(fill);
  *ptr = rp, *col = c, *val = x;
  return VES_OK;
}
