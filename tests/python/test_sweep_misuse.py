"""What a user can get wrong in a sweep or a fit spec, each refused by field before anything
runs, every mistake of one spec in one run, and nothing left behind: names that would share
a column of the results, a σ for some measured columns only, metric windows without a
communication point, values the FMU refuses anywhere in a design."""


import os
import pathlib
import signal
import subprocess
import sys
import time

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


# --- the command line ----------------------------------------------------------------------
LONG_GRID = """
[scenario]
stop = 60.0
step = 0.01
tolerance = 1e-8
parameters = { Mm_a0 = 100.0, Mm_a1 = -20.0, Mm_a2 = -1.0, Mr_b0 = 20.0, Mr_b1 = -0.05 }
[design]
kind = "grid"
parameters = { J3 = { linspace = [0.2, 0.6, 60] }, d12 = { linspace = [0.0, 0.5, 60] } }
[outputs.metrics]
peak = { variable = "rod_force", kind = "peak_abs" }
"""


def sweep_command(fmu_path, spec, *options, cwd=None, **popen):
    from sweep_helpers import environment_for_workers
    command = [sys.executable, "-m", "fmusweep", str(spec), "--fmu", str(fmu_path),
               "--no-progress", *map(str, options)]
    return subprocess.Popen(command, env=environment_for_workers(), cwd=cwd, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **popen)


