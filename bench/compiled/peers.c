/* Compiled peers of the benchmark: the mechanism's right-hand side in plain C (docs/model.md
 * §2, the orthogonal-complement form with the paper's slips corrected, as a performance-
 * minded C user writes it), and drivers for GSL's rk8pd and SUNDIALS' CVODE on it.
 *
 * Built by `cargo xtask bench` into target/bench/libpeers.so and loaded by the harness,
 * which also hands `mechanism_rhs` to Hairer's DOP853 and to LSODA (the shared libraries
 * of the numbalsoda package). Each driver reports the state at every communication point
 * k·h, k = 1..n, through `record`, as a doStep loop would see it. */

#include <math.h>
#include <stddef.h>
#include <time.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_odeiv2.h>

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

/* The parameters, the law coefficients already zero where the built-in laws are off, and a
 * counter of evaluations. The field order is the harness's `#[repr(C)]` twin. */
typedef struct {
    double J1, J2, J3, J4;
    double k12, k34, d12, d34, c4;
    double l, l2, l3;
    double a0, a1, a2, b0, b1;
    long n_rhs;
} mechanism;

typedef void (*recorder)(void *context, long k, const double *y);

/* dy = f(y): the eight states (φ1..φ4, ω1..ω4) and their rates. */
void mechanism_rhs(double t, double *y, double *dy, void *data) {
    (void)t;
    mechanism *m = (mechanism *)data;
    m->n_rhs++;
    double phi1 = y[0], phi2 = y[1], phi3 = y[2], phi4 = y[3];
    double w1 = y[4], w2 = y[5], w3 = y[6], w4 = y[7];
    double s2 = sin(phi2), c2 = cos(phi2), s3 = sin(phi3), c3 = cos(phi3);
    /* sin and cos of φ2 − φ3 from the two pairs, as the FMU's model does: no third pair. */
    double s23 = s2 * c3 - c2 * s3, c23 = c2 * c3 + s2 * s3;
    /* The constraint's coefficients B1, C1 [44]-[47] and their rates [49]-[51]. */
    double b1 = m->l2 * (m->l * s2 + m->l3 * s23);
    double c1 = m->l3 * (m->l2 * s23 + m->l * s3);
    double b1d = m->l2 * (m->l * c2 * w2 + m->l3 * c23 * (w2 - w3));
    double c1d = m->l3 * (m->l2 * c23 * (w2 - w3) + m->l * c3 * w3);
    double motor = m->a0 + (m->a1 + m->a2 * w1) * w1;
    double load = m->b0 + m->b1 * w1;
    double s12 = m->k12 * (phi2 - phi1) + m->d12 * (w2 - w1);
    double s34 = m->k34 * (phi3 - phi4) + m->d34 * (w3 - w4);
    double q2 = -s12, q3 = -s34;
    double r1 = c1 * q2 + b1 * q3;
    double r2 = -(b1d * w2 - c1d * w3);
    double det = -(c1 * c1 * m->J2 + b1 * b1 * m->J3);
    dy[0] = w1;
    dy[1] = w2;
    dy[2] = w3;
    dy[3] = w4;
    dy[4] = (motor + s12) / m->J1;
    dy[5] = (-c1 * r1 - b1 * m->J3 * r2) / det;
    dy[6] = (c1 * m->J2 * r2 - b1 * r1) / det;
    dy[7] = (s34 - load - m->c4 * w4) / m->J4;
}

/* The bare right-hand side's cost: n calls through a function pointer (as a solver makes
 * them), with the crank angle varied so that nothing is hoisted; nanoseconds per call,
 * the best of five. */
double mechanism_rhs_ns(mechanism *m, const double *y0, long n) {
    void (*volatile f)(double, double *, double *, void *) = mechanism_rhs;
    double y[8], dy[8], best = INFINITY;
    volatile double sink = 0.0;
    for (int i = 0; i < 8; i++) y[i] = y0[i];
    for (int repeat = 0; repeat < 5; repeat++) {
        struct timespec start, end;
        clock_gettime(CLOCK_MONOTONIC, &start);
        for (long k = 0; k < n; k++) {
            y[1] = (double)(k % 1000) * 6.283e-3;
            f(0.0, y, dy, m);
            sink += dy[5];
        }
        clock_gettime(CLOCK_MONOTONIC, &end);
        double ns = ((double)(end.tv_sec - start.tv_sec) * 1e9 +
                     (double)(end.tv_nsec - start.tv_nsec)) / (double)n;
        if (ns < best) best = ns;
    }
    (void)sink;
    return best;
}

