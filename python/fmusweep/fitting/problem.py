"""The fit's model evaluations: parameter vectors in, weighted residuals out, run as
batches on the sweep's pool, and every evaluated point written in the sweep's Parquet
format (points and, in long form, the model's values at the data times). A point that an
earlier, interrupted fit already evaluated is read back instead of run again, so that
resuming replays the same deterministic path at no cost up to where it stopped."""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from ..check import VALUE_TYPES, Variables, ask_the_fmu
from ..errors import Collector
from ..native import NativeRunner
from ..records import PointResult, Points, Rows
from ..store import ResultStore, coupling_columns
from .data import Data

if TYPE_CHECKING:
    from ..study import Study
    from .spec import FitSpec

__all__ = ["Problem", "Evaluation", "check_fit_against_fmu"]

READABLE = ("output", "local")


@dataclass
class Evaluation:
    status: str
    message: str
    predictions: Rows | None  # (data times, columns) when the run reached the end

    @property
    def ok(self) -> bool:
        return self.status == "ok" and self.predictions is not None


def check_fit_against_fmu(spec: FitSpec, description: dict[str, Any],
                          runner: NativeRunner) -> None:
    """Every name against the FMU, every mistake reported at once; then the values."""
    variables = Variables(description)
    errors = Collector()
    variables.check_scenario(spec.scenario, errors)
    for name in spec.data.columns:
        errors.run(lambda: variables.get(name, "data.file", READABLE, VALUE_TYPES, what="output"))
    names = spec.names
    rows = np.array([[p.start for p in spec.fitted], spec.lows, spec.highs])
    columns = list(rows.T)
    errors.run(lambda: variables.check_columns(names, columns, "fit.parameters"))
    errors.raise_any()
    ask_the_fmu(spec.plan(), names, rows[:1], columns, runner, "fit.parameters",
                "scenario.parameters")


class Problem:
    """Residuals of parameter vectors, for any number of optimisations at once (each
    evaluates from its own thread; the pool places the batches)."""

    def __init__(self, spec: FitSpec, study: Study):
        self.spec = spec
        self.study = study
        self.pool = study.pool
        self.store = study.store
        self.lock = threading.Lock()
        self.cache: dict[str, Evaluation] = _stored_evaluations(self.store, spec)
        self.next_point = _next_point(self.store)
        self.computed = 0
        self.reused = 0

    def residuals(self, evaluation: Evaluation) -> Rows:
        """Weighted residuals (model − data) / sigma, row by row; +inf for a failed run,
        which a trust-region step treats as infinitely bad."""
        data = self.spec.data
        if evaluation.predictions is None or not evaluation.ok:
            return np.full(data.values.size, np.inf)
        weighted: Rows = ((evaluation.predictions - data.values) / data.sigma).ravel()
        return weighted

    def cached(self, theta: Rows) -> Evaluation | None:
        """The evaluation of a point already run (or read back), without running it."""
        [key] = self.study.ids(self.spec.names, np.atleast_2d(theta))
        with self.lock:
            return self.cache.get(key)

    def evaluate(self, thetas: Rows, start: int, roles: list[str]) -> list[Evaluation]:
        thetas = np.atleast_2d(np.asarray(thetas, dtype=float))
        ids = self.study.ids(self.spec.names, thetas)
        with self.lock:
            found: list[Evaluation | None] = [self.cache.get(i) for i in ids]
        missing = [k for k, e in enumerate(found) if e is None]
        if missing:
            results = self.pool.run(self.spec.names, thetas[missing])
            fresh = [self._evaluation(r) for r in results]
            with self.lock:
                self.computed += len(missing)
                points = np.arange(self.next_point, self.next_point + len(missing))
                self.next_point += len(missing)
                for k, e in zip(missing, fresh):
                    self.cache[ids[k]] = e
                    found[k] = e
            self._write(points, [ids[k] for k in missing], thetas[missing], results, fresh,
                        start, [roles[k] for k in missing])
        with self.lock:
            self.reused += len(thetas) - len(missing)
        return [e for e in found if e is not None]

    def _evaluation(self, result: PointResult) -> Evaluation:
        series = result.get("series")
        rows = self.spec.data.rows
        if result["status"] != "ok" or series is None or len(series) <= rows[-1]:
            return Evaluation(result["status"] if result["status"] != "ok" else "error",
                              result["message"] or "the run ended before the last data time", None)
        return Evaluation("ok", result["message"], np.array(series[rows, 1:]))

    def _write(self, points: Points, ids: list[str], thetas: Rows, results: list[PointResult],
               evaluations: list[Evaluation], start: int, roles: list[str]) -> None:
        spec = self.spec
        columns = {"point": pa.array(points, pa.int64()), "point_id": pa.array(ids, pa.string())}
        for j, name in enumerate(spec.names):
            columns[name] = pa.array(thetas[:, j], pa.float64())
        columns["status"] = pa.array([e.status for e in evaluations], pa.string())
        columns["message"] = pa.array([e.message for e in evaluations], pa.string())
        costs = [0.5 * float(np.sum(self.residuals(e) ** 2)) if e.ok else None for e in evaluations]
        columns["cost"] = pa.array(costs, pa.float64())
        columns["start"] = pa.array([start] * len(points), pa.int64())
        columns["role"] = pa.array(roles, pa.string())
        for key, kind in (("t_end", pa.float64()), ("steps", pa.int64()), ("wall_s", pa.float64()),
                          ("worker", pa.string())):
            columns[key] = pa.array([r.get(key) for r in results], kind)
        if spec.system is not None and spec.system.coupling_tolerance is not None:
            columns.update(coupling_columns(results))
        long = [(int(p), e.predictions) for p, e in zip(points, evaluations)
                if e.ok and e.predictions is not None]
        self.store.write_batch(pa.table(columns), _long_form(long, spec.data) if long else None)


