/* vesica — geometry behind CGAL: Delaunay triangulation, exact neighbour search
 * with node-wise radii, local spacing, and adapted node sets on the meridian
 * rectangle [0, LR] x [-LZ, LZ] with mirrored ghost nodes across the axis R = 0.
 * The implementation (solver/discret/geom.cpp) is the project's only C++ file
 * (docs/design.md, "Discretization"). */
#ifndef VES_GEOM_H
#define VES_GEOM_H

#include "ves/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Delaunay triangulation of n points x[2n] (interleaved R, Z). On success
 * *tri (taken by the caller, free()) holds 3 * *ntri vertex indices, each
 * triangle counter-clockwise. Duplicate or all-collinear points are an error
 * (VES_ERR_GEOM); n < 3 or a non-finite coordinate is VES_ERR_ARG. */
ves_status ves_geom_delaunay(int n, const double *x, int *ntri, int **tri);

/* Local spacing h_a of every point: the mean length of its Delaunay edges,
 * then two passes of averaging with its Delaunay neighbours (weight 1 for a,
 * 1/2 for each neighbour), which removes the node-to-node jitter of the raw
 * measure where lattices meet (a uniform lattice keeps h_a = h exactly).
 * x[2n] borrowed, h[n] written. */
ves_status ves_geom_spacing(int n, const double *x, double *h);

/* Exact search for all nodes a with |X - x_a| <= radius_a (node-wise radii). */
typedef struct ves_geom_search ves_geom_search;

/* Build the search structure; x[2n] and radius[n] (>= 0) are copied. Nodes are
 * grouped in radius classes (within a factor 1.5), each a CGAL kd-tree of the
 * nodes lifted to 3D as (x_a, sqrt(rmax^2 - r_a^2)) and queried at (X, 0) with
 * the class's rmax; the result is filtered exactly, so nothing is missed. */
ves_status ves_geom_search_create(int n, const double *x, const double *radius,
                                  ves_geom_search **out);

/* All a with |X - x_a| <= radius_a, in increasing index order. Writes at most
 * cap indices to idx and the true count to *count (if *count > cap, idx holds
 * cap of the matches in no particular order: call again with a larger buffer).
 * idx may be NULL when cap = 0. Reads s only (concurrent queries are safe). */
ves_status ves_geom_search_query(const ves_geom_search *s, const double X[2], int cap, int *idx,
                                 int *count);

/* Candidates for every point within rho (>= 0) of X: all a with
 * |X - x_a| <= radius_a + rho, and possibly a few up to a relative 1e-9
 * beyond; same conventions as ves_geom_search_query (increasing index order,
 * cap, count). With ves_geom_search_filter, one query serves a cluster of
 * points (a triangle's quadrature points) with the same result as a query
 * at each. */
ves_status ves_geom_search_query_near(const ves_geom_search *s, const double X[2], double rho,
                                      int cap, int *idx, int *count);

/* Of the candidates cand[ncand] (borrowed), those a with |X - x_a| <= radius_a,
 * by the test of ves_geom_search_query, in their order, into idx (room for
 * ncand); *count their number. idx may alias cand. */
ves_status ves_geom_search_filter(const ves_geom_search *s, const double X[2], int ncand,
                                  const int *cand, int *idx, int *count);

/* Free; accepts NULL and sets *s to NULL. */
void ves_geom_search_destroy(ves_geom_search **s);

/* Target spacing h(X) > 0 at a point of the meridian plane (R >= 0). */
typedef double (*ves_sizing_fn)(const double X[2], void *ctx);

/* A region predicate: nonzero inside. */
typedef int (*ves_region_fn)(const double X[2], void *ctx);

/* Parameters of an adapted node set. */
typedef struct {
  double LR, LZ;          /* the box [0, LR] x [-LZ, LZ] (units of R0) */
  ves_sizing_fn h;        /* target spacing h(X) (units of R0) */
  void *h_ctx;            /* passed to h, borrowed */
  double axis_spacings;   /* width of the regular lattice strip along the axis,
                             in local spacings (>= 8; default 10) */
  int lloyd_iter;         /* Lloyd (CVT) iterations (default 60) */
  unsigned seed;          /* seed of the deterministic initial sampling */
  int nfixed;             /* caller-supplied fixed nodes, e.g. the interface-aligned
                             band layers of ves_shape_band_nodes (default 0) */
  const double *xfixed;   /* 2 nfixed positions (R >= 0, inside the box), copied */
  const int *fixed_flag;  /* nfixed VES_NODE_* flags (AXIS for R = 0), copied; BAND
                             is added */
  ves_region_fn reserved; /* where only the caller's nodes may lie: strip and
                           CVT nodes keep out (NULL: nowhere) */
  void *reserved_ctx;     /* passed to reserved, borrowed */
} ves_nodes_params;

/* Node flags. */
enum {
  VES_NODE_AXIS = 1,    /* R = 0: r stays 0, z free */
  VES_NODE_WALL = 2,    /* on R = LR or |Z| = LZ: fixed (no-slip wall) */
  VES_NODE_LATTICE = 4, /* part of the regular axis strip */
  VES_NODE_BAND = 8     /* a caller-supplied fixed node (interface band layers) */
};

/* An adapted node set with its ghosts. Real nodes are 0..n-1 (R >= 0); the
 * ghosts are the mirrors (-R_a, Z_a) of the real nodes with R_a > 0:
 * ghost k (0 <= k < ng) mirrors real node ghost_of[k]. */
typedef struct {
  double LR, LZ; /* the box (units of R0) */
  int n;         /* number of real nodes */
  double *x;     /* 2n reference positions (R, Z), units of R0 */
  double *h;     /* n local spacings h_a (ves_geom_spacing), measured
                    on the set of real and ghost nodes (units of R0) */
  int *flag;     /* n VES_NODE_* bits */
  int ng;        /* number of ghosts */
  int *ghost_of; /* ng indices of the mirrored real nodes */
} ves_nodes;

/* Defaults for everything but LR, LZ, h, h_ctx. */
void ves_nodes_params_default(ves_nodes_params *par);

/* Generate the node set: nodes on the box boundary (graded 1D placement),
 * a regular lattice strip through the axis (levels z_j graded by h(0, z),
 * columns R = k (sqrt3/2) h_j, odd columns at the level midpoints; a row
 * stops early where h(X) departs from its h_j by > 20% or the lattice shear
 * k |h_j - h_(j+1/2)| passes 0.2 h_j, so it is full width where h is constant,
 * i.e. where the interface meets the axis), the rest seeded with density
 * 2/(sqrt3 h^2) and moved by Lloyd iterations on CGAL's Delaunay
 * triangulation with centroid density h^-4 (a CVT's cell size goes as
 * rho^(-1/4) in 2D); then the ghosts and h_a. Deterministic for a given seed.
 * VES_ERR_ARG for bad parameters or h(X) <= 0 / non-finite anywhere sampled. */
ves_status ves_nodes_generate(const ves_nodes_params *par, ves_nodes **out);

/* Free; accepts NULL and sets *nodes to NULL. */
void ves_nodes_destroy(ves_nodes **nodes);

/* Extended coordinates of real + ghost nodes: xe[2(n+ng)] (caller allocated),
 * entries 0..n-1 the real nodes, n+k the ghost of ghost_of[k]. */
void ves_nodes_extended(const ves_nodes *nodes, double *xe);

#ifdef __cplusplus
}
#endif
#endif
