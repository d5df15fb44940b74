/* vesica — private: the model object (struct ves_model) and what its four
 * files share: model.c (the API and the physics: create, the evaluation
 * entry points, parameters), model_assemble.c (the assembly kernel: folding,
 * kinematics, the per-triangle products and their scatter, the threaded
 * loops), model_threads.c (the thread scheduling: the Morton order of the
 * triangles and the slabs in Z) and model_drift.c (the constant drift-damping
 * and stabilization matrices). docs/design.md, "Discretization". */
#ifndef VES_MODEL_CORE_IMPL_H
#define VES_MODEL_CORE_IMPL_H

#include "ves/model.h"
#include "ves/project.h"

#include <math.h>

#include "model/model_impl.h"

#define NPT VES_QUAD_NPT /* points per triangle: the unit of assembly */
#define NB 11            /* largest nr + nz (MAP_Q) */

/* Per-thread workspace (allocated at create; cap = NPT mmax bounds the
 * union of a triangle's node lists, numax is the largest union). */
typedef struct {
  int *un;         /* NPT x mmax: folded node lists of a triangle's points */
  double *Tr, *Tz; /* NPT x 6 mmax: folded tables */
  int *stamp;      /* n: fold_point's duplicate marks, -1 when free */
  int *slot;       /* n: position of a node in a point's list, then in the union */
  int *U, *Utmp;   /* cap: the triangle's union node list (ascending), merge buffer */
  double *X;       /* NPT NB x numax: the stacked B of a triangle (triangle_xy) */
  double *Y;       /* NPT (NB + 6) x numax: its products with the local Hessians */
  double *M;       /* 3 numax^2: the triangle's Mrr, Mrz, Mzz (triangle_blocks) */
  double *yl;      /* 4 mmax: a point's gathered y, then its gradient rows */
} model_ws;

/* One folded point of a triangle (pointers into the table or the workspace). */
typedef struct {
  int mu;                /* unique real nodes */
  const double *Tr, *Tz; /* folded tables, 6 x mu */
  const int *un;         /* its nodes, ascending */
} folded;

struct ves_model {
  const ves_nodes *nodes; /* borrowed */
  const ves_quad *q;      /* borrowed */
  ves_model_params par;   /* copied */
  ves_model_local_par lp; /* parameters for the local densities */
  ves_model_point *pt;    /* nq point data (phi0 and derivatives) */
  unsigned char *fixed;   /* 2n fixed-dof flags */
  ves_pattern *pat;       /* block pattern */
  double *yref;           /* 2n reference positions */
  int mmax;               /* largest neighbour count of a point */
  int cap;                /* NPT mmax: capacity of a triangle's union */
  int numax;              /* the largest union of a triangle (model_make_slabs) */
  /* Threads: the nodes are split into nthr slabs in Z of about equal
   * assembly work; slab k owns the rows (nodes) in it, and every triangle
   * whose union meets slab k is visited by the thread of slab k, which writes
   * only owned rows. Every block (and gradient entry) thus receives its
   * contributions in triangle order whatever the thread count. */
  int nthr;       /* slabs = threads (omp_get_max_threads() at create) */
  int *owner;     /* n: slab of a node */
  int *tlo, *thi; /* ntri: slab range of a triangle's union */
  int *torder;    /* ntri: the order of assembly, along a Morton curve of
                     the centroids, so that consecutive triangles share
                     most nodes and their pattern rows stay in cache */
  model_ws *ws;   /* nthr workspaces */
  double *ev;     /* 4 nq: per-point w e of E, A, V and the step's dissipation
                     (summed in point order) */
  /* The velocity variables q_0..4 of every point at the last evaluated y,
   * recorded by each value pass (model_eval_points), so that the next
   * step's reference at that y (ves_model_dissipation_ref at y^{n+1}, the
   * answer the last pass evaluated) is a copy, not a pass of its own. */
  double *qrec; /* VES_NQD nq */
  double *yrec; /* 2n: the y they belong to */
  int qrec_ok;  /* 1 when qrec holds a complete, admissible pass at yrec */
  /* Drift damping (par.drift > 0, else NULL): the block values of the
   * constant matrix S added to K (model_drift_build); qn, the points at the
   * nodes with their tables, lives only while the model is built (the rows
   * of S and E_s are made from it). */
  ves_quad *qn; /* n points at the nodes (ves_quad_create_at_nodes); NULL after the build */
  double *dblk; /* 4 ptr[n] block values of S in the pattern */
  /* Coefficient-mode stabilization of E (par.stab > 0, else NULL; model_stab_build):
   * E_s = (1/2) sum_a c_a |d_a|^2 from the defect rows, cut to the
   * quadrature's pattern and refit to the fields they reproduced,
   * d_a = sum_j (sdr_j y_r, sdz_j y_z)(snb_j), j in [sptr[a], sptr[a+1]). */
  int *sptr;    /* n + 1 offsets (wall nodes: empty rows) */
  int *snb;     /* sptr[n] nodes of the rows */
  double *sdr;  /* sptr[n] weights of y_r (ghosts folded with -1) */
  double *sdz;  /* sptr[n] weights of y_z */
  double *sc;   /* n: c_a = stab k 2 pi M_a / h_a^2 (0 on the wall) */
  double *sblk; /* 2 ptr[n]: the rr and zz entries of Hess E_s's blocks (constant) */
};

