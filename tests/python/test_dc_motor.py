"""The compiled DC motor of examples/dc_motor/native (packed by `cargo xtask motor`): a
valid FMU, exact steps and output derivatives for held inputs and for inputs moving along
their derivatives, bad values refused by name,
and coupled to the mechanism the same run as the Python-written motor of
examples/dc_motor/dc_motor.py."""

import math
import re
import sys

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import ROOT, compiled_slave

sys.path.insert(0, str(ROOT / "examples/dc_motor"))
import coupling  # noqa: E402

NATIVE = ROOT / "examples/dc_motor/native"
R, L, K, V = 0.5, 0.01, 2.0, 24.0


@pytest.fixture
def motor(motor_path, tmp_path):
    slave = compiled_slave(motor_path, "DcMotor", tmp_path / "motor")
    yield slave
    slave.freeInstance()


def test_the_fmu_is_valid_and_its_guid_is_the_binarys(motor_path):
    assert validate_fmu(str(motor_path)) == []
    source_guid = re.search(r'#define GUID "([^"]+)"', (NATIVE / "dc_motor.c").read_text()).group(1)
    assert fmpy.read_model_description(str(motor_path)).guid == source_guid


def test_a_step_of_any_size_is_exact_for_held_inputs(motor):
    motor.setupExperiment(startTime=0.0)
    motor.enterInitializationMode()
    motor.setReal([motor.vr["omega"]], [5.0])
    motor.exitInitializationMode()
    steady = (V - K * 5.0) / R
    t, current = 0.0, 0.0
    for h in (1e-4, 0.003, 0.02, 0.5):
        # Output derivatives at the start of the step, from the equations.
        rate = (V - R * current - K * 5.0) / L
        first, second = motor.getRealOutputDerivatives([motor.vr["torque"]] * 2, [1, 2])
        assert math.isclose(first, K * rate, rel_tol=1e-14)
        assert math.isclose(second, -(R / L) * K * rate, rel_tol=1e-14)
        motor.doStep(t, h)
        t += h
        current = steady + (current - steady) * math.exp(-h * R / L)
        got_current, got_torque = motor.getReal([motor.vr["current"], motor.vr["torque"]])
        assert math.isclose(got_current, current, rel_tol=1e-14)
        assert got_torque == K * got_current


def test_steps_along_input_derivatives_are_exact(motor):
    """Speed and voltage moving along the derivatives the master sets: steps of any size,
    and values set between them, agree with the current's ODE solved by scipy at tight
    tolerance, and so do the output derivatives."""
    from scipy.integrate import solve_ivp
    w0, w1, w2, v1 = 5.0, 30.0, -40.0, 6.0   # omega(t) = w0 + w1·t + w2·t²/2, V' = v1

    def omega(t):
        return w0 + w1 * t + 0.5 * w2 * t * t

    def rate(t, i):
        return (V + v1 * t - R * i - K * omega(t)) / L

    motor.setupExperiment(startTime=0.0)
    motor.enterInitializationMode()
    motor.setReal([motor.vr["omega"]], [w0])
    motor.setRealInputDerivatives([motor.vr["omega"]] * 2 + [motor.vr["voltage"]], [1, 2, 1],
                                  [w1, w2, v1])
    motor.exitInitializationMode()
    times = [0.0, 1e-4, 0.003, 0.02, 0.05, 0.2]
    exact = solve_ivp(lambda t, i: [rate(t, i[0])], (0.0, times[-1]), [0.0], method="DOP853",
                      rtol=1e-13, atol=1e-15, t_eval=times[1:], dense_output=True)
    for k, (t, t_next) in enumerate(zip(times, times[1:])):
        if k == 3:
            # The master sets the speed it would have anyway: the course goes on.
            motor.setReal([motor.vr["omega"]], [omega(t)])
        motor.doStep(t, t_next - t)
        current = motor.getReal([motor.vr["current"]])[0]
        assert math.isclose(current, exact.y[0][k], rel_tol=1e-11, abs_tol=1e-12), t_next
        first, second = motor.getRealOutputDerivatives([motor.vr["current"]] * 2, [1, 2])
        assert math.isclose(first, rate(t_next, current), rel_tol=1e-11)
        rate_of_rate = (v1 - K * (w1 + w2 * t_next) - R * first) / L
        assert math.isclose(second, rate_of_rate, rel_tol=1e-11)


def _run_along(motor, steps):
    """Steps of the given sizes from the motor's time, the inputs moving along derivatives
    set before each; the current after each step."""
    currents = []
    for h in steps:
        motor.setRealInputDerivatives([motor.vr["omega"], motor.vr["voltage"]], [1, 1],
                                      [30.0, -4.0])
        motor.doStep(motor.time, h)
        motor.time += h
        currents.append(motor.getReal([motor.vr["current"]])[0])
    return currents


def test_a_restored_state_steps_again_to_the_same_bits(motor):
    """The state a master takes before a step, set back after it, makes the step again to
    the last bit, also through its serialized bytes; a state from elsewhere is refused."""
    motor.setupExperiment(startTime=0.0)
    motor.enterInitializationMode()
    motor.setReal([motor.vr["omega"]], [5.0])
    motor.exitInitializationMode()
    motor.time = 0.0
    _run_along(motor, [0.002, 0.004])
    saved, at = motor.getFMUstate(), motor.time
    first = _run_along(motor, [0.003, 0.01])
    motor.setFMUstate(saved)
    motor.time = at
    assert _run_along(motor, [0.003, 0.01]) == first
    serialized = motor.serializeFMUstate(saved)
    motor.freeFMUstate(saved)
    restored = motor.deSerializeFMUstate(serialized)
    motor.setFMUstate(restored)
    motor.time = at
    assert _run_along(motor, [0.003, 0.01]) == first
    motor.freeFMUstate(restored)
    with pytest.raises(FMICallException):
        motor.deSerializeFMUstate(b"X" + bytes(serialized[1:]))
    assert "not a state this FMU serialized" in motor.messages[-1]


def test_bad_values_are_refused_by_name_and_change_nothing(motor):
    motor.setupExperiment(startTime=0.0)
    motor.enterInitializationMode()
    for name, value in (("R", 0.0), ("L", -1.0), ("voltage", math.nan)):
        with pytest.raises(FMICallException):
            motor.setReal([motor.vr["voltage"], motor.vr[name]], [12.0, value])
    assert motor.getReal([motor.vr["voltage"]]) == [V]  # the batch's valid part was not applied
    motor.exitInitializationMode()
    with pytest.raises(FMICallException):
        motor.setReal([motor.vr["k"]], [3.0])  # a fixed parameter after initialisation
    with pytest.raises(FMICallException):
        motor.doStep(0.0, -1.0)
    said = motor.messages
    assert "fmi2SetReal: R = 0: must be > 0" in said[0] and "L = -1: must be > 0" in said[1]
    assert "voltage = nan: must be a finite number" in said[2]
    assert "k is a fixed parameter" in said[3] and "communicationStepSize" in said[4]


def test_coupled_to_the_mechanism_it_is_the_python_motors_run(fmu_path, motor_path, tmp_path):
    compiled = coupling.run(fmu_path, tmp_path / "compiled", stop_time=0.5, motor_fmu=str(motor_path))
    scripted = coupling.run(fmu_path, tmp_path / "python", stop_time=0.5)
    for name in ("current", "torque", "omega1", "phi3", "rod_force"):
        assert np.max(np.abs(compiled[name] - scripted[name])) <= 1e-12 * np.max(np.abs(scripted[name])), name
