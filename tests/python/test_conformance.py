"""Every exported function that takes an instance, in every state this FMU reaches, for both
interfaces, called with valid arguments on a fresh instance through raw ctypes: fmi2OK where
the FMI 2.0.4 state tables allow the call (Model Exchange section 3.2.3, Co-Simulation
section 4.2.4), and fmi2Error with a message that names the function and the state where
they do not. The matrices below are typed from the standard's tables, not read from the
FMU's code. Columns the FMU never enters are left out: StepInProgress and StepCanceled (it
never returns fmi2Pending), Error (a refused argument leaves the instance where it was) and
Fatal (only a bug gets there)."""

import ctypes
import subprocess
from ctypes import POINTER, byref, c_char, c_double, c_int, c_size_t, c_uint, c_void_p

import fmpy.fmi2 as fmi2
import pytest

OK, DISCARD, ERROR = 0, 2, 3

# x: allowed, .: not allowed.
CO_SIMULATION_COLUMNS = ["Instantiated", "InitializationMode", "StepComplete", "StepFailed",
                         "Terminated"]
CO_SIMULATION = """
fmi2SetDebugLogging               x x x x x
fmi2SetupExperiment               x . . . .
fmi2EnterInitializationMode       x . . . .
fmi2ExitInitializationMode        . x . . .
fmi2Terminate                     . . x x .
fmi2Reset                         x x x x x
fmi2GetReal                       . x x x x
fmi2GetInteger                    . x x x x
fmi2GetBoolean                    . x x x x
fmi2GetString                     . x x x x
fmi2SetReal                       x x x . .
fmi2SetInteger                    x x x . .
fmi2SetBoolean                    x x x . .
fmi2SetString                     x x x . .
fmi2GetFMUstate                   x x x x x
fmi2SetFMUstate                   x x x x x
fmi2FreeFMUstate                  x x x x x
fmi2SerializedFMUstateSize        x x x x x
fmi2SerializeFMUstate             x x x x x
fmi2DeSerializeFMUstate           x x x x x
fmi2GetDirectionalDerivative      . x x x x
fmi2SetRealInputDerivatives       x x x . .
fmi2GetRealOutputDerivatives      . . x x x
fmi2DoStep                        . . x . .
fmi2CancelStep                    . . . . .
fmi2GetStatus                     . . x x x
fmi2GetRealStatus                 . . x x x
fmi2GetIntegerStatus              . . x x x
fmi2GetBooleanStatus              . . x x x
fmi2GetStringStatus               . . x x x
"""

MODEL_EXCHANGE_COLUMNS = ["Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode",
                          "Terminated"]
MODEL_EXCHANGE = """
fmi2SetDebugLogging               x x x x x
fmi2SetupExperiment               x . . . .
fmi2EnterInitializationMode       x . . . .
fmi2ExitInitializationMode        . x . . .
fmi2Terminate                     . . x x .
fmi2Reset                         x x x x x
fmi2GetReal                       . x x x x
fmi2GetInteger                    . x x x x
fmi2GetBoolean                    . x x x x
fmi2GetString                     . x x x x
fmi2SetReal                       x x x x .
fmi2SetInteger                    x x x . .
fmi2SetBoolean                    x x x . .
fmi2SetString                     x x x . .
fmi2GetFMUstate                   x x x x x
fmi2SetFMUstate                   x x x x x
fmi2FreeFMUstate                  x x x x x
fmi2SerializedFMUstateSize        x x x x x
fmi2SerializeFMUstate             x x x x x
fmi2DeSerializeFMUstate           x x x x x
fmi2GetDirectionalDerivative      . x x x x
fmi2EnterEventMode                . . x x .
fmi2NewDiscreteStates             . . x . .
fmi2EnterContinuousTimeMode       . . x . .
fmi2CompletedIntegratorStep       . . . x .
fmi2SetTime                       . . x x .
fmi2SetContinuousStates           . . . x .
fmi2GetEventIndicators            . x x x x
fmi2GetContinuousStates           . x x x x
fmi2GetDerivatives                . . x x x
fmi2GetNominalsOfContinuousStates x . x x x
"""

