"""Fits on the sweep engine: estimates and their intervals against known truths under
seeded noise, an unidentifiable pair reported, failed runs as infinitely bad points, the
same fit serially and on Dask, resuming, and every bad input refused by field."""

import json
import math
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from fmusweep import SpecError
from fmusweep import fit
from fmusweep.fmu import Archive, local_runner
from fmusweep.spec import Scenario
from conftest import packed
from sweep_helpers import (environment_for_workers, fit_command, lose_the_later_parts, start_cluster,
                           stop_cluster)

TRUTH = {"k34": 150.0, "d34": 0.8}
SIGMA = 0.05
SCENARIO = {"stop": 3.0, "step": 0.01, "tolerance": 1e-8}
MEASURED = ["omega1", "omega4"]
PARAMETERS = {"k34": {"start": 80.0, "range": [10.0, 400.0]},
              "d34": {"start": 0.1, "range": [0.0, 5.0]}}


def exact_rows(fmu_path, names, values, every=2, scenario=SCENARIO):
    """The FMU's own time and measured outputs at the given values, no noise."""
    runner = local_runner(Archive.read(fmu_path))
    runner.configure(Scenario.of({"scenario": scenario}).plan([], {"variables": MEASURED, "every": every}))
    [result] = runner.run(names, [values])
    assert result["status"] == "ok", result["message"]
    return np.array(result["series"])


def write_csv(path, rows, header=("time", *MEASURED)):
    np.savetxt(path, rows, delimiter=",", header=",".join(header), comments="", fmt="%.17g")
    return path


def fit_spec(fmu_path, directory, **changes):
    spec = {"fmu": str(fmu_path), "scenario": dict(SCENARIO),
            "data": {"file": str(directory / "measured.csv"), "sigma": {c: SIGMA for c in MEASURED}},
            "fit": {"parameters": json.loads(json.dumps(PARAMETERS))}}
    for key, value in changes.items():
        spec[key] = value
    return spec


@pytest.fixture(scope="module")
def truth_rows(fmu_path):
    return exact_rows(fmu_path, list(TRUTH), list(TRUTH.values()))


def noisy(rows, seed):
    out = rows.copy()
    out[:, 1:] += np.random.default_rng(seed).normal(0.0, SIGMA, size=out[:, 1:].shape)
    return out


def test_intervals_cover_the_truth_about_95_percent_of_the_time(fmu_path, truth_rows, tmp_path, report):
    """A stiffness and a damping from two noisy speeds, over 20 noise seeds: each estimate
    is close to the truth for its interval, and the 95 % intervals hold the truth in about
    95 % of the 40 cases (below 34 of 40 has a chance under 1 % if they are right)."""
    inside, z = 0, []
    for seed in range(20):
        directory = tmp_path / f"seed{seed}"
        directory.mkdir()
        write_csv(directory / "measured.csv", noisy(truth_rows, seed))
        result = fit(fit_spec(fmu_path, directory), out=directory / "out", serial=True, plots=False)
        summary = result.summary
        assert summary["status"] == "converged" and summary["warnings"] == []
        for name, true in TRUTH.items():
            p = summary["parameters"][name]
            low, high = p["ci95"]
            inside += low <= true <= high
            z.append((p["estimate"] - true) / p["stderr"])
            assert abs(z[-1]) < 4.5, (seed, name, p)
    coverage = inside / 40
    report["fit_coverage_95"] = coverage
    assert inside >= 34, f"{inside} of 40 intervals hold the truth"
    # Nor are the intervals too wide (which would hold the truth every time): the errors
    # scale with the intervals, their spread near 1 standard error.
    assert 0.6 < float(np.std(z)) < 1.5


