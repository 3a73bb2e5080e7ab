"""Running a sweep: check the spec against the FMU, cut the remaining points into
batches of about half a second of work, run them serially or on Dask (a LocalCluster of
single-threaded worker processes, or an existing cluster), and write each finished batch
as it arrives. Scheduling lives here; the work of a batch lives in ``worker``."""

from __future__ import annotations

import hashlib
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from importlib import metadata

import numpy as np
import pyarrow as pa

from . import design as design_module
from .check import check_against_fmu
from .fmu import Archive, local_runner
from .spec import Spec, SpecError
from .ssp import check_ssp, describe_ssp, prepare_ssp_worker, run_ssp_batch
from .store import FORMAT, ResultStore
from .worker import prepare_worker, run_batch

__all__ = ["run_sweep", "SweepReport", "BATCH_SECONDS"]

# A batch is sized to about this much work: Dask spends milliseconds per task.
BATCH_SECONDS = 0.5
# And at least this many batches per worker when the sweep is large enough, so that the
# last ones do not leave workers idle.
BATCHES_PER_WORKER = 4
CALIBRATION_POINTS = 4
# Batches in flight per worker on Dask: one running and the next ones queued, so that no
# worker waits; the rest stay here as indices until a slot frees.
IN_FLIGHT_PER_WORKER = 3


@dataclass
class SweepReport:
    """What a run did: counts, times and where the results are."""
    out: str
    points: int
    computed: int
    resumed: int
    batch_size: int
    batches: int
    workers: int
    engine: str
    wall_s: float
    point_seconds: float  # the sum of the points' own wall times
    startup_s: float = 0.0  # connecting to (or starting) the cluster, shipping the FMU
    dispatch_s: float = 0.0  # from the first task submitted to the last batch saved
    statuses: dict = field(default_factory=dict)
    # Finished batches whose results the Dask scheduler still held in memory when the last
    # batch was saved (its own accounting; 0: nothing of them stays on the workers). None
    # when the sweep ran without Dask.
    held_results: int | None = None


def _versions() -> dict:
    names = ["fmusweep", "numpy", "pyarrow", "dask", "distributed", "SALib", "scipy"]
    found = {"python": platform.python_version()}
    for name in names:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = None
    return found


def point_ids(fmu_sha: str, spec_digest: str, names: list[str], rows: np.ndarray) -> list[str]:
    """A stable id per point: a hash of the FMU, the scenario and the point's values."""
    prefix = f"{fmu_sha}|{spec_digest}|{','.join(names)}|".encode()
    return [hashlib.blake2b(prefix + row.tobytes(), digest_size=8).hexdigest() for row in rows]


def _tables(spec: Spec, names, rows, ids, batch) -> tuple[pa.Table, pa.Table | None]:
    points = np.asarray(batch["points"], dtype=np.int64)
    results = batch["results"]
    columns = {"point": pa.array(points, pa.int64()),
               "point_id": pa.array([ids[p] for p in points], pa.string())}
    for j, name in enumerate(names):
        columns[name] = pa.array(rows[points, j], pa.float64())
    columns["status"] = pa.array([r["status"] for r in results], pa.string())
    columns["message"] = pa.array([r["message"] for r in results], pa.string())
    for k, metric in enumerate(spec.metrics):
        columns[metric.name] = pa.array([r["metrics"][k] for r in results], pa.float64())
    columns["t_end"] = pa.array([r["t_end"] for r in results], pa.float64())
    columns["steps"] = pa.array([r["steps"] for r in results], pa.int64())
    columns["wall_s"] = pa.array([r["wall_s"] for r in results], pa.float64())
    columns["worker"] = pa.array([batch["worker"]] * len(results), pa.string())
    series = None
    if spec.series_variables:
        runs = [(p, r["series"]) for p, r in zip(points, results) if r.get("series") is not None]
        if runs:
            series = _long_form(runs, spec.series_variables)
    return pa.table(columns), series


def _long_form(runs, variables) -> pa.Table:
    """Series rows (t, v1, v2, …) of each point as one long table: point, variable,
    time, value; the variable column dictionary-encoded (one byte a row, not a string)."""
    n_v = len(variables)
    lengths = np.array([len(s) for _, s in runs])
    stacked = np.concatenate([s for _, s in runs])  # (rows, 1 + n_v)
    point = np.repeat(np.array([p for p, _ in runs], dtype=np.int64), lengths)
    which = np.repeat(np.arange(n_v, dtype=np.int8), len(stacked))
    return pa.table({
        "point": pa.array(np.tile(point, n_v)),
        "variable": pa.DictionaryArray.from_arrays(pa.array(which), pa.array(variables)),
        "time": pa.array(np.tile(stacked[:, 0], n_v)),
        "value": pa.array(stacked[:, 1:].T.reshape(-1)),
    })


