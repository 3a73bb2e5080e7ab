"""The FMI 3.0 conformance matrix: every exported fmi3 function that takes an instance, in
every state this FMU reaches, for both interfaces, called with valid arguments on a fresh
instance through raw ctypes. fmi3OK where the FMI 3.0 state tables allow the call (Model
Exchange section 3.2, Co-Simulation section 4.2), fmi3Error with a message that names the
function and the state where they do not. The matrices are typed from the standard's
tables, not read from the FMU's code.

Columns the FMU never enters are left out: Configuration, Reconfiguration, Clock Activation
and Intermediate Update modes (no structural parameters, clocks or intermediate update),
Error (a refused argument leaves the instance where it was) and Fatal (only a bug gets
there). Functions of features the FMU does not declare (per-element dependencies, clocked
discrete states, configuration mode, scheduled execution) are refused with that reason
where the state allows them."""

import ctypes
import subprocess
from ctypes import (CFUNCTYPE, POINTER, byref, c_bool, c_char, c_char_p, c_double, c_int32,
                    c_int64, c_size_t, c_uint, c_uint64, c_void_p)

import pytest

from test_conformance import matrix

OK, DISCARD, ERROR = 0, 2, 3
LOG = CFUNCTYPE(None, c_void_p, c_uint, c_char_p, c_char_p)
N_STATES = 6

# x: allowed, .: not allowed.
# FMI 3.0 has no state after a Discard of its own (FMI 2.0's stepFailed): "fmi3Discard: the
# call was not successful and the FMU is in the same state as before the call", Step Mode
# for fmi3DoStep (test_a_discarded_step_leaves_step_mode).
CO_SIMULATION_COLUMNS = ["Instantiated", "InitializationMode", "EventMode", "StepMode",
                         "Terminated"]
CO_SIMULATION = """
fmi3SetDebugLogging                   x x x x x
fmi3EnterInitializationMode           x . . . .
fmi3ExitInitializationMode            . x . . .
fmi3EnterEventMode                    . . . x .
fmi3Terminate                         . . x x .
fmi3Reset                             x x x x x
fmi3GetFloat32                        . x x x x
fmi3GetFloat64                        . x x x x
fmi3GetInt8                           . x x x x
fmi3GetUInt8                          . x x x x
fmi3GetInt16                          . x x x x
fmi3GetUInt16                         . x x x x
fmi3GetInt32                          . x x x x
fmi3GetUInt32                         . x x x x
fmi3GetInt64                          . x x x x
fmi3GetUInt64                         . x x x x
fmi3GetBoolean                        . x x x x
fmi3GetString                         . x x x x
fmi3GetBinary                         . x x x x
fmi3GetClock                          . . x . .
fmi3SetFloat32                        x x x x .
fmi3SetFloat64                        x x x x .
fmi3SetInt8                           x x x x .
fmi3SetUInt8                          x x x x .
fmi3SetInt16                          x x x x .
fmi3SetUInt16                         x x x x .
fmi3SetInt32                          x x x x .
fmi3SetUInt32                         x x x x .
fmi3SetInt64                          x x x x .
fmi3SetUInt64                         x x x x .
fmi3SetBoolean                        x x x x .
fmi3SetString                         x x x x .
fmi3SetBinary                         x x x x .
fmi3SetClock                          . . x . .
fmi3GetNumberOfVariableDependencies   x x x x x
fmi3GetVariableDependencies           x x x x x
fmi3GetFMUState                       x x x x x
fmi3SetFMUState                       x x x x x
fmi3FreeFMUState                      x x x x x
fmi3SerializedFMUStateSize            x x x x x
fmi3SerializeFMUState                 x x x x x
fmi3DeserializeFMUState               x x x x x
fmi3GetDirectionalDerivative          . x x x x
fmi3GetAdjointDerivative              . x x x x
fmi3EnterConfigurationMode            x . x x .
fmi3ExitConfigurationMode             . . . . .
fmi3GetIntervalDecimal                . . x . .
fmi3GetIntervalFraction               . . x . .
fmi3GetShiftDecimal                   . . x . .
fmi3GetShiftFraction                  . . x . .
fmi3SetIntervalDecimal                x . x . .
fmi3SetIntervalFraction               x . x . .
fmi3SetShiftDecimal                   x . . . .
fmi3SetShiftFraction                  x . . . .
fmi3EvaluateDiscreteStates            . . x x .
fmi3UpdateDiscreteStates              . . x . .
fmi3EnterStepMode                     . . x . .
fmi3GetOutputDerivatives              . . x x x
fmi3DoStep                            . . . x .
fmi3ActivateModelPartition            . . . . .
"""

