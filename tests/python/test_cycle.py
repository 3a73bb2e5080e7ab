"""The steady cycle found by shooting (``[cycle]``, docs/cycle.md), checked against what it
claims to replace and against physics: a long transient's last revolution, a difference
monodromy, the decay of a perturbation seen in a long run, the spectrum of the mechanism's
small free oscillations computed from its geometry alone, and the resonances a sweep of
crank speed shows where the Campbell diagram's order lines cross a mode. Mistakes are
refused by field, all in one run; points without a steady cycle say why."""

import ctypes
import math

import numpy as np
import pandas as pd
import pytest
from scipy.interpolate import CubicSpline
from scipy.linalg import eigh
from scipy.optimize import brentq

from fmusweep import SpecError, linearise, run_sweep
from sweep_helpers import faulty_rotor, stopped_mid_way

TAU = 2 * math.pi
CYCLE = {"state": "loop_angle", "advance": TAU, "shifted": ["phi1"]}
METRICS = {"peak": {"variable": "rod_force", "kind": "max"},
           "low": {"variable": "rod_force", "kind": "min"},
           "swing": {"variable": "rod_force", "kind": "peak_to_peak"},
           "speed": {"variable": "omega2", "kind": "mean"},
           "rms": {"variable": "rod_force", "kind": "rms"},
           "second": {"variable": "rod_force", "kind": "harmonic", "order": 2}}


def cycle_spec(parameters, design, metrics=None, tolerance=1e-10, **cycle):
    return {"scenario": {"stop": 100.0, "step": 0.01, "tolerance": tolerance,
                         "parameters": parameters},
            "design": design, "cycle": {**CYCLE, **cycle},
            "outputs": {"metrics": METRICS if metrics is None else metrics}}


def listed(**columns):
    return {"kind": "list", "parameters": {k: {"values": v} for k, v in columns.items()}}


def sweep(spec, fmu, out):
    return run_sweep(spec, fmu=fmu, out=out, serial=True, progress=False, plots=False)


def transient(fmu, out, parameters, step, stop, variables):
    """The FMU's own co-simulation from `parameters`, its series every `step`."""
    spec = {"scenario": {"stop": stop, "step": step, "tolerance": 1e-11,
                         "parameters": parameters},
            "design": listed(J1=[parameters.pop("J1", 0.5)]),
            "outputs": {"series": {"variables": variables}}}
    results = sweep(spec, fmu, out)
    assert (results.points["status"] == "ok").all(), results.points["message"]
    series = results.series()
    return {v: series[series["variable"] == v].sort_values("time") for v in variables}


def peak(values):
    """The largest value of a periodic sampling, by the parabola through the three
    samples around it (as the runner takes it)."""
    i = int(np.argmax(values))
    a, b, c = values[i - 1], values[i], values[(i + 1) % len(values)]
    return b - (a - c) ** 2 / (8 * (a - 2 * b + c))


@pytest.mark.parametrize("damping,version", [(0.5, "2.0"), (0.1, "2.0"), (0.1, "3.0")])
def test_the_steady_cycle_is_the_long_transients_last_revolution(fmu_path, fmu3_path, tmp_path,
                                                                  damping, version):
    """The transient, run by the FMU's own co-simulation until a perturbation would have
    shrunk to 1e-12, sampled at 2048 points over its last period: every metric and the
    period within 1e-6 of the cycle's (of FMI 2.0's or FMI 3.0's Model Exchange)."""
    fmu = fmu_path if version == "2.0" else fmu3_path
    parameters = {"d12": damping, "d34": damping}
    point = sweep(cycle_spec(parameters, listed(J1=[0.5])), fmu,
                  tmp_path / "cycle").points.iloc[0]
    assert point["status"] == "ok", point["message"]
    assert point["cycle_margin"] > 0 and point["cycle_residual"] <= 1e-10
    period, samples = point["cycle_period"], 2048
    revolutions = math.ceil(math.log(1e-12) / math.log(point["cycle_multiplier"])) + 5
    step = period / samples
    runs = transient(fmu_path, tmp_path / "transient", dict(parameters), step,
                     revolutions * samples * step, ["rod_force", "omega2", "phi2"])
    force = runs["rod_force"]["value"].to_numpy()[-samples - 1:-1]
    speed = runs["omega2"]["value"].to_numpy()[-samples - 1:-1]
    seen = {"peak": peak(force), "low": -peak(-force), "swing": peak(force) + peak(-force),
            "speed": speed.mean(), "rms": math.sqrt(np.mean(force ** 2)),
            "second": 2 * abs(np.fft.rfft(force)[2]) / samples}
    for name, value in seen.items():
        assert abs(point[name] - value) <= 1e-6 * abs(value), (name, point[name], value)
    angle = CubicSpline(runs["phi2"]["time"].to_numpy(), runs["phi2"]["value"].to_numpy())
    end = revolutions * period
    turns = math.floor(angle(end) / TAU)
    crossings = [brentq(lambda t: angle(t) - TAU * k, end - 3 * period, end, xtol=1e-13)
                 for k in (turns - 1, turns)]
    assert abs((crossings[1] - crossings[0]) - period) <= 1e-6 * period


