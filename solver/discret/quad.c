/* vesica — 6-point degree-4 quadrature on Delaunay triangles and the LME
 * discretization tables at the quadrature points (docs/design.md,
 * "Discretization").
 *
 * The rule is the symmetric degree-4 rule of Strang–Fix/Dunavant: two orbits of
 * three points with barycentric coordinates (1-2a, a, a); its four parameters
 * solve the moment equations of degree <= 4 (recomputed to 40 digits with
 * mpmath; every monomial of degree <= 4 is integrated to rounding, see
 * tests/test_quad.c). All points are interior, so the LME dual is never solved
 * on the hull boundary. */
#include "ves/quad.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>
#include "core/clock_impl.h"
#include "core/mem_impl.h"
#include "core/omp_impl.h"

#define QA1 0.4459484909159648863183292538830519883991
#define QW1 0.2233815896780114656950070084331228043703
#define QA2 0.09157621350977074345957146340220150785433
#define QW2 0.1099517436553218676383263249002105289631

void ves_quad_rule(double bary[3 * VES_QUAD_NPT], double w[VES_QUAD_NPT]) {
  const double a[2] = {QA1, QA2}, wt[2] = {QW1, QW2};
  for (int o = 0; o < 2; o++)
    for (int k = 0; k < 3; k++) { /* point k of orbit o: 1-2a at vertex k */
      double *b = bary + 3 * (3 * o + k);
      b[0] = b[1] = b[2] = a[o];
      b[k] = 1.0 - 2.0 * a[o];
      w[3 * o + k] = wt[o];
    }
}

/* Dunavant's degree-6 rule (12 points): orbits (1-2a, a, a) of a = D6A1, D6A2
 * and the six permutations of (D6B, D6C, 1 - D6B - D6C); Dunavant's 15-digit
 * values refined to double by Gauss-Newton on the 28 moment equations of
 * degree <= 6 (residual 6e-17; tests/test_quad.c checks the moments). */
#define D6A1 0.0630890144915062
#define D6W1 0.05084490637021254
#define D6A2 0.24928674517089058
#define D6W2 0.11678627572641141
#define D6B 0.053145049844803775
#define D6C 0.3103524510337995
#define D6W3 0.08285107561835468

static void rule_d6(double bary[36], double w[12]) {
  const double a[2] = {D6A1, D6A2}, wt[2] = {D6W1, D6W2};
  for (int o = 0; o < 2; o++)
    for (int k = 0; k < 3; k++) {
      double *b = bary + 3 * (3 * o + k);
      b[0] = b[1] = b[2] = a[o];
      b[k] = 1.0 - 2.0 * a[o];
      w[3 * o + k] = wt[o];
    }
  const double v[3] = {D6B, D6C, 1.0 - D6B - D6C};
  static const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < 6; k++) {
    for (int j = 0; j < 3; j++) bary[3 * (6 + k) + j] = v[perm[k][j]];
    w[6 + k] = D6W3;
  }
}

ves_status ves_quad_rule_parse(const char *s, ves_quad_rulespec *out) {
  VES_CHECK(s && out, VES_ERR_ARG);
  static const struct {
    const char *name;
    int degree, split;
  } R[] = {{"d4", 4, 1},   {"d6", 6, 1},    {"d4x4", 4, 2},
           {"d6x4", 6, 2}, {"d4x16", 4, 4}, {"d6x16", 6, 4}};
  for (size_t i = 0; i < sizeof R / sizeof *R; i++)
    if (!strcasecmp(s, R[i].name)) {
      out->degree = R[i].degree, out->split = R[i].split;
      return VES_OK;
    }
  return VES_ERR_ARG;
}

int ves_quad_rule_npt(ves_quad_rulespec r) {
  if ((r.degree != 4 && r.degree != 6) || (r.split != 1 && r.split != 2 && r.split != 4)) return 0;
  return (r.degree == 4 ? 6 : 12) * r.split * r.split;
}

/* The base rule on each sub-triangle of the uniform split: the sub-triangles
 * with corners (i, j), (i+1, j), (i, j+1) ("up") and (i+1, j), (i+1, j+1),
 * (i, j+1) ("down") in units 1/split of the barycentric coordinates
 * (lambda_1, lambda_2), each of area 1/split^2; a sub-triangle's points are
 * consecutive. */
