/* vesica — the variational time integrator (paper Sec. 3.2, Eq. 11), one
 * step at a time:
 *   y^{n+1} = argmin_y (1/2)(y - y^n)^T K(y^n) (y - y^n) + dt E(y)
 *             subject to A(y) = A0, V(y) = V_target(t^{n+1}).
 * A step is accepted when the backend converged and E(y^{n+1}) <= E(y^n)
 * (+ rounding) whenever y^n was feasible for it (no protocol change during
 * the step): a minimizer has dt E(y^{n+1}) <= f(y^{n+1}) <= f(y^n), so a
 * rise is explicit Euler's instability, and rejecting it keeps the step
 * size at Euler's stability limit. A rejected step is retried at dt/2 down
 * to dt_min. The step size (paper Sec. 4, Fig. 4):
 *   dt_next = dt clamp(dE_target / |dE|, 1/2, growth_max),
 * not grown after a hard step (more than iter_target iterations, nlopt's
 * counted in Hessians, or factor_target factorizations), at most dt/2 after
 * factor_shrink factorizations, capped by dt_max, by the next protocol
 * event and, for retry_memory accepted steps after a rejection at dt_r, by
 * retry_cap dt_r; a switch of C0 starts again from dt_initial. After an
 * accepted step a reset of the reference (paper Sec. 3.3, reconnect.h) or a
 * remeshing (remesh.h) runs when due, and the next dt is event_cut of the
 * controller's; the step problem and the backend are
 * built on the new model before the old ones are freed, so a failure leaves
 * the simulation on its old reference. Design: docs/design.md, "The time
 * loop"; the measured reason for each rule: docs/results.md, "Robustness at
 * large Δt". */
#include "ves/integrate.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/quad.h"
#include "ves/reconnect.h"
#include "ves/remesh.h"
#include "ves/profile.h"
#include "ves/project.h"

struct ves_sim {
  ves_model *model;                /* in use: the creation model (borrowed) or ref's */
  ves_reconnect *ref;              /* the last reset's reference (owned; NULL before one) */
  ves_reconnect_params rp;         /* when to reset (from ip) */
  long since;                      /* accepted steps since the last reset (or t = 0) */
  int reconnections;               /* resets so far */
  const ves_backend_type *backend; /* borrowed (static table entry) */
  ves_backend_options bopt;        /* copied */
  ves_integrate_params ip;         /* copied */
  ves_step *step;                  /* the step problem */
  void *bstate;                    /* the backend's state */
  int n, nvar;                     /* nodes, free dofs */
  double *y;                       /* 2n current positions */
  double *ynew;                    /* 2n trial positions */
  double *x;                       /* nvar trial free dofs */
  double t, dt;                    /* time, next step */
  long nstep;                      /* accepted steps */
  double E, A, V;                  /* at y */
  double E0, A0, V0;               /* at t = 0 */
  double lambda[2];                /* multipliers of the last accepted step */
  double c0;                       /* C0 in force */
  double c0_base;                  /* the model's C0 before and after the protocol */
  ves_quad *at_nodes;              /* points at the reference's nodes, with tables (lazy;
                                      dropped at a reset) */
  double *node_phi;                /* n: phi of the material at those nodes */
  int node_phi_ok;                 /* node_phi holds the current reference's values */
  double *coef;                    /* n: nodal coefficients of the creation model's phi0
                                      (ves_sim_set_phi0_coefficients; NULL: unknown) */
  long reset_step;                 /* the step of the last reset (0: none) */
  ves_remesh *mesh;                /* the last remeshing's reference (owned; NULL if none
                                      or a reset came after it) */
  int remesh_on;                   /* 1: remeshing enabled (ves_sim_set_remesh) */
  ves_discret_params rd;           /* remeshing: the discretization (a copy) */
  ves_remesh_policy rmp;           /* when to remesh */
  long rsince;                     /* accepted steps since the last remeshing (or t = 0) */
  long remesh_step;                /* the step of the last remeshing (0: none) */
  int remeshings;                  /* remeshings so far */
  double dt_rejected;              /* smallest recently rejected dt (0: none) */
  long since_rejected;             /* accepted steps since then */
  int fresh_next;                  /* the next step starts afresh (ves_step_params.fresh) */
  double *yprev;                   /* 2n: y before the last accepted step (predictor) */
  double dt_prev;                  /* that step's dt */
  int have_prev;                   /* yprev is on the current reference */
  ves_profile *prof;               /* the profile's restorer (ip.profile_every > 0) */
  int restored;                    /* 1: phi0 restored since the model was made (its nodal
                                      coefficients are then the restorer's) */
  int restored_last;               /* 1: the last accepted step was followed by a restoration */
};

void ves_integrate_params_default(ves_integrate_params *p) {
  p->t_end = 1.0;
  p->dt_initial = 1e-4;
  p->dt_max = 1e-1;
  p->dt_min = 1e-10;
  p->adaptive = 1;
  p->dE_target = 0.02;
  p->growth_max = 2.0;
  p->iter_target = 8;
  p->factor_target = 2;
  p->factor_shrink = 0;
  p->predictor = 1;
  p->order = 1;
  p->retry_memory = 10;
  p->retry_cap = 0.7;
  p->event_cut = 0.5;
  p->hold_area = 1;
  p->hold_volume = 1;
  p->volume_rate = 0.0;
  p->volume_final = 1.0;
  p->c0_time = -1.0;
  p->c0_after = 0.0;
  p->c0_until = -1.0;
  p->c0_ramp_start = -1.0;
  p->c0_ramp_end = -1.0;
  p->c0_ramp_to = 0.0;
  p->check_energy = 1;
  p->reconnect_every = 0;
  p->reconnect_cond_max = 0.0;
  p->reconnect_det_min = 0.0;
  p->reconnect_nodes = VES_RESET_NODES_COEF;
  p->profile_every = 0;
}

void ves_sim_destroy(ves_sim **s) {
  if (!s || !*s) return;
  ves_sim *p = *s;
  if (p->backend && p->bstate) p->backend->destroy(&p->bstate);
  ves_step_destroy(&p->step);
  ves_reconnect_destroy(&p->ref); /* after the step problem and backend built on it */
  ves_profile_destroy(&p->prof);
  ves_remesh_destroy(&p->mesh);
  ves_quad_destroy(&p->at_nodes);
  free(p->node_phi), free(p->coef);
  free(p->y);
  free(p->ynew);
  free(p->x), free(p->yprev);
  free(p);
  *s = NULL;
}