def cycle_of(fmu, out, parameters, **cycle):
    point = sweep(cycle_spec(parameters, listed(J1=[0.5]), metrics={}, **cycle), fmu,
                  out).points.iloc[0]
    assert point["status"] == "ok", point["message"]
    return point


def test_the_multipliers_agree_with_a_difference_monodromy(fmu_path, tmp_path):
    """The variational equations (the FMU's directional derivatives) and central
    differences of runs over the cycle give the same Floquet multipliers within 1e-6."""
    parameters = {"d12": 0.1, "d34": 0.1}
    exact = cycle_of(fmu_path, tmp_path / "variational", parameters, monodromy="variational")
    differences = cycle_of(fmu_path, tmp_path / "differences", parameters,
                           monodromy="differences")
    for part in ("re", "im"):
        a = np.asarray(exact[f"cycle_multipliers_{part}"])
        b = np.asarray(differences[f"cycle_multipliers_{part}"])
        assert len(a) == 5 and np.abs(a - b).max() <= 1e-6, (a, b)
    # A lightly damped spring: a complex pair inside the unit circle leads, the rocker
    # spring's mode (its eigenvector mostly the load's speed).
    assert 0.5 < exact["cycle_multiplier"] < 1 and exact["cycle_multipliers_im"][0] != 0
    assert exact["cycle_mode"].startswith("omega4 9"), exact["cycle_mode"]


def test_the_largest_multiplier_is_the_decay_of_a_perturbation_in_a_long_run(fmu_path,
                                                                           tmp_path):
    """Start the FMU's co-simulation on the cycle's section state with omega4 nudged, and
    read omega4 each time the crank passes the section: the nudge decays as the leading
    complex pair μ, ρ = |μ|; Prony's fit of s[k+2] = p s[k+1] + q s[k] gives ρ² = −q,
    within 1 % of the cycle's largest multiplier."""
    parameters = {"d12": 0.1, "d34": 0.1}
    spec = cycle_spec(parameters, listed(J1=[0.5]), metrics={"speed": METRICS["speed"]},
                      keep=["omega2", "phi3"])
    results = sweep(spec, fmu_path, tmp_path / "cycle")
    point = results.points.iloc[0]
    # A kept variable is kept whether or not a metric reads it too.
    series = results.series()
    kept = series[series["variable"] == "omega2"]["value"].to_numpy()
    assert len(kept) == 2048 and kept.mean() == pytest.approx(point["speed"], rel=1e-14)
    x = dict(zip(["phi1", "loop_angle", "phi4", "omega1", "loop_speed", "omega4"],
                 point["cycle_state"]))
    phi3 = series[series["variable"] == "phi3"].sort_values("time")["value"].iloc[0]
    start = {"phi2_0": 0.0, "twist12_0": x["phi1"] - x["loop_angle"],
             "twist34_0": phi3 - x["phi4"], "omega1_0": x["omega1"],
             "omega2_0": x["loop_speed"], "omega4_0": x["omega4"] + 1e-2}
    period, revolutions = point["cycle_period"], 45
    step = period / 256
    runs = transient(fmu_path, tmp_path / "nudged", {**parameters, **start}, step,
                     revolutions * 256 * step, ["phi2", "omega4"])
    t = runs["phi2"]["time"].to_numpy()
    angle = CubicSpline(t, runs["phi2"]["value"].to_numpy())
    omega4 = CubicSpline(t, runs["omega4"]["value"].to_numpy())
    nudge = np.array([omega4(brentq(lambda s: angle(s) - TAU * k, (k - 0.3) * period,
                                    (k + 0.3) * period, xtol=1e-13)) - x["omega4"]
                      for k in range(1, revolutions)])
    # After four revolutions the faster modes (|μ| < 0.1) are below 1e-4 of the nudge.
    s = nudge[4:]
    (p, q), *_ = np.linalg.lstsq(np.column_stack([s[1:-1], s[:-2]]), s[2:], rcond=None)
    seen = math.sqrt(-q)
    assert abs(seen / point["cycle_multiplier"] - 1) <= 0.01, (seen, point["cycle_multiplier"])



