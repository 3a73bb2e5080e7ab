"""Every mistake of a spec in one run, by construction: each table is read against its
declaration and the walk goes on past a wrong value, the rules between tables and the
checks against the FMU run over whatever was read, and the runner's rules of the plan are
asked in the same pass. Each case here took a new user two to five runs before; the last
test writes one mistake of every kind the docs list into each kind of spec."""

import math

import pytest

from fmusweep import SpecError, SpecWarning, fit, run_sweep
from sweep_helpers import PAPER_LAWS

TAU = 2 * math.pi
STARTS = ["twist12_0", "twist34_0", "omega1_0", "omega2_0", "omega4_0"]


def refused(spec, tmp_path, run=run_sweep, **options):
    """Every field the one run refuses, with its rule; nothing written."""
    kwargs = {"out": tmp_path / "out", "serial": True, **options}
    if run is run_sweep:
        kwargs["progress"] = False
    with pytest.raises(SpecError) as raised:
        run(spec, **kwargs)
    assert not (tmp_path / "out").exists()
    return {e.field: e.rule for e in getattr(raised.value, "errors", [raised.value])}


def grid(**scenario):
    return {"scenario": {"stop": 0.5, "step": 0.05, "tolerance": 1e-6,
                         "parameters": dict(PAPER_LAWS), **scenario},
            "design": {"kind": "grid", "parameters": {"k34": {"values": [100.0, 120.0]}}},
            "outputs": {"metrics": {"top": {"variable": "omega2", "kind": "max"}}}}


def test_two_unknown_fields_of_the_scenario(fmu_path, tmp_path):
    spec = grid(stpo=1.0, tolerence=1e-8)
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert set(said) == {"scenario.stpo", "scenario.tolerence"}, said
    assert "did you mean 'stop'" in said["scenario.stpo"]
    assert "did you mean 'tolerance'" in said["scenario.tolerence"]


def test_a_sobol_design_with_four_mistakes(fmu_path, tmp_path):
    spec = grid()
    spec["design"] = {"kind": "sobol", "samples": 100,
                      "parameters": {"k34": {"range": [400.0, 10.0]},
                                     "d34": {"range": [0.1, 1.0], "log": True}}}
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert set(said) == {"design.seed", "design.samples", "design.parameters.k34.range",
                         "design.parameters.d34.log"}, said
    assert said["design.seed"].startswith("is missing")
    assert "power of two, got 100" in said["design.samples"]
    assert "low < high, got [400, 10]" in said["design.parameters.k34.range"]
    assert "give range" not in said["design.parameters.d34.log"]
    assert "lhs" in said["design.parameters.d34.log"]


def test_a_system_table_with_mistakes_of_every_part(fmu_path, motor_path, tmp_path):
    spec = {"system": {"components": {"motor": str(motor_path), "mechanism": str(fmu_path)},
                       "connections": [["motor.torq", "mechanism.M_m"],
                                       ["mechanism.omega1", "motor.omega"]],
                       "coupling_tolerance": 3.0, "input_derivatives": 5, "engin": "native"},
            "scenario": {"stop": 0.5, "step": 0.05},
            "design": {"kind": "list", "parameters": {"k34": {"values": [100.0]}}},
            "outputs": {"metrics": {"w": {"variable": "omega1", "kind": "max"}}}}
    said = refused(spec, tmp_path)
    assert set(said) == {"system.coupling_tolerance", "system.input_derivatives",
                         "system.engin", "system.connections[0]", "design.parameters.k34",
                         "outputs.metrics.w.variable"}, said
    assert "(0, 1)" in said["system.coupling_tolerance"]
    # A name without its component's prefix is told the prefixed one.
    assert "did you mean 'mechanism.k34'" in said["design.parameters.k34"]
    assert "did you mean 'mechanism.omega1'" in said["outputs.metrics.w.variable"]


