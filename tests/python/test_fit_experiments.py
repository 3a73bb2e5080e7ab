"""Fits of several experiments at once: a pair one experiment cannot separate, separated
by two, with each experiment's own start value estimated; only the experiment whose
parameter moved runs again; serial and Dask agree; resuming; every mistake refused by
the field it is in, before anything runs."""

import copy
import json
import pathlib
import shutil
import tomllib

import numpy as np
import pandas as pd
import pytest

from fmusweep import SpecError, fit
from sweep_helpers import fit_command, lose_the_later_parts

EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "examples/fit"
TRUTH = {"Mm_a0": 100.0, "Mm_a1": -20.0, "braked.omega1_0": 0.5, "boosted.omega1_0": 5.0}


def example_spec(fmu_path):
    """examples/fit/two_experiments.toml with absolute data paths and the FMU under test."""
    spec = tomllib.loads((EXAMPLE / "two_experiments.toml").read_text())
    spec["fmu"] = str(fmu_path)
    for e in spec["experiment"]:
        e["data"]["file"] = str(EXAMPLE / e["data"]["file"])
    spec["fit"]["intervals"] = "wald"
    return spec


@pytest.fixture(scope="module")
def both(fmu_path, tmp_path_factory):
    out = tmp_path_factory.mktemp("both") / "out"
    return fit(example_spec(fmu_path), out=out, serial=True, plots=True)


def test_one_experiment_cannot_separate_the_motor_laws_pair(fmu_path, tmp_path):
    spec = example_spec(fmu_path)
    spec["experiment"] = spec["experiment"][1:]
    summary = fit(spec, out=tmp_path / "out", serial=True, plots=False).summary
    assert summary["correlation"]["Mm_a0"]["Mm_a1"] < -0.99
    assert summary["unidentifiable"] == ["Mm_a0", "Mm_a1"]
    assert any("Mm_a0 and Mm_a1 cannot be told apart" in w for w in summary["warnings"])


def test_two_experiments_separate_it_and_estimate_each_start_value(both, report):
    summary = both.summary
    assert summary["status"] == "converged" and summary["warnings"] == []
    correlation = summary["correlation"]["Mm_a0"]["Mm_a1"]
    report["fit_two_experiments_correlation"] = correlation
    assert abs(correlation) < 0.9
    for name, true in TRUTH.items():
        p = summary["parameters"][name]
        low, high = p["ci95"]
        assert low <= true <= high, (name, p)
        if name.startswith("Mm_"):
            assert high - low < 0.05 * abs(true), (name, p)
    assert set(summary["residual_rms"]) == {"braked", "boosted"}
    for rms in summary["residual_rms"].values():  # the noise was 0.05 rad/s
        assert all(0.04 < v < 0.06 for v in rms.values()), rms


def test_every_run_is_stored_with_its_experiment(both):
    points = both.points
    assert set(points["experiment"]) == {"braked", "boosted"}
    braked = points[points["experiment"] == "braked"]
    # A run of one experiment does not take the other's own parameter.
    assert braked["boosted.omega1_0"].isna().all() and braked["braked.omega1_0"].notna().all()
    assert len(points) == both.summary["computed"]
    series = pd.read_parquet(both.out / "series")
    first = int(braked["point"].iloc[0])
    assert len(series[series["point"] == first]) == 2 * 201  # omega1 and omega4 at 201 times


def test_a_perturbed_own_parameter_reruns_only_its_experiment(both):
    """Each Jacobian perturbs the 2 shared parameters (both experiments run again) and each
    experiment's own start value (only that experiment runs again): 3 runs per experiment
    per trial point, not 4."""
    points = both.points
    for name in ("braked", "boosted"):
        mine = points[points["experiment"] == name]
        trials, jacobian = (mine["role"] == "trial").sum(), (mine["role"] == "jacobian").sum()
        assert jacobian == 3 * trials, (name, trials, jacobian)
    s = both.summary
    assert s["computed"] + s["resumed"] == s["evaluations"] and s["resumed"] >= 2 * s["iterations"]


def test_each_experiment_has_its_own_pictures(both):
    names = {p.name for p in both.plots}
    assert names == {"fit_trajectories_braked.png", "fit_residuals_braked.png",
                     "fit_trajectories_boosted.png", "fit_residuals_boosted.png",
                     "fit_correlation.png"}
    for p in both.plots:
        assert p.stat().st_size > 10_000


def test_serial_and_a_local_cluster_agree_to_the_last_bit(fmu_path, both, tmp_path):
    cluster = fit(example_spec(fmu_path), out=tmp_path / "cluster", workers=2, plots=False).summary
    assert cluster["workers"] == 2
    for key in ("parameters", "correlation", "cost", "residual_rms", "evaluations"):
        assert cluster[key] == both.summary[key], key


