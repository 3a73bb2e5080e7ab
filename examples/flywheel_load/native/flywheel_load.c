/* A flywheel on a torsional shaft as an FMI 2.0 co-simulation FMU in C: the speed of the
 * body driving the shaft in, the torque the shaft puts back on that body out. States: the
 * shaft's twist Δ (driving end's angle minus the flywheel's) and the flywheel's speed w:
 *     Δ' = ω − w,    J·w' = M − c·w,    M = k·Δ + d·(ω − w),
 * with M the torque resisting the driving body (the mechanism's input M_r). A stiff shaft
 * on a light flywheel is the classic stiff coupling: held inputs over a long communication
 * step make the loop unstable. The system is linear, so with the input held or moving
 * along the derivatives a master sets, a step of any size is exact (its matrix exponential
 * in closed form), and so are the output derivatives. The FMI functions are
 * ../../native/cosim.c's; built and packed by `cargo xtask motor` into
 * target/fmu/FlywheelLoad.fmu. */

#include <math.h>
#include <stdio.h>

#include "cosim.h"

/* Also in modelDescription.xml; tests/python/test_flywheel_load.py checks the two agree. */
#define GUID "{464c5957-4845-454c-2d6c-6f6164000001}"

enum { VR_K, VR_D, VR_J, VR_C, VR_OMEGA, VR_TORQUE, VR_TWIST, VR_SPEED, N_VARIABLES };

const char MODEL_GUID[] = GUID;
const char MODEL_STATE_TAG[8] = {'F', 'L', 'Y', 'W', 'H', 'E', 'E', 'L'};
const int MODEL_VARIABLES = N_VARIABLES;
const char *const MODEL_NAMES[N_VARIABLES] = {"k", "d", "J", "c", "omega", "torque", "twist",
                                              "omega_flywheel"};
const Causality MODEL_CAUSALITY[N_VARIABLES] = {PARAMETER, PARAMETER, PARAMETER, PARAMETER,
                                                INPUT,     OUTPUT,    OUTPUT,    OUTPUT};
const int MODEL_INPUTS = 1;
const fmi2ValueReference MODEL_INPUT_VRS[] = {VR_OMEGA};
const int MODEL_DERIVED = 3;
const fmi2ValueReference MODEL_DERIVED_VRS[] = {VR_TORQUE, VR_TWIST, VR_SPEED};

void model_defaults(Fmu *m) {
    m->values[VR_K] = 2000.0;
    m->values[VR_D] = 2.0;
    m->values[VR_J] = 0.5;
    m->values[VR_C] = 1.0;
}

/* k, J > 0 (a shaft and a flywheel), d, c >= 0; the input any finite number. */
int model_out_of_range(fmi2ValueReference vr, double value, char *why, size_t size) {
    if ((vr == VR_K || vr == VR_J) && !(value > 0.0))
        snprintf(why, size, "%s = %g: must be > 0", MODEL_NAMES[vr], value);
    else if ((vr == VR_D || vr == VR_C) && value < 0.0)
        snprintf(why, size, "%s = %g: must be >= 0", MODEL_NAMES[vr], value);
    else
        return 0;
    return 1;
}

void model_update_outputs(Fmu *m) {
    double *v = m->values, u[3];
    input_course(m, 0, m->elapsed, u);
    v[VR_TORQUE] = v[VR_K] * v[VR_TWIST] + v[VR_D] * (u[0] - v[VR_SPEED]);
}

/* x = (Δ, w): x' = A·x + b·ω with A = [[0, −1], [k/J, −(d + c)/J]] and b = (1, d/J). */
static void system_matrix(const Fmu *m, double A[2][2], double b[2]) {
    const double *v = m->values;
    A[0][0] = 0.0;
    A[0][1] = -1.0;
    A[1][0] = v[VR_K] / v[VR_J];
    A[1][1] = -(v[VR_D] + v[VR_C]) / v[VR_J];
    b[0] = 1.0;
    b[1] = v[VR_D] / v[VR_J];
}

/* y = A⁻¹·r (det A = k/J > 0). */
static void solve(const double A[2][2], const double r[2], double y[2]) {
    const double det = A[0][0] * A[1][1] - A[0][1] * A[1][0];
    y[0] = (A[1][1] * r[0] - A[0][1] * r[1]) / det;
    y[1] = (A[0][0] * r[1] - A[1][0] * r[0]) / det;
}