ves_status ves_sim_create(ves_model *model, const ves_backend_type *backend,
                          const ves_backend_options *bopt, const ves_integrate_params *ip,
                          ves_sim **out) {
  VES_CHECK(model && backend && bopt && ip && out, VES_ERR_ARG);
  *out = NULL;
  /* one condition a check: the error record names the one that failed */
  VES_CHECK(ip->t_end > 0, VES_ERR_ARG);
  VES_CHECK(ip->dt_initial > 0, VES_ERR_ARG);
  VES_CHECK(ip->dt_max >= ip->dt_initial, VES_ERR_ARG);
  VES_CHECK(ip->dt_min > 0 && ip->dt_min <= ip->dt_initial, VES_ERR_ARG);
  VES_CHECK(ip->growth_max >= 1, VES_ERR_ARG);
  VES_CHECK(ip->dE_target > 0, VES_ERR_ARG);
  VES_CHECK(ip->factor_target >= 0, VES_ERR_ARG);
  VES_CHECK(ip->factor_shrink >= 0, VES_ERR_ARG);
  VES_CHECK(ip->volume_final > 0, VES_ERR_ARG);
  VES_CHECK(ip->retry_memory >= 0, VES_ERR_ARG);
  VES_CHECK(ip->retry_cap > 0 && ip->retry_cap <= 1, VES_ERR_ARG);
  VES_CHECK(ip->event_cut > 0 && ip->event_cut <= 1, VES_ERR_ARG);
  VES_CHECK(ip->reconnect_every >= 0, VES_ERR_ARG);
  VES_CHECK(ip->profile_every >= 0, VES_ERR_ARG);
  VES_CHECK(ip->reconnect_cond_max == 0 || ip->reconnect_cond_max > 1, VES_ERR_ARG);
  VES_CHECK(ip->reconnect_det_min >= 0 && ip->reconnect_det_min < 1, VES_ERR_ARG);
  VES_CHECK(ip->reconnect_nodes == VES_RESET_NODES_COEF ||
                ip->reconnect_nodes == VES_RESET_NODES_MOTION,
            VES_ERR_ARG);
  VES_CHECK(ip->c0_until < 0 || (ip->c0_time >= 0 && ip->c0_until > ip->c0_time), VES_ERR_ARG);
  VES_CHECK(ip->c0_ramp_start < 0 || (ip->c0_time < 0 && ip->c0_ramp_end > ip->c0_ramp_start &&
                                      isfinite(ip->c0_ramp_to)),
            VES_ERR_ARG);
  ves_status st = VES_ERR_ALLOC;
  ves_sim *s = calloc(1, sizeof *s);
  if (!s) return VES_ERR_ALLOC;
  s->model = model, s->backend = backend, s->bopt = *bopt, s->ip = *ip;
  s->rp.every = ip->reconnect_every;
  s->rp.cond_max = ip->reconnect_cond_max;
  s->rp.det_min = ip->reconnect_det_min;
  s->n = ves_model_pattern(model)->n;
  s->y = malloc(2 * (size_t)s->n * sizeof *s->y);
  s->ynew = malloc(2 * (size_t)s->n * sizeof *s->ynew);
  s->yprev = malloc(2 * (size_t)s->n * sizeof *s->yprev);
  if (!s->y || !s->ynew || !s->yprev) goto fail;
  ves_model_reference(model, s->y);
  if (ip->profile_every > 0 && (st = ves_profile_create(&s->prof)) != VES_OK) goto fail;
  if ((st = ves_step_create(model, &s->step)) != VES_OK) goto fail;
  s->nvar = ves_step_nvar(s->step);
  s->x = malloc((size_t)s->nvar * sizeof *s->x);
  if (!s->x) {
    st = VES_ERR_ALLOC;
    goto fail;
  }
  s->c0 = s->c0_base = ves_model_get_c0(model);
  if ((st = ves_model_eval(model, s->y, VES_F_E | VES_F_A | VES_F_V, &s->E, &s->A, &s->V, NULL,
                           NULL, NULL)) != VES_OK)
    goto fail;
  s->E0 = s->E, s->A0 = s->A, s->V0 = s->V;
  s->dt = ip->dt_initial;
  /* the backend's state needs a set step problem: set it once at t = 0 */
  ves_step_params sp = {.dt = s->dt,
                        .hold_area = ip->hold_area,
                        .A0 = s->A0,
                        .hold_volume = ip->hold_volume,
                        .V_target = s->V0};
  if ((st = ves_step_set(s->step, s->y, &sp)) != VES_OK) goto fail;
  if ((st = backend->create(&s->bopt, s->step, &s->bstate)) != VES_OK) goto fail;
  s->fresh_next = 1;
  *out = s;
  return VES_OK;
fail:
  ves_sim_destroy(&s);
  return st;
}

static ves_status node_phi_fit(ves_sim *s); /* phi at the reference's nodes (below) */
static double volume_target(const ves_sim *s, double t);

/* The step problem and the backend state (the step's matrices, the KKT
 * values and the factorization's workspace) are freed before a new
 * reference or mesh is built beside the old model, and restore_solver makes
 * them again on the old model when the new one fails: a reset's peak memory
 * is then the two models' tables without the step's matrices
 * (docs/results.md, "Resets and remeshing"). A failed reset or remeshing
 * thus continues with a fresh factorization. */
static void release_solver(ves_sim *s) {
  if (s->bstate) s->backend->destroy(&s->bstate);
  ves_step_destroy(&s->step);
}

static ves_status restore_solver(ves_sim *s, const ves_step_params *sp) {
  s->fresh_next = 1;
  VES_CALL(ves_step_create(s->model, &s->step));
  VES_CALL(ves_step_set(s->step, s->y, sp));
  return s->backend->create(&s->bopt, s->step, &s->bstate);
}

/* The step parameters at the current time (for a step problem made between
 * steps: the backend needs a set one). */
static ves_step_params params_now(const ves_sim *s) {
  ves_step_params sp = {.dt = s->dt,
                        .hold_area = s->ip.hold_area,
                        .A0 = s->A0,
                        .hold_volume = s->ip.hold_volume,
                        .V_target = volume_target(s, s->t)};
  return sp;
}

/* A new reference's or mesh's solver objects beside the old: its step
 * problem set at y with sp (the backend needs a set problem), a backend
 * state for it (*bstate), the model's C0 the run's, and E, A, V at y. */
static ves_status new_solver(ves_sim *s, ves_model *m, ves_step *step, const double *y,
                             const ves_step_params *sp, void **bstate, double *E, double *A,
                             double *V) {
  ves_status st = ves_step_set(step, y, sp);
  if (st == VES_OK) st = s->backend->create(&s->bopt, step, bstate);
  if (st == VES_OK) st = ves_model_set_c0(m, s->c0);
  if (st == VES_OK)
    st = ves_model_eval(m, y, VES_F_E | VES_F_A | VES_F_V, E, A, V, NULL, NULL, NULL);
  return st;
}