def test_an_unidentifiable_pair_is_named(fmu_path, truth_rows, tmp_path):
    """The motor law's constant Mm_a0 and the input M_m add up to one torque: only their sum
    shows in the data. The fit says so and names both."""
    write_csv(tmp_path / "measured.csv", noisy(truth_rows, 1))
    spec = fit_spec(fmu_path, tmp_path)
    spec["scenario"]["parameters"] = dict(TRUTH)
    spec["fit"]["parameters"] = {"Mm_a0": {"start": 90.0, "range": [50.0, 150.0]},
                                 "M_m": {"start": 5.0, "range": [-20.0, 20.0]}}
    summary = fit(spec, out=tmp_path / "out", serial=True).summary
    assert summary["unidentifiable"] == ["M_m", "Mm_a0"]
    assert summary["correlation"]["Mm_a0"]["M_m"] < -0.99
    assert any("Mm_a0 and M_m cannot be told apart" in w for w in summary["warnings"])
    assert not summary["parameters"]["M_m"]["identifiable"]
    estimates = [summary["parameters"][n]["estimate"] for n in ("Mm_a0", "M_m")]
    assert abs(sum(estimates) - 100.0) < 0.5  # what the data do decide
    plot = tmp_path / "out/plots/fit_correlation.png"
    assert plot.stat().st_size > 10_000


def test_the_truth_is_found_and_the_pair_is_not_flagged(fmu_path, truth_rows, tmp_path):
    """The counterpart of the test above: the identifiable pair gets no warning, its
    correlation is small, and every evaluated run is in the Parquet points with its cost."""
    write_csv(tmp_path / "measured.csv", noisy(truth_rows, 3))
    result = fit(fit_spec(fmu_path, tmp_path), out=tmp_path / "out", serial=True)
    s = result.summary
    assert s["unidentifiable"] == [] and abs(s["correlation"]["k34"]["d34"]) < 0.5
    points = pd.read_parquet(tmp_path / "out/points.parquet")
    assert len(points) == s["evaluations"] == s["computed"]
    assert set(points["role"]) == {"trial", "jacobian"}
    best = points.loc[points["cost"].idxmin()]
    assert best["cost"] == pytest.approx(s["cost"], rel=1e-12)
    series = pd.read_parquet(tmp_path / "out/series")
    assert set(series["variable"].astype(str)) == set(MEASURED)
    assert {p.name for p in result.plots} == {"fit_trajectories.png", "fit_residuals.png",
                                             "fit_correlation.png"}


def test_failed_runs_are_infinitely_bad_points_not_a_crash(fmu_path, tmp_path):
    """Rod lengths above about 0.945 m do not assemble. Data made at 0.93 m, starts on both
    sides: the runs past the limit fail, the starts inside it fail at once, and the fit
    still finds 0.93 from the others, reporting each start."""
    rows = exact_rows(fmu_path, ["L"], [0.93], scenario=dict(SCENARIO, stop=2.0))
    write_csv(tmp_path / "measured.csv", rows)
    spec = fit_spec(fmu_path, tmp_path, scenario=dict(SCENARIO, stop=2.0))
    spec["data"].pop("sigma")
    spec["fit"] = {"parameters": {"L": {"start": 0.5, "range": [0.4, 1.2]}}, "starts": 4, "seed": 5}
    result = fit(spec, out=tmp_path / "out", serial=True, plots=False)
    s = result.summary
    assert s["status"] == "converged"
    assert s["parameters"]["L"]["estimate"] == pytest.approx(0.93, abs=1e-8)
    statuses = [start["status"] for start in s["starts"]]
    assert "failed" in statuses and "converged" in statuses
    failed = next(start for start in s["starts"] if start["status"] == "failed")
    assert "initialisation failed" in failed["message"]
    assert (result.points["status"] != "ok").sum() >= 3