def test_a_cycle_through_the_start_values_with_every_kind_of_mistake(fmu_path, tmp_path):
    spec = grid(interface="model_exchange", stop=50.0)
    spec["design"] = {"kind": "list", "parameters": {"d34": {"values": [0.1]}}}
    spec["cycle"] = {"state": "phi22", "advance": TAU, "shifted": ["phi11"],
                     "keep": ["rod_forse"],
                     "starts": ["twist12_00", "twist34_0", "omega1_0", "omega2_0",
                                "omega4_0", "omega3_0", "phi2_00"]}
    spec["outputs"] = {"metrics": {"peak": {"variable": "rod_force", "kind": "max"}}}
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert {"scenario.interface", "cycle.starts[0]", "cycle.starts[5]", "cycle.starts[6]",
            "cycle.starts", "cycle.state", "cycle.shifted[0]",
            "cycle.keep[0]"} <= set(said), said
    assert "did you mean 'twist12_0'" in said["cycle.starts[0]"]


def test_a_fit_spec_with_mistakes_in_each_table(fmu_path, tmp_path):
    spec = {"scenario": {"stop": 0.5, "step": 0.05, "tolerance": 1e-8, "stpo": 1.0},
            "data": {"file": str(tmp_path / "absent.csv"), "sigma": {"omega2": -1.0}},
            "fit": {"starts": 3, "intervals": "wlad",
                    "parameters": {"k34": {"start": 900.0, "range": [10.0, 400.0]},
                                   "k43": {"start": 1.0, "range": [0.0, 2.0]}}}}
    said = refused(spec, tmp_path, run=fit, fmu=fmu_path)
    assert set(said) == {"scenario.stpo", "data.file", "data.sigma.omega2", "fit.seed",
                         "fit.intervals", "fit.parameters.k34.start", "fit.parameters.k43"}, said
    assert "did you mean 'wald'" in said["fit.intervals"]


def test_a_missing_fmu_is_named_with_the_other_mistakes(tmp_path):
    spec = dict(grid(stpo=1.0), fmu=str(tmp_path / "nowhere" / "Model.fmu"))
    spec["design"]["parameters"]["k34"] = {"linspace": [1.0, 2.0]}
    said = refused(spec, tmp_path)
    assert set(said) == {"fmu", "scenario.stpo", "design.parameters.k34.linspace"}, said
    assert "nowhere" in said["fmu"]


def test_a_tolerance_out_of_range_is_named_by_its_field_alone(fmu_path, tmp_path):
    said = refused(grid(tolerance=100.0), tmp_path, fmu=fmu_path)
    assert said == {"scenario.tolerance": "must lie in [1e-13, 0.1], got 100.0"}, said
    spec = grid(tolerance=100.0, stpo=1.0)
    spec["design"]["parameters"]["J2"] = {"values": [-1.0]}
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert set(said) == {"scenario.tolerance", "scenario.stpo", "design.parameters.J2"}, said


def test_types_are_said_plainly_with_the_variables_unit(fmu_path, tmp_path):
    spec = grid(stop="10 s")
    spec["scenario"]["parameters"].update(d34="0.5 N.m.s/rad", builtin_laws="false")
    spec["design"]["parameters"]["J2"] = {"values": ["heavy"]}
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert said["scenario.stop"] == "expected a number (s), got the string '10 s'", said
    assert said["scenario.parameters.d34"] == ("expected a number (N·m·s/rad), got the string "
                                               "'0.5 N.m.s/rad'"), said
    assert said["scenario.parameters.builtin_laws"].startswith("write false without quotes")
    assert said["design.parameters.J2.values"] == ("expected a number (kg·m2), got the string "
                                                   "'heavy'"), said
    spec = grid()
    spec["scenario"]["parameters"]["builtin_laws"] = 0
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert said == {"scenario.parameters.builtin_laws": "builtin_laws is a Boolean: write true "
                                                        "or false, got 0"}, said


