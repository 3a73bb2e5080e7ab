/* The bouncing ball (ball.h) as an FMI 2.0 Model Exchange FMU. */

#include <stdio.h>
#include <stdlib.h>

#include "../../ball.h"
#include "fmi2Functions.h"

typedef enum { INSTANTIATED, INITIALIZATION, EVENT, CONTINUOUS, TERMINATED } Mode;

typedef struct {
    Ball ball;
    Mode mode;
    fmi2CallbackFunctions callbacks;
    char name[64];
} Instance;

static const char TOKEN[] = "{8a1d6c52-5b0e-4c1e-9f61-ball-me-fmi2}";

static fmi2Status refuse(Instance *m, const char *message) {
    if (m->callbacks.logger)
        m->callbacks.logger(m->callbacks.componentEnvironment, m->name, fmi2Error,
                            "logStatusError", "%s", message);
    return fmi2Error;
}

static fmi2Status in_mode(Instance *m, int allowed, const char *refusal) {
    return allowed ? fmi2OK : refuse(m, refusal);
}

FMI2_Export const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI2_Export const char *fmi2GetVersion(void) { return fmi2Version; }

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                           const fmi2String categories[]) {
    return fmi2OK;
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String token,
                                          fmi2String resources,
                                          const fmi2CallbackFunctions *callbacks,
                                          fmi2Boolean visible, fmi2Boolean logging) {
    if (type != fmi2ModelExchange || !token || strcmp(token, TOKEN) != 0 || !callbacks) return NULL;
    Instance *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    m->callbacks = *callbacks;
    snprintf(m->name, sizeof m->name, "%s", name ? name : "");
    ball_defaults(&m->ball);
    m->mode = INSTANTIATED;
    return m;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c) { free(c); }

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean has_tol, fmi2Real tol,
                                           fmi2Real start, fmi2Boolean has_stop, fmi2Real stop) {
    Instance *m = c;
    m->ball.x[VR_TIME] = start;
    return in_mode(m, m->mode == INSTANTIATED, "fmi2SetupExperiment: not instantiated");
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *m = c;
    if (m->mode != INSTANTIATED) return refuse(m, "fmi2EnterInitializationMode: not instantiated");
    m->mode = INITIALIZATION;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *m = c;
    if (m->mode != INITIALIZATION) return refuse(m, "fmi2ExitInitializationMode: not initialising");
    ball_start(&m->ball);
    m->mode = EVENT;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterEventMode(fmi2Component c) {
    Instance *m = c;
    if (m->mode != CONTINUOUS) return refuse(m, "fmi2EnterEventMode: not in continuous-time mode");
    m->mode = EVENT;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Instance *m = c;
    if (m->mode != EVENT) return refuse(m, "fmi2NewDiscreteStates: not in event mode");
    info->valuesOfContinuousStatesChanged = ball_update(&m->ball);
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = ball_kick_due(&m->ball);
    info->nextEventTime = info->nextEventTimeDefined ? m->ball.x[VR_T_KICK] : 0.0;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    Instance *m = c;
    if (m->mode != EVENT) return refuse(m, "fmi2EnterContinuousTimeMode: not in event mode");
    m->mode = CONTINUOUS;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean no_prior,
                                                   fmi2Boolean *enter_event, fmi2Boolean *stop) {
    *enter_event = fmi2False;
    *stop = fmi2False;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    ((Instance *)c)->ball.x[VR_TIME] = t;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) {
    Instance *m = c;
    if (n != STATES) return refuse(m, "fmi2SetContinuousStates: the ball has 2 states");
    m->ball.x[VR_H] = x[0];
    m->ball.x[VR_V] = x[1];
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    Instance *m = c;
    if (n != STATES) return refuse(m, "fmi2GetContinuousStates: the ball has 2 states");
    x[0] = m->ball.x[VR_H];
    x[1] = m->ball.x[VR_V];
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n) {
    Instance *m = c;
    if (n != STATES) return refuse(m, "fmi2GetDerivatives: the ball has 2 states");
    ball_derivatives(&m->ball, dx);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n) {
    Instance *m = c;
    if (n != INDICATORS) return refuse(m, "fmi2GetEventIndicators: the ball has 1 indicator");
    z[0] = ball_indicator(&m->ball);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real nominal[],
                                                         size_t n) {
    for (size_t i = 0; i < n; i++) nominal[i] = 1.0;
    return n == STATES ? fmi2OK : refuse(c, "fmi2GetNominalsOfContinuousStates: 2 states");
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    ((Instance *)c)->mode = TERMINATED;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Reset(fmi2Component c) {
    Instance *m = c;
    ball_defaults(&m->ball);
    m->mode = INSTANTIATED;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                   const fmi2Real values[]) {
    Instance *m = c;
    for (size_t i = 0; i < n; i++) {
        if (m->mode != INSTANTIATED && m->mode != INITIALIZATION &&
            !(m->mode == EVENT && ball_tunable(vr[i])))
            return refuse(m, "fmi2SetReal: the parameters are fixed after initialisation "
                             "(e, tunable, may change in event mode)");
        if (!ball_allowed(vr[i], values[i]))
            return refuse(m, "fmi2SetReal: a value out of range or not a parameter "
                             "(g > 0, 0 <= e < 1, h0 >= 0, v_min > 0)");
        m->ball.x[vr[i]] = values[i];
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                   fmi2Real values[]) {
    Instance *m = c;
    for (size_t i = 0; i < n; i++)
        if (!ball_real(&m->ball, vr[i], &values[i]))
            return refuse(m, "fmi2GetReal: not a Real value reference");
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                      fmi2Integer values[]) {
    Instance *m = c;
    for (size_t i = 0; i < n; i++)
        if (!ball_integer(&m->ball, vr[i], &values[i]))
            return refuse(m, "fmi2GetInteger: not an Integer value reference");
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                      const fmi2Integer values[]) {
    return n == 0 ? fmi2OK : refuse(c, "fmi2SetInteger: the Integer variables are outputs");
}

FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                      fmi2Boolean values[]) {
    return n == 0 ? fmi2OK : refuse(c, "fmi2GetBoolean: the FMU has no Boolean");
}

FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                      const fmi2Boolean values[]) {
    return n == 0 ? fmi2OK : refuse(c, "fmi2SetBoolean: the FMU has no Boolean");
}

/* What the ball does not offer, refused (masters such as FMPy look every function up). */

FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                     fmi2String values[]) {
    return n == 0 ? fmi2OK : refuse(c, "fmi2GetString: the FMU has no String");
}

FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                     const fmi2String values[]) {
    return n == 0 ? fmi2OK : refuse(c, "fmi2SetString: the FMU has no String");
}

FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    return refuse(c, "fmi2GetFMUstate: the FMU cannot save its state");
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    return refuse(c, "fmi2SetFMUstate: the FMU cannot save its state");
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    return refuse(c, "fmi2FreeFMUstate: the FMU cannot save its state");
}

FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state,
                                                  size_t *size) {
    return refuse(c, "fmi2SerializedFMUstateSize: the FMU cannot save its state");
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state,
                                             fmi2Byte bytes[], size_t size) {
    return refuse(c, "fmi2SerializeFMUstate: the FMU cannot save its state");
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[],
                                               size_t size, fmi2FMUstate *state) {
    return refuse(c, "fmi2DeSerializeFMUstate: the FMU cannot save its state");
}

FMI2_Export fmi2Status fmi2GetDirectionalDerivative(fmi2Component c,
                                                    const fmi2ValueReference unknowns[],
                                                    size_t n_unknowns,
                                                    const fmi2ValueReference knowns[],
                                                    size_t n_knowns, const fmi2Real seed[],
                                                    fmi2Real sensitivity[]) {
    return refuse(c, "fmi2GetDirectionalDerivative: the FMU offers no derivatives");
}