def _long_form(runs: list[tuple[int, Rows]], data: Data) -> pa.Table:
    n_t, n_c = data.values.shape
    point = np.repeat(np.array([p for p, _ in runs], dtype=np.int64), n_t * n_c)
    variable = np.tile(np.repeat(np.arange(n_c, dtype=np.int8), n_t), len(runs))
    time_ = np.tile(np.tile(data.times, n_c), len(runs))
    value = np.concatenate([pred.T.ravel() for _, pred in runs])
    return pa.table({"point": pa.array(point),
                     "variable": pa.DictionaryArray.from_arrays(pa.array(variable), pa.array(data.columns)),
                     "time": pa.array(time_), "value": pa.array(value)})


def _stored_evaluations(store: ResultStore, spec: FitSpec) -> dict[str, Evaluation]:
    """The points an earlier run of this fit wrote (none for a new fit)."""
    try:
        points = ResultStore.points_table_of(store.out).to_pandas()
    except FileNotFoundError:
        return {}
    series = ResultStore.series_table_of(store.out)
    by_point: dict[int, Rows] = {}
    if series is not None:
        frame = series.to_pandas()
        n_t = len(spec.data.times)
        for point, group in frame.groupby("point"):
            values = np.empty((n_t, len(spec.data.columns)))
            for j, name in enumerate(spec.data.columns):
                values[:, j] = group[group["variable"] == name].sort_values("time")["value"].to_numpy()
            by_point[int(point)] = values
    cache: dict[str, Evaluation] = {}
    for row in points.itertuples(index=False):
        predictions = by_point.get(row.point)
        if row.status == "ok" and predictions is None:
            continue  # its series part was lost: run it again
        cache[row.point_id] = Evaluation(row.status, row.message, predictions)
    return cache


def _next_point(store: ResultStore) -> int:
    done = store.done_points()
    return int(done.max()) + 1 if len(done) else 0