def test_serial_and_a_local_cluster_give_the_same_fit_to_the_last_bit(fmu_path, truth_rows, tmp_path):
    """Every run is deterministic and each start's path depends only on its runs, so four
    starts side by side on two workers give what one after another gave here."""
    write_csv(tmp_path / "measured.csv", noisy(truth_rows, 4))
    spec = fit_spec(fmu_path, tmp_path)
    spec["fit"].update(starts=4, seed=11)
    serial = fit(spec, out=tmp_path / "serial", serial=True, plots=False).summary
    cluster = fit(spec, out=tmp_path / "cluster", workers=2, plots=False).summary
    assert cluster["engine"] == "LocalCluster" and cluster["workers"] == 2
    for key in ("parameters", "correlation", "cost", "residual_rms", "starts", "evaluations"):
        assert serial[key] == cluster[key], key
    a = pd.read_parquet(tmp_path / "serial/points.parquet").set_index("point_id").sort_index()
    b = pd.read_parquet(tmp_path / "cluster/points.parquet").set_index("point_id").sort_index()
    assert a[["k34", "d34", "status", "cost"]].equals(b[["k34", "d34", "status", "cost"]])


def test_a_fit_on_a_real_scheduler_gives_the_serial_fit(fmu_path, truth_rows, tmp_path):
    write_csv(tmp_path / "measured.csv", noisy(truth_rows, 6))
    serial = fit(fit_spec(fmu_path, tmp_path), out=tmp_path / "serial", serial=True, plots=False).summary
    address, processes = start_cluster(tmp_path, environment_for_workers(), ["--nworkers", "1"])
    try:
        remote = fit(fit_spec(fmu_path, tmp_path), out=tmp_path / "remote", scheduler=address, plots=False).summary
    finally:
        stop_cluster(processes)
    assert remote["workers"] == 2 and remote["parameters"] == serial["parameters"]


def test_an_interrupted_fit_resumes_without_running_its_points_again(fmu_path, truth_rows, tmp_path):
    """A fit whose last runs were lost (their Parquet parts deleted, as a kill leaves it)
    replays its path from the stored runs and computes only the lost ones."""
    write_csv(tmp_path / "measured.csv", noisy(truth_rows, 8))
    whole = fit(fit_spec(fmu_path, tmp_path), out=tmp_path / "whole", serial=True, plots=False).summary
    shutil.copytree(tmp_path / "whole", tmp_path / "cut")
    lost = lose_the_later_parts(tmp_path / "cut")
    with pytest.raises(FileExistsError):
        fit(fit_spec(fmu_path, tmp_path), out=tmp_path / "cut", serial=True, plots=False)
    resumed = fit(fit_spec(fmu_path, tmp_path), out=tmp_path / "cut", serial=True, resume=True, plots=False).summary
    assert resumed["parameters"] == whole["parameters"]
    assert resumed["computed"] == lost and resumed["resumed"] == whole["evaluations"] - lost
    assert len(pd.read_parquet(tmp_path / "cut/points.parquet")) == whole["evaluations"]
    # Other data, same file name: not the same fit.
    write_csv(tmp_path / "measured.csv", noisy(truth_rows, 9))
    with pytest.raises(ValueError, match="the specification or its data changed since the fit began"):
        fit(fit_spec(fmu_path, tmp_path), out=tmp_path / "cut", serial=True, resume=True, plots=False)


