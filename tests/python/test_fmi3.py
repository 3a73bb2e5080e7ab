"""The FMI 3.0 archive through FMPy, as users run it: validation, Co-Simulation and Model
Exchange (CVODE) against the independent reference, Co-Simulation equal to FMI 2.0's bit
for bit, the change point as an event (early return, the master's choice of branch, the
run going on), FMU states, and adjoint derivatives against the directional ones."""

import zipfile

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3Discard
from fmpy.validation import validate_fmu

import reference
from conftest import STATES, states

CASES = {
    "case1": dict(reference.PAPER_LAWS, k34=100.0),
    "case2": dict(reference.PAPER_LAWS, k34=40.0),
    "free": dict(reference.FREE_RUN),
}
PLATFORMS = {"x86_64-linux", "aarch64-linux", "x86_64-windows", "x86_64-darwin",
             "aarch64-darwin"}
# The change-point geometry l2 + L = l + l3 (collinear at φ2 = φ3 = 0 mod 2π), moving
# freely: the energy is constant.
CHANGE_POINT = dict(reference.NO_LAWS, L=0.95, phi2_0=np.pi / 2, omega2_0=4.0)
WATCH = STATES + ["energy", "rod_force", "constraint_residual"]


def run(path, fmi_type, values, tolerance=1e-10, **options):
    return fmpy.simulate_fmu(str(path), fmi_type=fmi_type, start_values=values, stop_time=10.0,
                             output_interval=0.01, relative_tolerance=tolerance, output=WATCH,
                             record_events=False, **options)


def scaled_error(result, expected):
    scale = np.maximum(1.0, np.abs(expected).max(axis=0))
    return np.abs(states(result) - expected) / scale


@pytest.fixture(scope="module")
def references():
    times = np.linspace(0.0, 10.0, 1001)
    return {case: reference.solve(reference.Params(**values), times)
            for case, values in CASES.items()}


@pytest.fixture(scope="module")
def vr(model_description3):
    return {v.name: v.valueReference for v in model_description3.modelVariables}


def test_fmpy_validates_the_archive(fmu3_path, model_description3):
    assert validate_fmu(str(fmu3_path)) == []
    assert model_description3.fmiVersion == "3.0"
    assert model_description3.coSimulation.hasEventMode
    assert model_description3.coSimulation.mightReturnEarlyFromDoStep


def test_both_archives_carry_the_same_binaries(fmu_path, fmu3_path):
    """One library for both versions: the FMI 3.0 archive's platform tuples hold the files
    of FMI 2.0's platform folders (its darwin64 file joins both darwin ones)."""
    with zipfile.ZipFile(fmu_path) as two, zipfile.ZipFile(fmu3_path) as three:
        folders = {n.split("/")[1] for n in three.namelist() if n.startswith("binaries/")}
        assert folders in ({"x86_64-linux"}, PLATFORMS), folders
        same = {"x86_64-linux": "linux64/CyclicMechanism.so",
                "x86_64-windows": "win64/CyclicMechanism.dll"}
        for folder, old in same.items():
            if folder in folders:
                new = [n for n in three.namelist() if n.startswith(f"binaries/{folder}/")]
                assert three.read(new[0]) == two.read(f"binaries/{old}")
        assert three.read("documentation/index.html") == two.read("documentation/index.html")


@pytest.mark.parametrize("case", sorted(CASES))
def test_co_simulation_equals_fmi2_bit_for_bit(fmu_path, fmu3_path, case, references, report):
    """The same integrator behind both interfaces: every value at every communication
    point the same to the last bit; and within 1e-6 of the independent reference."""
    two = run(fmu_path, "CoSimulation", CASES[case])
    three = run(fmu3_path, "CoSimulation", CASES[case])
    for name in ["time"] + WATCH:
        assert np.array_equal(two[name], three[name]), name
    error = scaled_error(three, references[case])
    report[f"fmi3_cs_{case}_max_scaled_error"] = float(error.max())
    assert error.max() < 1e-6, error.max(axis=0)


