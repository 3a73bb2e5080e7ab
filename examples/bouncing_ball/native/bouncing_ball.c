/* A ball bouncing on the ground, as an FMI 3.0 Co-Simulation FMU with event mode: a test
 * subject with a state event (the ball reaches the ground: its speed reverses, times the
 * restitution e) and a time event (at t_kick the ball is kicked upward by dv). Between
 * events the motion is ballistic and stepped exactly (h = h0 + v0 τ − g τ²/2), so every
 * value has a known solution. A bounce slower than v_min leaves the ball at rest (else
 * the bounces would pile up without end before a finite time).
 *
 * With event mode used and early return allowed, a step stops at the first event inside
 * it (returning early, or at its end) and asks the master to handle it; the master's
 * fmi3UpdateDiscreteStates applies it. Otherwise the FMU handles its events inside the
 * step. Counters: n_bounces (the bounces so far) and n_kicks. The model (its variables,
 * checks, bounce and kick) is ../ball.h, which the Model Exchange balls share; the exact
 * step between events is this file's. */

#include <stdio.h>
#include <stdlib.h>

#include "../ball.h"
#include "fmi3Functions.h"

typedef enum { INSTANTIATED, INITIALIZATION, EVENT, STEP, TERMINATED } Mode;
typedef enum { NONE, BOUNCE, KICK } Event;

typedef struct {
    Ball ball;
    Event pending; /* the event a step stopped at, for the master to handle */
    int event_mode, early_return;
    Mode mode;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log;
    char name[64];
} Instance;

static const char TOKEN[] = "{5b3f0e6e-2f55-4d8e-9a3b-bouncing-ball}";

static void say(const Instance *b, fmi3Status status, const char *message) {
    if (b->log) b->log(b->environment, status, "logStatusError", message);
}

static fmi3Status refuse(const Instance *b, const char *message) {
    say(b, fmi3Error, message);
    return fmi3Error;
}

static void defaults(Instance *b) {
    ball_defaults(&b->ball);
    b->pending = NONE;
}

/* The time from now until the ball reaches the ground; infinity at rest. */
static double time_to_ground(const Instance *b) {
    double h = b->ball.x[VR_H], v = b->ball.x[VR_V], g = b->ball.x[VR_G];
    if (b->ball.resting) return INFINITY;
    /* The larger root of h + v τ − g τ²/2 = 0, written so that it does not cancel. */
    double root = sqrt(v * v + 2.0 * g * h);
    return v >= 0.0 ? (v + root) / g : 2.0 * h / (root - v);
}

static void fly(Instance *b, double tau) {
    if (b->ball.resting) return;
    double g = b->ball.x[VR_G];
    b->ball.x[VR_H] += tau * (b->ball.x[VR_V] - 0.5 * g * tau);
    b->ball.x[VR_V] -= g * tau;
}

static void apply(Instance *b, Event e) {
    if (e == BOUNCE) ball_bounce(&b->ball);
    else if (e == KICK) ball_kick(&b->ball);
}

/* The first event after now and no later than `end`, and its time; NONE when none. */
static Event next_event(const Instance *b, double end, double *when) {
    double now = b->ball.x[VR_TIME];
    double ground = now + time_to_ground(b);
    double kick = b->ball.kicks == 0 && b->ball.x[VR_T_KICK] > now ? b->ball.x[VR_T_KICK] : INFINITY;
    Event e = NONE;
    *when = end;
    if (kick <= end) { e = KICK; *when = kick; }
    if (ground <= *when && ground <= end) { e = BOUNCE; *when = ground; }
    return e;
}

/* A change of mode the standard allows only from `from`. */
static fmi3Status switch_mode(Instance *b, Mode from, Mode to, const char *refusal) {
    if (b->mode != from) return refuse(b, refusal);
    b->mode = to;
    return fmi3OK;
}

FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean on, size_t n,
                                           const fmi3String categories[]) {
    return instance ? fmi3OK : fmi3Error;
}

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging, fmi3Boolean event_mode, fmi3Boolean early_return,
    const fmi3ValueReference required[], size_t n_required, fmi3InstanceEnvironment environment,
    fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback intermediate) {
    if (!token || strcmp(token, TOKEN) != 0) return NULL;
    Instance *b = calloc(1, sizeof *b);
    if (!b) return NULL;
    snprintf(b->name, sizeof b->name, "%s", name ? name : "");
    b->environment = environment;
    b->log = logging ? log : NULL;
    b->event_mode = event_mode;
    b->early_return = early_return;
    b->mode = INSTANTIATED;
    defaults(b);
    return b;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean has_tol,
                                                   fmi3Float64 tol, fmi3Float64 start,
                                                   fmi3Boolean has_stop, fmi3Float64 stop) {
    Instance *b = instance;
    b->ball.x[VR_TIME] = b->mode == INSTANTIATED ? start : b->ball.x[VR_TIME];
    return switch_mode(b, INSTANTIATED, INITIALIZATION,
                       "fmi3EnterInitializationMode: not instantiated");
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *b = instance;
    if (b->mode != INITIALIZATION) return refuse(b, "fmi3ExitInitializationMode: not initialising");
    b->ball.x[VR_H] = b->ball.x[VR_H0];
    b->ball.x[VR_V] = b->ball.x[VR_V0];
    b->mode = b->event_mode ? EVENT : STEP;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    return switch_mode(instance, STEP, EVENT, "fmi3EnterEventMode: not in step mode");
}

FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *again,
                                                fmi3Boolean *terminate, fmi3Boolean *nominals,
                                                fmi3Boolean *values, fmi3Boolean *next_defined,
                                                fmi3Float64 *next_time) {
    Instance *b = instance;
    if (b->mode != EVENT) return refuse(b, "fmi3UpdateDiscreteStates: not in event mode");
    int changed = b->pending != NONE;
    apply(b, b->pending);
    b->pending = NONE;
    *again = fmi3False;
    *terminate = fmi3False;
    *nominals = fmi3False;
    *values = changed;
    *next_defined = b->ball.kicks == 0 && b->ball.x[VR_T_KICK] > b->ball.x[VR_TIME] && b->ball.x[VR_T_KICK] < 1e299;
    *next_time = *next_defined ? b->ball.x[VR_T_KICK] : 0.0;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    return switch_mode(instance, EVENT, STEP, "fmi3EnterStepMode: not in event mode");
}

FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 now, fmi3Float64 h,
                                  fmi3Boolean no_set_prior, fmi3Boolean *event,
                                  fmi3Boolean *terminate, fmi3Boolean *early,
                                  fmi3Float64 *last) {
    Instance *b = instance;
    if (b->mode != STEP) return refuse(b, "fmi3DoStep: not in step mode");
    if (!(h > 0.0) || fabs(now - b->ball.x[VR_TIME]) > 1e-12 * fmax(1.0, fabs(now)))
        return refuse(b, "fmi3DoStep: the step does not start at the FMU's time or is not positive");
    double end = now + h, when;
    int stop_at_events = b->event_mode && b->early_return;
    *event = *terminate = *early = fmi3False;
    for (int guard = 0; guard < 1000000; guard++) {
        Event e = next_event(b, end, &when);
        fly(b, when - b->ball.x[VR_TIME]);
        b->ball.x[VR_TIME] = when;
        if (e == NONE) break;
        if (stop_at_events) {
            b->pending = e;
            *event = fmi3True;
            *early = when < end;
            break;
        }
        apply(b, e);
    }
    b->ball.x[VR_TIME] = *early ? when : end;
    *last = b->ball.x[VR_TIME];
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) {
    ((Instance *)instance)->mode = TERMINATED;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
    Instance *b = instance;
    defaults(b);
    b->mode = INSTANTIATED;
    return fmi3OK;
}

static int parameter(fmi3ValueReference vr) { return vr >= VR_G && vr <= VR_DV; }

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[],
                                      size_t n, const fmi3Float64 values[], size_t nv) {
    Instance *b = instance;
    if (n != nv) return refuse(b, "fmi3SetFloat64: one value per value reference");
    for (size_t i = 0; i < n; i++) {
        char why[160];
        if (!parameter(vr[i])) return refuse(b, "fmi3SetFloat64: only the parameters can be set");
        int tunable_now = ball_tunable(vr[i]) &&
                          (b->mode == EVENT || (b->mode == STEP && !b->event_mode));
        if (b->mode != INSTANTIATED && b->mode != INITIALIZATION && !tunable_now)
            return refuse(b, "fmi3SetFloat64: the parameters are fixed after initialisation "
                             "(e, tunable, may change in event mode, or in step mode without it)");
        double x = values[i];
        if (!ball_allowed(vr[i], x)) {
            snprintf(why, sizeof why, "fmi3SetFloat64: value reference %u = %g is out of range "
                     "(g > 0, 0 <= e < 1, h0 >= 0, v_min > 0)", (unsigned)vr[i], x);
            return refuse(b, why);
        }
        b->ball.x[vr[i]] = x;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[],
                                      size_t n, fmi3Float64 values[], size_t nv) {
    Instance *b = instance;
    if (n != nv) return refuse(b, "fmi3GetFloat64: one value per value reference");
    for (size_t i = 0; i < n; i++)
        if (vr[i] >= FLOATS || !ball_real(&b->ball, vr[i], &values[i]))
            return refuse(b, "fmi3GetFloat64: not a Float64 value reference");
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[],
                                    size_t n, fmi3Int32 values[], size_t nv) {
    Instance *b = instance;
    if (n != nv) return refuse(b, "fmi3GetInt32: one value per value reference");
    for (size_t i = 0; i < n; i++)
        if (!ball_integer(&b->ball, vr[i], &values[i]))
            return refuse(b, "fmi3GetInt32: not an Int32 value reference");
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[],
                                    size_t n, const fmi3Int32 values[], size_t nv) {
    return n == 0 ? fmi3OK : refuse(instance, "fmi3SetInt32: the Int32 variables are outputs");
}

FMI3_Export fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[],
                                      size_t n, fmi3Boolean values[], size_t nv) {
    return n == 0 ? fmi3OK : refuse(instance, "fmi3GetBoolean: the FMU has no Boolean");
}

FMI3_Export fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[],
                                      size_t n, const fmi3Boolean values[], size_t nv) {
    return n == 0 ? fmi3OK : refuse(instance, "fmi3SetBoolean: the FMU has no Boolean");
}
