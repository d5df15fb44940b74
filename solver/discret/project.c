/* vesica — the structures that need a quadrature: the node-level block
 * pattern of the model's matrices (nodes coupled through a common point) and
 * the L2 projection of a field onto the LME space, the normal equations
 * M c = b, M_ab = sum_alpha w_alpha P_alpha,a P_alpha,b, solved with the
 * Cholesky factorization of ldl.h and iterative refinement (docs/design.md,
 * "Discretization"). */
#include "ves/project.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "core/mem_impl.h"
#include "core/omp_impl.h"
#include "ves/ldl.h"

/* The tables' value rows folded over ghosts, by groups of points: a
 * triangle's VES_QUAD_NPT points (single points for a point set without
 * triangles). Point alpha's folded list L_alpha holds its distinct real nodes
 * with P_alpha,a = p_a + p_ghost(a). Group g keeps the union U_g of its
 * points' lists, ascending, with a bit mask per node (bit k: the group's
 * point k sees it) and (with values) the dense gs x |U_g| matrix V_g of the
 * P_alpha,a, zero where point k does not see node a. A triangle's points see
 * nearly the same nodes (|U_g| ~ 1.1 m against gs m entries), so rows of the
 * node-level matrices run over ~5 times fewer (group, node) incidences than
 * (point, node) ones, each over a contiguous list. */
typedef struct {
  int ng;               /* groups */
  int gs;               /* points per group: group g holds points gs g .. gs g + gs - 1 */
  int *uptr;            /* ng + 1 offsets of the unions */
  int *unod;            /* uptr[ng] nodes: U_g at uptr[g] .. uptr[g+1]-1, ascending */
  unsigned char *umask; /* uptr[ng] masks, bit k for the group's point k */
  double *uval;         /* gs uptr[ng] values or NULL: V_g row k at gs uptr[g] + k |U_g| */
  int umax;             /* largest |U_g| */
  int *npt;             /* n + 1 offsets of the incidence node -> groups */
  int *tgrp;            /* npt[n] groups whose union holds node a, ascending */
  int *tpos;            /* npt[n] positions of a in unod for those groups */
} folded;

static void folded_free(folded *fo) {
  free(fo->uptr);
  free(fo->unod);
  free(fo->umask);
  free(fo->uval);
  free(fo->npt);
  free(fo->tgrp);
  free(fo->tpos);
  memset(fo, 0, sizeof *fo);
}

_Static_assert(VES_QUAD_NPT <= 8, "a group's point masks are bytes");

/* One thread's scratch for folding a group. */
typedef struct {
  int *nb;               /* gs m_max: the group's folded lists, point k's at k m_max */
  double *v;             /* gs m_max: their values (or NULL) */
  int cnt[VES_QUAD_NPT]; /* lengths of the folded lists */
  int *u[2];             /* 2 gs m_max: union being merged, and the merge target */
  unsigned char *mk[2];  /* their masks */
} fold_ws;

/* Fold and sort point alpha's list into nb (and v) (insertion sort: a list
 * comes as two ascending runs, real then ghost entries), merging a node's
 * real and ghost entries: P = p_a + p_ghost. Returns the length, -1 for a
 * node outside [0, n). */
static int fold_point(const ves_quad *q, int n, int al, int *nb, double *v) {
  const int k0 = q->ptr[al], m = q->ptr[al + 1] - k0;
  const double *p = q->tab + 6 * (size_t)k0; /* value row */
  int cnt = 0;
  for (int k = 0; k < m; k++) {
    int a = q->nbr[k0 + k], j = cnt - 1;
    if (a < 0 || a >= n) return -1;  /* tables not for these n nodes */
    while (j >= 0 && nb[j] > a) j--; /* insert a after position j */
    if (j >= 0 && nb[j] == a) {      /* the ghost twin of an entry */
      if (v) v[j] += p[k];
      continue;
    }
    for (int i = cnt; i > j + 1; i--) {
      nb[i] = nb[i - 1];
      if (v) v[i] = v[i - 1];
    }
    nb[j + 1] = a;
    if (v) v[j + 1] = p[k];
    cnt++;
  }
  return cnt;
}

