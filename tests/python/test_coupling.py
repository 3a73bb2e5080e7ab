"""Coupling: output derivatives against their definitions, input
derivatives, and the convergence order of a master-closed motor/load law: about 1 with
held inputs, about 2 when the master passes first-order input derivatives computed from
the output derivatives."""

import math

import numpy as np
import pytest

from test_fmi_api import ERROR, Harness

LAWS = dict(Mm_a0=100.0, Mm_a1=-20.0, Mm_a2=-1.0, Mr_b0=20.0, Mr_b1=-0.05)
STATES = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4"]


def derivative(fmu, name, order):
    return fmu.slave.getRealOutputDerivatives([fmu.vr[name]], [order])[0]


@pytest.fixture
def running(unzipped, model_description):
    fmu = Harness(unzipped, model_description).instantiate().initialise(tolerance=1e-12, d34=0.3, **LAWS)
    for k in range(50):
        fmu.slave.doStep(k * 0.01, 0.01)
    yield fmu
    fmu.free()


def test_output_derivatives_follow_their_definitions(running):
    fmu = running
    for i in range(1, 5):
        assert derivative(fmu, f"phi{i}", 1) == fmu.get(f"omega{i}")
        assert derivative(fmu, f"phi{i}", 2) == derivative(fmu, f"omega{i}", 1)
    assert abs(derivative(fmu, "constraint_residual", 1)) < 1e-13
    # Rates against difference quotients of the trajectory itself (FMU state for rewinding).
    names = ["omega1", "omega3", "energy", "rod_force"]
    first = {n: derivative(fmu, n, 1) for n in names}
    second = {n: derivative(fmu, n, 2) for n in names}
    state = fmu.slave.getFMUstate()
    h, t = 1e-5, 0.5  # small enough that the h² term of the quotient is negligible
    before = fmu.get(*names)
    fmu.slave.doStep(t, h)
    after = fmu.get(*names)
    later = {n: derivative(fmu, n, 1) for n in names}
    later_second = {n: derivative(fmu, n, 2) for n in names}
    for n, a, b in zip(names, before, after):
        quotient = (b - a) / h  # first derivative at t + h/2
        expected = first[n] + 0.5 * h * second[n]
        assert abs(quotient - expected) < 1e-6 * max(1.0, abs(first[n])), (n, quotient, expected)
        # (f'(t + h) - f'(t))/h equals the mean of f'' at both ends to O(h²).
        mean_second = 0.5 * (second[n] + later_second[n])
        assert abs((later[n] - first[n]) / h - mean_second) < 1e-4 * max(1.0, abs(mean_second)), n
    fmu.slave.setFMUstate(state)
    fmu.slave.freeFMUstate(state)


def test_after_a_step_the_outputs_see_the_inputs_moved_along_their_derivatives(running):
    """With input derivatives set once, the torque goes on along its polynomial over the
    steps that follow, and the output derivatives at each step's end see the torque there:
    ω4's rates against difference quotients of ω4's own course, and the course against one
    that sets the same polynomial's values again at every step."""
    fmu = running
    fmu.set("M_r", 3.0)
    fmu.slave.setRealInputDerivatives([fmu.vr["M_r"]] * 2, [1, 2], [500.0, -4000.0])
    state = fmu.slave.getFMUstate()
    t, h = 0.5, 1e-4
    for k in range(3):
        fmu.slave.doStep(t + k * 0.01, 0.01)
    t += 0.03
    rates = [derivative(fmu, "omega4", order) for order in (1, 2)]
    before = fmu.get("omega4")
    first_before = rates[0]
    fmu.slave.doStep(t, h)
    after = fmu.get("omega4")
    first_after, second_after = (derivative(fmu, "omega4", order) for order in (1, 2))
    assert abs((after - before) / h - (rates[0] + 0.5 * h * rates[1])) < 1e-6 * max(1.0, abs(rates[0]))
    mean_second = 0.5 * (rates[1] + second_after)
    assert abs((first_after - first_before) / h - mean_second) < 1e-4 * max(1.0, abs(mean_second))
    # The same polynomial, its value and derivatives set again at every step's start.
    moved = fmu.get("omega4")
    fmu.slave.setFMUstate(state)
    fmu.slave.freeFMUstate(state)
    for k, s in enumerate((0.0, 0.01, 0.02)):
        fmu.set("M_r", 3.0 + s * (500.0 - 2000.0 * s))
        fmu.slave.setRealInputDerivatives([fmu.vr["M_r"]] * 2, [1, 2], [500.0 - 4000.0 * s, -4000.0])
        fmu.slave.doStep(0.5 + s, 0.01)
    fmu.slave.doStep(t, h)
    assert fmu.get("omega4") == pytest.approx(moved, rel=1e-9, abs=1e-12)


