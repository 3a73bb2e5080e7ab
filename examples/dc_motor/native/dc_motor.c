/* A DC motor as an FMI 2.0 co-simulation FMU in C: armature voltage and shaft speed in,
 * current and torque out. Electrical state: L·di/dt = V − R·i − k·ω; torque k·i. With the
 * inputs held over a communication step, or moving along the first and second derivatives
 * a master sets (fmi2SetRealInputDerivatives), the current has an exact solution, so a
 * step of any size is exact; its output derivatives are exact too (the same equations as
 * ../dc_motor.py, which builds the same motor with pythonfmu and holds its inputs). Built
 * and packed by `cargo xtask motor` into target/fmu/DcMotor.fmu. */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

/* Also in modelDescription.xml; tests/python/test_dc_motor.py checks the two agree. */
#define GUID "{4d4f544f-5200-4443-2d6d-6f746f720001}"

enum { VR_R, VR_L, VR_K, VR_VOLTAGE, VR_OMEGA, VR_CURRENT, VR_TORQUE, N_VARIABLES };
static const char *const NAMES[N_VARIABLES] = {"R", "L", "k", "voltage", "omega", "current",
                                                "torque"};

typedef enum { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED } State;

typedef struct {
    double values[N_VARIABLES];
    /* d/dt and d²/dt² of the inputs voltage and omega, as the master set them; the inputs
     * move along them from the time they were set, `elapsed` ago. */
    double input_derivatives[2][2];
    double elapsed;
    double time;
    State state;
    fmi2CallbackFunctions callbacks;
    char name[64];
} Motor;

/* The message is passed as the logger's format, with '%' doubled: masters that format it
 * and masters that print it as it is (FMPy's ctypes callback cannot read variadic
 * arguments) both show it. */