@pytest.mark.parametrize("options, said", [
    (["--workers", "-1"], "--workers: must be a whole number ≥ 1, got -1"),
    (["--workers", "0"], "--workers: must be a whole number ≥ 1, got 0"),
    (["--serial", "--workers", "2"], "--serial: runs in this process without Dask"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:9"], "--workers: sizes the LocalCluster"),
    (["--batch-size", "0"], "--batch-size: must be a whole number ≥ 1, got 0"),
    (["--scheduler", "tcp://127.0.0.1:9"], "cannot reach the Dask scheduler at tcp://127.0.0.1:9"),
    (["--scheduler", "tcp://127.0.0.1"], "--scheduler: must be a Dask scheduler's address"),
])
def test_a_bad_engine_option_is_refused_at_once_and_leaves_nothing(fmu_path, tmp_path, options, said):
    spec = tmp_path / "long.toml"
    spec.write_text(LONG_GRID)
    started = time.monotonic()
    done = sweep_command(fmu_path, spec, *options, cwd=tmp_path)
    out, err = done.communicate(timeout=60)
    assert done.returncode == 2 and time.monotonic() - started < 20, (out, err)
    assert err.strip() == f"fmusweep: {err.strip().split(': ', 1)[1]}" and said in err, err
    assert "Traceback" not in err and not (tmp_path / "results").exists()


def _interrupted(fmu_path, tmp_path, send):
    """A 3600-point sweep on 2 workers, interrupted by `send(process)` once batches landed;
    its output and exit code."""
    spec = tmp_path / "long.toml"
    spec.write_text(LONG_GRID)
    out = tmp_path / "out"
    # As a terminal starts it: its own process group, SIGINT not ignored.
    process = sweep_command(fmu_path, spec, "--workers", "2", "--batch-size", "50", "--out", out,
                            start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((out / "points").glob("part-*"))) < 4:
        assert process.poll() is None, process.communicate()
        time.sleep(0.01)
    send(process)
    said, err = process.communicate(timeout=60)
    return process.returncode, err, out


def test_ctrl_c_says_one_clean_line_and_the_sweep_resumes(fmu_path, tmp_path):
    code, err, out = _interrupted(fmu_path, tmp_path, lambda p: os.killpg(p.pid, signal.SIGINT))
    assert code == 130 and err.strip().splitlines() == [
        "fmusweep: interrupted; every finished batch is saved: run the same command again "
        "with --resume"], err
    assert len(list((out / "points").glob("part-*"))) >= 4


def test_sigterm_to_the_client_says_the_same_and_ends_its_workers(fmu_path, tmp_path):
    code, err, out = _interrupted(fmu_path, tmp_path, lambda p: p.terminate())
    assert code == 143 and err.strip().splitlines() == [
        "fmusweep: terminated; every finished batch is saved: run the same command again "
        "with --resume"], err
    time.sleep(1.0)
    left = subprocess.run(["pgrep", "-f", f"fmu-runner serve .*fmusweep"], capture_output=True,
                          text=True).stdout.split()
    mine = [pid for pid in left if str(out) in pathlib.Path(f"/proc/{pid}/cmdline").read_text()
            ] if left else []
    assert not mine


def test_results_go_to_a_new_folder_below_results_and_the_same_line_runs_again(fmu_path, tmp_path):
    spec = tmp_path / "short.toml"
    spec.write_text(LONG_GRID.replace("stop = 60.0", "stop = 0.5").replace("60 ]", "3 ]"))
    folders = []
    for _ in range(2):
        done = sweep_command(fmu_path, spec, "--no-plots", cwd=tmp_path)
        said, err = done.communicate(timeout=120)
        assert done.returncode == 0, err
        line = next(l for l in said.splitlines() if "results in" in l)
        folders.append(line.split("results in ")[1].split("/points.parquet")[0])
    assert folders[0] != folders[1] and all(f.startswith("results/short-") for f in folders), folders
    assert all((tmp_path / f / "points.parquet").exists() for f in folders)


def test_a_script_without_the_main_guard_is_told_why_and_its_folder_stays_usable(fmu_path, tmp_path):
    script = tmp_path / "unguarded.py"
    script.write_text(f"""
import fmusweep
fmusweep.run_sweep({str(tmp_path / 'long.toml')!r}, fmu={str(fmu_path)!r},
                   out={str(tmp_path / 'out')!r}, workers=2, progress=False, plots=False)
""")
    (tmp_path / "long.toml").write_text(LONG_GRID.replace("stop = 60.0", "stop = 0.5"))
    from sweep_helpers import environment_for_workers
    done = subprocess.run([sys.executable, str(script)], env=environment_for_workers(),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode != 0
    assert 'if __name__ == "__main__":' in done.stderr, done.stderr[-3000:]
    assert "already holds a sweep" not in done.stderr
    resumed = run_sweep(tmp_path / "long.toml", fmu=fmu_path, out=tmp_path / "out", resume=True,
                        serial=True, progress=False, plots=False)
    assert len(resumed.points) == 3600 and (resumed.points["status"] == "ok").all()


def test_no_plots_keeps_the_sensitivity_indices_and_says_what_rules_them_out(fmu_path, tmp_path):
    spec = {"scenario": {"stop": 0.5, "step": 0.05, "tolerance": 1e-6,
                         "parameters": dict(PAPER_LAWS)},
            "design": {"kind": "sobol", "seed": 3, "samples": 16,
                       "parameters": {"J2": {"range": [0.2, 0.6]}, "L": {"range": [0.6, 1.3]}}},
            "outputs": {"metrics": {"top": {"variable": "omega2", "kind": "max"},
                                    "n": {"variable": "n_rhs", "kind": "final"}}}}
    results = run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False,
                        plots=False)
    assert not results.plots and results.report_html is None
    assert set(results.sensitivity) == {"top", "n"}
    failed = (results.points["status"] != "ok").sum()
    assert failed > 0 and all("have no value" in note for note in results.notes), results.notes
    assert (tmp_path / "out" / "sensitivity.json").exists()


def test_enumerations_by_item_name_and_booleans_by_true_or_false(fmu_path, tmp_path):
    """solver by its items' names and builtin_laws by true/false in a design, a fixed
    change_point_branch by name, give the rows the numbers give."""
    def spec(solver, laws, fixed_solver):
        return {"scenario": {"stop": 0.3, "step": 0.05, "tolerance": 1e-6,
                             "parameters": dict(PAPER_LAWS, change_point_branch=fixed_solver)},
                "design": {"kind": "grid", "parameters": {"solver": {"values": solver},
                                                          "builtin_laws": {"values": laws}}},
                "outputs": {"metrics": {"w": {"variable": "omega1", "kind": "final"},
                                        "used": {"variable": "active_solver", "kind": "final"}}}}
    named = run_sweep(spec(["dop853", "implicit"], [True, False], "turn"), fmu=fmu_path,
                      out=tmp_path / "named", serial=True, progress=False, plots=False).points
    numbered = run_sweep(spec([2, 3], [True, False], 2), fmu=fmu_path,
                         out=tmp_path / "numbered", serial=True, progress=False,
                         plots=False).points
    assert (named["status"] == "ok").all(), named
    columns = ["solver", "builtin_laws", "w", "used"]
    assert named[columns].equals(numbered[columns])
    assert sorted(set(named["used"])) == [2.0, 3.0] and sorted(set(named["builtin_laws"])) == [0.0, 1.0]


def test_an_unknown_item_or_a_boolean_for_a_number_is_refused_by_field(fmu_path, tmp_path):
    spec = small_grid()
    spec["scenario"]["parameters"]["solver"] = "dop835"
    spec["design"]["parameters"]["k34"] = {"values": [True, False]}
    spec["design"]["parameters"]["J2"] = {"values": ["heavy"]}
    said = refused_fields(spec, fmu_path, tmp_path)
    assert set(said) == {"scenario.parameters.solver", "design.parameters.k34.values",
                         "design.parameters.J2.values"}, said
    assert "did you mean 'dop853'" in said["scenario.parameters.solver"]
    assert "true and false set a Boolean" in said["design.parameters.k34.values"]
    assert "expected a number (kg·m2), got the string 'heavy'" in said["design.parameters.J2.values"]


def test_names_and_values_the_fmu_refuses_come_in_the_same_run(fmu_path, tmp_path):
    spec = small_grid(w={"variable": "omega22", "kind": "max"})
    spec["scenario"]["parameters"]["J4"] = -0.5
    spec["design"]["parameters"] = {"d43": {"values": [1.0]}, "d34": {"values": [-2.0, 0.3]}}
    said = refused_fields(spec, fmu_path, tmp_path)
    assert set(said) == {"outputs.metrics.w.variable", "design.parameters.d43",
                         "scenario.parameters.J4", "design.parameters.d34"}, said


def test_a_fit_specs_scenario_data_and_parameters_mistakes_come_in_one_run(fmu_path, tmp_path):
    spec = {"scenario": {"stop": 0.5, "step": 0.05, "tolerance": -1.0},
            "data": {"file": str(tmp_path / "absent.csv")},
            "fit": {"max_iterations": 0,
                    "parameters": {"k34": {"start": 900.0, "range": [10.0, 400.0]},
                                   "k43": {"start": 1.0, "range": [0.0, 2.0]}}}}
    said = refused_fields(spec, fmu_path, tmp_path, run=fit)
    assert set(said) == {"scenario.tolerance", "data.file", "fit.max_iterations",
                         "fit.parameters.k34.start", "fit.parameters.k43"}, said


def test_a_system_specs_options_connections_and_names_come_in_one_run(fmu_path, motor_path, tmp_path):
    spec = {"system": {"components": {"motor": str(motor_path), "mechanism": str(fmu_path)},
                       "connections": [["motor.torq", "mechanism.M_m"],
                                       ["mechanism.omega1", "motor.omega"]],
                       "coupling_tolerance": 3.0, "input_derivatives": 5},
            "scenario": {"stop": 0.5, "step": 0.05},
            "design": {"kind": "list", "parameters": {"mechanism.k34": {"values": [100.0]}}},
            "outputs": {"metrics": {"w": {"variable": "mechanism.omega9", "kind": "max"}}}}
    with pytest.raises(SpecError) as refused:
        run_sweep(spec, out=tmp_path / "out", serial=True, progress=False)
    said = {e.field for e in refused.value.errors}
    assert said == {"system.coupling_tolerance", "system.input_derivatives",
                    "system.connections[0]", "outputs.metrics.w.variable"}, str(refused.value)
    spec["system"].update(coupling_tolerance=1e-4, input_derivatives=0)
    with pytest.raises(SpecError) as refused:
        run_sweep(spec, out=tmp_path / "out", serial=True, progress=False)
    said = {e.field for e in refused.value.errors}
    assert said == {"system.connections[0]", "outputs.metrics.w.variable"}, str(refused.value)


def test_an_input_table_from_a_csv_file_gives_the_inline_tables_rows(fmu_path, tmp_path):
    (tmp_path / "load.csv").write_text("time,brake,other\n0,0,9\n0.1,2.5,9\n0.3,-1,9\n")
    inline = small_grid()
    inline["scenario"]["inputs"] = {"M_r": {"times": [0.0, 0.1, 0.3], "values": [0.0, 2.5, -1.0]}}
    from_file = small_grid()
    from_file["scenario"]["inputs"] = {"M_r": {"file": "load.csv", "column": "brake"}}
    a = run_sweep(inline, fmu=fmu_path, out=tmp_path / "a", serial=True, progress=False,
                  plots=False).points
    b = run_sweep(fmusweep_spec(from_file, tmp_path), fmu=fmu_path, out=tmp_path / "b",
                  serial=True, progress=False, plots=False).points
    assert (a["status"] == "ok").all() and a[["top"]].equals(b[["top"]])
    (tmp_path / "load.csv").write_text("time,brake\n0,0\n0.1,2.5\n0.3,-1\n0.2,1\n")
    with pytest.raises(SpecError) as refused:
        fmusweep_spec(from_file, tmp_path)
    assert refused.value.field == "scenario.inputs.M_r.file", refused.value


def fmusweep_spec(raw, directory):
    """The spec read with its paths relative to `directory`."""
    from fmusweep import Spec
    return Spec.from_dict(raw, directory)


def test_breakpoints_between_communication_points_are_warned_of(fmu_path, tmp_path):
    spec = small_grid()
    spec["scenario"]["inputs"] = {"M_r": {"times": [0.0, 0.12, 0.2], "values": [0.0, 1.0, 0.0]}}
    with pytest.warns(UserWarning, match=r"scenario.inputs.M_r: 1 breakpoint\(s\) at t = 0.12 lie "
                                         r"between communication points"):
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "out", serial=True, progress=False,
                  plots=False)
    spec["scenario"]["inputs"]["M_r"]["times"] = [0.0, 0.1, 0.2]
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run_sweep(spec, fmu=fmu_path, out=tmp_path / "on_grid", serial=True, progress=False,
                  plots=False)


