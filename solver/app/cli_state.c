/* vesica — a run's state for the command line: setup and integrator from the
 * problem, snapshots, references and remeshings written and rebuilt from a
 * file (run, its restart, spectrum; docs/design.md, "The program"). */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app/cli_impl.h"
#include "ves/reconnect.h"

void cli_run_free(run_ctx *r) {
  ves_io_close(&r->io);
  ves_sim_destroy(&r->sim);
  ves_setup_destroy(&r->setup);
  free(r->phi);
  free(r->y);
  free(r->x);
  free(r->v);
  if (r->series) fclose(r->series);
}

/* The scratch buffers for n nodes (the node count changes at a remeshing). */
ves_status cli_ensure_nodes(run_ctx *r, int n) {
  if (n <= r->ncap) return VES_OK;
  double *phi = realloc(r->phi, (size_t)n * sizeof *phi);
  if (phi) r->phi = phi;
  double *y = realloc(r->y, 2 * (size_t)n * sizeof *y);
  if (y) r->y = y;
  double *x = realloc(r->x, 2 * (size_t)n * sizeof *x);
  if (x) r->x = x;
  double *v = realloc(r->v, 2 * (size_t)n * sizeof *v);
  if (v) r->v = v;
  if (!phi || !y || !x || !v) return VES_ERR_ALLOC;
  r->ncap = n;
  return VES_OK;
}

/* Nodes of the reference in use. */
int cli_nodes_now(run_ctx *r) { return ves_model_nodes(ves_sim_model(r->sim))->n; }

/* Setup, phi at the nodes and the integrator for r->cfg and r->bk (the
 * problem's parameters: ves_problem_params_from_config). */
int cli_build(run_ctx *r) {
  char err[1024] = "";
  ves_status st = ves_problem_setup_create(&r->cfg, VES_PHI0_L2, &r->setup, err, sizeof err);
  if (st != VES_OK) {
    cli_setup_error("run", r->label, err);
    return cli_exit_for(st);
  }
  if (cli_ensure_nodes(r, r->setup->nodes->n) != VES_OK) {
    fprintf(stderr, "vesica run: out of memory\n");
    return 3;
  }
  ves_problem_params p;
  ves_problem_params_from_config(&r->cfg, &p);
  ves_error_clear();
  if ((st = ves_sim_create(r->setup->model, r->bk, &p.bopt, &p.ip, &r->sim)) != VES_OK) {
    fprintf(stderr, "vesica run: %s: cannot start the time loop: %s\n", r->label, cli_why(st));
    return cli_exit_for(st);
  }
  if ((st = ves_sim_set_phi0_coefficients(r->sim, r->setup->phi0c)) != VES_OK) {
    fprintf(stderr, "vesica run: %s: cannot start the time loop: %s\n", r->label, cli_why(st));
    return cli_exit_for(st);
  }
  if (p.remesh) { /* the simulation copies the discretization */
    if ((st = ves_sim_set_remesh(r->sim, &p.discret, &p.remesh_policy)) != VES_OK) {
      fprintf(stderr, "vesica run: %s: [remesh]: %s\n", r->label, cli_why(st));
      return cli_exit_for(st);
    }
  }
  return 0;
}

/* The flow at the nodes over the last step into r->v, from r->x (the
 * material at the nodes now) and y_prev (the coefficients before the step):
 * v = (x - y^{n-1}(X_a)) / dt_prev, the material's velocity in R0 per t*.
 * Its motion at the nodes is linear in the coefficients, so this is the
 * last step's displacement field at the nodes over its dt. */
static ves_status flow_at_nodes(run_ctx *r, const double *y_prev, double dt_prev, int n) {
  VES_CALL(ves_sim_motion_at_nodes(r->sim, y_prev, r->v));
  for (int i = 0; i < 2 * n; i++) r->v[i] = (r->x[i] - r->v[i]) / dt_prev;
  return VES_OK;
}

/* A snapshot of the current state, with the flow at the nodes when the
 * integrator holds the last step (not at the first snapshot, nor right
 * after a restart from a file without y_prev). */
