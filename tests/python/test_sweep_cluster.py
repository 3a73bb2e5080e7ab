"""The sweep on Dask: a LocalCluster, and a real `dask scheduler` with two `dask worker`
processes started here on loopback, give the serial results bit for bit; a sweep whose
client is killed half-way resumes without redoing finished batches."""

import os
import pathlib
import signal
import subprocess
import sys
import time

import pyarrow.parquet as pq
import pytest

from fmusweep import run_sweep
from sweep_helpers import (environment_for_workers, faulty_fmu, grid_spec, kill_during,
                           same_results, start_cluster, stop_cluster)

VENV_BIN = pathlib.Path(sys.executable).parent
METRICS = ["peak_rod_force", "omega1_ripple", "n_rhs"]


@pytest.fixture(scope="module")
def serial_grid(fmu_path, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial") / "out"
    return run_sweep(grid_spec(), fmu=fmu_path, out=out, serial=True, progress=False, plots=False)


def test_local_cluster_gives_the_serial_results(fmu_path, tmp_path, serial_grid):
    results = run_sweep(grid_spec(), fmu=fmu_path, out=tmp_path / "out", workers=2,
                        batch_size=2, progress=False, plots=False)
    assert results.summary.workers == 2 and results.summary.engine == "LocalCluster"
    assert same_results(results.points, serial_grid.points, METRICS)
    # The points ran on both workers (and the calibration batch in the client).
    assert results.points["worker"].nunique() == 3


@pytest.fixture
def dask_cluster(tmp_path):
    address, processes = start_cluster(tmp_path, environment_for_workers(), ["--nworkers", "1"])
    yield address
    stop_cluster(processes)


def test_a_real_scheduler_and_workers_give_the_serial_results(fmu_path, tmp_path, serial_grid,
                                                              dask_cluster):
    results = run_sweep(grid_spec(), fmu=fmu_path, out=tmp_path / "out", scheduler=dask_cluster,
                        batch_size=2, progress=False, plots=False)
    assert results.summary.workers == 2
    assert same_results(results.points, serial_grid.points, METRICS)
    assert {"worker-w0", "worker-w1"} <= set(results.points["worker"])


def test_every_kind_of_fmu_on_a_real_scheduler_gives_the_serial_results(
        fmu_path, fmu3_path, ball_me_paths, tmp_path, dask_cluster):
    """FMI 3.0 Co-Simulation, and Model Exchange (this FMU's, and a ball's with events),
    on the scheduler's workers as in this process."""
    me = grid_spec()
    me["scenario"]["interface"] = "model_exchange"
    ball = {"scenario": {"stop": 2.0, "step": 0.01},
            "design": {"kind": "grid", "parameters": {"e": {"linspace": [0.4, 0.9, 6]},
                                                      "t_kick": {"values": [0.5, 1.234]}}},
            "outputs": {"metrics": {"h_end": {"variable": "h", "kind": "final"},
                                    "bounces": {"variable": "n_bounces", "kind": "final"}}}}
    for name, spec, fmu, metrics in (("fmi3", grid_spec(), fmu3_path, METRICS),
                                     ("me", me, fmu_path, METRICS[:2]),
                                     ("ball", ball, ball_me_paths["3.0"], ["h_end", "bounces"])):
        serial = run_sweep(spec, fmu=fmu, out=tmp_path / f"{name}-serial", serial=True,
                           progress=False, plots=False)
        remote = run_sweep(spec, fmu=fmu, out=tmp_path / name, scheduler=dask_cluster,
                           batch_size=2, progress=False, plots=False)
        assert same_results(remote.points, serial.points, metrics + ["events"]), name
        assert {"worker-w0", "worker-w1"} <= set(remote.points["worker"]), name
        assert (serial.points["status"] == "ok").sum() >= 6, name


def test_a_crash_on_a_worker_is_one_row(tmp_path):
    fmu = faulty_fmu(tmp_path)
    xs = [float(x) for x in range(1, 31) if x not in (3, 5, 7, 21)]
    spec = {"scenario": {"stop": 1.0, "step": 0.01},
            "design": {"kind": "list", "parameters": {"x": {"values": xs}}},
            "outputs": {"metrics": {"y_final": {"variable": "y", "kind": "final"}}}}
    results = run_sweep(spec, fmu=fmu, out=tmp_path / "out", workers=2, batch_size=4,
                        progress=False, plots=False)
    p = results.points
    assert (p["status"] == "crashed").sum() == 1
    assert p.loc[p["status"] == "crashed", "x"].tolist() == [13.0]
    ok = p[p["status"] == "ok"]
    assert len(ok) == len(xs) - 1 and (ok["y_final"] == ok["x"]).all()


def _trace(path):
    events = {"start": [], "end": []}
    if path.exists():
        for line in path.read_text().splitlines():
            event, first, count = line.split()
            events[event].append((int(first), int(count)))
    return events


def test_resume_after_killing_the_client_half_way(fmu_path, tmp_path, serial_grid):
    spec_path = tmp_path / "big.toml"
    spec_path.write_text("""
[scenario]
stop = 10.0
step = 0.01
tolerance = 1e-8
parameters = { Mm_a0 = 100.0, Mm_a1 = -20.0, Mm_a2 = -1.0, Mr_b0 = 20.0, Mr_b1 = -0.05 }
[design]
kind = "grid"
parameters = { k34 = { linspace = [50.0, 500.0, 60] }, L = { linspace = [0.5, 0.8, 60] } }
[outputs.metrics]
peak_rod_force = { variable = "rod_force", kind = "peak_abs" }
omega1_ripple = { variable = "omega1", kind = "peak_to_peak", from = 1.0 }
n_rhs = { variable = "n_rhs", kind = "final" }
""")
    out, trace = tmp_path / "out", tmp_path / "trace-1"
    command = [sys.executable, "-m", "fmusweep", str(spec_path), "--fmu", str(fmu_path),
               "--out", str(out), "--workers", "2", "--batch-size", "150", "--no-progress",
               "--no-plots"]
    env = dict(environment_for_workers(), FMUSWEEP_TRACE=str(trace))
    client = subprocess.Popen(command, env=env, start_new_session=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    parts = out / "points"
    deadline = time.monotonic() + 120
    # Kill the client (and its LocalCluster) once a third of the 24 batches are saved.
    while time.monotonic() < deadline and len(list(parts.glob("part-*.parquet"))) < 8:
        assert client.poll() is None, "the sweep ended before it could be killed"
        time.sleep(0.005)
    os.killpg(client.pid, signal.SIGKILL)
    client.wait()
    saved = {pq.read_table(p, columns=["point"])["point"][0].as_py()
             for p in parts.glob("part-*.parquet")}
    first = _trace(trace)
    assert 8 <= len(saved) < 24
    lost = {b for b in first["start"] if b[0] not in saved}
    running = {b for b in lost if b not in first["end"]}
    # Lost: the batch each worker was running, and at most one finished batch per worker
    # whose result was still on its way to the client.
    assert len(running) <= 2 and len(lost) <= 4, (lost, running)

    resumed_trace = tmp_path / "trace-2"
    env["FMUSWEEP_TRACE"] = str(resumed_trace)
    finished = subprocess.run(command + ["--resume"], env=env, capture_output=True, text=True)
    assert finished.returncode == 0, finished.stderr
    redone = sum(count for _, count in _trace(resumed_trace)["start"])
    assert redone == 3600 - sum(pq.read_table(p).num_rows for p in parts.glob("part-*.parquet")
                                if pq.read_table(p, columns=["point"])["point"][0].as_py() in saved)
    full = pq.read_table(out / "points.parquet").to_pandas()
    assert list(full["point"]) == list(range(3600))
    serial = run_sweep(spec_path, fmu=fmu_path, out=tmp_path / "serial", serial=True,
                       progress=False, plots=False)
    assert same_results(full, serial.points, METRICS)


def small_grid(points_per_axis):
    """A grid of short runs (1.5 s each): thousands of points in seconds."""
    return grid_spec(stop=1.5, k34={"linspace": [50.0, 400.0, points_per_axis]},
                     L={"linspace": [0.6, 0.7, points_per_axis]})


def test_no_finished_batch_is_held_on_the_cluster(fmu_path, tmp_path, dask_cluster):
    """3600 points in batches of 12 on a real scheduler: when the last batch is saved, the
    scheduler holds no result of any batch (its own task states, not memory readings), so
    nothing of a written batch stays on the workers; every point is there once."""
    results = run_sweep(small_grid(60), fmu=fmu_path, out=tmp_path / "out",
                        scheduler=dask_cluster, batch_size=12, progress=False, plots=False)
    assert results.summary.batches == 301
    assert results.summary.held_results == 0
    points = results.points["point"]
    assert len(points) == 3600 and points.is_unique
    assert (results.points["status"] == "ok").all()
    # And the client keeps no future of the sweep either once it is done.
    from distributed import Client
    with Client(dask_cluster) as client:
        def sweep_tasks(dask_scheduler=None):
            return [str(k) for k in dask_scheduler.tasks if str(k).startswith("fmusweep-")]
        assert client.run_on_scheduler(sweep_tasks) == []


@pytest.fixture
def workers_without_nanny(tmp_path):
    """Workers with no nanny: killing one kills the process that runs the batches, with
    nothing to restart it. Their trace file lists the batches they started."""
    env = dict(environment_for_workers(), FMUSWEEP_TRACE=str(tmp_path / "trace"))
    address, processes = start_cluster(tmp_path, env, ["--no-nanny"])
    yield address, processes[1:], tmp_path / "trace"
    stop_cluster(processes)


def test_a_worker_killed_mid_sweep_costs_nothing(fmu_path, tmp_path, workers_without_nanny):
    """`kill -9` of one worker (and its runner) once a third of the batches have started:
    the other worker runs the rest, and every point is written exactly once, all ok."""
    address, (victim, _), trace = workers_without_nanny
    results = kill_during(
        lambda: run_sweep(small_grid(50), fmu=fmu_path, out=tmp_path / "out", scheduler=address,
                          batch_size=25, progress=False, plots=False),
        victim, lambda: len(_started(trace)) >= 35)
    points = results.points
    assert len(points) == 2500 and points["point"].is_unique
    assert (points["status"] == "ok").all()
    assert set(points["worker"]) - {"worker-w0", "worker-w1"} == {"client"}


def _started(trace):
    if not trace.exists():
        return []
    return [line for line in trace.read_text().splitlines() if line.startswith("start")]
