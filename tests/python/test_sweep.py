"""The sweep (fmusweep and its native runner) against FMPy and by hand, on the packed
FMU and on a small C FMU that fails on purpose."""

import copy

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

import fmusweep
from fmusweep import SpecError, native, run_sweep
from sweep_helpers import PAPER_LAWS, faulty_fmu, grid_spec, in_description, repacked


def test_a_grid_runs_and_a_point_that_cannot_assemble_is_a_row(fmu_path, tmp_path):
    results = run_sweep(grid_spec(), fmu=fmu_path, out=tmp_path / "out", serial=True,
                        progress=False)
    p = results.points
    assert len(p) == 12 and list(p["point"]) == list(range(12))
    bad = p[p["L"] == 1.2]
    assert (bad["status"] == "error").all(), bad[["status", "message"]]
    assert bad["message"].str.contains("L").all()
    assert bad["peak_rod_force"].isna().all()
    good = p[p["L"] != 1.2]
    assert (good["status"] == "ok").all()
    assert (good["peak_rod_force"] > 10).all() and (good["n_rhs"] > 100).all()
    assert p["point_id"].nunique() == 12
    # A heatmap per metric; the unassemblable row shows as missing cells.
    assert sorted(path.name for path in results.plots) == [
        "heatmap_n_rhs.png", "heatmap_omega1_ripple.png", "heatmap_peak_rod_force.png"]
    assert all(path.stat().st_size > 10_000 for path in results.plots)
    again = fmusweep.load_results(tmp_path / "out")
    assert again.points.drop(columns=["wall_s", "worker"]).equals(p.drop(columns=["wall_s", "worker"]))


def test_a_grid_without_plots_leaves_its_points_on_disk(fmu_path, tmp_path):
    """The client holds no point of a sweep it need not read: a grid has no indices to
    compute, so without plots its points stay in points.parquet until asked for (what
    keeps the client's memory flat over 10⁶ points)."""
    results = run_sweep(grid_spec(), fmu=fmu_path, out=tmp_path / "out", serial=True,
                        progress=False, plots=False)
    assert results._points is None and results.sensitivity == {}
    assert len(results.points) == 12


def test_a_boolean_parameter_is_fixed_and_swept_by_true_or_false(fmu_path, tmp_path):
    """builtin_laws off leaves the mechanism without torque: at rest it stays at rest. A
    number for a Boolean is refused, with what to write."""
    metrics = {"omega1": {"variable": "omega1", "kind": "final"},
               "energy": {"variable": "energy", "kind": "max"}}
    fixed = {"scenario": {"stop": 1.0, "step": 0.01, "parameters": {"builtin_laws": False}},
             "design": {"kind": "list", "parameters": {"k34": {"values": [50.0, 100.0]}}},
             "outputs": {"metrics": metrics}}
    p = run_sweep(fixed, fmu=fmu_path, out=tmp_path / "fixed", serial=True, progress=False).points
    assert (p["status"] == "ok").all() and (p["omega1"] == 0.0).all() and (p["energy"] == 0.0).all()
    swept = dict(fixed, scenario={"stop": 1.0, "step": 0.01},
                 design={"kind": "list", "parameters": {"builtin_laws": {"values": [False, True]}}})
    p = run_sweep(swept, fmu=fmu_path, out=tmp_path / "swept", serial=True, progress=False).points
    assert list(p["omega1"] == 0.0) == [True, False] and p["omega1"].iloc[1] > 3.0, p
    for values in ([0, 1], [0, 2]):
        with pytest.raises(SpecError, match="builtin_laws is a Boolean: write true or false"):
            run_sweep(dict(swept, design={"kind": "list",
                                          "parameters": {"builtin_laws": {"values": values}}}),
                      fmu=fmu_path, out=tmp_path / "bad", serial=True, progress=False)
    fixed["scenario"]["parameters"]["builtin_laws"] = 0
    with pytest.raises(SpecError, match="scenario.parameters.builtin_laws: builtin_laws is a "
                                        "Boolean: write true or false, got 0"):
        run_sweep(fixed, fmu=fmu_path, out=tmp_path / "bad", serial=True, progress=False)


