/* vesica — the time loop of the variational integrator: one accepted step
 * at a time, y^{n+1} = argmin (1/2)|y - y^n|^2_K(y^n) + dt E(y) subject to
 * A = A0, V = V_target (paper Eq. 11), adaptive dt, rejected steps retried
 * with dt/2, protocols (steps and ramps of C0, volume ramps), resets of the
 * reference (reconnect.h) and remeshings (remesh.h). The driver (the
 * program) owns the loop, the output and the stopping decisions
 * (docs/design.md, "The time loop"). */
#ifndef VES_INTEGRATE_H
#define VES_INTEGRATE_H

#include "ves/backend.h"
#include "ves/lme.h"
#include "ves/model.h"
#include "ves/remesh.h"
#include "ves/status.h"
#include "ves/step.h"

/* Time stepping and protocol parameters (times in t* = t k / (mu R0^3)). */
typedef struct {
  double t_end;         /* final time */
  double dt_initial;    /* first step */
  double dt_max;        /* largest step */
  double dt_min;        /* floor for halving a rejected step; below it the run stops */
  int adaptive;         /* 1: dt from the energy decrement, 0: constant dt */
  double dE_target;     /* adaptive: target |E*(n+1) - E*(n)| per step (units k) */
  double growth_max;    /* adaptive: largest factor between consecutive steps (> 1) */
  int iter_target;      /* adaptive: above this many backend iterations dt is not grown */
  int factor_target;    /* adaptive, with a frozen Hessian (ves_backend_options
                           freeze_hessian >= 1): above this many KKT factorizations in the
                           accepted attempt (newton's builds and inertia corrections; euler
                           has one) dt is not grown (0: no such rule) */
  int factor_shrink;    /* adaptive, with a frozen Hessian: above this many KKT
                           factorizations in the accepted attempt the next dt is at most
                           dt/2, and the step is remembered as a rejected attempt at its dt
                           (retry_memory, retry_cap) (0: no such rule) */
  int predictor;        /* 1: a step starts from the linear extrapolation of the last two
                           states (and multipliers scaled by dt); 0: from y^n. y^{n-1} is
                           part of the restart state (ves_sim_y_prev, ves_sim_set_prev),
                           so a restart continues bit for bit either way */
  int order;            /* 1: backward Euler steps (paper Eq. 11); 2: BDF2 steps
                           (ves_step_set_history) wherever y^{n-1} is held and
                           dt / dt_prev <= VES_BDF2_RATIO_MAX, else backward Euler (the
                           first step, after a change of C0, after a step cut to land on
                           an event, or where the extrapolation leaves the domain);
                           growth_max must then be <= VES_BDF2_RATIO_MAX */
  int retry_memory;     /* adaptive: after a rejected attempt at dt_r, this many accepted
                           steps keep dt <= retry_cap dt_r (0: only the next step is held) */
  double retry_cap;     /* adaptive: that cap's factor, in (0, 1] */
  double event_cut;     /* adaptive: after a reset of the reference or a remeshing the
                           next dt is event_cut times the controller's, in (0, 1] (default
                           0.5; 1: no such rule): the new reference's fastest mode is 2-10x
                           stiffer for a few steps */
  int hold_area;        /* 1: A(y) = A0 at every step */
  int hold_volume;      /* 1: V(y) = V_target(t) at every step */
  double volume_rate;   /* protocol: dV/dt / V0 (1/t*; < 0 deflates; 0 = none) */
  double volume_final;  /* protocol: V / V0 at which the ramp stops and V is held */
  double c0_time;       /* protocol: time of a step change of C0 (< 0: none) */
  double c0_after;      /* protocol: C0 R0 from c0_time on */
  double c0_until;      /* protocol: time C0 returns to the model's C0 (< 0: never; else
                           > c0_time): a pulse that can push a shape past a barrier */
  double c0_ramp_start; /* protocol: a C0 ramp from the model's C0 at this time (< 0: none;
                           excludes c0_time) ... */
  double c0_ramp_end;   /* ... rising linearly to c0_ramp_to at this time (> c0_ramp_start),
                           then held; each step takes C0 at its end time, t + dt (as V_target),
                           and steps are cut to land on both times */
  double c0_ramp_to;    /* protocol: C0 R0 at the ramp's end */
  int check_energy;     /* 1: reject a step whose energy rises while the targets are fixed
                           (any backend: for Euler a rise is its instability) */
  /* reference-configuration reset after an accepted step when any enabled
   * criterion holds (ves_reconnect_due; all three 0: never, the default) */
  int reconnect_every;       /* accepted steps between resets (>= 0; 0: off) */
  double reconnect_cond_max; /* reset when max cond_2 F exceeds this (0: off; else > 1) */
  double reconnect_det_min;  /* reset when min det F drops below this (0: off; else in (0, 1)) */
  int reconnect_nodes;       /* where the new nodes go: a ves_reset_nodes (reconnect.h);
                                default VES_RESET_NODES_COEF, the paper's y^a */
  int profile_every;         /* restore phi's tanh profile (profile.h) after every this many
                                accepted steps (0: never, the default); A and V move by the
                                restoration and the next step's constraints bring them back */
} ves_integrate_params;

