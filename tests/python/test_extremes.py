"""Finite but extreme values (±1e±300, subnormals) set on every settable variable, before
and during a run: whatever the FMU accepts, everything read back after an fmi2OK is
finite, and what it refuses is refused with a message that names the variable."""

import math

from fmpy.fmi1 import FMICallException
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from test_fmi_api import DISCARD, ERROR, OK, Harness

EXTREMES = [1e300, -1e300, 1e200, -1e155, 1e155, 1e-300, -1e-300, 5e-324, -2.2e-308,
            1e100, -1e20, 0.0]
OUTPUTS = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
           "rod_force", "constraint_residual", "energy"]


def settable(model_description):
    return [v.name for v in model_description.modelVariables
            if v.type == "Real" and v.causality in ("parameter", "input")]


def values(name_list):
    ordinary = st.floats(-10.0, 10.0)
    return st.dictionaries(st.sampled_from(name_list), st.sampled_from(EXTREMES) | ordinary,
                           max_size=6)


def attempt(fmu, call, *args):
    """The call's status; a refusal must say which variable or rule."""
    before = len(fmu.messages)
    try:
        call(*args)
        return OK
    except FMICallException as e:
        assert e.status in (DISCARD, ERROR), e.status
        said = " | ".join(m for _, _, m in fmu.messages[before:])
        assert said, "a refusal without a message"
        return e.status


def all_finite_or_refused(fmu):
    vrs = [fmu.vr[n] for n in OUTPUTS]
    try:
        read = fmu.slave.getReal(vrs)
    except FMICallException as e:
        assert e.status == ERROR and "not finite" in fmu.messages[-1][2], fmu.messages[-1]
        return
    assert all(math.isfinite(v) for v in read), dict(zip(OUTPUTS, read))
    for order in (1, 2):
        try:
            derivatives = fmu.slave.getRealOutputDerivatives(vrs, [order] * len(vrs))
        except FMICallException as e:
            assert e.status == ERROR and "not finite" in fmu.messages[-1][2], fmu.messages[-1]
            continue
        assert all(math.isfinite(v) for v in derivatives), (order, derivatives)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_extreme_values_never_come_back_non_finite(unzipped, model_description, data):
    names = settable(model_description)
    start = data.draw(values(names), label="before initialisation")
    during = data.draw(values([n for n in names if n in ("M_m", "M_r")]), label="during the run")
    fmu = Harness(unzipped, model_description).instantiate()
    fmu.slave.setupExperiment(tolerance=1e-6, startTime=0.0)
    fmu.slave.enterInitializationMode()
    for name, value in start.items():
        if attempt(fmu, fmu.set, name, value) != OK:
            assert name in fmu.messages[-1][2], fmu.messages[-1]
    if attempt(fmu, fmu.slave.exitInitializationMode) == OK:
        all_finite_or_refused(fmu)
        t = 0.0
        for step in range(3):
            if step == 1:
                for name, value in during.items():
                    if attempt(fmu, fmu.set, name, value) != OK:
                        assert name in fmu.messages[-1][2], fmu.messages[-1]
            if attempt(fmu, fmu.slave.doStep, t, 0.01) != OK:
                break
            t += 0.01
            all_finite_or_refused(fmu)
    fmu.slave.freeInstance()