def _broken(change):
    spec = grid_spec()
    change(spec)
    return spec


SPEC_ERRORS = {
    "design.parameters.Jx": lambda s: s["design"]["parameters"].update(Jx={"values": [1.0]}),
    "design.parameters.J1": lambda s: s["design"]["parameters"].update(J1={"values": [0.5, -1.0]}),
    "design.parameters.k34.values": lambda s: s["design"]["parameters"].update(k34={"values": []}),
    "design.parameters.k34.linspace": lambda s: s["design"]["parameters"].update(k34={"linspace": [1, 2]}),
    "design.parameters.phi1": lambda s: s["design"]["parameters"].update(phi1={"values": [0.0]}),
    "design.parameters.solver": lambda s: s["design"]["parameters"].update(solver={"values": [1.5]}),
    "design.parameters": lambda s: s["design"].update(parameters={}),
    # A column that the scenario also sets: one of the two would be ignored without a word.
    "design.parameters.M_m": lambda s: (s["scenario"].update(inputs={"M_m": 5.0}),
                                        s["design"]["parameters"].update(M_m={"values": [0.0, 20.0]})),
    "design.parameters.k34": lambda s: s["scenario"]["parameters"].update(k34=100.0),
    "design.kind": lambda s: s["design"].update(kind="random"),
    "design.samples": lambda s: s["design"].update(kind="sobol", seed=1, samples=100, parameters={
        "J1": {"range": [0.1, 1.0]}}),
    "design.parameters.J1.range": lambda s: s["design"].update(kind="lhs", seed=1, samples=10, parameters={
        "J1": {"range": [1.0, 0.1]}}),
    "design.seed": lambda s: s["design"].update(kind="lhs", samples=10, parameters={
        "J1": {"range": [0.1, 1.0]}}),
    "outputs.metrics.peak_rod_force.variable": lambda s: s["outputs"]["metrics"]["peak_rod_force"].update(
        variable="rod_forc"),
    "outputs.metrics.n_rhs.kind": lambda s: s["outputs"]["metrics"]["n_rhs"].update(kind="median"),
    "outputs.series.interval": lambda s: s["outputs"].update(series={"variables": ["phi1"], "interval": 0.015}),
    "scenario.step": lambda s: s["scenario"].update(step=0.03),
    "scenario.stpo": lambda s: s["scenario"].update(stpo=3),
    "scenario.parameters.k12": lambda s: s["scenario"]["parameters"].update(k12=-5.0),
    "scenario.inputs.phi1": lambda s: s["scenario"].update(inputs={"phi1": 1.0}),
    "scenario.inputs.M_m.times": lambda s: s["scenario"].update(inputs={"M_m": {"times": [1, 0],
                                                                                "values": [0, 1]}}),
}


@pytest.mark.parametrize("field", sorted(SPEC_ERRORS))
def test_a_broken_spec_is_refused_before_anything_runs_naming_the_field(fmu_path, tmp_path, field):
    spec = _broken(SPEC_ERRORS[field])
    with pytest.raises(SpecError) as refused:
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False)
    assert refused.value.field == field, str(refused.value)
    assert not (tmp_path / "out").exists()


def test_every_mistake_of_a_spec_is_reported_in_one_pass(fmu_path, tmp_path):
    """Its own fields' mistakes together, every name the FMU lacks together (each with the
    nearest name it has), and both kinds together when a spec has both."""
    spec = grid_spec()
    spec["scenario"]["step"] = 0.03
    spec["design"]["kind"] = "random"
    spec["outputs"]["metrics"]["n_rhs"]["kind"] = "median"
    with pytest.raises(SpecError) as refused:
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False)
    said = str(refused.value)
    assert "3 problems" in said, said
    for field in ("scenario.step", "design.kind", "outputs.metrics.n_rhs.kind"):
        assert field in said, (field, said)
    spec = grid_spec(k43={"values": [1.0]})
    spec["outputs"]["metrics"]["peak_rod_force"]["variable"] = "rod_forc"
    with pytest.raises(SpecError) as refused:
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False)
    said = str(refused.value)
    assert "2 problems" in said, said
    assert "did you mean 'rod_force'" in said and "did you mean 'k34'" in said, said
    # Both kinds at once: a field's mistake and a name the FMU lacks, in one run.
    spec = grid_spec(k43={"values": [1.0]})
    spec["scenario"]["step"] = 0.03
    with pytest.raises(SpecError) as refused:
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False)
    said = str(refused.value)
    assert "2 problems" in said and "scenario.step" in said, said
    assert "design.parameters.k43" in said and "did you mean 'k34'" in said, said
    assert not (tmp_path / "out").exists()