def rocker_ratio(phi2, l=0.5, l2=0.05, l3=0.5, rod=0.7, guess=math.pi / 2):
    """dφ3/dφ2 of the four-bar from its geometry alone (O2 at the origin, O3 at (l, 0),
    the assembly with φ3 nearest the guess), by a central difference of the closure."""
    def rocker(q):
        a2 = np.array([l2 * math.cos(q), l2 * math.sin(q)]) - np.array([l, 0.0])
        d = math.hypot(*a2)
        base = math.atan2(a2[1], a2[0])
        spread = math.acos((d * d + l3 * l3 - rod * rod) / (2 * d * l3))
        return min((base + s * spread for s in (1, -1)),
                   key=lambda p: abs(math.remainder(p - guess, TAU)))
    h = 1e-6
    return math.remainder(rocker(phi2 + h) - rocker(phi2 - h), TAU) / (2 * h)


@pytest.mark.parametrize("phi2", [0.0, 0.7, 2.0, 4.0])
def test_modes_are_the_spectrum_of_small_free_oscillations(fmu_path, phi2):
    """At rest with the laws off, at crank angle φ2: the modes of A (the FMU's Jacobian)
    are the undamped frequencies of M q'' + K q = 0 in q = (φ1, φ2, φ4), written here from
    the inertias, the springs and the four-bar's ratio r = dφ3/dφ2 alone: M = diag(J1,
    J2 + J3 r², J4), K from ½k12(φ1 − φ2)² + ½k34(φ3 − φ4)²; within 0.5 %."""
    found = linearise(fmu_path, {"builtin_laws": 0, "phi2_0": phi2})
    r = rocker_ratio(phi2)
    (j1, j2, j3, j4), (k12, k34) = (0.5, 0.2, 0.3, 0.7), (100.0, 100.0)
    mass = np.diag([j1, j2 + j3 * r * r, j4])
    stiffness = np.array([[k12, -k12, 0.0], [-k12, k12 + k34 * r * r, -k34 * r],
                          [0.0, -k34 * r, k34]])
    squares = eigh(stiffness, mass, eigvals_only=True)
    expected = np.sqrt(squares[squares > 1e-9 * squares.max()]) / TAU
    assert len(found.frequencies) == 2 == len(expected)
    assert np.allclose(found.frequencies, expected, rtol=5e-3, atol=0), (found.frequencies,
                                                                        expected)
    assert np.allclose(found.dampings, 0.0, atol=1e-9)
    # The linearisation's other blocks: the motor torque accelerates body 1 alone.
    assert found.inputs == ["M_m", "M_r"] and found.B.shape == (6, 2)
    assert found.B[3, 0] == pytest.approx(1 / j1) and found.B[:3].any() == False  # noqa: E712