static int gsl_rhs(double t, const double y[], double dydt[], void *params) {
    mechanism_rhs(t, (double *)y, dydt, params);
    return GSL_SUCCESS;
}

/* GSL's rk8pd (Prince-Dormand 8(7)) under its driver, relative and absolute tolerance
 * `tol`: GSL has no dense output, so each interval ends on its communication point.
 * 0 on success. */
int gsl_rk8pd_run(mechanism *m, const double *y0, double h, long n, double tol,
                  recorder record, void *context) {
    gsl_odeiv2_system system = {gsl_rhs, NULL, 8, m};
    gsl_odeiv2_driver *driver =
        gsl_odeiv2_driver_alloc_y_new(&system, gsl_odeiv2_step_rk8pd, h, tol, tol);
    if (driver == NULL) return -1;
    gsl_odeiv2_driver_set_nmax(driver, 0);
    double y[8], t = 0.0;
    for (int i = 0; i < 8; i++) y[i] = y0[i];
    int status = GSL_SUCCESS;
    for (long k = 1; k <= n && status == GSL_SUCCESS; k++) {
        status = gsl_odeiv2_driver_apply(driver, &t, (double)k * h, y);
        if (status == GSL_SUCCESS) record(context, k, y);
    }
    gsl_odeiv2_driver_free(driver);
    return status == GSL_SUCCESS ? 0 : -1;
}

static int cvode_rhs(sunrealtype t, N_Vector y, N_Vector dy, void *data) {
    mechanism_rhs(t, N_VGetArrayPointer(y), N_VGetArrayPointer(dy), data);
    return 0;
}

/* CVODE 6 with relative and absolute tolerance `tol`, output interpolated at each
 * communication point (CV_NORMAL): `bdf` != 0 is BDF with Newton iterations on a dense
 * difference-quotient Jacobian (CVODE's usual setting), else Adams-Moulton with fixed-point
 * iterations (its non-stiff setting). 0 on success. */
int cvode_run(mechanism *m, const double *y0, double h, long n, double tol, int bdf,
              recorder record, void *context) {
    SUNContext sun = NULL;
    if (SUNContext_Create(NULL, &sun) != 0) return -1;
    N_Vector y = N_VNew_Serial(8, sun);
    void *cvode = CVodeCreate(bdf ? CV_BDF : CV_ADAMS, sun);
    SUNMatrix matrix = NULL;
    SUNLinearSolver linear = NULL;
    SUNNonlinearSolver fixed_point = NULL;
    int status = (y == NULL || cvode == NULL) ? -1 : 0;
    if (status == 0) {
        double *values = N_VGetArrayPointer(y);
        for (int i = 0; i < 8; i++) values[i] = y0[i];
        status = CVodeInit(cvode, cvode_rhs, 0.0, y);
    }
    if (status == 0) status = CVodeSetUserData(cvode, m);
    if (status == 0) status = CVodeSStolerances(cvode, tol, tol);
    /* A bound per communication interval: where the step collapses (the free run at
     * tol 1e-3), the run fails instead of creeping on for ever. */
    if (status == 0) status = CVodeSetMaxNumSteps(cvode, 100000);
    /* Silent about steps too small to change t (where the step collapses): the bench's
     * log is for results. */
    if (status == 0) status = CVodeSetMaxHnilWarns(cvode, -1);
    if (status == 0 && bdf) {
        matrix = SUNDenseMatrix(8, 8, sun);
        linear = SUNLinSol_Dense(y, matrix, sun);
        status = (matrix && linear) ? CVodeSetLinearSolver(cvode, linear, matrix) : -1;
    } else if (status == 0) {
        fixed_point = SUNNonlinSol_FixedPoint(y, 0, sun);
        status = fixed_point ? CVodeSetNonlinearSolver(cvode, fixed_point) : -1;
    }
    for (long k = 1; k <= n && status == 0; k++) {
        sunrealtype t = 0.0;
        status = CVode(cvode, (double)k * h, y, &t, CV_NORMAL) < 0 ? -1 : 0;
        if (status == 0) record(context, k, N_VGetArrayPointer(y));
    }
    CVodeFree(&cvode);
    if (linear) SUNLinSolFree(linear);
    if (matrix) SUNMatDestroy(matrix);
    if (fixed_point) SUNNonlinSolFree(fixed_point);
    if (y) N_VDestroy(y);
    SUNContext_Free(&sun);
    return status;
}