@pytest.mark.parametrize("case", sorted(CASES))
def test_model_exchange_with_cvode_matches_the_reference(fmu3_path, case, references, report):
    """CVODE's own error sets the figure: at rtol 1e-10 the free run misses 1e-6 by a
    little (CVODE's, not the model's: it falls with the tolerance), at 1e-12 all pass."""
    result = run(fmu3_path, "ModelExchange", CASES[case], tolerance=1e-12)
    error = scaled_error(result, references[case])
    report[f"fmi3_me_cvode_{case}_max_scaled_error"] = float(error.max())
    assert error.max() < 1e-6, error.max(axis=0)
    assert np.abs(result["constraint_residual"]).max() < 1e-14


class Slave:
    """A low-level FMI 3.0 Co-Simulation instance with its log."""

    def __init__(self, unzipped3, md, event_mode, early_return, enumerations=None, **values):
        self.messages = []
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU3Slave(guid=md.instantiationToken, unzipDirectory=unzipped3,
                             modelIdentifier="CyclicMechanism", instanceName="fmi3")
        self.fmu.instantiate(loggingOn=True, eventModeUsed=event_mode,
                             earlyReturnAllowed=early_return,
                             logMessage=lambda env, status, category, message:
                             self.messages.append(message.decode()))
        self.fmu.setDebugLogging(True, ["logSolver"])
        booleans = {k: v for k, v in values.items() if isinstance(v, bool)}
        reals = {k: v for k, v in values.items() if not isinstance(v, bool)}
        self.fmu.setBoolean([self.vr[k] for k in booleans], list(booleans.values()))
        self.fmu.setFloat64([self.vr[k] for k in reals], list(reals.values()))
        enumerations = enumerations or {}
        self.fmu.setInt64([self.vr[k] for k in enumerations], list(enumerations.values()))
        self.fmu.enterInitializationMode(tolerance=1e-10, startTime=0.0, stopTime=10.0)
        self.fmu.exitInitializationMode()
        if event_mode:
            self.fmu.updateDiscreteStates()
            self.fmu.enterStepMode()

    def get(self, *names):
        return self.fmu.getFloat64([self.vr[n] for n in names])

    def step_to_change_point(self, h=1e-3):
        """Steps of h from t = 0 until one returns early: the event's flag and its time."""
        t = 0.0
        while True:
            event, _, early, last = self.fmu.doStep(t, h)
            if early:
                return event, last
            t += h

    def handle_event(self, branch=None):
        """Event mode at a change point, on `branch` if given, then Step Mode again."""
        self.fmu.enterEventMode()
        if branch is not None:
            self.fmu.setInt64([self.vr["change_point_branch"]], [branch])
        self.fmu.updateDiscreteStates()
        self.fmu.enterStepMode()

    def free(self):
        """The instance freed (FMPy does not free it when the object goes): under valgrind
        an instance left over is a leak attributed to the FMU."""
        self.fmu.freeInstance()


def change_point_run(unzipped3, md, branch, until=8.0, h=1e-3):
    """Step by h with event mode and early return; at each event choose `branch`. Returns
    the events (time, state, energy) and the instance."""
    slave = Slave(unzipped3, md, True, True, **CHANGE_POINT)
    t, events = 0.0, []
    while t < until - 1e-9:
        target = (np.floor(t / h + 1e-6) + 1) * h
        event, terminate, early, last = slave.fmu.doStep(t, target - t)
        assert not terminate
        if early:
            assert event and last < target
            events.append((last, slave.get(*STATES), slave.get("energy")[0]))
            slave.handle_event(branch)
            t = last
        else:
            assert not event
            t = target
    return events, slave


