"""The positive control of the valgrind run (cargo xtask test): deliberately passes
fmi2GetReal a buffer one value too short, so that the FMU writes past a heap block. The
valgrind check must attribute that error to the FMU's library; if it does not, a clean
report of the real suite would prove nothing. Not a pytest test (no test_ prefix).

Usage: python valgrind_probe.py FMU
"""

import ctypes
import sys

import fmpy
from fmpy.fmi2 import FMU2Slave


def main(fmu_path):
    unzipped = fmpy.extract(fmu_path)
    md = fmpy.read_model_description(unzipped)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier)
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    refs = (ctypes.c_uint * 2)(vr["phi1"], vr["phi2"])
    libc = ctypes.CDLL(None)
    libc.malloc.restype = ctypes.c_void_p
    block = libc.malloc(8)  # room for one double, two requested
    slave.fmi2GetReal(slave.component, refs, 2, ctypes.cast(block, ctypes.POINTER(ctypes.c_double)))
    slave.terminate()
    slave.freeInstance()


if __name__ == "__main__":
    main(sys.argv[1])