def test_rod_force_resonates_where_order_lines_cross_a_mode(fmu_path, tmp_path):
    """Over a sweep of the motor law's constant (the crank speed), lightly damped: the
    rod force's swing and its harmonic of order k peak within 2 % of the crank frequency
    where k times it meets the spring mode the Campbell diagram shows (orders 2 and 3 for
    the swing, which order 4 is too weak to lift; orders 2 to 4 for the harmonics)."""
    metrics = {"swing": {"variable": "rod_force", "kind": "peak_to_peak"},
               **{f"h{k}": {"variable": "rod_force", "kind": "harmonic", "order": k}
                  for k in (2, 3, 4)}}
    spec = cycle_spec({"d12": 0.02, "d34": 0.02}, {"parameters": {"Mm_a0": {
        "linspace": [50, 175, 126]}}}, metrics, tolerance=1e-9, modes=8)
    points = sweep(spec, fmu_path, tmp_path / "out").points
    assert (points["status"] == "ok").all(), points["message"]
    crank = 1 / points["cycle_period"].to_numpy()
    mode = np.array([hz[0] for hz in points["cycle_modes_hz"]])
    for k, columns in ((2, ("swing", "h2")), (3, ("swing", "h3")), (4, ("h4",))):
        gap = k * crank - mode
        i = int(np.nonzero(np.diff(np.sign(gap)))[0][0])
        crossing = crank[i] - gap[i] * (crank[i + 1] - crank[i]) / (gap[i + 1] - gap[i])
        near = np.abs(crank / crossing - 1) <= 0.1
        for column in columns:
            values = points[column].to_numpy()
            j = int(np.flatnonzero(near)[np.argmax(values[near])])
            assert 0 < j < len(values) - 1 and values[j] > 1.2 * min(values[j - 3], values[j + 3])
            assert abs(crank[j] / crossing - 1) <= 0.02, (k, column, crank[j], crossing)


def test_points_without_a_steady_cycle_say_why(fmu_path, tmp_path):
    """A conservative run (laws off, no damper: every multiplier on the unit circle), a
    free run that dies away, a linkage whose change point lies on the way: rows that say
    why, with no number in a metric or a cycle column; the good point beside them runs."""
    spec = cycle_spec({"omega1_0": 4.0, "omega2_0": 4.0, "phi2_0": 1.5707963267948966,
                       "l3": 0.5},
                      listed(builtin_laws=[False, False, False, True], d34=[0.0, 0.5, 0.0, 0.05],
                             L=[0.7, 0.7, 0.95, 0.7]), metrics={"swing": METRICS["swing"]},
                      tolerance=1e-9)
    spec["scenario"]["stop"] = 60.0
    points = sweep(spec, fmu_path, tmp_path / "out").points
    assert list(points["status"]) == ["no_cycle", "no_cycle", "no_cycle", "ok"]
    said = list(points["message"])
    assert "unit circle" in said[0] and "undamped" in said[0]
    assert "did not converge" in said[1] or "did not advance" in said[1]
    assert "event indicator" in said[2] and "change point" in said[2]
    failed = points.iloc[:3]
    assert failed["swing"].isna().all() and failed["cycle_period"].isna().all()
    assert points["swing"].iloc[3] > 0


def test_mistakes_in_a_cycle_are_refused_by_field_in_one_run(fmu_path, tmp_path):
    """Every mistake of a [cycle] table, of its metrics and of its names against the FMU,
    in one run: the runner holds the table's rules and answers them all at once."""
    spec = cycle_spec({}, listed(J1=[0.5]), {
        "a": {"variable": "rod_force", "kind": "final"},
        "b": {"variable": "rod_force", "kind": "max", "from": 2.0},
        "c": {"variable": "rod_force", "kind": "harmonic"},
        "d": {"variable": "rod_force", "kind": "max", "extremes": "between"}},
        state="phi2", advance=-1.0, shifted=["phi9"], monodromy="guess", samples=4,
        keep=["n_steps"], sampels=8)
    with pytest.raises(SpecError) as raised:
        sweep(spec, fmu_path, tmp_path / "out")
    fields = {e.field: e.rule for e in raised.value.errors}
    assert set(fields) == {"cycle.advance", "cycle.monodromy", "cycle.samples", "cycle.sampels",
                           "cycle.state", "cycle.shifted[0]", "cycle.keep[0]",
                           "outputs.metrics.a.kind", "outputs.metrics.b.from",
                           "outputs.metrics.c.order", "outputs.metrics.d.extremes"}, fields
    assert "whole number in [8, " in fields["cycle.samples"]
    assert "did you mean samples" in fields["cycle.sampels"]
    assert "not a continuous state" in fields["cycle.state"] and "loop_angle" in fields["cycle.state"]
    assert "no variable named \"phi9\"" in fields["cycle.shifted[0]"]
    assert not (tmp_path / "out").exists()
    # The old name of the advance is told its new one.
    spec = cycle_spec({}, listed(J1=[0.5]), metrics={})
    spec["cycle"]["period"] = spec["cycle"].pop("advance")
    with pytest.raises(SpecError) as raised:
        sweep(spec, fmu_path, tmp_path / "out")
    assert raised.value.field == "cycle.period" and "advance" in raised.value.rule