def _bad(tmp, fmu_path, truth_rows):
    """Each bad input: how to make it, and the field its error must name."""
    good = noisy(truth_rows, 0)

    def data(rows, header=("time", *MEASURED)):
        write_csv(tmp / "measured.csv", rows, header)

    def text(content):
        (tmp / "measured.csv").write_text(content)

    def param(name, entry):
        def change(spec):
            spec["fit"]["parameters"][name] = entry
        return change

    def no_sigma(spec):
        spec["data"].pop("sigma")

    nan = good.copy()
    nan[5, 2] = math.nan
    inf = good.copy()
    inf[7, 1] = math.inf
    late = good.copy()
    late[-1, 0] = 3.5
    off_grid = good.copy()
    off_grid[3, 0] = 0.065
    return {
        "no data file": ("data.file", lambda s: s["data"].update(file=str(tmp / "missing.csv")), None),
        "no time column": ("data.file", None, lambda: data(good, ("t", *MEASURED))),
        "a column that names no output": ("data.file", no_sigma, lambda: data(good, ("time", "omega1", "omega9"))),
        "a column that names a parameter": ("data.file", no_sigma, lambda: data(good, ("time", "omega1", "k12"))),
        "NaN": ("data.file", None, lambda: data(nan)),
        "infinity": ("data.file", None, lambda: data(inf)),
        "text": ("data.file", None, lambda: text("time,omega1\n0,1\n0.02,fast\n")),
        "no rows": ("data.file", None, lambda: text("time,omega1\n")),
        "times out of order": ("data.file", None, lambda: text("time,omega1\n0,1\n0.04,1\n0.02,1\n")),
        "a time after the scenario": ("data.file", None, lambda: data(late)),
        "a time off the grid": ("data.file", None, lambda: data(off_grid)),
        "a sigma for no column": ("data.sigma.omega2", lambda s: s["data"]["sigma"].update(omega2=1.0), None),
        "a sigma of zero": ("data.sigma.omega1", lambda s: s["data"]["sigma"].update(omega1=0.0), None),
        "a start outside its range": ("fit.parameters.k34.start", param("k34", {"start": 500.0, "range": [10.0, 400.0]}), None),
        "an empty range": ("fit.parameters.k34.range", param("k34", {"start": 50.0, "range": [400.0, 10.0]}), None),
        "no parameter": ("fit.parameters", lambda s: s["fit"].update(parameters={}), None),
        "a parameter the FMU lacks": ("fit.parameters.k99", param("k99", {"start": 1.0, "range": [0.0, 2.0]}), None),
        "an output as a parameter": ("fit.parameters.omega1", param("omega1", {"start": 1.0, "range": [0.0, 2.0]}), None),
        "a range the FMU refuses": ("fit.parameters.d34", param("d34", {"start": 0.1, "range": [-1.0, 5.0]}), None),
        "a parameter also fixed": ("fit.parameters.k34", lambda s: s["scenario"].update(parameters={"k34": 100.0}), None),
        "a parameter also an input": ("fit.parameters.M_r", lambda s: (s["scenario"].update(inputs={"M_r": 1.0}),
                                                                       s["fit"]["parameters"].update(M_r={"start": 0.0, "range": [-1.0, 1.0]})), None),
        "starts without a seed": ("fit.seed", lambda s: s["fit"].update(starts=3), None),
        "a fixed value the FMU refuses": ("scenario.parameters.J1", lambda s: s["scenario"].update(parameters={"J1": -1.0}), None),
        "an unknown field": ("fit.method", lambda s: s["fit"].update(method="lm"), None),
        "an unknown Jacobian": ("fit.jacobian", lambda s: s["fit"].update(jacobian="adjoint"), None),
    }


BAD = list(_bad(pathlib.Path("."), None, np.zeros((20, 3))))


@pytest.mark.parametrize("case", BAD)
def test_a_bad_input_is_refused_by_field_before_anything_runs(fmu_path, truth_rows, tmp_path, case):
    field, change_spec, write_data = _bad(tmp_path, fmu_path, truth_rows)[case]
    write_csv(tmp_path / "measured.csv", noisy(truth_rows, 0))
    if write_data:
        write_data()
    spec = fit_spec(fmu_path, tmp_path)
    if change_spec:
        change_spec(spec)
    with pytest.raises(SpecError) as refused:
        fit(spec, out=tmp_path / "out", serial=True, plots=False)
    # Every mistake comes in one run: a file of one column also leaves the spec's σ of
    # another without its column.
    named = {e.field for e in getattr(refused.value, "errors", [refused.value])}
    assert field in named, str(refused.value)
    assert not (tmp_path / "out").exists()


