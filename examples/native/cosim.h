/* What the compiled co-simulation FMUs of examples/ share: one instance layout and the FMI
 * 2.0 Co-Simulation functions over it (cosim.c), and the hooks each model defines (its
 * variables, defaults, checks, exact step and output derivatives). A model's inputs move
 * over a step along the derivatives a master sets (fmi2SetRealInputDerivatives), from the
 * time they were set. */
#ifndef COSIM_H
#define COSIM_H

#include <stddef.h>

#include "fmi2Functions.h"

enum { MAX_VARIABLES = 16, MAX_INPUTS = 4 };

typedef enum { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED } Lifecycle;

/* What a model's variable is, for the rules every model shares: a parameter is set before
 * initialisation ends, an input any time, an output never. */
typedef enum { PARAMETER, INPUT, OUTPUT } Causality;

typedef struct {
    double values[MAX_VARIABLES];
    /* d/dt and d²/dt² of each input (in the model's input order), as the master set
     * them; the inputs move along them from the time they were set, `elapsed` ago. */
    double input_derivatives[MAX_INPUTS][2];
    double elapsed;
    double time;
    Lifecycle state;
    fmi2CallbackFunctions callbacks;
    char name[64];
} Fmu;

/* Defined by each model. */
extern const char MODEL_GUID[];
extern const char MODEL_STATE_TAG[8]; /* leads its serialized FMU states */
extern const int MODEL_VARIABLES;     /* value references 0 .. MODEL_VARIABLES - 1 */
extern const char *const MODEL_NAMES[];
extern const Causality MODEL_CAUSALITY[];
extern const int MODEL_INPUTS;
extern const fmi2ValueReference MODEL_INPUT_VRS[]; /* the inputs' value references, in order */
extern const fmi2ValueReference MODEL_DERIVED_VRS[]; /* outputs with output derivatives */
extern const int MODEL_DERIVED;

/* The start values. */
void model_defaults(Fmu *m);
/* Whether a finite `value` is out of `vr`'s range, and if so why, in `why`. */
int model_out_of_range(fmi2ValueReference vr, double value, char *why, size_t size);
/* The outputs from the state and the inputs now. */
void model_update_outputs(Fmu *m);
/* The state `h` later, exactly, with the inputs along their course from `elapsed`. */
void model_step(Fmu *m, double h);
/* The first and second time derivatives of output `vr` (one of MODEL_DERIVED_VRS) now. */
void model_output_rates(Fmu *m, fmi2ValueReference vr, double rates[2]);

/* For the models: input `j` (in MODEL_INPUT_VRS order) and its first two derivatives, `s`
 * after the inputs were set. */
void input_course(const Fmu *m, int j, double s, double u[3]);

#endif