/* Put the simulation on the reference nr (taken on success): a new step
 * problem and backend state on its model are made (the old ones already
 * released: release_solver); y continues from the new reference nodes. E, A,
 * V re-evaluated on the new model. On failure nr and everything made are
 * freed and s continues on its old reference, with a new step problem and
 * backend state (restore_solver). */
static ves_status switch_reference(ves_sim *s, ves_reconnect *nr, const ves_step_params *sp) {
  ves_step *step = NULL;
  void *bstate = NULL;
  double E, A, V;
  ves_model *m = ves_reconnect_model(nr);
  const double *y = ves_reconnect_nodes(nr)->x;
  ves_status st = ves_step_create(m, &step);
  if (st == VES_OK && ves_step_nvar(step) != s->nvar) st = VES_ERR_INTERNAL; /* same dofs */
  if (st == VES_OK) st = new_solver(s, m, step, y, sp, &bstate, &E, &A, &V);
  if (st != VES_OK) {
    if (bstate) s->backend->destroy(&bstate);
    ves_step_destroy(&step);
    ves_reconnect_destroy(&nr);
    if (!s->step) VES_CALL(restore_solver(s, sp));
    return st;
  }
  release_solver(s); /* (released already) the old pattern's objects, then their model */
  ves_reconnect_destroy(&s->ref);
  ves_remesh_destroy(&s->mesh); /* nr borrows nothing from it */
  s->ref = nr, s->model = m, s->step = step, s->bstate = bstate;
  ves_profile_forget(s->prof), s->restored = 0; /* a new model: its own phi0 */
  s->fresh_next = 1;
  s->have_prev = 0;
  memcpy(s->y, y, 2 * (size_t)s->n * sizeof *s->y);
  s->E = E, s->A = A, s->V = V;
  ves_quad_destroy(&s->at_nodes); /* built on the old nodes */
  return VES_OK;
}

/* Reset the reference to s->y (reconnect.h) and switch to it. The
 * positions continue from the new reference nodes (y with the nodes that
 * crossed the axis mirrored: the same motion); E, A, V are re-evaluated on
 * the new model (equal up to rounding). On failure s is unchanged. */
static ves_status reconnect(ves_sim *s, const ves_step_params *sp) {
  /* nodes at y(X_a) keep their material, so phi there is carried over: fit
   * it on the old reference if it is not fitted yet (failure only means a
   * refit on the new one, ves_sim_node_material) */
  if (s->ip.reconnect_nodes == VES_RESET_NODES_MOTION && !s->node_phi_ok) (void)node_phi_fit(s);
  ves_reconnect *nr = NULL;
  release_solver(s);
  const ves_reset_nodes where = (ves_reset_nodes)s->ip.reconnect_nodes;
  ves_status st = ves_reconnect_create(s->model, s->y, where, &nr);
  /* the predictor's y^{n-1} carried onto the new reference (NULL: not held,
   * or not carried: the next step then starts from y^n) */
  double *prev = st == VES_OK && s->have_prev ? malloc(2 * (size_t)s->n * sizeof *prev) : NULL;
  if (prev && ves_reconnect_carry(s->model, s->y, where, s->yprev, prev) != VES_OK)
    free(prev), prev = NULL;
  if (st == VES_OK)
    st = switch_reference(s, nr, sp);
  else
    VES_CALL(restore_solver(s, sp));
  if (st == VES_OK && prev) {
    memcpy(s->yprev, prev, 2 * (size_t)s->n * sizeof *prev);
    s->have_prev = 1;
  }
  free(prev);
  if (st != VES_OK) return st;
  s->since = 0;
  s->reset_step = s->nstep;
  s->reconnections++;
  if (s->ip.reconnect_nodes != VES_RESET_NODES_MOTION) s->node_phi_ok = 0;
  return VES_OK;
}

ves_status ves_sim_adopt_reference(ves_sim *s, ves_reconnect *ref, int reconnections,
                                   long reset_step, const double *node_phi) {
  int ok = s && ref && reconnections > 0 && reset_step >= 0;
  for (int a = 0; ok && node_phi && a < s->n; a++) ok = isfinite(node_phi[a]);
  if (!ok) {
    ves_reconnect_destroy(&ref); /* taken, as on every failure */
    return VES_ERR_ARG;
  }
  ves_step_params sp = params_now(s);
  release_solver(s);
  VES_CALL(switch_reference(s, ref, &sp));
  s->reconnections = reconnections, s->reset_step = reset_step;
  s->since = s->nstep >= reset_step ? s->nstep - reset_step : 0;
  s->node_phi_ok = 0;
  if (node_phi && (s->node_phi || (s->node_phi = malloc((size_t)s->n * sizeof *s->node_phi)))) {
    memcpy(s->node_phi, node_phi, (size_t)s->n * sizeof *s->node_phi);
    s->node_phi_ok = 1;
  }
  return VES_OK;
}

/* C0 of the ramp protocol at time t: the model's C0 before c0_ramp_start,
 * linear to c0_ramp_to at c0_ramp_end, then held. */
static double c0_ramp(const ves_sim *s, double t) {
  const ves_integrate_params *p = &s->ip;
  if (t <= p->c0_ramp_start) return s->c0_base;
  if (t >= p->c0_ramp_end) return p->c0_ramp_to;
  return s->c0_base + (p->c0_ramp_to - s->c0_base) * (t - p->c0_ramp_start) /
                          (p->c0_ramp_end - p->c0_ramp_start);
}

/* Volume target at time t: V0 (1 + rate t), stopped at V0 * final. */
static double volume_target(const ves_sim *s, double t) {
  double r = 1.0 + s->ip.volume_rate * t;
  if (s->ip.volume_rate < 0) r = fmax(r, s->ip.volume_final);
  if (s->ip.volume_rate > 0) r = fmin(r, s->ip.volume_final);
  return s->V0 * r;
}

static ves_status switch_remesh(ves_sim *s, ves_remesh *nm, double V_target);

/* Remesh s->y (remesh.h) and continue on the new reference (switch_remesh).
 * On failure s is unchanged. */
