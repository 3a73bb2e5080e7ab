/* A minimal FMI 2.0 and FMI 3.0 co-simulation master in C, built for each platform the
   FMU ships (native gcc, MinGW for win64, zig cc for aarch64 Linux) and run there
   (natively, under Wine, under QEMU), so that every platform's binary is driven through its
   own C ABI by the same code.

   usage: master LIBRARY GUID TOLERANCE STEP STOP OUT [KIND:VR=VALUE ...] -- KIND:VR ...

   With GUID written fmi3:TOKEN the master drives the library's FMI 3.0 functions with that
   instantiation token, the value references still FMI 2.0's (FMI 3.0's are one more).
   KIND is R (Real: Float64), I (Integer: Int32), E (Enumeration: Int64 in FMI 3.0) or B
   (Boolean). The settings before "--" are applied in initialisation mode; after it come
   the variables to record, Reals, Integers and Enumerations. OUT gets one line per communication point, starting with the initial one: the
   time and each recorded value in the order given, a Real as the 16 hex digits of its IEEE
   bits (so that no C library's printf rounds anything), an Integer in decimal. The time
   spent in the stepping loop goes to stderr. */

#define _POSIX_C_SOURCE 200809L
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"

#ifdef _WIN32
#include <windows.h>
typedef HMODULE Library;
static Library open_library(const char *path) { return LoadLibraryA(path); }
static void *symbol(Library lib, const char *name) { return (void *)GetProcAddress(lib, name); }
static double seconds(void) {
    LARGE_INTEGER count, frequency;
    QueryPerformanceCounter(&count);
    QueryPerformanceFrequency(&frequency);
    return (double)count.QuadPart / (double)frequency.QuadPart;
}
#else
#include <dlfcn.h>
#include <time.h>
typedef void *Library;
static Library open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(Library lib, const char *name) { return dlsym(lib, name); }
static double seconds(void) {
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)now.tv_sec + 1e-9 * (double)now.tv_nsec;
}
#endif

#define MAX_RECORDED 256

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    va_list args;
    (void)env;
    fprintf(stderr, "[%s %d %s] ", instance, (int)status, category);
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

static void fail(const char *what) {
    fprintf(stderr, "master: %s\n", what);
    exit(1);
}

static void *must(Library lib, const char *name) {
    void *f = symbol(lib, name);
    if (!f) {
        fprintf(stderr, "master: the library does not export %s\n", name);
        exit(1);
    }
    return f;
}

static void check(fmi2Status status, const char *call) {
    if (status != fmi2OK) {
        fprintf(stderr, "master: %s returned status %d\n", call, (int)status);
        exit(1);
    }
}

/* One variable to record: its kind ('R', 'I' or 'E') and value reference. */
typedef struct {
    char kind;
    fmi2ValueReference vr;
} Recorded;

static void write_hex(FILE *out, const char *before, double x) {
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    fprintf(out, "%s%016" PRIx64, before, bits);
}

static void write_point(FILE *out, double t, const fmi2Real *reals,
                        const fmi2Integer *integers, const Recorded *recorded, size_t n) {
    size_t i, r = 0, k = 0;
    write_hex(out, "", t);
    for (i = 0; i < n; i++) {
        if (recorded[i].kind == 'R')
            write_hex(out, " ", reals[r++]);
        else
            fprintf(out, " %d", (int)integers[k++]);
    }
    fputc('\n', out);
}

/* The recorded values at one point: Reals and Integers, each kind in its own array. */
static void read_point(fmi2Component c, fmi2GetRealTYPE *get_real, fmi2GetIntegerTYPE *get_integer,
                       const fmi2ValueReference *real_vrs, size_t n_reals, fmi2Real *reals,
                       const fmi2ValueReference *integer_vrs, size_t n_integers,
                       fmi2Integer *integers) {
    if (n_reals) check(get_real(c, real_vrs, n_reals, reals), "fmi2GetReal");
    if (n_integers) check(get_integer(c, integer_vrs, n_integers, integers), "fmi2GetInteger");
}