def test_change_point_returns_early_and_goes_on_on_the_chosen_branch(unzipped3,
                                                                    model_description3,
                                                                    report):
    runs = {branch: change_point_run(unzipped3, model_description3, branch)
            for branch in (1, 2)}
    (events, straight), (turned_events, turned) = runs[1], runs[2]
    assert events and turned_events
    t_event, y, energy = events[0]
    # Stopped just before crank, rod and rocker fall collinear (φ2 = φ3 = 0 mod 2π).
    assert abs((y[1] + np.pi) % (2 * np.pi) - np.pi) < 1e-3 and abs(y[2]) < 1e-3, y
    assert turned_events[0][0] == t_event
    crossed = [m for m in straight.messages if "crossed onto the branch straight" in m]
    assert crossed, straight.messages[-5:]
    # Both go on, on different branches, the energy and the constraint holding.
    for slave, name in ((straight, "straight"), (turned, "turn")):
        e, residual = slave.get("energy", "constraint_residual")
        drift = abs(e - energy) / energy
        report[f"fmi3_change_point_{name}_energy_drift_after_event"] = float(drift)
        assert drift < 1e-7 and abs(residual) < 1e-12, (name, drift, residual)
    end_straight, end_turned = straight.get(*STATES), turned.get(*STATES)
    assert np.abs(np.subtract(end_straight, end_turned)).max() > 0.1
    report["fmi3_change_point_event_time"] = t_event
    report["fmi3_change_point_events_straight"] = len(events)
    straight.free()
    turned.free()


def test_sensitivities_end_at_a_change_point_with_the_reason(unzipped3, model_description3):
    """The branch a change-point linkage takes is a choice, not a differentiable function of
    the parameters: the step that would carry a slot's sensitivities across the change point
    fails, naming it, and leaves the FMU as it was (a Discard); up to it the run and its
    sensitivities go on."""
    items = next(t for t in model_description3.typeDefinitions if t.name == "SensitivityParameter").items
    k34 = next(int(i.value) for i in items if i.name == "k34")
    slave = Slave(unzipped3, model_description3, True, True,
                  enumerations={"sensitivity_1.parameter": k34}, **CHANGE_POINT)
    event, last = slave.step_to_change_point()
    assert event and last > 0
    before = slave.get(*STATES, "sensitivity_1.phi3")
    assert np.all(np.isfinite(before)) and before[-1] != 0.0
    slave.handle_event()
    with pytest.raises(FMICallException) as refused:
        slave.fmu.doStep(last, 1e-3)
    assert refused.value.status == fmi3Discard
    reason = [m for m in slave.messages if "sensitivities end at the change point" in m]
    assert reason and "not a differentiable function of the parameters" in reason[-1], slave.messages[-3:]
    assert slave.get(*STATES, "sensitivity_1.phi3") == before
    slave.free()


def test_the_branch_taken_is_the_tangent_chosen(unzipped3, model_description3):
    """Just after the crossing the rocker-to-crank speed ratio is the slope of the branch:
    the arrival one for straight, the other for turn (the two roots of the closure's
    second-order terms: L·l2 + l2² − 2·l2·l3·m + (l3² − L·l3)·m² = 0)."""
    l, l2, l3, L = 0.5, 0.05, 0.5, CHANGE_POINT["L"]
    slopes = np.roots([l3 * l3 - L * l3, -2 * l2 * l3, L * l2 + l2 * l2])
    for branch in (1, 2):
        slave = Slave(unzipped3, model_description3, True, True, **CHANGE_POINT)
        _, last = slave.step_to_change_point()
        w2, w3 = slave.get("omega2", "omega3")
        arrival = w3 / w2
        slave.handle_event(branch)
        slave.fmu.doStep(last, 2e-3)
        w2, w3 = slave.get("omega2", "omega3")
        nearest = slopes[np.argmin(np.abs(slopes - w3 / w2))]
        arrived = slopes[np.argmin(np.abs(slopes - arrival))]
        assert abs(arrival - arrived) < 1e-2
        assert (nearest == arrived) == (branch == 1), (branch, arrival, w3 / w2, slopes)
        assert w2 > 0
        slave.free()