static ves_status remesh(ves_sim *s, ves_remesh_info *info) {
  ves_remesh_params rp;
  ves_remesh_params_default(&rp);
  rp.hold_area = s->ip.hold_area, rp.A_target = s->A0;
  rp.hold_volume = s->ip.hold_volume, rp.V_target = volume_target(s, s->t);
  rp.y_prev = s->have_prev ? s->yprev : NULL; /* the predictor's y^{n-1}, carried */
  ves_remesh *nm = NULL;
  char err[256];
  release_solver(s);
  ves_status st = ves_remesh_create(&s->rd, s->model, s->y, &rp, &nm, err, sizeof err);
  if (st > 0) st = VES_OK; /* the correction short of ctol: its residuals are reported */
  if (st == VES_OK) ves_remesh_get_info(nm, info);
  if (st == VES_OK) {
    st = switch_remesh(s, nm, rp.V_target); /* nm is s->mesh once it succeeds */
    if (st == VES_OK && ves_remesh_y_prev(s->mesh)) {
      memcpy(s->yprev, ves_remesh_y_prev(s->mesh), 2 * (size_t)s->n * sizeof *s->yprev);
      s->have_prev = 1;
    }
  } else {
    ves_remesh_destroy(&nm);
    ves_step_params sp = params_now(s);
    VES_CALL(restore_solver(s, &sp));
  }
  if (st != VES_OK) return st;
  s->rsince = 0, s->remesh_step = s->nstep;
  s->remeshings++;
  return VES_OK;
}

/* Put the simulation on the remeshed reference nm (taken; freed on
 * failure, s then unchanged) at its positions ves_remesh_y: the node count
 * changes, so the positions, trial buffers, step problem and backend are all
 * made anew first and swapped in only once everything exists; E, A, V
 * re-evaluated there. */
static ves_status switch_remesh(ves_sim *s, ves_remesh *nm, double V_target) {
  ves_step *step = NULL;
  void *bstate = NULL;
  double *y = NULL, *ynew = NULL, *x = NULL, *yprev = NULL, E, A, V;
  ves_model *m = ves_remesh_model(nm);
  const int n = ves_remesh_nodes(nm)->n;
  ves_status st = ves_step_create(m, &step);
  if (st == VES_OK) {
    y = malloc(2 * (size_t)n * sizeof *y), ynew = malloc(2 * (size_t)n * sizeof *ynew);
    yprev = malloc(2 * (size_t)n * sizeof *yprev);
    x = malloc((size_t)ves_step_nvar(step) * sizeof *x);
    st = y && ynew && yprev && x ? VES_OK : VES_ERR_ALLOC;
  }
  if (st == VES_OK) {
    memcpy(y, ves_remesh_y(nm), 2 * (size_t)n * sizeof *y);
    ves_step_params sp = params_now(s);
    sp.V_target = V_target;
    st = new_solver(s, m, step, y, &sp, &bstate, &E, &A, &V);
  }
  if (st != VES_OK) {
    if (bstate) s->backend->destroy(&bstate);
    ves_step_destroy(&step);
    ves_remesh_destroy(&nm);
    free(y), free(ynew), free(x), free(yprev);
    if (!s->step) {
      ves_step_params sp = params_now(s);
      VES_CALL(restore_solver(s, &sp));
    }
    return st;
  }
  release_solver(s); /* (released already) the old pattern's objects, then their model */
  ves_reconnect_destroy(&s->ref);
  ves_remesh_destroy(&s->mesh);
  s->mesh = nm, s->model = m, s->step = step, s->bstate = bstate;
  ves_profile_forget(s->prof), s->restored = 0; /* a new model: its own phi0 */
  free(s->y), free(s->ynew), free(s->x), free(s->yprev);
  s->y = y, s->ynew = ynew, s->x = x, s->yprev = yprev;
  s->have_prev = 0;
  s->n = n, s->nvar = ves_step_nvar(step);
  s->E = E, s->A = A, s->V = V;
  ves_quad_destroy(&s->at_nodes); /* built on the old nodes */
  free(s->node_phi);
  s->node_phi = NULL, s->node_phi_ok = 0;
  s->since = 0, s->reset_step = s->nstep; /* a new reference */
  s->fresh_next = 1;
  return VES_OK;
}

ves_status ves_sim_adopt_remesh(ves_sim *s, ves_remesh *nm, int remeshings, long remesh_step,
                                int reconnections) {
  if (!s || !nm || remeshings < 1 || remesh_step < 1 || reconnections < 0) {
    ves_remesh_destroy(&nm); /* taken, as on every failure */
    return VES_ERR_ARG;
  }
  release_solver(s);
  VES_CALL(switch_remesh(s, nm, volume_target(s, s->t)));
  s->reset_step = s->remesh_step = remesh_step, s->remeshings = remeshings;
  s->reconnections = reconnections;
  return VES_OK;
}

const ves_remesh *ves_sim_remesh(const ves_sim *s) { return s ? s->mesh : NULL; }

/* After an accepted step: is a remeshing due by its own rules (every
 * rmp.every steps, the distortion past rmp's thresholds)? Counts the step.
 * 0 when not, or when the distortion cannot be measured (rep->remesh_status).
 * One that came due by rmp.every and failed is tried again every
 * max(1, every/4) steps: a function of the steps since the last remeshing
 * alone, which a restart recomputes, so restarts stay bit for bit; a
 * remeshing that keeps failing then costs a quarter of the steps, not all of
 * them (docs/results.md, "Resets and remeshing"). */
static int remesh_due(ves_sim *s, ves_step_report *rep) {
  s->rsince++;
  if (s->rmp.every > 0 && s->rsince >= s->rmp.every) {
    const long back = s->rmp.every >= 8 ? s->rmp.every / 4 : 1;
    if ((s->rsince - s->rmp.every) % back == 0) return 1;
  }
  if (s->rmp.cond_max > 0 || s->rmp.det_min > 0) {
    double c = 1, d = 1;
    rep->remesh_status = ves_reconnect_distortion(s->model, s->y, &c, &d);
    if (rep->remesh_status != VES_OK) return 0;
    return (s->rmp.cond_max > 0 && c > s->rmp.cond_max) ||
           (s->rmp.det_min > 0 && d < s->rmp.det_min);
  }
  return 0;
}

ves_status ves_sim_set_remesh(ves_sim *s, const ves_discret_params *d,
                              const ves_remesh_policy *pol) {
  VES_CHECK(s && (!d || pol), VES_ERR_ARG);
  if (d)
    VES_CHECK(pol->every >= 0 && (pol->cond_max == 0 || pol->cond_max > 1) && pol->det_min >= 0 &&
                  pol->det_min < 1,
              VES_ERR_ARG);
  s->remesh_on = d != NULL;
  if (d) s->rd = *d, s->rmp = *pol;
  s->rsince = 0;
  return VES_OK;
}

int ves_sim_remeshings(const ves_sim *s) { return s->remeshings; }

