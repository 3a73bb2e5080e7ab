"""FMU states round-trip through FMPy in every state a master can reach: random legal call
sequences (Co-Simulation and Model Exchange, extreme start times, tolerances and parameters
at their ranges' ends) each end with get -> serialize -> deserialize -> set, after which every
variable and the next call must give exactly what the instance gave before."""

import ctypes
import math

from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from test_fmi_api import Harness

START_TIMES = [0.0, 1.5, -3.0, 1e-300, 1e300, -1e300]
TOLERANCES = [None, 1e-13, 1e-10, 1e-6, 0.1]
STEPS = [0.01, 0.1, 1e-9]
SETTINGS = settings(max_examples=300, deadline=None, derandomize=True,
                    suppress_health_check=list(HealthCheck))


def attempt(call, *args):
    """A call's result, or the FMI status of its refusal (a legal call may still be refused
    for its values: a linkage that cannot be assembled, a step past the stop time)."""
    try:
        return call(*args)
    except FMICallException as refusal:
        return ("refused", refusal.status)


def observe(fmu, model_description):
    """Every variable, read one at a time by its type, with refusals as they came."""
    seen = []
    for v in model_description.modelVariables:
        read = {"Real": fmu.getReal, "Boolean": fmu.getBoolean}.get(v.type, fmu.getInteger)
        value = attempt(read, [v.valueReference])
        seen.append(value if isinstance(value, tuple) else [_bits(x) for x in value])
    return seen


def _bits(x):
    # NaN never equals itself; -0.0 equals 0.0: compare what was returned exactly.
    return x.hex() if isinstance(x, float) else x


STATES = 6
INDICATORS = 1


def read_array(call, n):
    """A Model Exchange array call: the values, or the refusal."""
    values = (ctypes.c_double * n)()
    result = attempt(call, values, n)
    return result if isinstance(result, tuple) else list(values)


def continuation(fmu, exchange, time):
    """The next call a master makes, with what it returns."""
    if exchange:
        results = [read_array(fmu.getDerivatives, STATES),
                   read_array(fmu.getEventIndicators, INDICATORS),
                   read_array(fmu.getContinuousStates, STATES)]
        return [r if isinstance(r, tuple) else [_bits(x) for x in r] for r in results]
    return [attempt(fmu.doStep, time, 0.01)]


def parameter_values(model_description):
    """Each tunable or fixed Real parameter with the ends of its range and its start."""
    choices = []
    for v in model_description.modelVariables:
        if v.causality == "parameter" and v.type == "Real":
            ends = [float(x) for x in (v.min, v.max, v.start) if x is not None]
            choices.append((v.name, sorted(set(x for x in ends if math.isfinite(x)))))
    return choices


def sequence(data, model_description, exchange):
    """Draw and run a legal sequence on a fresh instance; return it with its time."""
    harness = Harness(*model_description)
    if exchange:
        harness.slave = FMU2Model(guid=model_description[1].guid, unzipDirectory=model_description[0],
                                  modelIdentifier="CyclicMechanism", instanceName="probe")
    fmu = harness.slave
    fmu.instantiate(callbacks=harness.callbacks)
    start = data.draw(st.sampled_from(START_TIMES), "start")
    stop = data.draw(st.sampled_from([None, start, start + 1.0, start + 100.0]), "stop")
    fmu.setupExperiment(tolerance=data.draw(st.sampled_from(TOLERANCES), "tolerance"),
                        startTime=start, stopTime=stop)
    time = start
    if data.draw(st.booleans(), "stay instantiated"):
        return harness, time
    fmu.enterInitializationMode()
    for name, values in data.draw(st.lists(st.sampled_from(parameter_values(model_description[1])),
                                           max_size=3), "parameters"):
        attempt(harness.set, name, data.draw(st.sampled_from(values), name))
    if data.draw(st.booleans(), "read in initialization mode"):
        attempt(fmu.getReal, [harness.vr["phi1"], harness.vr["rod_force"]])
    if data.draw(st.integers(0, 9), "stay initialising") == 0:
        return harness, time
    if isinstance(attempt(fmu.exitInitializationMode), tuple):
        return harness, time  # the parameters admit no assembly: still initialising
    for _ in range(data.draw(st.integers(0, 4), "steps")):
        h = data.draw(st.sampled_from(STEPS), "h")
        if exchange:
            _model_exchange_step(data, fmu, time, h)
        elif stop is None or time + h <= stop:
            if data.draw(st.booleans(), "input"):
                attempt(harness.set, "M_m", data.draw(st.sampled_from([-1e12, 0.0, 5.0, 1e12]), "M_m"))
            if not isinstance(attempt(fmu.doStep, time, h), tuple):
                time += h
    if data.draw(st.integers(0, 4), "terminate") == 0:
        fmu.terminate()
    return harness, time


def _model_exchange_step(data, fmu, time, h):
    """An event iteration or an integrator step as a master makes them."""
    if data.draw(st.booleans(), "event"):
        attempt(fmu.enterEventMode)
        attempt(fmu.newDiscreteStates)
        return
    attempt(fmu.enterContinuousTimeMode)
    x = read_array(fmu.getContinuousStates, STATES)
    dx = read_array(fmu.getDerivatives, STATES)
    if isinstance(x, tuple) or isinstance(dx, tuple):
        return
    attempt(fmu.setTime, time + h)
    moved = (ctypes.c_double * STATES)(*[a + h * b for a, b in zip(x, dx)])
    attempt(fmu.setContinuousStates, moved, STATES)
    attempt(fmu.completedIntegratorStep)


def round_trip(harness, model_description, exchange, time):
    fmu = harness.slave
    state = fmu.getFMUstate()
    buffer = fmu.serializeFMUstate(state)
    before = observe(fmu, model_description)
    after_next = continuation(fmu, exchange, time)
    restored = fmu.deSerializeFMUstate(buffer)  # raises if the FMU refuses its own buffer
    fmu.setFMUstate(restored)
    assert bytes(fmu.serializeFMUstate(fmu.getFMUstate())) == bytes(buffer)
    assert observe(fmu, model_description) == before
    assert continuation(fmu, exchange, time) == after_next
    harness.free()


@SETTINGS
@given(data=st.data())
def test_co_simulation_states_round_trip(unzipped, model_description, data):
    harness, time = sequence(data, (unzipped, model_description), exchange=False)
    round_trip(harness, model_description, False, time)


@SETTINGS
@given(data=st.data())
def test_model_exchange_states_round_trip(unzipped, model_description, data):
    harness, time = sequence(data, (unzipped, model_description), exchange=True)
    round_trip(harness, model_description, True, time)
