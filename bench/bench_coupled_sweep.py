"""The coupled-sweep benchmark: the DC motor driving the mechanism (examples/dc_motor, 10 s
at H = 1 ms), points per second of one worker through each engine, side by side in this
process, and the coupling error of the native engine against the monolithic reference
(motor and mechanism as one ODE, scipy's DOP853 at rtol 1e-11) at H = 1, 2, 5 and 10 ms.

    python bench/bench_coupled_sweep.py <CyclicMechanism.fmu> <DcMotor.fmu> <output directory> [--quick]

Engines: the native one (a [system] of the compiled motor and the mechanism, one container
FMU in the runner), FMPy's SSP support through fmusweep (the Python-written motor, as the
SSP example packs it), and an FMPy master loop of FMPy's calls (the compiled motor).
Writes results.json and results.md.
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


def system_spec(fmu, motor, stop, step, points, series=False):
    spec = {"system": {"components": {"motor": str(motor), "mechanism": str(fmu)},
                       "connections": [["motor.torque", "mechanism.M_m"],
                                       ["mechanism.omega1", "motor.omega"]]},
            "scenario": {"stop": stop, "step": step, "tolerance": 1e-8,
                         "parameters": {f"mechanism.{k}": v for k, v in MECHANISM.items()}},
            "design": {"kind": "grid", "parameters": {
                "mechanism.d34": {"linspace": [0.5, 1.5, points]} if points > 1 else {"values": [1.0]}}},
            "outputs": {"metrics": {"final": {"variable": "mechanism.omega1", "kind": "final"}}}}
    if series:
        spec["outputs"]["series"] = {"variables": [f"mechanism.{s}" for s in STATES] + ["motor.current"]}
    return spec


def native_rate(fmu, motor, points, tmp):
    spec = system_spec(fmu, motor, 10.0, 1e-3, points)
    r = run_sweep(spec, out=pathlib.Path(tmp) / "native", serial=True, progress=False, plots=False).report
    return r.computed / r.point_seconds


def master_loop_rate(fmu, motor, points):
    t0 = time.perf_counter()
    for _ in range(points):
        coupled_run(fmu, motor, 1e-3, 1e-8, 10.0)
    return points / (time.perf_counter() - t0)


def coupling_errors(fmu, motor, tmp, stop=2.0):
    """The native engine's worst error over the states and the current at every
    communication point against the monolithic reference, in units of each one's scale
    max(1, max |y|), per communication step."""
    p = reference.Params(**MECHANISM, d34=1.0)
    errors = {}
    for step in (1e-3, 2e-3, 5e-3, 1e-2):
        spec = system_spec(fmu, motor, stop, step, 1, series=True)
        results = run_sweep(spec, out=pathlib.Path(tmp) / f"error-{step}", serial=True,
                            progress=False, plots=False)
        series = results.series()
        names = [f"mechanism.{s}" for s in STATES] + ["motor.current"]
        columns = [series[series["variable"] == n].sort_values("time") for n in names]
        times = columns[0]["time"].to_numpy()
        mine = np.column_stack([c["value"].to_numpy() for c in columns])
        exact = reference.solve_with_motor(p, reference.Motor(), times, rtol=1e-11)
        scale = np.maximum(1.0, np.abs(exact).max(axis=0))
        errors[step] = float((np.abs(mine - exact) / scale).max())
    return errors


def report(r) -> str:
    rates = r["rates"]
    e = r["errors"]
    steps = sorted(e, key=float)
    orders = [np.log(e[b] / e[a]) / np.log(float(b) / float(a)) for a, b in zip(steps, steps[1:])]
    return "\n".join([
        "# Coupled-sweep benchmark", "",
        f"Machine: {r['machine']}. The DC motor driving the mechanism (examples/dc_motor: the "
        "motor's torque to M_m, omega1 back; the built-in motor law off, the paper's load "
        "law, c4 = 0.5), 10 s at H = 1 ms, tol 1e-8, one worker, engines side by side in one run.", "",
        "| engine (one worker) | points/s | against the SSP path |", "| --- | --- | --- |",
        f"| native: a [system] as one container FMU in the runner, compiled motor | {rates['native']:.1f} | "
        f"{rates['native'] / rates['ssp']:.0f}× |",
        f"| an FMPy master loop of FMPy's calls, compiled motor | {rates['master_loop']:.2f} | "
        f"{rates['master_loop'] / rates['ssp']:.1f}× |",
        f"| FMPy's SSP support through fmusweep, Python-written motor | {rates['ssp']:.2f} | 1× |", "",
        "Coupling error of the native engine (inputs held over each step: the container passes no "
        "input derivatives) against the monolithic reference (motor and mechanism as one ODE, "
        "scipy's DOP853 at rtol 1e-11), worst over φ1..φ4, ω1..ω4 and the current at every "
        "communication point of 2 s, in units of each one's scale max(1, max |y|):", "",
        "| H | error |", "| --- | --- |",
        *[f"| {float(s) * 1000:g} ms | {e[s]:.2e} |" for s in steps], "",
        "Observed order between successive steps: " + ", ".join(f"{o:.2f}" for o in orders) + ".", ""])


def main():
    fmu, motor, out = (pathlib.Path(a) for a in sys.argv[1:4])
    quick = "--quick" in sys.argv
    out.mkdir(parents=True, exist_ok=True)
    r = {"machine": machine(), "quick": quick, "rates": {}}
    with tempfile.TemporaryDirectory() as tmp:
        print("bench-coupled-sweep: engines", flush=True)
        r["rates"]["native"] = native_rate(fmu, motor, 20 if quick else 100, tmp)
        r["rates"]["master_loop"] = master_loop_rate(fmu, motor, 2 if quick else 5)
        r["rates"]["ssp"] = ssp_rate(fmu, 2 if quick else 4, stop=10.0)["points_per_s"]
        print("bench-coupled-sweep: coupling error", flush=True)
        r["errors"] = {str(k): v for k, v in coupling_errors(fmu, motor, tmp).items()}
    write_results(out, r, report(r))


if __name__ == "__main__":
    main()