/* The predictor (ves_integrate_params.predictor): the step starts from the
 * linear extrapolation of the last two states, x = y^n + r (y^n - y^{n-1}),
 * r = dt / dt_prev, and the multipliers from lambda r (the step's objective
 * is (1/2) d^T K d + dt E, so the tensions enter it as dt sigma). The start
 * is an error of O(dt^2) instead of O(dt) from y^n; the fixed point, the
 * convergence test and the answer are the step's own. A start outside the
 * domain (det F <= 0 somewhere) falls back to y^n. Evaluated here at once
 * with its gradient, which the backend finds in the step's cache.
 * y^{n-1} survives a reset (ves_reconnect_carry: the old motion at the new
 * nodes) and a remeshing (ves_remesh_params.y_prev: the step's displacement
 * projected onto the new basis with phi), so the step after a reset starts
 * as close as any other (docs/results.md, "Resets and remeshing"). Only a
 * change of C0 drops it. */
static void predict(ves_sim *s, double dt, double lam[2]) {
  const ves_pattern *pat = ves_model_pattern(s->model);
  const double r = dt / s->dt_prev;
  for (int i = 0; i < 2 * s->n; i++)
    if (pat->dof[i] >= 0) s->x[pat->dof[i]] = s->y[i] + r * (s->y[i] - s->yprev[i]);
  if (ves_step_eval_grad(s->step, s->x, s->ynew) != VES_OK) { /* ynew: scratch, nvar <= 2n */
    ves_step_x0(s->step, s->x);
    return;
  }
  lam[0] *= r, lam[1] *= r;
}

/* The protocol's C0 step change when its time is reached: a new energy
 * landscape, so dt starts again from dt_initial and nothing of the old one
 * (rejections, the predictor's last velocity) is carried over. */
static ves_status c0_event(ves_sim *s, double tiny) {
  double c0 = s->ip.c0_ramp_start >= 0 ? s->c0 : s->c0_base; /* a ramp: in the steps */
  if (s->ip.c0_time >= 0 && s->t >= s->ip.c0_time - tiny &&
      !(s->ip.c0_until >= 0 && s->t >= s->ip.c0_until - tiny))
    c0 = s->ip.c0_after;
  if (c0 == s->c0) return VES_OK;
  s->c0 = c0;
  s->dt = fmin(s->dt, s->ip.dt_initial);
  s->dt_rejected = 0, s->since_rejected = 0; /* rejections on the old landscape */
  s->fresh_next = 1;
  s->have_prev = 0; /* the last step's velocity belongs to the old landscape */
  VES_CALL(ves_model_set_c0(s->model, s->c0));
  return ves_model_eval(s->model, s->y, VES_F_E, &s->E, NULL, NULL, NULL, NULL, NULL);
}

/* The next attempt's dt: the controller's, cut to land on t_end and on the
 * protocol's events (the C0 switch times, the C0 ramp's ends and the end of
 * the volume ramp, where V/V0 reaches volume_final: there the forced
 * deflation stops, E* peaks, and a step across it would smear both). */
static double event_dt(const ves_sim *s, double tiny) {
  /* s->dt is at most dt_max, unless a restart lowered dt_max */
  double dt = fmin(fmin(s->dt, s->ip.dt_max), s->ip.t_end - s->t);
  if (s->ip.volume_rate != 0) {
    const double tv = (s->ip.volume_final - 1.0) / s->ip.volume_rate;
    if (tv > s->t + tiny) dt = fmin(dt, tv - s->t);
  }
  if (s->ip.c0_time > s->t + tiny) dt = fmin(dt, s->ip.c0_time - s->t);
  if (s->ip.c0_until > s->t + tiny) dt = fmin(dt, s->ip.c0_until - s->t);
  if (s->ip.c0_ramp_start >= 0 && s->ip.c0_ramp_start > s->t + tiny)
    dt = fmin(dt, s->ip.c0_ramp_start - s->t);
  if (s->ip.c0_ramp_start >= 0 && s->ip.c0_ramp_end > s->t + tiny)
    dt = fmin(dt, s->ip.c0_ramp_end - s->t);
  return dt;
}

/* The step controller after an accepted step of size dt that changed E by
 * dE in `iterations` backend iterations with `factorizations` KKT
 * factorizations after `retries` halvings: sets s->dt. */
static void next_dt(ves_sim *s, double dt, double dE, int iterations, int factorizations,
                    int retries) {
  double next = s->dt;
  if (s->ip.adaptive) {
    double f = dE > 0 ? s->ip.dE_target * ves_model_get_k(s->model) / dE : s->ip.growth_max;
    f = fmin(fmax(f, 0.5), s->ip.growth_max);
    const int hard =
        iterations > s->ip.iter_target || (s->ip.factor_target > 0 && s->bopt.freeze_hessian > 0 &&
                                           factorizations > s->ip.factor_target);
    if (hard) f = fmin(f, 1.0); /* a hard step: no growth */
    if (s->ip.factor_shrink > 0 && s->bopt.freeze_hessian > 0 &&
        factorizations > s->ip.factor_shrink) {
      f = fmin(f, 0.5); /* a very hard one: the next is shorter, */
#ifndef VES_NO_SHRINK_MEMORY
      if (s->dt_rejected == 0 || dt < s->dt_rejected) /* and remembered as a rejection */
        s->dt_rejected = dt;
      s->since_rejected = 0;
#endif
    }
    next = dt * f;
    if (retries) next = fmin(next, dt); /* just halved: do not jump back at once */
    if (s->dt_rejected > 0 && s->since_rejected >= s->ip.retry_memory)
      s->dt_rejected = 0; /* forgotten: the landscape may have changed */
    if (s->dt_rejected > 0) next = fmin(next, s->ip.retry_cap * s->dt_rejected);
  }
  if (s->dt_rejected > 0) s->since_rejected++;
  s->dt = fmin(fmax(next, s->ip.dt_min), s->ip.dt_max);
}

/* After an accepted step: a remeshing when one is due, else (none due, or
 * it failed) a reset of the reference when one is due, then a remeshing if
 * that reset failed, rmp.on_failed_reset and none was tried already; the
 * step stands whatever happens here (the outcomes are in rep). A remeshing
 * makes a new reference, so it replaces a reset due on the same step (a
 * step records at most one new reference: the file's references are
 * numbered by reset). A failed remeshing is tried again only later
 * (remesh_due), so the resets keep running meanwhile and the steps do not
 * each pay a failed remeshing (docs/results.md, "Resets and remeshing").
 * sp: the step's parameters (a reset rebuilds the step problem with them). */
