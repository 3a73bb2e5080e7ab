/* A DC motor as an FMI 2.0 co-simulation FMU in C: armature voltage and shaft speed in,
 * current and torque out. Electrical state: L·di/dt = V − R·i − k·ω; torque k·i. With the
 * inputs held over a communication step, or moving along the first and second derivatives
 * a master sets (fmi2SetRealInputDerivatives), the current has an exact solution, so a
 * step of any size is exact; its output derivatives are exact too (the same equations as
 * ../dc_motor.py, which builds the same motor with pythonfmu and holds its inputs). The
 * FMI functions are ../../native/cosim.c's; built and packed by `cargo xtask motor` into
 * target/fmu/DcMotor.fmu. */

#include <math.h>
#include <stdio.h>

#include "cosim.h"

/* Also in modelDescription.xml; tests/python/test_dc_motor.py checks the two agree. */
#define GUID "{4d4f544f-5200-4443-2d6d-6f746f720001}"

enum { VR_R, VR_L, VR_K, VR_VOLTAGE, VR_OMEGA, VR_CURRENT, VR_TORQUE, N_VARIABLES };
enum { IN_VOLTAGE, IN_OMEGA };

const char MODEL_GUID[] = GUID;
const char MODEL_STATE_TAG[8] = {'D', 'C', 'M', 'O', 'T', 'O', 'R', '1'};
const int MODEL_VARIABLES = N_VARIABLES;
const char *const MODEL_NAMES[N_VARIABLES] = {"R", "L", "k", "voltage", "omega", "current",
                                              "torque"};
const Causality MODEL_CAUSALITY[N_VARIABLES] = {PARAMETER, PARAMETER, PARAMETER, INPUT,
                                                INPUT,     OUTPUT,    OUTPUT};
const int MODEL_INPUTS = 2;
const fmi2ValueReference MODEL_INPUT_VRS[] = {VR_VOLTAGE, VR_OMEGA};
const int MODEL_DERIVED = 2;
const fmi2ValueReference MODEL_DERIVED_VRS[] = {VR_CURRENT, VR_TORQUE};

void model_defaults(Fmu *m) {
    m->values[VR_R] = 0.5;
    m->values[VR_L] = 0.01;
    m->values[VR_K] = 2.0;
    m->values[VR_VOLTAGE] = 24.0;
}

/* R, L > 0 and k >= 0; the inputs any finite number. */
int model_out_of_range(fmi2ValueReference vr, double value, char *why, size_t size) {
    if ((vr == VR_R || vr == VR_L) && !(value > 0.0))
        snprintf(why, size, "%s = %g: must be > 0", MODEL_NAMES[vr], value);
    else if (vr == VR_K && value < 0.0)
        snprintf(why, size, "k = %g: must be >= 0", value);
    else
        return 0;
    return 1;
}

/* The outputs from the state: torque = k·i. */
void model_update_outputs(Fmu *m) {
    m->values[VR_TORQUE] = m->values[VR_K] * m->values[VR_CURRENT];
}

/* The forcing V − k·ω and its first two time derivatives, `s` after the inputs were set. */
static void forcing(const Fmu *m, double s, double f[3]) {
    double voltage[3], omega[3];
    int j;
    input_course(m, IN_VOLTAGE, s, voltage);
    input_course(m, IN_OMEGA, s, omega);
    for (j = 0; j < 3; j++) f[j] = voltage[j] - m->values[VR_K] * omega[j];
}

/* The exact step: with the forcing F(s) = F0 + F1·s + F2·s²/2 over the step (constant for
 * held inputs), L·i' + R·i = F has the particular solution a + b·s + c·s² with R·c = F2/2,
 * R·b = F1 − 2L·c, R·a = F0 − L·b, and i − (a + b·s + c·s²) decays with the time constant
 * L/R. Held inputs give b = c = 0: i relaxes to its steady value (V − k·ω)/R. */
void model_step(Fmu *m, double h) {
    double f[3], a, b, c, decay;
    const double R = m->values[VR_R], L = m->values[VR_L];
    forcing(m, m->elapsed, f);
    c = 0.5 * f[2] / R;
    b = (f[1] - 2.0 * L * c) / R;
    a = (f[0] - L * b) / R;
    decay = exp(-h * R / L);
    m->values[VR_CURRENT] = (a + h * (b + h * c)) + (m->values[VR_CURRENT] - a) * decay;
}

/* di/dt = (F − R·i)/L and d²i/dt² = (F' − R·di/dt)/L (F' = 0 for held inputs); the
 * torque's are k times the current's. */
void model_output_rates(Fmu *m, fmi2ValueReference vr, double rates[2]) {
    const double *v = m->values;
    const double scale = vr == VR_TORQUE ? v[VR_K] : 1.0;
    double f[3];
    forcing(m, m->elapsed, f);
    rates[0] = (f[0] - v[VR_R] * v[VR_CURRENT]) / v[VR_L];
    rates[1] = (f[1] - v[VR_R] * rates[0]) / v[VR_L];
    rates[0] *= scale;
    rates[1] *= scale;
}