ves_status ves_quad_rule_composite(ves_quad_rulespec r, double bary[3 * VES_QUAD_NPT_MAX],
                                   double w[VES_QUAD_NPT_MAX]) {
  const int npt = ves_quad_rule_npt(r);
  VES_CHECK(npt > 0 && bary && w, VES_ERR_ARG);
  double bb[36], wb[12];
  int nb = r.degree == 4 ? 6 : 12;
  if (r.degree == 4)
    ves_quad_rule(bb, wb);
  else
    rule_d6(bb, wb);
  if (r.split == 1) { /* the base rule itself, bit for bit */
    memcpy(bary, bb, 3 * (size_t)nb * sizeof *bary);
    memcpy(w, wb, (size_t)nb * sizeof *w);
    return VES_OK;
  }
  const int S = r.split;
  const double h = 1.0 / S, ws = 1.0 / (S * S);
  int k = 0;
  for (int i = 0; i < S; i++)
    for (int j = 0; i + j < S; j++)
      for (int up = 1; up >= 0 && (up || i + j + 1 < S); up--) {
        /* corners in (lambda_1, lambda_2) */
        const double c[3][2] = {
            {(i + !up) * h, (j + 0) * h}, {(i + 1) * h, (j + !up) * h}, {(i + 0) * h, (j + 1) * h}};
        for (int p = 0; p < nb; p++, k++) {
          const double *b = bb + 3 * p;
          const double l1 = b[0] * c[0][0] + b[1] * c[1][0] + b[2] * c[2][0],
                       l2 = b[0] * c[0][1] + b[1] * c[1][1] + b[2] * c[2][1];
          bary[3 * k] = 1.0 - l1 - l2, bary[3 * k + 1] = l1, bary[3 * k + 2] = l2;
          w[k] = wb[p] * ws;
        }
      }
  return k == npt ? VES_OK : VES_ERR_INTERNAL;
}

static void tables_free(ves_quad *q) {
  free(q->ptr);
  free(q->nbr);
  free(q->mirror);
  free(q->tab);
  q->ptr = q->nbr = NULL;
  q->mirror = NULL;
  q->tab = NULL;
}

void ves_quad_destroy(ves_quad **q) {
  if (!q || !*q) return;
  tables_free(*q);
  free((*q)->tri);
  free((*q)->x);
  free((*q)->w);
  free(*q);
  *q = NULL;
}

/* Points X = sum_j bary_j V_j and weights w_k |T| on every triangle T. */
ves_status ves_quad_create(const ves_nodes *nodes, ves_quad **out) {
  const ves_quad_rulespec r = {4, 1};
  return ves_quad_create_rule(nodes, r, out);
}