MODEL_EXCHANGE_COLUMNS = ["Instantiated", "InitializationMode", "EventMode",
                          "ContinuousTimeMode", "Terminated"]
MODEL_EXCHANGE = """
fmi3SetDebugLogging                   x x x x x
fmi3EnterInitializationMode           x . . . .
fmi3ExitInitializationMode            . x . . .
fmi3EnterEventMode                    . . . x .
fmi3Terminate                         . . x x .
fmi3Reset                             x x x x x
fmi3GetFloat32                        . x x x x
fmi3GetFloat64                        . x x x x
fmi3GetInt8                           . x x x x
fmi3GetUInt8                          . x x x x
fmi3GetInt16                          . x x x x
fmi3GetUInt16                         . x x x x
fmi3GetInt32                          . x x x x
fmi3GetUInt32                         . x x x x
fmi3GetInt64                          . x x x x
fmi3GetUInt64                         . x x x x
fmi3GetBoolean                        . x x x x
fmi3GetString                         . x x x x
fmi3GetBinary                         . x x x x
fmi3GetClock                          . . x . .
fmi3SetFloat32                        x x x x .
fmi3SetFloat64                        x x x x .
fmi3SetInt8                           x x x . .
fmi3SetUInt8                          x x x . .
fmi3SetInt16                          x x x . .
fmi3SetUInt16                         x x x . .
fmi3SetInt32                          x x x . .
fmi3SetUInt32                         x x x . .
fmi3SetInt64                          x x x . .
fmi3SetUInt64                         x x x . .
fmi3SetBoolean                        x x x . .
fmi3SetString                         x x x . .
fmi3SetBinary                         x x x . .
fmi3SetClock                          . . x . .
fmi3GetNumberOfVariableDependencies   x x x x x
fmi3GetVariableDependencies           x x x x x
fmi3GetFMUState                       x x x x x
fmi3SetFMUState                       x x x x x
fmi3FreeFMUState                      x x x x x
fmi3SerializedFMUStateSize            x x x x x
fmi3SerializeFMUState                 x x x x x
fmi3DeserializeFMUState               x x x x x
fmi3GetDirectionalDerivative          . x x x x
fmi3GetAdjointDerivative              . x x x x
fmi3EnterConfigurationMode            x . x . .
fmi3ExitConfigurationMode             . . . . .
fmi3GetIntervalDecimal                . . x . .
fmi3GetIntervalFraction               . . x . .
fmi3GetShiftDecimal                   . . x . .
fmi3GetShiftFraction                  . . x . .
fmi3SetIntervalDecimal                x . x . .
fmi3SetIntervalFraction               x . x . .
fmi3SetShiftDecimal                   x . . . .
fmi3SetShiftFraction                  x . . . .
fmi3EvaluateDiscreteStates            . . x x .
fmi3UpdateDiscreteStates              . . x . .
fmi3EnterContinuousTimeMode           . . x . .
fmi3CompletedIntegratorStep           . . . x .
fmi3SetTime                           . . x x .
fmi3SetContinuousStates               . . . x .
fmi3GetContinuousStateDerivatives     . x x x x
fmi3GetEventIndicators                . x x x x
fmi3GetContinuousStates               . x x x x
fmi3GetNominalsOfContinuousStates     . x x x x
fmi3GetNumberOfEventIndicators        x x x x x
fmi3GetNumberOfContinuousStates       x x x x x
fmi3ActivateModelPartition            . . . . .
"""

