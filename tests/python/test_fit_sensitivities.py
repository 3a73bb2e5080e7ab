"""A fit whose Jacobian comes from the FMU's own sensitivities (docs/sensitivities.md):
the same estimates as by differences from a fraction of the runs, a parameter the FMU has
no sensitivity for differenced beside the others, and an FMU without sensitivities fitted
by differences."""

import json

import numpy as np
import pandas as pd
import pytest

from fmusweep import fit
from fmusweep.fmu import Archive, local_runner
from fmusweep.spec import Scenario
from conftest import packed
from test_fit import MEASURED, SIGMA, exact_rows, noisy, write_csv

SCENARIO = {"stop": 3.0, "step": 0.01, "tolerance": 1e-8}
PARAMETERS = {"k34": {"start": 120.0, "range": [10.0, 400.0]},
              "d34": {"start": 0.5, "range": [0.0, 5.0]},
              "k12": {"start": 100.0, "range": [10.0, 400.0]}}
TRUTH = {"k34": 150.0, "d34": 0.8, "k12": 120.0}


def spec_of(fmu_path, tmp_path, jacobian, parameters=PARAMETERS):
    return {"fmu": str(fmu_path), "scenario": dict(SCENARIO),
            "data": {"file": str(tmp_path / "measured.csv"), "sigma": {c: SIGMA for c in MEASURED}},
            "fit": {"jacobian": jacobian, "parameters": json.loads(json.dumps(parameters))}}


@pytest.fixture(scope="module")
def rows(fmu_path):
    return noisy(exact_rows(fmu_path, list(TRUTH), list(TRUTH.values())), 11)


def test_sensitivities_give_the_estimates_of_differences_from_fewer_runs(fmu_path, rows, tmp_path):
    write_csv(tmp_path / "measured.csv", rows)
    by = {j: fit(spec_of(fmu_path, tmp_path, j), out=tmp_path / j, serial=True, plots=False).summary
          for j in ("sensitivities", "differences")}
    s, d = by["sensitivities"], by["differences"]
    assert s["status"] == d["status"] == "converged"
    for name in TRUTH:
        gap = abs(s["parameters"][name]["estimate"] - d["parameters"][name]["estimate"])
        assert gap <= 0.01 * d["parameters"][name]["stderr"], (name, gap)
        assert s["parameters"][name]["stderr"] == pytest.approx(d["parameters"][name]["stderr"], rel=1e-3)
    # One run per trial instead of 1 + 3: no Jacobian runs at all.
    points = pd.read_parquet(tmp_path / "sensitivities/points.parquet")
    assert set(points["role"]) == {"trial"}
    assert s["computed"] < d["computed"] / 2


def test_a_parameter_without_sensitivity_is_differenced_beside_the_others(fmu_path, rows, tmp_path):
    write_csv(tmp_path / "measured.csv", rows)
    parameters = {"k34": PARAMETERS["k34"], "L": {"start": 0.7, "range": [0.65, 0.75]}}
    by = {}
    for j in ("sensitivities", "differences"):
        spec = spec_of(fmu_path, tmp_path, j, parameters)
        spec["scenario"]["parameters"] = {"d34": TRUTH["d34"], "k12": TRUTH["k12"]}
        by[j] = fit(spec, out=tmp_path / j, serial=True, plots=False).summary
    for name in parameters:
        gap = abs(by["sensitivities"]["parameters"][name]["estimate"]
                  - by["differences"]["parameters"][name]["estimate"])
        assert gap <= 0.01 * by["differences"]["parameters"][name]["stderr"], name
    points = pd.read_parquet(tmp_path / "sensitivities/points.parquet")
    jacobian = points[points["role"] == "jacobian"]
    # Only L's perturbations: k34 keeps the trial's value in each.
    assert len(jacobian)
    assert np.isin(jacobian["k34"], points.loc[points["role"] == "trial", "k34"]).all()


def test_an_fmu_without_sensitivities_is_fitted_by_differences(tmp_path):
    """The compiled DC motor has no slot: asked for sensitivities, the fit differences,
    to the same bits."""
    motor = packed("DC_MOTOR_FMU", "target/fmu/DcMotor.fmu", "motor")
    scenario = {"stop": 0.1, "step": 0.001, "tolerance": 1e-8, "inputs": {"voltage": 24.0}}
    runner = local_runner(Archive.read(motor))
    runner.configure(Scenario.of({"scenario": scenario}).plan([], {"variables": ["current"], "every": 2}))
    [made] = runner.run(["R", "L"], [[0.5, 0.01]])
    write_csv(tmp_path / "current.csv", np.array(made["series"]), ("time", "current"))
    summaries = []
    for jacobian in ("sensitivities", "differences"):
        spec = {"fmu": str(motor), "scenario": scenario,
                "data": {"file": str(tmp_path / "current.csv"), "sigma": {"current": 0.1}},
                "fit": {"jacobian": jacobian,
                        "parameters": {"R": {"start": 1.0, "range": [0.05, 5.0]},
                                       "L": {"start": 0.05, "range": [0.001, 0.5]}}}}
        summaries.append(fit(spec, out=tmp_path / jacobian, serial=True, plots=False).summary)
    assert summaries[0]["parameters"] == summaries[1]["parameters"]
    assert summaries[0]["computed"] == summaries[1]["computed"]
