"""The coupled-sweep benchmark: the DC motor driving the mechanism (examples/dc_motor, 10 s
at H = 1 ms), points per second of one worker through each engine, side by side in this
process; and for each engine of a [system] the coupling error against the monolithic
reference (motor and mechanism as one ODE, scipy's DOP853 at rtol 1e-11) and the points
per second at H = 1, 2, 5 and 10 ms: the two curves that decide between the engines. Then,
on two systems (the motor's, and the mechanism driving a flywheel on a stiff shaft,
examples/flywheel_load), the native engine with a coupling tolerance (1e-3 to 1e-6 on a
10 ms grid) against the same engine at fixed steps, at equal error.

    python bench/bench_coupled_sweep.py <CyclicMechanism.fmu> <DcMotor.fmu> <FlywheelLoad.fmu> <output directory> [--quick]

Engines: a [system] of the compiled motor and the mechanism run by the runner itself
(`native`, with input derivatives of order 0, 1 or 2) or as one container FMU
(`container`); the same system as an SSP file (examples/dc_motor/ssp, the compiled motor)
run natively and through FMPy's SSP support; FMPy's SSP support with the Python-written
motor, as the SSP example packs it by default; and an FMPy master loop of FMPy's calls
(the compiled motor).
Every points/s is the best of a few runs of the same points (the machine is shared).
Writes results.json, results.md and coupled_sweep_curves.png.
"""

import pathlib
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from bench_coupled_step import coupled_run
from bench_sweep import machine, ssp_rate, write_results
from fmusweep import run_sweep

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests/python"))
import reference  # noqa: E402

MECHANISM = {"Mm_a0": 0.0, "Mm_a1": 0.0, "Mm_a2": 0.0, "Mr_b0": 20.0, "Mr_b1": -0.05, "c4": 0.5}
STATES = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4"]


@dataclass(frozen=True)
class System:
    """A coupled system measured here: the mechanism and one compiled component."""
    name: str
    title: str
    component: str  # its name in [system]
    connections: list
    mechanism: dict  # the mechanism's fixed parameters
    outputs: list  # the component's states, compared with the reference's last columns
    reference: Callable  # (Params, times) -> the monolithic reference's columns


MOTOR = System(
    "motor", "the DC motor driving the mechanism (the motor's torque to M_m, omega1 back; "
    "the built-in motor law off, the paper's load law, c4 = 0.5)", "motor",
    [["motor.torque", "mechanism.M_m"], ["mechanism.omega1", "motor.omega"]], MECHANISM,
    ["motor.current"], lambda p, t: reference.solve_with_motor(p, reference.Motor(), t, rtol=1e-11))
FLYWHEEL = System(
    "flywheel", "the mechanism driving a flywheel on a stiff shaft (the shaft's torque to "
    "M_r, omega4 back; the paper's motor law, the built-in load law off; shaft k = 2000, "
    "d = 2, flywheel J = 0.5, c = 1)", "load",
    [["load.torque", "mechanism.M_r"], ["mechanism.omega4", "load.omega"]],
    {"Mr_b0": 0.0, "Mr_b1": 0.0}, ["load.twist", "load.omega_flywheel"],
    lambda p, t: reference.solve_with_flywheel(p, reference.Flywheel(), t, rtol=1e-11))

# (engine, input derivatives): the [system] engines compared.
ENGINES = [("native", 2), ("native", 1), ("native", 0), ("container", 0)]
STEPS = (1e-3, 2e-3, 5e-3, 1e-2)
# A coupling tolerance: the tolerances measured, their output grid, and the shorter fixed
# steps that extend the best fixed engine's curve to the errors they reach.
TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6)
GRID = 1e-2
FINE_STEPS = (2.5e-4, 5e-4)
# The FMUs' tolerance at fixed steps (and in the engines' comparison).
FMU_TOLERANCE = 1e-8
# Best of this many runs of the same points for each points/s.
REPEATS = 5