ves_status ves_quad_create_rule(const ves_nodes *nodes, ves_quad_rulespec r, ves_quad **out) {
  VES_CHECK(nodes && out && nodes->n >= 3, VES_ERR_ARG);
  *out = NULL;
  const int npt = ves_quad_rule_npt(r);
  VES_CHECK(npt > 0 && npt % VES_QUAD_NPT == 0, VES_ERR_ARG);
  double *bary = malloc(3 * (size_t)npt * sizeof *bary), *wr = malloc((size_t)npt * sizeof *wr);
  ves_quad *q = calloc(1, sizeof *q);
  ves_status s = VES_ERR_ALLOC;
  int ncell = 0, *cell = NULL;
  if (!q || !bary || !wr) goto fail;
  if ((s = ves_quad_rule_composite(r, bary, wr)) != VES_OK) goto fail;
  if ((s = ves_geom_delaunay(nodes->n, nodes->x, &ncell, &cell)) != VES_OK) goto fail;
  q->sub = npt / VES_QUAD_NPT, q->rule = r;
  q->ntri = q->sub * ncell;
  if (q->sub == 1)
    q->tri = cell, cell = NULL;
  else if ((q->tri = malloc(3 * (size_t)q->ntri * sizeof *q->tri)))
    for (int t = 0; t < ncell; t++)
      for (int g = 0; g < q->sub; g++)
        memcpy(q->tri + 3 * (q->sub * t + g), cell + 3 * t, 3 * sizeof *cell);
  q->nq = npt * ncell;
  q->x = malloc(2 * (size_t)q->nq * sizeof *q->x);
  q->w = malloc((size_t)q->nq * sizeof *q->w);
  if (!q->tri || !q->x || !q->w) {
    s = VES_ERR_ALLOC;
    goto fail;
  }
  for (int t = 0; t < ncell; t++) {
    const int *c = q->tri + 3 * q->sub * t;
    const double *v0 = nodes->x + 2 * c[0], *v1 = nodes->x + 2 * c[1], *v2 = nodes->x + 2 * c[2];
    /* |T| = ((v1 - v0) x (v2 - v0)) / 2, positive for counter-clockwise */
    double area = 0.5 * ((v1[0] - v0[0]) * (v2[1] - v0[1]) - (v1[1] - v0[1]) * (v2[0] - v0[0]));
    if (!(area > 0.0)) {
      s = VES_ERR_GEOM;
      goto fail;
    }
    for (int k = 0; k < npt; k++) {
      const double *b = bary + 3 * k;
      double *X = q->x + 2 * ((size_t)npt * t + k);
      X[0] = b[0] * v0[0] + b[1] * v1[0] + b[2] * v2[0];
      X[1] = b[0] * v0[1] + b[1] * v1[1] + b[2] * v2[1];
      q->w[(size_t)npt * t + k] = wr[k] * area;
    }
  }
  free(bary), free(wr), free(cell);
  *out = q;
  return VES_OK;
fail:
  free(bary), free(wr), free(cell);
  ves_quad_destroy(&q);
  return s;
}

ves_status ves_quad_cells(const ves_quad *q, int *ncell, int **cells) {
  VES_CHECK(q && ncell && cells && q->ntri > 0, VES_ERR_ARG);
  const int sub = q->sub > 1 ? q->sub : 1, nc = q->ntri / sub;
  int *c = malloc(3 * (size_t)nc * sizeof *c);
  if (!c) return VES_ERR_ALLOC;
  for (int t = 0; t < nc; t++) memcpy(c + 3 * t, q->tri + 3 * (size_t)sub * t, 3 * sizeof *c);
  *ncell = nc, *cells = c;
  return VES_OK;
}

/* Copies of the caller's points, weights and (optional) triangles. */
ves_status ves_quad_create_points(int nq, const double *x, const double *w, int ntri,
                                  const int *tri, ves_quad **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(nq >= 1 && x && w && ntri >= 0 && (ntri == 0 || tri), VES_ERR_ARG);
  VES_CHECK(ntri == 0 || nq == VES_QUAD_NPT * ntri, VES_ERR_ARG);
  for (int p = 0; p < nq; p++)
    VES_CHECK(isfinite(x[2 * p]) && isfinite(x[2 * p + 1]) && isfinite(w[p]) && w[p] > 0,
              VES_ERR_ARG);
  for (int k = 0; k < 3 * ntri; k++) VES_CHECK(tri[k] >= 0, VES_ERR_ARG);
  ves_quad *q = calloc(1, sizeof *q);
  if (!q) return VES_ERR_ALLOC;
  q->ntri = ntri, q->nq = nq;
  q->tri = malloc((ntri ? 3 * (size_t)ntri : 1) * sizeof *q->tri);
  q->x = malloc(2 * (size_t)nq * sizeof *q->x);
  q->w = malloc((size_t)nq * sizeof *q->w);
  if (!q->tri || !q->x || !q->w) {
    ves_quad_destroy(&q);
    return VES_ERR_ALLOC;
  }
  if (ntri) memcpy(q->tri, tri, 3 * (size_t)ntri * sizeof *q->tri);
  memcpy(q->x, x, 2 * (size_t)nq * sizeof *q->x);
  memcpy(q->w, w, (size_t)nq * sizeof *q->w);
  *out = q;
  return VES_OK;
}