static void apply_setting(fmi2Component c, const char *setting, fmi2SetRealTYPE *set_real,
                          fmi2SetIntegerTYPE *set_integer, fmi2SetBooleanTYPE *set_boolean) {
    char *end;
    fmi2ValueReference vr = (fmi2ValueReference)strtoul(setting + 2, &end, 10);
    const char *value = end + 1;
    if (setting[1] != ':' || *end != '=') fail("a setting is KIND:VR=VALUE");
    if (setting[0] == 'R') {
        fmi2Real v = strtod(value, NULL);
        check(set_real(c, &vr, 1, &v), "fmi2SetReal");
    } else if (setting[0] == 'I' || setting[0] == 'E') {
        fmi2Integer v = (fmi2Integer)strtol(value, NULL, 10);
        check(set_integer(c, &vr, 1, &v), "fmi2SetInteger");
    } else if (setting[0] == 'B') {
        fmi2Boolean v = (fmi2Boolean)strtol(value, NULL, 10);
        check(set_boolean(c, &vr, 1, &v), "fmi2SetBoolean");
    } else {
        fail("a setting's KIND is R, I or B");
    }
}

/* Every point to OUT, and the arrays freed. */
static void write_results(const char *path, double step, long points, fmi2Real *reals,
                          fmi2Integer *integers, const Recorded *recorded, size_t n,
                          size_t n_reals, size_t n_integers) {
    long k;
    FILE *out = fopen(path, "wb"); /* binary: the same bytes on Windows */
    if (!out) fail("cannot write the output file");
    for (k = 0; k <= points; k++)
        write_point(out, (double)k * step, reals + (size_t)k * n_reals,
                    integers + (size_t)k * n_integers, recorded, n);
    if (fclose(out) != 0) fail("cannot write the output file");
    free(reals);
    free(integers);
}

/* ---- FMI 3.0: the same run through the fmi3 functions ---- */

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                    fmi3String message) {
    (void)env;
    fprintf(stderr, "[fmi3 %d %s] %s\n", (int)status, category, message);
}

static void check3(fmi3Status status, const char *call) {
    if (status != fmi3OK) {
        fprintf(stderr, "master: %s returned status %d\n", call, (int)status);
        exit(1);
    }
}

typedef struct {
    fmi3SetFloat64TYPE *set_float64;
    fmi3SetInt32TYPE *set_int32;
    fmi3SetInt64TYPE *set_int64;
    fmi3SetBooleanTYPE *set_boolean;
    fmi3GetFloat64TYPE *get_float64;
    fmi3GetInt32TYPE *get_int32;
    fmi3GetInt64TYPE *get_int64;
} Access3;

static void apply_setting3(fmi3Instance c, const char *setting, const Access3 *a) {
    char *end;
    fmi3ValueReference vr = (fmi3ValueReference)strtoul(setting + 2, &end, 10) + 1;
    const char *value = end + 1;
    if (setting[1] != ':' || *end != '=') fail("a setting is KIND:VR=VALUE");
    if (setting[0] == 'R') {
        fmi3Float64 v = strtod(value, NULL);
        check3(a->set_float64(c, &vr, 1, &v, 1), "fmi3SetFloat64");
    } else if (setting[0] == 'I') {
        fmi3Int32 v = (fmi3Int32)strtol(value, NULL, 10);
        check3(a->set_int32(c, &vr, 1, &v, 1), "fmi3SetInt32");
    } else if (setting[0] == 'E') {
        fmi3Int64 v = (fmi3Int64)strtol(value, NULL, 10);
        check3(a->set_int64(c, &vr, 1, &v, 1), "fmi3SetInt64");
    } else if (setting[0] == 'B') {
        fmi3Boolean v = strtol(value, NULL, 10) != 0;
        check3(a->set_boolean(c, &vr, 1, &v, 1), "fmi3SetBoolean");
    } else {
        fail("a setting's KIND is R, I, E or B");
    }
}

/* The recorded values at one point, as FMI 2.0's master keeps them: Reals, and Integers
   and Enumerations together, each one by one (the FMI 3.0 types differ by kind). */
static void read_point3(fmi3Instance c, const Access3 *a, const Recorded *recorded, size_t n,
                        fmi3Float64 *reals, fmi2Integer *integers) {
    size_t i, r = 0, k = 0;
    for (i = 0; i < n; i++) {
        fmi3ValueReference vr = recorded[i].vr + 1;
        if (recorded[i].kind == 'R') {
            check3(a->get_float64(c, &vr, 1, reals + r++, 1), "fmi3GetFloat64");
        } else if (recorded[i].kind == 'E') {
            fmi3Int64 v;
            check3(a->get_int64(c, &vr, 1, &v, 1), "fmi3GetInt64");
            integers[k++] = (fmi2Integer)v;
        } else {
            fmi3Int32 v;
            check3(a->get_int32(c, &vr, 1, &v, 1), "fmi3GetInt32");
            integers[k++] = (fmi2Integer)v;
        }
    }
}

