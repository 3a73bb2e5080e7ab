"""The fit's model evaluations: parameter vectors in, weighted residuals out, run as
batches on the sweep's pool, and every run written in the sweep's Parquet format (a row
per experiment's run in the points, and in long form the model's values at its data
times). A vector's evaluation is one run per experiment; a run that another vector
already made (an experiment whose parameters a perturbation did not touch) is not made
again, and a run that an earlier, interrupted fit made is read back, so that resuming
replays the same deterministic path at no cost up to where it stopped."""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from ..records import PointResult, Points, Rows
from ..store import ResultStore, coupling_columns
from .data import Data
from ..sensitivity_slots import read_offer, slot_parameter, slot_variable
from .spec import SINGLE_EXPERIMENT

if TYPE_CHECKING:
    from ..pool import Task
    from ..study import Study
    from .spec import Experiment, FitSpec

__all__ = ["Problem", "Evaluation", "Trial"]


@dataclass
class Evaluation:
    """One experiment's run."""
    status: str
    message: str
    predictions: Rows | None  # (data times, columns) when the run reached the end

    @property
    def ok(self) -> bool:
        return self.status == "ok" and self.predictions is not None


@dataclass
class Trial:
    """A parameter vector's evaluation: one run per experiment, in the spec's order."""
    runs: list[Evaluation]
    experiments: list[str]

    @property
    def ok(self) -> bool:
        return all(r.ok for r in self.runs)

    @property
    def message(self) -> str:
        """The first failed run's message (naming its experiment where there are several)."""
        for name, run in zip(self.experiments, self.runs):
            if not run.ok:
                return run.message if len(self.runs) == 1 else f"experiment {name}: {run.message}"
        return ""