def _batch_size(requested, per_point_s: float, remaining: int, workers: int) -> int:
    if requested is not None:
        if not isinstance(requested, int) or requested < 1:
            raise SpecError("batch_size", f"must be a whole number ≥ 1, got {requested!r}")
        return requested
    size = max(1, int(BATCH_SECONDS / max(per_point_s, 1e-6)))
    balanced = math.ceil(remaining / (BATCHES_PER_WORKER * max(workers, 1)))
    return max(1, min(size, balanced, 100_000))


class _Progress:
    def __init__(self, total: int, initial: int, enabled: bool):
        self.failures = 0
        self.bar = None
        if enabled:
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=initial, unit="pt", smoothing=0.05,
                            mininterval=0.5, dynamic_ncols=True, file=sys.stderr)

    def update(self, results: list[dict]):
        self.failures += sum(r["status"] != "ok" for r in results)
        if self.bar is not None:
            self.bar.set_postfix(failed=self.failures, refresh=False)
            self.bar.update(len(results))

    def close(self):
        if self.bar is not None:
            self.bar.close()


def run_sweep(spec, *, fmu=None, out=None, workers: int | None = None,
              scheduler: str | None = None, serial: bool = False, resume: bool = False,
              batch_size: int | None = None, progress: bool = True, plots: bool = True,
              on_batch=None):
    """Run a sweep and return its ``Results`` (see ``fmusweep.results``).

    spec: a TOML path, a dict, or a Spec. fmu: the FMU's path, over the spec's own
    (default: the spec's FMU, else its SSP system, else $FMUSWEEP_FMU).
    out: the output directory (default ``sweep-<digest>`` here). workers: LocalCluster
    size (default: every core). scheduler: the address of an existing Dask scheduler
    (``tcp://host:8786``) instead of a LocalCluster. serial: no Dask, this process only.
    resume: finish a sweep that ``out`` already holds, redoing only missing points.
    on_batch: called with (points saved so far, points in the sweep) after each batch.
    """
    started = time.perf_counter()
    spec = Spec.load(spec)
    design = spec.points if spec.points is not None else design_module.generate(spec)
    plan = spec.plan()
    if spec.ssp is not None and fmu is None:
        target = Archive.read(spec.ssp)
        check_ssp(spec, design, describe_ssp(target))
        identity = {"ssp_name": target.name, "ssp_sha256": target.sha256}
        batch_function, prepare_function = run_ssp_batch, prepare_ssp_worker
    else:
        fmu_path = fmu or spec.fmu or os.environ.get("FMUSWEEP_FMU")
        if not fmu_path:
            raise SpecError("fmu", "no FMU: name one in the spec (fmu = \"…\"), pass fmu=, "
                                   "or set FMUSWEEP_FMU")
        target = Archive.read(fmu_path)
        local = local_runner(target)
        description = local.describe()
        check_against_fmu(spec, design, description, local)
        local.configure(plan)
        identity = {"fmu_name": target.name, "fmu_guid": description["guid"]}
        batch_function, prepare_function = run_batch, prepare_worker
    names, rows = design.names, design.rows
    digest = spec.digest()
    meta = {
        "format": FORMAT, "spec": spec.raw, "spec_digest": digest, "seed": spec.seed,
        "fmu_sha256": target.sha256, **identity,
        "design": {"kind": design.kind, "names": names, "points": len(rows)},
        "metrics": [m.name for m in spec.metrics], "versions": _versions(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    out = out or f"sweep-{digest[:10]}"
    store = ResultStore(out, meta, resume)
    ids = point_ids(target.sha256, digest, names, rows)
    done = store.done_points()
    todo = np.setdiff1d(np.arange(len(rows)), done)
    bar = _Progress(len(rows), len(rows) - len(todo), progress)
    point_seconds, statuses, saved = 0.0, {}, len(rows) - len(todo)

    def keep(batch):
        nonlocal point_seconds, saved
        points_table, series_table = _tables(spec, names, rows, ids, batch)
        store.write_batch(points_table, series_table)
        for r in batch["results"]:
            statuses[r["status"]] = statuses.get(r["status"], 0) + 1
            point_seconds += r["wall_s"] or 0.0
        bar.update(batch["results"])
        saved += len(batch["results"])
        if on_batch is not None:
            on_batch(saved, len(rows))

    n_workers = 1 if serial else (workers or os.cpu_count() or 1)
    size, batches, startup_s, dispatch_s, held = 0, 0, 0.0, 0.0, None
    try:
        if len(todo):
            # Calibrate the batch size on the first points, here; they are kept.
            first = todo[:CALIBRATION_POINTS]
            calibration = batch_function(target, plan, names, rows[first], first)
            keep(calibration)
            per_point = float(np.median([r["wall_s"] or 0.0 for r in calibration["results"]]))
            todo = todo[len(first):]
            size = _batch_size(batch_size, per_point, len(todo), n_workers)
            chunks = [todo[i:i + size] for i in range(0, len(todo), size)]
            batches = len(chunks) + 1
            if serial:
                t0 = time.perf_counter()
                for chunk in chunks:
                    keep(batch_function(target, plan, names, rows[chunk], chunk))
                dispatch_s = time.perf_counter() - t0
            else:
                with _without_message_log():
                    n_workers, startup_s, dispatch_s, held = _run_on_dask(
                        target, (batch_function, prepare_function), plan, names, rows, chunks,
                        keep, workers, scheduler, digest)
    finally:
        bar.close()
    table = store.consolidate()
    report = SweepReport(
        out=str(store.out), points=len(rows), computed=sum(statuses.values()),
        resumed=len(done), batch_size=size, batches=batches, workers=n_workers,
        engine="serial" if serial else (scheduler or "LocalCluster"),
        wall_s=time.perf_counter() - started, point_seconds=point_seconds, startup_s=startup_s,
        dispatch_s=dispatch_s, statuses=statuses, held_results=held)
    from .results import Results
    results = Results(store.out, table.to_pandas(), store.meta, report)
    if plots:
        results.analyse_and_plot(design)
    return results


def _without_message_log():
    """Dask keeps the last messages of every connection for debugging (1000 by default),
    and a task's message carries its batch's rows: the sweep's client and, in a
    LocalCluster, the scheduler and workers would grow by each batch up to that many."""
    import dask
    import distributed  # noqa: F401  (its defaults must be in dask's config before the set)
    return dask.config.set({"distributed.admin.low-level-log-length": 0})


def _run_on_dask(target, functions, plan, names, rows, chunks, keep, workers, scheduler, digest):
    """Run the chunks on Dask; returns the workers used, the start-up and dispatch times,
    and how many finished batches the scheduler still held at the end.

    Memory stays flat whatever the number of points: at most IN_FLIGHT_PER_WORKER batches
    per worker are submitted at a time, and each batch's future is released as soon as
    its rows are written, so that neither the workers nor the scheduler keep its result.
    """
    import logging
    from distributed import Client, LocalCluster, as_completed
    from distributed.scheduler import KilledWorker

    cluster = None
    t0 = time.perf_counter()
    if scheduler:
        client = Client(scheduler, timeout="30s")
    else:
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                               processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
        client = Client(cluster)
    pending = {}
    prefix = f"fmusweep-{digest[:8]}-"
    try:
        n_workers = len(client.scheduler_info()["workers"])
        if n_workers == 0:
            client.wait_for_workers(1, timeout=60)
            n_workers = len(client.scheduler_info()["workers"])
        # The FMU travels to every worker once; tasks carry only a reference to it.
        batch_function, prepare_function = functions
        [fmu_future] = client.scatter([target], broadcast=True, hash=False)
        # Each worker unpacks the FMU and starts its runner now, as part of start-up.
        warm = [client.submit(prepare_function, fmu_future, plan, workers=[address], pure=False,
                              key=f"{prefix}warm-{i}")
                for i, address in enumerate(client.scheduler_info()["workers"])]
        client.gather(warm)
        for future in warm:
            future.release()
        t1 = time.perf_counter()
        waiting = iter(chunks)
        finished = as_completed()

        def submit_next():
            chunk = next(waiting, None)
            if chunk is not None:
                future = client.submit(batch_function, fmu_future, plan, names, rows[chunk],
                                       chunk, key=f"{prefix}{int(chunk[0])}", pure=False)
                pending[future] = chunk
                finished.add(future)

        for _ in range(IN_FLIGHT_PER_WORKER * max(n_workers, 1)):
            submit_next()
        for future in finished:
            chunk = pending.pop(future)
            try:
                batch = future.result()
            except KilledWorker as e:  # a worker process lost again and again
                batch = {"points": chunk, "worker": "", "results": [
                    {"status": "crashed", "message": f"the batch failed on the cluster: {e!r}",
                     "metrics": [None] * len(plan["metrics"]), "t_end": None, "steps": None,
                     "wall_s": None} for _ in chunk]}
            future.release()
            del future
            submit_next()
            keep(batch)

        def held_by_scheduler(dask_scheduler=None):
            # Defined here to travel by value: the scheduler need not have this package.
            return sum(1 for key, task in dask_scheduler.tasks.items()
                       if str(key).startswith(prefix) and task.state == "memory")

        # The releases travel on the client's batched stream and the question on another
        # connection: a second to let them arrive. A result held for good stays counted.
        deadline = time.monotonic() + 1.0
        while (held := client.run_on_scheduler(held_by_scheduler)) and time.monotonic() < deadline:
            time.sleep(0.02)
        return n_workers, t1 - t0, time.perf_counter() - t1, held
    finally:
        for future in pending:
            future.cancel()
        client.close()
        if cluster is not None:
            cluster.close()

