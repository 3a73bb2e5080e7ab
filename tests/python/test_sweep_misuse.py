"""What a user can get wrong in a sweep or a fit spec, each refused by field before anything
runs, every mistake of one spec in one run, and nothing left behind: names that would share
a column of the results, a σ for some measured columns only, metric windows without a
communication point, values the FMU refuses anywhere in a design."""


import numpy as np
import pytest

from fmusweep import SpecError, fit, run_sweep
from sweep_helpers import PAPER_LAWS


def small_grid(**outputs):
    return {
        "scenario": {"stop": 0.5, "step": 0.05, "tolerance": 1e-6, "parameters": dict(PAPER_LAWS)},
        "design": {"kind": "grid", "parameters": {"d34": {"values": [0.2, 0.4]},
                                                  "J2": {"values": [0.3, 0.6]}}},
        "outputs": {"metrics": outputs or {"top": {"variable": "omega2", "kind": "max"}}},
    }


def refused_fields(spec, fmu_path, tmp_path, run=run_sweep):
    with pytest.raises(SpecError) as refused:
        run(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, **(
            {"progress": False} if run is run_sweep else {}))
    assert not (tmp_path / "out").exists()
    errors = getattr(refused.value, "errors", [refused.value])
    return {e.field: e.rule for e in errors}


@pytest.mark.parametrize("name", ["d34", "point", "message", "status", "steps", "wall_s",
                                  "worker", "coupling_error"])
def test_a_metric_named_like_a_column_is_refused(fmu_path, tmp_path, name):
    spec = small_grid(**{name: {"variable": "omega4", "kind": "min"}})
    said = refused_fields(spec, fmu_path, tmp_path)
    assert list(said) == [f"outputs.metrics.{name}"], said
    assert "choose another name" in said[f"outputs.metrics.{name}"]


def test_a_metric_named_like_its_variable_is_taken_where_no_column_has_that_name(fmu_path, tmp_path):
    spec = small_grid(omega3={"variable": "omega3", "kind": "rms"}, time={"variable": "omega3",
                                                                         "kind": "min"})
    said = refused_fields(spec, fmu_path, tmp_path)
    assert list(said) == ["outputs.metrics.time"], said
    del spec["outputs"]["metrics"]["time"]
    spec["outputs"]["series"] = {"variables": ["omega3"]}
    p = run_sweep(spec, fmu=fmu_path, out=tmp_path / "ok", serial=True, progress=False).points
    assert (p["status"] == "ok").all() and (p["omega3"] > 0).all(), p


def test_metric_windows_outside_the_run_or_between_points_are_refused_together(fmu_path, tmp_path):
    spec = small_grid(between={"variable": "omega2", "kind": "mean", "from": 0.21, "to": 0.24},
                      late={"variable": "omega2", "kind": "final", "from": 0.7},
                      early={"variable": "omega2", "kind": "min", "to": -0.1},
                      fine={"variable": "omega2", "kind": "max", "from": 0.2, "to": 0.2})
    said = refused_fields(spec, fmu_path, tmp_path)
    assert set(said) == {"outputs.metrics.between", "outputs.metrics.late.from",
                         "outputs.metrics.early.to"}, said
    assert "holds no communication point" in said["outputs.metrics.between"]
    assert "[0, 0.5]" in said["outputs.metrics.late.from"]


def test_every_value_the_fmu_refuses_is_named_by_its_field_in_one_run(fmu_path, tmp_path):
    spec = small_grid()
    spec["scenario"]["parameters"]["k12"] = -3.0
    spec["design"]["parameters"] = {"J2": {"values": [0.3, -0.1, -0.2]},
                                    "d34": {"values": [0.2, 0.4, -1.0]},
                                    "k34": {"values": [100.0, 120.0]}}
    said = refused_fields(spec, fmu_path, tmp_path)
    assert set(said) == {"scenario.parameters.k12", "design.parameters.J2",
                         "design.parameters.d34"}, said
    assert "J2 = -0.2, -0.1 (2 values)" in said["design.parameters.J2"], said
    assert "d34 = -1" in said["design.parameters.d34"], said


def test_a_first_point_refused_names_its_column(fmu_path, tmp_path):
    spec = small_grid()
    spec["design"]["parameters"] = {"J2": {"values": [-0.3, 0.5]}, "d34": {"values": [0.2, 0.4]}}
    said = refused_fields(spec, fmu_path, tmp_path)
    assert list(said) == ["design.parameters.J2"] and "J2 = -0.3" in said["design.parameters.J2"], said


def test_a_missing_fmu_file_names_the_field(tmp_path):
    spec = dict(small_grid(), fmu=str(tmp_path / "nowhere" / "Model.fmu"))
    with pytest.raises(SpecError) as refused:
        run_sweep(spec, out=tmp_path / "out", serial=True, progress=False)
    assert refused.value.field == "fmu" and "nowhere" in str(refused.value)


# --- the fit -----------------------------------------------------------------------------
def measured(fmu_path, path, columns=("omega2", "omega3")):
    from fmusweep.fmu import Archive, local_runner
    from fmusweep.spec import Scenario
    runner = local_runner(Archive.read(fmu_path))
    runner.configure(Scenario.of({"scenario": {"stop": 0.5, "step": 0.05, "tolerance": 1e-8}}).plan(
        [], {"variables": list(columns), "every": 1}))
    [result] = runner.run([], [[]])
    np.savetxt(path, np.array(result["series"]), delimiter=",",
               header=",".join(("time", *columns)), comments="", fmt="%.17g")
    return path


def test_a_sigma_for_some_measured_columns_only_is_refused(fmu_path, tmp_path):
    data = measured(fmu_path, tmp_path / "m.csv")
    spec = {"scenario": {"stop": 0.5, "step": 0.05, "tolerance": 1e-8},
            "data": {"file": str(data), "sigma": {"omega3": 0.01}},
            "fit": {"parameters": {"k34": {"start": 80.0, "range": [10.0, 400.0]}}}}
    said = refused_fields(spec, fmu_path, tmp_path, run=fit)
    assert list(said) == ["data.sigma"] and "omega2" in said["data.sigma"], said


def test_a_sigma_in_some_experiments_only_is_refused(fmu_path, tmp_path):
    data = measured(fmu_path, tmp_path / "m.csv")
    spec = {"scenario": {"stop": 0.5, "step": 0.05, "tolerance": 1e-8},
            "experiment": [{"name": "a", "data": {"file": str(data),
                                                  "sigma": {"omega2": 0.1, "omega3": 0.1}}},
                           {"name": "b", "data": {"file": str(data)}}],
            "fit": {"parameters": {"k34": {"start": 80.0, "range": [10.0, 400.0]}}}}
    said = refused_fields(spec, fmu_path, tmp_path, run=fit)
    assert list(said) == ["experiment.b.data.sigma"], said


def test_a_fitted_parameter_named_like_a_column_is_refused(fmu_path, tmp_path):
    from fmusweep.columns import FIT_COLUMNS, refuse_collisions
    from fmusweep.errors import Collector
    errors = Collector()
    refuse_collisions([("cost", "fit.parameters.cost", "the fitted parameter"),
                       ("k34", "fit.parameters.k34", "the fitted parameter")], FIT_COLUMNS, errors)
    assert [e.field for e in errors.errors] == ["fit.parameters.cost"]