def engine_name(engine, derivatives):
    return f"{engine}, input derivatives {derivatives}" if engine == "native" else engine


def system_spec(fmu, other, stop, step, points, series=False, engine=("native", 2),
                tolerance=None, system=MOTOR, fmu_tolerance=FMU_TOLERANCE):
    """A sweep of `system` (`other` its component's FMU) over the mechanism's d34; with a
    coupling tolerance and `fmu_tolerance` None, the FMUs run at the sweep's default."""
    spec = {"system": {"components": {system.component: str(other), "mechanism": str(fmu)},
                       "connections": system.connections,
                       "engine": engine[0], "input_derivatives": engine[1]},
            "scenario": {"stop": stop, "step": step,
                         "parameters": {f"mechanism.{k}": v for k, v in system.mechanism.items()}},
            "design": {"kind": "grid", "parameters": {
                "mechanism.d34": {"linspace": [0.5, 1.5, points]} if points > 1 else {"values": [1.0]}}},
            "outputs": {"metrics": {"final": {"variable": "mechanism.omega1", "kind": "final"}}}}
    if fmu_tolerance is not None:
        spec["scenario"]["tolerance"] = fmu_tolerance
    if series:
        spec["outputs"]["series"] = {"variables": [f"mechanism.{s}" for s in STATES] + system.outputs}
    if tolerance is not None:
        spec["system"]["coupling_tolerance"] = tolerance
    return spec


def system_rate(fmu, other, points, tmp, engine=("native", 2), step=1e-3, tolerance=None,
                system=MOTOR, fmu_tolerance=FMU_TOLERANCE):
    """Points/s of 10 s runs, the best of REPEATS sweeps of the same points."""
    spec = system_spec(fmu, other, 10.0, step, points, engine=engine, tolerance=tolerance,
                       system=system, fmu_tolerance=fmu_tolerance)
    best = 0.0
    for _ in range(REPEATS):
        out = pathlib.Path(tempfile.mkdtemp(dir=tmp)) / "rate"
        r = run_sweep(spec, out=out, serial=True, progress=False, plots=False).summary
        best = max(best, r.computed / r.point_seconds)
    return best


def ssp_spec(ssp, points, engine="native"):
    """The motor's SSP file (examples/dc_motor/ssp: the same load values as MECHANISM, from
    its load.ssv) swept over d34 as system_spec sweeps the [system] table."""
    return {"ssp": str(ssp), "system": {"engine": engine},
            "scenario": {"stop": 10.0, "step": 1e-3, "tolerance": FMU_TOLERANCE},
            "design": {"kind": "grid", "parameters": {
                "mechanism.d34": {"linspace": [0.5, 1.5, points]}}},
            "outputs": {"metrics": {"final": {"variable": "mechanism.omega1", "kind": "final"}}}}


def ssp_rates(fmu, motor, points, slow_points, tmp):
    """Points/s of the motor's SSP file with the compiled motor: run natively (the best of
    REPEATS), and through FMPy's SSP support (`slow_points` points, once); and whether the
    native run equals the [system] table's with the connections in the file's order."""
    sys.path.insert(0, str(ROOT / "examples/dc_motor"))
    import ssp as example
    ssp = example.build_ssp(fmu, pathlib.Path(tempfile.mkdtemp(dir=tmp)), motor)
    best, native = 0.0, None
    for _ in range(REPEATS):
        out = pathlib.Path(tempfile.mkdtemp(dir=tmp)) / "ssp"
        native = run_sweep(ssp_spec(ssp, points), out=out, serial=True, progress=False, plots=False)
        best = max(best, native.summary.computed / native.summary.point_seconds)
    table = system_spec(fmu, motor, 10.0, 1e-3, points)
    table["system"]["connections"] = [["mechanism.omega1", "motor.omega"],
                                      ["motor.torque", "mechanism.M_m"]]
    by_table = run_sweep(table, out=pathlib.Path(tempfile.mkdtemp(dir=tmp)) / "table",
                         serial=True, progress=False, plots=False)
    out = pathlib.Path(tempfile.mkdtemp(dir=tmp)) / "fmpy"
    fmpy = run_sweep(ssp_spec(ssp, slow_points, "fmpy"), out=out, serial=True, progress=False,
                     plots=False).summary
    return {"ssp_native": best, "ssp_fmpy_compiled": fmpy.computed / fmpy.point_seconds,
            "ssp_native_equals_table": bool(native.points["final"].equals(by_table.points["final"]))}