def test_an_fmi1_archive_is_refused_naming_the_users_file(fmu_path, tmp_path):
    old = repacked(fmu_path, tmp_path / "Old.fmu",
                   in_description(b'fmiVersion="2.0"', b'fmiVersion="1.0"'))
    with pytest.raises(SpecError) as refused:
        run_sweep(grid_spec(), fmu=old, out=tmp_path / "out", serial=True, progress=False)
    assert refused.value.field == "fmu"
    said = str(refused.value)
    assert str(old) in said and "FMI 1.0" in said and "FMI 2.0 and FMI 3.0" in said, said
    assert "fmusweep-" not in said, "the folder it was unpacked into is named: " + said
    assert not (tmp_path / "out").exists()


def test_the_fmus_own_rule_is_in_the_message(fmu_path, tmp_path):
    spec = _broken(SPEC_ERRORS["design.parameters.J1"])
    with pytest.raises(SpecError, match=r"J1 = -1 .*must be > 0"):
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False)


def _fmpy_series(unzipped, points, names, stop, step, variables):
    """The same master loop in FMPy: one instance, reset between points, the same calls."""
    md = read_model_description(unzipped)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="fmpy")
    slave.instantiate()
    n = round(stop / step)
    times = [k * step for k in range(n)] + [stop]
    real = [vr[v] for v in variables if v != "n_rhs"]
    runs = []
    for i, row in enumerate(points):
        if i:
            slave.reset()
        slave.setupExperiment(tolerance=1e-8, startTime=0.0, stopTime=stop)
        slave.enterInitializationMode()
        values = dict(PAPER_LAWS, **dict(zip(names, row)))
        slave.setReal([vr[k] for k in values], list(values.values()))
        slave.exitInitializationMode()
        rows = []
        for k in range(n + 1):
            if k:
                slave.doStep(times[k - 1], times[k] - times[k - 1])
            rows.append([times[k]] + slave.getReal(real) + [float(slave.getInteger([vr["n_rhs"]])[0])])
        runs.append(np.array(rows))
    slave.terminate()
    slave.freeInstance()
    return runs