/* Fold the points of group g into w and merge their lists: U_g with its masks
 * in w->u[0], w->mk[0]. Returns |U_g|, -1 for a node outside [0, n). */
static int fold_group(const ves_quad *q, int n, int gs, int m_max, int g, fold_ws *w) {
  int len = 0;
  for (int k = 0; k < gs; k++) {
    int *L = w->nb + (size_t)k * m_max, c;
    if ((c = fold_point(q, n, gs * g + k, L, w->v ? w->v + (size_t)k * m_max : NULL)) < 0)
      return -1;
    w->cnt[k] = c;
    const int *U = w->u[0];
    const unsigned char *M = w->mk[0];
    const unsigned char bit = (unsigned char)(1u << k);
    int *O = w->u[1], i = 0, j = 0, o = 0;
    unsigned char *MO = w->mk[1];
    while (i < len || j < c) { /* merge U and L_k, both ascending */
      if (j == c || (i < len && U[i] < L[j]))
        O[o] = U[i], MO[o++] = M[i++];
      else if (i == len || L[j] < U[i])
        O[o] = L[j++], MO[o++] = bit;
      else
        O[o] = U[i], MO[o++] = M[i++] | bit, j++;
    }
    len = o;
    int *t = w->u[0];
    unsigned char *tm = w->mk[0];
    w->u[0] = w->u[1], w->mk[0] = w->mk[1], w->u[1] = t, w->mk[1] = tm;
  }
  return len;
}

/* The grouped folded lists and their transpose, on the OpenMP threads: thread
 * k takes a contiguous block of groups; pass 1 sizes the unions, pass 2 folds
 * again and stores them, counting its nodes in cnt[k n + a]; the counts give
 * every thread its slots per node after those of the blocks before it, so the
 * transpose (pass 3) comes out in group order for any number of threads.
 * Long, on purpose: the three passes are one parallel region whose threads
 * keep their block of groups and their counts across the barriers; in
 * helpers each pass would take that whole shared state as arguments. */