def test_the_run_after_the_event_agrees_across_tolerances(unzipped3, model_description3,
                                                         report):
    """No independent reference goes through a change point (the reference's ODE is
    singular there: at rtol 1e-10 it turns back, at 1e-12 it takes the other branch), so
    the straight run is compared with itself at tolerance 1e-12, 1 s after the event. Where
    each run stops before the change point varies with the tolerance (by up to 4e-5 s, so
    the crossings start 2.9e-4 to 4.3e-4 rad before it); the runs still agree after it to
    about 1e-8: the crossing does not depend on where it starts, to that order."""
    results = {}
    for tolerance in (1e-8, 1e-10, 1e-12):
        r = fmpy.simulate_fmu(str(unzipped3), fmi_type="CoSimulation", start_values=CHANGE_POINT,
                              stop_time=5.2, output_interval=0.01,
                              relative_tolerance=tolerance, use_event_mode=True,
                              early_return_allowed=True, output=STATES, record_events=False)
        at = [np.argmin(np.abs(r["time"] - t)) for t in (4.1, 5.2)]
        results[tolerance] = states(r)[at]
    before = [float(np.abs(results[t][0] - results[1e-12][0]).max()) for t in (1e-8, 1e-10)]
    after = [float(np.abs(results[t][1] - results[1e-12][1]).max()) for t in (1e-8, 1e-10)]
    report["fmi3_change_point_before_event_difference_tol_1e-8_1e-10_vs_1e-12"] = before
    report["fmi3_change_point_after_event_difference_tol_1e-8_1e-10_vs_1e-12"] = after
    assert before[0] < 1e-7 and before[1] < 1e-9, before
    assert max(after) < 1e-7, after


def test_without_event_mode_the_step_ends_at_the_change_point(unzipped3, model_description3):
    slave = Slave(unzipped3, model_description3, False, False, **CHANGE_POINT)
    t = 0.0
    with pytest.raises(FMICallException) as refused:
        while t < 8.0:
            slave.fmu.doStep(t, 1e-3)
            t += 1e-3
    assert refused.value.status == 2  # fmi3Discard
    message = slave.messages[-1]
    assert "change point" in message and "eventModeUsed" in message, message
    # FMI 3.0's Discard: the FMU as before the call, in Step Mode; the message says where
    # the change point lies, and a step to just before it passes.
    time = slave.fmu.getFloat64([0])[0]
    assert time == t, (t, time)
    located = float(message.split("meets a change point at t = ")[1].split()[0])
    assert t < located < t + 1e-3, (t, located)
    slave.fmu.doStep(t, 0.5 * (located - t))
    slave.free()
    # Event mode without early return: the step completes, and says an event happened.
    slave = Slave(unzipped3, model_description3, True, False, **CHANGE_POINT)
    t, flagged = 0.0, []
    while t < 4.5:
        event, _, early, _ = slave.fmu.doStep(t, 1e-3)
        assert not early
        if event:
            flagged.append(t)
            slave.handle_event()
        t += 1e-3
    assert len(flagged) == 1 and 4.0 < flagged[0] < 4.2, flagged
    slave.free()


def test_fmu_state_round_trips_bit_for_bit(unzipped3, model_description3):
    """Saved in the middle of a run, and just before a change point (a crossing pending),
    serialized and restored in a fresh instance: the run goes on to the same bits."""
    def go_on(slave, t, steps=300):
        seen = []
        for _ in range(steps):
            event, _, early, last = slave.fmu.doStep(t, 1e-3)
            if early:
                slave.handle_event()
                t = last
            else:
                t += 1e-3
            seen.append(list(slave.get(*WATCH)) + [t])
        return seen

    source = Slave(unzipped3, model_description3, True, True, **CHANGE_POINT)
    _, t = source.step_to_change_point()
    state = source.fmu.getFMUState()
    buffer = source.fmu.serializeFMUState(state)
    source.handle_event()
    expected = go_on(source, t)
    source.fmu.setFMUState(state)
    source.handle_event()
    assert go_on(source, t) == expected
    target = Slave(unzipped3, model_description3, True, True, **CHANGE_POINT)
    target.fmu.setFMUState(target.fmu.deserializeFMUState(buffer))
    target.handle_event()
    assert go_on(target, t) == expected
    source.fmu.freeFMUState(state)
    source.free()
    target.free()


