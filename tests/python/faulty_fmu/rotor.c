/* A small FMI 2.0 Model Exchange FMU with a steady cycle that fails on purpose, for the
 * tests of what a master does after an error: a rotor of inertia J driven by a torque T
 * against viscous friction c and a gravity-like torque a·sin(theta),
 *     theta' = omega,   J omega' = T - c omega - a sin(theta),
 * which turns round a steady cycle when T > a. The Integer parameter fail_call names a
 * function (1 fmi2SetTime, 2 fmi2SetContinuousStates, 3 fmi2GetDerivatives, 4 fmi2GetReal,
 * 5 fmi2GetDirectionalDerivative, 6 fmi2GetEventIndicators) whose fail_after-th call
 * returns fmi2Error. From then on every call but fmi2FreeInstance and fmi2Reset says
 * "... called after ... returned fmi2Error" through the logger, at fmi2Error: a master must
 * call nothing else on an instance that returned Error.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

enum { THETA, OMEGA, T_DRIVE, C_FRICTION, A_GRAVITY, J_INERTIA, DER_THETA, DER_OMEGA };
enum { FAIL_CALL = 8, FAIL_AFTER = 9 };

static const char *NAMES[] = {"", "fmi2SetTime", "fmi2SetContinuousStates",
                              "fmi2GetDerivatives", "fmi2GetReal",
                              "fmi2GetDirectionalDerivative", "fmi2GetEventIndicators"};

typedef struct {
    fmi2CallbackFunctions cb;
    double x[2], p[4], time;
    int fail_call, fail_after, calls;
    const char *failed; /* the function that returned fmi2Error, once one has */
} Rotor;

static void say(Rotor *r, fmi2Status s, const char *message) {
    if (r->cb.logger) r->cb.logger(r->cb.componentEnvironment, "rotor", s, "logStatusError", "%s", message);
}

/* fmi2Error where an earlier call returned it (said so), or where `which` is the function
 * that fails and this is its fail_after-th call; else fmi2OK. */
static fmi2Status enter(Rotor *r, int which, const char *name) {
    char message[160];
    if (r->failed) {
        snprintf(message, sizeof message, "%s called after %s returned fmi2Error", name, r->failed);
        say(r, fmi2Error, message);
        return fmi2Error;
    }
    if (which && which == r->fail_call && ++r->calls >= r->fail_after) {
        r->failed = NAMES[which];
        snprintf(message, sizeof message, "%s fails on purpose", name);
        say(r, fmi2Error, message);
        return fmi2Error;
    }
    return fmi2OK;
}

#define ENTER(r, which, name) do { if (enter((r), (which), (name)) != fmi2OK) return fmi2Error; } while (0)

static void defaults(Rotor *r) {
    r->x[0] = 0.0;
    r->x[1] = 0.0;
    r->p[0] = 1.5; /* T */
    r->p[1] = 0.5; /* c */
    r->p[2] = 1.0; /* a */
    r->p[3] = 1.0; /* J */
    r->time = 0.0;
    r->fail_call = 0;
    r->fail_after = 1;
    r->calls = 0;
    r->failed = NULL;
}

static double acceleration(const Rotor *r) {
    return (r->p[0] - r->p[1] * r->x[1] - r->p[2] * sin(r->x[0])) / r->p[3];
}

