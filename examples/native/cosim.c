/* The FMI 2.0 Co-Simulation functions of the compiled FMUs of examples/, over the hooks of
 * cosim.h that each model defines. Linked with one model into one shared library. */

#include "cosim.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The message is passed as the logger's format, with '%' doubled: masters that format it
 * and masters that print it as it is (FMPy's ctypes callback cannot read variadic
 * arguments) both show it. */
static void report(Fmu *m, fmi2Status status, const char *format, ...) {
    char message[512], escaped[1024];
    size_t i, j = 0;
    va_list args;
    if (!m->callbacks.logger) return;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    for (i = 0; message[i] && j + 2 < sizeof escaped; i++) {
        if (message[i] == '%') escaped[j++] = '%';
        escaped[j++] = message[i];
    }
    escaped[j] = '\0';
    m->callbacks.logger(m->callbacks.componentEnvironment, m->name, status,
                        status == fmi2OK ? "logAll" : "logStatusError", escaped);
}

static fmi2Status refuse(Fmu *m, const char *function, const char *why) {
    report(m, fmi2Error, "%s: %s", function, why);
    return fmi2Error;
}

void input_course(const Fmu *m, int j, double s, double u[3]) {
    const double *d = m->input_derivatives[j];
    u[0] = m->values[MODEL_INPUT_VRS[j]] + s * (d[0] + 0.5 * s * d[1]);
    u[1] = d[0] + s * d[1];
    u[2] = d[1];
}

static int input_index(fmi2ValueReference vr) {
    int j;
    for (j = 0; j < MODEL_INPUTS; j++)
        if (MODEL_INPUT_VRS[j] == vr) return j;
    return -1;
}

static void set_defaults(Fmu *m) {
    memset(m->values, 0, sizeof m->values);
    memset(m->input_derivatives, 0, sizeof m->input_derivatives);
    m->elapsed = 0.0;
    m->time = 0.0;
    m->state = INSTANTIATED;
    model_defaults(m);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String resources, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Fmu *m;
    (void)resources;
    (void)visible;
    (void)loggingOn;
    if (!functions || fmuType != fmi2CoSimulation || !fmuGUID || strcmp(fmuGUID, MODEL_GUID) != 0)
        return NULL;
    m = calloc(1, sizeof *m);
    if (!m) return NULL;
    m->callbacks = *functions;
    snprintf(m->name, sizeof m->name, "%s", instanceName ? instanceName : "fmu");
    set_defaults(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)on;
    (void)n;
    (void)cats;
    return c ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol,
                               fmi2Real start, fmi2Boolean stopDefined, fmi2Real stop) {
    Fmu *m = c;
    (void)tolDefined;
    (void)tol;
    (void)stopDefined;
    (void)stop;
    if (!m) return fmi2Error;
    if (m->state != INSTANTIATED) return refuse(m, "fmi2SetupExperiment", "only after instantiation");
    if (!isfinite(start)) return refuse(m, "fmi2SetupExperiment", "startTime must be finite");
    m->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Fmu *m = c;
    if (!m) return fmi2Error;
    if (m->state != INSTANTIATED) return refuse(m, "fmi2EnterInitializationMode", "only after instantiation");
    m->state = INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Fmu *m = c;
    if (!m) return fmi2Error;
    if (m->state != INITIALIZATION) return refuse(m, "fmi2ExitInitializationMode", "not in initialization mode");
    model_update_outputs(m);
    m->state = STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Fmu *m = c;
    if (!m) return fmi2Error;
    m->state = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Fmu *m = c;
    if (!m) return fmi2Error;
    set_defaults(m);
    return fmi2OK;
}

/* Whether `value` may be written to `vr` now, and if not why, in `why` (the caller's
 * buffer: instances may run in threads of their own). */
static int refused(const Fmu *m, fmi2ValueReference vr, double value, char *why, size_t size) {
    if (vr >= (fmi2ValueReference)MODEL_VARIABLES)
        snprintf(why, size, "no variable has value reference %u", vr);
    else if (!isfinite(value))
        snprintf(why, size, "%s = %g: must be a finite number", MODEL_NAMES[vr], value);
    else if (MODEL_CAUSALITY[vr] == OUTPUT)
        snprintf(why, size, "%s is an output and cannot be set", MODEL_NAMES[vr]);
    else if (MODEL_CAUSALITY[vr] == PARAMETER && m->state != INSTANTIATED && m->state != INITIALIZATION)
        snprintf(why, size, "%s is a fixed parameter: set it before fmi2ExitInitializationMode",
                 MODEL_NAMES[vr]);
    else
        return model_out_of_range(vr, value, why, size);
    return 1;
}

