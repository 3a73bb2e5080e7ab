"""A step the integrator cannot complete: fmi2Discard with a
message, outputs finite and unchanged at the last good communication point, the status
functions as the standard says, and rollback (FMU state) or reset still work."""

import math

import fmpy.fmi2 as fmi2
import pytest
from fmpy.fmi1 import FMICallException

from test_fmi_api import DISCARD, ERROR, Harness

# A motor law with positive quadratic feedback: ω1 blows up in finite time (about 0.05 s).
RUNAWAY = dict(Mm_a2=1.0, omega1_0=10.0)
WATCH = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
         "rod_force", "energy", "constraint_residual"]


def run_until_discard(fmu, h=0.01):
    for k in range(1000):
        before = fmu.get(*WATCH)
        try:
            fmu.slave.doStep(k * h, h)
        except FMICallException as failure:
            assert failure.status == DISCARD
            return k * h, before
    pytest.fail("the runaway never failed")


def test_discard_keeps_the_last_good_point(unzipped, model_description):
    fmu = Harness(unzipped, model_description).instantiate().initialise(**RUNAWAY)
    state = fmu.slave.getFMUstate()
    t_fail, before = run_until_discard(fmu)
    message = fmu.messages[-1]
    assert message[1] == "logStatusDiscard" and f"state kept at t = {t_fail}" in message[2]
    after = fmu.get(*WATCH)
    assert after == before and all(math.isfinite(v) for v in after)
    assert fmu.slave.getRealStatus(fmi2.fmi2LastSuccessfulTime) == t_fail
    assert fmu.slave.getBooleanStatus(fmi2.fmi2Terminated) is False
    assert "never returns fmi2Pending" in fmu.expect(ERROR, fmu.slave.getStatus, fmi2.fmi2DoStepStatus)
    assert "step failed" in fmu.expect(ERROR, fmu.slave.doStep, t_fail, 0.01)
    # Roll back to the start and run a little, then reset and run the default case.
    fmu.slave.setFMUstate(state)
    fmu.slave.doStep(0.0, 0.01)
    fmu.slave.reset()
    fmu.initialise()
    fmu.slave.doStep(0.0, 0.01)
    fmu.slave.terminate()
    fmu.free()
