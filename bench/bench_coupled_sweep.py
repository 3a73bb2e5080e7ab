"""The coupled-sweep benchmark: the DC motor driving the mechanism (examples/dc_motor, 10 s
at H = 1 ms), points per second of one worker through each engine, side by side in this
process; and for each engine of a [system] the coupling error against the monolithic
reference (motor and mechanism as one ODE, scipy's DOP853 at rtol 1e-11) and the points
per second at H = 1, 2, 5 and 10 ms: the two curves that decide between the engines; and
the native engine with a coupling tolerance (1e-3 to 1e-6 on a 10 ms grid) against the
same engine at fixed steps, at equal error.

    python bench/bench_coupled_sweep.py <CyclicMechanism.fmu> <DcMotor.fmu> <output directory> [--quick]

Engines: a [system] of the compiled motor and the mechanism run by the runner itself
(`native`, with input derivatives of order 0, 1 or 2) or as one container FMU
(`container`); FMPy's SSP support through fmusweep (the Python-written motor, as the SSP
example packs it); and an FMPy master loop of FMPy's calls (the compiled motor).
Writes results.json, results.md and coupled_sweep_curves.png.
"""

import pathlib
import sys
import tempfile
import time

import numpy as np

from bench_coupled_step import coupled_run
from bench_sweep import machine, ssp_rate, write_results
from fmusweep import run_sweep

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests/python"))
import reference  # noqa: E402

MECHANISM = {"Mm_a0": 0.0, "Mm_a1": 0.0, "Mm_a2": 0.0, "Mr_b0": 20.0, "Mr_b1": -0.05, "c4": 0.5}
STATES = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4"]


# (engine, input derivatives): the [system] engines compared.
ENGINES = [("native", 2), ("native", 1), ("native", 0), ("container", 0)]
STEPS = (1e-3, 2e-3, 5e-3, 1e-2)
# A coupling tolerance: the tolerances measured, their output grid, and the shorter fixed
# steps that extend the best fixed engine's curve to the errors they reach.
TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6)
GRID = 1e-2
FINE_STEPS = (2.5e-4, 5e-4)


def engine_name(engine, derivatives):
    return f"{engine}, input derivatives {derivatives}" if engine == "native" else engine


def system_spec(fmu, motor, stop, step, points, series=False, engine=("native", 2), tolerance=None):
    spec = {"system": {"components": {"motor": str(motor), "mechanism": str(fmu)},
                       "connections": [["motor.torque", "mechanism.M_m"],
                                       ["mechanism.omega1", "motor.omega"]],
                       "engine": engine[0], "input_derivatives": engine[1]},
            "scenario": {"stop": stop, "step": step, "tolerance": 1e-8,
                         "parameters": {f"mechanism.{k}": v for k, v in MECHANISM.items()}},
            "design": {"kind": "grid", "parameters": {
                "mechanism.d34": {"linspace": [0.5, 1.5, points]} if points > 1 else {"values": [1.0]}}},
            "outputs": {"metrics": {"final": {"variable": "mechanism.omega1", "kind": "final"}}}}
    if series:
        spec["outputs"]["series"] = {"variables": [f"mechanism.{s}" for s in STATES] + ["motor.current"]}
    if tolerance is not None:
        spec["system"]["coupling_tolerance"] = tolerance
    return spec


def system_rate(fmu, motor, points, tmp, engine=("native", 2), step=1e-3, tolerance=None):
    spec = system_spec(fmu, motor, 10.0, step, points, engine=engine, tolerance=tolerance)
    out = pathlib.Path(tmp) / f"rate-{engine[0]}-{engine[1]}-{step}-{tolerance}"
    r = run_sweep(spec, out=out, serial=True, progress=False, plots=False).report
    return r.computed / r.point_seconds


def master_loop_rate(fmu, motor, points):
    t0 = time.perf_counter()
    for _ in range(points):
        coupled_run(fmu, motor, 1e-3, 1e-8, 10.0)
    return points / (time.perf_counter() - t0)


def coupling_errors(fmu, motor, tmp, engine, stop=2.0, steps=STEPS):
    """An engine's worst error over the states and the current at every communication point
    against the monolithic reference, in units of each one's scale max(1, max |y|), per
    communication step."""
    return {step: worst_error(system_spec(fmu, motor, stop, step, 1, series=True, engine=engine),
                              pathlib.Path(tmp) / f"error-{engine[0]}-{engine[1]}-{step}")[0]
            for step in steps}