# One mistake of every kind docs/sweeps.md lists, each in its own field.
SWEEP_MISTAKES = {
    "scenario.stpo": ("unknown field", lambda s: s["scenario"].update(stpo=1.0)),
    "outputs.metrics.m2.variable": ("is missing", lambda s: s["outputs"]["metrics"].update(
        m2={"kind": "max"})),
    "scenario.timeout": ("expected a number", lambda s: s["scenario"].update(timeout="1 min")),
    "scenario.tolerance": ("must lie in", lambda s: s["scenario"].update(tolerance=1.0)),
    "scenario.parameters.builtin_laws": (
        "without quotes", lambda s: s["scenario"]["parameters"].update(builtin_laws="true")),
    "scenario.parameters.d12": ("expected a number",
                                lambda s: s["scenario"]["parameters"].update(d12="0.1")),
    "scenario.parameters.J4": ("the FMU refuses", lambda s: s["scenario"]["parameters"].update(J4=-1.0)),
    "scenario.parameters.k21": ("did you mean", lambda s: s["scenario"]["parameters"].update(k21=1.0)),
    "scenario.inputs.M_r.times": ("strictly increasing", lambda s: s["scenario"]["inputs"].update(
        M_r={"times": [0.0, 0.2, 0.1], "values": [0.0, 1.0, 2.0]})),
    "design.parameters.k34.linspace": ("[start, stop, count]", lambda s: s["design"]["parameters"].update(
        k34={"linspace": [1.0, 2.0]})),
    "design.parameters.J2": ("the FMU refuses", lambda s: s["design"]["parameters"].update(
        J2={"values": [0.3, -0.2]})),
    "design.parameters.solver.values": ("has no item", lambda s: s["design"]["parameters"].update(
        solver={"values": ["dop835"]})),
    "design.parameters.phi1": ("causality", lambda s: s["design"]["parameters"].update(
        phi1={"values": [0.0]})),
    "outputs.metrics.top.kind": ("must be one of", lambda s: s["outputs"]["metrics"]["top"].update(
        kind="maximum")),
    "outputs.metrics.late.from": ("must lie in the run", lambda s: s["outputs"]["metrics"].update(
        late={"variable": "omega2", "kind": "final", "from": 9.0})),
    "outputs.metrics.status": ("choose another name", lambda s: s["outputs"]["metrics"].update(
        status={"variable": "omega2", "kind": "min"})),
    "outputs.metrics.w.variable": ("did you mean", lambda s: s["outputs"]["metrics"].update(
        w={"variable": "omega22", "kind": "max"})),
    "outputs.series.interval": ("whole multiple", lambda s: s["outputs"].update(
        series={"variables": ["omega1"], "interval": 0.07})),
}


def test_one_mistake_of_every_kind_in_a_sweep_spec_is_named_in_one_run(fmu_path, tmp_path):
    spec = grid()
    spec["scenario"]["inputs"] = {}
    for _, change in SWEEP_MISTAKES.values():
        change(spec)
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert set(said) >= set(SWEEP_MISTAKES), set(SWEEP_MISTAKES) - set(said)
    for field, (words, _) in SWEEP_MISTAKES.items():
        assert words in said[field], (field, said[field])


def test_one_mistake_of_every_kind_in_a_cycle_spec_is_named_in_one_run(fmu_path, tmp_path):
    spec = grid(stop=50.0, stpo=1.0)
    spec["design"] = {"kind": "list", "parameters": {"d34": {"values": [0.1]}}}
    spec["cycle"] = {"state": "loop_angel", "advance": 360.0, "shifted": ["phi9"],
                     "samples": 4, "monodromy": "guess", "keep": ["n_steps"], "sampels": 8}
    spec["outputs"] = {"metrics": {"a": {"variable": "rod_force", "kind": "final"},
                                   "c": {"variable": "rod_force", "kind": "harmonic"}},
                       "series": {"variables": ["omega1"]}}
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert {"scenario.stpo", "cycle.state", "cycle.shifted[0]", "cycle.samples",
            "cycle.monodromy", "cycle.keep[0]", "cycle.sampels", "outputs.metrics.a.kind",
            "outputs.metrics.c.order", "outputs.series"} <= set(said), said
    spec["cycle"]["state"] = "loop_angle"
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert "looks like degrees" in said["cycle.advance"], said