def test_an_interrupted_fit_of_two_experiments_resumes(fmu_path, both, tmp_path):
    shutil.copytree(both.out, tmp_path / "cut")
    shutil.rmtree(tmp_path / "cut/plots")
    lost = lose_the_later_parts(tmp_path / "cut")
    resumed = fit(example_spec(fmu_path), out=tmp_path / "cut", serial=True, resume=True,
                  plots=False).summary
    assert resumed["parameters"] == both.summary["parameters"]
    assert resumed["computed"] == lost


def test_the_example_runs_from_the_command_line_with_both_intervals(fmu_path, tmp_path):
    done = fit_command(fmu_path, EXAMPLE / "two_experiments.toml", "--out", tmp_path / "out")
    assert done.returncode == 0, done.stderr
    assert "braked.omega1_0 = " in done.stdout and ", profile [" in done.stdout
    summary = json.loads((tmp_path / "out/fit.json").read_text())
    for name, true in TRUTH.items():
        wald, profile = (summary["parameters"][name][k] for k in ("wald_ci95", "profile_ci95"))
        assert wald[0] <= true <= wald[1] and profile[0] <= true <= profile[1], name
        # Nearly linear here: the two intervals agree to a small part of their width.
        assert abs(profile[0] - wald[0]) + abs(profile[1] - wald[1]) < 0.02 * (wald[1] - wald[0])
    assert (tmp_path / "out/plots/fit_profiles.png").stat().st_size > 10_000


def _bad_cases(tmp):
    def experiment(k, **changes):
        def change(spec):
            spec["experiment"][k].update(changes)
        return change

    def own(k, name, entry):
        def change(spec):
            spec["experiment"][k]["parameters"][name] = entry
        return change

    def late(spec):
        rows = np.loadtxt(EXAMPLE / "braked.csv", delimiter=",", skiprows=1)
        rows[-1, 0] = 4.5
        path = tmp / "late.csv"
        np.savetxt(path, rows, delimiter=",", header="time,omega1,omega4", comments="", fmt="%.17g")
        spec["experiment"][0]["data"]["file"] = str(path)

    return {
        "an experiment without data": ("experiment.braked.data", lambda s: s["experiment"][0].pop("data")),
        "both [data] and experiments": ("data", lambda s: s.update(data={"file": "x.csv"})),
        "no experiment": ("experiment", lambda s: s.update(experiment=[])),
        "a nameless experiment": ("experiment[1].name", lambda s: s["experiment"][1].pop("name")),
        "two experiments of one name": ("experiment.braked.name", experiment(1, name="braked")),
        "an unknown field": ("experiment.braked.weight", experiment(0, weight=2.0)),
        "a bad stop of its own": ("experiment.boosted.scenario.stop", experiment(1, scenario={"stop": -1.0})),
        "data past its own stop": ("experiment.braked.data.file", late),
        "a sigma for no column": ("experiment.boosted.data.sigma.omega9",
                                  lambda s: s["experiment"][1]["data"]["sigma"].update(omega9=1.0)),
        "a start value one cannot set": ("experiment.braked.parameters.phi1",
                                         own(0, "phi1", {"start": 0.0, "range": [-1.0, 1.0]})),
        "a start value the FMU lacks": ("experiment.braked.parameters.omega9_0",
                                        own(0, "omega9_0", {"start": 0.0, "range": [-1.0, 1.0]})),
        "a range the FMU refuses": ("experiment.boosted.parameters.J1",
                                    own(1, "J1", {"start": 0.5, "range": [-1.0, 1.0]})),
        "its own parameter also shared": ("experiment.braked.parameters.Mm_a0",
                                          own(0, "Mm_a0", {"start": 90.0, "range": [50.0, 150.0]})),
        "its own parameter also fixed": ("experiment.braked.parameters.omega1_0",
                                         experiment(0, scenario={"parameters": {"omega1_0": 1.0}})),
        "a shared parameter fixed in one": ("fit.parameters.Mm_a0",
                                            experiment(1, scenario={"parameters": {"Mm_a0": 1.0}})),
        "intervals of no kind": ("fit.intervals", lambda s: s["fit"].update(intervals="bootstrap")),
        "a profile of no fitted parameter": ("fit.profile", lambda s: s["fit"].update(
            intervals="profile", profile=["omega1_0"])),
        "a profile without profile intervals": ("fit.profile", lambda s: s["fit"].update(profile=["Mm_a0"])),
    }


BAD = list(_bad_cases(pathlib.Path(".")))


@pytest.mark.parametrize("case", BAD)
def test_a_bad_experiment_is_refused_by_field_before_anything_runs(fmu_path, tmp_path, case):
    field, change = _bad_cases(tmp_path)[case]
    spec = copy.deepcopy(example_spec(fmu_path))
    change(spec)
    with pytest.raises(SpecError) as refused:
        fit(spec, out=tmp_path / "out", serial=True, plots=False)
    assert refused.value.field == field, str(refused.value)
    assert not (tmp_path / "out").exists()