STATE_WORDS = {
    "Instantiated": "instantiated",
    "InitializationMode": "initialization mode",
    "EventMode": "event mode",
    "StepMode": "step mode",
    "Terminated": "terminated",
    "ContinuousTimeMode": "continuous-time mode",
}

# Allowed in the state, and refused for the feature the FMU does not declare.
UNDECLARED = {
    "fmi3GetNumberOfVariableDependencies": "providesPerElementDependencies",
    "fmi3GetVariableDependencies": "providesPerElementDependencies",
    "fmi3EnterConfigurationMode": "no structural parameters",
    "fmi3EvaluateDiscreteStates": "providesEvaluateDiscreteStates",
}

# A motor law with positive feedback: ω1 runs away within about 0.05 s, and a step fails.
RUNAWAY = {"Mm_a2": 1.0, "omega1_0": 10.0}


class Probe:
    """One fresh FMI 3.0 instance, driven to a state, with its log."""

    def __init__(self, library, token, vr, interface):
        self.lib, self.vr, self.messages = library, vr, []
        self.time = 0.0
        self.x = (c_double * N_STATES)()
        self._log = LOG(lambda env, status, category, message:
                        self.messages.append(message.decode()))
        if interface == "CoSimulation":
            self.lib.fmi3InstantiateCoSimulation.restype = c_void_p
            self.c = c_void_p(self.lib.fmi3InstantiateCoSimulation(
                b"conformance", token.encode(), b"", c_bool(False), c_bool(True),
                c_bool(True), c_bool(True), None, c_size_t(0), None, self._log, None))
        else:
            self.lib.fmi3InstantiateModelExchange.restype = c_void_p
            self.c = c_void_p(self.lib.fmi3InstantiateModelExchange(
                b"conformance", token.encode(), b"", c_bool(False), c_bool(True), None,
                self._log))
        assert self.c.value
        # Logging on (FMI 3.0 calls no logger otherwise), but not every call and step.
        quiet = (c_char_p * 2)(b"logCalls", b"logSolver")
        self.must("fmi3SetDebugLogging", c_bool(False), c_size_t(2), quiet)

    def call(self, name, *args):
        return getattr(self.lib, name)(self.c, *args)

    def must(self, name, *args):
        status = self.call(name, *args)
        assert status == OK, (name, self.messages[-1:])

    def refs(self, *names):
        return (c_uint * len(names))(*(self.vr[n] for n in names))

    def enter_initialization(self):
        self.must("fmi3EnterInitializationMode", c_bool(True), c_double(1e-8), c_double(0.0),
                  c_bool(False), c_double(0.0))

    def initialise(self, parameters=None):
        self.enter_initialization()
        for name, value in (parameters or {}).items():
            self.must("fmi3SetFloat64", self.refs(name), c_size_t(1), (c_double * 1)(value),
                      c_size_t(1))
        self.must("fmi3ExitInitializationMode")

    def step(self, h):
        flags = [c_bool() for _ in range(3)]
        last = c_double()
        status = self.call("fmi3DoStep", c_double(self.time), c_double(h), c_bool(True),
                           *(byref(f) for f in flags), byref(last))
        return status, last.value

    def free(self):
        self.lib.fmi3FreeInstance(self.c)


def reach(probe, state, interface):
    """Drive a fresh instance into `state` as a master would."""
    if state == "Instantiated":
        return
    if state == "InitializationMode":
        probe.enter_initialization()
        return
    probe.initialise()
    if interface == "CoSimulation" and state in ("StepMode", "Terminated"):
        probe.must("fmi3EnterStepMode")
        status, _ = probe.step(0.01)
        assert status == OK
        probe.time = 0.01
    if state == "ContinuousTimeMode":
        flags = [c_bool() for _ in range(5)]
        probe.must("fmi3UpdateDiscreteStates", *(byref(f) for f in flags), byref(c_double()))
        probe.must("fmi3EnterContinuousTimeMode")
        probe.must("fmi3GetContinuousStates", probe.x, c_size_t(N_STATES))
    elif state == "Terminated":
        probe.must("fmi3Terminate")


