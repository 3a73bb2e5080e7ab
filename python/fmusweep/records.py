"""The records that travel between the study runner, the workers and the native runner,
written once: the plan every point of a study shares (sent to ``fmu-runner`` as JSON, so
its keys are the runner's), a point's result, and a finished batch."""

from __future__ import annotations

from typing import Any, Callable, NotRequired, TypedDict

import numpy as np
import numpy.typing as npt

__all__ = ["InputTable", "MetricPlan", "SeriesPlan", "Plan", "new_plan", "CouplingRecord",
           "PointResult", "Batch",
           "BatchFunction", "PrepareFunction", "Rows", "Points"]

# A batch's parameter values, one row per point (float64), and the points' indices.
Rows = npt.NDArray[np.float64]
Points = npt.NDArray[np.int64]


class InputTable(TypedDict):
    """A piecewise-linear input, held beyond its ends; one point makes a constant."""
    times: list[float]
    values: list[float]


# "from" is a keyword: the functional form. `field` is what the runner's refusals of it
# name; `extremes`, "refined" (the runner's default) or "sampled".
MetricPlan = TypedDict("MetricPlan", {"variable": str, "kind": str, "from": float | None,
                                      "to": float | None, "field": NotRequired[str],
                                      "extremes": NotRequired[str | None]})


class SeriesPlan(TypedDict):
    variables: list[str]
    every: int  # every how many communication steps a row is kept


class Plan(TypedDict):
    """What every point of a study shares."""
    start: float
    stop: float
    step: float
    tolerance: float | None
    fixed: dict[str, float]
    inputs: dict[str, InputTable]
    metrics: list[MetricPlan]
    series: SeriesPlan | None
    timeout_s: float | None
    interface: NotRequired[str | None]  # "co_simulation" or "model_exchange"
    integrator: NotRequired[str | None]  # "dop853" or "radau5" (Model Exchange)
    cycle: NotRequired[Any]  # the steady cycle's plan (fmusweep.cycle.CycleSpec.plan)
    # The client's own, not the runner's: how a sweep of continued steady cycles cuts its
    # points into chains (fmusweep.designs.base.chains_of's row and most).
    chain: NotRequired[dict[str, int] | None]


def new_plan(start: float, stop: float, step: float, *, tolerance: float | None = None,
             interface: str | None = None, cycle: Any = None) -> Plan:
    """A plan that sets nothing and measures nothing: a run over (start, stop) at `step`,
    through `interface` (None: the runner's choice), with a steady `cycle` where given."""
    return {"start": start, "stop": stop, "step": step, "tolerance": tolerance, "fixed": {},
            "inputs": {}, "metrics": [], "series": None, "timeout_s": None,
            "interface": interface, "integrator": None, "cycle": cycle}


class CouplingRecord(TypedDict):
    """A coupled point's communication steps, with a coupling tolerance: the largest
    estimate of an accepted step (in units of the connections' scales), the accepted and
    rejected steps and the smallest accepted one (None before any)."""
    worst_estimate: float
    accepted: int
    rejected: int
    min_step: float | None


class PointResult(TypedDict):
    """One point's outcome: ``status`` ok, or why not (``message``); the metrics in the
    plan's order (None where the run did not get far enough); the series' rows
    (t, variables…) when the plan keeps a series; ``events`` the events an FMI 3.0 FMU met
    (each handled in its event mode); ``coupling`` for a system with a coupling
    tolerance; ``worker`` once a pool has placed it."""
    status: str
    message: str
    metrics: list[float | None]
    t_end: float | None
    steps: int | None
    wall_s: float | None
    events: NotRequired[int | None]
    series: NotRequired[npt.NDArray[np.float64]]
    coupling: NotRequired[CouplingRecord | None]
    # The steady cycle, when the plan asks for one (runner/src/cycle/mod.rs's record).
    cycle: NotRequired[dict[str, Any] | None]
    worker: NotRequired[str]


class Batch(TypedDict):
    """A batch's results in its points' order, and the worker that ran it."""
    points: Points
    results: list[PointResult]
    worker: str


# What a pool runs on a chunk of points, and how a worker prepares itself once; the
# first argument is the study's target (an FMU's or an SSP's bytes).
BatchFunction = Callable[..., Batch]
PrepareFunction = Callable[..., str]
