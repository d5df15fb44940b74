/* vesica — building the initial discrete state from a configuration. */
#include "ves/setup.h"

#include "ves/project.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
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

/* The shape stage of the setup (setup.h). */
ves_status ves_setup_shape(const ves_config *cfg, ves_shape **shape, char *err, size_t errlen) {
  VES_CHECK(cfg && shape && err && errlen, VES_ERR_ARG);
  *shape = NULL;
  ves_status st;
  double *cpts = NULL;
  ves_shape_params sp;
  ves_shape_params_default(&sp);
  if (!strcasecmp(cfg->shape_type, "sphere"))
    sp.kind = VES_SHAPE_SPHERE;
  else if (!strcasecmp(cfg->shape_type, "spheroid"))
    sp.kind = VES_SHAPE_SPHEROID;
  else if (!strcasecmp(cfg->shape_type, "curve"))
    sp.kind = VES_SHAPE_CURVE;
  else
    sp.kind = VES_SHAPE_DISCOCYTE;
  if (sp.kind == VES_SHAPE_CURVE) {
    if ((st = ves_config_read_points(cfg, &sp.npts, &cpts, err, errlen)) != VES_OK) goto fail;
    sp.pts = cpts;
  }
  sp.radius = cfg->radius;
  sp.v = cfg->reduced_volume;
  sp.prolate = !strcasecmp(cfg->orientation, "prolate");
  sp.mode = cfg->mode;
  sp.delta = cfg->delta;
  st = ves_shape_create(&sp, shape);
  free(cpts);
  cpts = NULL;
  if (st == VES_ERR_GEOM && sp.kind == VES_SHAPE_CURVE) /* bad input: exit code 2 */
    FAIL(VES_ERR_CONFIG,
         "[shape] points = %s: the spline through the points crosses the axis (R < 0 between "
         "the poles) or encloses no volume; add points along its longest segments",
         cfg->points);
  if (st != VES_OK) FAIL(st, "shape: %s", ves_error_text(st));
  return VES_OK;
fail:
  free(cpts);
  return st;
}

/* The node set of cfg's discretization adapted to a shape: the band and
 * box check, the sizing field, the interface-aligned band layers and
 * ves_nodes_generate (used by the setup and by a remeshing, remesh.h). */