static ves_status folded_create(const ves_quad *q, int n, int with_values, folded *fo) {
  memset(fo, 0, sizeof *fo);
  const int nt = ves_omp_threads();
  fo->gs = q->ntri > 0 && q->nq == VES_QUAD_NPT * q->ntri ? VES_QUAD_NPT : 1;
  fo->ng = q->nq / fo->gs;
  const int gs = fo->gs, ng = fo->ng;
  int m_max = 1;
  for (int al = 0; al < q->nq; al++)
    if (q->ptr[al + 1] - q->ptr[al] > m_max) m_max = q->ptr[al + 1] - q->ptr[al];
  fo->uptr = malloc(((size_t)ng + 1) * sizeof *fo->uptr);
  fo->npt = calloc((size_t)n + 1, sizeof *fo->npt);
  int *cnt = calloc((size_t)nt * n, sizeof *cnt);
  fold_ws *ws = calloc((size_t)nt, sizeof *ws);
  int bad_arg = 0, bad_alloc = !fo->uptr || !fo->npt || !cnt || !ws;
  const size_t sc = (size_t)gs * m_max;
  for (int k = 0; k < nt && !bad_alloc; k++) {
    fold_ws *w = ws + k;
    w->nb = malloc(sc * sizeof *w->nb);
    w->v = with_values ? malloc(sc * sizeof *w->v) : NULL;
    w->u[0] = malloc(sc * sizeof *w->u[0]), w->u[1] = malloc(sc * sizeof *w->u[1]);
    w->mk[0] = malloc(sc), w->mk[1] = malloc(sc);
    bad_alloc = !w->nb || (with_values && !w->v) || !w->u[0] || !w->u[1] || !w->mk[0] || !w->mk[1];
  }
  if (bad_alloc) goto done;
  fo->uptr[0] = 0;
#pragma omp parallel num_threads(nt)
  {
    const int k = ves_omp_tid(), T = ves_omp_nteam();
    const int g0 = (int)((long)ng * k / T), g1 = (int)((long)ng * (k + 1) / T);
    fold_ws *w = ws + k;
    double *vk = w->v;
    int *ck = cnt + (size_t)k * n;
    w->v = NULL; /* pass 1: the lengths only */
    for (int g = g0; g < g1; g++) {
      const int len = fold_group(q, n, gs, m_max, g, w);
      if (len < 0) {
#pragma omp atomic write
        bad_arg = 1;
      }
      fo->uptr[g + 1] = len < 0 ? 0 : len;
    }
    w->v = vk;
#pragma omp barrier
#pragma omp single
    if (!bad_arg) {
      for (int g = 0; g < ng; g++) {
        if (fo->uptr[g + 1] > fo->umax) fo->umax = fo->uptr[g + 1];
        fo->uptr[g + 1] += fo->uptr[g];
      }
      const size_t tot = (size_t)fo->uptr[ng] + 1;
      fo->unod = ves_big_alloc(tot * sizeof *fo->unod);
      fo->umask = ves_big_alloc(tot);
      fo->uval = with_values ? ves_big_calloc((size_t)gs * tot, sizeof *fo->uval) : NULL;
      bad_alloc = !fo->unod || !fo->umask || (with_values && !fo->uval);
    }
    /* pass 2: the unions, masks and values; node counts per thread */
    for (int g = g0; g < g1 && !bad_arg && !bad_alloc; g++) {
      const int e0 = fo->uptr[g], len = fold_group(q, n, gs, m_max, g, w);
      memcpy(fo->unod + e0, w->u[0], (size_t)len * sizeof *fo->unod);
      memcpy(fo->umask + e0, w->mk[0], (size_t)len);
      for (int e = 0; e < len; e++) ck[w->u[0][e]]++;
      if (!fo->uval) continue;
      for (int kk = 0; kk < gs; kk++) { /* V_g row kk: L_kk is a subsequence of U_g */
        const int *L = w->nb + (size_t)kk * m_max;
        const double *v = w->v + (size_t)kk * m_max;
        double *V = fo->uval + (size_t)gs * e0 + (size_t)kk * len;
        for (int j = 0, e = 0; j < w->cnt[kk]; j++) {
          while (w->u[0][e] < L[j]) e++;
          V[e] = v[j];
        }
      }
    }
#pragma omp barrier
#pragma omp single
    if (!bad_arg && !bad_alloc) { /* slots: node a's groups of block j after those of blocks < j */
      for (int a = 0; a < n; a++) {
        int off = fo->npt[a];
        for (int j = 0; j < T; j++) {
          const int c = cnt[(size_t)j * n + a];
          cnt[(size_t)j * n + a] = off;
          off += c;
        }
        fo->npt[a + 1] = off;
      }
      fo->tgrp = ves_big_alloc(((size_t)fo->npt[n] + 1) * sizeof *fo->tgrp);
      fo->tpos = ves_big_alloc(((size_t)fo->npt[n] + 1) * sizeof *fo->tpos);
      bad_alloc = !fo->tgrp || !fo->tpos;
    }
    /* pass 3: the transpose */
    for (int g = g0; g < g1 && !bad_arg && !bad_alloc; g++)
      for (int e = fo->uptr[g]; e < fo->uptr[g + 1]; e++) {
        const int u = ck[fo->unod[e]]++;
        fo->tgrp[u] = g, fo->tpos[u] = e;
      }
  }
done:
  if (ws)
    for (int k = 0; k < nt; k++)
      free(ws[k].nb), free(ws[k].v), free(ws[k].u[0]), free(ws[k].u[1]), free(ws[k].mk[0]),
          free(ws[k].mk[1]);
  free(ws);
  free(cnt);
  if (bad_arg || bad_alloc) {
    folded_free(fo);
    return bad_arg ? VES_ERR_ARG : VES_ERR_ALLOC;
  }
  return VES_OK;
}

/* Sort x[0 .. n-1] ascending: quicksort (median of three, the smaller part
 * first, so the stack stays O(log n)) down to runs of 16, then one insertion
 * sort; rows hold a few hundred distinct columns. */
