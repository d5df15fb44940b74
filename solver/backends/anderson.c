/* vesica — Anderson acceleration (type II) of a fixed-point iteration
 * u <- u + g(u) (anderson_impl.h): gamma = argmin |g - dG gamma|_2,
 * p = g - (dU + dG) gamma, the least squares by modified Gram-Schmidt in
 * fixed loops (deterministic: no BLAS threads); a column nearly dependent on
 * the newer ones ends the history there. docs/design.md, "Backends". */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "backends/anderson_impl.h"

void anderson_destroy(anderson *a) {
  if (!a) return;
  free(a->du), free(a->dg), free(a->q), free(a->u), free(a->g), free(a->p);
  memset(a, 0, sizeof *a);
}

ves_status anderson_create(int n, int nls, anderson *a) {
  memset(a, 0, sizeof *a);
  if (n < 1 || nls < 0 || nls > n) return VES_ERR_ARG;
  a->n = n, a->nls = nls;
  const size_t na = (size_t)n, nv = (size_t)nls;
  a->du = malloc(ANDERSON_DEPTH * na * sizeof *a->du);
  a->dg = malloc(ANDERSON_DEPTH * na * sizeof *a->dg);
  a->q = malloc(ANDERSON_DEPTH * (nv > 0 ? nv : 1) * sizeof *a->q);
  a->u = malloc(na * sizeof *a->u);
  a->g = malloc(na * sizeof *a->g);
  a->p = malloc(na * sizeof *a->p);
  if (!a->du || !a->dg || !a->q || !a->u || !a->g || !a->p) {
    anderson_destroy(a);
    return VES_ERR_ALLOC;
  }
  return VES_OK;
}

void anderson_reset(anderson *a) { a->ncol = 0, a->prev = 0; }

void anderson_plain(anderson *a, const double *g) {
  a->ncol = 0;
  memcpy(a->p, g, (size_t)a->n * sizeof *g);
}

/* The step (anderson_impl.h): the history updated with (x, lam) and g, then
 * the QR of the dG columns' first nls components, newest first. */
int anderson_step(anderson *a, const double *x, const double *lam, const double *g) {
  const int nv = a->nls, na = a->n;
  if (a->prev) {                     /* a new column: the differences to the previous iterate */
    if (a->ncol == ANDERSON_DEPTH) { /* drop the oldest */
      memmove(a->du, a->du + na, (size_t)(ANDERSON_DEPTH - 1) * na * sizeof *a->du);
      memmove(a->dg, a->dg + na, (size_t)(ANDERSON_DEPTH - 1) * na * sizeof *a->dg);
      a->ncol--;
    }
    double *du = a->du + (size_t)a->ncol * na, *dg = a->dg + (size_t)a->ncol * na;
    for (int j = 0; j < nv; j++) du[j] = x[j] - a->u[j];
    for (int i = 0; i < na - nv; i++) du[nv + i] = lam[i] - a->u[nv + i];
    for (int j = 0; j < na; j++) dg[j] = g[j] - a->g[j];
    a->ncol++;
  }
  memcpy(a->u, x, (size_t)nv * sizeof *x);
  memcpy(a->u + nv, lam, (size_t)(na - nv) * sizeof *lam);
  memcpy(a->g, g, (size_t)na * sizeof *g);
  a->prev = 1;
  memcpy(a->p, g, (size_t)na * sizeof *g);
  if (a->ncol == 0) return 0;
  /* QR of the dG columns (x part), newest first; R upper triangular */
  double R[ANDERSON_DEPTH][ANDERSON_DEPTH] = {{0}}, rhs[ANDERSON_DEPTH], gam[ANDERSON_DEPTH];
  int m = 0;
  for (int c = a->ncol - 1; c >= 0; c--, m++) {
    double *q = a->q + (size_t)m * nv;
    const double *dg = a->dg + (size_t)c * na;
    double n0 = 0;
    for (int j = 0; j < nv; j++) q[j] = dg[j], n0 += dg[j] * dg[j];
    for (int i = 0; i < m; i++) {
      const double *qi = a->q + (size_t)i * nv;
      double d = 0;
      for (int j = 0; j < nv; j++) d += qi[j] * q[j];
      R[i][m] = d;
      for (int j = 0; j < nv; j++) q[j] -= d * qi[j];
    }
    double nn = 0;
    for (int j = 0; j < nv; j++) nn += q[j] * q[j];
    if (!(nn > 1e-20 * n0) || n0 == 0) break; /* dependent: the older columns go too */
    R[m][m] = sqrt(nn);
    for (int j = 0; j < nv; j++) q[j] /= R[m][m];
  }
  if (m < a->ncol) { /* keep the m newest columns */
    const int drop = a->ncol - m;
    memmove(a->du, a->du + (size_t)drop * na, (size_t)m * na * sizeof *a->du);
    memmove(a->dg, a->dg + (size_t)drop * na, (size_t)m * na * sizeof *a->dg);
    a->ncol = m;
  }
  if (m == 0) return 0;
  for (int i = 0; i < m; i++) {
    const double *qi = a->q + (size_t)i * nv;
    double d = 0;
    for (int j = 0; j < nv; j++) d += qi[j] * g[j];
    rhs[i] = d;
  }
  for (int i = m - 1; i >= 0; i--) { /* R gam = Q^T g */
    double d = rhs[i];
    for (int k = i + 1; k < m; k++) d -= R[i][k] * gam[k];
    gam[i] = d / R[i][i];
  }
  double gn = 0, pn = 0;
  for (int i = 0; i < m; i++) { /* column i of the QR is history column aa_n - 1 - i */
    const size_t c = (size_t)(a->ncol - 1 - i) * na;
    for (int j = 0; j < na; j++) a->p[j] -= gam[i] * (a->du[c + j] + a->dg[c + j]);
  }
  for (int j = 0; j < nv; j++) gn += g[j] * g[j], pn += a->p[j] * a->p[j];
  if (!(pn <= ANDERSON_GROW * ANDERSON_GROW * gn)) { /* a wild extrapolation: plain chord */
    memcpy(a->p, g, (size_t)na * sizeof *g);
    a->ncol = 0;
    return 0;
  }
  return 1;
}