static void after_step_reference(ves_sim *s, const ves_step_params *sp, ves_step_report *rep) {
  int remesh_now = s->remesh_on && remesh_due(s, rep), tried = remesh_now;
  if (remesh_now) { /* due by its own rules */
    rep->remesh_status = remesh(s, &rep->remesh);
    if (rep->remesh_status == VES_OK) {
      rep->remeshed = 1;
      return;
    }
    remesh_now = 0; /* failed: the reset rules decide this step, as if none had been due */
  }
  if (s->rp.every > 0 || s->rp.cond_max > 0 || s->rp.det_min > 0) {
    int due = 0;
    s->since++;
    rep->reconnect_status =
        ves_reconnect_due(&s->rp, s->model, s->y, s->since, &due, &rep->cond, &rep->det_min);
    if (rep->reconnect_status == VES_OK && due) {
      ves_reconnect_info info;
      rep->reconnect_status = reconnect(s, sp);
      if (rep->reconnect_status == VES_OK) {
        ves_reconnect_get_info(s->ref, &info);
        rep->reconnected = 1;
        rep->cond = info.cond_max, rep->det_min = info.det_min;
        rep->E_reset = s->E / ves_model_get_k(s->model);
        rep->mirrored = info.mirrored;
        rep->shift = info.shift_max;
      }
    }
    remesh_now = s->remesh_on && s->rmp.on_failed_reset && rep->reconnect_status < 0 &&
                 !tried; /* not twice in a step */
  }
  if (remesh_now) {
    rep->remesh_status = remesh(s, &rep->remesh);
    if (rep->remesh_status == VES_OK) rep->remeshed = 1;
  }
}

/* The profile's restoration after every ip.profile_every accepted steps
 * (profile.h): E, A, V re-evaluated on the restored phi0; the next step
 * starts afresh, and its energy is not compared with this E when A or V is
 * held (the restoration moves them off their targets, which the step
 * restores). A failed restoration leaves the model as it was. */
static void restore_profile(ves_sim *s, ves_step_report *rep) {
  if (!s->prof || s->nstep % s->ip.profile_every != 0) return;
  ves_profile_info info;
  rep->profile_status = ves_profile_restore(s->prof, s->model, s->y, &info);
  if (rep->profile_status != VES_OK) return;
  rep->profile_restored = 1, rep->profile_shift = info.max_shift;
  s->restored = 1, s->restored_last = 1, s->node_phi_ok = 0, s->fresh_next = 1;
  rep->profile_status = ves_model_eval(s->model, s->y, VES_F_E | VES_F_A | VES_F_V, &s->E, &s->A,
                                       &s->V, NULL, NULL, NULL);
}

/* After a reset or a remeshing the next dt is cut to event_cut of the
 * controller's (within dt_min): the new reference's linearized flow is
 * 2-10x stiffer for 5-10 steps, and a full-size first step there takes
 * 2-5x the factorizations of an ordinary one (docs/results.md, "Why the steps
 * after a reset or a remeshing are hard"). The cut dt is the state's dt, so
 * a restart from the snapshot of that step continues bit for bit. */
static void after_step(ves_sim *s, const ves_step_params *sp, ves_step_report *rep) {
  after_step_reference(s, sp, rep);
  if (s->ip.adaptive && (rep->reconnected || rep->remeshed))
    s->dt = fmax(s->ip.event_cut * s->dt, s->ip.dt_min);
  restore_profile(s, rep);
}

/* Take the attempt's result (positions s->ynew, E, A, V, multipliers lam,
 * the C0 and volume target it was solved at) as the new state. */
static void accept(ves_sim *s, double dt, double E, double A, double V, const double lam[2],
                   double c0n, double Vt, int retries, ves_step_report *rep) {
  const double dE = fabs(E - s->E);
  memcpy(s->yprev, s->y, 2 * (size_t)s->n * sizeof *s->y);
  s->dt_prev = dt, s->have_prev = 1;
  memcpy(s->y, s->ynew, 2 * (size_t)s->n * sizeof *s->y);
  s->fresh_next = 0, s->restored_last = 0;
  s->t += dt;
  s->nstep++;
  s->E = E, s->A = A, s->V = V;
  s->c0 = c0n;
  s->lambda[0] = lam[0], s->lambda[1] = lam[1];
  rep->step = s->nstep, rep->t = s->t, rep->dt = dt;
  rep->E = E / ves_model_get_k(s->model), rep->A = A, rep->V = V;
  rep->lambda[0] = lam[0], rep->lambda[1] = lam[1];
  rep->c0 = s->c0, rep->V_target = Vt, rep->retries = retries, rep->solve_status = VES_OK;
  next_dt(s, dt, dE, s->backend->hard_by_hessians ? rep->stats.h_evals : rep->stats.iterations,
          rep->stats.factorizations, retries);
}

/* Book a rejected attempt at dt (status st) into rep and the controller's
 * memory of rejections. */
static void reject(ves_sim *s, double dt, ves_status st, int retries, ves_step_report *rep) {
  rep->solve_status = st;
  rep->dt = dt;
  if (retries == 0) rep->reject_dt = dt;
  if (s->dt_rejected == 0 || dt < s->dt_rejected) s->dt_rejected = dt;
  s->since_rejected = 0;
  rep->reject_status = st;
  rep->rejected.iterations += rep->stats.iterations, rep->rejected.f_evals += rep->stats.f_evals;
  rep->rejected.g_evals += rep->stats.g_evals, rep->rejected.h_evals += rep->stats.h_evals;
  rep->rejected.factorizations += rep->stats.factorizations;
  rep->rejected.seconds += rep->stats.seconds, rep->rejected.violation = rep->stats.violation;
  rep->rejected.solver_status = rep->stats.solver_status;
  rep->rejected.limit = rep->stats.limit;
}

/* A BDF2 step's answer x against its start y^n, both feasible: a minimizer
 * cannot have f(x) > f(x0) (f: step.h). One values pass at x0; x's f is in
 * the step's cache. VES_STEP_REJECTED when f rose. */
static ves_status descent_from_start(ves_sim *s) {
  double fx, f0;
  VES_CALL(ves_step_eval_f(s->step, s->x, &fx));
  VES_CALL(ves_step_eval_f_start(s->step, &f0));
  return fx > f0 + 1e-10 * fabs(f0) ? VES_STEP_REJECTED : VES_OK;
}

/* One accepted step: attempts at dt, dt/2, ... until one is accepted. It
 * stays whole: one attempt is set up, solved, checked and accepted or
 * rejected in sequence over shared locals (dt, C0 and volume target of the
 * attempt, its multipliers); the parts with a meaning of their own are the
 * functions above. */
