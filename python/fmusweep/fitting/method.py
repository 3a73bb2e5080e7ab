"""Bounded nonlinear least squares on the weighted residuals: scipy's trust-region
reflective method in the unit box of the parameters' ranges, with the Jacobian from the
FMU's own sensitivities where it offers them (one run gives the residuals and those
columns) and from forward differences for the rest. Each trial point goes to the pool
together with its perturbed points, as one batch: on n workers a trial costs the time of
one run whatever the number of parameters, and an accepted trial has its Jacobian ready
(a rejected one wastes its perturbed runs, which on spare workers cost no time)."""

from __future__ import annotations

import concurrent.futures
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..records import Rows

if TYPE_CHECKING:
    from .problem import Problem
    from .spec import FitSpec

__all__ = ["Start", "solve", "starting_points"]

STATUS = {-1: "failed", 0: "max_iterations", 1: "converged", 2: "converged", 3: "converged",
          4: "converged"}


@dataclass
class Start:
    """One optimisation from one starting point."""
    index: int
    start: Rows
    status: str = "failed"
    message: str = ""
    estimate: Rows | None = None
    cost: float = float("inf")
    iterations: int = 0
    jacobian: Rows | None = None  # d(weighted residuals)/d(parameters) at the estimate
    residuals: Rows | None = None
    notes: list[str] = field(default_factory=list)


def starting_points(spec: FitSpec) -> Rows:
    """The spec's start, then a seeded Latin hypercube over the ranges for the others."""
    first = np.array([[p.start for p in spec.fitted]])
    if spec.starts == 1:
        return first
    from scipy.stats import qmc
    unit = qmc.LatinHypercube(d=len(spec.fitted), seed=spec.seed).random(spec.starts - 1)
    return np.vstack([first, spec.lows + unit * (spec.highs - spec.lows)])


def solve_all(problem: Problem, starts: Rows, concurrency: int) -> list[Start]:
    """Every start's optimisation; with concurrency > 1 they run side by side, each
    waiting on its own batches, so that the workers stay busy."""
    if concurrency <= 1 or len(starts) == 1:
        return [solve(problem, s, i) for i, s in enumerate(starts)]
    with concurrent.futures.ThreadPoolExecutor(max_workers=min(concurrency, len(starts))) as threads:
        return list(threads.map(lambda item: solve(problem, item[1], item[0]), enumerate(starts)))


def solve(problem: Problem, start: Rows, index: int, free: list[int] | None = None,
          role: str = "trial") -> Start:
    """One optimisation from `start`, of the parameters `free` (default: all; the others
    held at their values in `start`)."""
    from scipy.optimize import least_squares
    spec = problem.spec
    free = list(range(len(spec.fitted))) if free is None else free
    low, width = spec.lows[free], (spec.highs - spec.lows)[free]
    held = np.array(start, dtype=float)
    outcome = Start(index, start)
    # The Jacobian of the last evaluated point: the trust region asks for the Jacobian of
    # an accepted trial, always the point it evaluated last.
    last: tuple[bytes, Rows] | None = None
    failure = ""

    def theta(z: Any) -> Rows:
        moved: Rows = held.copy()
        moved[free] = low + np.asarray(z) * width
        return moved

    def residuals(z: Any) -> Rows:
        nonlocal last, failure
        f, jacobian, message = _evaluate_with_jacobian(problem, theta(z), index, outcome.notes,
                                                       free, role)
        if jacobian is None:
            # Asked for only at the start (scipy then stops on the infinite residuals):
            # any finite matrix will do.
            jacobian = np.zeros((len(f), len(width)))
            failure = message
        last = (np.asarray(z).tobytes(), jacobian * width)
        return f

    def jacobian(z: Any, *_: object) -> Rows:
        if last is None or last[0] != np.asarray(z).tobytes():
            residuals(z)
        assert last is not None
        return last[1]

    z0 = (held[free] - low) / width
    try:
        result = least_squares(residuals, z0, jac=jacobian, bounds=(0.0, 1.0), method="trf",
                               max_nfev=spec.max_iterations)
    except ValueError as e:
        outcome.message = (f"the run at the start failed: {failure}" if failure
                           else f"the optimiser stopped: {e}")
        return outcome
    outcome.status = STATUS.get(result.status, "failed")
    outcome.message = str(result.message)
    outcome.estimate = theta(result.x)
    outcome.cost = float(result.cost)
    outcome.iterations = int(result.nfev)
    outcome.jacobian = np.asarray(result.jac) / width
    outcome.residuals = np.asarray(result.fun)
    return outcome


def _evaluate_with_jacobian(problem: Problem, theta: Rows, start: int, notes: list[str],
                            free: list[int], role: str) -> tuple[Rows, Rows | None, str]:
    """The residuals at theta and their Jacobian in the free parameters' units: the
    columns the FMU's own sensitivities give from theta's run, the others by forward
    differences (see ``_differences``)."""
    sensitive = problem.with_sensitivities(free)
    columns: dict[int, Rows] = {}
    if sensitive:
        trial, columns = problem.evaluate_with_sensitivities(theta, start, role)
        if not trial.ok:
            columns = {}  # the sensitivities failed (a change point, say): differences
    rest = [j for j in free if j not in columns]
    f, differenced, message = _differences(problem, theta, start, notes, rest, role)
    if differenced is None:
        return f, None, message
    columns.update(zip(rest, differenced.T))
    return f, np.column_stack([columns[j] for j in free]), ""


def _differences(problem: Problem, theta: Rows, start: int, notes: list[str],
                 free: list[int], role: str) -> tuple[Rows, Rows | None, str]:
    """The residuals at theta and the Jacobian columns of `free` by forward differences,
    from one batch of theta and its perturbed points (and a second batch for a column
    whose perturbed run failed, perturbed the other way). An experiment a perturbation
    does not touch is not run again, nor is theta where it ran before
    (``Problem.evaluate``)."""
    spec = problem.spec
    steps = _steps(spec, theta)
    unit = np.eye(len(theta))
    rows = [theta] + [theta + unit[j] * steps[j] for j in free]
    evaluations = problem.evaluate(np.array(rows), start, [role] + ["jacobian"] * len(free))
    if not evaluations[0].ok:
        return problem.residuals(evaluations[0]), None, evaluations[0].message
    f = problem.residuals(evaluations[0])
    columns: list[Rows | None] = [None if not e.ok else (problem.residuals(e) - f) / steps[j]
                                  for j, e in zip(free, evaluations[1:])]
    retry = [c for c, col in enumerate(columns) if col is None]
    if retry:
        back = np.array([theta - unit[free[c]] * steps[free[c]] for c in retry])
        for c, e in zip(retry, problem.evaluate(back, start, ["jacobian"] * len(retry))):
            j = free[c]
            if e.ok:
                columns[c] = (f - problem.residuals(e)) / steps[j]
            else:
                columns[c] = np.zeros_like(f)
                notes.append(f"{spec.names[j]}: the runs perturbed both ways from {theta[j]:g} "
                             f"failed ({e.message}); its Jacobian column was taken as zero")
    if not free:
        return f, np.zeros((len(f), 0)), ""
    return f, np.column_stack([c for c in columns if c is not None]), ""


def _steps(spec: FitSpec, theta: Rows) -> Rows:
    """A forward step per parameter, from its size and its range; backward where forward
    would leave the range."""
    width = spec.highs - spec.lows
    h = spec.relative_step * np.maximum(np.abs(theta), 0.1 * width)
    steps: Rows = np.where(theta + h > spec.highs, -h, h)
    return steps