ves_status cli_snapshot(run_ctx *r, double wall) {
  ves_io_snapinfo si = {.wall_seconds = wall,
                        .reconnections = ves_sim_reconnections(r->sim),
                        .rows = ves_io_rows(r->io)};
  const int n = cli_nodes_now(r);
  VES_CALL(cli_ensure_nodes(r, n));
  ves_sim_get_state(r->sim, &si.state, r->y);
  si.y_prev = ves_sim_y_prev(r->sim); /* the predictor's state, when held */
  ves_sim_restart_point(r->sim);      /* a restart from here repeats the next steps exactly */
  r->last_snapshot_step = si.state.nstep;
  ves_status st = ves_sim_node_material(r->sim, r->x, r->phi);
  if (st != VES_OK) { /* x and phi are for looking at: the run and its state go on */
    for (int i = 0; i < 2 * n; i++) r->x[i] = NAN;
    for (int a = 0; a < n; a++) r->phi[a] = NAN;
    fprintf(stderr,
            "vesica run: warning: step %ld: the material at the nodes could not be evaluated "
            "(%s); snapshot %d holds x and phi as NaN (y, the state, is complete)\n",
            si.state.nstep, ves_status_str(st), ves_io_snapshots(r->io));
  } else if (si.y_prev && si.state.dt_prev > 0) {
    if (flow_at_nodes(r, si.y_prev, si.state.dt_prev, n) == VES_OK) si.velocity = r->v;
  }
  return ves_io_snapshot(r->io, r->y, r->x, r->phi, &si);
}

/* The reference the last reset made, for a restart (io.h). */
ves_status cli_write_reference(run_ctx *r, long step) {
  const ves_reconnect *ref = ves_sim_reference(r->sim);
  const ves_nodes *nd = ves_reconnect_nodes(ref);
  const ves_quad *q = ves_reconnect_quad(ref);
  double *pd = malloc(6 * (size_t)q->nq * sizeof *pd);
  if (!pd) return VES_ERR_ALLOC;
  ves_model_point_data(ves_reconnect_model_const(ref), pd);
  ves_io_reference io_ref = {
      .step = step, .nq = q->nq, .x = nd->x, .h = nd->h, .xq = q->x, .wq = q->w, .pd = pd};
  ves_status st = ves_io_write_reference(r->io, &io_ref);
  free(pd);
  return st;
}

/* A restart after resets: reference k of the file rebuilt and adopted, with
 * phi of the snapshot (its material at the reference's nodes). */
static ves_status restore_reference(run_ctx *r, int k, int reconnections, const double *phi) {
  ves_model *m = ves_sim_model(r->sim); /* the setup's, or a remeshing's */
  const int n = ves_model_nodes(m)->n, nq = ves_model_quad(m)->nq;
  ves_io_reference_buf b = {.nq = nq, .n = n};
  b.x = malloc(2 * (size_t)n * sizeof *b.x), b.h = malloc((size_t)n * sizeof *b.h);
  b.xq = malloc(2 * (size_t)nq * sizeof *b.xq), b.wq = malloc((size_t)nq * sizeof *b.wq);
  b.pd = malloc(6 * (size_t)nq * sizeof *b.pd);
  ves_status st = b.x && b.h && b.xq && b.wq && b.pd ? VES_OK : VES_ERR_ALLOC;
  ves_reconnect *ref = NULL;
  if (st == VES_OK) st = ves_io_read_reference(r->io, k, &b);
  if (st == VES_OK) st = ves_reconnect_restore(m, b.x, b.h, nq, b.xq, b.wq, b.pd, &ref);
  if (st == VES_OK) st = ves_sim_adopt_reference(r->sim, ref, reconnections, b.step, phi);
  free(b.x), free(b.h), free(b.xq), free(b.wq), free(b.pd);
  return st;
}