static double value(const Rotor *r, fmi2ValueReference vr) {
    switch (vr) {
    case THETA: return r->x[0];
    case OMEGA: return r->x[1];
    case DER_THETA: return r->x[1];
    case DER_OMEGA: return acceleration(r);
    default: return vr < DER_THETA ? r->p[vr - T_DRIVE] : 0.0;
    }
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) { return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean log) {
    Rotor *r = calloc(1, sizeof(Rotor));
    if (!r) return NULL;
    r->cb = *cb;
    defaults(r);
    return r;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2Reset(fmi2Component c) { defaults(c); return fmi2OK; }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real start,
                               fmi2Boolean sd, fmi2Real stop) {
    Rotor *r = c;
    ENTER(r, 0, "fmi2SetupExperiment");
    r->time = start;
    return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { ENTER((Rotor *)c, 0, "fmi2EnterInitializationMode"); return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { ENTER((Rotor *)c, 0, "fmi2ExitInitializationMode"); return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { ENTER((Rotor *)c, 0, "fmi2Terminate"); return fmi2OK; }

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Rotor *r = c;
    ENTER(r, 0, "fmi2SetReal");
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= T_DRIVE && vr[i] <= J_INERTIA) r->p[vr[i] - T_DRIVE] = v[i];
        else if (vr[i] <= OMEGA) r->x[vr[i]] = v[i];
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Rotor *r = c;
    ENTER(r, 4, "fmi2GetReal");
    for (size_t i = 0; i < n; i++) v[i] = value(r, vr[i]);
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    Rotor *r = c;
    ENTER(r, 0, "fmi2SetInteger");
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == FAIL_CALL) r->fail_call = v[i];
        else if (vr[i] == FAIL_AFTER) r->fail_after = v[i];
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    Rotor *r = c;
    ENTER(r, 0, "fmi2GetInteger");
    for (size_t i = 0; i < n; i++) v[i] = vr[i] == FAIL_CALL ? r->fail_call : r->fail_after;
    return fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { return n ? fmi2Error : fmi2OK; }

fmi2Status fmi2EnterEventMode(fmi2Component c) { ENTER((Rotor *)c, 0, "fmi2EnterEventMode"); return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    ENTER((Rotor *)c, 0, "fmi2NewDiscreteStates");
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { ENTER((Rotor *)c, 0, "fmi2EnterContinuousTimeMode"); return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSet, fmi2Boolean *event,
                                       fmi2Boolean *terminate) {
    ENTER((Rotor *)c, 0, "fmi2CompletedIntegratorStep");
    *event = fmi2False;
    *terminate = fmi2False;
    return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    Rotor *r = c;
    ENTER(r, 1, "fmi2SetTime");
    r->time = t;
    return fmi2OK;
}
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) {
    Rotor *r = c;
    ENTER(r, 2, "fmi2SetContinuousStates");
    r->x[0] = x[0];
    r->x[1] = x[1];
    return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n) {
    Rotor *r = c;
    ENTER(r, 3, "fmi2GetDerivatives");
    dx[0] = r->x[1];
    dx[1] = acceleration(r);
    return fmi2OK;
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n) {
    ENTER((Rotor *)c, 6, "fmi2GetEventIndicators");
    return fmi2OK;
}
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    Rotor *r = c;
    ENTER(r, 0, "fmi2GetContinuousStates");
    x[0] = r->x[0];
    x[1] = r->x[1];
    return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    ENTER((Rotor *)c, 0, "fmi2GetNominalsOfContinuousStates");
    x[0] = x[1] = 1.0;
    return fmi2OK;
}
/* d(der)/d(state) · seed: rows der(theta), der(omega); columns theta, omega. */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknowns[], size_t nu,
                                        const fmi2ValueReference knowns[], size_t nk,
                                        const fmi2Real seed[], fmi2Real out[]) {
    Rotor *r = c;
    ENTER(r, 5, "fmi2GetDirectionalDerivative");
    for (size_t i = 0; i < nu; i++) {
        out[i] = 0.0;
        for (size_t j = 0; j < nk; j++) {
            double d = 0.0;
            int state = knowns[j] == THETA ? 0 : knowns[j] == OMEGA ? 1 : -1;
            if (state < 0) return fmi2Error;
            if ((unknowns[i] == DER_THETA || unknowns[i] == OMEGA) && state == 1) d = 1.0;
            if (unknowns[i] == THETA && state == 0) d = 1.0;
            if (unknowns[i] == DER_OMEGA)
                d = state == 0 ? -r->p[2] * cos(r->x[0]) / r->p[3] : -r->p[1] / r->p[3];
            out[i] += d * seed[j];
        }
    }
    return fmi2OK;
}
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) { return fmi2Error; }