/* What one accepted step did. */
typedef struct {
  long step;               /* index of the accepted step (1, 2, ...) */
  double t, dt;            /* time reached and the step taken */
  double E, A, V;          /* E* (units k), area and volume after the step */
  double lambda[2];        /* multipliers of the area and volume constraints */
  double c0;               /* C0 R0 in force */
  double V_target;         /* volume target of the step */
  int retries;             /* halvings before acceptance */
  ves_backend_stats stats; /* the backend's statistics of the accepted solve */
  ves_status solve_status; /* the accepted solve's status */
  /* the rejected attempts of this step (all zero when retries = 0) */
  ves_backend_stats rejected; /* their statistics summed (iterations, evaluations,
                                 seconds; violation and solver_status of the last) */
  ves_status reject_status;   /* why the last one was rejected (VES_MAXITER, VES_ERR_NOCONV,
                                 VES_ERR_DOMAIN, VES_STEP_REJECTED: E rose, ...) */
  double reject_dt;           /* the largest dt tried (the first attempt's) */
  /* reconnection after the step (all zero when reconnection is off) */
  int reconnected;             /* 1: the reference was reset to the new y */
  double cond, det_min;        /* distortion of y relative to the reference the step was
                                  taken on: max cond_2 F and min det F (measured when a
                                  threshold is on or a reset was made; else 1 and 1) */
  double E_reset;              /* reconnected: E* at y evaluated on the new reference */
  int mirrored;                /* reconnected: nodes mirrored across the axis (ves_reconnect.h) */
  double shift;                /* reconnected: max_a |y^a - y(X_a)| / h_a (ves_reconnect.h) */
  ves_status reconnect_status; /* VES_OK, or why a due reset failed (the step stands and
                                  the old reference stays in use; tried again next step) */
  /* remeshing after the step (ves_sim_set_remesh; all zero when none) */
  int remeshed;             /* 1: the state was remeshed (node count may change) */
  ves_remesh_info remesh;   /* remeshed: what it changed (remesh.h) */
  ves_status remesh_status; /* VES_OK, or why a due remeshing failed (the step stands) */
  /* restoration of the profile after the step (ip.profile_every; all zero when none) */
  int profile_restored;      /* 1: phi0 restored (E, A, V above are the step's, before it) */
  double profile_shift;      /* restored: max shift of the level sets |phi| < 0.9 (units R0) */
  ves_status profile_status; /* VES_OK, or why the restoration failed (the step stands) */
} ves_step_report;

typedef struct ves_sim ves_sim;

/* Defaults (documented in the implementation). */
void ves_integrate_params_default(ves_integrate_params *p);

/* A simulation from the model's reference state: model borrowed (must
 * outlive the simulation; its C0 is set by the protocol; after a reset the
 * simulation works on a model of its own and leaves this one alone),
 * backend type borrowed (static), options copied. */
ves_status ves_sim_create(ves_model *model, const ves_backend_type *backend,
                          const ves_backend_options *bopt, const ves_integrate_params *ip,
                          ves_sim **out);
void ves_sim_destroy(ves_sim **s);

/* Take one accepted step (retrying with dt/2 on failure or energy rise),
 * then reset the reference configuration to the new y if one is due
 * (ves_reconnect_create; the step problem and the backend state are rebuilt
 * on the new model, y, t, dt, A0, V0, E0 and the multipliers are kept, E, A,
 * V re-evaluated on it). A reset allocates (~ the setup's LME tables); until
 * it has succeeded in full the old reference stays in use.
 * VES_OK: a step was taken (rep filled); VES_DONE: t_end already reached,
 * nothing done; < 0: no acceptable step down to dt_min — the state is the
 * last accepted one and rep describes the last attempt. */
