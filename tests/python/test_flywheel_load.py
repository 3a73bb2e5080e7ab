"""The compiled flywheel load of examples/flywheel_load/native (packed by `cargo xtask
motor`): a valid FMU, steps of any size exact for an input held or moving along the
derivatives a master sets (against scipy), output derivatives from the equations, a
restored state that steps again to the same bits, and bad values refused by name."""

import math
import re

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from conftest import ROOT, compiled_slave

NATIVE = ROOT / "examples/flywheel_load/native"
K, D, J, C = 2000.0, 2.0, 0.5, 1.0


@pytest.fixture
def load(load_path, tmp_path):
    slave = compiled_slave(load_path, "FlywheelLoad", tmp_path / "load")
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    yield slave
    slave.freeInstance()


def test_the_fmu_is_valid_and_its_guid_is_the_binarys(load_path):
    assert validate_fmu(str(load_path)) == []
    source_guid = re.search(r'#define GUID "([^"]+)"', (NATIVE / "flywheel_load.c").read_text()).group(1)
    assert fmpy.read_model_description(str(load_path)).guid == source_guid


def _exact(omega, times):
    """Twist and flywheel speed at `times` for the driving speed omega(t) = (ω, ω', ω''),
    from rest, by scipy at tight tolerance."""
    from scipy.integrate import solve_ivp

    def rhs(t, x):
        u = omega(t)[0]
        torque = K * x[0] + D * (u - x[1])
        return [u - x[1], (torque - C * x[1]) / J]
    return solve_ivp(rhs, (0.0, times[-1]), [0.0, 0.0], method="DOP853", rtol=1e-13,
                     atol=1e-15, t_eval=times).y


@pytest.mark.parametrize("course", [(2.0, 0.0, 0.0), (2.0, 30.0, -400.0)], ids=["held", "moving"])
def test_steps_of_any_size_are_exact_and_so_are_the_output_derivatives(load, course):
    """The driving speed held, or moving along first and second derivatives set once; steps
    from 0.1 ms to 50 ms (many periods of the shaft's oscillation) agree with the ODE, and
    the torque's rates with its equations."""
    w0, w1, w2 = course

    def omega(t):
        return w0 + t * (w1 + 0.5 * t * w2), w1 + t * w2, w2

    load.setReal([load.vr["omega"]], [w0])
    load.setRealInputDerivatives([load.vr["omega"]] * 2, [1, 2], [w1, w2])
    load.exitInitializationMode()
    times = np.cumsum([1e-4, 0.003, 0.05, 0.02, 0.0005])
    exact = _exact(omega, times)
    t = 0.0
    for k, t_next in enumerate(times):
        load.doStep(t, t_next - t)
        t = t_next
        twist, speed, torque = load.getReal([load.vr[n] for n in ("twist", "omega_flywheel", "torque")])
        assert math.isclose(twist, exact[0][k], rel_tol=1e-9, abs_tol=1e-13), t
        assert math.isclose(speed, exact[1][k], rel_tol=1e-9, abs_tol=1e-12), t
        u, u1, u2 = omega(t)
        assert torque == pytest.approx(K * twist + D * (u - speed), rel=1e-14, abs=1e-12)
        first, second = load.getRealOutputDerivatives([load.vr["torque"]] * 2, [1, 2])
        speed1 = (torque - C * speed) / J
        assert first == pytest.approx(K * (u - speed) + D * (u1 - speed1), rel=1e-12, abs=1e-9)
        speed2 = (first - C * speed1) / J
        assert second == pytest.approx(K * (u1 - speed1) + D * (u2 - speed2), rel=1e-12, abs=1e-7)


def test_a_restored_state_steps_again_to_the_same_bits(load):
    load.setReal([load.vr["omega"]], [1.0])
    load.exitInitializationMode()

    def steps(t0):
        out, t = [], t0
        for h in (0.002, 0.007):
            load.setRealInputDerivatives([load.vr["omega"]], [1], [12.0])
            load.doStep(t, h)
            t += h
            out.append(load.getReal([load.vr["torque"], load.vr["twist"]]))
        return out

    load.doStep(0.0, 0.01)
    saved = load.getFMUstate()
    first = steps(0.01)
    load.setFMUstate(saved)
    assert steps(0.01) == first
    restored = load.deSerializeFMUstate(load.serializeFMUstate(saved))
    load.setFMUstate(restored)
    assert steps(0.01) == first
    load.freeFMUstate(saved)
    load.freeFMUstate(restored)


def test_bad_values_are_refused_by_name_and_change_nothing(load):
    for name, value in (("k", 0.0), ("J", -1.0), ("d", -0.5), ("omega", math.inf)):
        with pytest.raises(FMICallException):
            load.setReal([load.vr["omega"], load.vr[name]], [3.0, value])
    assert load.getReal([load.vr["omega"]]) == [0.0]  # the batch's valid part was not applied
    load.exitInitializationMode()
    with pytest.raises(FMICallException):
        load.setReal([load.vr["c"]], [2.0])  # a fixed parameter after initialisation
    with pytest.raises(FMICallException):
        load.setReal([load.vr["torque"]], [1.0])
    said = load.messages
    assert "k = 0: must be > 0" in said[0] and "J = -1: must be > 0" in said[1]
    assert "d = -0.5: must be >= 0" in said[2] and "omega = inf: must be a finite number" in said[3]
    assert "c is a fixed parameter" in said[4] and "torque is an output" in said[5]