def test_runner_and_fmpy_agree_to_the_last_bit_and_metrics_match_a_hand_computation(
        fmu_path, unzipped, tmp_path):
    spec = grid_spec(stop=3.0, k34={"values": [60.0, 250.0]}, L={"values": [0.55, 0.8]})
    spec["design"] = {"kind": "list", "parameters": {"k34": {"values": [60.0, 250.0, 900.0]},
                                                     "L": {"values": [0.55, 0.8, 0.7]}}}
    spec["outputs"]["metrics"].update({
        "omega1_mean": {"variable": "omega1", "kind": "mean", "from": 0.5, "to": 2.5},
        "omega1_rms": {"variable": "omega1", "kind": "rms", "from": 0.5, "to": 2.5},
        "phi1_final": {"variable": "phi1", "kind": "final"},
        "rod_force_min": {"variable": "rod_force", "kind": "min"},
        "rod_force_max": {"variable": "rod_force", "kind": "max"},
    })
    # By hand, the extremes at the communication points: as the metric asks for them.
    for metric in spec["outputs"]["metrics"].values():
        metric["extremes"] = "sampled"
    variables = ["rod_force", "omega1", "phi1", "n_rhs"]
    spec["outputs"]["series"] = {"variables": variables, "interval": 0.01}
    results = run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False,
                        plots=False)
    series = results.series()
    names = ["k34", "L"]
    theirs = _fmpy_series(unzipped, results.points[names].to_numpy(), names, 3.0, 0.01, variables)
    for point, fmpy_run in enumerate(theirs):
        ours = series[series["point"] == point].pivot(index="time", columns="variable", values="value")
        np.testing.assert_array_equal(ours.index.to_numpy(), fmpy_run[:, 0])
        for j, name in enumerate(variables):
            np.testing.assert_array_equal(ours[name].to_numpy(), fmpy_run[:, j + 1], err_msg=name)
        t, force, omega1, phi1, n_rhs = fmpy_run.T
        row = results.points.iloc[point]
        assert row["peak_rod_force"] == np.max(np.abs(force))
        assert row["rod_force_min"] == np.min(force) and row["rod_force_max"] == np.max(force)
        late = t >= 1.0 - 1e-9
        assert row["omega1_ripple"] == np.ptp(omega1[late])
        assert row["phi1_final"] == phi1[-1] and row["n_rhs"] == n_rhs[-1]
        window = (t >= 0.5 - 1e-9) & (t <= 2.5 + 1e-9)
        span = t[window][-1] - t[window][0]
        # The runner sums the trapezoids in time order; numpy sums pairwise: the two
        # agree to rounding.
        mean = np.trapezoid(omega1[window], t[window]) / span
        rms = np.sqrt(np.trapezoid(omega1[window] ** 2, t[window]) / span)
        assert row["omega1_mean"] == pytest.approx(mean, rel=1e-13, abs=0)
        assert row["omega1_rms"] == pytest.approx(rms, rel=1e-13, abs=0)


def test_a_transient_peak_is_found_between_communication_points(fmu_path, tmp_path):
    """The rod force's peak, trough and swing over paper case 1's last 5 s at a 10 ms grid
    against a 0.1 ms run's: found between the communication points from the FMU's output
    derivatives (co-simulation) or by a parabola (Model Exchange, which gives none here),
    each far closer than the largest sample, which `extremes = "sampled"` still gives."""
    kinds = {"peak": "max", "low": "min", "swing": "peak_to_peak", "size": "peak_abs"}

    def measured(step, interface="co_simulation", extremes=None, out="run"):
        metrics = {name: {"variable": "rod_force", "kind": kind, "from": 5.0}
                   for name, kind in kinds.items()}
        for metric in metrics.values():
            if extremes is not None:
                metric["extremes"] = extremes
        spec = {"scenario": {"stop": 10.0, "step": step, "tolerance": 1e-11,
                             "interface": interface},
                "design": {"kind": "list", "parameters": {"J1": {"values": [0.5]}}},
                "outputs": {"metrics": metrics,
                            "series": {"variables": ["rod_force"], "interval": step}}}
        results = run_sweep(spec, fmu=fmu_path, out=tmp_path / out, serial=True,
                            progress=False, plots=False)
        assert (results.points["status"] == "ok").all(), results.points["message"]
        return results

    truth = measured(1e-4, out="fine").points.iloc[0]
    coarse = measured(0.01, out="coarse").points.iloc[0]
    exchange = measured(0.01, "model_exchange", out="exchange").points.iloc[0]
    sampled = measured(0.01, extremes="sampled", out="sampled")
    at_points = sampled.series()
    force = at_points[at_points["time"] >= 5.0 - 1e-9]["value"].to_numpy()
    row = sampled.points.iloc[0]
    assert (row["peak"], row["low"], row["swing"]) == (force.max(), force.min(), np.ptp(force))
    for name in kinds:
        scale = abs(truth["size"])
        missed = abs(row[name] - truth[name]) / scale
        assert missed > 1e-6, (name, missed)
        assert abs(coarse[name] - truth[name]) / scale < 1e-3 * missed, name
        assert abs(exchange[name] - truth[name]) / scale < 0.1 * missed, name