static void report(Motor *m, fmi2Status status, const char *format, ...) {
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

static fmi2Status refuse(Motor *m, const char *function, const char *why) {
    report(m, fmi2Error, "%s: %s", function, why);
    return fmi2Error;
}

/* The outputs from the state: torque = k·i. */
static void update_outputs(Motor *m) {
    m->values[VR_TORQUE] = m->values[VR_K] * m->values[VR_CURRENT];
}

static void set_defaults(Motor *m) {
    memset(m->values, 0, sizeof m->values);
    memset(m->input_derivatives, 0, sizeof m->input_derivatives);
    m->elapsed = 0.0;
    m->values[VR_R] = 0.5;
    m->values[VR_L] = 0.01;
    m->values[VR_K] = 2.0;
    m->values[VR_VOLTAGE] = 24.0;
    m->time = 0.0;
    m->state = INSTANTIATED;
}

/* The forcing V − k·ω and its first two time derivatives, `s` after the inputs were set. */
static void forcing(const Motor *m, double s, double f[3]) {
    const double *v = m->values, (*d)[2] = m->input_derivatives;
    double voltage = v[VR_VOLTAGE] + s * (d[0][0] + 0.5 * s * d[0][1]);
    double omega = v[VR_OMEGA] + s * (d[1][0] + 0.5 * s * d[1][1]);
    f[0] = voltage - v[VR_K] * omega;
    f[1] = (d[0][0] + s * d[0][1]) - v[VR_K] * (d[1][0] + s * d[1][1]);
    f[2] = d[0][1] - v[VR_K] * d[1][1];
}

/* di/dt and d²i/dt² now. */
static void current_rates(const Motor *m, double rates[2]) {
    const double *v = m->values;
    double f[3];
    forcing(m, m->elapsed, f);
    rates[0] = (f[0] - v[VR_R] * v[VR_CURRENT]) / v[VR_L];
    rates[1] = (f[1] - v[VR_R] * rates[0]) / v[VR_L];
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String resources, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Motor *m;
    (void)resources;
    (void)visible;
    (void)loggingOn;
    if (!functions || fmuType != fmi2CoSimulation || !fmuGUID || strcmp(fmuGUID, GUID) != 0)
        return NULL;
    m = calloc(1, sizeof *m);
    if (!m) return NULL;
    m->callbacks = *functions;
    snprintf(m->name, sizeof m->name, "%s", instanceName ? instanceName : "motor");
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
    Motor *m = c;
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
    Motor *m = c;
    if (!m) return fmi2Error;
    if (m->state != INSTANTIATED) return refuse(m, "fmi2EnterInitializationMode", "only after instantiation");
    m->state = INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Motor *m = c;
    if (!m) return fmi2Error;
    if (m->state != INITIALIZATION) return refuse(m, "fmi2ExitInitializationMode", "not in initialization mode");
    update_outputs(m);
    m->state = STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Motor *m = c;
    if (!m) return fmi2Error;
    m->state = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Motor *m = c;
    if (!m) return fmi2Error;
    set_defaults(m);
    return fmi2OK;
}

/* Whether `value` may be written to `vr` now, and if not why, in `why` (the caller's
 * buffer: instances may run in threads of their own). The rules: parameters R, L > 0 and
 * k >= 0, settable before initialisation ends; inputs any finite number; outputs not
 * settable. */
static int refused(const Motor *m, fmi2ValueReference vr, double value, char *why, size_t size) {
    if (vr >= N_VARIABLES)
        snprintf(why, size, "no variable has value reference %u", vr);
    else if (!isfinite(value))
        snprintf(why, size, "%s = %g: must be a finite number", NAMES[vr], value);
    else if (vr == VR_CURRENT || vr == VR_TORQUE)
        snprintf(why, size, "%s is an output and cannot be set", NAMES[vr]);
    else if (vr <= VR_K && m->state != INSTANTIATED && m->state != INITIALIZATION)
        snprintf(why, size, "%s is a fixed parameter: set it before fmi2ExitInitializationMode",
                 NAMES[vr]);
    else if ((vr == VR_R || vr == VR_L) && !(value > 0.0))
        snprintf(why, size, "%s = %g: must be > 0", NAMES[vr], value);
    else if (vr == VR_K && value < 0.0)
        snprintf(why, size, "k = %g: must be >= 0", value);
    else
        return 0;
    return 1;
}

/* Move the inputs to now along their derivatives, all but `kept` (just set), and count
 * their time from now. */
static void restart_inputs(Motor *m, fmi2ValueReference kept) {
    double s = m->elapsed, (*d)[2] = m->input_derivatives;
    int j;
    for (j = 0; j < 2; j++) {
        fmi2ValueReference vr = j == 0 ? VR_VOLTAGE : VR_OMEGA;
        if (vr != kept) m->values[vr] += s * (d[j][0] + 0.5 * s * d[j][1]);
        d[j][0] += s * d[j][1];
    }
    m->elapsed = 0.0;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Motor *m = c;
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
        m->values[vr[i]] = value[i];
        /* A new input value: the inputs move from here along their derivatives. The other
         * input is moved to now first, so that it keeps its course. */
        if (vr[i] == VR_VOLTAGE || vr[i] == VR_OMEGA) restart_inputs(m, vr[i]);
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Motor *m = c;
    size_t i;
    if (!m) return fmi2Error;
    if (m->state == INSTANTIATED) return refuse(m, "fmi2GetReal", "not before fmi2EnterInitializationMode");
    if (n > 0 && (!vr || !value)) return refuse(m, "fmi2GetReal", "vr or value is NULL");
    update_outputs(m);
    for (i = 0; i < n; i++) {
        if (vr[i] >= N_VARIABLES) return refuse(m, "fmi2GetReal", "unknown value reference");
        value[i] = m->values[vr[i]];
    }
    return fmi2OK;
}

/* The exact step: with the forcing F(s) = F0 + F1·s + F2·s²/2 over the step (constant for
 * held inputs), L·i' + R·i = F has the particular solution a + b·s + c·s² with R·c = F2/2,
 * R·b = F1 − 2L·c, R·a = F0 − L·b, and i − (a + b·s + c·s²) decays with the time constant
 * L/R. Held inputs give b = c = 0: i relaxes to its steady value (V − k·ω)/R. */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real now, fmi2Real h, fmi2Boolean noSetPrior) {
    Motor *m = c;
    double f[3], a, b, cc, R, L, decay;
    (void)noSetPrior;
    if (!m) return fmi2Error;
    if (m->state != STEPPING) return refuse(m, "fmi2DoStep", "only after initialisation");
    if (!(h > 0.0) || !isfinite(h)) return refuse(m, "fmi2DoStep", "communicationStepSize must be finite and > 0");
    if (fabs(now - m->time) > 1e-12 * fmax(fabs(m->time), h))
        return refuse(m, "fmi2DoStep", "currentCommunicationPoint does not match the FMU's time");
    R = m->values[VR_R];
    L = m->values[VR_L];
    forcing(m, m->elapsed, f);
    cc = 0.5 * f[2] / R;
    b = (f[1] - 2.0 * L * cc) / R;
    a = (f[0] - L * b) / R;
    decay = exp(-h * R / L);
    m->values[VR_CURRENT] = (a + h * (b + h * cc)) + (m->values[VR_CURRENT] - a) * decay;
    update_outputs(m);
    m->elapsed += h;
    m->time = now + h;
    return fmi2OK;
}