def test_an_input_reads_back_what_was_set_while_it_moves_along_its_derivatives(running):
    """The FMU integrates with the input moved on along its derivatives, and its getter
    returns the value the master set, after steps, a refused set and a saved state."""
    fmu = running
    fmu.set("M_r", 3.0)
    fmu.set("M_m", -1.5)
    fmu.slave.setRealInputDerivatives([fmu.vr["M_r"], fmu.vr["M_m"]], [1, 2], [500.0, -40.0])
    held = fmu.slave.getFMUstate()
    for k in range(3):
        fmu.slave.doStep(0.5 + k * 0.01, 0.01)
        assert fmu.get("M_r", "M_m") == [3.0, -1.5]
    moved = fmu.get("omega4")
    # The same steps with the input held end elsewhere: it did move.
    fmu.slave.setFMUstate(held)
    assert fmu.get("M_r", "M_m") == [3.0, -1.5]
    fmu.slave.setRealInputDerivatives([fmu.vr["M_r"], fmu.vr["M_m"]], [1, 2], [0.0, 0.0])
    for k in range(3):
        fmu.slave.doStep(0.5 + k * 0.01, 0.01)
    assert fmu.get("omega4") != moved
    fmu.slave.freeFMUstate(held)
    # A refused set leaves the value read back as it was.
    fmu.expect(ERROR, fmu.slave.setReal, [fmu.vr["M_r"]], [float("nan")])
    assert fmu.get("M_r") == 3.0


def test_bad_derivative_requests_are_errors(running):
    fmu = running
    assert "order = 3" in fmu.expect(ERROR, fmu.slave.getRealOutputDerivatives, [fmu.vr["phi1"]], [3])
    assert "not a Real output" in fmu.expect(ERROR, fmu.slave.getRealOutputDerivatives, [fmu.vr["k12"]], [1])
    assert "not an input" in fmu.expect(ERROR, fmu.slave.setRealInputDerivatives, [fmu.vr["phi1"]], [1], [0.0])
    assert "order = 0" in fmu.expect(ERROR, fmu.slave.setRealInputDerivatives, [fmu.vr["M_m"]], [0], [1.0])
    message = fmu.expect(ERROR, fmu.slave.setRealInputDerivatives, [fmu.vr["M_m"], fmu.vr["M_r"]], [1, 1], [1.0, math.nan])
    assert "M_r" in message and "finite" in message


def test_input_derivatives_drive_a_ramp(unzipped, model_description):
    """A torque ramp given as a derivative equals the same ramp sampled finely."""
    def run(h, with_derivative):
        fmu = Harness(unzipped, model_description).instantiate().initialise(tolerance=1e-11)
        for k in range(round(1.0 / h)):
            t = k * h
            fmu.set("M_m", 5.0 * t)
            if with_derivative:
                fmu.slave.setRealInputDerivatives([fmu.vr["M_m"]], [1], [5.0])
            fmu.slave.doStep(t, h)
        values = np.array(fmu.get(*STATES))
        fmu.free()
        return values

    exact = run(0.1, True)
    fine = run(1e-3, False)
    coarse = run(0.1, False)
    assert np.max(np.abs(exact - fine)) < 0.02 * np.max(np.abs(coarse - fine))


def coupled(unzipped, model_description, h, with_derivatives, stop=2.0):
    """Paper case 1 with the laws closed by the master through M_m and M_r (the built-in
    laws off)."""
    fmu = Harness(unzipped, model_description).instantiate().initialise(tolerance=1e-11, builtin_laws=False)
    for k in range(round(stop / h)):
        w1 = fmu.get("omega1")
        fmu.slave.setReal([fmu.vr["M_m"], fmu.vr["M_r"]], [100.0 - 20.0 * w1 - w1 * w1, 20.0 - 0.05 * w1])
        if with_derivatives:
            a1 = derivative(fmu, "omega1", 1)
            fmu.slave.setRealInputDerivatives([fmu.vr["M_m"], fmu.vr["M_r"]], [1, 1],
                                              [(-20.0 - 2.0 * w1) * a1, -0.05 * a1])
        fmu.slave.doStep(k * h, h)
    values = np.array(fmu.get(*STATES))
    fmu.free()
    return values


def test_coupling_orders(unzipped, model_description, report):
    reference = Harness(unzipped, model_description).instantiate().initialise(tolerance=1e-12, **LAWS)
    for k in range(200):
        reference.slave.doStep(k * 0.01, 0.01)
    exact = np.array(reference.get(*STATES))
    reference.free()
    steps = [0.01, 0.005, 0.0025]
    for with_derivatives, (low, high) in ((False, (0.8, 1.2)), (True, (1.7, 2.5))):
        errors = [np.max(np.abs(coupled(unzipped, model_description, h, with_derivatives) - exact)) for h in steps]
        orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
        key = "derivatives" if with_derivatives else "held"
        report[f"coupling_{key}_errors_H_0.01_0.005_0.0025"] = errors
        report[f"coupling_{key}_orders"] = orders
        assert all(low < q < high for q in orders), (key, errors, orders)