def test_adjoint_is_the_transpose_of_the_directional_derivative(unzipped3, model_description3,
                                                                vr):
    """In Model Exchange, knowns = the continuous states and the inputs, unknowns = the
    state derivatives and the Real outputs: for random seeds u and v, uᵀ·(J·v) = (Jᵀ·u)ᵀ·v,
    and with unit seeds every entry agrees exactly."""
    md = model_description3
    model = FMU3Model(guid=md.instantiationToken, unzipDirectory=unzipped3,
                      modelIdentifier="CyclicMechanism", instanceName="adjoint")
    model.instantiate()
    model.setFloat64([vr[k] for k in reference.PAPER_LAWS], list(reference.PAPER_LAWS.values()))
    model.enterInitializationMode(startTime=0.0)
    model.exitInitializationMode()
    model.updateDiscreteStates()
    model.enterContinuousTimeMode()
    states_vr = [d.variable.derivative.valueReference for d in md.derivatives]
    knowns = states_vr + [vr["M_m"], vr["M_r"]]
    unknowns = [d.variable.valueReference for d in md.derivatives] + [
        u.variable.valueReference for u in md.outputs if u.variable.type == "Float64"]
    rng = np.random.default_rng(7)
    for _ in range(5):
        u, v = rng.normal(size=len(unknowns)), rng.normal(size=len(knowns))
        jv = np.array(model.getDirectionalDerivative(unknowns, knowns, list(v)))
        # FMPy sizes the sensitivity by the unknowns unless told: it has one entry per known.
        jtu = np.array(model.getAdjointDerivative(unknowns, knowns, list(u), len(knowns)))
        assert abs(u @ jv - jtu @ v) <= 1e-12 * max(1.0, abs(u @ jv)), (u @ jv, jtu @ v)
    for i, known in enumerate(knowns):
        column = model.getDirectionalDerivative(unknowns, [known], [1.0])
        for j, unknown in enumerate(unknowns):
            row = model.getAdjointDerivative([unknown], knowns, [1.0], len(knowns))
            assert row[i] == column[j], (known, unknown)
    model.terminate()
    model.freeInstance()


def test_fmpy_hears_why_a_value_is_refused_without_debug_logging(fmu3_path, capsys):
    """FMPy instantiates with loggingOn = debug_logging (false by default): the refusal's
    reason reaches its console all the same, and the debug categories stay quiet."""
    with pytest.raises(Exception):
        fmpy.simulate_fmu(fmu3_path, start_values={"L": -0.7}, stop_time=0.1)
    out = capsys.readouterr().out
    assert "[ERROR]" in out and "L = -0.7" in out and "must be > 0" in out, out
    assert "[OK]" not in out, out


@pytest.mark.parametrize("which", ["2.0", "3.0"])
def test_the_archives_reference_result_replays_through_fmpy(which, fmu_path, fmu3_path, tmp_path):
    """The archive alone: its fmi-ls-ref manifest names a CSV of the default experiment's
    Real outputs; FMPy's co-simulation of the default experiment from the same archive
    gives every row within 1e-9 of each column's scale (the FMU is deterministic: the same
    run, bit for bit, is expected), and FMPy still validates the archive."""
    import csv
    import xml.etree.ElementTree as ET
    archive = fmu_path if which == "2.0" else fmu3_path
    folder = "extra/org.fmi-standard.fmi-ls-ref/"
    with zipfile.ZipFile(archive) as z:
        manifest = ET.fromstring(z.read(folder + "fmi-ls-manifest.xml"))
        ls = "{http://fmi-standard.org/fmi-ls-manifest}"
        assert manifest.get(f"{ls}fmi-ls-name") == "org.fmi-standard.fmi-ls-ref"
        related = manifest.find("Related")
        assert related.get("role") == "result" and related.get("type") == "text/csv"
        rows = list(csv.reader(z.read(folder + related.get("source")).decode().splitlines()))
    names, table = rows[0], np.array(rows[1:], dtype=float)
    assert names[0] == "time" and len(table) > 100
    md = fmpy.read_model_description(archive)
    experiment = md.defaultExperiment
    run = fmpy.simulate_fmu(archive, fmi_type="CoSimulation", output=names[1:],
                            stop_time=float(experiment.stopTime),
                            output_interval=float(experiment.stepSize))
    every = int(round((table[1, 0] - table[0, 0]) / float(experiment.stepSize)))
    replay = run[::every]
    assert len(replay) == len(table)
    assert np.allclose(replay["time"], table[:, 0], rtol=0, atol=1e-12)
    for k, name in enumerate(names[1:], start=1):
        scale = max(1.0, float(np.abs(table[:, k]).max()))
        assert np.abs(replay[name] - table[:, k]).max() <= 1e-9 * scale, name
    assert validate_fmu(str(archive)) == []
