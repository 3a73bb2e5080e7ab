/* The bouncing ball (ball.h) as an FMI 3.0 Model Exchange FMU. */

#include <stdio.h>
#include <stdlib.h>

#include "../../ball.h"
#include "fmi3Functions.h"

typedef enum { INSTANTIATED, INITIALIZATION, EVENT, CONTINUOUS, TERMINATED } Mode;

typedef struct {
    Ball ball;
    Mode mode;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log;
} Instance;

static const char TOKEN[] = "{3e9c7b10-6d2a-4f8b-8c35-ball-me-fmi3}";

static fmi3Status refuse(Instance *m, const char *message) {
    if (m->log) m->log(m->environment, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

/* A change of mode the standard allows only from `from`. */
static fmi3Status switch_mode(Instance *m, Mode from, Mode to, const char *refusal) {
    if (m->mode != from) return refuse(m, refusal);
    m->mode = to;
    return fmi3OK;
}

FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean on, size_t n,
                                           const fmi3String categories[]) {
    return fmi3OK;
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token,
                                                      fmi3String resources, fmi3Boolean visible,
                                                      fmi3Boolean logging,
                                                      fmi3InstanceEnvironment environment,
                                                      fmi3LogMessageCallback log) {
    if (!token || strcmp(token, TOKEN) != 0) return NULL;
    Instance *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    m->environment = environment;
    m->log = logging ? log : NULL;
    ball_defaults(&m->ball);
    m->mode = INSTANTIATED;
    return m;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean has_tol,
                                                   fmi3Float64 tol, fmi3Float64 start,
                                                   fmi3Boolean has_stop, fmi3Float64 stop) {
    Instance *m = instance;
    if (m->mode == INSTANTIATED) m->ball.x[VR_TIME] = start;
    return switch_mode(m, INSTANTIATED, INITIALIZATION,
                       "fmi3EnterInitializationMode: not instantiated");
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *m = instance;
    if (m->mode == INITIALIZATION) ball_start(&m->ball);
    return switch_mode(m, INITIALIZATION, EVENT, "fmi3ExitInitializationMode: not initialising");
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    return switch_mode(instance, CONTINUOUS, EVENT,
                       "fmi3EnterEventMode: not in continuous-time mode");
}

FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *again,
                                                fmi3Boolean *terminate, fmi3Boolean *nominals,
                                                fmi3Boolean *values, fmi3Boolean *next_defined,
                                                fmi3Float64 *next_time) {
    Instance *m = instance;
    if (m->mode != EVENT) return refuse(m, "fmi3UpdateDiscreteStates: not in event mode");
    *values = ball_update(&m->ball);
    *again = *terminate = *nominals = fmi3False;
    *next_defined = ball_kick_due(&m->ball);
    *next_time = *next_defined ? m->ball.x[VR_T_KICK] : 0.0;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    return switch_mode(instance, EVENT, CONTINUOUS,
                       "fmi3EnterContinuousTimeMode: not in event mode");
}

FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean no_prior,
                                                   fmi3Boolean *enter_event,
                                                   fmi3Boolean *terminate) {
    *enter_event = *terminate = fmi3False;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 t) {
    ((Instance *)instance)->ball.x[VR_TIME] = t;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[],
                                               size_t n) {
    Instance *m = instance;
    if (n != STATES) return refuse(m, "fmi3SetContinuousStates: the ball has 2 states");
    m->ball.x[VR_H] = x[0];
    m->ball.x[VR_V] = x[1];
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    Instance *m = instance;
    if (n != STATES) return refuse(m, "fmi3GetContinuousStates: the ball has 2 states");
    x[0] = m->ball.x[VR_H];
    x[1] = m->ball.x[VR_V];
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[],
                                                         size_t n) {
    Instance *m = instance;
    if (n != STATES) return refuse(m, "fmi3GetContinuousStateDerivatives: the ball has 2 states");
    ball_derivatives(&m->ball, dx);
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 z[], size_t n) {
    Instance *m = instance;
    if (n != INDICATORS) return refuse(m, "fmi3GetEventIndicators: the ball has 1 indicator");
    z[0] = ball_indicator(&m->ball);
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance,
                                                         fmi3Float64 nominal[], size_t n) {
    for (size_t i = 0; i < n; i++) nominal[i] = 1.0;
    return n == STATES ? fmi3OK : refuse(instance, "fmi3GetNominalsOfContinuousStates: 2 states");
}

FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n) {
    *n = INDICATORS;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n) {
    *n = STATES;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) {
    ((Instance *)instance)->mode = TERMINATED;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
    Instance *m = instance;
    ball_defaults(&m->ball);
    m->mode = INSTANTIATED;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[],
                                      size_t n, const fmi3Float64 values[], size_t nv) {
    Instance *m = instance;
    if (n != nv) return refuse(m, "fmi3SetFloat64: one value per value reference");
    for (size_t i = 0; i < n; i++) {
        if (m->mode != INSTANTIATED && m->mode != INITIALIZATION &&
            !(m->mode == EVENT && ball_tunable(vr[i])))
            return refuse(m, "fmi3SetFloat64: the parameters are fixed after initialisation "
                             "(e, tunable, may change in event mode)");
        if (!ball_allowed(vr[i], values[i]))
            return refuse(m, "fmi3SetFloat64: a value out of range or not a parameter "
                             "(g > 0, 0 <= e < 1, h0 >= 0, v_min > 0)");
        m->ball.x[vr[i]] = values[i];
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[],
                                      size_t n, fmi3Float64 values[], size_t nv) {
    Instance *m = instance;
    if (n != nv) return refuse(m, "fmi3GetFloat64: one value per value reference");
    for (size_t i = 0; i < n; i++)
        if (!ball_real(&m->ball, vr[i], &values[i]))
            return refuse(m, "fmi3GetFloat64: not a Float64 value reference");
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[],
                                    size_t n, fmi3Int32 values[], size_t nv) {
    Instance *m = instance;
    if (n != nv) return refuse(m, "fmi3GetInt32: one value per value reference");
    for (size_t i = 0; i < n; i++)
        if (!ball_integer(&m->ball, vr[i], &values[i]))
            return refuse(m, "fmi3GetInt32: not an Int32 value reference");
    return fmi3OK;
}