# What the FMU's messages call each state.
STATE_WORDS = {
    "Instantiated": "instantiated",
    "InitializationMode": "initialization mode",
    "StepComplete": "step complete",
    "StepFailed": "step failed",
    "Terminated": "terminated",
    "EventMode": "event mode",
    "ContinuousTimeMode": "continuous-time mode",
}

# Calls that have no valid arguments outside an asynchronous step, which this FMU never
# starts: where the table allows them they are refused for that reason, not for the state.
NO_VALID_ARGUMENTS = {"fmi2GetStatus", "fmi2GetIntegerStatus", "fmi2GetStringStatus"}

# A motor law with positive feedback: ω1 runs away within about 0.05 s, and a step fails.
RUNAWAY = {"Mm_a2": 1.0, "omega1_0": 10.0}
N_STATES = 6


def matrix(table, columns):
    cells = {}
    for line in table.strip().splitlines():
        name, *marks = line.split()
        assert len(marks) == len(columns), line
        cells[name] = {column for column, mark in zip(columns, marks) if mark == "x"}
    return cells


class Probe:
    """One fresh instance, driven to a state, with its log."""

    def __init__(self, library, guid, vr, interface):
        self.lib, self.vr, self.messages = library, vr, []
        self.time = 0.0
        self.x = (c_double * N_STATES)()
        self._logger = fmi2.fmi2CallbackLoggerTYPE(self._log)
        self.callbacks = fmi2.fmi2CallbackFunctions()
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = fmi2.fmi2CallbackAllocateMemoryTYPE(fmi2.calloc)
        self.callbacks.freeMemory = fmi2.fmi2CallbackFreeMemoryTYPE(fmi2.free)
        self.lib.fmi2Instantiate.restype = c_void_p
        self.c = c_void_p(self.lib.fmi2Instantiate(b"conformance", interface, guid.encode(), b"",
                                                   byref(self.callbacks), 0, 0))
        assert self.c.value

    def _log(self, env, name, status, category, message):
        self.messages.append(message.decode())

    def call(self, name, *args):
        return getattr(self.lib, name)(self.c, *args)

    def must(self, name, *args):
        status = self.call(name, *args)
        assert status == OK, (name, self.messages[-1:])

    def refs(self, *names):
        return (c_uint * len(names))(*(self.vr[n] for n in names))

    def enter_initialization(self):
        self.must("fmi2SetupExperiment", 1, c_double(1e-8), c_double(0.0), 0, c_double(0.0))
        self.must("fmi2EnterInitializationMode")

    def initialise(self, parameters=None):
        self.enter_initialization()
        for name, value in (parameters or {}).items():
            self.must("fmi2SetReal", self.refs(name), 1, (c_double * 1)(value))
        self.must("fmi2ExitInitializationMode")

    def free(self):
        self.lib.fmi2FreeInstance(self.c)


def reach(probe, state):
    """Drive a fresh instance into `state` as a master would."""
    if state == "Instantiated":
        return
    if state == "InitializationMode":
        probe.enter_initialization()
        return
    if state == "StepFailed":
        probe.initialise(RUNAWAY)
        for k in range(1000):
            status = probe.call("fmi2DoStep", c_double(k * 0.01), c_double(0.01), 1)
            if status == DISCARD:
                probe.time = k * 0.01
                return
            assert status == OK
        pytest.fail("the runaway never failed a step")
    probe.initialise()
    if state == "StepComplete":
        probe.must("fmi2DoStep", c_double(0.0), c_double(0.01), 1)
        probe.time = 0.01
    elif state == "ContinuousTimeMode":
        info = fmi2.fmi2EventInfo()
        probe.must("fmi2NewDiscreteStates", byref(info))
        probe.must("fmi2EnterContinuousTimeMode")
        probe.must("fmi2GetContinuousStates", probe.x, N_STATES)
    elif state == "Terminated":
        probe.must("fmi2Terminate")