def test_a_cycle_needs_model_exchange(motor_path, fmu_path, tmp_path):
    spec = cycle_spec({}, listed(R=[1.0]), metrics={})
    with pytest.raises(SpecError) as raised:
        sweep(spec, motor_path, tmp_path / "out")
    assert raised.value.field == "cycle" and "Model Exchange" in raised.value.rule
    spec = cycle_spec({}, listed(J1=[0.5]), metrics={})
    spec["scenario"]["interface"] = "co_simulation"
    with pytest.raises(SpecError) as raised:
        sweep(spec, fmu_path, tmp_path / "out")
    assert raised.value.field == "scenario.interface"


def test_a_cycle_grid_gives_the_same_table_on_any_number_of_workers(fmu_path, tmp_path):
    """Each point of a grid of steady cycles starts from its neighbours' cycles along its
    row, or from its own transient at a row's start, whatever ran where: serially and on
    2 and 3 workers the table is the same bit for bit (the times and workers aside), every
    point with its cycle."""
    spec = cycle_spec({"d12": 0.05, "d34": 0.05},
                      {"parameters": {"Mm_a0": {"linspace": [60, 200, 15]},
                                      "k34": {"linspace": [60, 160, 6]}}},
                      metrics={"peak": METRICS["peak"], "swing": METRICS["swing"]},
                      tolerance=1e-8, modes=2)
    spec["scenario"]["stop"] = 400.0
    tables = []
    for engine in ({"serial": True}, {"workers": 2}, {"workers": 3}):
        out = tmp_path / str(len(tables))
        points = run_sweep(spec, fmu=fmu_path, out=out, progress=False, plots=False,
                           **engine).points
        tables.append(points.drop(columns=["wall_s", "worker"]).sort_values("point"))
    assert (tables[0]["status"] == "ok").all(), tables[0]["message"].unique()
    assert tables[0]["cycle_continued"].sum() > 60
    for other in tables[1:]:
        pd.testing.assert_frame_equal(other.reset_index(drop=True),
                                      tables[0].reset_index(drop=True), check_exact=True)


@pytest.mark.parametrize("call", ["fmi2SetTime", "fmi2SetContinuousStates",
                                  "fmi2GetDerivatives", "fmi2GetReal",
                                  "fmi2GetDirectionalDerivative"])
def test_nothing_is_called_after_an_fmu_returns_error(tmp_path, call):
    """A rotor whose `call` returns Error at its n-th call: the cycle's search stops there
    (the row says the FMU's error; the rotor says so of any call after it, and none
    comes), and a rotor that never fails turns round its steady cycle."""
    calls = ["fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives", "fmi2GetReal",
             "fmi2GetDirectionalDerivative"]
    rotor = faulty_rotor(tmp_path)
    spec = {"scenario": {"stop": 200.0, "step": 0.01, "tolerance": 1e-8,
                         "parameters": {"fail_call": calls.index(call) + 1}},
            "design": listed(fail_after=[1, 2, 5, 40, 300, 3000, 30000, 2 ** 30]),
            "cycle": {"state": "theta", "advance": TAU, "modes": 2, "samples": 64},
            "outputs": {"metrics": {"top": {"variable": "omega", "kind": "max"}}}}
    points = sweep(spec, rotor, tmp_path / "out").points
    said = list(points["message"])
    assert not any("called after" in m for m in said), said
    failed = points[points["status"] != "ok"]
    assert len(failed) >= 3, said
    assert (failed["status"] == "error").all() and all("fails on purpose" in m
                                                       for m in failed["message"]), said
    assert points["status"].iloc[-1] == "ok" and points["top"].iloc[-1] > 1.0