def test_series_are_decimated_to_the_interval(fmu_path, tmp_path):
    spec = grid_spec(stop=1.0, k34={"values": [100.0, 200.0]})
    spec["outputs"]["series"] = {"variables": ["phi1", "omega4"], "interval": 0.25}
    results = run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False,
                        plots=False)
    series = results.series()
    assert len(series) == 2 * 2 * 5
    np.testing.assert_array_equal(np.unique(series["time"]), [0.0, 0.25, 0.5, 0.75, 1.0])
    assert set(series["variable"]) == {"phi1", "omega4"}


@pytest.fixture(scope="module")
def faulty(tmp_path_factory):
    return faulty_fmu(tmp_path_factory.mktemp("faulty"))


FAULTY = {"scenario": {"stop": 1.0, "step": 0.01, "timeout": 0.05},
          "outputs": {"metrics": {"y_final": {"variable": "y", "kind": "final"}}}}


def test_each_failure_is_one_row_and_the_others_finish(faulty, tmp_path, monkeypatch):
    # The hung step (x = 7) is killed after 2 × 0.05 s + this grace.
    monkeypatch.setattr(native, "HARD_DEADLINE_GRACE_S", 0.5)
    xs = [1.0, 13.0, 2.0, 5.0, 3.0, 7.0, 21.0, 4.0, 13.0, 6.0]
    spec = dict(FAULTY, design={"kind": "list", "parameters": {"x": {"values": xs}}})
    results = run_sweep(spec, fmu=faulty, out=tmp_path / "out", serial=True, progress=False,
                        plots=False)
    p = results.points.set_index("x")
    status = results.points["status"].tolist()
    assert status == ["ok", "crashed", "ok", "discard", "timeout", "timeout", "ok", "ok",
                      "crashed", "ok"]
    assert p.loc[13.0, "message"].str.contains("SIGSEGV").all()
    assert "x = 5 cannot pass t = 0.5" in p.loc[5.0, "message"]
    assert "budget" in p.loc[3.0, "message"] and "killed" in p.loc[7.0, "message"]
    # The survivors' values are right: y = x·t at t = 1, even after a crash and a kill.
    for x in (1.0, 2.0, 21.0, 4.0, 6.0):
        assert p.loc[x, "y_final"] == x


def test_a_value_the_fmu_refuses_is_a_spec_error(faulty, tmp_path):
    spec = dict(FAULTY, design={"kind": "list", "parameters": {"x": {"values": [1.0, -2.0]}}})
    with pytest.raises(SpecError, match="x = -2.*x must be >= 0") as refused:
        run_sweep(spec, fmu=faulty, out=tmp_path / "out", serial=True, progress=False)
    assert refused.value.field == "design.parameters.x"


ISHIGAMI_S1 = [0.3139, 0.4424, 0.0]
ISHIGAMI_ST = [0.5576, 0.4424, 0.2437]


def test_sobol_indices_recover_ishigami():
    spec = fmusweep.Spec.from_dict({
        "scenario": {"stop": 1.0, "step": 1.0},
        "design": {"kind": "sobol", "seed": 3, "samples": 4096, "parameters": {
            name: {"range": [-np.pi, np.pi]} for name in ("x1", "x2", "x3")}},
        "outputs": {"metrics": {"f": {"variable": "f", "kind": "final"}}},
    }, ".")
    design = spec.points
    x1, x2, x3 = design.rows.T
    f = np.sin(x1) + 7 * np.sin(x2) ** 2 + 0.1 * x3 ** 4 * np.sin(x1)
    s = fmusweep.sobol_indices(design.problem, f, seed=3)
    for key, known in (("S1", ISHIGAMI_S1), ("ST", ISHIGAMI_ST)):
        error = np.abs(np.array(s[key]) - known)
        assert np.all(error <= np.array(s[f"{key}_conf"])), (key, s[key], s[f"{key}_conf"])