/* exp(A·h) in closed form: with μ = tr A / 2 and N = A − μ·I, N² = q·I for
 * q = μ² − det A, so exp(A·h) = e^{μh}·(C·I + S·N) with C = cosh(√q·h) and
 * S = sinh(√q·h)/√q (cos and sin for q < 0; their series near q·h² = 0). */
static void exponential(const double A[2][2], double h, double E[2][2]) {
    const double mu = 0.5 * (A[0][0] + A[1][1]);
    const double q = mu * mu - (A[0][0] * A[1][1] - A[0][1] * A[1][0]);
    const double z = q * h * h, scale = exp(mu * h);
    double C, S;
    if (fabs(z) < 1e-4) {
        C = 1.0 + z / 2.0 * (1.0 + z / 12.0);
        S = h * (1.0 + z / 6.0 * (1.0 + z / 20.0));
    } else if (q > 0.0) {
        C = cosh(sqrt(q) * h);
        S = sinh(sqrt(q) * h) / sqrt(q);
    } else {
        C = cos(sqrt(-q) * h);
        S = sin(sqrt(-q) * h) / sqrt(-q);
    }
    E[0][0] = scale * (C + S * (A[0][0] - mu));
    E[0][1] = scale * S * A[0][1];
    E[1][0] = scale * S * A[1][0];
    E[1][1] = scale * (C + S * (A[1][1] - mu));
}

/* With the input ω(τ) = U0 + U1·τ + U2·τ²/2 over the step, x' = A·x + b·ω has the
 * particular solution p0 + p1·τ + p2·τ² with A·p2 = −b·U2/2, A·p1 = 2·p2 − b·U1 and
 * A·p0 = p1 − b·U0; x − p decays as exp(A·τ). */
void model_step(Fmu *m, double h) {
    double A[2][2], b[2], E[2][2], U[3], p0[2], p1[2], p2[2], r[2], x[2];
    int i;
    system_matrix(m, A, b);
    input_course(m, 0, m->elapsed, U);
    for (i = 0; i < 2; i++) r[i] = -0.5 * b[i] * U[2];
    solve(A, r, p2);
    for (i = 0; i < 2; i++) r[i] = 2.0 * p2[i] - b[i] * U[1];
    solve(A, r, p1);
    for (i = 0; i < 2; i++) r[i] = p1[i] - b[i] * U[0];
    solve(A, r, p0);
    exponential(A, h, E);
    x[0] = m->values[VR_TWIST] - p0[0];
    x[1] = m->values[VR_SPEED] - p0[1];
    m->values[VR_TWIST] = p0[0] + h * (p1[0] + h * p2[0]) + E[0][0] * x[0] + E[0][1] * x[1];
    m->values[VR_SPEED] = p0[1] + h * (p1[1] + h * p2[1]) + E[1][0] * x[0] + E[1][1] * x[1];
}

/* Δ' = ω − w, w' = (M − c·w)/J, M' = k·Δ' + d·(ω' − w'), and once more for the second. */
void model_output_rates(Fmu *m, fmi2ValueReference vr, double rates[2]) {
    const double *v = m->values;
    double u[3], twist[2], speed[2], torque[2];
    model_update_outputs(m);
    input_course(m, 0, m->elapsed, u);
    twist[0] = u[0] - v[VR_SPEED];
    speed[0] = (v[VR_TORQUE] - v[VR_C] * v[VR_SPEED]) / v[VR_J];
    torque[0] = v[VR_K] * twist[0] + v[VR_D] * (u[1] - speed[0]);
    twist[1] = u[1] - speed[0];
    speed[1] = (torque[0] - v[VR_C] * speed[0]) / v[VR_J];
    torque[1] = v[VR_K] * twist[1] + v[VR_D] * (u[2] - speed[1]);
    if (vr == VR_TWIST) {
        rates[0] = twist[0];
        rates[1] = twist[1];
    } else if (vr == VR_SPEED) {
        rates[0] = speed[0];
        rates[1] = speed[1];
    } else {
        rates[0] = torque[0];
        rates[1] = torque[1];
    }
}
