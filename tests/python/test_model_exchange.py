"""Model Exchange (docs/model.md §6) through FMPy, as a master with its own integrator uses
it: CVODE and forward Euler from `simulate_fmu(fmi_type="ModelExchange")`, and the
low-level FMU2Model for the state machine, argument checks, FMU states and the exact
directional derivatives."""

import ctypes

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model, FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

import reference
from conftest import STATES, simulate, states
from test_fmi_api import ERROR
from test_linkages import GEOMETRIES

CONTINUOUS = ["phi1", "loop_angle", "phi4", "omega1", "loop_speed", "omega4"]
DERIVATIVES = [f"der({name})" for name in CONTINUOUS]
FREE_RUN = reference.FREE_RUN


def exchange(unzipped, values, stop_time, interval, tolerance=1e-10, outputs=STATES, **options):
    return fmpy.simulate_fmu(unzipped, fmi_type="ModelExchange", start_values=values,
                             stop_time=stop_time, output_interval=interval,
                             relative_tolerance=tolerance, output=outputs, record_events=False,
                             **options)


def scaled_error(result, expected):
    """|error| per state in units of that state's scale max(1, max|y|)."""
    scale = np.maximum(1.0, np.abs(expected).max(axis=0))
    return np.abs(states(result) - expected) / scale


@pytest.fixture(scope="module")
def paper_cases():
    times = np.linspace(0.0, 10.0, 1001)
    cases = {}
    for case, k34 in (("case1", 100.0), ("case2", 40.0)):
        values = dict(reference.PAPER_LAWS, k34=k34)
        cases[case] = (values, reference.solve(reference.Params(**values), times))
    return cases


@pytest.mark.parametrize("case", ["case1", "case2"])
def test_cvode_reproduces_the_paper_cases(unzipped, paper_cases, case, report):
    values, expected = paper_cases[case]
    result = exchange(unzipped, values, 10.0, 0.01, outputs=STATES + ["constraint_residual"])
    error = scaled_error(result, expected)
    report[f"me_cvode_{case}_max_scaled_error"] = float(error.max())
    report[f"me_cvode_{case}_max_abs_error"] = float(np.abs(states(result) - expected).max())
    assert error.max() < 1e-6, error.max(axis=0)
    # The follower's angle is computed in closed form: the loop closes to rounding.
    assert np.abs(result["constraint_residual"]).max() < 1e-14


def test_cvode_error_is_the_integrators_and_converges(unzipped, paper_cases, report):
    """The error above is CVODE's: it falls with the master's tolerance."""
    values, expected = paper_cases["case1"]
    errors = [scaled_error(exchange(unzipped, values, 10.0, 0.01, tolerance=tol), expected).max()
              for tol in (1e-8, 1e-10, 1e-12)]
    report["me_cvode_case1_scaled_error_at_1e-8_1e-10_1e-12"] = [float(e) for e in errors]
    assert errors[0] > 10 * errors[1] > 100 * errors[2]


def test_model_exchange_agrees_with_co_simulation(unzipped, paper_cases, report):
    values, _ = paper_cases["case1"]
    me = exchange(unzipped, values, 10.0, 0.01, tolerance=1e-12)
    cs = simulate(unzipped, values, 10.0, 0.01, tolerance=1e-10)
    scale = np.maximum(1.0, np.abs(states(cs)).max(axis=0))
    gap = float((np.abs(states(me) - states(cs)) / scale).max())
    report["me_cvode_1e-12_vs_cs_1e-10_max_scaled_gap"] = gap
    assert gap < 1e-7


def test_free_run_stays_on_the_constraint(unzipped, report):
    outputs = ["energy", "constraint_residual", "omega1"]
    drifts = {}
    for tolerance in (1e-10, 1e-12):
        result = exchange(unzipped, FREE_RUN, 100.0, 0.01, tolerance=tolerance, outputs=outputs)
        residual = float(np.abs(result["constraint_residual"]).max())
        energy = result["energy"]
        drifts[tolerance] = float(np.abs(energy - energy[0]).max() / energy[0])
        report[f"me_free_run_100s_rtol_{tolerance:g}_max_residual_m"] = residual
        report[f"me_free_run_100s_rtol_{tolerance:g}_energy_drift"] = drifts[tolerance]
        assert residual <= 1e-10
        assert np.ptp(result["omega1"]) > 1.0
    # CVODE's BDF damps oscillations: the drift is the integrator's, and falls with its
    # tolerance (DOP853 in Co-Simulation keeps it below 1e-8 at 1e-10).
    assert drifts[1e-12] < 1e-6 and drifts[1e-12] < drifts[1e-10] / 10