static void sort_int(int *x, int n) {
  int lo_st[64], hi_st[64], top = 0, lo = 0, hi = n - 1;
  for (;;) {
    while (hi - lo > 16) {
      const int mid = lo + (hi - lo) / 2;
      int t;
      if (x[mid] < x[lo]) t = x[mid], x[mid] = x[lo], x[lo] = t;
      if (x[hi] < x[lo]) t = x[hi], x[hi] = x[lo], x[lo] = t;
      if (x[hi] < x[mid]) t = x[hi], x[hi] = x[mid], x[mid] = t;
      const int pv = x[mid];
      int i = lo, j = hi;
      while (i <= j) { /* Hoare partition: x[lo..j] <= pv <= x[i..hi] */
        while (x[i] < pv) i++;
        while (x[j] > pv) j--;
        if (i <= j) t = x[i], x[i] = x[j], x[j] = t, i++, j--;
      }
      if (j - lo < hi - i)
        lo_st[top] = i, hi_st[top++] = hi, hi = j; /* larger part later */
      else
        lo_st[top] = lo, hi_st[top++] = j, lo = i;
    }
    if (!top) break;
    top--, lo = lo_st[top], hi = hi_st[top];
  }
  for (int a = 1; a < n; a++) { /* runs of <= 17 left: insertion sort */
    const int v = x[a];
    int b = a - 1;
    while (b >= 0 && x[b] > v) x[b + 1] = x[b], b--;
    x[b + 1] = v;
  }
}

/* Rows per task of node_pattern. */
#define PATTERN_CHUNK 64

/* One thread's rows of node_pattern: their columns one chunk after another. */
typedef struct {
  int *mark;   /* n: mark[b] == a once b is in row a */
  int *col;    /* the columns of the thread's chunks */
  size_t cap;  /* capacity of col */
  size_t used; /* entries in col */
  int fail;    /* an allocation failed */
} pattern_ws;

/* Row a of the node-level lower pattern appended to w->col: the union over
 * the groups g whose union U_g holds a of the nodes b <= a (the head of U_g up
 * to a) that share a point of g with a (masks intersect), ascending. Returns
 * the row's length, -1 if an allocation failed. */
static int pattern_row(const folded *fos, int nfo, int a, pattern_ws *w) {
  const size_t start = w->used;
  int *mark = w->mark;
  for (int f = 0; f < nfo; f++) { /* the union over the point sets */
    const folded *fo = fos + f;
    const int *unod = fo->unod;
    const unsigned char *umask = fo->umask;
    for (int u = fo->npt[a]; u < fo->npt[a + 1]; u++) {
      const int e0 = fo->uptr[fo->tgrp[u]], ea = fo->tpos[u];
      const unsigned char ma = umask[ea];
      if (w->cap - w->used < (size_t)(ea - e0 + 1)) { /* room for the whole head */
        size_t c = w->cap ? 2 * w->cap : 1 << 16;
        while (c - w->used < (size_t)(ea - e0 + 1)) c *= 2;
        int *tmp = ves_big_realloc(w->col, w->cap * sizeof *tmp, c * sizeof *tmp);
        if (!tmp) return -1;
        w->col = tmp, w->cap = c;
      }
      int *col = w->col;
      size_t used = w->used;
      for (int e = e0; e <= ea; e++) {
        const int b = unod[e];
        if (!(umask[e] & ma) || mark[b] == a) continue;
        mark[b] = a;
        col[used++] = b;
      }
      w->used = used;
    }
  }
  sort_int(w->col + start, (int)(w->used - start));
  return (int)(w->used - start);
}

/* Node-level lower pattern: row a = union over the points alpha that see a of
 * the nodes b <= a that alpha sees, columns ascending (pattern_row). Chunks
 * of rows on the OpenMP threads, each into its thread's buffer, then copied
 * into place in row order: the same arrays for any number of threads. Once
 * per configuration. */