def test_a_cycle_keeps_to_the_points_time_budget(fmu_path, tmp_path):
    """scenario.timeout holds for a steady cycle's search as for a transient: a budget the
    search reaches mid-way stops it there, the row saying timeout and why."""
    spec = cycle_spec({"d34": 0.05}, listed(J1=[0.5]), metrics={"swing": METRICS["swing"]})
    free, budget, row = stopped_mid_way(spec, fmu_path, tmp_path)
    assert row["status"] == "timeout"
    assert row["message"].startswith("over the budget of") and "s per point" in row["message"]
    assert budget <= row["wall_s"] < 0.9 * free["wall_s"], (budget, row["wall_s"], free["wall_s"])
    assert np.isnan(row["swing"])


@pytest.mark.parametrize("through_starts", [False, True])
def test_the_linearisation_along_the_cycle_is_the_fmus_own(fmu_path, tmp_path, through_starts):
    """A, B, C and D at points along the steady cycle (``linearise(..., along=…)``, on
    Model Exchange or through the start values) against central differences of the FMU's
    derivatives and outputs at the same states and inputs, driven by FMPy: within 1e-8 of
    each matrix's size; the points evenly spaced over the cycle's period, the modes those
    of the sweep's row."""
    import fmpy
    from fmpy.fmi2 import FMU2Model
    parameters = {"d12": 0.1, "d34": 0.1}
    along = {**CYCLE, "modes": 4}
    if through_starts:
        along = {"state": "phi2", "advance": TAU, "shifted": ["phi1"], "modes": 4,
                 "starts": ["twist12_0", "twist34_0", "omega1_0", "omega2_0", "omega4_0"]}
    found = linearise(fmu_path, parameters, along=along)
    point = cycle_of(fmu_path, tmp_path / "cycle", dict(parameters), modes=4)
    assert [lin.t for lin in found] == pytest.approx(
        [k * point["cycle_period"] / 4 for k in range(4)], rel=1e-9, abs=1e-12)
    mean = np.mean([lin.frequencies for lin in found], axis=0)
    assert mean == pytest.approx(point["cycle_modes_hz"], rel=1e-6)
    md = fmpy.read_model_description(fmu_path)
    unzipped = fmpy.extract(fmu_path, unzipdir=tmp_path / "unzipped")
    fmu = FMU2Model(guid=md.guid, unzipDirectory=unzipped,
                    modelIdentifier=md.modelExchange.modelIdentifier, instanceName="lin")
    fmu.instantiate()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu.setupExperiment(tolerance=1e-10)
    fmu.enterInitializationMode()
    fmu.setReal([vr[k] for k in parameters], list(parameters.values()))
    fmu.exitInitializationMode()
    fmu.newDiscreteStates()
    fmu.enterContinuousTimeMode()
    lin = found[0]
    inputs, outputs = [vr[u] for u in lin.inputs], [vr[y] for y in lin.outputs]

    def rates(x, u):
        states, derivatives = (ctypes.c_double * len(x))(*x), (ctypes.c_double * len(x))()
        fmu.setContinuousStates(states, len(x))
        fmu.setReal(inputs, list(u))
        fmu.getDerivatives(derivatives, len(x))
        return np.asarray(derivatives[:]), np.asarray(fmu.getReal(outputs))

    for lin in found:
        fmu.setTime(lin.t)
        x, u = np.asarray(lin.x), np.zeros(len(inputs))
        columns = {"x": [], "u": []}
        for name, base in (("x", x), ("u", u)):
            for j in range(len(base)):
                h = 1e-6 * max(1.0, abs(base[j]))
                up, down = base.copy(), base.copy()
                up[j] += h
                down[j] -= h
                (f1, y1), (f0, y0) = (rates(up, u) if name == "x" else rates(x, up),
                                      rates(down, u) if name == "x" else rates(x, down))
                columns[name].append((np.concatenate([f1, y1]) - np.concatenate([f0, y0]))
                                     / (2 * h))
        n = len(x)
        by_x, by_u = np.column_stack(columns["x"]), np.column_stack(columns["u"])
        for mine, theirs in ((lin.A, by_x[:n]), (lin.C, by_x[n:]), (lin.B, by_u[:n]),
                             (lin.D, by_u[n:])):
            assert np.abs(mine - theirs).max() <= 1e-8 * max(1.0, np.abs(theirs).max()), \
                (lin.t, mine, theirs)
    fmu.terminate()
    fmu.freeInstance()