def test_forward_euler_converges_at_order_one(unzipped, paper_cases, report):
    values, _ = paper_cases["case1"]
    times = np.linspace(0.0, 1.0, 101)
    expected = reference.solve(reference.Params(**values), times)
    errors = []
    for step in (4e-4, 2e-4, 1e-4):
        result = exchange(unzipped, values, 1.0, step, solver="Euler", step_size=step)
        picked = np.round(times / step).astype(int)
        errors.append(float(np.abs(states(result)[picked] - expected).max()))
    orders = [float(np.log2(a / b)) for a, b in zip(errors, errors[1:])]
    report["me_euler_errors_4e-4_2e-4_1e-4"] = errors
    assert all(0.9 < order < 1.1 for order in orders), orders


@pytest.mark.parametrize("name", ["non_grashof", "double_crank"])
def test_linkages_through_their_dead_points(unzipped, name, report):
    """The crank's dead points are crossed by handing the lead to the rocker at the event
    indicator's zero; a double crank winds both angles without any event."""
    values = dict(GEOMETRIES[name], **reference.NO_LAWS, omega1_0=6.0, twist12_0=0.3)
    times = np.linspace(0.0, 10.0, 1001)
    expected = reference.solve(reference.Params(**values), times, rtol=1e-13)
    errors = []
    for tolerance in (1e-10, 1e-12):
        result = exchange(unzipped, values, 10.0, 0.01, tolerance=tolerance,
                          outputs=STATES + ["loop_chart", "constraint_residual"])
        errors.append(float(scaled_error(result, expected).max()))
        assert np.abs(result["constraint_residual"]).max() < 1e-14
    handovers = int(np.sum(np.diff(result["loop_chart"]) != 0))
    report[f"me_{name}_max_scaled_error_at_1e-10_1e-12"] = errors
    report[f"me_{name}_handovers"] = handovers
    # The violent free swing of the non-Grashof linkage is hard for CVODE (Co-Simulation's
    # DOP853 is within 5e-9 of the reference): the error is the master integrator's, and
    # falls with its tolerance.
    assert errors[1] < 1e-5 and errors[1] < errors[0] / 10, errors
    if name == "non_grashof":
        assert handovers >= 2, "the crank reverses: the lead must change hands"
    else:
        assert handovers == 0


def test_cvode_hands_over_at_every_dead_point(unzipped):
    """The handover path alone, cheap enough for the valgrind run: a non-Grashof linkage
    swings through the crank's dead points; every output stays finite and on the loop."""
    values = dict(GEOMETRIES["non_grashof"], **reference.NO_LAWS, omega1_0=6.0, twist12_0=0.3)
    result = exchange(unzipped, values, 3.0, 0.01, tolerance=1e-8,
                      outputs=STATES + ["loop_chart", "constraint_residual", "rod_force"])
    assert np.sum(np.diff(result["loop_chart"]) != 0) >= 2
    assert np.abs(result["constraint_residual"]).max() < 1e-14
    assert all(np.isfinite(result[name]).all() for name in STATES + ["rod_force"])


class Model:
    """An FMU2Model (or FMU2Slave) with collected log messages."""

    def __init__(self, unzipped, model_description, kind=FMU2Model):
        self.vr = {v.name: v.valueReference for v in model_description.modelVariables}
        self.messages = []
        self._logger = fmi2CallbackLoggerTYPE(lambda env, name, status, cat, msg:
                                              self.messages.append(msg.decode()))
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = self._logger
        self.fmu = kind(guid=model_description.guid, unzipDirectory=unzipped,
                        modelIdentifier="CyclicMechanism", instanceName="probe")
        self.fmu.instantiate(callbacks=callbacks)

    def start(self, **values):
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for name, value in values.items():
            if isinstance(value, bool):
                self.fmu.setBoolean([self.vr[name]], [value])
            else:
                self.fmu.setReal([self.vr[name]], [value])
        self.fmu.exitInitializationMode()
        if isinstance(self.fmu, FMU2Model):
            assert not self.fmu.newDiscreteStates()[0]
            self.fmu.enterContinuousTimeMode()
        return self

    def states(self):
        x = (ctypes.c_double * 6)()
        self.fmu.getContinuousStates(x, 6)
        return np.array(x)

    def set_states(self, x):
        self.fmu.setContinuousStates((ctypes.c_double * 6)(*x), 6)

    def derivatives(self):
        dx = (ctypes.c_double * 6)()
        self.fmu.getDerivatives(dx, 6)
        return np.array(dx)

    def real(self, names):
        return np.array(self.fmu.getReal([self.vr[n] for n in names]))

    def expect_error(self, call, *args):
        before = len(self.messages)
        with pytest.raises(FMICallException) as failure:
            call(*args)
        assert failure.value.status == ERROR
        return " | ".join(self.messages[before:])


@pytest.fixture
def model(unzipped, model_description):
    m = Model(unzipped, model_description)
    yield m
    m.fmu.freeInstance()