ves_status ves_sim_step(ves_sim *s, ves_step_report *rep);

/* The integrator's whole state between steps: with the same model and
 * parameters, a simulation set to it continues the identical trajectory,
 * bit for bit (what a restart needs). E, A, V in model units (E* = E / k). */
typedef struct {
  double t;            /* time reached (t*) */
  double dt;           /* the next step's dt (t*) */
  long nstep;          /* accepted steps so far */
  double E, A, V;      /* energy, area and volume at y */
  double E0, A0, V0;   /* at t = 0 (A0 is the area target, V0 scales the volume ramp) */
  double lambda[2];    /* multipliers of the last accepted step (the next warm start) */
  double c0;           /* C0 R0 in force */
  double dt_rejected;  /* the smallest dt rejected within the last retry_memory accepted
                          steps (0: none) */
  long since_rejected; /* accepted steps since that rejection */
  double dt_prev;      /* dt of the last accepted step when y^{n-1} is held for the
                          predictor (ves_sim_y_prev), else 0: at the start, after a reset,
                          a remeshing or a change of C0 */
} ves_sim_state;

/* Copy the state out; y (2n, the caller's buffer) receives the positions
 * unless NULL. */
void ves_sim_get_state(const ves_sim *s, ves_sim_state *st, double *y);

/* Continue from state st and positions y (2n); both copied. Sets the
 * model's C0 to st->c0. y is relative to the reference in use: the
 * creation model's, or the one given by ves_sim_adopt_reference (the steps
 * counted towards the next reset are then st->nstep minus the step of that
 * reference's reset, as in the uninterrupted run). y_prev (2n, copied): the
 * positions before the last step (ves_sim_y_prev), required when
 * st->dt_prev > 0 and ignored otherwise.
 * VES_ERR_ARG for non-finite or inconsistent values (t < 0, dt <= 0,
 * nstep < 0 or before the reset of the reference in use, A0 or V0 <= 0,
 * dt_prev < 0, dt_prev > 0 without y_prev); then nothing changes. */
ves_status ves_sim_set_state(ves_sim *s, const ves_sim_state *st, const double *y,
                             const double *y_prev);

/* The positions before the last accepted step (2n, on the reference in
 * use: the predictor's y^{n-1}), or NULL when none are held
 * (state.dt_prev = 0). Valid until the next step. */
const double *ves_sim_y_prev(const ves_sim *s);

/* The state now is a restart point (a snapshot was written): the next step
 * carries nothing over from earlier steps (ves_step_params.fresh), so a run
 * restarted from this state repeats the following steps bit for bit. The
 * state set by ves_sim_set_state, a reset and a new C0 are restart points
 * by themselves. */
void ves_sim_restart_point(ves_sim *s);

typedef struct ves_reconnect ves_reconnect; /* reconnect.h */

/* A restart after resets: continue on ref (taken by the simulation on
 * success), a reference rebuilt by ves_reconnect_restore, which the run
 * reached with its reconnections-th reset at step reset_step; then set the
 * state on it with ves_sim_set_state. node_phi (n, may be NULL) is phi of
 * the material at ref's nodes as the run's snapshot holds it (carried on
 * from there, ves_sim_node_material; NULL: refitted). The step problem and
 * the backend are rebuilt on ref's model. On failure ref is freed and the
 * simulation is unchanged. VES_ERR_ARG for reconnections < 1, reset_step <
 * 0 or a non-finite node_phi; errors of the step problem and backend. */
ves_status ves_sim_adopt_reference(ves_sim *s, ves_reconnect *ref, int reconnections,
                                   long reset_step, const double *node_phi);

/* The reference the last reset made or adopted (owned by the simulation;
 * valid until the next reset), NULL before any: its nodes, quadrature and
 * point data are what io.h stores for a restart. */
const ves_reconnect *ves_sim_reference(const ves_sim *s);
/* The model in use: the creation model, or the last reset's (owned by the
 * simulation or borrowed at create; valid until the next reset). */
ves_model *ves_sim_model(ves_sim *s);