ves_status ves_quad_create_at_nodes(const ves_nodes *nodes, ves_quad **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(nodes && nodes->n >= 1, VES_ERR_ARG);
  const int n = nodes->n;
  double *x = malloc(2 * (size_t)n * sizeof *x), *w = malloc((size_t)n * sizeof *w);
  ves_status s = VES_ERR_ALLOC;
  if (x && w) {
    for (int a = 0; a < n; a++) {
      const double d = 1e-3 * nodes->h[a];
      double R = nodes->x[2 * a], Z = nodes->x[2 * a + 1];
      if (nodes->flag[a] & VES_NODE_WALL) { /* off the hull, inwards */
        if (R >= nodes->LR - d) R = nodes->LR - d;
        if (Z >= nodes->LZ - d) Z = nodes->LZ - d;
        if (Z <= -nodes->LZ + d) Z = -nodes->LZ + d;
      }
      x[2 * a] = R, x[2 * a + 1] = Z, w[a] = 1.0;
    }
    s = ves_quad_create_points(n, x, w, 0, NULL, out);
  }
  free(x), free(w);
  return s;
}

/* Grow *buf to hold at least need elements of size sz (capacity in *cap). */
static int grow(void **buf, size_t *cap, size_t need, size_t sz) {
  if (need <= *cap) return 0;
  size_t c = *cap ? *cap : 1024;
  while (c < need) c *= 2;
  void *p = ves_big_realloc(*buf, *cap * sz, c * sz);
  if (!p) return -1;
  *buf = p;
  *cap = c;
  return 0;
}

/* One thread's part of the tables build. */
typedef struct {
  int *idx;      /* query output, cap entries */
  int cap;       /* capacity of idx */
  int *nb;       /* the thread's neighbour lists (extended indices), one after the other */
  size_t cap_nb; /* capacity of nb */
  int g0, g1;    /* its groups [g0, g1) in pass 1 */
  int m_max;     /* longest list among them */
  ves_status s;  /* first failure in pass 1 */
} tables_ws;

/* Query the search at X (near != 0: the candidates within rho of X) into
 * w->idx, enlarging it as needed; *cnt the number of hits. */
static ves_status tables_query(const ves_geom_search *search, const double X[2], int near,
                               double rho, tables_ws *w, int *cnt) {
  for (;;) {
    ves_status s = near ? ves_geom_search_query_near(search, X, rho, w->cap, w->idx, cnt)
                        : ves_geom_search_query(search, X, w->cap, w->idx, cnt);
    if (s != VES_OK || *cnt <= w->cap) return s;
    int *tmp = realloc(w->idx, 2 * (size_t)*cnt * sizeof *tmp); /* rare: enlarge, ask again */
    if (!tmp) return VES_ERR_ALLOC;
    w->idx = tmp, w->cap = 2 * *cnt;
  }
}

/* Pass 1 for the groups [w->g0, w->g1) of gs points (a triangle's, or single
 * points): every point's neighbours a (real and ghost) with |X - x_a| <= r_a,
 * ascending, appended to w->nb, the counts in cnt[p]. A triangle's points are
 * found among the candidates of one query at their centre C, within
 * rho = max |X - C| of it (|X - x_a| <= r_a implies |C - x_a| <= r_a + rho),
 * by the same exact test as a query at each point: the same lists. */