def test_one_mistake_of_every_kind_in_a_fit_spec_is_named_in_one_run(fmu_path, tmp_path):
    (tmp_path / "m.csv").write_text("time,omega2,omega9\n0,1,1\n0.05,1,1\n0.07,1,1\n")
    spec = {"scenario": {"stop": 0.5, "step": 0.05, "tolerance": 1e-8,
                         "parameters": {"J4": -0.5, "k21": 1.0}},
            "data": {"file": str(tmp_path / "m.csv"), "sigma": {"omega3": 0.1}},
            "fit": {"max_iterations": 0, "relative_step": 0.5, "profile": ["k34"],
                    "parameters": {"k34": {"start": 900.0, "range": [10.0, 400.0]},
                                   "d34": {"start": 0.1, "range": [-1.0, 1.0]},
                                   "cost": {"start": 0.1, "range": [0.0, 1.0]}}}}
    said = refused(spec, tmp_path, run=fit, fmu=fmu_path)
    assert {"scenario.parameters.J4", "scenario.parameters.k21", "data.file",
            "data.sigma.omega3", "fit.max_iterations", "fit.relative_step", "fit.profile",
            "fit.parameters.k34.start", "fit.parameters.d34", "fit.parameters.cost"} <= set(said), said


# What else the new user met: each said plainly.

def test_a_resume_refused_for_a_changed_spec_names_the_changed_fields(fmu_path, tmp_path):
    spec = grid()
    run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False, plots=False)
    spec["scenario"]["stop"] = 0.6
    spec["design"]["parameters"]["k34"]["values"] = [100.0, 130.0]
    with pytest.raises(ValueError) as refused:
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False,
                  resume=True)
    said = str(refused.value)
    assert "scenario.stop 0.5 → 0.6" in said, said
    assert "design.parameters.k34.values [100.0, 120.0] → [100.0, 130.0]" in said, said
    assert "digest" not in said


def test_repeated_points_of_a_design_are_named(fmu_path, tmp_path):
    spec = grid()
    spec["design"]["parameters"]["k34"] = {"values": [100.0, 120.0, 100]}
    spec["design"]["parameters"]["d34"] = {"linspace": [0.2, 0.2, 3]}
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert "lists 100.0 more than once" in said["design.parameters.k34.values"], said
    assert "gives 0.2 3 times" in said["design.parameters.d34.linspace"], said
    spec["design"] = {"kind": "list", "parameters": {"k34": {"values": [100.0, 120.0, 100.0]},
                                                     "d34": {"values": [0.1, 0.2, 0.1]}}}
    # A list may repeat a point on purpose: each runs, and the warning names them.
    with pytest.warns(SpecWarning, match=r"design\.parameters: points 0 and 2 are the same "
                                         r"\(k34 = 100\.0, d34 = 0\.1\): each runs"):
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "listed", serial=True, progress=False,
                  plots=False)


def test_an_integer_column_comes_back_as_integers(fmu_path, tmp_path):
    for name, values, numbers in (("solver_code", [1, 2], [1, 2]),
                                  ("solver", ["dop853", "implicit"], None)):
        spec = grid()
        spec["design"]["parameters"] = {name: {"values": values}}
        results = run_sweep(spec, fmu=fmu_path, out=tmp_path / name, serial=True,
                            progress=False, plots=False)
        points = results.points
        assert str(points[name].dtype) == "int64", points.dtypes
        assert list(points["status"]) == ["ok", "ok"]
        if numbers is not None:
            assert sorted(points[name]) == numbers