def test_derivatives_match_the_variables_and_states_round_trip(model):
    model.start(**reference.PAPER_LAWS, omega2_0=2.0)
    x = model.states()
    assert np.allclose(x, model.real(CONTINUOUS), rtol=0, atol=0)
    assert np.array_equal(model.derivatives(), model.real(DERIVATIVES))
    moved = x + np.array([0.01, 0.02, -0.01, 0.5, 0.3, -0.2])
    model.set_states(moved)
    assert np.array_equal(model.states(), moved)
    # The follower follows: the loop stays closed, the outputs move with the states.
    assert abs(model.real(["constraint_residual"])[0]) < 1e-15
    assert model.real(["phi2"])[0] == moved[1] and model.real(["omega2"])[0] == moved[4]
    nominals = (ctypes.c_double * 6)()
    model.fmu.getNominalsOfContinuousStates(nominals, 6)
    assert list(nominals) == [1.0] * 6


def test_bad_states_and_wrong_calls_are_refused_and_change_nothing(model):
    model.start(**reference.PAPER_LAWS)
    x = model.states()
    bad = x.copy()
    bad[4] = np.nan
    message = model.expect_error(model.set_states, bad)
    assert "loop_speed" in message and "finite" in message
    assert np.array_equal(model.states(), x)
    message = model.expect_error(model.fmu.fmi2GetDerivatives, model.fmu.component,
                                 (ctypes.c_double * 5)(), 5)
    assert "nx = 5" in message and "6 continuous states" in message
    do_step = model.fmu.dll.fmi2DoStep
    do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
    assert do_step(model.fmu.component, 0.0, 0.1, 1) == ERROR
    assert "Co-Simulation function" in model.messages[-1]
    message = model.expect_error(model.fmu.fmi2NewDiscreteStates, model.fmu.component, None)
    assert "not allowed in state continuous-time mode" in message
    message = model.expect_error(model.fmu.setTime, float("inf"))
    assert "finite" in message
    # A parameter is fixed after initialisation; an input is not.
    message = model.expect_error(model.fmu.setReal, [model.vr["k34"]], [50.0])
    assert "k34" in message and "fixed" in message
    model.fmu.setReal([model.vr["M_m"]], [5.0])
    assert np.array_equal(model.states(), x)


def test_co_simulation_refuses_model_exchange_calls(unzipped, model_description):
    slave = Model(unzipped, model_description, kind=FMU2Slave).start()
    set_time = slave.fmu.dll.fmi2SetTime
    set_time.argtypes, set_time.restype = [ctypes.c_void_p, ctypes.c_double], ctypes.c_int
    assert set_time(slave.fmu.component, 0.5) == ERROR
    assert "Model Exchange function" in slave.messages[-1]
    slave.fmu.doStep(0.0, 0.01)
    slave.fmu.freeInstance()


def test_fmu_state_restores_model_exchange_exactly(model):
    model.start(**reference.PAPER_LAWS, omega2_0=2.0)
    model.fmu.setTime(0.3)
    model.set_states(model.states() + 0.01)
    saved = model.fmu.getFMUstate()
    serialized = model.fmu.serializeFMUstate(saved)
    before = (model.states(), model.derivatives(), model.real(["rod_force", "phi3"]))
    model.set_states(model.states() + 0.2)
    model.fmu.setFMUstate(model.fmu.deSerializeFMUstate(serialized))
    after = (model.states(), model.derivatives(), model.real(["rod_force", "phi3"]))
    for a, b in zip(before, after):
        assert np.array_equal(a, b)
    # A forged state (checksum recomputed) whose x no longer gives the plant's state
    # is refused by value.
    forged = bytearray(serialized)
    forged[-16:-8] = np.float64(99.0).tobytes()  # the last state, omega4
    reseal(forged)
    before = len(model.messages)
    with pytest.raises(FMICallException):
        model.fmu.deSerializeFMUstate(bytes(forged))
    assert "continuous states do not give the plant's state" in model.messages[before]
    model.fmu.freeFMUstate(saved)


def reseal(buffer, header=36):
    """Recompute the serialized state's checksum (FNV-1a 64 of the payload, after the
    36 bytes of the header: magic, format version, 128-bit interface hash, length)."""
    h = 0xcbf29ce484222325
    for byte in buffer[header:-8]:
        h = ((h ^ byte) * 0x100000001b3) % 2**64
    buffer[-8:] = h.to_bytes(8, "little")