static void tables_search(const ves_quad *q, const ves_geom_search *search, int gs, tables_ws *w,
                          int *cnt) {
  size_t used = 0;
  for (int g = w->g0; g < w->g1; g++) {
    const int p0 = gs * g, p1 = p0 + gs < q->nq ? p0 + gs : q->nq;
    double C[2] = {0.0, 0.0}, rho = 0.0;
    int nc = 0;
    ves_status s = VES_OK;
    if (p1 - p0 > 1) {
      for (int p = p0; p < p1; p++) C[0] += q->x[2 * p], C[1] += q->x[2 * p + 1];
      C[0] /= p1 - p0, C[1] /= p1 - p0;
      for (int p = p0; p < p1; p++)
        rho = fmax(rho, hypot(q->x[2 * p] - C[0], q->x[2 * p + 1] - C[1]));
      s = tables_query(search, C, 1, rho * (1.0 + 1e-12), w, &nc); /* rho rounded up */
    }
    for (int p = p0; p < p1 && s == VES_OK; p++) {
      int c = 0;
      if (p1 - p0 > 1) { /* filter the candidates (they have room for all) */
        if (grow((void **)&w->nb, &w->cap_nb, used + nc, sizeof *w->nb))
          s = VES_ERR_ALLOC;
        else if (nc > 0)
          s = ves_geom_search_filter(search, q->x + 2 * p, nc, w->idx, w->nb + used, &c);
      } else {
        s = tables_query(search, q->x + 2 * p, 0, 0.0, w, &c);
        if (s == VES_OK && grow((void **)&w->nb, &w->cap_nb, used + c, sizeof *w->nb))
          s = VES_ERR_ALLOC;
        if (s == VES_OK && c > 0) memcpy(w->nb + used, w->idx, (size_t)c * sizeof *w->idx);
      }
      if (s != VES_OK) break;
      used += c;
      cnt[p] = c;
      if (c > w->m_max) w->m_max = c;
    }
    if (s != VES_OK) {
      w->s = s;
      return;
    }
  }
}

/* Pass 1 of ves_quad_tables: every point's neighbour list (extended
 * indices, ascending) into q->ptr and q->nbr, and room for q->mirror and
 * q->tab; *m_max_out the longest list. ws[nt]: the threads' workspaces (the
 * caller frees them). */
static ves_status tables_lists(ves_quad *q, const ves_geom_search *search, int gsize, int ngroup,
                               int nt, tables_ws *ws, int *m_max_out) {
  /* the lists of thread k's block of groups in ws[k].nb, counts in
   * ptr[p + 1]; then concatenated into nbr */
  for (int k = 0; k < nt; k++) {
    ws[k].cap = 256;
    ws[k].idx = malloc((size_t)ws[k].cap * sizeof *ws[k].idx);
    if (!ws[k].idx) return VES_ERR_ALLOC;
  }
#pragma omp parallel num_threads(nt)
  {
    const int k = ves_omp_tid(), T = ves_omp_nteam();
    ws[k].g0 = (int)((long)ngroup * k / T);
    ws[k].g1 = (int)((long)ngroup * (k + 1) / T);
    tables_search(q, search, gsize, ws + k, q->ptr + 1);
  }
  ves_status s = VES_OK;
  int m_max = 0;
  for (int k = 0; k < nt; k++) {
    if (ws[k].s != VES_OK && s == VES_OK) s = ws[k].s; /* the first block's failure */
    if (ws[k].m_max > m_max) m_max = ws[k].m_max;
  }
  if (s != VES_OK) return s;
  q->ptr[0] = 0;
  for (int p = 0; p < q->nq; p++) q->ptr[p + 1] += q->ptr[p];
  size_t nnz = (size_t)q->ptr[q->nq];
  q->nbr = ves_big_alloc(nnz * sizeof *q->nbr); /* nnz 0 is served (mem_impl.h) */
  q->mirror = ves_big_alloc(nnz);
  q->tab = ves_big_alloc(6 * nnz * sizeof *q->tab);
  if (!q->nbr || !q->mirror || !q->tab) return VES_ERR_ALLOC;
  for (int k = 0; k < nt; k++) {
    const int p0 = gsize * ws[k].g0 < q->nq ? gsize * ws[k].g0 : q->nq;
    const int p1 = gsize * ws[k].g1 < q->nq ? gsize * ws[k].g1 : q->nq;
    if (q->ptr[p1] > q->ptr[p0])
      memcpy(q->nbr + q->ptr[p0], ws[k].nb, (size_t)(q->ptr[p1] - q->ptr[p0]) * sizeof *q->nbr);
    free(ws[k].nb);
    ws[k].nb = NULL;
  }
  *m_max_out = m_max;
  return VES_OK;
}

/* Pass 2 of ves_quad_tables: the ghost indices folded (q->nbr, q->mirror)
 * and the LME tables (q->tab) at every point, from the extended node
 * positions xe and their beta_e; the sum and the largest count of the
 * Newton iterations. */
