"""A sweep: a design's points streamed through a study (``study``): the spec checked
against what runs, the remaining points cut into batches of about half a second of work,
run serially or on Dask, and each finished batch written as it arrives. The batches are
placed by ``pool``; their work lives in ``worker``."""

from __future__ import annotations

import math
import os
import pathlib
import shutil
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pyarrow as pa

from .designs import Design
from .errors import SpecError, SpecWarning, refuse_in_spawned_child
from .pool import check_engine
from .indices import write_indices
from .records import Batch, PointResult, Points, Rows
from .results import Results, SweepSummary
from .spec import Spec
from .store import coupling_columns
from .cycle import CHAIN_POINTS, cycle_columns
from .show import show_sweep
from .study import Study, Target, checked_sweep, spec_name


__all__ = ["run_sweep", "SweepSummary", "BATCH_SECONDS"]

# A batch is sized to about this much work: Dask spends milliseconds per task.
BATCH_SECONDS = 0.5
# And at least this many batches per worker when the sweep is large enough, so that the
# last ones do not leave workers idle.
BATCHES_PER_WORKER = 4
CALIBRATION_POINTS = 4
# Without an engine named, the points left run where they take less time, from the work
# the calibration points measure: a LocalCluster costs its start-up (its workers started
# and prepared, seconds) and shares the work among its workers at this efficiency (the
# client, the scheduler and the workers share the cores); bench-engine's report measures
# both against each worked sweep.
CLUSTER_START_S = 1.6
CLUSTER_EFFICIENCY = 0.7
# What a sweep writes, for the disk check: a series value in Parquet (its time, point and
# variable compress to about 2 bytes beside its 8; bench-sweep's report measures it), and a
# point's row of points.parquet at most.
SERIES_BYTES_PER_VALUE = 10
POINT_ROW_BYTES = 200
SAY_ABOVE_BYTES = 1e9


def _whole_numbered(description: dict[str, Any], names: list[str]) -> set[str]:
    """The design's columns that set Integer or Enumeration variables: written as integers."""
    types = {v["name"]: v.get("type") for v in description.get("variables", [])}
    return {n for n in names if types.get(n) in ("integer", "enumeration")}


def _tables(spec: Spec, study: Study, names: list[str], rows: Rows, batch: Batch,
            whole: set[str]) -> tuple[pa.Table, pa.Table | None]:
    """A batch's rows of points.parquet and of the series, `rows` its points' values (the
    columns in `whole` as integers)."""
    points = np.asarray(batch["points"], dtype=np.int64)
    results = batch["results"]
    columns = {"point": pa.array(points, pa.int64()),
               "point_id": pa.array(study.ids(names, rows), pa.string())}
    for j, name in enumerate(names):
        columns[name] = (pa.array(rows[:, j].astype(np.int64), pa.int64()) if name in whole
                         else pa.array(rows[:, j], pa.float64()))
    columns["status"] = pa.array([r["status"] for r in results], pa.string())
    columns["message"] = pa.array([r["message"] for r in results], pa.string())
    for k, metric in enumerate(spec.metrics):
        columns[metric.name] = pa.array([r["metrics"][k] for r in results], pa.float64())
    columns["t_end"] = pa.array([r["t_end"] for r in results], pa.float64())
    columns["steps"] = pa.array([r["steps"] for r in results], pa.int64())
    columns["events"] = pa.array([r.get("events") for r in results], pa.int64())
    columns["wall_s"] = pa.array([r["wall_s"] for r in results], pa.float64())
    columns["worker"] = pa.array([batch["worker"]] * len(results), pa.string())
    if spec.system is not None and spec.system.coupling_tolerance is not None:
        columns.update(coupling_columns(results))
    if spec.cycle is not None:
        columns.update(cycle_columns(results))
    series = None
    if spec.series_variables:
        runs = [(int(p), r["series"]) for p, r in zip(points, results) if "series" in r]
        if runs:
            series = _long_form(runs, spec.series_variables)
    return pa.table(columns), series


def _long_form(runs: list[tuple[int, Rows]], variables: list[str]) -> pa.Table:
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


def _batch_size(requested: int | None, per_point_s: float, remaining: int, workers: int) -> int:
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
        self.bar: Any = None
        if enabled:
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=initial, unit="pt", smoothing=0.05,
                            mininterval=0.5, dynamic_ncols=True, file=sys.stderr)

    def update(self, results: list[PointResult]) -> None:
        self.failures += sum(r["status"] != "ok" for r in results)
        if self.bar is not None:
            self.bar.set_postfix(failed=self.failures, refresh=False)
            self.bar.update(len(results))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _chunks(todo: Points, first: int, size: int) -> Iterator[Points]:
    """The points from todo[first:] in chunks of `size`, made one at a time."""
    for i in range(first, len(todo), size):
        yield todo[i:i + size]


