"""The cost of a coupled communication step: the mechanism driven by the compiled DC motor
(examples/dc_motor: the motor's torque to M_m, omega1 back, Jacobi coupling through FMPy's
low-level calls, 10 s), its right-hand sides per communication step at H = 1, 2, 5 and 10 ms and
tol 1e-6, 1e-8 and 1e-10, and the worst error of any output at any communication point
against the same coupled run at tol 1e-12, in units of tol and of each output's scale
max(1, max |y|).

    python bench/bench_coupled_step.py <CyclicMechanism.fmu> <DcMotor.fmu> <output directory>
        [--before OTHER.fmu]

With --before, the same table for another build of the mechanism (an earlier one) beside.
Writes results.json and results.md.
"""

import argparse
import pathlib
import tempfile

import fmpy
import numpy as np
from fmpy.fmi2 import FMU2Slave

from bench_sweep import machine, write_results

# examples/dc_motor/coupling.py's mechanism: no built-in motor law, the paper's load, dampers.
MECHANISM = {"Mm_a0": 0.0, "Mm_a1": 0.0, "Mm_a2": 0.0, "Mr_b0": 20.0, "Mr_b1": -0.05,
             "c4": 0.5, "d34": 1.0}
OUTPUTS = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
           "rod_force", "energy"]
STOP = 10.0
STEPS = (1e-3, 2e-3, 5e-3, 1e-2)
TOLERANCES = (1e-6, 1e-8, 1e-10)


def load(path, name):
    description = fmpy.read_model_description(str(path))
    unzipped = fmpy.extract(str(path), unzipdir=tempfile.mkdtemp())
    slave = FMU2Slave(guid=description.guid, unzipDirectory=unzipped, instanceName=name,
                      modelIdentifier=description.coSimulation.modelIdentifier)
    return slave, {v.name: v.valueReference for v in description.modelVariables}


def coupled_run(mechanism_fmu, motor_fmu, step, tol, stop=STOP):
    """Every output at every communication point, and the right-hand sides and steps the
    mechanism took per communication step."""
    motor, motor_vr = load(motor_fmu, "motor")
    mechanism, vr = load(mechanism_fmu, "mechanism")
    for slave in (motor, mechanism):
        slave.instantiate()
        slave.setupExperiment(tolerance=tol, startTime=0.0, stopTime=stop)
        slave.enterInitializationMode()
    mechanism.setReal([vr[n] for n in MECHANISM], list(MECHANISM.values()))
    for slave in (motor, mechanism):
        slave.exitInitializationMode()
    n = round(stop / step)
    rows = np.empty((n, len(OUTPUTS)))
    for k in range(n):
        t = k * step
        omega1 = mechanism.getReal([vr["omega1"]])[0]
        torque = motor.getReal([motor_vr["torque"]])[0]
        motor.setReal([motor_vr["omega"]], [omega1])
        mechanism.setReal([vr["M_m"]], [torque])
        motor.doStep(t, step)
        mechanism.doStep(t, step)
        rows[k] = mechanism.getReal([vr[o] for o in OUTPUTS])
    rhs, steps = mechanism.getInteger([vr["n_rhs"], vr["n_steps"]])
    for slave in (motor, mechanism):
        slave.terminate()
        slave.freeInstance()
    return rows, rhs / n, steps / n


def table(mechanism_fmu, motor_fmu) -> list[dict]:
    rows = []
    for step in STEPS:
        reference, _, _ = coupled_run(mechanism_fmu, motor_fmu, step, 1e-12)
        scale = np.maximum(1.0, np.abs(reference).max(axis=0))
        for tol in TOLERANCES:
            result, rhs, steps = coupled_run(mechanism_fmu, motor_fmu, step, tol)
            error = np.abs(result - reference) / scale
            worst = np.unravel_index(np.argmax(error), error.shape)
            rows.append({"H": step, "tol": tol, "rhs_per_step": rhs, "steps_per_step": steps,
                         "worst_error_in_tol": float(error[worst]) / tol,
                         "worst_output": OUTPUTS[worst[1]], "worst_time": (worst[0] + 1) * step})
    return rows


def report(r) -> str:
    builds = list(r["builds"])
    lines = ["# The cost of a coupled communication step", "",
             f"Machine: {r['machine']}. The mechanism driven by the compiled DC motor "
             "(examples/dc_motor, Jacobi coupling through FMPy's calls, 10 s): right-hand sides "
             "and integration steps per communication step, and the worst error of any output "
             "at any communication point against the same coupled run at tol 1e-12, in units "
             "of tol and of each output's scale max(1, max |y|).", "",
             "| H | tol | " + " | ".join(f"{b}: RHS per step | {b}: steps per step | {b}: worst error / tol"
                                       for b in builds) + " |",
             "| --- | --- | " + " | ".join("--- | --- | ---" for _ in builds) + " |"]
    for i, row in enumerate(r["builds"][builds[0]]):
        cells = []
        for b in builds:
            x = r["builds"][b][i]
            cells.append(f"{x['rhs_per_step']:.2f} | {x['steps_per_step']:.2f} | "
                         f"{x['worst_error_in_tol']:.3f} ({x['worst_output']})")
        tol = f"1e{round(np.log10(row['tol']))}"
        lines.append(f"| {row['H'] * 1000:g} ms | {tol} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mechanism")
    parser.add_argument("motor")
    parser.add_argument("out", type=pathlib.Path)
    parser.add_argument("--before", help="another build of the mechanism, for comparison")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    r = {"machine": machine(), "builds": {}}
    if args.before:
        r["builds"]["before"] = table(args.before, args.motor)
    r["builds"]["this build"] = table(args.mechanism, args.motor)
    write_results(args.out, r, report(r))


if __name__ == "__main__":
    main()
