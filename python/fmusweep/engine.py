"""Running a sweep: check the spec against the FMU, cut the remaining points into
batches of about half a second of work, run them serially or on Dask (a LocalCluster of
single-threaded worker processes, or an existing cluster), and write each finished batch
as it arrives. The batches are placed by ``pool``; their work lives in ``worker``."""

from __future__ import annotations

import hashlib
import math
import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from . import design as design_module
from .check import check_against_fmu
from .fmu import Archive
from .pool import Pool, without_message_log
from .spec import Spec, SpecError
from .ssp import check_ssp, describe_ssp, prepare_ssp_worker, run_ssp_batch
from .system import open_target
from .store import FORMAT, ResultStore, versions
from .worker import prepare_worker, run_batch

__all__ = ["run_sweep", "SweepReport", "BATCH_SECONDS"]

# A batch is sized to about this much work: Dask spends milliseconds per task.
BATCH_SECONDS = 0.5
# And at least this many batches per worker when the sweep is large enough, so that the
# last ones do not leave workers idle.
BATCHES_PER_WORKER = 4
CALIBRATION_POINTS = 4


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
        target, local, description = open_target(spec.system, fmu, spec.fmu, spec.scenario.step)
        if spec.system is not None and fmu is None:
            identity = {"system": {name: str(path) for name, path in spec.system.components.items()},
                        "connections": [str(c) for c in spec.system.connections]}
        else:
            identity = {"fmu_name": target.name, "fmu_guid": description["guid"]}
        check_against_fmu(spec, design, description, local)
        local.configure(plan)
        batch_function, prepare_function = run_batch, prepare_worker
    names, rows = design.names, design.rows
    digest = spec.digest()
    meta = {
        "format": FORMAT, "spec": spec.raw, "spec_digest": digest, "seed": spec.seed,
        "fmu_sha256": target.sha256, **identity,
        "design": {"kind": design.kind, "names": names, "points": len(rows)},
        "metrics": [m.name for m in spec.metrics], "versions": versions(),
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

    size, batches, dispatch_s, held = 0, 0, 0.0, None
    pool = Pool(target, (batch_function, prepare_function), plan, workers=workers,
                scheduler=scheduler, serial=serial, prefix=f"fmusweep-{digest[:8]}-")
    try:
        if len(todo):
            # Calibrate the batch size on the first points, here; they are kept.
            first = todo[:CALIBRATION_POINTS]
            calibration = batch_function(target, plan, names, rows[first], first)
            keep(calibration)
            per_point = float(np.median([r["wall_s"] or 0.0 for r in calibration["results"]]))
            todo = todo[len(first):]
            expected_workers = 1 if serial else (workers or os.cpu_count() or 1)
            size = _batch_size(batch_size, per_point, len(todo), expected_workers)
            chunks = [todo[i:i + size] for i in range(0, len(todo), size)]
            batches = len(chunks) + 1
            with without_message_log(serial), pool:
                t0 = time.perf_counter()
                for batch in pool.stream(names, rows, chunks,
                                         key=lambda chunk: f"{pool.prefix}{int(chunk[0])}"):
                    keep(batch)
                dispatch_s = time.perf_counter() - t0
                held = pool.held_by_scheduler()
    finally:
        bar.close()
    store.consolidate()
    report = SweepReport(
        out=str(store.out), points=len(rows), computed=sum(statuses.values()),
        resumed=len(done), batch_size=size, batches=batches, workers=pool.workers,
        engine=pool.engine,
        wall_s=time.perf_counter() - started, point_seconds=point_seconds, startup_s=pool.startup_s,
        dispatch_s=dispatch_s, statuses=statuses, held_results=held)
    from .results import Results
    results = Results(store.out, None, store.meta, report)
    if plots:
        results.analyse_and_plot(design)
    return results