def _chains(spec: Spec, design: Design, todo: Points) -> list[Points] | None:
    """The chains of a sweep of steady cycles continued from neighbours, which a batch
    holds whole (None for any other sweep)."""
    if spec.cycle is None or not spec.cycle.continued:
        return None
    return design.chains(todo, CHAIN_POINTS)


def _whole_chains(chains: list[Points], size: int) -> Iterator[Points]:
    """Consecutive chains joined into chunks of about `size` points, none cut."""
    chunk: list[Points] = []
    for chain in chains:
        chunk.append(chain)
        if sum(len(c) for c in chunk) >= size:
            yield np.concatenate(chunk)
            chunk = []
    if chunk:
        yield np.concatenate(chunk)


def _remaining(total: int, done: Points) -> Points:
    """The points no part holds, in order."""
    if not len(done):
        return np.arange(total, dtype=np.int64)
    missing = np.ones(total, dtype=bool)
    missing[done] = False
    return np.flatnonzero(missing).astype(np.int64)


class _Keeper:
    """Writes each finished batch and counts what the sweep did."""

    def __init__(self, spec: Spec, study: Study, design: Design, saved: int,
                 progress: bool, on_batch: Callable[[int, int], None] | None):
        self.spec, self.study, self.design = spec, study, design
        self.saved, self.on_batch = saved, on_batch
        self.point_seconds = 0.0
        self.statuses: dict[str, int] = {}
        self.bar = _Progress(len(design), saved, progress)
        self.whole = _whole_numbered(study.target.description, design.names)

    def __call__(self, batch: Batch) -> None:
        rows = self.design.rows_at(batch["points"])
        points_table, series_table = _tables(self.spec, self.study, self.design.names, rows,
                                             batch, self.whole)
        self.study.store.write_batch(points_table, series_table)
        for r in batch["results"]:
            self.statuses[r["status"]] = self.statuses.get(r["status"], 0) + 1
            self.point_seconds += r["wall_s"] or 0.0
        self.bar.update(batch["results"])
        self.saved += len(batch["results"])
        if self.on_batch is not None:
            self.on_batch(self.saved, len(self.design))


def run_sweep(spec: Spec | str | pathlib.Path | dict[str, Any], *, fmu: str | None = None,
              out: str | None = None, workers: int | None = None, scheduler: str | None = None,
              serial: bool = False, resume: bool = False, batch_size: int | None = None,
              progress: bool = True, plots: bool = True,
              on_batch: Callable[[int, int], None] | None = None) -> Results:
    """Run a sweep and return its ``Results`` (see ``fmusweep.results``).

    spec: a TOML path, a dict, or a Spec. fmu: the FMU's path, over the spec's own
    (default: the spec's FMU, else its SSP system, else $FMUSWEEP_FMU).
    out: the output directory (default: a new ``results/NAME-DATE-TIME`` here, NAME the
    spec file's stem; with resume, the newest such folder of the same spec). workers: LocalCluster
    size (default: every core, or serial where the points left would take less time
    here than on a LocalCluster, its start-up included: ``_choose_engine``).
    scheduler: the address of an existing Dask scheduler (``tcp://host:8786``) instead of
    a LocalCluster. serial: no Dask, this process only.
    resume: finish a sweep that ``out`` already holds, redoing only missing points.
    on_batch: called with (points saved so far, points in the sweep) after each batch.
    """
    started = time.perf_counter()
    refuse_in_spawned_child("run_sweep")
    check_engine(workers, scheduler, serial)
    if batch_size is not None:
        _batch_size(batch_size, 0.0, 1, 1)
    given = spec
    spec, target = checked_sweep(given, fmu)
    for said in spec.scenario.off_grid_breakpoints(spec.system):
        warnings.warn(said, SpecWarning, stacklevel=2)
    design = spec.points
    if target.local is not None:
        target.local.configure(spec.plan(target.description))
    record = {"design": {"kind": design.kind, "names": design.names, "points": len(design)},
              "metrics": [m.name for m in spec.metrics]}
    study = Study("sweep", spec, target, spec.plan(target.description), out=out, resume=resume, record=record,
                  workers=workers, scheduler=scheduler, serial=serial,
                  name=spec_name(given, "sweep"))
    try:
        return _run(spec, study, target, started, batch_size=batch_size, progress=progress,
                    plots=plots, on_batch=on_batch)
    except BaseException:
        study.abandon()
        raise