def master_loop_rate(fmu, motor, points):
    t0 = time.perf_counter()
    for _ in range(points):
        coupled_run(fmu, motor, 1e-3, 1e-8, 10.0)
    return points / (time.perf_counter() - t0)


def coupling_errors(fmu, other, tmp, engine, stop=2.0, steps=STEPS, system=MOTOR):
    """An engine's worst error over the states at every communication point against the
    monolithic reference, in units of each one's scale max(1, max |y|), per communication
    step."""
    return {step: worst_error(system_spec(fmu, other, stop, step, 1, series=True, engine=engine,
                                          system=system),
                              pathlib.Path(tmp) / f"error-{system.name}-{engine[0]}-{engine[1]}-{step}",
                              system)[0]
            for step in steps}


def scaled_errors(spec, out, system=MOTOR):
    """A one-point spec's scaled error against the monolithic reference, worst over the
    states, at each communication point: (times, errors, the point's row)."""
    p = reference.Params(**system.mechanism, d34=1.0)
    results = run_sweep(spec, out=out, serial=True, progress=False, plots=False)
    row = results.points.iloc[0]
    if row["status"] != "ok":
        raise RuntimeError(f"{out.name}: {row['status']}: {row['message']}")
    series = results.series()
    names = [f"mechanism.{s}" for s in STATES] + system.outputs
    columns = [series[series["variable"] == n].sort_values("time") for n in names]
    times = columns[0]["time"].to_numpy()
    mine = np.column_stack([c["value"].to_numpy() for c in columns])
    exact = system.reference(p, times)
    scale = np.maximum(1.0, np.abs(exact).max(axis=0))
    return times, (np.abs(mine - exact) / scale).max(axis=1), row


def worst_error(spec, out, system=MOTOR):
    """A one-point spec's worst scaled error at every communication point, and its row."""
    _, errors, row = scaled_errors(spec, out, system)
    return float(errors.max()), row


def fmu_tolerance_runs(fmu, motor, tmp):
    """The worst error (2 s, 10 ms grid) with the FMUs' own tolerance at several fractions
    of the coupling tolerance, and without one (the tenth the sweep then passes)."""
    runs = []
    for coupling in (1e-4, 1e-6):
        for ratio in (1.0, 0.1, 0.01, 0.001, None):
            spec = system_spec(fmu, motor, 2.0, GRID, 1, series=True, tolerance=coupling,
                               fmu_tolerance=None if ratio is None else ratio * coupling)
            error, _ = worst_error(spec, pathlib.Path(tmp) / f"fmu-tolerance-{coupling}-{ratio}")
            runs.append({"coupling": coupling, "ratio": ratio, "error": error})
    return runs


def tolerance_runs(fmu, other, points, tmp, system, fixed):
    """With a coupling tolerance on a 10 ms output grid (native engine, 2 input
    derivatives, the FMUs at the sweep's default tolerance, a tenth of it): per tolerance
    the worst error over 2 s, the points/s of 10 s runs and the communication steps taken;
    and the fixed steps of `fixed` [(step, error, rate)] that bracket that error, run
    again with the FMUs at the same tolerance."""
    runs = []
    for tol in TOLERANCES:
        spec = system_spec(fmu, other, 2.0, GRID, 1, series=True, tolerance=tol, system=system,
                           fmu_tolerance=None)
        error, row = worst_error(spec, pathlib.Path(tmp) / f"tolerance-{system.name}-{tol}", system)
        same = []
        for h in bracketing_steps(fixed, error):
            spec = system_spec(fmu, other, 2.0, h, 1, series=True, system=system,
                               fmu_tolerance=tol / 10)
            e, _ = worst_error(spec, pathlib.Path(tmp) / f"same-{system.name}-{tol}-{h}", system)
            same.append((h, e, system_rate(fmu, other, points, tmp, step=h, system=system,
                                           fmu_tolerance=tol / 10)))
        runs.append({"tolerance": tol, "error": error, "estimate": float(row["coupling_error"]),
                     "accepted": int(row["coupling_steps"]), "rejected": int(row["coupling_rejected"]),
                     "min_step": float(row["coupling_min_step"]),
                     "rate": system_rate(fmu, other, points, tmp, step=GRID, tolerance=tol,
                                         system=system, fmu_tolerance=None),
                     "fixed_same_tolerance": same})
    return runs