def test_sobol_on_the_fmu_finds_a_parameter_without_effect(fmu_path, tmp_path):
    # phi3_guess only picks the assembly; over this range it is always the same one.
    spec = {
        "scenario": {"stop": 2.0, "step": 0.01, "tolerance": 1e-8, "parameters": PAPER_LAWS},
        "design": {"kind": "sobol", "seed": 7, "samples": 64, "parameters": {
            "J1": {"range": [0.3, 0.8]}, "k34": {"range": [50.0, 300.0]},
            "phi3_guess": {"range": [1.2, 1.9]}}},
        "outputs": {"metrics": {"peak_rod_force": {"variable": "rod_force", "kind": "peak_abs"}}},
    }
    results = run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False)
    s = results.sensitivity["peak_rod_force"]
    assert s["names"] == ["J1", "k34", "phi3_guess"]
    assert abs(s["ST"][2]) < 1e-12 and abs(s["S1"][2]) < 1e-12, s
    # k34 dominates the peak force; J1 matters a little (ST 0.025 ± 0.014 at this seed).
    assert s["ST"][1] > 0.5 and s["ST"][0] > 0.005
    assert [path.name for path in results.plots] == ["scatter.png", "sobol_peak_rod_force.png"]


def test_latin_hypercube_is_seeded_and_within_its_ranges():
    raw = {"scenario": {"stop": 1.0, "step": 1.0},
           "design": {"kind": "lhs", "seed": 11, "samples": 50, "parameters": {
               "a": {"range": [1.0, 2.0]}, "b": {"range": [1e-3, 1e3], "log": True}}},
           "outputs": {"metrics": {"m": {"variable": "v", "kind": "max"}}}}
    one = fmusweep.Spec.from_dict(raw, ".").points
    two = fmusweep.Spec.from_dict(copy.deepcopy(raw), ".").points
    np.testing.assert_array_equal(one.rows, two.rows)
    a, b = one.rows.T
    assert a.min() >= 1 and a.max() <= 2 and b.min() >= 1e-3 and b.max() <= 1e3
    # One sample per stratum: each tenth of a's range holds exactly five points.
    assert np.all(np.bincount(np.floor((a - 1) * 10).astype(int), minlength=10) == 5)
    assert np.all(np.bincount(np.floor((np.log10(b) + 3) / 0.6).astype(int), minlength=10) == 5)


def test_a_coupled_ssp_system_sweeps_through_fmpy(fmu_path, tmp_path):
    """FMPy's path, asked for by engine = "fmpy": the file's own load parameters reach it
    (FMPy applies no binding of the file's, the sweep hands them over)."""
    import pathlib
    import sys
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples/dc_motor"))
    import ssp as example  # examples/dc_motor/ssp.py

    direct = example.run(fmu_path, tmp_path / "direct", stop_time=0.5)
    system = example.build_ssp(fmu_path, tmp_path / "system")
    spec = {
        "ssp": str(system),
        "system": {"engine": "fmpy"},
        "scenario": {"stop": 0.5, "step": 1e-3},
        "design": {"kind": "list", "parameters": {"mechanism.Mr_b0": {"values": [10.0, 20.0, 40.0]}}},
        "outputs": {"metrics": {
            "omega1_final": {"variable": "mechanism.omega1", "kind": "final"},
            "current_peak": {"variable": "motor.current", "kind": "peak_abs"}}},
    }
    results = run_sweep(spec, out=tmp_path / "out", serial=True, progress=False, plots=False)
    p = results.points
    assert (p["status"] == "ok").all(), p["message"]
    # The point with the example's own load is the example's run, to the last bit.
    at_20 = p[p["mechanism.Mr_b0"] == 20.0].iloc[0]
    assert at_20["omega1_final"] == direct["mechanism.omega1"][-1]
    assert at_20["current_peak"] == np.max(np.abs(direct["motor.current"]))
    # The parameter reaches its component: three loads, three motions.
    assert p["omega1_final"].nunique() == 3
    assert results.meta["ssp_sha256"] and at_20["steps"] == 500
    # 10 s at 1 ms is 10 000 steps, ending at 10 s (an accumulated time took one more).
    long = run_sweep(dict(spec, scenario=dict(spec["scenario"], stop=10.0),
                          design={"kind": "list", "parameters": {"mechanism.Mr_b0": {"values": [20.0]}}}),
                     out=tmp_path / "long", serial=True, progress=False, plots=False).points.iloc[0]
    assert (long["status"], long["steps"], long["t_end"]) == ("ok", 10000, 10.0)
    with pytest.raises(SpecError) as refused:
        run_sweep(dict(spec, design={"kind": "list", "parameters": {"mechanism.Mr_b9": {"values": [1.0]}}}),
                  out=tmp_path / "bad", serial=True, progress=False)
    assert refused.value.field == "design.parameters.mechanism.Mr_b9"


