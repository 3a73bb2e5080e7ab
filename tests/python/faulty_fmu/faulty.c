/* A small FMI 2.0 co-simulation FMU that fails on purpose, for the sweep's tests: the
 * parameter x selects how it misbehaves in fmi2DoStep; the output y = x * time.
 *   x < 0   fmi2SetReal refuses it: fmi2Error, "x must be >= 0"
 *   x == 5  fmi2DoStep returns fmi2Discard at t >= 0.5
 *   x == 3  every step takes 2 ms of wall time (a point over a small budget)
 *   x == 7  fmi2DoStep never returns (a hung step)
 *   x == 13 fmi2DoStep writes through a NULL pointer (a segfault)
 *   x == 21 fmi2DoStep prints to standard output (must not disturb the runner)
 */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "fmi2Functions.h"

typedef struct {
    fmi2CallbackFunctions cb;
    double x, time;
} Faulty;

static void say(Faulty *f, fmi2Status s, const char *message) {
    if (f->cb.logger) f->cb.logger(f->cb.componentEnvironment, "faulty", s, "logStatusError", "%s", message);
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean log) {
    Faulty *f = calloc(1, sizeof(Faulty));
    if (f) f->cb = *cb;
    return f;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real start,
                               fmi2Boolean sd, fmi2Real stop) {
    ((Faulty *)c)->time = start;
    return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    Faulty *f = c;
    f->x = 1.0;
    f->time = 0.0;
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Faulty *f = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != 0) { say(f, fmi2Error, "only x can be set"); return fmi2Error; }
        if (v[i] < 0) { say(f, fmi2Error, "x must be >= 0"); return fmi2Error; }
        f->x = v[i];
    }
    return fmi2OK;
}
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Faulty *f = c;
    for (size_t i = 0; i < n; i++) v[i] = vr[i] == 0 ? f->x : f->x * f->time;
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
/* No String variable and no asynchronous step: present because a container FMU loads only
   components that export every function of the standard. */
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) { return fmi2Error; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) { return fmi2Error; }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSet) {
    Faulty *f = c;
    if (f->x == 13.0) { volatile int *nowhere = NULL; *nowhere = 1; }
    if (f->x == 7.0) { for (;;) pause(); }
    if (f->x == 5.0 && t >= 0.5) { say(f, fmi2Discard, "x = 5 cannot pass t = 0.5"); return fmi2Discard; }
    if (f->x == 3.0) { struct timespec d = {0, 2000000}; nanosleep(&d, NULL); }
    if (f->x == 21.0) { printf("{\"done\": 0} noise on standard output\n"); fflush(stdout); }
    f->time = t + h;
    return fmi2OK;
}