static ves_status node_pattern(const folded *fos, int nfo, int n, int **ptr_out, int **col_out) {
  const int nt = ves_omp_threads(), nchunk = (n + PATTERN_CHUNK - 1) / PATTERN_CHUNK;
  int *ptr = calloc((size_t)n + 1, sizeof *ptr), *col = NULL;
  int *chunk_thr = malloc(((size_t)nchunk + 1) * sizeof *chunk_thr);
  size_t *chunk_off = malloc(((size_t)nchunk + 1) * sizeof *chunk_off);
  pattern_ws *ws = calloc((size_t)nt, sizeof *ws);
  ves_status s = VES_ERR_ALLOC;
  int fail = !ptr || !chunk_thr || !chunk_off || !ws;
  for (int k = 0; k < nt && !fail; k++) {
    ws[k].mark = malloc((size_t)n * sizeof *ws[k].mark);
    if (!ws[k].mark)
      fail = 1;
    else
      for (int a = 0; a < n; a++) ws[k].mark[a] = -1;
  }
  if (fail) goto done;
#pragma omp parallel num_threads(nt)
  {
    pattern_ws *w = ws + ves_omp_tid();
#pragma omp for schedule(dynamic, 1)
    for (int c = 0; c < nchunk; c++) {
      chunk_thr[c] = ves_omp_tid();
      chunk_off[c] = w->used;
      const int a1 = (c + 1) * PATTERN_CHUNK < n ? (c + 1) * PATTERN_CHUNK : n;
      for (int a = c * PATTERN_CHUNK; a < a1 && !w->fail; a++) {
        const int len = pattern_row(fos, nfo, a, w);
        if (len < 0)
          w->fail = 1;
        else
          ptr[a + 1] = len;
      }
    }
  }
  for (int k = 0; k < nt; k++) fail |= ws[k].fail;
  if (fail) goto done;
  for (int a = 0; a < n; a++) ptr[a + 1] += ptr[a];
  col = ves_big_alloc(((size_t)ptr[n] + 1) * sizeof *col);
  if (!col) goto done;
#pragma omp parallel for num_threads(nt) schedule(static)
  for (int c = 0; c < nchunk; c++) {
    const int a0 = c * PATTERN_CHUNK, a1 = a0 + PATTERN_CHUNK < n ? a0 + PATTERN_CHUNK : n;
    if (ptr[a1] > ptr[a0])
      memcpy(col + ptr[a0], ws[chunk_thr[c]].col + chunk_off[c],
             (size_t)(ptr[a1] - ptr[a0]) * sizeof *col);
  }
  s = VES_OK;
done:
  if (ws)
    for (int k = 0; k < nt; k++) free(ws[k].mark), free(ws[k].col);
  free(ws);
  free(chunk_thr);
  free(chunk_off);
  if (s != VES_OK) free(ptr), free(col), ptr = col = NULL;
  *ptr_out = ptr;
  *col_out = col;
  return s;
}

ves_status ves_pattern_create(const ves_quad *q, const ves_quad *q2, int n,
                              const unsigned char *fixed, ves_pattern **out) {
  VES_CHECK(q && q->tab && (!q2 || q2->tab) && fixed && out && n > 0, VES_ERR_ARG);
  *out = NULL;
  folded fo[2] = {{0}, {0}};
  const int nfo = q2 ? 2 : 1;
  ves_pattern *p = calloc(1, sizeof *p);
  ves_status s = p ? folded_create(q, n, 0, fo) : VES_ERR_ALLOC;
  if (s == VES_OK && q2) s = folded_create(q2, n, 0, fo + 1);
  if (s != VES_OK) goto fail;
  p->n = n;
  s = node_pattern(fo, nfo, n, &p->ptr, &p->col);
  folded_free(fo), folded_free(fo + 1); /* not needed past the node pattern */
  if (s != VES_OK) goto fail;
  s = VES_ERR_ALLOC;
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
            if (di < 0 || dj < 0 || (a == b && j > i))
              continue; /* fixed, or upper half of a diagonal block */
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
      p->irow = ves_big_alloc(((size_t)cnt + 1) * sizeof *p->irow);
      p->jcol = ves_big_alloc(((size_t)cnt + 1) * sizeof *p->jcol);
      p->src = ves_big_alloc(((size_t)cnt + 1) * sizeof *p->src);
      if (!p->irow || !p->jcol || !p->src) goto fail;
    }
  }
  s = VES_OK;
  *out = p;
  p = NULL;
fail:
  ves_pattern_destroy(&p);
  folded_free(fo), folded_free(fo + 1);
  return s;
}

/* ---- L2 projection ---- */

