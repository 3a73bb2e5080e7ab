"""The motor-driven mechanism as an SSP (System Structure and Parameterization) file, run
by FMPy's SSP support:

    python examples/dc_motor/ssp.py <CyclicMechanism.fmu> <output directory> [stop time]

Packs MotorDrivenMechanism.ssp (ssp/SystemStructure.ssd, both FMUs, the load parameters
ssp/load.ssv bound to the mechanism) and simulates it with
fmpy.ssp.simulation.simulate_ssp: the same system and coupling as coupling.py. The motor
is the Python-written one of dc_motor.py, or a given FMU (the compiled one, which
`cargo xtask motor` packs, is what fmusweep runs natively).
"""

import pathlib
import sys
import zipfile

from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import read_ssv

import coupling

HERE = pathlib.Path(__file__).resolve().parent / "ssp"


def build_ssp(mechanism_fmu, out, motor_fmu=None):
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    motor_fmu = motor_fmu or coupling.build_motor(out)
    ssp = out / "MotorDrivenMechanism.ssp"
    with zipfile.ZipFile(ssp, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.write(HERE / "SystemStructure.ssd", "SystemStructure.ssd")
        archive.write(mechanism_fmu, "resources/CyclicMechanism.fmu")
        archive.write(motor_fmu, "resources/DcMotor.fmu")
        archive.write(HERE / "load.ssv", "resources/load.ssv")
    return ssp


def run(mechanism_fmu, out, stop_time=5.0, step=1e-3, motor_fmu=None):
    ssp = build_ssp(mechanism_fmu, out, motor_fmu)
    # FMPy applies no parameter binding of the file's own: the load's values are handed to
    # it as a parameter set, named as it matches them (component.variable).
    parameters = read_ssv(str(ssp), resource="resources/load.ssv")
    for parameter in parameters.parameters:
        parameter.name = f"mechanism.{parameter.name}"
    # Half a step short: simulate_ssp's loop accumulates time and would take a step more
    # where the sum falls short of the stop time (10 s at 1 ms).
    return simulate_ssp(str(ssp), stop_time=stop_time - 0.5 * step, step_size=step,
                        parameter_set=parameters)


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit("usage: ssp.py <CyclicMechanism.fmu> <output directory> [stop time]")
    result = run(sys.argv[1], sys.argv[2], float(sys.argv[3]) if len(sys.argv) > 3 else 5.0)
    print(f"final omega1 = {result['mechanism.omega1'][-1]:.3f} rad/s; "
          f"written {pathlib.Path(sys.argv[2]) / 'MotorDrivenMechanism.ssp'}")
