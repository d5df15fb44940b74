/* vesica — the node-level block pattern of the model's matrices and its map
 * to lower-triangle triplets over the free degrees of freedom. */
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

/* Row a of the pattern = union over the points alpha that see a of the nodes
 * b <= a that alpha sees (cost sum_alpha m_alpha^2, once per configuration). */
ves_status ves_pattern_create(const ves_quad *q, int n, const unsigned char *fixed,
                              ves_pattern **out) {
  VES_CHECK(q && q->tab && fixed && out && n > 0, VES_ERR_ARG);
  *out = NULL;
  ves_status s = VES_ERR_ALLOC;
  ves_pattern *p = calloc(1, sizeof *p);
  int *npt = calloc((size_t)n + 1, sizeof *npt), *pts = NULL, *mark = malloc((size_t)n * sizeof *mark);
  int *fill = NULL;
  if (!p || !npt || !mark) goto fail;
  p->n = n;
  /* node -> points incidence (transpose of the neighbour lists) */
  for (int k = 0; k < q->ptr[q->nq]; k++) npt[q->nbr[k] + 1]++;
  for (int a = 0; a < n; a++) npt[a + 1] += npt[a];
  pts = malloc((size_t)npt[n] * sizeof *pts);
  fill = malloc((size_t)n * sizeof *fill);
  if (!pts || !fill) goto fail;
  memcpy(fill, npt, (size_t)n * sizeof *fill);
  for (int al = 0; al < q->nq; al++)
    for (int k = q->ptr[al]; k < q->ptr[al + 1]; k++) pts[fill[q->nbr[k]]++] = al; /* ghost pairs give repeats: harmless */
  /* two passes over the rows: count, then fill */
  p->ptr = calloc((size_t)n + 1, sizeof *p->ptr);
  if (!p->ptr) goto fail;
  for (int pass = 0; pass < 2; pass++) {
    for (int a = 0; a < n; a++) mark[a] = -1;
    for (int a = 0; a < n; a++) {
      int cnt = 0, base = pass ? p->ptr[a] : 0;
      for (int t = npt[a]; t < npt[a + 1]; t++) {
        int al = pts[t];
        for (int k = q->ptr[al]; k < q->ptr[al + 1]; k++) {
          int b = q->nbr[k];
          if (b > a || mark[b] == a) continue;
          mark[b] = a;
          if (pass) p->col[base + cnt] = b;
          cnt++;
        }
      }
      if (!pass) p->ptr[a + 1] = cnt;
      else { /* sort the row (insertion sort: rows hold a few hundred entries) */
        int *c = p->col + base;
        for (int i = 1; i < cnt; i++) {
          int v = c[i], j = i - 1;
          while (j >= 0 && c[j] > v) c[j + 1] = c[j], j--;
          c[j + 1] = v;
        }
      }
    }
    if (!pass) {
      for (int a = 0; a < n; a++) p->ptr[a + 1] += p->ptr[a];
      p->col = malloc((size_t)p->ptr[n] * sizeof *p->col);
      if (!p->col) goto fail;
    }
  }
  /* free dofs and the lower triplets over them */
  p->dof = malloc(2 * (size_t)n * sizeof *p->dof);
  if (!p->dof) goto fail;
  p->nfree = 0;
  for (int i = 0; i < 2 * n; i++) p->dof[i] = fixed[i] ? -1 : p->nfree++;
  long cnt = 0;
  for (int pass = 0; pass < 2; pass++) {
    cnt = 0;
    for (int a = 0; a < n; a++)
      for (int t = p->ptr[a]; t < p->ptr[a + 1]; t++) {
        int b = p->col[t];
        for (int i = 0; i < 2; i++)
          for (int j = 0; j < 2; j++) {
            int di = p->dof[2 * a + i], dj = p->dof[2 * b + j];
            if (di < 0 || dj < 0 || (a == b && j > i)) continue; /* fixed, or upper half of a diagonal block */
            if (pass) {
              /* rows >= cols in free numbering: a > b gives di > dj since dofs
               * are numbered node by node */
              p->irow[cnt] = di, p->jcol[cnt] = dj, p->src[cnt] = 4L * t + 2 * i + j;
            }
            cnt++;
          }
      }
    if (!pass) {
      p->nnz = (int)cnt;
      p->irow = malloc((size_t)cnt * sizeof *p->irow);
      p->jcol = malloc((size_t)cnt * sizeof *p->jcol);
      p->src = malloc((size_t)cnt * sizeof *p->src);
      if (!p->irow || !p->jcol || !p->src) goto fail;
    }
  }
  s = VES_OK;
  *out = p;
  p = NULL;
fail:
  ves_pattern_destroy(&p);
  free(npt);
  free(pts);
  free(mark);
  free(fill);
  return s;
}

long ves_pattern_find(const ves_pattern *p, int a, int b) {
  int lo = p->ptr[a], hi = p->ptr[a + 1] - 1;
  while (lo <= hi) { /* binary search in the sorted row */
    int mid = (lo + hi) / 2;
    if (p->col[mid] == b) return mid;
    if (p->col[mid] < b) lo = mid + 1; else hi = mid - 1;
  }
  return -1;
}

void ves_pattern_extract(const ves_pattern *p, const double *blk, double *v) {
  for (int k = 0; k < p->nnz; k++) v[k] = blk[p->src[k]];
}

void ves_pattern_symv(const ves_pattern *p, const double *v, const double *x, double *y) {
  for (int i = 0; i < p->nfree; i++) y[i] = 0.0;
  for (int k = 0; k < p->nnz; k++) {
    int i = p->irow[k], j = p->jcol[k];
    y[i] += v[k] * x[j];
    if (i != j) y[j] += v[k] * x[i]; /* the mirrored upper entry */
  }
}