/* Remeshing (remesh.h) after accepted steps when pol says so (pol->every,
 * cond_max, det_min as for resets, on_failed_reset: also when a due reset
 * failed); d is the discretization the remeshings build (copied into the
 * simulation); d NULL turns remeshing off. After a remeshing the node count,
 * ves_sim_y and ves_sim_model change (the driver's buffers must follow
 * ves_model_nodes(ves_sim_model(s))->n); a restart restores it with
 * ves_sim_adopt_remesh. VES_ERR_ARG for invalid thresholds. */
ves_status ves_sim_set_remesh(ves_sim *s, const ves_discret_params *d,
                              const ves_remesh_policy *pol);
int ves_sim_remeshings(const ves_sim *s); /* remeshings so far */

/* The last remeshing's reference (owned by the simulation), NULL before any
 * or once a reset has replaced it: its nodes, flags, phi0 coefficients
 * (ves_remesh_nodes, ves_remesh_phi0c) are what io.h stores for a restart. */
const ves_remesh *ves_sim_remesh(const ves_sim *s);

/* A restart after remeshings: continue on nm (taken by the simulation, also
 * on failure), a remesh rebuilt by ves_remesh_restore, which the run made
 * as its remeshings-th at step remesh_step after reconnections resets; then (after a later reset)
 * ves_sim_adopt_reference on its model, and ves_sim_set_state with
 * positions of nm's node count. The step problem and the backend are
 * rebuilt on nm's model. On failure the simulation is unchanged.
 * VES_ERR_ARG for remeshings < 1, remesh_step < 1 or reconnections < 0. */
ves_status ves_sim_adopt_remesh(ves_sim *s, ves_remesh *nm, int remeshings, long remesh_step,
                                int reconnections);

double ves_sim_time(const ves_sim *s);
double ves_sim_dt(const ves_sim *s);         /* the next step's dt */
const double *ves_sim_y(const ves_sim *s);   /* current positions, 2n */
int ves_sim_reconnections(const ves_sim *s); /* reference resets so far */
void ves_sim_initial(const ves_sim *s, double *E, double *A, double *V); /* at t = 0 */

/* The material at the nodes of the reference in use, for output:
 *   x[2n]   (may be NULL) its current positions y(X_a) (r, z), the motion
 *           evaluated at the nodes, not the coefficients y^a (LME does not
 *           interpolate; near a squeezed axis the two part by many spacings,
 *           docs/results.md, "Resets and remeshing"); wall nodes at y^a, axis nodes at r = 0
 *   phi[n]  (may be NULL) the phase field it carries: phi0 of the reference
 *           at X_a, the model's nodal coefficients of phi0 evaluated there
 *           when they are known (the creation model's, given by
 *           ves_sim_set_phi0_coefficients; a remeshing's), else the L2 fit
 *           of the model's point values of phi0 onto the reference's basis;
 *           after a reset with nodes at y(X_a) the values are carried over
 *           (the same material), after one at y^a refitted on the new
 *           reference
 * The first call after a reset builds a point set at the nodes with its
 * tables (~n/nq of the setup's table build) and, for phi without known
 * coefficients, the fit (a sparse factorization); later calls evaluate
 * only. VES_ERR_ARG, VES_ERR_ALLOC, or the errors of ves_quad_tables and
 * ves_project_l2; the simulation state is never changed. */
ves_status ves_sim_node_material(ves_sim *s, double *x, double *phi);

/* The nodal coefficients phi0c[n] of the creation model's phi0 (the ones
 * given to ves_model_create: its point data is their field), copied: phi
 * at the nodes (ves_sim_node_material, and the nodes a reset with
 * reconnect_nodes = motion places) is then their value there instead of an
 * L2 refit of the point data (the same field to the fit's 1e-12; the refit
 * cost ~2.5 s at eps 0.01). A remeshing brings its own coefficients, a
 * reset none. VES_ERR_ARG after a reset or remeshing (adopted ones
 * included), or for a non-finite entry; VES_ERR_ALLOC. */
ves_status ves_sim_set_phi0_coefficients(ves_sim *s, const double *phi0c);

/* The motion that coefficients u[2n] (per node (r, z), a displacement or a
 * velocity field, fixed components included) give at the current
 * reference's nodes: du(X_a) = sum_b p_b(X_a) u^b over the nodes and their
 * mirrored ghosts, into du[2n] (linear in u; with u = y it is the x of
 * ves_sim_node_material). Builds the point set at the nodes on first use, as
 * ves_sim_node_material does; VES_ERR_ARG or its errors. */
ves_status ves_sim_motion_at_nodes(ves_sim *s, const double *u, double *du);

#endif