/* y = M x, M symmetric given by its lower CSR (ptr, col, val). */
static void csr_symv(int n, const int *ptr, const int *col, const double *val, const double *x,
                     double *y) {
  for (int a = 0; a < n; a++) y[a] = 0.0;
  for (int a = 0; a < n; a++)
    for (int t = ptr[a]; t < ptr[a + 1]; t++) {
      int b = col[t];
      y[a] += val[t] * x[b];
      if (b != a) y[b] += val[t] * x[a]; /* the mirrored upper entry */
    }
}

/* Relative residual |b - M c| / |b|, r = b - M c. */
static double residual(int n, const int *ptr, const int *col, const double *val, const double *b,
                       const double *c, double bnorm, double *r) {
  csr_symv(n, ptr, col, val, c, r);
  double rn = 0.0;
  for (int a = 0; a < n; a++) r[a] = b[a] - r[a], rn += r[a] * r[a];
  return bnorm > 0 ? sqrt(rn) / bnorm : sqrt(rn);
}

/* M of ves_project_l2 (val on the pattern ptr/col, with the rows irow; 1
 * when a workspace could not be allocated; b: right_hand_side), row by row on the
 * OpenMP threads. Row a: each point alpha that sees a, in ascending order, adds w P_alpha,a
 * P_alpha,b to (a, b) for the nodes b <= a it sees. By groups: the
 * head of U_g up to a is gathered from the row, each point k of g that sees a adds w P_k,a V_g(k,
 * .) to it (a zero of V_g adds nothing), and it is scattered back. Every entry is thus summed in
 * point order, the same sums for any number of threads. */
static int normal_equations(const ves_quad *q, const folded *fo, int n, const int *ptr,
                            const int *col, int *irow, double *val) {
  int fail = 0;
#pragma omp parallel num_threads(ves_omp_threads())
  {
    int *pos = malloc((size_t)n * sizeof *pos); /* column -> slot in row a */
    double *acc = malloc((size_t)(fo->umax ? fo->umax : 1) * sizeof *acc); /* a head of a row */
    if (!pos || !acc) {
#pragma omp atomic write
      fail = 1;
    }
#pragma omp for schedule(dynamic, 16)
    for (int a = 0; a < n; a++) {
      if (!pos || !acc) continue;
      for (int t = ptr[a]; t < ptr[a + 1]; t++) pos[col[t]] = t, irow[t] = a;
      for (int u = fo->npt[a]; u < fo->npt[a + 1]; u++) {
        const int g = fo->tgrp[u], e0 = fo->uptr[g], len = fo->uptr[g + 1] - e0,
                  ka = fo->tpos[u] - e0;
        const int *U = fo->unod + e0;
        const unsigned char *msk = fo->umask + e0, ma = msk[ka];
        const double *V = fo->uval + (size_t)fo->gs * e0;
        for (int i = 0; i <= ka; i++) /* (a, U_i) is in the row if a point sees both */
          acc[i] = msk[i] & ma ? val[pos[U[i]]] : 0.0;
        for (int k = 0; k < fo->gs; k++) {
          if (!(ma >> k & 1)) continue; /* point k does not see a */
          const int al = fo->gs * g + k;
          const double *Vk = V + (size_t)k * len, wPa = q->w[al] * Vk[ka];
#pragma omp simd
          for (int i = 0; i <= ka; i++) acc[i] += wPa * Vk[i];
        }
        for (int i = 0; i <= ka; i++)
          if (msk[i] & ma) val[pos[U[i]]] = acc[i];
      }
    }
    free(pos);
    free(acc);
  }
  return fail;
}

/* b_a = sum_alpha w_alpha P_alpha,a f_alpha, the right-hand side of the
 * normal equations (normal_equations forms M on the same folded rows). */
static void right_hand_side(const ves_quad *q, const folded *fo, int n, const double *f,
                            double *b) {
#pragma omp parallel for schedule(dynamic, 16) num_threads(ves_omp_threads())
  for (int a = 0; a < n; a++) {
    double ba = 0.0;
    for (int u = fo->npt[a]; u < fo->npt[a + 1]; u++) {
      const int g = fo->tgrp[u], e0 = fo->uptr[g], len = fo->uptr[g + 1] - e0,
                ka = fo->tpos[u] - e0;
      const unsigned char ma = fo->umask[e0 + ka];
      const double *V = fo->uval + (size_t)fo->gs * e0;
      for (int k = 0; k < fo->gs; k++) {
        if (!(ma >> k & 1)) continue;
        const int al = fo->gs * g + k;
        ba += q->w[al] * V[(size_t)k * len + ka] * f[al];
      }
    }
    b[a] = ba;
  }
}

