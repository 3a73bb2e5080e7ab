/* The bouncing ball, the model its three FMUs share: the Co-Simulation one (native/, which
 * steps it exactly) and the Model Exchange ones (model_exchange/, FMI 2.0 and 3.0, whose
 * masters integrate it). States h (height) and v (upward speed), h' = v, v' = −g; one
 * event indicator, the height, whose fall through zero is a bounce (v reverses, times e;
 * slower than v_min the ball stays at rest); a time event at t_kick adds dv to v. */
#ifndef BALL_H
#define BALL_H

#include <float.h>
#include <math.h>
#include <string.h>

enum { VR_TIME, VR_H, VR_V, VR_G, VR_E, VR_H0, VR_V0, VR_V_MIN, VR_T_KICK, VR_DV, VR_BOUNCES, VR_KICKS,
       VR_DER_H, VR_DER_V, VR_INDICATOR };
enum { FLOATS = VR_DV + 1, STATES = 2, INDICATORS = 1 };

typedef struct {
    double x[FLOATS]; /* time, h, v and the parameters, by value reference */
    int bounces, kicks, resting;
} Ball;

static inline void ball_defaults(Ball *b) {
    memset(b, 0, sizeof *b);
    b->x[VR_G] = 9.81;
    b->x[VR_E] = 0.7;
    b->x[VR_H0] = 1.0;
    b->x[VR_V_MIN] = 0.1;
    b->x[VR_T_KICK] = 1e300;
}

/* Whether a parameter's value is allowed (g > 0, 0 <= e < 1, h0 >= 0, v_min > 0). */
static inline int ball_allowed(unsigned vr, double x) {
    if (!isfinite(x)) return 0;
    if (vr == VR_G || vr == VR_V_MIN) return x > 0.0;
    if (vr == VR_E) return x >= 0.0 && x < 1.0;
    if (vr == VR_H0) return x >= 0.0;
    return vr >= VR_G && vr <= VR_DV;
}

/* Whether a parameter may change after initialisation (in event mode): e alone, which
 * takes effect at the next bounce. */
static inline int ball_tunable(unsigned vr) { return vr == VR_E; }
static inline void ball_start(Ball *b) {
    b->x[VR_H] = b->x[VR_H0];
    b->x[VR_V] = b->x[VR_V0];
}

static inline void ball_derivatives(const Ball *b, double dx[STATES]) {
    dx[0] = b->resting ? 0.0 : b->x[VR_V];
    dx[1] = b->resting ? 0.0 : -b->x[VR_G];
}

/* The height, except at rest (no more crossings) and just after a bounce, where the ball
 * leaves from the least positive height so that the indicator starts above zero. */
static inline double ball_indicator(const Ball *b) {
    return b->resting ? 1.0 : b->x[VR_H];
}

/* A Float64 (Real) variable by value reference: the state, parameters and time, the
 * derivatives and the event indicator; 0 when `vr` is none of them. */
static inline int ball_real(const Ball *b, unsigned vr, double *value);

static inline int ball_kick_due(const Ball *b) {
    return b->kicks == 0 && b->x[VR_T_KICK] < 1e299;
}

/* A bounce: the speed reverses, times e, and the ball leaves from the least positive
 * height (so that the indicator starts above zero); slower than v_min it stays at rest. */
static inline void ball_bounce(Ball *b) {
    b->x[VR_V] = -b->x[VR_E] * b->x[VR_V];
    b->x[VR_H] = DBL_MIN;
    b->bounces++;
    if (b->x[VR_V] < b->x[VR_V_MIN]) {
        b->x[VR_V] = 0.0;
        b->x[VR_H] = 0.0;
        b->resting = 1;
    }
}

/* The kick: dv added to the speed; upward, it lifts a resting ball. */
static inline void ball_kick(Ball *b) {
    b->x[VR_V] += b->x[VR_DV];
    b->kicks++;
    if (b->resting && b->x[VR_V] > 0.0) {
        b->resting = 0;
        b->x[VR_H] = DBL_MIN;
    }
}

/* The discrete update at an event of an integrating master: a bounce where the ball is at
 * or below the ground and falling, the kick once its time has come. Returns whether the
 * states changed. */
static inline int ball_update(Ball *b) {
    int changed = 0;
    if (!b->resting && b->x[VR_H] <= 0.0 && b->x[VR_V] < 0.0) {
        ball_bounce(b);
        changed = 1;
    }
    if (ball_kick_due(b) && b->x[VR_TIME] >= b->x[VR_T_KICK]) {
        ball_kick(b);
        changed = 1;
    }
    return changed;
}

/* An Int32 (Integer) variable by value reference: the bounces or the kicks; 0 when `vr`
 * is neither. */
static inline int ball_integer(const Ball *b, unsigned vr, int *value) {
    if (vr == VR_BOUNCES) *value = b->bounces;
    else if (vr == VR_KICKS) *value = b->kicks;
    else return 0;
    return 1;
}

static inline int ball_real(const Ball *b, unsigned vr, double *value) {
    double dx[STATES];
    ball_derivatives(b, dx);
    if (vr < FLOATS) *value = b->x[vr];
    else if (vr == VR_DER_H) *value = dx[0];
    else if (vr == VR_DER_V) *value = dx[1];
    else if (vr == VR_INDICATOR) *value = ball_indicator(b);
    else return 0;
    return 1;
}

#endif