class Problem:
    """Residuals of parameter vectors, for any number of optimisations at once (each
    evaluates from its own thread; the pool places the batches)."""

    def __init__(self, spec: FitSpec, study: Study):
        self.spec = spec
        self.study = study
        self.pool = study.pool
        self.store = study.store
        self.plans = [e.plan(spec.system) for e in spec.experiments]
        self.lock = threading.Lock()
        self.cache: dict[str, Evaluation] = _stored_evaluations(self.store, spec)
        self.next_point = _next_point(self.store)
        self.computed = 0
        self.reused = 0
        # Per experiment, the fitted parameters (places in the vector) whose sensitivities
        # the FMU computes in its run, and the slot value that selects each.
        offer = (read_offer(study.target.description)
                 if spec.jacobian == "sensitivities" and spec.system is None else None)
        self.sensitive: list[list[tuple[int, int]]] = []
        for e in spec.experiments:
            chosen = []
            if offer is not None and all(offer.covers(c) for c in e.data.columns):
                chosen = [(j, offer.items[v]) for j, v in zip(e.columns, e.variables)
                          if v in offer.items][:offer.slots]
            self.sensitive.append(chosen)

    def with_sensitivities(self, free: list[int]) -> list[int]:
        """The parameters of `free` whose Jacobian columns the FMU's sensitivities give:
        every experiment that runs with one computes it."""
        running = [(e.columns, {i for i, _ in mine})
                   for e, mine in zip(self.spec.experiments, self.sensitive)]
        return [j for j in free
                if any(j in columns for columns, _ in running)
                and all(j in followed for columns, followed in running if j in columns)]

    def evaluate_with_sensitivities(self, theta: Rows, start: int, role: str
                                    ) -> tuple[Trial, dict[int, Rows]]:
        """`theta`'s evaluation, and for each parameter of ``with_sensitivities`` its
        column of the weighted residuals' Jacobian, from one run per experiment that
        computes sensitivities (a run another evaluation made is kept, not written twice).
        A failed sensitivity run gives no column; the caller differences instead."""
        spec = self.spec
        order = [k for k, mine in enumerate(self.sensitive) if mine]
        tasks: list[Task] = []
        for k in order:
            e, mine = spec.experiments[k], self.sensitive[k]
            slots = [slot_parameter(s + 1) for s in range(len(mine))]
            extra = [slot_variable(s + 1, c) for s in range(len(mine)) for c in e.data.columns]
            row = np.concatenate([theta[e.columns], [float(v) for _, v in mine]])
            tasks.append((e.plan(spec.system, extra), e.variables + slots, row[None, :]))
        answers = self.pool.run_each(tasks) if tasks else []
        sensitivities: dict[int, dict[int, Rows]] = {}
        keys = self._keys(np.atleast_2d(theta))[0]
        for k, results in zip(order, answers):
            e, result = spec.experiments[k], results[0]
            evaluation = _evaluation(e, result)
            if not evaluation.ok:
                return Trial([evaluation], [e.name]), {}
            with self.lock:
                fresh = keys[k] not in self.cache
                if fresh:
                    self.cache[keys[k]] = evaluation
                    self.computed += 1
                    point = self.next_point
                    self.next_point += 1
            if fresh:
                self._write(e, np.array([point]), [keys[k]], np.atleast_2d(theta),
                            [result], [evaluation], start, [role])
            n_c = len(e.data.columns)
            series = np.asarray(result["series"])[e.data.rows, 1 + n_c:]
            sensitivities[k] = {j: series[:, s * n_c:(s + 1) * n_c] / e.data.sigma
                                for s, (j, _) in enumerate(self.sensitive[k])}
        trial = self.evaluate(np.atleast_2d(theta), start, [role])[0]
        if not trial.ok:
            return trial, {}
        columns: dict[int, Rows] = {}
        for j in self.with_sensitivities(list(range(len(theta)))):
            parts = [sensitivities[k][j].ravel() if j in e.columns
                     else np.zeros(e.data.values.size)
                     for k, e in enumerate(spec.experiments)]
            columns[j] = np.concatenate(parts)
        return trial, columns

    def residuals(self, trial: Trial) -> Rows:
        """Weighted residuals (model − data) / sigma, experiment by experiment and row by
        row; +inf for a failed run, which a trust-region step treats as infinitely bad."""
        parts = [_weighted(e.data, run) for e, run in zip(self.spec.experiments, trial.runs)]
        if not trial.ok:
            return np.full(sum(len(p) for p in parts), np.inf)
        return np.concatenate(parts)

    def cost(self, trial: Trial) -> float:
        return 0.5 * float(np.sum(self.residuals(trial) ** 2)) if trial.ok else float("inf")

    def cached(self, theta: Rows) -> Trial | None:
        """The evaluation of a vector already run (or read back), without running it."""
        keys = self._keys(np.atleast_2d(theta))[0]
        with self.lock:
            runs = [self.cache.get(k) for k in keys]
        if any(r is None for r in runs):
            return None
        return Trial([r for r in runs if r is not None], [e.name for e in self.spec.experiments])

    def _keys(self, thetas: Rows) -> list[list[str]]:
        """Each vector's run ids, one per experiment: a hash of the experiment and the
        values it runs with."""
        per_experiment = []
        for e in self.spec.experiments:
            names = e.variables if e.name == SINGLE_EXPERIMENT else [f"{e.name}/{v}" for v in e.variables]
            per_experiment.append(self.study.ids(names, thetas[:, e.columns]))
        return [list(keys) for keys in zip(*per_experiment)]

    def evaluate(self, thetas: Rows, start: int, roles: list[str]) -> list[Trial]:
        thetas = np.atleast_2d(np.asarray(thetas, dtype=float))
        experiments = self.spec.experiments
        keys = self._keys(thetas)
        # The runs to make: each (experiment, id) once, from the first vector that needs it.
        missing: dict[tuple[int, str], int] = {}
        with self.lock:
            for i, row in enumerate(keys):
                for k, key in enumerate(row):
                    if key not in self.cache and (k, key) not in missing:
                        missing[(k, key)] = i
        if missing:
            self._run(thetas, missing, start, roles)
        with self.lock:
            self.reused += sum(len(row) for row in keys) - len(missing)
            return [Trial([self.cache[key] for key in row], [e.name for e in experiments])
                    for row in keys]

    def _run(self, thetas: Rows, missing: dict[tuple[int, str], int], start: int,
             roles: list[str]) -> None:
        """Make the missing runs, every experiment's at once, and keep them."""
        spec = self.spec
        by_experiment: dict[int, list[tuple[str, int]]] = {}
        for (k, key), i in missing.items():
            by_experiment.setdefault(k, []).append((key, i))
        order = sorted(by_experiment)
        tasks: list[Task] = [(self.plans[k], spec.experiments[k].variables,
                              thetas[[i for _, i in by_experiment[k]]][:, spec.experiments[k].columns])
                             for k in order]
        answers = self.pool.run_each(tasks)
        for k, results in zip(order, answers):
            e = spec.experiments[k]
            made = by_experiment[k]
            fresh = [_evaluation(e, r) for r in results]
            with self.lock:
                self.computed += len(made)
                points = np.arange(self.next_point, self.next_point + len(made))
                self.next_point += len(made)
                for (key, _), evaluation in zip(made, fresh):
                    self.cache[key] = evaluation
            self._write(e, points, [key for key, _ in made], thetas[[i for _, i in made]],
                        results, fresh, start, [roles[i] for _, i in made])

    def _write(self, experiment: Experiment, points: Points, ids: list[str], thetas: Rows,
               results: list[PointResult], evaluations: list[Evaluation], start: int,
               roles: list[str]) -> None:
        spec = self.spec
        columns = {"point": pa.array(points, pa.int64()), "point_id": pa.array(ids, pa.string()),
                   "experiment": pa.array([experiment.name] * len(points), pa.string())}
        for j, name in enumerate(spec.names):
            # Another experiment's own parameter does not take part in this run: null.
            values = thetas[:, j] if j in experiment.columns else [None] * len(points)
            columns[name] = pa.array(values, pa.float64())
        columns["status"] = pa.array([e.status for e in evaluations], pa.string())
        columns["message"] = pa.array([e.message for e in evaluations], pa.string())
        costs = [0.5 * float(np.sum(_weighted(experiment.data, e) ** 2)) if e.ok else None
                 for e in evaluations]
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
        self.store.write_batch(pa.table(columns),
                               _long_form(long, experiment.data, spec.measured_columns)
                               if long else None)