ves_status ves_project_l2(const ves_quad *q, int n, const double *f, double *c, double rtol,
                          int maxref, int *refinements, double *relres) {
  return ves_project_l2_fields(q, n, 1, f, c, rtol, maxref, refinements, relres);
}

ves_status ves_project_l2_fields(const ves_quad *q, int n, int nf, const double *f, double *c,
                                 double rtol, int maxref, int *refinements, double *relres) {
  VES_CHECK(q && q->tab && f && c && n > 0 && nf > 0 && rtol >= 0 && maxref >= 0, VES_ERR_ARG);
  folded fo = {0};
  int *ptr = NULL, *col = NULL, *irow = NULL;
  double *val = NULL, *b = NULL, *r = NULL, *cbest = NULL;
  ves_ldl *ldl = NULL;
  ves_status s;
  double worst = 0.0;
  if ((s = folded_create(q, n, 1, &fo)) != VES_OK) goto done;
  for (int a = 0; a < n; a++)
    if (fo.npt[a + 1] == fo.npt[a]) { /* a node no point sees: M singular */
      s = VES_ERR_SINGULAR;
      goto done;
    }
  if ((s = node_pattern(&fo, 1, n, &ptr, &col)) != VES_OK) goto done;
  s = VES_ERR_ALLOC;
  int nnz = ptr[n];
  irow = malloc((size_t)nnz * sizeof *irow);
  val = calloc((size_t)nnz, sizeof *val);
  b = calloc((size_t)nf * n, sizeof *b);
  r = malloc((size_t)n * sizeof *r);
  cbest = malloc((size_t)n * sizeof *cbest);
  if (!irow || !val || !b || !r || !cbest) goto done;

  /* M (normal_equations) and each field's b = P^T W f */
  int fail = normal_equations(q, &fo, n, ptr, col, irow, val);
  if (fail) goto done;
  for (int k = 0; k < nf; k++) right_hand_side(q, &fo, n, f + (size_t)k * q->nq, b + (size_t)k * n);
  folded_free(&fo); /* no longer needed: free it before the factorization */

  /* c = M^-1 b by Cholesky, then refinement c += M^-1 (b - M c), per field */
  if ((s = ves_ldl_create(n, nnz, irow, col, 1, &ldl)) != VES_OK) goto done;
  if ((s = ves_ldl_factor(ldl, val)) != VES_OK) goto done;
  for (int k = 0; k < nf; k++) {
    const double *bk = b + (size_t)k * n;
    double *ck = c + (size_t)k * n, bnorm = 0.0;
    for (int a = 0; a < n; a++) bnorm += bk[a] * bk[a];
    bnorm = sqrt(bnorm);
    memcpy(ck, bk, (size_t)n * sizeof *ck);
    if ((s = ves_ldl_solve(ldl, ck)) != VES_OK) goto done;
    double res = residual(n, ptr, col, val, bk, ck, bnorm, r), best = res;
    memcpy(cbest, ck, (size_t)n * sizeof *ck);
    int it = 0;
    while (res > rtol && it < maxref) {
      if ((s = ves_ldl_solve(ldl, r)) != VES_OK) goto done; /* r = M^-1 (b - M c) */
      for (int a = 0; a < n; a++) ck[a] += r[a];
      it++;
      res = residual(n, ptr, col, val, bk, ck, bnorm, r);
      if (!(res < best)) break; /* stagnation at rounding level (or NaN) */
      best = res;
      memcpy(cbest, ck, (size_t)n * sizeof *ck);
    }
    memcpy(ck, cbest, (size_t)n * sizeof *ck);
    if (refinements) refinements[k] = it;
    if (relres) relres[k] = best;
    worst = k == 0 || !(best <= worst) ? best : worst;
  }
  s = worst <= rtol ? VES_OK : VES_MAXITER;
done:
  folded_free(&fo);
  free(ptr);
  free(col);
  free(irow);
  free(val);
  free(b);
  free(r);
  free(cbest);
  ves_ldl_destroy(&ldl);
  return s;
}

