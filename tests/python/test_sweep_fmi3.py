"""FMI 3.0 Co-Simulation swept by the native runner: the FMU's FMI 3.0 archive gives the
FMI 2.0 archive's results bit for bit where nothing happens that only FMI 3.0 can handle;
a change-point linkage goes on through its change point in event mode (FMPy's FMI 3.0
master with event mode gives the same numbers), where FMI 2.0 can only discard; an
enumeration is a design column like a Real; a system may mix FMI 2.0 and FMI 3.0
components; an FMI 3.0 FMU the runner cannot run is refused by name before any point
runs."""

import re

import fmpy
import numpy as np
import pytest

from conftest import ROOT
from fmusweep import SpecError, run_sweep
from sweep_helpers import grid_spec, in_description, repacked
from test_sweep_system import MECHANISM, system_spec

CHANGE_POINTS = ROOT / "examples/sweeps/change_point_branches.toml"
COLUMNS = ["status", "t_end", "steps", "peak_rod_force", "omega1_ripple", "n_rhs"]


def sweep(spec, fmu, out, **options):
    return run_sweep(spec, fmu=fmu, out=out, serial=True, progress=False, plots=False,
                     **options)


def test_the_fmi3_archive_sweeps_as_the_fmi2_archive_bit_for_bit(fmu_path, fmu3_path, tmp_path):
    spec = grid_spec()
    spec["outputs"]["series"] = {"variables": ["omega1", "phi4", "n_steps", "active_solver"]}
    spec["outputs"]["metrics"]["linkage"] = {"variable": "linkage_class", "kind": "final"}
    two = sweep(spec, fmu_path, tmp_path / "fmi2")
    three = sweep(spec, fmu3_path, tmp_path / "fmi3")
    a, b = two.points, three.points
    assert (a["status"] == "ok").sum() == 8 and (a["status"] == "error").sum() == 4
    assert a[COLUMNS + ["linkage"]].equals(b[COLUMNS + ["linkage"]])
    # The unassemblable geometry is refused by both, naming L; each version its own call.
    bad = b[b["status"] == "error"]
    assert bad["message"].str.contains("L").all()
    assert bad["message"].str.contains("fmi3ExitInitializationMode").all(), bad["message"]
    assert (b.loc[b["status"] == "ok", "events"] == 0).all()
    assert (a.loc[a["status"] == "ok", "events"] == 0).all()
    assert (b.loc[b["status"] == "ok", "linkage"] == 1).all()  # crank_rocker, an Enumeration
    sa, sb = two.series(), three.series()
    assert len(sa) > 1000 and sa.reset_index(drop=True).equals(sb.reset_index(drop=True))


def test_a_change_point_sweep_goes_through_in_event_mode_where_fmi2_discards(fmu_path,
                                                                             fmu3_path,
                                                                             tmp_path):
    results = run_sweep(CHANGE_POINTS, out=tmp_path / "fmi3", serial=True, progress=False,
                        plots=False)
    p = results.points
    assert len(p) == 8 and (p["status"] == "ok").all(), p[["status", "message"]]
    assert (p["linkage_class"] == 6).all()  # change_point
    assert (p["events"] >= 1).all() and (p["t_end"] == 8.0).all()
    assert (p["residual"] < 1e-12).all()
    # The two branches part: the same geometry ends elsewhere on each.
    by_branch = p.pivot(index="l3", columns="change_point_branch", values="phi4_end")
    assert (np.abs(by_branch[1.0] - by_branch[2.0]) > 0.5).all(), by_branch
    # FMPy's FMI 3.0 master, with event mode and early return, gives the same numbers.
    for _, row in p.iloc[2:4].iterrows():
        start = {"Mm_a0": 0.0, "Mm_a1": 0.0, "Mm_a2": 0.0, "Mr_b0": 0.0, "Mr_b1": 0.0,
                 "phi2_0": np.pi / 2, "omega2_0": 4.0, "l3": row["l3"], "L": row["L"],
                 "change_point_branch": int(row["change_point_branch"])}
        r = fmpy.simulate_fmu(str(fmu3_path), fmi_type="CoSimulation", start_values=start,
                              stop_time=8.0, output_interval=0.01, relative_tolerance=1e-8,
                              use_event_mode=True, early_return_allowed=True,
                              output=["phi4", "energy"], record_events=True)
        assert r["time"][-1] == 8.0
        assert (r["phi4"][-1], r["energy"][-1]) == (row["phi4_end"], row["energy_end"])
        assert len(r) - 801 == 2 * row["events"]  # FMPy records two rows per event
    # The same points through the FMI 2.0 archive: each ends in discard at the change point.
    two = run_sweep(CHANGE_POINTS, fmu=fmu_path, out=tmp_path / "fmi2", serial=True,
                    progress=False, plots=False).points
    assert (two["status"] == "discard").all(), two[["status", "message"]]
    assert (two["t_end"] < 8.0).all() and two["message"].str.contains("fmi2DoStep").all()