def saved_state(probe):
    state = c_void_p()
    probe.call("fmi3GetFMUState", byref(state))
    return state


def serialized(probe):
    state, size = saved_state(probe), c_size_t()
    probe.call("fmi3SerializedFMUStateSize", state, byref(size))
    buffer = (c_char * size.value)()
    probe.call("fmi3SerializeFMUState", state, buffer, size)
    return buffer, size


def valid_call(probe, name):
    """Call `name` with arguments that are valid whenever the state allows the call."""
    reals = c_double * 1
    one, none = c_size_t(1), c_size_t(0)
    if name == "fmi3SetDebugLogging":
        return probe.call(name, c_bool(True), none, None)
    if name == "fmi3EnterInitializationMode":
        return probe.call(name, c_bool(True), c_double(1e-8), c_double(0.0), c_bool(False),
                          c_double(0.0))
    if name in ("fmi3ExitInitializationMode", "fmi3EnterEventMode", "fmi3Terminate",
                "fmi3Reset", "fmi3EnterConfigurationMode", "fmi3ExitConfigurationMode",
                "fmi3EvaluateDiscreteStates", "fmi3EnterContinuousTimeMode",
                "fmi3EnterStepMode"):
        return probe.call(name)
    if name == "fmi3GetFloat64":
        return probe.call(name, probe.refs("phi1"), one, reals(), one)
    if name == "fmi3GetInt32":
        return probe.call(name, probe.refs("n_steps"), one, (c_int32 * 1)(), one)
    if name == "fmi3GetInt64":
        return probe.call(name, probe.refs("linkage_class"), one, (c_int64 * 1)(), one)
    if name == "fmi3GetBoolean":
        return probe.call(name, probe.refs("builtin_laws"), one, (c_bool * 1)(), one)
    if name == "fmi3SetFloat64":
        return probe.call(name, probe.refs("M_m"), one, reals(0.0), one)
    if name == "fmi3SetInt64":
        # The tunable branch at change points: settable wherever discrete values are.
        return probe.call(name, probe.refs("change_point_branch"), one, (c_int64 * 1)(1), one)
    if name.startswith(("fmi3Get", "fmi3Set")) and name[7:] in (
            "Float32", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "UInt64",
            "Boolean", "String"):
        return probe.call(name, None, none, None, none)  # no variable settable in every state
    if name in ("fmi3GetBinary", "fmi3SetBinary"):
        return probe.call(name, None, none, None, None, none)
    if name in ("fmi3GetClock", "fmi3SetClock", "fmi3GetShiftDecimal",
                "fmi3SetIntervalDecimal", "fmi3SetShiftDecimal"):
        return probe.call(name, None, none, None)
    if name in ("fmi3GetIntervalDecimal", "fmi3GetShiftFraction", "fmi3SetIntervalFraction",
                "fmi3SetShiftFraction"):
        return probe.call(name, None, none, None, None)
    if name == "fmi3GetIntervalFraction":
        return probe.call(name, None, none, None, None, None)
    if name == "fmi3GetNumberOfVariableDependencies":
        return probe.call(name, c_uint(probe.vr["phi1"]), byref(c_size_t()))
    if name == "fmi3GetVariableDependencies":
        return probe.call(name, c_uint(probe.vr["phi1"]), None, None, None, None, none)
    if name == "fmi3GetFMUState":
        return probe.call(name, byref(c_void_p()))
    if name == "fmi3SetFMUState":
        return probe.call(name, saved_state(probe))
    if name == "fmi3FreeFMUState":
        return probe.call(name, byref(saved_state(probe)))
    if name == "fmi3SerializedFMUStateSize":
        return probe.call(name, saved_state(probe), byref(c_size_t()))
    if name == "fmi3SerializeFMUState":
        state, size = saved_state(probe), c_size_t()
        probe.call("fmi3SerializedFMUStateSize", state, byref(size))
        return probe.call(name, state, (c_char * size.value)(), size)
    if name == "fmi3DeserializeFMUState":
        buffer, size = serialized(probe)
        return probe.call(name, buffer, size, byref(c_void_p()))
    if name in ("fmi3GetDirectionalDerivative", "fmi3GetAdjointDerivative"):
        return probe.call(name, probe.refs("phi1"), one, probe.refs("M_m"), one, reals(1.0), one,
                          reals(), one)
    if name == "fmi3UpdateDiscreteStates":
        flags = [c_bool() for _ in range(5)]
        return probe.call(name, *(byref(f) for f in flags), byref(c_double()))
    if name == "fmi3GetOutputDerivatives":
        return probe.call(name, probe.refs("omega1"), one, (c_int32 * 1)(1), reals(), one)
    if name == "fmi3DoStep":
        return probe.step(0.01)[0]
    if name == "fmi3ActivateModelPartition":
        return probe.call(name, c_uint(0), c_double(probe.time))
    if name == "fmi3CompletedIntegratorStep":
        return probe.call(name, c_bool(True), byref(c_bool()), byref(c_bool()))
    if name == "fmi3SetTime":
        return probe.call(name, c_double(probe.time))
    if name == "fmi3SetContinuousStates":
        return probe.call(name, probe.x, c_size_t(N_STATES))
    if name in ("fmi3GetContinuousStateDerivatives", "fmi3GetContinuousStates",
                "fmi3GetNominalsOfContinuousStates"):
        return probe.call(name, (c_double * N_STATES)(), c_size_t(N_STATES))
    if name == "fmi3GetEventIndicators":
        return probe.call(name, (c_double * 1)(), one)
    if name in ("fmi3GetNumberOfEventIndicators", "fmi3GetNumberOfContinuousStates"):
        return probe.call(name, byref(c_size_t()))
    raise AssertionError(f"no valid call written for {name}")