def test_any_fmu_fits_the_compiled_dc_motor(tmp_path):
    """Nothing of the fit knows the mechanism: the DC motor's resistance and inductance
    from its current after a voltage step, against a speed that ramps (a tabulated input)."""
    motor = packed("DC_MOTOR_FMU", "target/fmu/DcMotor.fmu", "motor")
    scenario = {"stop": 0.2, "step": 0.001, "tolerance": 1e-8,
                "inputs": {"voltage": 24.0, "omega": {"times": [0.0, 0.2], "values": [0.0, 8.0]}}}
    runner = local_runner(Archive.read(motor))
    runner.configure(Scenario.of({"scenario": scenario}).plan([], {"variables": ["current"], "every": 2}))
    [made] = runner.run(["R", "L"], [[0.5, 0.01]])
    rows = np.array(made["series"])
    rows[:, 1] += np.random.default_rng(12).normal(0.0, 0.1, size=len(rows))
    write_csv(tmp_path / "current.csv", rows, ("time", "current"))
    spec = {"fmu": str(motor), "scenario": scenario,
            "data": {"file": str(tmp_path / "current.csv"), "sigma": {"current": 0.1}},
            "fit": {"parameters": {"R": {"start": 1.0, "range": [0.05, 5.0]},
                                   "L": {"start": 0.05, "range": [0.001, 0.5]}}}}
    summary = fit(spec, out=tmp_path / "out", serial=True, plots=False).summary
    assert summary["status"] == "converged" and summary["unidentifiable"] == []
    for name, true in {"R": 0.5, "L": 0.01}.items():
        low, high = summary["parameters"][name]["ci95"]
        assert low <= true <= high and high - low < 0.05 * true, (name, low, high)


EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "examples/fit"


