/* vesica — Anderson acceleration (type II) of a fixed-point iteration
 * u <- u + g(u), private to the backends (the newton backend's chord):
 *
 *   gamma = argmin |g - dG gamma|_2 (over the first nls components),
 *   p = g - (dU + dG) gamma,
 *
 * dU, dG the differences of the last ANDERSON_DEPTH iterates and their
 * steps. For a linear residual this is GMRES on the preconditioned system
 * (Walker & Ni 2011). docs/design.md, "Backends". */
#ifndef VES_ANDERSON_IMPL_H
#define VES_ANDERSON_IMPL_H

#include "ves/status.h"

#define ANDERSON_DEPTH 5   /* steps remembered */
#define ANDERSON_GROW 10.0 /* an accelerated step longer than this many plain steps is refused */

typedef struct {
  int n;      /* the iterate's length */
  int nls;    /* its first nls components carry the least squares */
  double *du; /* ANDERSON_DEPTH columns of n: differences of the iterates */
  double *dg; /* ANDERSON_DEPTH columns of n: differences of their steps */
  double *q;  /* ANDERSON_DEPTH columns of nls: orthonormalized dg, workspace */
  double *u;  /* n: the previous iterate */
  double *g;  /* n: its step */
  double *p;  /* n: the accelerated step (anderson_step) */
  int ncol;   /* columns held (0: none; the newest at ncol - 1) */
  int prev;   /* u, g hold the previous iterate of the same map */
} anderson;

/* Workspaces for iterates of n components, the least squares over the first
 * nls; VES_ERR_ALLOC (with *a released) when out of memory. */
ves_status anderson_create(int n, int nls, anderson *a);
/* Frees the workspaces (a zeroed or destroyed one too). */
void anderson_destroy(anderson *a);
/* Forgets the history: a new iteration map. */
void anderson_reset(anderson *a);
/* The iterate u = (x[nls], lam[n - nls]) and its plain step g[n]: appended
 * to the history; a->p = the accelerated step, returns 1, or a->p = g and
 * 0 when no history is held or the extrapolation is wild (> ANDERSON_GROW
 * plain steps, which also drops the history). */
int anderson_step(anderson *a, const double *x, const double *lam, const double *g);
/* The plain step g[n] in a->p, the columns dropped (the last iterate kept). */
void anderson_plain(anderson *a, const double *g);

#endif