def saved_state(probe):
    state = c_void_p()
    probe.call("fmi2GetFMUstate", byref(state))
    return state


def serialized(probe):
    state, size = saved_state(probe), c_size_t()
    probe.call("fmi2SerializedFMUstateSize", state, byref(size))
    buffer = (c_char * size.value)()
    probe.call("fmi2SerializeFMUstate", state, buffer, size)
    return buffer, size


def valid_call(probe, name):
    """Call `name` with arguments that are valid whenever the state allows the call."""
    reals = c_double * 1
    one = c_size_t(1)
    if name == "fmi2SetDebugLogging":
        return probe.call(name, 1, c_size_t(0), None)
    if name == "fmi2SetupExperiment":
        return probe.call(name, 1, c_double(1e-8), c_double(0.0), 0, c_double(0.0))
    if name in ("fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
                "fmi2Reset", "fmi2CancelStep", "fmi2EnterEventMode",
                "fmi2EnterContinuousTimeMode"):
        return probe.call(name)
    if name == "fmi2GetReal":
        return probe.call(name, probe.refs("phi1"), one, reals())
    if name == "fmi2GetInteger":
        return probe.call(name, probe.refs("linkage_class"), one, (c_int * 1)())
    if name == "fmi2GetBoolean":
        return probe.call(name, probe.refs("builtin_laws"), one, (c_int * 1)())
    if name == "fmi2SetReal":
        return probe.call(name, probe.refs("M_m"), one, reals(0.0))
    if name in ("fmi2GetString", "fmi2SetString", "fmi2SetInteger", "fmi2SetBoolean"):
        return probe.call(name, None, c_size_t(0), None)  # no settable variable in every state
    if name == "fmi2GetFMUstate":
        return probe.call(name, byref(c_void_p()))
    if name == "fmi2SetFMUstate":
        return probe.call(name, saved_state(probe))
    if name == "fmi2FreeFMUstate":
        return probe.call(name, byref(saved_state(probe)))
    if name == "fmi2SerializedFMUstateSize":
        return probe.call(name, saved_state(probe), byref(c_size_t()))
    if name == "fmi2SerializeFMUstate":
        state, size = saved_state(probe), c_size_t()
        probe.call("fmi2SerializedFMUstateSize", state, byref(size))
        return probe.call(name, state, (c_char * size.value)(), size)
    if name == "fmi2DeSerializeFMUstate":
        buffer, size = serialized(probe)
        return probe.call(name, buffer, size, byref(c_void_p()))
    if name == "fmi2GetDirectionalDerivative":
        return probe.call(name, probe.refs("phi1"), one, probe.refs("M_m"), one, reals(1.0), reals())
    if name == "fmi2SetRealInputDerivatives":
        return probe.call(name, probe.refs("M_m"), one, (c_int * 1)(1), reals(0.0))
    if name == "fmi2GetRealOutputDerivatives":
        return probe.call(name, probe.refs("omega1"), one, (c_int * 1)(1), reals())
    if name == "fmi2DoStep":
        return probe.call(name, c_double(probe.time), c_double(0.01), 1)
    if name == "fmi2GetStatus":
        return probe.call(name, fmi2.fmi2DoStepStatus, byref(c_int()))
    if name == "fmi2GetRealStatus":
        return probe.call(name, fmi2.fmi2LastSuccessfulTime, byref(c_double()))
    if name == "fmi2GetIntegerStatus":
        return probe.call(name, fmi2.fmi2DoStepStatus, byref(c_int()))
    if name == "fmi2GetBooleanStatus":
        return probe.call(name, fmi2.fmi2Terminated, byref(c_int()))
    if name == "fmi2GetStringStatus":
        return probe.call(name, fmi2.fmi2PendingStatus, byref(ctypes.c_char_p()))
    if name == "fmi2NewDiscreteStates":
        return probe.call(name, byref(fmi2.fmi2EventInfo()))
    if name == "fmi2CompletedIntegratorStep":
        return probe.call(name, 1, byref(c_int()), byref(c_int()))
    if name == "fmi2SetTime":
        return probe.call(name, c_double(probe.time))
    if name == "fmi2SetContinuousStates":
        return probe.call(name, probe.x, c_size_t(N_STATES))
    if name in ("fmi2GetDerivatives", "fmi2GetContinuousStates",
                "fmi2GetNominalsOfContinuousStates"):
        return probe.call(name, (c_double * N_STATES)(), c_size_t(N_STATES))
    if name == "fmi2GetEventIndicators":
        return probe.call(name, (c_double * 1)(), one)
    raise AssertionError(f"no valid call written for {name}")


