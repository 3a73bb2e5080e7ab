"""The motor-driven mechanism as an SSP (System Structure and Parameterization) file, run
by FMPy's SSP support:

    python examples/dc_motor/ssp.py <CyclicMechanism.fmu> <output directory> [stop time]

Packs MotorDrivenMechanism.ssp (SystemStructure.ssd, both FMUs, the load parameters as
load.ssv) and simulates it with fmpy.ssp.simulation.simulate_ssp: the same system and
coupling as coupling.py.
"""

import pathlib
import sys
import zipfile

from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import read_ssv

import coupling

LOAD = coupling.MECHANISM  # the built-in motor law off, the load law and dampers

SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="MotorDrivenMechanism"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription">
  <ssd:System name="System">
    <ssd:Elements>
      <ssd:Component name="motor" source="resources/DcMotor.fmu" type="application/x-fmu-sharedlibrary">
        <ssd:Connectors>
          <ssd:Connector name="omega" kind="input"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="current" kind="output"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="torque" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>
      <ssd:Component name="mechanism" source="resources/CyclicMechanism.fmu" type="application/x-fmu-sharedlibrary">
        <ssd:Connectors>
          <ssd:Connector name="M_m" kind="input"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="omega1" kind="output"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="phi3" kind="output"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="phi4" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding source="resources/load.ssv" prefix="mechanism."/>
        </ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="mechanism" startConnector="omega1" endElement="motor" endConnector="omega"/>
      <ssd:Connection startElement="motor" startConnector="torque" endElement="mechanism" endConnector="M_m"/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="5"/>
</ssd:SystemStructureDescription>
"""


def ssv(prefix):
    parameters = "\n".join(
        f'    <ssv:Parameter name="{prefix}{name}"><ssv:Real value="{value}"/></ssv:Parameter>'
        for name, value in LOAD.items())
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet version="1.0" name="load" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssv:Parameters>
{parameters}
  </ssv:Parameters>
</ssv:ParameterSet>
"""


def build_ssp(mechanism_fmu, out):
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    motor_fmu = coupling.build_motor(out)
    ssp = out / "MotorDrivenMechanism.ssp"
    with zipfile.ZipFile(ssp, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("SystemStructure.ssd", SSD)
        archive.write(mechanism_fmu, "resources/CyclicMechanism.fmu")
        archive.write(motor_fmu, "resources/DcMotor.fmu")
        # The binding above adds the prefix for tools that apply it; FMPy matches full
        # names, so the set read back for FMPy carries it already.
        archive.writestr("resources/load.ssv", ssv(""))
        archive.writestr("resources/load_fmpy.ssv", ssv("mechanism."))
    return ssp


def run(mechanism_fmu, out, stop_time=5.0, step=1e-3):
    ssp = build_ssp(mechanism_fmu, out)
    parameters = read_ssv(str(ssp), resource="resources/load_fmpy.ssv")
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
