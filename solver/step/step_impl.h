/* vesica — private: the model under a step problem, for the analysis of the
 * linearized flow (spectrum.c), which needs its Hessian and block pattern.
 * Not in step.h: the backends see the step problem only, never the model
 * (DESIGN.md §5). */
#ifndef VES_STEP_IMPL_H
#define VES_STEP_IMPL_H

#include "ves/model.h"
#include "ves/step.h"

/* The model of step problem s (borrowed; NULL for a NULL s). */
ves_model *ves_step_model(ves_step *s);

#endif