def worst_error(spec, out):
    """A one-point spec's worst scaled error against the monolithic reference at every
    communication point, and its row."""
    p = reference.Params(**MECHANISM, d34=1.0)
    results = run_sweep(spec, out=out, serial=True, progress=False, plots=False)
    series = results.series()
    names = [f"mechanism.{s}" for s in STATES] + ["motor.current"]
    columns = [series[series["variable"] == n].sort_values("time") for n in names]
    times = columns[0]["time"].to_numpy()
    mine = np.column_stack([c["value"].to_numpy() for c in columns])
    exact = reference.solve_with_motor(p, reference.Motor(), times, rtol=1e-11)
    scale = np.maximum(1.0, np.abs(exact).max(axis=0))
    return float((np.abs(mine - exact) / scale).max()), results.points.iloc[0]


def fmu_tolerance_runs(fmu, motor, tmp):
    """The worst error (2 s, 10 ms grid) with the FMUs' own tolerance at several fractions
    of the coupling tolerance, and without one (the tenth the sweep then passes)."""
    runs = []
    for coupling in (1e-4, 1e-6):
        for ratio in (1.0, 0.1, 0.01, 0.001, None):
            spec = system_spec(fmu, motor, 2.0, GRID, 1, series=True, tolerance=coupling)
            if ratio is None:
                spec["scenario"].pop("tolerance")
            else:
                spec["scenario"]["tolerance"] = ratio * coupling
            error, _ = worst_error(spec, pathlib.Path(tmp) / f"fmu-tolerance-{coupling}-{ratio}")
            runs.append({"coupling": coupling, "ratio": ratio, "error": error})
    return runs


def tolerance_runs(fmu, motor, points, tmp):
    """With a coupling tolerance on a 10 ms output grid (native engine, 2 input
    derivatives): per tolerance the worst error over 2 s, the points/s of 10 s runs and
    the communication steps taken."""
    runs = []
    for tol in TOLERANCES:
        spec = system_spec(fmu, motor, 2.0, GRID, 1, series=True, tolerance=tol)
        error, row = worst_error(spec, pathlib.Path(tmp) / f"tolerance-{tol}")
        runs.append({"tolerance": tol, "error": error, "estimate": float(row["coupling_error"]),
                     "accepted": int(row["coupling_steps"]), "rejected": int(row["coupling_rejected"]),
                     "min_step": float(row["coupling_min_step"]),
                     "rate": system_rate(fmu, motor, points, tmp, step=GRID, tolerance=tol)})
    return runs


def interpolated_rate(curve, target):
    """Points/s at coupling error `target` on an engine's curve [(step, error, rate)],
    log-log interpolated between measured steps; None outside the errors measured."""
    for (h0, e0, r0), (h1, e1, r1) in zip(curve, curve[1:]):
        if min(e0, e1) <= target <= max(e0, e1):
            x = np.log(target / e0) / np.log(e1 / e0)
            return float(np.exp(np.log(r0) + x * np.log(r1 / r0)))
    return None


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


