"""Couple an external DC-motor model to the mechanism, by FMPy's low-level API:

    python examples/dc_motor/coupling.py <CyclicMechanism.fmu> <output directory> [stop time] [--motor DcMotor.fmu]

The motor is the compiled one of examples/dc_motor/native (`cargo xtask motor` packs
target/fmu/DcMotor.fmu) when given with --motor, else examples/dc_motor/dc_motor.py, the
same motor written in Python, built into an FMU with pythonfmu; each
communication step the master passes the mechanism's `omega1` to the motor and the motor's
`torque` to the mechanism's `M_m` (Jacobi coupling: both step from the previous outputs).
The motor replaces the mechanism's built-in motor law, whose coefficients are set to 0;
the load is the paper's law [80], still built in, plus dampers (c4 on the load, d34
across its spring). (`builtin_laws = false` would switch off both laws at once.) M_r acts on body 4, which only swings, so the dampers are what
consume power. The motor runs up towards its no-load speed V/k = 12 rad/s and settles
below it, drawing the current that feeds the dampers. (Without damping the crank, turning
near √(k34/J4) ≈ 12 rad/s, drives the load spring into resonance.)
Writes coupling.csv and coupling.png to the output directory.
"""

import argparse
import pathlib
import shutil
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import fmpy  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent

# The mechanism's settings: no built-in motor law (the DC motor drives M_m), the paper's
# load law, and dampers.
MECHANISM = {"Mm_a0": 0.0, "Mm_a1": 0.0, "Mm_a2": 0.0, "Mr_b0": 20.0, "Mr_b1": -0.05,
             "c4": 0.5, "d34": 1.0}


def build_motor(out):
    """Build DcMotor.fmu from dc_motor.py with pythonfmu."""
    subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(HERE / "dc_motor.py"), "-d", str(out)],
                   check=True, capture_output=True)
    return out / "DcMotor.fmu"


def load(fmu_path, instance):
    description = fmpy.read_model_description(str(fmu_path))
    unzipped = fmpy.extract(str(fmu_path), unzipdir=tempfile.mkdtemp())
    slave = FMU2Slave(guid=description.guid, unzipDirectory=unzipped,
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName=instance)
    refs = {v.name: v.valueReference for v in description.modelVariables}
    return slave, refs, unzipped


def run(mechanism_fmu, out, stop_time=5.0, step=1e-3, motor_fmu=None):
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    motor, motor_vr, motor_dir = load(motor_fmu or build_motor(out), "motor")
    mech, mech_vr, mech_dir = load(mechanism_fmu, "mechanism")
    for slave in (motor, mech):
        slave.instantiate()
        slave.setupExperiment(startTime=0.0, stopTime=stop_time)
        slave.enterInitializationMode()
    mech.setReal([mech_vr[n] for n in MECHANISM], list(MECHANISM.values()))
    for slave in (motor, mech):
        slave.exitInitializationMode()
    rows = []
    names = ["omega1", "phi3", "phi4", "rod_force"]
    for k in range(round(stop_time / step)):
        t = k * step
        omega1 = mech.getReal([mech_vr["omega1"]])[0]
        current, torque = motor.getReal([motor_vr["current"], motor_vr["torque"]])
        rows.append([t, current, torque] + mech.getReal([mech_vr[n] for n in names]))
        motor.setReal([motor_vr["omega"]], [omega1])
        mech.setReal([mech_vr["M_m"]], [torque])
        motor.doStep(t, step)
        mech.doStep(t, step)
    for slave, directory in ((motor, motor_dir), (mech, mech_dir)):
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(directory, ignore_errors=True)
    data = np.array(rows)
    header = "time,current,torque," + ",".join(names)
    np.savetxt(out / "coupling.csv", data, delimiter=",", header=header, comments="")
    plot(data, out / "coupling.png")
    return dict(zip(header.split(","), data.T))


def plot(data, path):
    fig, axes = plt.subplots(3, 1, figsize=(9.5, 8), sharex=True)
    t = data[:, 0]
    axes[0].plot(t, data[:, 3], label="ω1 (rad/s)")
    axes[0].set_ylabel("speed (rad/s)")
    axes[1].plot(t, data[:, 1], label="current (A)")
    axes[1].plot(t, data[:, 2], label="torque (N·m)")
    axes[1].set_ylabel("motor")
    axes[2].plot(t, data[:, 4], label="φ3 (rad)")
    axes[2].plot(t, data[:, 5], "--", label="φ4 (rad)")
    axes[2].set(xlabel="time (s)", ylabel="angle (rad)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        # Beside the axes, where no curve runs.
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle("DC motor FMU driving the mechanism FMU (FMPy master, H = 1 ms)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="Couple a DC-motor FMU to the mechanism FMU.")
    parser.add_argument("mechanism", help="CyclicMechanism.fmu")
    parser.add_argument("out", help="output directory")
    parser.add_argument("stop_time", nargs="?", type=float, default=5.0, help="stop time (s)")
    parser.add_argument("--motor", help="a DC-motor FMU (default: dc_motor.py built with pythonfmu)")
    args = parser.parse_args()
    result = run(args.mechanism, args.out, args.stop_time, motor_fmu=args.motor)
    print(f"final: omega1 = {result['omega1'][-1]:.3f} rad/s, current = {result['current'][-1]:.3f} A")
    out = pathlib.Path(args.out)
    print(f"written: {out / 'coupling.csv'}, {out / 'coupling.png'}")