/* Instantiate (no event mode), initialise with the settings, step to every point, and
   fill the arrays as FMI 2.0's run does. Returns the stepping loop's time. */
static double run_fmi3(Library lib, const char *token, double tolerance, double step,
                       double stop, long points, char **settings, int n_settings,
                       const Recorded *recorded, size_t n, size_t n_reals, size_t n_integers,
                       fmi3Float64 *reals, fmi2Integer *integers) {
    Access3 a;
    double t = 0.0, started;
    long k;
    int i;
    fmi3InstantiateCoSimulationTYPE *instantiate =
        (fmi3InstantiateCoSimulationTYPE *)must(lib, "fmi3InstantiateCoSimulation");
    fmi3EnterInitializationModeTYPE *enter =
        (fmi3EnterInitializationModeTYPE *)must(lib, "fmi3EnterInitializationMode");
    fmi3ExitInitializationModeTYPE *leave =
        (fmi3ExitInitializationModeTYPE *)must(lib, "fmi3ExitInitializationMode");
    fmi3DoStepTYPE *do_step = (fmi3DoStepTYPE *)must(lib, "fmi3DoStep");
    fmi3TerminateTYPE *terminate = (fmi3TerminateTYPE *)must(lib, "fmi3Terminate");
    fmi3FreeInstanceTYPE *free_instance = (fmi3FreeInstanceTYPE *)must(lib, "fmi3FreeInstance");
    fmi3Instance c;
    a.set_float64 = (fmi3SetFloat64TYPE *)must(lib, "fmi3SetFloat64");
    a.set_int32 = (fmi3SetInt32TYPE *)must(lib, "fmi3SetInt32");
    a.set_int64 = (fmi3SetInt64TYPE *)must(lib, "fmi3SetInt64");
    a.set_boolean = (fmi3SetBooleanTYPE *)must(lib, "fmi3SetBoolean");
    a.get_float64 = (fmi3GetFloat64TYPE *)must(lib, "fmi3GetFloat64");
    a.get_int32 = (fmi3GetInt32TYPE *)must(lib, "fmi3GetInt32");
    a.get_int64 = (fmi3GetInt64TYPE *)must(lib, "fmi3GetInt64");

    c = instantiate("master", token, "", fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0,
                    NULL, logger3, NULL);
    if (!c) fail("fmi3InstantiateCoSimulation returned NULL");
    check3(enter(c, fmi3True, tolerance, 0.0, fmi3True, stop), "fmi3EnterInitializationMode");
    for (i = 0; i < n_settings; i++) apply_setting3(c, settings[i], &a);
    check3(leave(c), "fmi3ExitInitializationMode");
    read_point3(c, &a, recorded, n, reals, integers);
    started = seconds();
    for (k = 1; k <= points; k++) {
        double next = (double)k * step, last = 0.0;
        fmi3Boolean event = fmi3False, terminate_now = fmi3False, early = fmi3False;
        check3(do_step(c, t, next - t, fmi3True, &event, &terminate_now, &early, &last),
               "fmi3DoStep");
        if (early || event || terminate_now) fail("fmi3DoStep reported an event");
        t = next;
        read_point3(c, &a, recorded, n, reals + (size_t)k * n_reals,
                    integers + (size_t)k * n_integers);
    }
    started = seconds() - started;
    check3(terminate(c), "fmi3Terminate");
    free_instance(c);
    return started;
}

