"""Shared pieces of the sweep tests: specs, the faulty FMU, comparisons."""

import json
import os
import pathlib
import signal
import subprocess
import sys
import time
import zipfile

import fmpy

HERE = pathlib.Path(__file__).parent
VENV_BIN = pathlib.Path(sys.executable).parent
PAPER_LAWS = dict(Mm_a0=100.0, Mm_a1=-20.0, Mm_a2=-1.0, Mr_b0=20.0, Mr_b1=-0.05)
# Columns that depend only on the points, not on where or when they ran.
RESULT_COLUMNS = ["point", "point_id", "status", "message", "t_end", "steps"]


def grid_spec(stop=2.0, **design_parameters):
    parameters = design_parameters or {"k34": {"linspace": [50.0, 400.0, 4]},
                                       "L": {"values": [0.6, 0.7, 1.2]}}
    return {
        "scenario": {"stop": stop, "step": 0.01, "tolerance": 1e-8, "parameters": dict(PAPER_LAWS)},
        "design": {"kind": "grid", "parameters": parameters},
        "outputs": {"metrics": {
            "peak_rod_force": {"variable": "rod_force", "kind": "peak_abs"},
            "omega1_ripple": {"variable": "omega1", "kind": "peak_to_peak", "from": 1.0},
            "n_rhs": {"variable": "n_rhs", "kind": "final"},
        }},
    }


def same_results(a, b, metrics):
    """Bit for bit: every result column and metric (NaN equal to NaN)."""
    columns = RESULT_COLUMNS + metrics
    return a[columns].reset_index(drop=True).equals(b[columns].reset_index(drop=True))


def faulty_fmu(directory: pathlib.Path) -> pathlib.Path:
    """Compile tests/python/faulty_fmu/faulty.c against FMPy's copy of the FMI 2.0
    headers and pack it as Faulty.fmu."""
    headers = pathlib.Path(fmpy.__file__).parent / "c-code"
    library = directory / "Faulty.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O1", "-o", str(library), "-I", str(headers),
                    str(HERE / "faulty_fmu/faulty.c")], check=True)
    fmu = directory / "Faulty.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.write(HERE / "faulty_fmu/modelDescription.xml", "modelDescription.xml")
        z.write(library, "binaries/linux64/Faulty.so")
    return fmu


def faulty_rotor(directory: pathlib.Path) -> pathlib.Path:
    """Compile tests/python/faulty_fmu/rotor.c, a Model Exchange FMU with a steady cycle
    whose chosen function fails on purpose, and pack it as FaultyRotor.fmu."""
    headers = pathlib.Path(fmpy.__file__).parent / "c-code"
    library = directory / "FaultyRotor.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O1", "-o", str(library), "-I", str(headers),
                    str(HERE / "faulty_fmu/rotor.c"), "-lm"], check=True)
    fmu = directory / "FaultyRotor.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.write(HERE / "faulty_fmu/rotorDescription.xml", "modelDescription.xml")
        z.write(library, "binaries/linux64/FaultyRotor.so")
    return fmu


def stopped_mid_way(spec, fmu, out):
    """A point's steady cycle searched once without a budget, then with a third of the time
    it took: the search stops there, with status timeout, before it would have ended."""
    from fmusweep import run_sweep
    spec = {**spec, "cycle": {**spec["cycle"], "continuation": False}}
    free = run_sweep(spec, fmu=fmu, out=out / "free", serial=True, progress=False,
                     plots=False).points.iloc[0]
    assert free["status"] == "ok", free["message"]
    budget = free["wall_s"] / 3
    spec = {**spec, "scenario": {**spec["scenario"], "timeout": budget}}
    row = run_sweep(spec, fmu=fmu, out=out / "cut", serial=True, progress=False,
                    plots=False).points.iloc[0]
    return free, budget, row


def environment_for_workers():
    """The test's environment for worker processes; the package comes from the wheel
    that `cargo xtask test` installs in the venv."""
    env = dict(os.environ)
    env.pop("FMUSWEEP_RUNNER", None)
    return env


def start_cluster(tmp_path, env, worker_options):
    """`dask scheduler` and two single-threaded `dask worker` processes (w0, w1) on
    127.0.0.1; returns the address and the processes, the scheduler first."""
    scheduler_file = tmp_path / "scheduler.json"
    common = dict(env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                  start_new_session=True)
    processes = [subprocess.Popen(
        [str(VENV_BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0",
         "--no-dashboard", "--scheduler-file", str(scheduler_file)], **common)]
    deadline = time.monotonic() + 60
    while not scheduler_file.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    address = json.loads(scheduler_file.read_text())["address"]
    for i in range(2):
        work = tmp_path / f"worker{i}"
        work.mkdir()
        processes.append(subprocess.Popen(
            [str(VENV_BIN / "dask"), "worker", address, "--nthreads", "1", *worker_options,
             "--no-dashboard", "--name", f"w{i}", "--local-directory", str(work)],
            cwd=work, **common))
    from distributed import Client
    with Client(address) as client:
        client.wait_for_workers(2, timeout=60)
    return address, processes


def stop_cluster(processes):
    """Workers first, while their scheduler is there to release them; then the scheduler."""
    for p in processes[1:] + processes[:1]:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=15)


def kill_during(sweep, victim, ready, timeout=300):
    """Run `sweep()` (which returns results) in a thread, `kill -9` the process group of
    `victim` once `ready()` holds, and return the sweep's results when it ends."""
    import threading
    outcome = {}
    thread = threading.Thread(target=lambda: outcome.update(results=sweep()))
    thread.start()
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not ready():
        assert thread.is_alive(), "the sweep ended before a worker could be killed"
        time.sleep(0.002)
    os.killpg(victim.pid, signal.SIGKILL)
    victim.wait()
    thread.join(timeout=timeout)
    assert not thread.is_alive()
    return outcome["results"]


def repacked(fmu, path, change):
    """A copy of the archive `fmu` at `path`, each file passed through
    `change(name, bytes)` (a None leaves the file out)."""
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(path, "w") as copy:
        for item in source.infolist():
            data = change(item.filename, source.read(item))
            if data is not None:
                copy.writestr(item, data)
    return path


def in_description(old, new):
    """A `change` for `repacked`: `old` replaced by `new` in modelDescription.xml."""
    def change(name, data):
        return data.replace(old, new) if name == "modelDescription.xml" else data
    return change


def fit_command(fmu_path, spec, *options, cwd=None):
    """`python -m fmusweep fit SPEC OPTIONS…` on the FMU under test, as a user runs it."""
    env = dict(environment_for_workers(), FMUSWEEP_FMU=str(fmu_path))
    return subprocess.run([sys.executable, "-m", "fmusweep", "fit", str(spec), *map(str, options)],
                          env=env, capture_output=True, text=True, cwd=cwd)


def lose_the_later_parts(out):
    """Delete the later half of a study's Parquet parts and their series, as a kill leaves
    them (with the final table and fit.json not yet written); the rows lost."""
    import pandas as pd
    for name in ("fit.json", "points.parquet"):
        (out / name).unlink(missing_ok=True)
    parts = sorted((out / "points").glob("part-*.parquet"))
    lost = 0
    for part in parts[len(parts) // 2:]:
        lost += len(pd.read_parquet(part))
        part.unlink()
        (out / "series" / part.name).unlink(missing_ok=True)
    return lost