ves_status ves_sim_step(ves_sim *s, ves_step_report *rep) {
  VES_CHECK(s && rep, VES_ERR_ARG);
  memset(rep, 0, sizeof *rep);
  const double tiny = 1e-12 * (1.0 + fabs(s->t));
  if (s->t >= s->ip.t_end - tiny) return VES_DONE;
  VES_CALL(c0_event(s, tiny)); /* protocol: C0 switches when its time is reached */
  double dt = event_dt(s, tiny);
  const int ramp = s->ip.c0_ramp_start >= 0; /* C0(t + dt) at each attempt */
  ves_status st = VES_ERR_NOCONV;
  int retries = 0;
  for (;;) {
    double Vt = volume_target(s, s->t + dt);
    int fixed_targets = fabs(Vt - volume_target(s, s->t)) <= 1e-14 * s->V0;
    const double c0n = ramp ? c0_ramp(s, s->t + dt) : s->c0;
    if (c0n != s->c0) fixed_targets = 0; /* the ramp moves the landscape during the step */
    if (s->restored_last && (s->ip.hold_area || s->ip.hold_volume))
      fixed_targets = 0; /* y^n off the targets after a restoration */
    if ((st = ves_model_set_c0(s->model, c0n)) != VES_OK) return st;
    ves_step_params sp = {.dt = dt,
                          .hold_area = s->ip.hold_area,
                          .A0 = s->A0,
                          .hold_volume = s->ip.hold_volume,
                          .V_target = Vt,
                          .fresh = s->fresh_next || retries > 0};
    double lam[2] = {s->lambda[0], s->lambda[1]}, E, A, V;
    memset(&rep->stats, 0, sizeof rep->stats); /* this attempt's */
    st = ves_step_set(s->step, s->y, &sp);
    if (st == VES_OK && s->ip.order == 2 && s->have_prev && dt <= VES_BDF2_RATIO_MAX * s->dt_prev) {
      const ves_status sh = ves_step_set_history(s->step, s->yprev, dt / s->dt_prev);
      if (sh != VES_ERR_DOMAIN) st = sh; /* DOMAIN: y~ inadmissible, this attempt BDF1 */
    }
    if (st == VES_OK) {
      ves_step_x0(s->step, s->x);
      if (s->ip.predictor && s->have_prev && retries == 0 && !s->backend->ignores_start)
        predict(s, dt, lam); /* not on a retry: its start may have been the trouble */
      st = s->backend->solve(s->bstate, s->step, s->x, lam, &rep->stats);
    }
    if (st == VES_OK) {
      ves_step_expand(s->step, s->x, s->ynew);
      st = ves_step_values(s->step, s->x, &E, &A, &V); /* the backend's last pass, mostly */
    }
    /* energy stability: a VTI minimizer cannot raise E when y^n was feasible;
     * an explicit Euler step that raises it is unstable. A BDF2 step may
     * raise E (its anchor is not y^n): there the test is its objective's
     * descent from y^n (descent_from_start) */
    if (st == VES_OK && s->ip.check_energy && fixed_targets) {
      if (ves_step_is_bdf2(s->step))
        st = descent_from_start(s);
      else if (E > s->E + 1e-10 * fabs(s->E))
        st = VES_STEP_REJECTED;
    }
    if (st == VES_OK) {
      accept(s, dt, E, A, V, lam, c0n, Vt, retries, rep);
      after_step(s, &sp, rep);
      return VES_OK;
    }
    reject(s, dt, st, retries, rep);
    if (c0n != s->c0) (void)ves_model_set_c0(s->model, s->c0); /* the state's C0 again */
    if (st < 0 && st != VES_ERR_DOMAIN && st != VES_ERR_NOCONV && st != VES_ERR_SOLVER &&
        st != VES_ERR_SINGULAR)
      return st; /* not a numerical rejection: argument or memory errors */
    dt *= 0.5;
    retries++;
    rep->retries = retries;
    if (dt < s->ip.dt_min) {
      s->dt = s->ip.dt_min;
      if (st == VES_STEP_REJECTED) VES_FAIL(VES_ERR_NOCONV, "the last attempt raised E*");
      if (st == VES_MAXITER) { /* the limit by its key (every backend's VES_MAXITER names one) */
        const char *key = ves_backend_limit_key(rep->stats.limit);
        char why[64];
        snprintf(why, sizeof why, "the last attempt hit %s", *key ? key : "solver.max_iter");
        VES_FAIL(VES_ERR_NOCONV, why);
      }
      return ves_error_pass(st, __FILE__, __LINE__, __func__, "the last attempt");
    }
  }
}

double ves_sim_time(const ves_sim *s) { return s->t; }
double ves_sim_dt(const ves_sim *s) { return s->dt; }
const double *ves_sim_y(const ves_sim *s) { return s->y; }
int ves_sim_reconnections(const ves_sim *s) { return s->reconnections; }
const ves_reconnect *ves_sim_reference(const ves_sim *s) { return s->ref; }

ves_model *ves_sim_model(ves_sim *s) { return s ? s->model : NULL; }

void ves_sim_initial(const ves_sim *s, double *E, double *A, double *V) {
  if (E) *E = s->E0 / ves_model_get_k(s->model);
  if (A) *A = s->A0;
  if (V) *V = s->V0;
}

void ves_sim_get_state(const ves_sim *s, ves_sim_state *st, double *y) {
  st->t = s->t, st->dt = s->dt, st->nstep = s->nstep;
  st->E = s->E, st->A = s->A, st->V = s->V;
  st->E0 = s->E0, st->A0 = s->A0, st->V0 = s->V0;
  st->lambda[0] = s->lambda[0], st->lambda[1] = s->lambda[1];
  st->c0 = s->c0;
  st->dt_rejected = s->dt_rejected, st->since_rejected = s->since_rejected;
  st->dt_prev = s->have_prev ? s->dt_prev : 0;
  if (y) memcpy(y, s->y, 2 * (size_t)s->n * sizeof *y);
}