int main(int argc, char **argv) {
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    Recorded recorded[MAX_RECORDED];
    fmi2ValueReference real_vrs[MAX_RECORDED], integer_vrs[MAX_RECORDED];
    size_t n = 0, n_reals = 0, n_integers = 0;
    int first_setting = 7, separator = argc, i;
    double tolerance, step, stop, t, started, elapsed;
    long points, k;
    fmi2Real *reals;
    fmi2Integer *integers;
    Library lib;
    fmi2Component c;

    if (argc < 9) fail("usage: master LIBRARY GUID TOLERANCE STEP STOP OUT [KIND:VR=VALUE ...] -- KIND:VR ...");
    tolerance = strtod(argv[3], NULL);
    step = strtod(argv[4], NULL);
    stop = strtod(argv[5], NULL);
    for (i = first_setting; i < argc; i++)
        if (strcmp(argv[i], "--") == 0) separator = i;
    for (i = separator + 1; i < argc; i++) {
        if (n == MAX_RECORDED) fail("too many variables to record");
        if ((argv[i][0] != 'R' && argv[i][0] != 'I' && argv[i][0] != 'E') || argv[i][1] != ':')
            fail("a recorded variable is R:VR, I:VR or E:VR");
        recorded[n].kind = argv[i][0];
        recorded[n].vr = (fmi2ValueReference)strtoul(argv[i] + 2, NULL, 10);
        if (recorded[n].kind == 'R')
            real_vrs[n_reals++] = recorded[n].vr;
        else
            integer_vrs[n_integers++] = recorded[n].vr;
        n++;
    }
    if (n == 0) fail("no variable to record after --");
    /* FMPy's stepping: the k-th point at k * step, each step from the last point. */
    points = (long)(stop / step + 0.5);
    if (!(points >= 1 && points <= 10000000)) fail("STOP / STEP must be between 1 and 1e7 points");

    lib = open_library(argv[1]);
    if (!lib) fail("cannot load the library");
    reals = (fmi2Real *)malloc((size_t)(points + 1) * (n_reals + 1) * sizeof *reals);
    integers = (fmi2Integer *)malloc((size_t)(points + 1) * (n_integers + 1) * sizeof *integers);
    if (!reals || !integers) fail("out of memory");
    if (strncmp(argv[2], "fmi3:", 5) == 0) {
        elapsed = run_fmi3(lib, argv[2] + 5, tolerance, step, stop, points, argv + first_setting,
                           separator - first_setting, recorded, n, n_reals, n_integers, reals,
                           integers);
        write_results(argv[6], step, points, reals, integers, recorded, n, n_reals, n_integers);
        fprintf(stderr, "loop_seconds=%.9f\n", elapsed);
        return 0;
    }
    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)must(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)must(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter =
        (fmi2EnterInitializationModeTYPE *)must(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *leave =
        (fmi2ExitInitializationModeTYPE *)must(lib, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = (fmi2SetRealTYPE *)must(lib, "fmi2SetReal");
    fmi2SetIntegerTYPE *set_integer = (fmi2SetIntegerTYPE *)must(lib, "fmi2SetInteger");
    fmi2SetBooleanTYPE *set_boolean = (fmi2SetBooleanTYPE *)must(lib, "fmi2SetBoolean");
    fmi2GetRealTYPE *get_real = (fmi2GetRealTYPE *)must(lib, "fmi2GetReal");
    fmi2GetIntegerTYPE *get_integer = (fmi2GetIntegerTYPE *)must(lib, "fmi2GetInteger");
    fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)must(lib, "fmi2DoStep");
    fmi2TerminateTYPE *terminate = (fmi2TerminateTYPE *)must(lib, "fmi2Terminate");
    fmi2FreeInstanceTYPE *free_instance = (fmi2FreeInstanceTYPE *)must(lib, "fmi2FreeInstance");

    c = instantiate("master", fmi2CoSimulation, argv[2], "", &callbacks, fmi2False, fmi2False);
    if (!c) fail("fmi2Instantiate returned NULL");
    check(setup(c, fmi2True, tolerance, 0.0, fmi2True, stop), "fmi2SetupExperiment");
    check(enter(c), "fmi2EnterInitializationMode");
    for (i = first_setting; i < separator; i++)
        apply_setting(c, argv[i], set_real, set_integer, set_boolean);
    check(leave(c), "fmi2ExitInitializationMode");

    /* Kept in memory and written after the loop, so that the time measured is the FMU's
       and not the C library's file output. */
    read_point(c, get_real, get_integer, real_vrs, n_reals, reals, integer_vrs, n_integers, integers);
    t = 0.0;
    started = seconds();
    for (k = 1; k <= points; k++) {
        double next = (double)k * step;
        check(do_step(c, t, next - t, fmi2True), "fmi2DoStep");
        t = next;
        read_point(c, get_real, get_integer, real_vrs, n_reals, reals + (size_t)k * n_reals,
                   integer_vrs, n_integers, integers + (size_t)k * n_integers);
    }
    elapsed = seconds() - started;
    check(terminate(c), "fmi2Terminate");
    free_instance(c);

    write_results(argv[6], step, points, reals, integers, recorded, n, n_reals, n_integers);
    fprintf(stderr, "loop_seconds=%.9f\n", elapsed);
    return 0;
}