ves_status ves_setup_nodes(const ves_config *cfg, const ves_shape *shape, ves_sizing **sizing,
                           ves_nodes **nodes, char *err, size_t errlen) {
  VES_CHECK(cfg && shape && sizing && nodes && err && errlen, VES_ERR_ARG);
  *sizing = NULL, *nodes = NULL;
  ves_status st;
  double *bx = NULL;
  int *bflag = NULL;
  /* the refined band (and its layers) must fit in the box with a spacing to spare */
  double rmax, zmax, margin = (cfg->band + 1) * cfg->epsilon;
  ves_shape_extent(shape, &rmax, &zmax);
  if (rmax + margin >= cfg->box_r || zmax + margin >= cfg->box_z)
    FAIL(
        VES_ERR_CONFIG,
        "[geometry] box_r = %g, box_z = %g: the shape (R up to %.3f, |Z| up to %.3f) with its band "
        "of (band + 1) eps = %.3f does not fit",
        cfg->box_r, cfg->box_z, rmax, zmax, margin);

  /* band layers: lattice layers up to band*eps; strip and CVT nodes keep half
   * a layer spacing beyond the last layer */
  double hb = cfg->h_band * cfg->epsilon, dl = 0.5 * sqrt(3.0) * hb;
  double halfwidth = cfg->band * cfg->epsilon;
  double reserve = cfg->band_layers ? (floor(halfwidth / dl + 1e-9) + 0.5) * dl + 0.25 * hb : 0.0;
  ves_sizing_params zp = {.eps = cfg->epsilon,
                          .h_band = hb,
                          .band = cfg->band,
                          .slope = cfg->slope,
                          .h_far = cfg->h_far,
                          .reserve = reserve};
  if ((st = ves_sizing_create(shape, &zp, cfg->box_r, cfg->box_z, sizing)) != VES_OK)
    FAIL(st, "sizing: %s", ves_error_text(st));
  ves_nodes_params np;
  ves_nodes_params_default(&np);
  np.LR = cfg->box_r, np.LZ = cfg->box_z;
  np.h = ves_sizing_eval, np.h_ctx = *sizing;
  np.axis_spacings = cfg->axis_spacings;
  np.lloyd_iter = cfg->lloyd_iterations;
  np.seed = (unsigned)cfg->seed;
  if (cfg->band_layers) {
    if ((st = ves_shape_band_nodes(shape, hb, halfwidth, &np.nfixed, &bx, &bflag)) != VES_OK)
      /* a fold of the offset curves is bad input (the band is too wide for
       * the shape), not a failure of the numerics: exit code 2 */
      FAIL(st == VES_ERR_GEOM ? VES_ERR_CONFIG : st,
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

/* Longer than most functions, on purpose: one pipeline (shape, nodes,
 * quadrature, tables, projection, model) with one cleanup exit (STYLE.md
 * §4); each stage's message names the stage, and helpers would only pass
 * the half-built objects around. */
ves_status ves_setup_create(const ves_config *cfg, ves_phi0_method method, ves_setup **out,
                            char *err, size_t errlen) {
  VES_CHECK(cfg && out && err && errlen, VES_ERR_ARG);
  *out = NULL;
  ves_error_clear(); /* err names the record of this setup's failure (status.h) */
  double t0 = ves_wall_seconds(), t;
  ves_status st;
  double *f = NULL;
  ves_setup *s = calloc(1, sizeof *s);
  if (!s) return VES_ERR_ALLOC;

  if ((st = ves_setup_shape(cfg, &s->shape, err, errlen)) != VES_OK) goto fail;
  ves_shape_sharp(s->shape, &s->area_sharp, &s->volume_sharp);
  t = ves_wall_seconds();
  if ((st = ves_setup_nodes(cfg, s->shape, &s->sizing, &s->nodes, err, errlen)) != VES_OK)
    goto fail;
  s->seconds_nodes = ves_wall_seconds() - t;

  t = ves_wall_seconds();
  ves_quad_rulespec rule;
  if (ves_quad_rule_parse(cfg->quadrature, &rule) != VES_OK)
    FAIL(VES_ERR_CONFIG, "[geometry] quadrature = %s: not a rule", cfg->quadrature);
  if ((st = ves_quad_create_rule(s->nodes, rule, &s->quad)) != VES_OK)
    FAIL(st, "quadrature: %s", ves_error_text(st));
  ves_lme_params lp;
  ves_lme_params_default(&lp);
  lp.gamma = cfg->gamma, lp.tol0 = cfg->support_tol;
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
  for (int a = 0; a < n; a++)
    s->phi0c[a] = ves_shape_phi0(s->shape, cfg->epsilon, s->nodes->x + 2 * a);
  if (method == VES_PHI0_L2) {
#pragma omp parallel for schedule(static)
    for (int p = 0; p < s->quad->nq; p++)
      f[p] = ves_shape_phi0(s->shape, cfg->epsilon, s->quad->x + 2 * p);
    /* sparse Cholesky + at most 3 refinement steps (proj_refinements counts
     * them); 1e-12: the fit error then sits far below the discretization error */
    st = ves_project_l2(s->quad, n, f, s->phi0c, 1e-12, 3, &s->proj_refinements, &s->proj_residual);
    if (st != VES_OK)
      FAIL(st < 0 ? st : VES_ERR_NOCONV,
           "phi0 projection: %s (relative residual %.2e after %d refinement steps)",
           ves_error_text(st), s->proj_residual, s->proj_refinements);
  }
  s->seconds_project = ves_wall_seconds() - t;

  ves_model_params mp = {.eps = cfg->epsilon,
                         .c0 = cfg->c0,
                         .k = cfg->k,
                         .mu = cfg->mu,
                         .lambda = cfg->lambda_ratio * cfg->mu,
                         .drift = cfg->drift_damping,
                         .stab = cfg->stabilization};
  if ((st = ves_model_create(s->nodes, s->quad, s->phi0c, &mp, &s->model)) != VES_OK)
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