static ves_status tables_eval(ves_quad *q, const ves_nodes *nodes, const ves_lme_params *lme,
                              const double *xe, const double *beta_e, int gsize, int ngroup,
                              int m_max, int nt, long *iter_sum_out, int *iter_max_out) {
  const int n = nodes->n;
  /* One group of points
   * (a triangle's, or a single point for a point set without triangles: it
   * is not ordered in space) per task. An error is reported for the lowest
   * failing point: groups above the lowest failure seen so far are skipped,
   * those below it all run, so the outcome does not depend on the threads. */
  int bad = q->nq;
  ves_status bad_s = VES_OK;
  long iter_sum = 0;
  int iter_max = 0;
#pragma omp parallel num_threads(nt) reduction(+ : iter_sum) reduction(max : iter_max)
  {
    double *xa = malloc(2 * (size_t)(m_max ? m_max : 1) * sizeof *xa);
    double *beta = malloc((size_t)(m_max ? m_max : 1) * sizeof *beta);
    double *work = malloc((size_t)(m_max ? ves_lme_work_size(m_max) : 1) * sizeof *work);
    if (!xa || !beta || !work) {
#pragma omp critical(ves_quad_tables_bad)
      {
#pragma omp atomic write
        bad = -1; /* ranks before every point: all groups are skipped */
        bad_s = VES_ERR_ALLOC;
      }
    }
#pragma omp for schedule(dynamic, 16)
    for (int g = 0; g < ngroup; g++) {
      int lowest;
#pragma omp atomic read
      lowest = bad;
      if (gsize * g > lowest) continue;
      double lambda[2] = {0.0, 0.0}; /* warm start along the group's points */
      const int pend = gsize * (g + 1) < q->nq ? gsize * (g + 1) : q->nq;
      for (int p = gsize * g; p < pend; p++) {
        const int m = q->ptr[p + 1] - q->ptr[p];
        int *nb = q->nbr + q->ptr[p];
        unsigned char *mir = q->mirror + q->ptr[p];
        for (int k = 0; k < m; k++) {
          const int a = nb[k];
          xa[2 * k] = xe[2 * a];
          xa[2 * k + 1] = xe[2 * a + 1];
          beta[k] = beta_e[a];
          nb[k] = a < n ? a : nodes->ghost_of[a - n]; /* fold: the ghost's real node */
          mir[k] = a >= n;
        }
        ves_lme_info li;
        ves_status sp = ves_lme_eval(lme, q->x + 2 * p, m, xa, beta, lambda, 2,
                                     q->tab + 6 * (size_t)q->ptr[p], work, &li);
        if (sp != VES_OK) {
#pragma omp critical(ves_quad_tables_bad)
          if (p < bad) {
#pragma omp atomic write
            bad = p;
            bad_s = sp;
          }
          break;
        }
        iter_sum += li.iterations;
        if (li.iterations > iter_max) iter_max = li.iterations;
      }
    }
    free(xa);
    free(beta);
    free(work);
  }
  *iter_sum_out = iter_sum, *iter_max_out = iter_max;
  return bad_s;
}

/* For each point: neighbours a (real and ghost) with |X - X_a| <= r_a, then
 * the LME table at X over exactly those neighbours. Both passes run on the
 * OpenMP threads: pass 1 (one search query per triangle, tables_search) in
 * contiguous blocks of triangles whose lists are then concatenated in point
 * order, pass 2 (the LME evaluations) over triangles, a triangle's points in
 * order with the warm start of lambda passed along them and lambda = 0 at its
 * first point. Every table therefore depends on its own triangle only, and
 * the tables are bit for bit the same for any number of threads. */