/* torque' = k·di/dt and torque'' = k·d²i/dt², with d²i/dt² = (F' − R·di/dt)/L (F' = 0
 * for held inputs); likewise for the current. */
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    Motor *m = c;
    size_t i;
    if (!m) return fmi2Error;
    if (m->state != STEPPING && m->state != TERMINATED)
        return refuse(m, "fmi2GetRealOutputDerivatives", "only after initialisation");
    if (n > 0 && (!vr || !order || !value)) return refuse(m, "fmi2GetRealOutputDerivatives", "an array is NULL");
    for (i = 0; i < n; i++) {
        double rates[2], scale;
        current_rates(m, rates);
        if (vr[i] != VR_CURRENT && vr[i] != VR_TORQUE)
            return refuse(m, "fmi2GetRealOutputDerivatives", "only current and torque have output derivatives");
        if (order[i] != 1 && order[i] != 2)
            return refuse(m, "fmi2GetRealOutputDerivatives", "order must be 1 or 2");
        scale = vr[i] == VR_TORQUE ? m->values[VR_K] : 1.0;
        value[i] = scale * rates[order[i] - 1];
    }
    return fmi2OK;
}

/* The inputs' first and second derivatives, for the steps to come: applied from now (the
 * inputs' values are moved to now first). */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Motor *m = c;
    size_t i;
    if (!m) return fmi2Error;
    if (m->state != INITIALIZATION && m->state != STEPPING)
        return refuse(m, "fmi2SetRealInputDerivatives", "only in initialisation or stepping");
    if (n > 0 && (!vr || !order || !value)) return refuse(m, "fmi2SetRealInputDerivatives", "an array is NULL");
    for (i = 0; i < n; i++) {
        if (vr[i] != VR_VOLTAGE && vr[i] != VR_OMEGA)
            return refuse(m, "fmi2SetRealInputDerivatives", "only voltage and omega are inputs");
        if (order[i] != 1 && order[i] != 2)
            return refuse(m, "fmi2SetRealInputDerivatives", "order must be 1 or 2");
        if (!isfinite(value[i])) return refuse(m, "fmi2SetRealInputDerivatives", "a derivative must be finite");
    }
    restart_inputs(m, N_VARIABLES);
    for (i = 0; i < n; i++) m->input_derivatives[vr[i] == VR_OMEGA][order[i] - 1] = value[i];
    return fmi2OK;
}

/* The FMU state: everything a step reads and writes (the values, the inputs' course, the
 * time and the lifecycle state), not the master's callbacks or the instance's name. A
 * master that rejects a communication step restores it and steps again, shorter. */
typedef struct {
    double values[N_VARIABLES];
    double input_derivatives[2][2];
    double elapsed;
    double time;
    double state;
} Snapshot;

/* Serialized: this tag, then the snapshot's doubles in this platform's byte order. */
static const char SNAPSHOT_TAG[8] = {'D', 'C', 'M', 'O', 'T', 'O', 'R', '1'};
enum { SNAPSHOT_DOUBLES = sizeof(Snapshot) / sizeof(double),
       SERIALIZED_SIZE = sizeof SNAPSHOT_TAG + sizeof(Snapshot) };

static void take(const Motor *m, Snapshot *s) {
    memcpy(s->values, m->values, sizeof s->values);
    memcpy(s->input_derivatives, m->input_derivatives, sizeof s->input_derivatives);
    s->elapsed = m->elapsed;
    s->time = m->time;
    s->state = (double)m->state;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *out) {
    Motor *m = c;
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
    Motor *m = c;
    const Snapshot *s = state;
    if (!m) return fmi2Error;
    if (!s) return refuse(m, "fmi2SetFMUstate", "FMUstate is NULL");
    memcpy(m->values, s->values, sizeof m->values);
    memcpy(m->input_derivatives, s->input_derivatives, sizeof m->input_derivatives);
    m->elapsed = s->elapsed;
    m->time = s->time;
    m->state = (State)s->state;
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
    memcpy(bytes, SNAPSHOT_TAG, sizeof SNAPSHOT_TAG);
    memcpy(bytes + sizeof SNAPSHOT_TAG, state, sizeof(Snapshot));
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
    if (size != SERIALIZED_SIZE || memcmp(bytes, SNAPSHOT_TAG, sizeof SNAPSHOT_TAG) != 0)
        return refuse(c, "fmi2DeSerializeFMUstate", "not a state this FMU serialized");
    memcpy(&read, bytes + sizeof SNAPSHOT_TAG, sizeof read);
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

/* What this motor does not have: no Integer, Boolean or String variables (an empty request
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
 * because this FMU is for Co-Simulation only. */
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