def test_the_final_table_is_streamed_in_point_order_from_its_parts(tmp_path):
    """points.parquet is written a group of parts at a time (parts whose point ranges
    overlap, as a resumed sweep's do, sorted together), in point order."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    from fmusweep.store import ResultStore
    store = ResultStore(tmp_path, {"kind": "sweep", "spec_digest": "d", "fmu_sha256": "f",
                                   "format": 1}, resume=False)
    for points in ([0, 1, 2], [3, 4], [5, 7, 9], [6, 8], [10, 11]):
        store.write_batch(pa.table({"point": pa.array(points, pa.int64()),
                                    "status": pa.array(["ok"] * len(points))}), None)
    assert store.consolidate() == 12
    assert pq.read_table(tmp_path / "points.parquet")["point"].to_pylist() == list(range(12))


def test_a_new_design_kind_is_one_module(fmu_path, tmp_path, monkeypatch):
    """What a kind is lives in its module of fmusweep.designs: a kind registered there
    alone (here a seeded Halton sequence with its own field) has its fields checked, its
    seed asked for, its points made and swept, and its pictures drawn, with no other file
    knowing it."""
    from scipy.stats import qmc

    from typing import Literal

    from fmusweep import designs
    from fmusweep.designs.base import Design, DesignKind, DesignTable, RangeEntry
    from fmusweep.schema import field

    class HaltonTable(DesignTable):
        about = "A seeded Halton sequence over each column's range."
        kind: Literal["halton"] = field("the kind of design")
        seed: int = field("the sequence's scrambling seed", ge=0)
        points: int = field("the number of points", ge=1)
        parameters: dict[str, RangeEntry] = field("each column: range = [low, high]")

        @classmethod
        def count(cls, parts):
            return parts.get("points")

    def make(table, names):
        unit = qmc.Halton(d=len(names), seed=table.seed).random(table.points)
        low, high = (np.array([table.parameters[n].range[k] for n in names]) for k in (0, 1))
        return Design("halton", names, stored=low + unit * (high - low))

    halton = DesignKind("halton", HaltonTable, make=make)
    monkeypatch.setitem(designs.KINDS, "halton", halton)
    spec = {"scenario": {"stop": 0.2, "step": 0.01, "tolerance": 1e-6},
            "design": {"kind": "halton", "seed": 5, "points": 6,
                       "parameters": {"k12": {"range": [50.0, 150.0]},
                                      "k34": {"range": [50.0, 150.0]}}},
            "outputs": {"metrics": {"peak": {"variable": "rod_force", "kind": "peak_abs"}}}}
    results = run_sweep(spec, fmu=str(fmu_path), out=str(tmp_path / "out"), serial=True,
                        progress=False)
    assert len(results.points) == 6 and (results.points["status"] == "ok").all()
    assert results.points["k12"].between(50.0, 150.0).all()
    assert [p.name for p in results.plots] == ["scatter.png"] and results.report_html
    for field, value in (("samples", 6), ("seed", None)):
        wrong = copy.deepcopy(spec)
        wrong["design"][field] = value
        if value is None:
            del wrong["design"][field]
        with pytest.raises(SpecError) as refused:
            run_sweep(wrong, fmu=str(fmu_path), out=str(tmp_path / field), serial=True,
                      progress=False)
        assert f"design.{field}" in str(refused.value)