def bracket(curve, target):
    """The neighbouring points of `curve` [(step, error, rate)] whose errors bracket
    `target`, and where `target` lies between them in log: (a, b, x); None outside."""
    for a, b in zip(curve, curve[1:]):
        if min(a[1], b[1]) <= target <= max(a[1], b[1]):
            return a, b, np.log(target / a[1]) / np.log(b[1] / a[1])
    return None


def between_in_log(u, v, x):
    return float(np.exp(np.log(u) + x * np.log(v / u)))


def bracketing_steps(curve, target):
    """The two neighbouring steps of `curve` whose errors bracket `target`, or the two
    nearest it."""
    found = bracket(curve, target)
    a, b = found[:2] if found else (curve[:2] if target < curve[0][1] else curve[-2:])
    return [a[0], b[0]]


def error_by_window(fmu, other, tmp, system, step=2e-3, window=0.25):
    """Where a fixed-step run makes its error: the worst scaled error in each window of
    2 s (2 input derivatives)."""
    spec = system_spec(fmu, other, 2.0, step, 1, series=True, system=system)
    times, errors, _ = scaled_errors(spec, pathlib.Path(tmp) / f"windows-{system.name}", system)
    starts = np.arange(0.0, 2.0, window)
    return {"step": step, "window": window,
            "worst": [float(errors[(times > a) & (times <= a + window + 1e-12)].max()) for a in starts]}


def interpolated_steps(curve, target, stop=2.0):
    """The communication steps over `stop` of fixed steps at coupling error `target` on
    `curve` [(step, error, rate)], the step log-log interpolated; None outside it."""
    found = bracket(curve, target)
    return stop / between_in_log(found[0][0], found[1][0], found[2]) if found else None


def interpolated_rate(curve, target):
    """Points/s at coupling error `target` on an engine's curve [(step, error, rate)],
    log-log interpolated between measured steps; None outside the errors measured."""
    found = bracket(curve, target)
    return between_in_log(found[0][2], found[1][2], found[2]) if found else None


def rate_at_error(curve, target):
    """interpolated_rate as text: "≥ rate" when even the longest step measured is more
    accurate (longer steps would be faster still), "–" when the shortest is not accurate
    enough."""
    rate = interpolated_rate(curve, target)
    if rate is not None:
        return f"{rate:.0f}"
    if target > max(e for _, e, _ in curve):
        return f"≥ {curve[-1][2]:.0f}"
    return "–"


def versus(curve, run) -> str:
    """Points/s of fixed steps at the run's error (from `curve`) and the run's speed-up."""
    rate = interpolated_rate(curve, run["error"])
    return f"{rate:.0f} | {run['rate'] / rate:.2f}×" if rate else "– | –"


def steps_versus(curve, run) -> str:
    """How many fixed steps reach the run's error over 2 s, against the run's own."""
    steps = interpolated_steps(curve, run["error"])
    return f"{steps:.0f} ({steps / run['accepted']:.2f}×)" if steps else "–"