ves_status ves_quad_tables(ves_quad *q, const ves_nodes *nodes, const ves_lme_params *lme,
                           ves_quad_info *info) {
  VES_CHECK(q && nodes && lme, VES_ERR_ARG);
  double t0 = ves_wall_seconds();
  tables_free(q);
  const int n = nodes->n, ne = nodes->n + nodes->ng, nt = ves_omp_threads();
  ves_status s = VES_OK;
  ves_geom_search *search = NULL;
  double *xe = malloc(2 * (size_t)ne * sizeof *xe);
  double *rad = malloc((size_t)ne * sizeof *rad);
  double *beta_e = malloc((size_t)ne * sizeof *beta_e);
  tables_ws *ws = calloc((size_t)nt, sizeof *ws);
  q->ptr = malloc(((size_t)q->nq + 1) * sizeof *q->ptr);
  if (!xe || !rad || !beta_e || !ws || !q->ptr) {
    s = VES_ERR_ALLOC;
    goto done;
  }
  ves_nodes_extended(nodes, xe);
  for (int a = 0; a < ne; a++) {
    double h = nodes->h[a < n ? a : nodes->ghost_of[a - n]];
    rad[a] = ves_lme_radius(lme, h);
    beta_e[a] = lme->gamma / (h * h);
  }
  s = ves_geom_search_create(ne, xe, rad, &search);
  if (s != VES_OK) goto done;

  /* Pass 1: the neighbour lists (tables_lists). A group is a triangle's
   * points (their lists come from one query), or a single point for a point
   * set without triangles. */
  const int gsize = q->ntri ? VES_QUAD_NPT : 1, ngroup = (q->nq + gsize - 1) / gsize;
  int m_max = 0;
  if ((s = tables_lists(q, search, gsize, ngroup, nt, ws, &m_max)) != VES_OK) goto done;
  const size_t nnz = (size_t)q->ptr[q->nq];

  /* Pass 2: the tables (tables_eval). */
  long iter_sum = 0;
  int iter_max = 0;
  s = tables_eval(q, nodes, lme, xe, beta_e, gsize, ngroup, m_max, nt, &iter_sum, &iter_max);
  if (s != VES_OK) goto done;
  q->lme = *lme;
  if (info) {
    info->m_mean = q->nq ? (double)nnz / q->nq : 0.0;
    info->m_max = m_max;
    info->iter_mean = q->nq ? (double)iter_sum / q->nq : 0.0;
    info->iter_max = iter_max;
    info->seconds = ves_wall_seconds() - t0;
  }
done:
  if (s != VES_OK) tables_free(q);
  ves_geom_search_destroy(&search);
  free(xe);
  free(rad);
  free(beta_e);
  if (ws)
    for (int k = 0; k < nt; k++) free(ws[k].idx), free(ws[k].nb);
  free(ws);
  return s;
}

/* out[6 alpha + j] = sum_k T_jk c_{nbr_k} (a ghost entry uses its real node's
 * coefficient: the field is even in R). */
void ves_quad_field(const ves_quad *q, const double *c, int nder, double *out) {
  int rows = nder <= 0 ? 1 : nder == 1 ? 3 : 6;
#pragma omp parallel for schedule(static) /* points independent: the same sums on any threads */
  for (int p = 0; p < q->nq; p++) {
    int m = q->ptr[p + 1] - q->ptr[p];
    const int *nb = q->nbr + q->ptr[p];
    const double *t = q->tab + 6 * (size_t)q->ptr[p];
    for (int j = 0; j < rows; j++) {
      double s = 0.0;
      for (int k = 0; k < m; k++) s += t[j * m + k] * c[nb[k]];
      out[6 * (size_t)p + j] = s;
    }
  }
}

/* y_i(X_al) = sum_k T_jk s_k y_i(nbr_k), s_k = -1 for the r of a ghost entry
 * (r odd in R), else +1; rows j = value, d/dR, d/dZ, d2/dR2, d2/dRdZ, d2/dZ2. */
void ves_quad_motion(const ves_quad *q, const double *y, int al, int nder, double out[12]) {
  const int rows = nder <= 0 ? 1 : nder == 1 ? 3 : 6, m = q->ptr[al + 1] - q->ptr[al];
  const int *nb = q->nbr + q->ptr[al];
  const unsigned char *mir = q->mirror + q->ptr[al];
  const double *t = q->tab + 6 * (size_t)q->ptr[al];
  for (int j = 0; j < rows; j++) {
    double sr = 0.0, sz = 0.0;
    for (int k = 0; k < m; k++) {
      sr += t[j * m + k] * (mir[k] ? -y[2 * nb[k]] : y[2 * nb[k]]);
      sz += t[j * m + k] * y[2 * nb[k] + 1];
    }
    out[j] = sr, out[6 + j] = sz;
  }
}