/* The step's dissipation (ves_model_dissipation_ref): the velocity
 * variables qn (VES_NQD a point) of the configuration K is taken at (y^n, or
 * the extrapolated state of a BDF2 step), the coefficient cK of K in what is
 * assembled or evaluated, and the anchor qa of the displacement d = q - qa
 * (NULL: qn). */
typedef struct {
  const double *qn;
  double cK;
  const double *qa;
} step_ref;

/* What a triangle pass assembles. */
typedef enum { ASM_HESS, ASM_DISS } asm_kind;

/* The prefactors of the integrands of E, A and V: 2 pi (the axisymmetric
 * measure) times f_E = 3k/(16 sqrt2 eps), f_A = 3/(2 sqrt2), f_V = 1
 * (docs/design.md, "The model"), each times its coefficient c[i]. */
static inline void model_functional_factors(const ves_model *m, double cE, double cA, double cV,
                                            double fac[3]) {
  fac[0] = 2 * M_PI * 3 * m->par.k / (16 * M_SQRT2 * m->par.eps) * cE;
  fac[1] = 2 * M_PI * 3 / (2 * M_SQRT2) * cA;
  fac[2] = 2 * M_PI * cV;
}

/* The function model_each_point calls at every point al with its
 * kinematics q (VES_NQ) at y; ctx is the caller's. */
typedef ves_status point_fn(const ves_model *m, int al, const double q[VES_NQ], void *ctx);

/* model_assemble.c: the per-thread workspace (free accepts a zeroed one). */
ves_status model_ws_alloc(model_ws *w, int n, int mmax, int cap);
ves_status model_ws_alloc_products(model_ws *w, int numax);
void model_ws_free(model_ws *w);

/* model_assemble.c: fold the NPT points of triangle t into f[] and build the
 * union of their node lists (ascending) in *U; returns its size. */
int model_triangle_union(const ves_model *m, model_ws *w, int t, folded f[NPT], const int **U);

/* model_assemble.c: blk = sum over the triangles of their block matrices:
 * the Hessian of fac[0] E + fac[1] A + fac[2] V (+ cK K(y^n) with sr), or
 * K(y) (ASM_DISS), the slabs shared out over the threads; single != 0: each
 * triangle's products in single precision (blk is summed in double). */
ves_status model_assemble(ves_model *m, asm_kind kind, const double fac[3], const step_ref *sr,
                          int single, const double *y, double *blk);

/* model_assemble.c: ves_model_eval and ves_model_eval_step (values and
 * gradients, the totals summed in point order). */
ves_status model_eval_points(ves_model *m, const double *y, int which, const step_ref *sr,
                             double cE, double *E, double *A, double *V, double *Dv, double *gE,
                             double *gA, double *gV);

/* model_assemble.c: fn at every point with its kinematics at y, each
 * triangle by one thread. */
ves_status model_each_point(ves_model *m, const double *y, point_fn *fn, void *ctx);

/* model_threads.c: the slabs (m->owner, m->tlo, m->thi, m->numax) and the
 * order of assembly (m->torder). */
ves_status model_make_slabs(ves_model *m);
ves_status model_order_triangles(ves_model *m);

/* model_drift.c: the drift-damping matrix S (m->dblk), the stabilization's
 * rows and Hessian (m->sptr .. m->sblk), and E_s with its gradient. */
ves_status model_drift_build(ves_model *m);
ves_status model_stab_build(ves_model *m);
long double model_stab_eval(const ves_model *m, const double *y, double *g, double gs);

#endif