INTERFACES = {
    "CoSimulation": (matrix(CO_SIMULATION, CO_SIMULATION_COLUMNS), CO_SIMULATION_COLUMNS),
    "ModelExchange": (matrix(MODEL_EXCHANGE, MODEL_EXCHANGE_COLUMNS), MODEL_EXCHANGE_COLUMNS),
}


def library_path(unzipped3):
    return f"{unzipped3}/binaries/x86_64-linux/CyclicMechanism.so"


@pytest.fixture(scope="module")
def library(unzipped3):
    return ctypes.CDLL(library_path(unzipped3))


@pytest.fixture(scope="module")
def vr(model_description3):
    return {v.name: v.valueReference for v in model_description3.modelVariables}


def test_the_matrices_cover_every_function_that_takes_an_instance(unzipped3):
    """Of fmi3Functions.h's 75 functions, all but fmi3GetVersion, the three instantiation
    functions and fmi3FreeInstance are in a matrix."""
    symbols = subprocess.run(["nm", "-D", "--defined-only", library_path(unzipped3)],
                             check=True, capture_output=True, text=True).stdout.split()
    exported = {s for s in symbols if s.startswith("fmi3")}
    without_instance = {"fmi3GetVersion", "fmi3InstantiateModelExchange",
                        "fmi3InstantiateCoSimulation", "fmi3InstantiateScheduledExecution",
                        "fmi3FreeInstance"}
    names = set(INTERFACES["CoSimulation"][0]) | set(INTERFACES["ModelExchange"][0])
    assert names == exported - without_instance and len(exported) == 75


