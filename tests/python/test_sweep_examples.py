"""The worked sweeps of examples/sweeps run from the command line as the README shows,
and give what each promises."""

import json
import pathlib
import subprocess
import sys

import pyarrow.parquet as pq

from conftest import packed
from sweep_helpers import environment_for_workers

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples/sweeps"


def sweep(spec, fmu_path, out):
    env = dict(environment_for_workers(), FMUSWEEP_FMU=str(fmu_path))
    done = subprocess.run([sys.executable, "-m", "fmusweep", str(EXAMPLES / spec), "--out", str(out),
                           "--workers", "2", "--no-progress"], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return pq.read_table(out / "points.parquet").to_pandas(), done.stdout


def test_rod_force_grid(fmu_path, tmp_path):
    points, said = sweep("rod_force_grid.toml", fmu_path, tmp_path)
    assert len(points) == 1600 and (points["status"] == "ok").all()
    assert points["k34"].nunique() == 40 and points["L"].nunique() == 40
    assert "1600 points" in said
    for metric in ("peak_rod_force", "omega1_ripple"):
        assert (tmp_path / "plots" / f"heatmap_{metric}.png").stat().st_size > 10_000
    # The peak rod force grows with the rod length at the soft end of k34.
    soft = points[points["k34"] == points["k34"].min()].sort_values("L")
    assert soft["peak_rod_force"].iloc[-1] > 1.5 * soft["peak_rod_force"].iloc[0]


def test_sobol_study_of_the_rod_force(fmu_path, tmp_path):
    points, _ = sweep("sobol_rod_force.toml", fmu_path, tmp_path)
    assert len(points) == 8192 and (points["status"] == "ok").all()
    s = json.loads((tmp_path / "sensitivity.json").read_text())["peak_rod_force"]
    assert s["names"] == ["J1", "J2", "J3", "J4", "k12", "k34"]
    assert all(abs(x) < 1.5 for x in s["ST"]) and max(s["ST"]) > 0.3
    assert (tmp_path / "plots" / "sobol_peak_rod_force.png").exists()


def test_latin_hypercube_over_the_geometry(fmu_path, tmp_path):
    points, _ = sweep("lhs_geometry.toml", fmu_path, tmp_path)
    assert len(points) == 500
    assert (points["status"] == "ok").sum() > 250
    failed = points[points["status"] != "ok"]
    assert failed["message"].str.len().gt(0).all()
    assert (tmp_path / "plots" / "scatter.png").exists()


def _with_components(example, fmu_path, directory):
    """The example with its components the FMUs under test."""
    motor = packed("DC_MOTOR_FMU", "target/fmu/DcMotor.fmu", "motor")
    load = packed("FLYWHEEL_LOAD_FMU", "target/fmu/FlywheelLoad.fmu", "motor")
    text = (EXAMPLES / example).read_text()
    text = text.replace('"../../target/fmu/DcMotor.fmu"', f'"{motor.resolve()}"')
    text = text.replace('"../../target/fmu/FlywheelLoad.fmu"', f'"{load.resolve()}"')
    text = text.replace('"../../target/fmu/CyclicMechanism.fmu"', f'"{fmu_path.resolve()}"')
    (directory / example).write_text(text)
    return directory / example


def test_coupled_motor_and_mechanism(fmu_path, tmp_path):
    """The [system] example: 400 coupled runs, all ok, and the load spring's resonance
    where the motor's no-load speed V/k meets √(k34/J4)."""
    spec = _with_components("coupled_motor.toml", fmu_path, tmp_path)
    points, said = sweep(spec, fmu_path, tmp_path / "out")
    assert len(points) == 400 and (points["status"] == "ok").all()
    assert "400 points" in said
    worst = points.loc[points["omega1_ripple"].idxmax()]
    assert 22.0 <= worst["motor.voltage"] <= 28.0 and worst["mechanism.d34"] == points["mechanism.d34"].min()


def test_coupled_motor_with_a_coupling_tolerance(fmu_path, tmp_path):
    """The same grid with a coupling tolerance: every point ok within it, its steps
    reported, and the same resonance as at fixed steps."""
    spec = _with_components("coupled_motor_tolerance.toml", fmu_path, tmp_path)
    points, said = sweep(spec, fmu_path, tmp_path / "out")
    assert len(points) == 400 and (points["status"] == "ok").all()
    assert (points["coupling_error"] <= 1e-5).all() and (points["coupling_steps"] > 1000).all()
    assert (points["coupling_rejected"] <= 0.1 * points["coupling_steps"]).all()
    worst = points.loc[points["omega1_ripple"].idxmax()]
    assert 22.0 <= worst["motor.voltage"] <= 28.0 and worst["mechanism.d34"] == points["mechanism.d34"].min()


def test_flywheel_on_a_stiff_shaft_with_a_coupling_tolerance(fmu_path, tmp_path):
    """The second coupled example: every point ok within its coupling tolerance, few steps
    rejected; a heavier flywheel takes more torque to swing, a stiffer shaft twists less."""
    spec = _with_components("coupled_flywheel_tolerance.toml", fmu_path, tmp_path)
    points, said = sweep(spec, fmu_path, tmp_path / "out")
    assert len(points) == 100 and (points["status"] == "ok").all()
    assert (points["coupling_error"] <= 1e-5).all() and (points["coupling_steps"] > 500).all()
    assert (points["coupling_rejected"] <= 0.1 * points["coupling_steps"]).all()
    by_k = points.sort_values("load.J").groupby("load.k")["peak_shaft_torque"]
    assert (by_k.last() > 5 * by_k.first()).all()
    by_j = points.sort_values("load.k").groupby("load.J")["peak_twist"]
    assert (by_j.last() < by_j.first() / 10).all()


def test_linkages_through_their_change_point_with_the_fmi3_archive(fmu_path, fmu3_path,
                                                                   tmp_path):
    """The FMI 3.0 example on two Dask workers: every geometry goes through its change
    point (an event each) on both branches, which part."""
    text = (EXAMPLES / "change_point_branches.toml").read_text()
    text = text.replace('"../../target/fmu/CyclicMechanism-fmi3.fmu"', f'"{fmu3_path.resolve()}"')
    (tmp_path / "change_point_branches.toml").write_text(text)
    points, said = sweep(tmp_path / "change_point_branches.toml", fmu_path, tmp_path / "out")
    assert len(points) == 8 and (points["status"] == "ok").all(), points[["status", "message"]]
    assert (points["events"] >= 1).all() and (points["linkage_class"] == 6).all()
    ends = points.pivot(index="l3", columns="change_point_branch", values="phi4_end")
    assert ((ends[1.0] - ends[2.0]).abs() > 0.5).all()


def test_the_motor_system_as_an_ssp_file(fmu_path, tmp_path):
    """The SSP example on two Dask workers: the file's system runs natively, its load
    values and its 5 s default experiment hold, and more voltage turns the linkage faster."""
    sys.path.insert(0, str(EXAMPLES.parents[0] / "dc_motor"))
    import ssp as example  # examples/dc_motor/ssp.py
    motor = packed("DC_MOTOR_FMU", "target/fmu/DcMotor.fmu", "motor")
    ssp = example.build_ssp(fmu_path, tmp_path / "ssp", motor)
    text = (EXAMPLES / "coupled_motor_ssp.toml").read_text()
    text = text.replace('"../../target/fmu/MotorDrivenMechanism.ssp"', f'"{ssp.resolve()}"')
    (tmp_path / "coupled_motor_ssp.toml").write_text(text)
    points, said = sweep(tmp_path / "coupled_motor_ssp.toml", fmu_path, tmp_path / "out")
    assert len(points) == 100 and (points["status"] == "ok").all(), points["message"].unique()
    assert (points["t_end"] == 5.0).all() and "100 points" in said
    speed = points.groupby("motor.voltage")["final_omega1"].mean()
    assert speed.is_monotonic_increasing and speed.iloc[-1] > 2 * speed.iloc[0], speed


def test_the_rod_force_grid_through_model_exchange(fmu_path, tmp_path):
    points, said = sweep("rod_force_model_exchange.toml", fmu_path, tmp_path / "me")
    assert len(points) == 100 and (points["status"] == "ok").all(), points["message"].unique()
    assert "100 points" in said
    # The same grid through co-simulation at the same tolerance: the same forces to the
    # tolerance's order (two integrations of one model, each held to 1e-8).
    text = (EXAMPLES / "rod_force_model_exchange.toml").read_text()
    (tmp_path / "cs.toml").write_text(text.replace('interface = "model_exchange"', ""))
    cosimulation, _ = sweep(tmp_path / "cs.toml", fmu_path, tmp_path / "cs")
    mine, theirs = points.sort_values("point"), cosimulation.sort_values("point")
    force = mine["peak_rod_force"].to_numpy() / theirs["peak_rod_force"].to_numpy()
    assert abs(force - 1).max() < 1e-6, abs(force - 1).max()


def test_steady_cycles_over_the_motor_law(fmu_path, tmp_path):
    """Every point's steady cycle found; the swing peaks where two, three (and faintly
    four) times the crank's frequency meet the rocker spring's mode, as the Campbell
    diagram marks."""
    points, said = sweep("steady_cycle.toml", fmu_path, tmp_path)
    assert len(points) == 181 and (points["status"] == "ok").all(), points["message"].unique()
    assert (points["cycle_margin"] > 0).all()
    assert "181 points" in said
    for picture in ("campbell", "cycle_multipliers", "cycle", "metrics"):
        assert (tmp_path / "plots" / f"{picture}.png").stat().st_size > 10_000
    # The phase portrait is of the first two kept variables, in the order kept.
    report = (tmp_path / "report.html").read_text()
    portrait = report[report.index('"cycle-portrait"'):]
    assert '"xaxis": {"title": {"text": "phi2"}}' in portrait
    assert '"yaxis": {"title": {"text": "omega2"}}' in portrait
    crank = 1 / points["cycle_period"]
    swing = points["rod_force_swing"].to_numpy()
    peaks = [i for i in range(3, len(swing) - 3)
             if swing[i] == swing[i - 3:i + 4].max() and swing[i] > 1.2 * swing[i - 3]]
    orders = set()
    for i in peaks:
        mode = points["cycle_modes_hz"].iloc[i][0]
        k = round(mode / crank[i])
        assert abs(k * crank[i] / mode - 1) < 0.02, (i, k)
        orders.add(k)
    assert {2, 3} <= orders <= {2, 3, 4}, orders
