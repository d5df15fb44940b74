/* vesica — the setup stage (setup.h): the nodes adapted to a shape, the
 * quadrature and LME tables, the least-squares phi0 coefficients and the
 * model, built once per problem (docs/design.md, "Discretization"). */
#include "ves/setup.h"

#include "ves/project.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "core/clock_impl.h"

void ves_setup_destroy(ves_setup **s) {
  if (!s || !*s) return;
  ves_model_destroy(&(*s)->model);
  free((*s)->phi0c);
  ves_quad_destroy(&(*s)->quad);
  ves_nodes_destroy(&(*s)->nodes);
  ves_sizing_destroy(&(*s)->sizing);
  ves_shape_destroy(&(*s)->shape);
  free(*s);
  *s = NULL;
}

#define FAIL(code, ...)                                                                            \
  do {                                                                                             \
    st = (code);                                                                                   \
    snprintf(err, errlen, __VA_ARGS__);                                                            \
    goto fail;                                                                                     \
  } while (0)

/* The refined band (and its layers) must fit in the box with a spacing to
 * spare. */
static ves_status box_check(const ves_discret_params *d, const ves_shape *shape, char *err,
                            size_t errlen) {
  double rmax, zmax, margin = (d->band + 1) * d->eps;
  ves_shape_extent(shape, &rmax, &zmax);
  if (rmax + margin < d->box_r && zmax + margin < d->box_z) return VES_OK;
  snprintf(err, errlen,
           "[geometry] box_r = %g, box_z = %g: the shape (R up to %.3f, |Z| up to %.3f) with its "
           "band of (band + 1) eps = %.3f does not fit",
           d->box_r, d->box_z, rmax, zmax, margin);
  return VES_ERR_CONFIG;
}

/* A fold of the band's offset curves is bad input (the band is too wide for
 * the shape), not a failure of the numerics: exit code 2. */
static ves_status fold_refused(double halfwidth, char *err, size_t errlen) {
  snprintf(err, errlen,
           "band layers: %s: band*epsilon = %g exceeds a radius of curvature of the shape "
           "(set a smaller [geometry] band, or band_layers = 0)",
           ves_error_text(VES_ERR_CONFIG), halfwidth);
  return VES_ERR_CONFIG;
}

ves_status ves_setup_check_geometry(const ves_discret_params *d, const ves_shape *shape, char *err,
                                    size_t errlen) {
  VES_CHECK(d && shape && err && errlen, VES_ERR_ARG);
  ves_status st = box_check(d, shape, err, errlen);
  if (st != VES_OK || !d->band_layers) return st;
  int n = 0, *flag = NULL;
  double *x = NULL;
  st = ves_shape_band_nodes(shape, d->h_band * d->eps, d->band * d->eps, &n, &x, &flag);
  free(x), free(flag);
  return st == VES_ERR_GEOM ? fold_refused(d->band * d->eps, err, errlen) : VES_OK;
}

/* The node set of the discretization d adapted to a shape: the band and
 * box check, the sizing field, the interface-aligned band layers and
 * ves_nodes_generate (used by the setup and by a remeshing, remesh.h). */
ves_status ves_setup_nodes(const ves_discret_params *d, const ves_shape *shape, ves_sizing **sizing,
                           ves_nodes **nodes, char *err, size_t errlen) {
  VES_CHECK(d && shape && sizing && nodes && err && errlen, VES_ERR_ARG);
  *sizing = NULL, *nodes = NULL;
  ves_status st;
  double *bx = NULL;
  int *bflag = NULL;
  if ((st = box_check(d, shape, err, errlen)) != VES_OK) goto fail;

  /* band layers: lattice layers up to band*eps; strip and CVT nodes keep half
   * a layer spacing beyond the last layer */
  double hb = d->h_band * d->eps, dl = 0.5 * sqrt(3.0) * hb;
  double halfwidth = d->band * d->eps;
  double reserve = d->band_layers ? (floor(halfwidth / dl + 1e-9) + 0.5) * dl + 0.25 * hb : 0.0;
  ves_sizing_params zp = {.eps = d->eps,
                          .h_band = hb,
                          .band = d->band,
                          .slope = d->slope,
                          .h_far = d->h_far,
                          .reserve = reserve};
  if ((st = ves_sizing_create(shape, &zp, d->box_r, d->box_z, sizing)) != VES_OK)
    FAIL(st, "sizing: %s", ves_error_text(st));
  ves_nodes_params np;
  ves_nodes_params_default(&np);
  np.LR = d->box_r, np.LZ = d->box_z;
  np.h = ves_sizing_eval, np.h_ctx = *sizing;
  np.axis_spacings = d->axis_spacings;
  np.lloyd_iter = d->lloyd_iterations;
  np.seed = (unsigned)d->seed;
  if (d->band_layers) {
    st = ves_shape_band_nodes(shape, hb, halfwidth, &np.nfixed, &bx, &bflag);
    if (st == VES_ERR_GEOM) {
      st = fold_refused(halfwidth, err, errlen);
      goto fail;
    }
    if (st != VES_OK)
      FAIL(st,
           "band layers: %s: band*epsilon = %g exceeds a radius of curvature of the shape "
           "(set a smaller [geometry] band, or band_layers = 0)",
           ves_error_text(st), halfwidth);
    np.xfixed = bx, np.fixed_flag = bflag;
    np.reserved = ves_sizing_reserved, np.reserved_ctx = *sizing;
  }
  if ((st = ves_nodes_generate(&np, nodes)) != VES_OK)
    FAIL(st, "node generation: %s", ves_error_text(st));
  free(bx);
  free(bflag);
  return VES_OK;
fail:
  free(bx);
  free(bflag);
  ves_sizing_destroy(sizing);
  ves_nodes_destroy(nodes);
  return st;
}