@pytest.mark.parametrize("interface", sorted(INTERFACES))
def test_every_function_in_every_state(library, model_description3, vr, interface, report):
    cells, columns = INTERFACES[interface]
    other = INTERFACES["ModelExchange" if interface == "CoSimulation" else "CoSimulation"][0]
    foreign = sorted(set(other) - set(cells))
    token = model_description3.instantiationToken
    wrong, checked = [], 0
    for state in columns:
        for name in sorted(cells) + foreign:
            probe = Probe(library, token, vr, interface)
            try:
                reach(probe, state, interface)
                before = len(probe.messages)
                status = valid_call(probe, name)
                said = " | ".join(probe.messages[before:])
                checked += 1
                if name in foreign:
                    if status != ERROR or name not in said or "function" not in said:
                        wrong.append((state, name, "foreign", status, said))
                elif state in cells[name]:
                    refused_for_state = "not allowed in state" in said
                    if name in UNDECLARED:
                        if status != ERROR or UNDECLARED[name] not in said or refused_for_state:
                            wrong.append((state, name, "undeclared", status, said))
                    elif status != OK:
                        wrong.append((state, name, "allowed", status, said))
                elif (status != ERROR or name not in said
                      or f"not allowed in state {STATE_WORDS[state]}" not in said):
                    wrong.append((state, name, "refused", status, said))
            finally:
                probe.free()
    report[f"fmi3_conformance_{interface}_cells"] = checked
    assert not wrong, "\n".join(map(str, wrong))


def test_instantiation_refuses_what_it_cannot_make(library, model_description3):
    token = model_description3.instantiationToken.encode()
    messages = []
    log = LOG(lambda env, status, category, message: messages.append(message.decode()))
    library.fmi3InstantiateCoSimulation.restype = c_void_p
    library.fmi3InstantiateModelExchange.restype = c_void_p
    library.fmi3InstantiateScheduledExecution.restype = c_void_p
    cases = [
        (lambda: library.fmi3InstantiateModelExchange(b"x", b"{wrong}", b"", False, True, None,
                                                      log), "instantiationToken"),
        (lambda: library.fmi3InstantiateModelExchange(b"  ", token, b"", False, True, None,
                                                      log), "instanceName"),
        (lambda: library.fmi3InstantiateCoSimulation(b"x", token, b"", False, True, False,
                                                     False, (c_uint * 1)(1), c_size_t(1), None,
                                                     log, None), "intermediate update"),
        (lambda: library.fmi3InstantiateScheduledExecution(b"x", token, b"", False, True,
                                                           None, log, None, None, None),
         "Scheduled Execution"),
    ]
    # With loggingOn false too: every token but the exact one, and every name without a
    # visible character, each refused with its reason in a message of modest length.
    for bad in (b"", b" " + token, token + b" ", b"x" + token, token[:-1], b"\xff\xfe" + token,
                b"{" + b"a" * (1 << 20) + b"}"):
        cases.append((lambda bad=bad: library.fmi3InstantiateCoSimulation(
            b"x", bad, b"", False, False, False, False, None, c_size_t(0), None, log, None),
            "instantiationToken"))
    for name in (b"", b" \t", None):
        cases.append((lambda name=name: library.fmi3InstantiateModelExchange(
            name, token, b"", False, False, None, log), "instanceName"))
    for make, word in cases:
        before = len(messages)
        assert make() is None
        assert any(word in m for m in messages[before:]), (word, messages[before:])
        assert all(len(m) < 1000 for m in messages[before:])
    # "If a null pointer is returned, then instantiation failed. In that case, logMessage
    # is called with detailed information about the reason": also with loggingOn false,
    # which governs the debug categories (as in the standard's Reference-FMUs).
    before = len(messages)
    assert library.fmi3InstantiateModelExchange(b"x", b"{wrong}", b"", False, False, None,
                                                log) is None
    assert any("instantiationToken" in m for m in messages[before:])
    library.fmi3GetVersion.restype = c_char_p
    assert library.fmi3GetVersion() == b"3.0"