/* ves_projector: the projection's M factorized once for repeated fields on
 * the same points (the profile's restoration, profile.h). */
struct ves_projector {
  const ves_quad *q;
  int n, *ptr, *col, *irow;
  double *val, *r, *cbest;
  folded fo;
  ves_ldl *ldl;
};

void ves_projector_destroy(ves_projector **p) {
  if (!p || !*p) return;
  folded_free(&(*p)->fo);
  free((*p)->ptr), free((*p)->col), free((*p)->irow), free((*p)->val);
  free((*p)->r), free((*p)->cbest);
  ves_ldl_destroy(&(*p)->ldl);
  free(*p);
  *p = NULL;
}

ves_status ves_projector_create(const ves_quad *q, int n, ves_projector **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(q && q->tab && n > 0, VES_ERR_ARG);
  ves_projector *p = calloc(1, sizeof *p);
  if (!p) return VES_ERR_ALLOC;
  p->q = q, p->n = n;
  ves_status s;
  if ((s = folded_create(q, n, 1, &p->fo)) != VES_OK) goto fail;
  for (int a = 0; a < n; a++)
    if (p->fo.npt[a + 1] == p->fo.npt[a]) {
      s = VES_ERR_SINGULAR;
      goto fail;
    }
  if ((s = node_pattern(&p->fo, 1, n, &p->ptr, &p->col)) != VES_OK) goto fail;
  s = VES_ERR_ALLOC;
  const int nnz = p->ptr[n];
  p->irow = malloc((size_t)nnz * sizeof *p->irow);
  p->val = calloc((size_t)nnz, sizeof *p->val);
  p->r = malloc((size_t)n * sizeof *p->r);
  p->cbest = malloc((size_t)n * sizeof *p->cbest);
  if (!p->irow || !p->val || !p->r || !p->cbest) goto fail;
  if (normal_equations(q, &p->fo, n, p->ptr, p->col, p->irow, p->val)) goto fail;
  if ((s = ves_ldl_create(n, nnz, p->irow, p->col, 1, &p->ldl)) != VES_OK) goto fail;
  if ((s = ves_ldl_factor(p->ldl, p->val)) != VES_OK) goto fail;
  *out = p;
  return VES_OK;
fail:
  ves_projector_destroy(&p);
  return s;
}

ves_status ves_projector_apply(ves_projector *p, const double *f, double *c, double rtol,
                               int maxref) {
  VES_CHECK(p && f && c && rtol >= 0 && maxref >= 0, VES_ERR_ARG);
  const int n = p->n;
  double *b = malloc((size_t)n * sizeof *b);
  if (!b) return VES_ERR_ALLOC;
  right_hand_side(p->q, &p->fo, n, f, b);
  double bnorm = 0.0;
  for (int a = 0; a < n; a++) bnorm += b[a] * b[a];
  bnorm = sqrt(bnorm);
  memcpy(c, b, (size_t)n * sizeof *c);
  ves_status s = ves_ldl_solve(p->ldl, c);
  if (s == VES_OK) {
    double res = residual(n, p->ptr, p->col, p->val, b, c, bnorm, p->r), best = res;
    memcpy(p->cbest, c, (size_t)n * sizeof *c);
    for (int it = 0; res > rtol && it < maxref; it++) {
      if ((s = ves_ldl_solve(p->ldl, p->r)) != VES_OK) break;
      for (int a = 0; a < n; a++) c[a] += p->r[a];
      res = residual(n, p->ptr, p->col, p->val, b, c, bnorm, p->r);
      if (!(res < best)) break;
      best = res;
      memcpy(p->cbest, c, (size_t)n * sizeof *c);
    }
    memcpy(c, p->cbest, (size_t)n * sizeof *c);
    if (s == VES_OK) s = best <= rtol ? VES_OK : VES_MAXITER;
  }
  free(b);
  return s;
}