def _weighted(data: Data, run: Evaluation) -> Rows:
    if run.predictions is None or not run.ok:
        return np.full(data.values.size, np.inf)
    weighted: Rows = ((run.predictions - data.values) / data.sigma).ravel()
    return weighted


def _evaluation(experiment: Experiment, result: PointResult) -> Evaluation:
    series = result.get("series")
    rows = experiment.data.rows
    if result["status"] != "ok" or series is None or len(series) <= rows[-1]:
        return Evaluation(result["status"] if result["status"] != "ok" else "error",
                          result["message"] or "the run ended before the last data time", None)
    n_c = len(experiment.data.columns)
    return Evaluation("ok", result["message"], np.array(series[rows, 1:1 + n_c]))


def _long_form(runs: list[tuple[int, Rows]], data: Data, measured: list[str]) -> pa.Table:
    """The runs' values at the data times; the variables coded over every experiment's
    measured columns, so that all parts of the store share one dictionary."""
    n_t, n_c = data.values.shape
    codes = np.array([measured.index(c) for c in data.columns], dtype=np.int8)
    point = np.repeat(np.array([p for p, _ in runs], dtype=np.int64), n_t * n_c)
    variable = np.tile(np.repeat(codes, n_t), len(runs))
    time_ = np.tile(np.tile(data.times, n_c), len(runs))
    value = np.concatenate([pred.T.ravel() for _, pred in runs])
    return pa.table({"point": pa.array(point),
                     "variable": pa.DictionaryArray.from_arrays(pa.array(variable), pa.array(measured)),
                     "time": pa.array(time_), "value": pa.array(value)})


def _stored_evaluations(store: ResultStore, spec: FitSpec) -> dict[str, Evaluation]:
    """The runs an earlier run of this fit wrote (none for a new fit)."""
    try:
        points = ResultStore.points_table_of(store.out).to_pandas()
    except FileNotFoundError:
        return {}
    series = ResultStore.series_table_of(store.out)
    frames = dict(iter(series.to_pandas().groupby("point"))) if series is not None else {}
    experiments = {e.name: e for e in spec.experiments}
    cache: dict[str, Evaluation] = {}
    for row in points.itertuples(index=False):
        group = frames.get(row.point)
        if row.status == "ok" and group is None:
            continue  # its series part was lost: run it again
        predictions = None
        if group is not None:
            data = experiments[row.experiment].data
            predictions = np.empty((len(data.times), len(data.columns)))
            for j, name in enumerate(data.columns):
                mine = group[group["variable"] == name]
                predictions[:, j] = mine.sort_values("time")["value"].to_numpy()
        cache[row.point_id] = Evaluation(row.status, row.message, predictions)
    return cache


def _next_point(store: ResultStore) -> int:
    done = store.done_points()
    return int(done.max()) + 1 if len(done) else 0