def test_a_discarded_step_leaves_step_mode(library, model_description3, vr):
    """FMI 3.0 has no state of its own after a Discard: "fmi3Discard: The call was not
    successful and the FMU is in the same state as before the call", and fmi3DoStep may
    return it only "if the FMU is in the same state as before the call". So the FMU keeps
    its time and values, and Step Mode's calls go on (in FMI 2.0, stepFailed refuses them)."""
    probe = Probe(library, model_description3.instantiationToken, vr, "CoSimulation")
    try:
        probe.initialise(RUNAWAY)
        probe.must("fmi3EnterStepMode")
        watched = list(vr.values())
        for k in range(1000):
            probe.time = k * 0.01
            values = (c_double * 1)()
            before = {}
            for ref in watched:
                if probe.call("fmi3GetFloat64", (c_uint * 1)(ref), c_size_t(1), values,
                              c_size_t(1)) == OK:
                    before[ref] = values[0]
            status, last = probe.step(0.01)
            if status == DISCARD:
                break
            assert status == OK
        else:
            pytest.fail("the runaway never failed a step")
        assert last == probe.time
        for ref, value in before.items():
            probe.must("fmi3GetFloat64", (c_uint * 1)(ref), c_size_t(1), values, c_size_t(1))
            assert values[0] == value, ref
        probe.must("fmi3SetFloat64", probe.refs("M_m"), c_size_t(1), (c_double * 1)(0.0),
                   c_size_t(1))
        probe.must("fmi3SetInt64", probe.refs("change_point_branch"), c_size_t(1),
                   (c_int64 * 1)(2), c_size_t(1))
        probe.must("fmi3EnterEventMode")
        probe.must("fmi3EnterStepMode")
        status, _ = probe.step(1e-4)
        assert status == OK, probe.messages[-1:]
    finally:
        probe.free()


def test_states_the_loop_cannot_close_are_a_discard(library, model_description3, vr):
    """Model Exchange, explicit Euler at h = 0.01 on a change-point linkage: where Euler's
    states leave the region in which the loop closes, fmi3SetContinuousStates returns
    fmi3Discard, which FMI 3.0 recommends there so that the importer retries with a smaller
    step, and changes nothing: the same step at half the size goes on."""
    probe = Probe(library, model_description3.instantiationToken, vr, "ModelExchange")
    try:
        probe.enter_initialization()
        for name, value in dict(L=0.95, phi2_0=1.0742, omega2_0=-5.4821).items():
            probe.must("fmi3SetFloat64", probe.refs(name), c_size_t(1),
                       (c_double * 1)(value), c_size_t(1))
        probe.must("fmi3ExitInitializationMode")
        flags = [c_bool() for _ in range(5)]
        probe.must("fmi3UpdateDiscreteStates", *(byref(f) for f in flags), byref(c_double()))
        probe.must("fmi3EnterContinuousTimeMode")
        x, dx = (c_double * N_STATES)(), (c_double * N_STATES)()
        t, h, discards = 0.0, 0.01, 0
        while t < 2.0:
            probe.must("fmi3GetContinuousStates", x, c_size_t(N_STATES))
            probe.must("fmi3GetContinuousStateDerivatives", dx, c_size_t(N_STATES))
            before = list(x)
            step = h
            while True:
                moved = (c_double * N_STATES)(*(a + step * b for a, b in zip(before, dx)))
                probe.must("fmi3SetTime", c_double(t + step))
                status = probe.call("fmi3SetContinuousStates", moved, c_size_t(N_STATES))
                if status == OK:
                    break
                assert status == DISCARD, probe.messages[-1:]
                discards += 1
                probe.must("fmi3GetContinuousStates", x, c_size_t(N_STATES))
                assert list(x) == before, "a Discard changed the states"
                step *= 0.5
                assert step > 1e-9, "no step small enough"
            t += step
            event, stop = c_bool(), c_bool()
            probe.must("fmi3CompletedIntegratorStep", c_bool(True), byref(event), byref(stop))
            if event.value:
                probe.must("fmi3EnterEventMode")
                probe.must("fmi3UpdateDiscreteStates", *(byref(f) for f in flags),
                           byref(c_double()))
                probe.must("fmi3EnterContinuousTimeMode")
        assert discards > 0, "Euler's states always closed the loop"
    finally:
        probe.free()