def tolerance_report(r) -> list[str]:
    fixed = r["fixed_native_2"]
    lines = ["## A coupling tolerance", "",
             f"The native engine with 2 input derivatives and `coupling_tolerance`, on an output "
             f"grid of {GRID * 1000:g} ms: the error as above (2 s), points/s of 10 s runs, and "
             "the steps the controller took; against it, the same engine at fixed steps "
             "(the curve above, extended by " + " and ".join(f"{h * 1000:g} ms" for h in FINE_STEPS)
             + "), its points/s interpolated at the same error.", "",
             "| tolerance | worst error | error / tolerance | points/s | steps accepted, rejected | "
             "smallest step | fixed steps at that error: points/s | speed-up |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for run in r["tolerances"]:
        rate = interpolated_rate(fixed, run["error"])
        versus = f"{rate:.0f} | {run['rate'] / rate:.2f}×" if rate else "– | –"
        lines.append(f"| {run['tolerance']:g} | {run['error']:.2e} | {run['error'] / run['tolerance']:.2f} "
                     f"| {run['rate']:.0f} | {run['accepted']}, {run['rejected']} "
                     f"({run['rejected'] / (run['accepted'] + run['rejected']):.1%}) | "
                     f"{run['min_step']:.2e} s | {versus} |")
    if r.get("fmu_tolerances"):
        lines += ["", "The FMUs' own tolerance under a coupling tolerance (worst error as above; "
                      "\"none given\": the sweep passes a tenth of the coupling tolerance):", "",
                  "| coupling tolerance | FMU tolerance | worst error |", "| --- | --- | --- |"]
        for run in r["fmu_tolerances"]:
            given = "none given" if run["ratio"] is None else f"{run['ratio']:g} × coupling"
            lines.append(f"| {run['coupling']:g} | {given} | {run['error']:.2e} |")
    lines += ["", "Fixed steps, native engine, 2 input derivatives: " + ", ".join(
        f"{h * 1000:g} ms: {e:.2e} at {rate:.0f} points/s" for h, e, rate in fixed) + ".", ""]
    return lines


def report(r) -> str:
    rates = r["rates"]
    curves = r["curves"]
    names = list(curves)
    lines = [
        "# Coupled-sweep benchmark", "",
        f"Machine: {r['machine']}. The DC motor driving the mechanism (examples/dc_motor: the "
        "motor's torque to M_m, omega1 back; the built-in motor law off, the paper's load "
        "law, c4 = 0.5), tol 1e-8, one worker, engines side by side in one run.", "",
        "## Engines at H = 1 ms", "",
        "10 s per point.", "",
        "| engine (one worker) | points/s | against the SSP path |", "| --- | --- | --- |",
        *[f"| [system], engine {n} | {rates[n]:.1f} | {rates[n] / rates['ssp']:.0f}× |" for n in names],
        f"| an FMPy master loop of FMPy's calls, compiled motor | {rates['master_loop']:.2f} | "
        f"{rates['master_loop'] / rates['ssp']:.1f}× |",
        f"| FMPy's SSP support through fmusweep, Python-written motor | {rates['ssp']:.2f} | 1× |", "",
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
        lines.append(f"| {n} | " + " | ".join(rate_at_error(curves[n], t) for t in r["targets"]) + " |")
    lines += ["", "![points/s against coupling error](coupled_sweep_curves.png)", ""]
    if r.get("tolerances"):
        lines += tolerance_report(r)
    return "\n".join(lines)


def plot(r, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for n, c in r["curves"].items():
        errors = [e for _, e, _ in c]
        rates = [rate for _, _, rate in c]
        ax.loglog(errors, rates, "o-", label=n)
        for h, e, rate in c:
            ax.annotate(f"{h * 1000:g} ms", (e, rate), textcoords="offset points", xytext=(4, 4),
                        fontsize=7)
    if r.get("tolerances"):
        runs = r["tolerances"]
        ax.loglog([t["error"] for t in runs], [t["rate"] for t in runs], "s--", color="k",
                  label="native, input derivatives 2, coupling tolerance (10 ms grid)")
        for t in runs:
            ax.annotate(f"tol {t['tolerance']:g}", (t["error"], t["rate"]), textcoords="offset points",
                        xytext=(4, -10), fontsize=7)
    ax.set_xlabel("coupling error against the monolithic reference (scaled, worst point)")
    ax.set_ylabel("points/s, one worker (10 s runs)")
    ax.set_title("Coupled DC motor and mechanism: speed against coupling error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    fmu, motor, out = (pathlib.Path(a) for a in sys.argv[1:4])
    quick = "--quick" in sys.argv
    out.mkdir(parents=True, exist_ok=True)
    r = {"machine": machine(), "quick": quick, "rates": {}, "curves": {},
         "targets": [3e-2, 1e-2, 1e-3, 1e-4]}
    points = 20 if quick else 100
    with tempfile.TemporaryDirectory() as tmp:
        print("bench-coupled-sweep: engines", flush=True)
        for engine in ENGINES:
            r["rates"][engine_name(*engine)] = system_rate(fmu, motor, points, tmp, engine)
        r["rates"]["master_loop"] = master_loop_rate(fmu, motor, 2 if quick else 5)
        r["rates"]["ssp"] = ssp_rate(fmu, 2 if quick else 4, stop=10.0)["points_per_s"]
        print("bench-coupled-sweep: coupling error and speed by step", flush=True)
        for engine in ENGINES:
            errors = coupling_errors(fmu, motor, tmp, engine)
            name = engine_name(*engine)
            r["curves"][name] = [
                (step, errors[step],
                 r["rates"][name] if step == 1e-3 else system_rate(fmu, motor, points, tmp, engine, step))
                for step in STEPS]
        print("bench-coupled-sweep: a coupling tolerance", flush=True)
        best = engine_name("native", 2)
        fine = coupling_errors(fmu, motor, tmp, ("native", 2), steps=FINE_STEPS)
        r["fixed_native_2"] = [(h, fine[h], system_rate(fmu, motor, points, tmp, step=h))
                               for h in FINE_STEPS] + r["curves"][best]
        r["tolerances"] = tolerance_runs(fmu, motor, points, tmp)
        r["fmu_tolerances"] = fmu_tolerance_runs(fmu, motor, tmp)
    write_results(out, r, report(r))
    plot(r, out / "coupled_sweep_curves.png")


if __name__ == "__main__":
    main()