def tolerance_report(title, name, s) -> list[str]:
    fixed = s["fixed"]
    lines = [f"## A coupling tolerance: {title}", "",
             f"The native engine with 2 input derivatives and `coupling_tolerance`, on an output "
             f"grid of {GRID * 1000:g} ms, the FMUs at the sweep's default tolerance (a tenth of "
             "the coupling tolerance): the worst scaled error over 2 s against the monolithic "
             "reference, points/s of 10 s runs, and the steps the controller took. Against it, "
             f"the same engine at fixed steps: with the FMUs at {FMU_TOLERANCE:g} (the curve "
             "below), and with the FMUs at the same tenth of the tolerance (the two fixed steps "
             "whose errors bracket the run's, run again); their points/s interpolated at the "
             "run's error. \"Fixed steps at that error\": how many fixed steps over the 2 s reach "
             "the same error (the step interpolated on the curve), against the controller's "
             "accepted steps.", "",
             "| tolerance | worst error | error / tolerance | points/s | steps accepted, rejected | "
             "smallest step | fixed steps at that error | "
             f"fixed steps, FMUs at {FMU_TOLERANCE:g}: points/s | speed-up | "
             "fixed steps, FMUs at the same tolerance: points/s | speed-up |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for run in s["tolerances"]:
        lines.append(f"| {name}, {run['tolerance']:g} | {run['error']:.2e} | {run['error'] / run['tolerance']:.2f} "
                     f"| {run['rate']:.0f} | {run['accepted']}, {run['rejected']} "
                     f"({run['rejected'] / (run['accepted'] + run['rejected']):.1%}) | "
                     f"{run['min_step']:.2e} s | {steps_versus(fixed, run)} | {versus(fixed, run)} | "
                     f"{versus(run['fixed_same_tolerance'], run)} |")
    lines += ["", f"Fixed steps, {name}, native engine, 2 input derivatives, FMUs at {FMU_TOLERANCE:g}: " + ", ".join(
        f"{h * 1000:g} ms: {e:.2e} at {rate:.0f} points/s" for h, e, rate in fixed) + "."]
    if s.get("held"):
        lines += ["", f"Fixed steps holding inputs, {name} (0 input derivatives): " + ", ".join(
            f"{h * 1000:g} ms: {e:.2e}" for h, e in s["held"]) + "."]
    w = s["windows"]
    worst = w["worst"]
    lines += ["", f"Where the error is made, {name}: at fixed {w['step'] * 1000:g} ms steps, the worst "
                  f"scaled error in each {w['window']:g} s of the 2 s lies between {min(worst):.2e} "
                  f"and {max(worst):.2e} (the largest {max(worst) / min(worst):.1f}× the smallest): "
                  + ", ".join(f"{e:.1e}" for e in worst) + ".", ""]
    return lines


def fmu_tolerance_report(runs) -> list[str]:
    lines = ["## The FMUs' own tolerance under a coupling tolerance", "",
             "The motor system, worst error as above; \"none given\": the sweep passes a tenth "
             "of the coupling tolerance.", "",
             "| coupling tolerance | FMU tolerance | worst error |", "| --- | --- | --- |"]
    for run in runs:
        given = "none given" if run["ratio"] is None else f"{run['ratio']:g} × coupling"
        lines.append(f"| {run['coupling']:g} | {given} | {run['error']:.2e} |")
    return lines + [""]


def report(r) -> str:
    rates = r["rates"]
    curves = r["curves"]
    names = list(curves)
    lines = [
        "# Coupled-sweep benchmark", "",
        f"Machine: {r['machine']}. The DC motor driving the mechanism (examples/dc_motor: the "
        "motor's torque to M_m, omega1 back; the built-in motor law off, the paper's load "
        f"law, c4 = 0.5), tol {FMU_TOLERANCE:g}, one worker, engines side by side in one run; "
        f"each points/s the best of {r['repeats']} runs of the same points.", "",
        "## Engines at H = 1 ms", "",
        "10 s per point.", "",
        "| engine (one worker) | points/s | against the SSP path |", "| --- | --- | --- |",
        *[f"| [system], engine {n} | {rates[n]:.1f} | {rates[n] / rates['ssp']:.0f}× |" for n in names],
        f"| SSP file run natively (engine native, input derivatives 2), compiled motor | "
        f"{rates['ssp_native']:.1f} | {rates['ssp_native'] / rates['ssp']:.0f}× |",
        f"| FMPy's SSP support through fmusweep, compiled motor | {rates['ssp_fmpy_compiled']:.2f} | "
        f"{rates['ssp_fmpy_compiled'] / rates['ssp']:.1f}× |",
        f"| an FMPy master loop of FMPy's calls, compiled motor | {rates['master_loop']:.2f} | "
        f"{rates['master_loop'] / rates['ssp']:.1f}× |",
        f"| FMPy's SSP support through fmusweep, Python-written motor | {rates['ssp']:.2f} | 1× |", "",
        f"The SSP file run natively against FMPy's SSP support with the same compiled motor: "
        f"{rates['ssp_native'] / rates['ssp_fmpy_compiled']:.0f}×. Its results equal the [system] "
        f"table's with the connections in the file's order, bit for bit: "
        f"{'yes' if rates['ssp_native_equals_table'] else 'NO'}.", "",
        "## Coupling error and speed by communication step", "",
        "Error against the monolithic reference (motor and mechanism as one ODE, scipy's "
        "DOP853 at rtol 1e-11), worst over φ1..φ4, ω1..ω4 and the current at every "
        "communication point of 2 s, in units of each one's scale max(1, max |y|); points/s "
        "of 10 s runs at that step. The native engine passes the motor's torque derivatives "
        "to the mechanism and the mechanism's speed derivatives to the motor up to the order "
        "given; the container holds inputs over a step.", "",
        "| engine | " + " | ".join(f"H = {h * 1000:g} ms: error, points/s" for h in STEPS) + " | observed order |",
        "| --- | " + " | ".join("---" for _ in STEPS) + " | --- |"]
    for n in names:
        c = curves[n]
        orders = [np.log(b[1] / a[1]) / np.log(b[0] / a[0]) for a, b in zip(c, c[1:])]
        lines.append(f"| {n} | " + " | ".join(f"{e:.2e}, {rate:.0f}" for _, e, rate in c)
                     + " | " + ", ".join(f"{o:.2f}" for o in orders) + " |")
    lines += ["", "Points/s at equal coupling error (log-log interpolation between the measured "
                  "steps; ≥ where the longest step measured is already more accurate, – where the "
                  "shortest is not accurate enough):", "",
              "| engine | " + " | ".join(f"error {t:g}" for t in r["targets"]) + " |",
              "| --- | " + " | ".join("---" for _ in r["targets"]) + " |"]
    for n in names:
        lines.append(f"| {n}, at equal error | " + " | ".join(rate_at_error(curves[n], t) for t in r["targets"]) + " |")
    lines += ["", "![points/s against coupling error](coupled_sweep_curves.png)", ""]
    for system in (MOTOR, FLYWHEEL):
        if system.name in r.get("systems", {}):
            lines += tolerance_report(system.title, system.name, r["systems"][system.name])
    if r.get("fmu_tolerances"):
        lines += fmu_tolerance_report(r["fmu_tolerances"])
    return "\n".join(lines)


def plot(r, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 4.8))
    curves = dict(r["curves"])
    if "motor" in r.get("systems", {}):  # the best engine's curve with its shorter steps
        curves[engine_name("native", 2)] = r["systems"]["motor"]["fixed"]
    for n, c in curves.items():
        left.loglog([e for _, e, _ in c], [rate for _, _, rate in c], "o-", label=n)
        for h, e, rate in c:
            left.annotate(f"{h * 1000:g} ms", (e, rate), textcoords="offset points", xytext=(4, 4),
                          fontsize=7)
    left.set_title("DC motor driving the mechanism")
    flywheel = r.get("systems", {}).get("flywheel")
    if flywheel:
        fixed = flywheel["fixed"]
        right.loglog([e for _, e, _ in fixed], [rate for _, _, rate in fixed], "o-",
                     label=engine_name("native", 2))
        for h, e, rate in fixed:
            right.annotate(f"{h * 1000:g} ms", (e, rate), textcoords="offset points", xytext=(4, 4),
                           fontsize=7)
        right.set_title("Mechanism driving a flywheel on a stiff shaft")
    for ax, name in ((left, "motor"), (right, "flywheel")):
        runs = r.get("systems", {}).get(name, {}).get("tolerances", [])
        if runs:
            ax.loglog([t["error"] for t in runs], [t["rate"] for t in runs], "s--", color="k",
                      label="native, input derivatives 2, coupling tolerance (10 ms grid)")
            for t in runs:
                ax.annotate(f"tol {t['tolerance']:g}", (t["error"], t["rate"]),
                            textcoords="offset points", xytext=(4, -10), fontsize=7)
        ax.set_xlabel("coupling error against the monolithic reference (scaled, worst point)")
        ax.set_ylabel("points/s, one worker (10 s runs)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def measure_system(fmu, other, points, tmp, system, r):
    """The coupling-tolerance measurements of one system, into r["systems"]."""
    print(f"bench-coupled-sweep: a coupling tolerance, {system.name}", flush=True)
    if system is MOTOR:
        fixed = r["curves"][engine_name("native", 2)]
        held = None
    else:
        fixed = [(h, e, system_rate(fmu, other, points, tmp, step=h, system=system))
                 for h, e in coupling_errors(fmu, other, tmp, ("native", 2), system=system).items()]
        held = sorted(coupling_errors(fmu, other, tmp, ("native", 0), system=system).items())
    fine = coupling_errors(fmu, other, tmp, ("native", 2), steps=FINE_STEPS, system=system)
    fixed = [(h, fine[h], system_rate(fmu, other, points, tmp, step=h, system=system))
             for h in FINE_STEPS] + sorted(fixed)
    r["systems"][system.name] = {
        "fixed": fixed, "held": held,
        "tolerances": tolerance_runs(fmu, other, points, tmp, system, fixed),
        "windows": error_by_window(fmu, other, tmp, system)}


def main():
    fmu, motor, load, out = (pathlib.Path(a) for a in sys.argv[1:5])
    quick = "--quick" in sys.argv
    out.mkdir(parents=True, exist_ok=True)
    global REPEATS
    REPEATS = 1 if quick else REPEATS
    r = {"machine": machine(), "quick": quick, "repeats": REPEATS, "rates": {}, "curves": {},
         "targets": [3e-2, 1e-2, 1e-3, 1e-4], "systems": {}}
    points = 20 if quick else 100
    with tempfile.TemporaryDirectory() as tmp:
        print("bench-coupled-sweep: engines", flush=True)
        for engine in ENGINES:
            r["rates"][engine_name(*engine)] = system_rate(fmu, motor, points, tmp, engine)
        r["rates"]["master_loop"] = master_loop_rate(fmu, motor, 2 if quick else 5)
        r["rates"]["ssp"] = ssp_rate(fmu, 2 if quick else 4, stop=10.0)["points_per_s"]
        r["rates"].update(ssp_rates(fmu, motor, points, 2 if quick else 4, tmp))
        print("bench-coupled-sweep: coupling error and speed by step", flush=True)
        for engine in ENGINES:
            errors = coupling_errors(fmu, motor, tmp, engine)
            name = engine_name(*engine)
            r["curves"][name] = [
                (step, errors[step],
                 r["rates"][name] if step == 1e-3 else system_rate(fmu, motor, points, tmp, engine, step))
                for step in STEPS]
        measure_system(fmu, motor, points, tmp, MOTOR, r)
        measure_system(fmu, load, points, tmp, FLYWHEEL, r)
        r["fmu_tolerances"] = fmu_tolerance_runs(fmu, motor, tmp)
    write_results(out, r, report(r))
    plot(r, out / "coupled_sweep_curves.png")


if __name__ == "__main__":
    main()