def test_a_system_may_mix_fmi2_and_fmi3_components(fmu_path, fmu3_path, motor_path, tmp_path):
    """With inputs held over each step, the mechanism's FMI 3.0 archive in the system gives
    what its FMI 2.0 archive gives, bit for bit."""
    runs = {}
    for name, mechanism in (("fmi2", fmu_path), ("fmi3", fmu3_path)):
        spec = system_spec(mechanism, motor_path, stop=1.0, series=True, engine=("native", 0))
        runs[name] = run_sweep(spec, out=tmp_path / name, serial=True, progress=False,
                               plots=False)
    two, three = runs["fmi2"], runs["fmi3"]
    assert list(three.points["status"]) == ["ok", "ok"]
    columns = ["final_omega1", "peak_current", "t_end", "steps"]
    assert two.points[columns].equals(three.points[columns])
    assert two.series().equals(three.series())


def _coupling_error(fmu3_path, motor_path, directory, derivatives, step):
    """The worst scaled state error of the motor and the mechanism's FMI 3.0 archive,
    coupled at H = `step` over 1 s, against the monolithic reference."""
    import reference
    states = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4"]
    names = [f"mechanism.{n}" for n in states] + ["motor.current"]
    spec = system_spec(fmu3_path, motor_path, stop=1.0, design={"mechanism.d34": {"values": [1.0]}},
                       engine=("native", derivatives))
    spec["scenario"]["step"] = step
    spec["outputs"]["series"] = {"variables": names}
    series = run_sweep(spec, out=directory / f"out-{derivatives}-{step}", serial=True,
                       progress=False, plots=False).series()
    columns = [series[series["variable"] == v].sort_values("time") for v in names]
    times = columns[0]["time"].to_numpy()
    mine = np.column_stack([c["value"].to_numpy() for c in columns])
    exact = reference.solve_with_motor(reference.Params(**MECHANISM, d34=1.0), reference.Motor(),
                                       times, rtol=1e-11)
    return float((np.abs(mine - exact) / np.maximum(1.0, np.abs(exact).max(axis=0))).max())


def test_input_derivatives_reach_only_the_components_that_take_them(fmu3_path, motor_path,
                                                                    tmp_path):
    """FMI 3.0 has no input derivatives: the mechanism's torque is held over each step,
    while the FMI 2.0 motor still gets omega1's derivatives (from fmi3GetOutputDerivatives).
    The held torque keeps the coupling error of first order, and the derivatives the motor
    gets make it smaller than with both held."""
    one_way = [_coupling_error(fmu3_path, motor_path, tmp_path, 2, h) for h in (1e-3, 2e-3)]
    held = _coupling_error(fmu3_path, motor_path, tmp_path, 0, 1e-3)
    order = np.log2(one_way[1] / one_way[0])
    assert 0.8 < order < 1.3, one_way
    assert one_way[0] < held, (one_way, held)


_with_clock = in_description(b"</ModelVariables>", b'<Clock name="tick" valueReference="999" '
                             b'causality="input" intervalVariability="constant"/></ModelVariables>')


def _without_binary(name, data):
    return None if name.startswith("binaries/x86_64-linux/") else data


@pytest.mark.parametrize("change, words", [
    (_with_clock, ["clock", "\"tick\""]),
    (_without_binary, ["no binary for this platform", "x86_64-linux"]),
])
def test_an_fmi3_fmu_the_runner_cannot_run_is_refused_by_name(fmu3_path, tmp_path, change,
                                                              words):
    bad = repacked(fmu3_path, tmp_path / "Changed.fmu", change)
    with pytest.raises(SpecError) as refused:
        sweep(grid_spec(), bad, tmp_path / "out")
    assert refused.value.field == "fmu" and str(bad) in str(refused.value)
    for word in words:
        assert word in str(refused.value), str(refused.value)
    assert not (tmp_path / "out" / "points.parquet").exists()


def test_an_unsupported_variable_type_is_refused_by_name(fmu3_path, tmp_path):
    """An FMI 3.0 type the runner does not read (here a Float32 output) is refused where
    the spec names it."""
    float32 = in_description(b"</ModelVariables>", b'<Float32 name="f32" valueReference="998" '
                             b'causality="output"/></ModelVariables>')
    bad = repacked(fmu3_path, tmp_path / "Changed.fmu", float32)
    spec = grid_spec()
    spec["outputs"]["metrics"]["f"] = {"variable": "f32", "kind": "final"}
    with pytest.raises(SpecError, match="f32"):
        sweep(spec, bad, tmp_path / "out")
    assert not (tmp_path / "out" / "points.parquet").exists()


def test_an_fmi3_sweep_resumes_what_was_lost(tmp_path):
    """The change-point sweep in batches of two; a batch's part lost, the sweep resumed:
    only its points run again, and the table is the uninterrupted one."""
    whole = run_sweep(CHANGE_POINTS, out=tmp_path / "whole", serial=True, progress=False,
                      plots=False, batch_size=2).points
    parts = sorted((tmp_path / "whole" / "points").glob("part-*.parquet"))
    assert len(parts) >= 3
    parts[1].unlink()
    (tmp_path / "whole" / "points.parquet").unlink()
    again = run_sweep(CHANGE_POINTS, out=tmp_path / "whole", serial=True, progress=False,
                      plots=False, batch_size=2, resume=True)
    assert again.summary.resumed == 8 - 2 and again.summary.computed == 2
    columns = ["point", "status", "phi4_end", "energy_end", "events", "t_end"]
    assert again.points[columns].equals(whole[columns])