def test_linearise_gives_a_b_c_d_by_their_names_and_names_its_arguments(fmu_path):
    from fmusweep import linearise
    found = linearise(fmu_path, dict(PAPER_LAWS))
    n, m, p = len(found.states), len(found.inputs), len(found.outputs)
    assert found.A.shape == (n, n) and found.B.shape == (n, m)
    assert found.C.shape == (p, n) and found.D.shape == (p, m)
    with pytest.raises(SpecError) as refused:
        linearise(fmu_path, {"k43": 1.0, "d34": "0.1"})
    said = {e.field: e.rule for e in getattr(refused.value, "errors", [refused.value])}
    assert "did you mean 'k34'" in said["parameters.k43"], said
    assert "finite number" in said["parameters.d34"], said


def test_the_command_line_names_fmu_and_says_how_the_engine_is_chosen(tmp_path):
    import os
    import subprocess
    import sys
    spec = tmp_path / "s.toml"
    spec.write_text('[scenario]\nstop = 1.0\nstep = 0.1\n[design]\nkind = "list"\n'
                    '[design.parameters]\nk34 = { values = [1.0] }\n')
    env = {k: v for k, v in os.environ.items() if k != "FMUSWEEP_FMU"}
    done = subprocess.run([sys.executable, "-m", "fmusweep", str(spec), "--no-progress"],
                          capture_output=True, text=True, env=env, cwd=tmp_path)
    assert done.returncode == 2 and "--fmu FILE" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    shown = subprocess.run([sys.executable, "-m", "fmusweep", "--help"], capture_output=True,
                           text=True, env=env).stdout
    assert "the engine is chosen after the first points" in " ".join(shown.split()), shown


def test_a_sweep_that_would_fill_the_disk_is_refused_and_a_large_one_says_so(
        fmu_path, tmp_path, monkeypatch):
    import collections
    import fmusweep.sweep as sweep_module
    spec = grid()
    spec["outputs"]["series"] = {"variables": ["omega1", "omega2"]}
    need, values = sweep_module.written_bytes(sweep_module.Spec.from_dict(spec, tmp_path), 2)
    assert values == 2 * 11 * 2  # two points, 11 samples, two variables
    usage = collections.namedtuple("usage", "total used free")
    # The thresholds scaled down to this small sweep; the check itself as it runs.
    monkeypatch.setattr(sweep_module, "SAY_ABOVE_BYTES", need - 1)
    monkeypatch.setattr(sweep_module.shutil, "disk_usage", lambda _: usage(0, 0, need - 1))
    said = refused(spec, tmp_path, fmu=fmu_path)
    assert list(said) == ["outputs.series"], said
    assert "would write about" in said["outputs.series"] and "2 points × 11 samples × 2 " \
        "variables" in said["outputs.series"], said
    monkeypatch.setattr(sweep_module.shutil, "disk_usage", lambda _: usage(0, 0, 10 * need))
    with pytest.warns(SpecWarning, match="the sweep will write about"):
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False,
                  plots=False)


def test_a_small_sweep_without_an_engine_named_runs_serially_and_says_why(fmu_path, tmp_path):
    spec = grid()
    spec["design"]["parameters"]["k34"] = {"linspace": [100.0, 120.0, 20]}
    results = run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", progress=False, plots=False)
    summary = results.summary
    assert summary.engine == "serial", summary
    assert summary.engine_choice.startswith("serial: the 16 points left take about "), \
        summary.engine_choice
    assert "a LocalCluster of" in summary.engine_choice and "with its start-up" in \
        summary.engine_choice, summary.engine_choice


@pytest.mark.parametrize("starts", [None, STARTS])
def test_a_cycle_search_out_of_scenario_time_says_so_and_names_stop(fmu_path, tmp_path, starts):
    spec = grid(stop=1.0)
    spec["design"] = {"kind": "list", "parameters": {"d34": {"values": [0.1]}}}
    spec["cycle"] = {"state": "phi1", "advance": TAU, **({"starts": starts} if starts else {})}
    spec["outputs"] = {"metrics": {"peak": {"variable": "rod_force", "kind": "max"}}}
    points = run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False,
                       plots=False).points
    assert list(points["status"]) == ["no_cycle"], points
    said = points["message"][0]
    assert "within the scenario's time, stop − start = 1 s" in said, said
    assert "give scenario.stop more time" in said and "turned back" not in said, said