/* Longer than most functions, on purpose: one pipeline (nodes, quadrature,
 * tables, projection, model) with one cleanup exit that frees what a
 * failure half-way made; each stage's message names the stage, and helpers
 * would only pass the half-built objects around. */
ves_status ves_setup_create(const ves_discret_params *d, ves_shape *shape,
                            const ves_model_params *mp, ves_phi0_method method, ves_setup **out,
                            char *err, size_t errlen) {
  if (!(d && shape && mp && out && err && errlen)) {
    ves_shape_destroy(&shape); /* taken, on failure too */
    VES_FAIL(VES_ERR_ARG, "failed: d && shape && mp && out && err && errlen");
  }
  *out = NULL;
  ves_error_clear(); /* err names the record of this setup's failure (status.h) */
  double t0 = ves_wall_seconds(), t;
  ves_status st;
  double *f = NULL;
  ves_setup *s = calloc(1, sizeof *s);
  if (!s) {
    ves_shape_destroy(&shape);
    return VES_ERR_ALLOC;
  }
  s->shape = shape;
  if (mp->eps != d->eps)
    FAIL(VES_ERR_ARG, "setup: the model's eps %g is not the discretization's %g", mp->eps, d->eps);
  if (ves_quad_rule_npt(d->rule) == 0) FAIL(VES_ERR_ARG, "setup: not a quadrature rule");
  ves_shape_sharp(s->shape, &s->area_sharp, &s->volume_sharp);
  t = ves_wall_seconds();
  if ((st = ves_setup_nodes(d, s->shape, &s->sizing, &s->nodes, err, errlen)) != VES_OK) goto fail;
  s->seconds_nodes = ves_wall_seconds() - t;

  t = ves_wall_seconds();
  if ((st = ves_quad_create_rule(s->nodes, d->rule, &s->quad)) != VES_OK)
    FAIL(st, "quadrature: %s", ves_error_text(st));
  ves_lme_params lp;
  ves_lme_params_default(&lp);
  lp.gamma = d->gamma, lp.tol0 = d->support_tol;
  if ((st = ves_quad_tables(s->quad, s->nodes, &lp, &s->qinfo)) != VES_OK)
    FAIL(st, "LME tables: %s", ves_error_text(st));
  s->seconds_tables = ves_wall_seconds() - t;

  /* phi0 coefficients: sampled values, then (L2) the least-squares fit */
  t = ves_wall_seconds();
  int n = s->nodes->n;
  s->phi0c = malloc((size_t)n * sizeof *s->phi0c);
  f = malloc((size_t)s->quad->nq * sizeof *f);
  if (!s->phi0c || !f) FAIL(VES_ERR_ALLOC, "out of memory");
    /* phi0 at the nodes and points: independent evaluations of a read-only
     * shape (each a search over the curve's samples), on the OpenMP threads */
#pragma omp parallel for schedule(static)
  for (int a = 0; a < n; a++) s->phi0c[a] = ves_shape_phi0(s->shape, d->eps, s->nodes->x + 2 * a);
  if (method == VES_PHI0_L2) {
#pragma omp parallel for schedule(static)
    for (int p = 0; p < s->quad->nq; p++)
      f[p] = ves_shape_phi0(s->shape, d->eps, s->quad->x + 2 * p);
    /* sparse Cholesky + at most 3 refinement steps (proj_refinements counts
     * them); 1e-12: the fit error then sits far below the discretization error */
    st = ves_project_l2(s->quad, n, f, s->phi0c, 1e-12, 3, &s->proj_refinements, &s->proj_residual);
    if (st != VES_OK)
      FAIL(st < 0 ? st : VES_ERR_NOCONV,
           "phi0 projection: %s (relative residual %.2e after %d refinement steps)",
           ves_error_text(st), s->proj_residual, s->proj_refinements);
  }
  s->seconds_project = ves_wall_seconds() - t;

  if ((st = ves_model_create(s->nodes, s->quad, s->phi0c, mp, &s->model)) != VES_OK)
    FAIL(st, "model: %s", ves_error_text(st));
  s->seconds_total = ves_wall_seconds() - t0;
  free(f);
  *out = s;
  return VES_OK;
fail:
  free(f);
  ves_setup_destroy(&s);
  return st;
}