/* The remeshing just made, for a restart and for the record (io.h). */
ves_status cli_write_remesh(run_ctx *r, long step, const ves_remesh_info *info) {
  const ves_remesh *rm = ves_sim_remesh(r->sim);
  const ves_nodes *nd = ves_remesh_nodes(rm);
  const ves_quad *q = ves_remesh_quad(rm);
  ves_io_remesh io_rm = {.step = step,
                         .n = nd->n,
                         .x = nd->x,
                         .h = nd->h,
                         .flag = nd->flag,
                         .phi0c = ves_remesh_phi0c(rm),
                         .ntri = q->ntri,
                         .tri = q->tri,
                         .info = info};
  return ves_io_write_remesh(r->io, &io_rm);
}

/* A restart after remeshings: remeshing k of the file (the remeshings-th,
 * made with reconnections resets behind it) rebuilt on the setup's model
 * and adopted. */
static ves_status restore_remesh(run_ctx *r, int k, int remeshings, int reconnections) {
  long step = 0;
  int n = 0;
  ves_status st = ves_io_remesh_size(r->io, k, &step, &n, NULL);
  if (st != VES_OK) return st;
  ves_io_remesh_buf b = {.n = n};
  b.x = malloc(2 * (size_t)n * sizeof *b.x), b.h = malloc((size_t)n * sizeof *b.h);
  b.flag = malloc((size_t)n * sizeof *b.flag), b.phi0c = malloc((size_t)n * sizeof *b.phi0c);
  st = b.x && b.h && b.flag && b.phi0c ? VES_OK : VES_ERR_ALLOC;
  ves_remesh *nm = NULL;
  if (st == VES_OK) st = ves_io_read_remesh(r->io, k, &b);
  if (st == VES_OK) st = ves_remesh_restore(r->setup->model, n, b.x, b.h, b.flag, b.phi0c, &nm);
  if (st == VES_OK) st = ves_sim_adopt_remesh(r->sim, nm, remeshings, b.step, reconnections);
  free(b.x), free(b.h), free(b.flag), free(b.phi0c);
  return st;
}

/* The setup just rebuilt against the file's mesh: it is deterministic, so
 * its nodes must be the file's, bit for bit. 0 or the exit code. */
static int same_mesh(run_ctx *r, const char *pre) {
  const ves_io_info *in = ves_io_get_info(r->io);
  int n = r->setup->nodes->n;
  const int ncell = r->setup->quad->ntri / (r->setup->quad->sub > 1 ? r->setup->quad->sub : 1);
  if (n != in->n || ncell != in->ntri) {
    fprintf(stderr, "%s: the rebuilt setup has %d nodes, %d triangles; the file %d, %d\n", pre, n,
            ncell, in->n, in->ntri);
    return 2;
  }
  double *X = malloc(2 * (size_t)n * sizeof *X);
  if (!X) return 3;
  ves_status st = ves_io_read_mesh(r->io, X, NULL);
  int same = st == VES_OK && !memcmp(X, r->setup->nodes->x, 2 * (size_t)n * sizeof *X);
  free(X);
  if (!same) {
    fprintf(stderr,
            "%s: the rebuilt nodes differ from the file's mesh (another vesica version, or a "
            "changed points file?)\n",
            pre);
    return 2;
  }
  return 0;
}

/* The node set in force at snapshot S (its info si, ns nodes, phi in
 * r->phi): the last remeshing made at or before its step, and on it a later
 * reset's reference when there is one. 0 or the exit code. */