def random_point(rng):
    """Random geometry that assembles, random state, laws, dampers and inputs."""
    while True:
        l, l2, l3, L = rng.uniform(0.1, 1.0, 4)
        values = dict(l=l, l2=l2, l3=l3, L=L, phi2_0=rng.uniform(-3, 3),
                      phi3_guess=rng.choice([-1.5, 1.5]), omega1_0=rng.normal(), omega2_0=rng.normal(),
                      omega4_0=rng.normal(), twist12_0=rng.normal(0, 0.2), twist34_0=rng.normal(0, 0.2),
                      d12=rng.uniform(0, 1), d34=rng.uniform(0, 1), c4=rng.uniform(0, 1),
                      **reference.PAPER_LAWS)
        p = reference.Params(**values)
        try:
            reference.initial_state(p)
        except (ValueError, IndexError):
            continue
        return values


def test_directional_derivatives_are_exact(unzipped, model_description, report):
    """Against central differences, at random states of random geometries: the Jacobians of
    the derivatives and outputs with respect to states and inputs."""
    rng = np.random.default_rng(7)
    unknowns = DERIVATIVES + STATES + ["rod_force", "energy"]
    worst, points = 0.0, 0
    for _ in range(12):
        model = Model(unzipped, model_description)
        try:
            model.start(**random_point(rng))
        except FMICallException:
            model.fmu.freeInstance()  # a change point or a dead point at the start
            continue
        model.fmu.setReal([model.vr["M_m"], model.vr["M_r"]], list(rng.normal(size=2)))
        model.set_states(model.states() + rng.normal(0, 0.05, 6))
        x = model.states()
        for known in CONTINUOUS + ["M_m", "M_r"]:
            exact = np.array(model.fmu.getDirectionalDerivative(
                [model.vr[u] for u in unknowns], [model.vr[known]], [1.0]))
            h = 1e-6 * max(1.0, abs(model.real([known])[0]))

            def values_at(delta):
                if known in CONTINUOUS:
                    moved = x.copy()
                    moved[CONTINUOUS.index(known)] += delta
                    model.set_states(moved)
                else:
                    base = model.real([known])[0]
                    model.fmu.setReal([model.vr[known]], [base + delta])
                out = model.real(unknowns)
                if known in CONTINUOUS:
                    model.set_states(x)
                else:
                    model.fmu.setReal([model.vr[known]], [base])
                return out

            plus, minus = values_at(h), values_at(-h)
            estimate = (plus - minus) / (2 * h)
            scale = np.maximum(1.0, np.abs(exact)) + 1e-9 * np.abs(plus) / h
            relative = np.abs(exact - estimate) / scale
            worst = max(worst, float(relative.max()))
            assert relative.max() < 1e-6, (known, dict(zip(unknowns, relative)))
        model.fmu.freeInstance()
        points += 1
    report["directional_derivative_worst_relative_gap"] = worst
    assert points >= 8, points


def test_co_simulation_directional_derivatives(unzipped, model_description):
    """In Co-Simulation the knowns are the inputs: no output feels them directly (as the
    dependencies say), the accelerations of bodies 1 and 4 do, through 1/J."""
    slave = Model(unzipped, model_description, kind=FMU2Slave).start(**reference.PAPER_LAWS)
    slave.fmu.doStep(0.0, 0.1)
    outputs = [v.name for v in model_description.modelVariables
               if v.causality == "output" and v.type == "Real"]
    for known, accelerated, inertia in (("M_m", "der(omega1)", 0.5), ("M_r", "der(omega4)", 0.7)):
        column = slave.fmu.getDirectionalDerivative([slave.vr[o] for o in outputs], [slave.vr[known]], [1.0])
        assert list(column) == [0.0] * len(outputs)
        (rate,) = slave.fmu.getDirectionalDerivative([slave.vr[accelerated]], [slave.vr[known]], [1.0])
        assert abs(rate - (1 if known == "M_m" else -1) / inertia) < 1e-15
    with pytest.raises(FMICallException):
        slave.fmu.getDirectionalDerivative([slave.vr["phi2"]], [slave.vr["phi1"]], [1.0])
    assert "the knowns are the inputs (in Co-Simulation)" in slave.messages[-1]
    slave.fmu.freeInstance()


def test_the_event_indicator_is_readable_as_a_variable(model, unzipped, model_description):
    """`handover_indicator` is the event indicator, in Model Exchange at any state the master
    sets and in Co-Simulation after every step."""
    model.start(**reference.PAPER_LAWS, omega2_0=2.0)
    z = (ctypes.c_double * 1)()
    for shift in (0.0, 0.3, 0.6, 0.9):
        x = model.states()
        x[1] += shift
        model.set_states(x)
        model.fmu.getEventIndicators(z, 1)
        assert model.real(["handover_indicator"])[0] == z[0]
    slave = Model(unzipped, model_description, kind=FMU2Slave).start(omega2_0=2.0)
    values = []
    for k in range(50):
        slave.fmu.doStep(k * 0.02, 0.02)
        values.append(slave.real(["handover_indicator"])[0])
    assert all(np.isfinite(values)) and len(set(values)) > 1
    slave.fmu.freeInstance()