def test_the_example_measurements_are_what_their_script_makes(fmu_path, tmp_path):
    """The examples' data files are the output of make_measurements.py on this FMU, bit for
    bit."""
    done = subprocess.run([sys.executable, str(EXAMPLE / "make_measurements.py"), str(fmu_path), str(tmp_path)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    for name in ("measured.csv", "braked.csv", "boosted.csv"):
        assert (tmp_path / name).read_bytes() == (EXAMPLE / name).read_bytes(), name


def test_the_example_fit_runs_from_the_command_line_and_finds_the_truth(fmu_path, tmp_path):
    done = fit_command(fmu_path, EXAMPLE / "fit.toml", "--out", tmp_path / "out")
    assert done.returncode == 0, done.stderr
    assert "fmusweep fit: converged" in done.stdout and "engine: serial" in done.stdout
    summary = json.loads((tmp_path / "out/fit.json").read_text())
    for name, true in {"k34": 150.0, "d34": 0.8}.items():
        low, high = summary["parameters"][name]["ci95"]
        assert low <= true <= high
    assert len(summary["starts"]) == 4 and summary["warnings"] == []
    for picture in ("fit_trajectories", "fit_residuals", "fit_correlation"):
        assert (tmp_path / f"out/plots/{picture}.png").stat().st_size > 10_000


def test_the_command_line_refuses_a_bad_spec_by_field(fmu_path, tmp_path):
    (tmp_path / "fit.toml").write_text((EXAMPLE / "fit.toml").read_text().replace(
        'file = "measured.csv"', 'file = "nowhere.csv"'))
    env = dict(environment_for_workers(), FMUSWEEP_FMU=str(fmu_path))
    done = subprocess.run([sys.executable, "-m", "fmusweep", "fit", str(tmp_path / "fit.toml")],
                          env=env, capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.startswith("fmusweep fit: data.file: cannot read") and "nowhere.csv" in done.stderr
    help_text = subprocess.run([sys.executable, "-m", "fmusweep", "fit", "--help"], capture_output=True,
                               text=True).stdout
    assert "example:" in help_text and "[fit.parameters]" in help_text


@pytest.mark.parametrize("coupling_tolerance", [None, 1e-7])
def test_a_coupled_system_fits_as_one_fmu(fmu_path, tmp_path, coupling_tolerance):
    """A [system] of the DC motor and the mechanism: the motor's resistance and the load
    spring's damping from the mechanism's speed and the motor's current, measured with
    noise; both 95 % intervals hold the truth, at fixed communication steps and with the
    steps chosen by a coupling tolerance (every run's steps then in its row)."""
    motor = packed("DC_MOTOR_FMU", "target/fmu/DcMotor.fmu", "motor")
    system = {"components": {"motor": str(motor), "mechanism": str(fmu_path)},
              "connections": [["motor.torque", "mechanism.M_m"], ["mechanism.omega1", "motor.omega"]]}
    laws = {"mechanism.Mm_a0": 0.0, "mechanism.Mm_a1": 0.0, "mechanism.Mm_a2": 0.0, "mechanism.c4": 0.5}
    scenario = {"stop": 1.0, "step": 0.001, "tolerance": 1e-8, "parameters": laws}
    from fmusweep.schema.core import read
    from fmusweep.schema.sweep import SystemTable
    from fmusweep.system import System, load_system
    table = read(SystemTable, system, ("system",)).complete
    runner, _ = load_system(System.from_table(table, tmp_path).build(0.001))
    columns = ["mechanism.omega1", "motor.current"]
    runner.configure(Scenario.of({"scenario": scenario}).plan([], {"variables": columns, "every": 10}))
    [made] = runner.run(["motor.R", "mechanism.d34"], [[0.6, 0.8]])
    rows = np.array(made["series"])
    rows[:, 1:] += np.random.default_rng(21).normal(0.0, [0.02, 0.05], size=rows[:, 1:].shape)
    write_csv(tmp_path / "measured.csv", rows, ("time", *columns))
    if coupling_tolerance is not None:
        system = dict(system, coupling_tolerance=coupling_tolerance)
        scenario = dict(scenario, step=0.01)
    spec = {"system": system, "scenario": scenario,
            "data": {"file": str(tmp_path / "measured.csv"),
                     "sigma": {"mechanism.omega1": 0.02, "motor.current": 0.05}},
            "fit": {"parameters": {"motor.R": {"start": 1.0, "range": [0.1, 5.0]},
                                   "mechanism.d34": {"start": 0.3, "range": [0.0, 5.0]}}}}
    result = fit(spec, out=tmp_path / "out", serial=True, plots=False)
    summary = result.summary
    assert summary["status"] == "converged"
    for name, true in {"motor.R": 0.6, "mechanism.d34": 0.8}.items():
        low, high = summary["parameters"][name]["ci95"]
        assert low <= true <= high, (name, low, high)
    if coupling_tolerance is not None:
        ok = result.points[result.points["status"] == "ok"]
        assert (ok["coupling_error"] <= coupling_tolerance).all() and (ok["coupling_steps"] > 100).all()


def test_every_mistake_of_a_fit_spec_is_reported_in_one_pass(fmu_path, truth_rows, tmp_path):
    """The fields' mistakes of every table and the names the FMU lacks, in one run."""
    write_csv(tmp_path / "measured.csv", noisy(truth_rows, 0))
    spec = fit_spec(fmu_path, tmp_path)
    spec["fit"].update(starts=3, method="lm")
    spec["data"]["sigma"]["omega1"] = 0.0
    spec["fit"]["parameters"]["k43"] = {"start": 1.0, "range": [0.0, 2.0]}
    with pytest.raises(SpecError) as refused:
        fit(spec, out=tmp_path / "out", serial=True, plots=False)
    said = str(refused.value)
    assert "4 problems" in said, said
    for field in ("fit.seed", "fit.method", "data.sigma.omega1", "fit.parameters.k43"):
        assert field in said, (field, said)
    assert "did you mean 'k34'" in said, said
    assert not (tmp_path / "out").exists()