/* Move the inputs to now along their derivatives, all but input `kept` (just set; -1 for
 * none), and count their time from now. */
static void restart_inputs(Fmu *m, int kept) {
    double u[3];
    int j;
    for (j = 0; j < MODEL_INPUTS; j++) {
        input_course(m, j, m->elapsed, u);
        if (j != kept) m->values[MODEL_INPUT_VRS[j]] = u[0];
        m->input_derivatives[j][0] = u[1];
    }
    m->elapsed = 0.0;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Fmu *m = c;
    size_t i;
    if (!m) return fmi2Error;
    if (m->state == TERMINATED) return refuse(m, "fmi2SetReal", "not after fmi2Terminate");
    if (n > 0 && (!vr || !value)) return refuse(m, "fmi2SetReal", "vr or value is NULL");
    for (i = 0; i < n; i++) {
        char why[160];
        if (refused(m, vr[i], value[i], why, sizeof why))
            return refuse(m, "fmi2SetReal", why); /* nothing applied */
    }
    for (i = 0; i < n; i++) {
        int j = input_index(vr[i]);
        m->values[vr[i]] = value[i];
        /* A new input value: the inputs move from here along their derivatives. The others
         * are moved to now first, so that they keep their course. */
        if (j >= 0) restart_inputs(m, j);
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Fmu *m = c;
    size_t i;
    if (!m) return fmi2Error;
    if (m->state == INSTANTIATED) return refuse(m, "fmi2GetReal", "not before fmi2EnterInitializationMode");
    if (n > 0 && (!vr || !value)) return refuse(m, "fmi2GetReal", "vr or value is NULL");
    model_update_outputs(m);
    for (i = 0; i < n; i++) {
        if (vr[i] >= (fmi2ValueReference)MODEL_VARIABLES) return refuse(m, "fmi2GetReal", "unknown value reference");
        value[i] = m->values[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real now, fmi2Real h, fmi2Boolean noSetPrior) {
    Fmu *m = c;
    (void)noSetPrior;
    if (!m) return fmi2Error;
    if (m->state != STEPPING) return refuse(m, "fmi2DoStep", "only after initialisation");
    if (!(h > 0.0) || !isfinite(h)) return refuse(m, "fmi2DoStep", "communicationStepSize must be finite and > 0");
    if (fabs(now - m->time) > 1e-12 * fmax(fabs(m->time), h))
        return refuse(m, "fmi2DoStep", "currentCommunicationPoint does not match the FMU's time");
    model_step(m, h);
    m->elapsed += h;
    m->time = now + h;
    model_update_outputs(m); /* from the state and the inputs at the step's end */
    return fmi2OK;
}

static int derived(fmi2ValueReference vr) {
    int j;
    for (j = 0; j < MODEL_DERIVED; j++)
        if (MODEL_DERIVED_VRS[j] == vr) return 1;
    return 0;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    Fmu *m = c;
    size_t i;
    if (!m) return fmi2Error;
    if (m->state != STEPPING && m->state != TERMINATED)
        return refuse(m, "fmi2GetRealOutputDerivatives", "only after initialisation");
    if (n > 0 && (!vr || !order || !value)) return refuse(m, "fmi2GetRealOutputDerivatives", "an array is NULL");
    for (i = 0; i < n; i++) {
        double rates[2];
        if (!derived(vr[i]))
            return refuse(m, "fmi2GetRealOutputDerivatives", "this variable has no output derivatives");
        if (order[i] != 1 && order[i] != 2)
            return refuse(m, "fmi2GetRealOutputDerivatives", "order must be 1 or 2");
        model_output_rates(m, vr[i], rates);
        value[i] = rates[order[i] - 1];
    }
    return fmi2OK;
}

/* The inputs' first and second derivatives, for the steps to come: applied from now (the
 * inputs' values are moved to now first). */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Fmu *m = c;
    size_t i;
    if (!m) return fmi2Error;
    if (m->state != INITIALIZATION && m->state != STEPPING)
        return refuse(m, "fmi2SetRealInputDerivatives", "only in initialisation or stepping");
    if (n > 0 && (!vr || !order || !value)) return refuse(m, "fmi2SetRealInputDerivatives", "an array is NULL");
    for (i = 0; i < n; i++) {
        if (input_index(vr[i]) < 0)
            return refuse(m, "fmi2SetRealInputDerivatives", "this variable is not an input");
        if (order[i] != 1 && order[i] != 2)
            return refuse(m, "fmi2SetRealInputDerivatives", "order must be 1 or 2");
        if (!isfinite(value[i])) return refuse(m, "fmi2SetRealInputDerivatives", "a derivative must be finite");
    }
    restart_inputs(m, -1);
    for (i = 0; i < n; i++) m->input_derivatives[input_index(vr[i])][order[i] - 1] = value[i];
    return fmi2OK;
}

/* The FMU state: everything a step reads and writes (the values, the inputs' course, the
 * time and the lifecycle state), not the master's callbacks or the instance's name. A
 * master that rejects a communication step restores it and steps again, shorter. */
typedef struct {
    double values[MAX_VARIABLES];
    double input_derivatives[MAX_INPUTS][2];
    double elapsed;
    double time;
    double state;
} Snapshot;

/* Serialized: the model's tag, then the snapshot's doubles in this platform's byte order. */
enum { SNAPSHOT_DOUBLES = sizeof(Snapshot) / sizeof(double),
       SERIALIZED_SIZE = sizeof MODEL_STATE_TAG + sizeof(Snapshot) };

static void take(const Fmu *m, Snapshot *s) {
    memcpy(s->values, m->values, sizeof s->values);
    memcpy(s->input_derivatives, m->input_derivatives, sizeof s->input_derivatives);
    s->elapsed = m->elapsed;
    s->time = m->time;
    s->state = (double)m->state;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *out) {
    Fmu *m = c;
    Snapshot *s;
    if (!m) return fmi2Error;
    if (!out) return refuse(m, "fmi2GetFMUstate", "FMUstate is NULL");
    /* A state the master passes back is overwritten, as the standard has it. */
    s = *out ? (Snapshot *)*out : malloc(sizeof *s);
    if (!s) return refuse(m, "fmi2GetFMUstate", "out of memory");
    take(m, s);
    *out = s;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Fmu *m = c;
    const Snapshot *s = state;
    if (!m) return fmi2Error;
    if (!s) return refuse(m, "fmi2SetFMUstate", "FMUstate is NULL");
    memcpy(m->values, s->values, sizeof m->values);
    memcpy(m->input_derivatives, s->input_derivatives, sizeof m->input_derivatives);
    m->elapsed = s->elapsed;
    m->time = s->time;
    m->state = (Lifecycle)s->state;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    if (!c) return fmi2Error;
    if (state) {
        free(*state);
        *state = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    if (!c) return fmi2Error;
    if (!state || !size) return refuse(c, "fmi2SerializedFMUstateSize", "an argument is NULL");
    *size = SERIALIZED_SIZE;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    if (!c) return fmi2Error;
    if (!state || !bytes) return refuse(c, "fmi2SerializeFMUstate", "an argument is NULL");
    if (size < SERIALIZED_SIZE) return refuse(c, "fmi2SerializeFMUstate", "the buffer is too small");
    memcpy(bytes, MODEL_STATE_TAG, sizeof MODEL_STATE_TAG);
    memcpy(bytes + sizeof MODEL_STATE_TAG, state, sizeof(Snapshot));
    return fmi2OK;
}

/* Only what this FMU wrote: the tag, the size, finite values and a lifecycle state. */
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                   fmi2FMUstate *out) {
    Snapshot read, *s;
    const double *field = (const double *)&read;
    size_t i;
    if (!c) return fmi2Error;
    if (!bytes || !out) return refuse(c, "fmi2DeSerializeFMUstate", "an argument is NULL");
    if (size != SERIALIZED_SIZE || memcmp(bytes, MODEL_STATE_TAG, sizeof MODEL_STATE_TAG) != 0)
        return refuse(c, "fmi2DeSerializeFMUstate", "not a state this FMU serialized");
    memcpy(&read, bytes + sizeof MODEL_STATE_TAG, sizeof read);
    for (i = 0; i < SNAPSHOT_DOUBLES; i++)
        if (!isfinite(field[i])) return refuse(c, "fmi2DeSerializeFMUstate", "a value is not finite");
    if (read.state != floor(read.state) || read.state < INSTANTIATED || read.state > TERMINATED)
        return refuse(c, "fmi2DeSerializeFMUstate", "not a state this FMU serialized");
    s = malloc(sizeof *s);
    if (!s) return refuse(c, "fmi2DeSerializeFMUstate", "out of memory");
    *s = read;
    *out = s;
    return fmi2OK;
}

/* What these models do not have: no Integer, Boolean or String variables (an empty request
 * succeeds), no directional derivatives, no asynchronous steps. */
#define NO_VARIABLES(fn, T, qualifier)                                                          \
    fmi2Status fn(fmi2Component c, const fmi2ValueReference vr[], size_t n, qualifier T value[]) { \
        (void)vr;                                                                               \
        (void)value;                                                                            \
        if (!c) return fmi2Error;                                                               \
        return n == 0 ? fmi2OK : refuse(c, #fn, "this FMU has no variables of this type");       \
    }
NO_VARIABLES(fmi2GetInteger, fmi2Integer, )
NO_VARIABLES(fmi2GetBoolean, fmi2Boolean, )
NO_VARIABLES(fmi2GetString, fmi2String, )
NO_VARIABLES(fmi2SetInteger, fmi2Integer, const)
NO_VARIABLES(fmi2SetBoolean, fmi2Boolean, const)
NO_VARIABLES(fmi2SetString, fmi2String, const)

#define UNSUPPORTED(fn, ...)                                                                    \
    fmi2Status fn(fmi2Component c, __VA_ARGS__) {                                               \
        return c ? refuse(c, #fn, "not supported by this FMU (see its modelDescription.xml)")    \
                 : fmi2Error;                                                                   \
    }
UNSUPPORTED(fmi2GetDirectionalDerivative, const fmi2ValueReference u[], size_t nu,
            const fmi2ValueReference k[], size_t nk, const fmi2Real dk[], fmi2Real du[])
UNSUPPORTED(fmi2GetStatus, const fmi2StatusKind s, fmi2Status *value)
UNSUPPORTED(fmi2GetRealStatus, const fmi2StatusKind s, fmi2Real *value)
UNSUPPORTED(fmi2GetIntegerStatus, const fmi2StatusKind s, fmi2Integer *value)
UNSUPPORTED(fmi2GetBooleanStatus, const fmi2StatusKind s, fmi2Boolean *value)
UNSUPPORTED(fmi2GetStringStatus, const fmi2StatusKind s, fmi2String *value)

fmi2Status fmi2CancelStep(fmi2Component c) {
    return c ? refuse(c, "fmi2CancelStep", "this FMU never returns fmi2Pending") : fmi2Error;
}

/* Model Exchange functions: exported because fmi2Functions.h declares them, refused
 * because these FMUs are for Co-Simulation only. */
#define NOT_MODEL_EXCHANGE(fn, ...)                                                             \
    fmi2Status fn(fmi2Component c, __VA_ARGS__) {                                               \
        return c ? refuse(c, #fn, "a Model Exchange function; this FMU is Co-Simulation only")  \
                 : fmi2Error;                                                                   \
    }
fmi2Status fmi2EnterEventMode(fmi2Component c) {
    return c ? refuse(c, "fmi2EnterEventMode", "a Model Exchange function; this FMU is Co-Simulation only") : fmi2Error;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    return c ? refuse(c, "fmi2EnterContinuousTimeMode", "a Model Exchange function; this FMU is Co-Simulation only") : fmi2Error;
}
NOT_MODEL_EXCHANGE(fmi2NewDiscreteStates, fmi2EventInfo *info)
NOT_MODEL_EXCHANGE(fmi2CompletedIntegratorStep, fmi2Boolean noSetPrior, fmi2Boolean *event,
                   fmi2Boolean *terminate)
NOT_MODEL_EXCHANGE(fmi2SetTime, fmi2Real time)
NOT_MODEL_EXCHANGE(fmi2SetContinuousStates, const fmi2Real x[], size_t nx)
NOT_MODEL_EXCHANGE(fmi2GetDerivatives, fmi2Real dx[], size_t nx)
NOT_MODEL_EXCHANGE(fmi2GetEventIndicators, fmi2Real z[], size_t nz)
NOT_MODEL_EXCHANGE(fmi2GetContinuousStates, fmi2Real x[], size_t nx)
NOT_MODEL_EXCHANGE(fmi2GetNominalsOfContinuousStates, fmi2Real x[], size_t nx)