static int restore_nodes(run_ctx *r, const char *pre, int S, const ves_io_snapinfo *si, int ns) {
  ves_status st;
  int R = 0; /* remeshings before the snapshot */
  long rstep = 0, fstep = 0;
  while (R < ves_io_remeshes(r->io) && ves_io_remesh_size(r->io, R, &rstep, NULL, NULL) == VES_OK &&
         rstep <= si->state.nstep)
    R++, fstep = rstep;
  if (R > 0 && (st = restore_remesh(r, R - 1, R, si->reconnections)) != VES_OK) {
    fprintf(stderr, "%s: remeshing %d (step %ld) cannot be rebuilt: %s\n", pre, R - 1, fstep,
            cli_why(st));
    return 2;
  }
  long fref = 0; /* the reset of the reference in force came after the remeshing */
  if (si->reconnections > 0 &&
      (st = ves_io_reference_step(r->io, si->reconnections - 1, &fref)) != VES_OK) {
    fprintf(stderr, "%s: reference %d is unreadable: %s\n", pre, si->reconnections - 1,
            cli_why(st));
    return 2;
  }
  if (ns != cli_nodes_now(r)) { /* a reset keeps the node count */
    fprintf(stderr, "%s: snapshot %d has %d nodes, its node set %d\n", pre, S, ns,
            cli_nodes_now(r));
    return 2;
  }
  int phi_ok = 1; /* NaN when the snapshot could not evaluate it: refitted when needed */
  for (int a = 0; a < ns && phi_ok; a++) phi_ok = isfinite(r->phi[a]);
  if (si->reconnections > 0 && (R == 0 || fref > fstep) &&
      (st = restore_reference(r, si->reconnections - 1, si->reconnections,
                              phi_ok ? r->phi : NULL)) != VES_OK) {
    fprintf(stderr, "%s: reference %d (reset #%d) cannot be rebuilt: %s\n", pre,
            si->reconnections - 1, si->reconnections, cli_why(st));
    return 2;
  }
  return 0;
}

/* Rebuild the run stored in r->io (its problem already in r->cfg) at
 * snapshot S: the setup (which must reproduce the file's nodes), the
 * reference in force at S (rebuilt from the file after resets) and the
 * integrator's state there, into r. pre starts every message. Returns 0 or
 * an exit code (a message printed). */
int cli_rebuild_at(run_ctx *r, const char *pre, int S, ves_io_snapinfo *si) {
  /* after resets the snapshot's y is relative to the last reference made
   * before it, which the file must hold */
  const ves_io_info *in = ves_io_get_info(r->io);
  ves_error_clear();
  ves_status st = ves_io_read_snapshot(r->io, S, NULL, NULL, NULL, si);
  if (st != VES_OK) {
    fprintf(stderr, "%s: snapshot %d is unreadable: %s\n", pre, S, cli_why(st));
    return 2;
  }
  if (si->reconnections > ves_io_references(r->io)) {
    fprintf(stderr,
            "%s: the run reset its reference configuration %d time(s) before snapshot %d "
            "(step %ld) but the file holds only %d of the references they made "
            "(format_version 1 files hold none): rerun the problem\n",
            pre, si->reconnections, S, si->state.nstep, ves_io_references(r->io));
    return 2;
  }
  if (!(r->bk = ves_backend_find(in->backend))) {
    fprintf(stderr, "%s: unknown backend '%s'\n", pre, in->backend);
    return 2;
  }
  int rc;
  if ((rc = cli_build(r)) || (rc = same_mesh(r, pre))) return rc;
  const int ns = ves_io_snapshot_nodes(r->io, S); /* after remeshings: the snapshot's own */
  if (ns < 1 || cli_ensure_nodes(r, ns) != VES_OK ||
      (st = ves_io_read_snapshot_n(r->io, S, ns, r->y, NULL, r->phi, si)) != VES_OK ||
      si->rows > ves_io_rows(r->io) || si->rows != si->state.nstep) {
    fprintf(stderr, "%s: snapshot %d is unreadable or inconsistent\n", pre, S);
    return 2;
  }
  ves_error_clear();
  if ((rc = restore_nodes(r, pre, S, si, ns))) return rc;
  /* the predictor's y^{n-1} when the snapshot holds one (r->x as the buffer: 2 ns) */
  if (si->state.dt_prev > 0 && (st = ves_io_read_snapshot_prev(r->io, S, ns, r->x)) != VES_OK) {
    fprintf(stderr, "%s: snapshot %d: its y_prev (the predictor's state): %s\n", pre, S,
            cli_why(st));
    return 2;
  }
  ves_error_clear();
  if ((st = ves_sim_set_state(r->sim, &si->state, r->y, r->x)) != VES_OK) {
    fprintf(stderr, "%s: snapshot %d: %s\n", pre, S, cli_why(st));
    return 2;
  }
  return 0;
}