ves_status ves_sim_set_state(ves_sim *s, const ves_sim_state *st, const double *y,
                             const double *y_prev) {
  VES_CHECK(s && st && y, VES_ERR_ARG);
  const double v[] = {st->t,  st->dt,          st->E,      st->A,         st->V,
                      st->E0, st->A0,          st->V0,     st->lambda[0], st->lambda[1],
                      st->c0, st->dt_rejected, st->dt_prev};
  for (size_t i = 0; i < sizeof v / sizeof v[0]; i++) VES_CHECK(isfinite(v[i]), VES_ERR_ARG);
  VES_CHECK(st->t >= 0, VES_ERR_ARG);
  VES_CHECK(st->dt > 0, VES_ERR_ARG);
  VES_CHECK(st->nstep >= 0, VES_ERR_ARG);
  VES_CHECK(st->A0 > 0 && st->V0 > 0, VES_ERR_ARG);
  VES_CHECK(st->dt_rejected >= 0 && st->since_rejected >= 0, VES_ERR_ARG);
  for (int i = 0; i < 2 * s->n; i++) VES_CHECK(isfinite(y[i]), VES_ERR_ARG);
  VES_CHECK(st->dt_prev >= 0 && (st->dt_prev == 0 || y_prev), VES_ERR_ARG);
  if (st->dt_prev > 0)
    for (int i = 0; i < 2 * s->n; i++) VES_CHECK(isfinite(y_prev[i]), VES_ERR_ARG);
  VES_CHECK(st->nstep >= s->reset_step && st->nstep >= s->remesh_step,
            VES_ERR_ARG); /* not before the reference's reset or remeshing */
  VES_CALL(ves_model_set_c0(s->model, st->c0));
  memcpy(s->y, y, 2 * (size_t)s->n * sizeof *s->y);
  s->t = st->t, s->dt = st->dt, s->nstep = st->nstep;
  s->since = st->nstep - s->reset_step; /* as in the uninterrupted run */
  s->rsince = st->nstep - s->remesh_step;
  s->E = st->E, s->A = st->A, s->V = st->V;
  s->E0 = st->E0, s->A0 = st->A0, s->V0 = st->V0;
  s->lambda[0] = st->lambda[0], s->lambda[1] = st->lambda[1];
  s->c0 = st->c0;
  s->dt_rejected = st->dt_rejected, s->since_rejected = st->since_rejected;
  s->fresh_next = 1;
  s->have_prev = st->dt_prev > 0;
  if (s->have_prev) {
    memcpy(s->yprev, y_prev, 2 * (size_t)s->n * sizeof *s->yprev);
    s->dt_prev = st->dt_prev;
  }
  return VES_OK;
}

const double *ves_sim_y_prev(const ves_sim *s) { return s->have_prev ? s->yprev : NULL; }

void ves_sim_restart_point(ves_sim *s) {
  if (s) s->fresh_next = 1;
}

/* The point set at the reference's nodes with its tables (once per
 * reference: ~n/nq of a table build). */
static ves_status node_points(ves_sim *s) {
  if (s->at_nodes) return VES_OK;
  const ves_nodes *nd = ves_model_nodes(s->model);
  ves_status st = ves_quad_create_at_nodes(nd, &s->at_nodes);
  if (st == VES_OK) st = ves_quad_tables(s->at_nodes, nd, &ves_model_quad(s->model)->lme, NULL);
  if (st != VES_OK) ves_quad_destroy(&s->at_nodes);
  return st;
}

/* The nodal coefficients of the phi0 of the model in use when they are
 * known: the remeshing's that made it (s->mesh is dropped at the next
 * reset), or the creation model's before any reset or remeshing; NULL
 * after a reset (its model has point values only). */
static const double *known_coefficients(const ves_sim *s) {
  if (s->restored) return ves_profile_coefficients(s->prof);
  if (s->mesh) return ves_remesh_phi0c(s->mesh);
  return s->ref ? NULL : s->coef;
}

/* phi at the reference's nodes into s->node_phi: the model's nodal
 * coefficients of phi0 evaluated at the nodes when they are known (the
 * creation model's, a remeshing's), else (after a reset: the model has the
 * pushed-forward point values only) the L2 projection of the model's point
 * values of phi0 onto the reference's basis (ves_project_l2, as the setup
 * fits phi0), evaluated there. The known coefficients spare that second
 * projection, which would only give them back to the fit's tolerance (1e-12)
 * at the cost of a setup's projection (docs/results.md, "Performance and its
 * scaling"). */
static ves_status node_phi_fit(ves_sim *s) {
  const ves_quad *q = ves_model_quad(s->model);
  const int n = s->n;
  ves_status st = node_points(s);
  if (st != VES_OK) return st;
  if (!s->node_phi && !(s->node_phi = malloc((size_t)n * sizeof *s->node_phi)))
    return VES_ERR_ALLOC;
  const double *known = known_coefficients(s);
  double *pd = known ? NULL : malloc(6 * (size_t)q->nq * sizeof *pd);
  double *c = known ? NULL : malloc((size_t)n * sizeof *c);
  double *fld = malloc(6 * (size_t)n * sizeof *fld);
  st = fld && (known || (pd && c)) ? VES_OK : VES_ERR_ALLOC;
  if (st == VES_OK && !known) {
    ves_model_point_data(s->model, pd);
    for (int al = 0; al < q->nq; al++) pd[al] = pd[6 * (size_t)al]; /* phi0 row, in place */
    /* the setup's tolerance: the fit error far below the discretization's */
    st = ves_project_l2(q, n, pd, c, 1e-12, 3, NULL, NULL);
    if (st == VES_MAXITER) st = VES_OK; /* the best iterate: ample for output */
  }
  if (st == VES_OK) {
    ves_quad_field(s->at_nodes, known ? known : c, 0, fld);
    for (int a = 0; a < n; a++) s->node_phi[a] = fld[6 * (size_t)a];
    s->node_phi_ok = 1;
  }
  free(pd), free(fld), free(c);
  return st;
}

ves_status ves_sim_set_phi0_coefficients(ves_sim *s, const double *phi0c) {
  VES_CHECK(s && phi0c && !s->ref && !s->mesh, VES_ERR_ARG);
  for (int a = 0; a < s->n; a++) VES_CHECK(isfinite(phi0c[a]), VES_ERR_ARG);
  if (!s->coef && !(s->coef = malloc((size_t)s->n * sizeof *s->coef))) return VES_ERR_ALLOC;
  memcpy(s->coef, phi0c, (size_t)s->n * sizeof *s->coef);
  s->node_phi_ok = 0; /* evaluated from them at the next need */
  return VES_OK;
}

ves_status ves_sim_node_material(ves_sim *s, double *x, double *phi) {
  VES_CHECK(s, VES_ERR_ARG);
  ves_status st = node_points(s);
  if (st != VES_OK) return st;
  if (x) ves_reconnect_motion_at_nodes(ves_model_nodes(s->model), s->at_nodes, s->y, x, NULL);
  if (!phi) return VES_OK;
  if (!s->node_phi_ok && (st = node_phi_fit(s)) != VES_OK) return st;
  memcpy(phi, s->node_phi, (size_t)s->n * sizeof *phi);
  return VES_OK;
}

ves_status ves_sim_motion_at_nodes(ves_sim *s, const double *u, double *du) {
  VES_CHECK(s && u && du, VES_ERR_ARG);
  VES_CALL(node_points(s));
  ves_reconnect_motion_at_nodes(ves_model_nodes(s->model), s->at_nodes, u, du, NULL);
  return VES_OK;
}