INTERFACES = {
    "CoSimulation": (fmi2.fmi2CoSimulation, matrix(CO_SIMULATION, CO_SIMULATION_COLUMNS),
                     CO_SIMULATION_COLUMNS),
    "ModelExchange": (fmi2.fmi2ModelExchange, matrix(MODEL_EXCHANGE, MODEL_EXCHANGE_COLUMNS),
                      MODEL_EXCHANGE_COLUMNS),
}


@pytest.fixture(scope="module")
def library(unzipped):
    return ctypes.CDLL(f"{unzipped}/binaries/linux64/CyclicMechanism.so")


@pytest.fixture(scope="module")
def vr(model_description):
    return {v.name: v.valueReference for v in model_description.modelVariables}


def test_the_matrices_cover_every_function_that_takes_an_instance(unzipped):
    """Of fmi2Functions.h's 44 functions, all but fmi2GetTypesPlatform, fmi2GetVersion,
    fmi2Instantiate and fmi2FreeInstance (tested below) are in a matrix."""
    library = f"{unzipped}/binaries/linux64/CyclicMechanism.so"
    symbols = subprocess.run(["nm", "-D", "--defined-only", library], check=True,
                             capture_output=True, text=True).stdout.split()
    exported = {s for s in symbols if s.startswith("fmi2")}
    without_instance = {"fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2Instantiate",
                        "fmi2FreeInstance"}
    names = set(INTERFACES["CoSimulation"][1]) | set(INTERFACES["ModelExchange"][1])
    assert names == exported - without_instance and len(exported) == 44


@pytest.mark.parametrize("interface", sorted(INTERFACES))
def test_every_function_in_every_state(library, model_description, vr, interface, report):
    kind, cells, columns = INTERFACES[interface]
    other = next(v[1] for k, v in INTERFACES.items() if k != interface)
    foreign = sorted(set(other) - set(cells))
    wrong = []
    checked = 0
    for state in columns:
        for name in sorted(cells) + foreign:
            probe = Probe(library, model_description.guid, vr, kind)
            try:
                reach(probe, state)
                before = len(probe.messages)
                status = valid_call(probe, name)
                said = " | ".join(probe.messages[before:])
                checked += 1
                if name in foreign:
                    if status != ERROR or name not in said or "function" not in said:
                        wrong.append((state, name, "foreign", status, said))
                elif state in cells[name]:
                    refused_for_state = "not allowed in state" in said
                    if name in NO_VALID_ARGUMENTS:
                        if status != ERROR or refused_for_state:
                            wrong.append((state, name, "allowed", status, said))
                    elif status != OK:
                        wrong.append((state, name, "allowed", status, said))
                elif status != ERROR or name not in said or STATE_WORDS[state] not in said:
                    wrong.append((state, name, "not allowed", status, said))
            finally:
                probe.free()
    report[f"conformance_{interface}_cells"] = checked
    assert not wrong, "\n".join(map(str, wrong))


@pytest.mark.parametrize("interface", sorted(INTERFACES))
def test_free_instance_in_every_state(library, model_description, vr, interface):
    kind, _, columns = INTERFACES[interface]
    for state in columns:
        probe = Probe(library, model_description.guid, vr, kind)
        reach(probe, state)
        probe.free()  # a crash or a leak here fails the run (and memcheck)