def test_values_the_fmu_refuses_come_with_the_specs_own_mistakes(fmu_path, tmp_path):
    """Own fields wrong and values the FMU refuses, in a fit and in a sweep: one run names
    them all."""
    spec = {"scenario": {"stop": 0.5, "step": 0.05, "parameters": {"J4": -0.5}},
            "data": {"file": str(tmp_path / "absent.csv")},
            "fit": {"max_iterations": 0,
                    "parameters": {"k34": {"start": -5.0, "range": [-10.0, 400.0]}}}}
    said = refused_fields(spec, fmu_path, tmp_path, run=fit)
    assert set(said) == {"data.file", "fit.max_iterations", "scenario.parameters.J4",
                         "fit.parameters.k34"}, said
    assert "J4 = -0.5" in said["scenario.parameters.J4"]
    assert "k34 = -10, -5 (2 values)" in said["fit.parameters.k34"]
    sweep = small_grid()
    sweep["scenario"]["tolerance"] = -1.0
    sweep["scenario"]["parameters"]["d12"] = -1.0
    sweep["design"]["parameters"] = {"J2": {"values": [0.3, -0.1]}, "k34": {"values": [1.0]}}
    said = refused_fields(sweep, fmu_path, tmp_path)
    assert set(said) == {"scenario.tolerance", "scenario.parameters.d12",
                         "design.parameters.J2"}, said
    assert "J2 = -0.1" in said["design.parameters.J2"]


def test_what_the_event_loop_logs_of_calls_cut_short_is_not_shown(capfd, caplog):
    """A SIGTERM that cuts a cluster's call short may make its event loop log an error
    while the run unwinds (distributed cancelling a call not yet started): the one line
    that says what ended is all that shows."""
    import logging

    from fmusweep.cli import Terminated, _guarded

    loop = logging.getLogger("tornado.application")

    def run():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)  # the signal arrives during it
        except Terminated:
            loop.error("Exception in callback cancel")
            raise
        return 0

    with caplog.at_level(logging.ERROR, logger="tornado.application"):
        assert _guarded("fmusweep", "every finished batch is saved", run) == 143
        assert [r for r in caplog.records if r.name == "tornado.application"] == []
        # Outside an interrupt the loop's errors are logged as before.
        loop.error("shown")
        assert [r.getMessage() for r in caplog.records] == ["shown"]
    err = capfd.readouterr().err
    assert err.strip().splitlines() == [
        "fmusweep: terminated; every finished batch is saved: run the same command again "
        "with --resume"], err