def _run(spec: Spec, study: Study, target: Target, started: float, *, batch_size: int | None,
         progress: bool, plots: bool, on_batch: Callable[[int, int], None] | None) -> Results:
    """The sweep's points through the study's pool, after the checks."""
    design = spec.points
    done = study.store.done_points()
    todo = _remaining(len(design), done)
    check_disk(spec, len(todo), study.store.out)
    keep = _Keeper(spec, study, design, len(design) - len(todo), progress, on_batch)
    names = design.names
    size, batches, dispatch_s, held, note = 0, 0, 0.0, None, "nothing left to run"
    try:
        if len(todo):
            chains = _chains(spec, design, todo)
            # Calibrate the batch size and the engine on the first points, here; they are
            # kept.
            first = todo[:CALIBRATION_POINTS] if chains is None else chains[0]
            calibration = target.run_batch(target.archive, study.plan, names,
                                           design.rows_at(first), first)
            keep(calibration)
            per_point = float(np.median([r["wall_s"] or 0.0 for r in calibration["results"]]))
            note = _choose_engine(study, per_point, len(todo) - len(first))
            expected_workers = 1 if study.pool.serial else (
                study.pool.requested_workers or os.cpu_count() or 1)
            size = _batch_size(batch_size, per_point, len(todo) - len(first), expected_workers)
            chunks = (_chunks(todo, len(first), size) if chains is None
                      else _whole_chains(chains[1:], size))
            batches = math.ceil((len(todo) - len(first)) / size) + 1
            with study.running() as pool:
                t0 = time.perf_counter()
                for batch in pool.stream(names, design.rows_at, chunks,
                                         key=lambda chunk: f"{pool.prefix}{int(chunk[0])}"):
                    keep(batch)
                dispatch_s = time.perf_counter() - t0
                held = pool.held_by_scheduler()
    finally:
        keep.bar.close()
    study.finish()
    summary = SweepSummary(
        out=str(study.store.out), points=len(design), computed=sum(keep.statuses.values()),
        resumed=len(done), batch_size=size, batches=batches, workers=study.pool.workers,
        engine=study.pool.engine, wall_s=time.perf_counter() - started,
        point_seconds=keep.point_seconds, startup_s=study.pool.startup_s,
        dispatch_s=dispatch_s, statuses=keep.statuses, held_results=held, engine_choice=note)
    results = Results(study.store.out, None, study.store.meta, summary)
    meta = study.store.meta
    results.sensitivity = write_indices(design, lambda: results.points, meta["metrics"],
                                        meta.get("seed") or 0, results.out)
    if plots:
        cyclic = [spec.cycle.state, *spec.cycle.shifted] if spec.cycle is not None else []
        kept = spec.cycle.keep if spec.cycle is not None else []
        results.plots, results.report_html = show_sweep(results.out, design, results.points,
                                                        meta["metrics"], results.sensitivity,
                                                        cyclic, kept)
    return results


def series_samples(spec: Spec) -> int:
    """How many samples of each recorded variable a point's series holds."""
    if not spec.series_variables:
        return 0
    return spec.scenario.steps // max(spec.series_every, 1) + 1


def written_bytes(spec: Spec, points: int) -> tuple[int, int]:
    """About how many bytes `points` points of the sweep write, and how many series values
    that is (each point's samples of each recorded variable)."""
    values = points * series_samples(spec) * len(spec.series_variables)
    return values * SERIES_BYTES_PER_VALUE + points * POINT_ROW_BYTES, values


def check_disk(spec: Spec, points: int, out: pathlib.Path) -> None:
    """A sweep that would write more than the disk holding `out` has free is refused
    before it starts; one that writes more than SAY_ABOVE_BYTES says so first."""
    need, _ = written_bytes(spec, points)
    if need <= SAY_ABOVE_BYTES:
        return
    where = out.resolve()
    while not where.exists():
        where = where.parent
    free = shutil.disk_usage(where).free
    said = (f"about {need / 1e9:.3g} GB ({points} points × {series_samples(spec)} samples × "
            f"{len(spec.series_variables)} variables of series)")
    if need > free:
        raise SpecError("outputs.series", f"the sweep would write {said} to {where}, which has "
                                          f"{free / 1e9:.3g} GB free: record fewer variables, "
                                          "give a longer interval, or sweep fewer points")
    warnings.warn(f"the sweep will write {said} to {out} ({free / 1e9:.3g} GB free)",
                  SpecWarning, stacklevel=3)


def _choose_engine(study: Study, per_point: float, remaining: int) -> str:
    """Serial when the caller named no engine and the points left would take less time
    here than on a LocalCluster, its start-up included; why, in words."""
    pool = study.pool
    if pool.named:
        return "as asked"
    work = per_point * remaining
    workers = os.cpu_count() or 1
    on_cluster = CLUSTER_START_S + work / (workers * CLUSTER_EFFICIENCY)
    if on_cluster >= work:
        pool.serial = True
        return (f"serial: the {remaining} points left take about {work:.2g} s here, a "
                f"LocalCluster of {workers} workers about {on_cluster:.2g} s with its "
                "start-up (name --workers or --scheduler to use one)")
    return (f"a LocalCluster of {workers} workers: the {remaining} points left take about "
            f"{work:.2g} s serially, about {on_cluster:.2g} s there with its start-up")
