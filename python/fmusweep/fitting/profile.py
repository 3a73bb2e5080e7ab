"""Likelihood-profile intervals: for a parameter, the least cost with it held at a value
and every other parameter re-optimised, walked outward from the estimate on each side
until the cost has risen by the 95 % threshold; the interval is where it crosses.

Unlike the Wald interval, which assumes the model linear in its parameters near the
estimate, the profile follows the cost as the model makes it, so it is lopsided where the
model is. Each side of each parameter is one walk (each point starts from its neighbour's
optimum), and the walks run side by side on the pool. A side that reaches the parameter's
range without crossing is open: the data do not bound it there, and the interval says so
instead of giving a number.

The threshold on the cost C = ½ Σ r² (weighted residuals):
- with every standard deviation given, 2 ΔC ≤ χ²₁(0.95);
- otherwise (weights relative, the variance estimated) C ≤ Ĉ (1 + F₁,ₘ₋ₚ(0.95) / (m − p)),
  which for a linear model is exactly the t-based Wald interval.
"""

from __future__ import annotations

import concurrent.futures
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..records import Rows
from .method import solve

if TYPE_CHECKING:
    from .method import Start
    from .problem import Problem

__all__ = ["Profile", "profile_all", "threshold"]

# Points of one side's walk, at most: the walk reaches the threshold in a few quadratic
# predictions, and one more pins the crossing.
MAX_POINTS = 10
# Each step aims a little past the threshold, so that the walk brackets the crossing in
# one step where the cost is near quadratic.
OVERSHOOT = 1.3
# Points spent narrowing a crossing, at most, and the bracket (relative to the crossing's
# distance from the first point) below which it is taken as found.
REFINEMENTS = 2
CROSSING_TOLERANCE = 1e-3
# A profile point lower than the estimate's cost by more than this (relative) means the
# fit stopped short of the optimum.
LOWER_SLACK = 1e-6


@dataclass
class Side:
    """One side's walk: the values held and the least costs there (inf where no run
    finished), and where it crosses the threshold (None: open)."""
    values: list[float] = field(default_factory=list)
    costs: list[float] = field(default_factory=list)
    crossing: float | None = None
    note: str = ""
    # The estimate sits on this side's bound (the Wald statistics warn of it already).
    at_bound: bool = False


@dataclass
class Profile:
    name: str
    estimate: float
    cost: float
    threshold: float
    low: Side
    high: Side

    @property
    def interval(self) -> tuple[float | None, float | None]:
        return self.low.crossing, self.high.crossing

    def points(self) -> tuple[list[float], list[float]]:
        """The profile's values and costs in increasing order, the estimate included."""
        pairs = sorted(zip(self.low.values + [self.estimate] + self.high.values,
                           self.low.costs + [self.cost] + self.high.costs))
        return [v for v, _ in pairs], [c for _, c in pairs]


def threshold(problem: Problem, best: Start) -> float:
    """The cost at which a profile leaves the 95 % interval."""
    from scipy import stats
    assert best.residuals is not None
    m, p = len(best.residuals), len(problem.spec.fitted)
    if problem.spec.absolute_sigma:
        return best.cost + 0.5 * float(stats.chi2.ppf(0.95, 1))
    dof = m - p
    if dof <= 0:
        return math.inf
    return best.cost * (1.0 + float(stats.f.ppf(0.95, 1, dof)) / dof)


def profile_all(problem: Problem, best: Start, scales: dict[str, float | None],
                concurrency: int) -> list[Profile]:
    """The profiles of the spec's profiled parameters, both sides of each walked side by
    side (`scales`: a first step per parameter, its Wald standard error where there is one)."""
    spec = problem.spec
    assert best.estimate is not None
    limit = threshold(problem, best)
    walks = [(spec.names.index(name), sign) for name in spec.profiled for sign in (-1, 1)]

    def walk(item: tuple[int, int]) -> Side:
        j, sign = item
        return _walk(problem, best, j, sign, limit, scales.get(spec.names[j]))

    if concurrency <= 1:
        sides = [walk(w) for w in walks]
    else:
        with concurrent.futures.ThreadPoolExecutor(max_workers=min(concurrency, len(walks))) as threads:
            sides = list(threads.map(walk, walks))
    return [Profile(name, float(best.estimate[spec.names.index(name)]), best.cost, limit,
                    sides[2 * k], sides[2 * k + 1]) for k, name in enumerate(spec.profiled)]


def _walk(problem: Problem, best: Start, j: int, sign: int, limit: float,
          scale: float | None) -> Side:
    spec = problem.spec
    assert best.estimate is not None
    p = spec.fitted[j]
    bound = p.high if sign > 0 else p.low
    side = Side()
    estimate = float(best.estimate[j])
    if abs(bound - estimate) <= 1e-9 * p.width:
        side.note = f"{p.name} ended at its range's {'upper' if sign > 0 else 'lower'} bound"
        side.at_bound = True
        return side
    step = scale if scale is not None and 0 < scale < p.width else 0.05 * p.width
    rise = limit - best.cost
    held = np.array(best.estimate, dtype=float)
    inside = (estimate, 0.0)  # the farthest value inside the interval, and its rise
    for _ in range(MAX_POINTS):
        value = _clip(estimate + sign * step, p.low, p.high)
        cost, held = _least_cost(problem, held, j, value)
        side.values.append(value)
        side.costs.append(cost)
        if not math.isfinite(cost):
            # No run finished there (a geometry that does not assemble, a failed step): the
            # data say nothing of it, so the interval has no end on this side to report.
            side.note = (f"{p.name}'s profile stops at {value:g}, where no run finished: "
                         "its interval on that side is not known")
            return side
        if cost < best.cost * (1 - LOWER_SLACK) - 1e-12:
            side.note = (f"{p.name} = {value:g} has a lower cost ({cost:.6g}) than the "
                         f"estimate ({best.cost:.6g}): the fit stopped short of its optimum")
        if cost >= limit:
            side.crossing = _refined(problem, side, held, j, estimate, inside,
                                     (value, cost - best.cost), best.cost, rise)
            return side
        inside = (value, cost - best.cost)
        if value == bound:
            side.note = side.note or (f"{p.name}'s profile stays below the threshold up to its "
                                      f"range's {'upper' if sign > 0 else 'lower'} bound {bound:g}: "
                                      "the data do not bound it on that side")
            return side
        # Where a quadratic through the estimate would cross, a little past it.
        distance = abs(value - estimate)
        grown = distance * math.sqrt(OVERSHOOT * rise / max(cost - best.cost, 1e-300))
        step = min(max(grown, 1.2 * distance), 4.0 * distance)
    side.note = f"{p.name}'s profile did not reach the threshold in {MAX_POINTS} points"
    return side


def _refined(problem: Problem, side: Side, held: Rows, j: int, estimate: float,
             inside: tuple[float, float], outside: tuple[float, float], cost: float,
             rise: float) -> float:
    """The crossing between a value inside and one outside, narrowed by REFINEMENTS
    further points where the profile is not quadratic enough for one interpolation."""
    for _ in range(REFINEMENTS):
        guess = _crossing(inside, outside, rise)
        if abs(outside[0] - inside[0]) <= CROSSING_TOLERANCE * abs(guess - estimate):
            return guess
        value_cost, held = _least_cost(problem, held, j, guess)
        side.values.append(guess)
        side.costs.append(value_cost)
        if not math.isfinite(value_cost):
            return _crossing(inside, outside, rise)
        if value_cost - cost >= rise:
            outside = (guess, value_cost - cost)
        else:
            inside = (guess, value_cost - cost)
    return _crossing(inside, outside, rise)


def _least_cost(problem: Problem, held: Rows, j: int, value: float) -> tuple[float, Rows]:
    """The least cost with parameter j at `value` and the others re-optimised from `held`;
    and the optimum found (the next point's start)."""
    spec = problem.spec
    start = np.clip(held, spec.lows, spec.highs)
    start[j] = value
    free = [k for k in range(len(start)) if k != j]
    if not free:
        [trial] = problem.evaluate(start[None, :], -1, ["profile"])
        return problem.cost(trial), start
    outcome = solve(problem, start, -1, free, role="profile")
    if outcome.estimate is None:
        return math.inf, start
    return outcome.cost, outcome.estimate


def _crossing(inside: tuple[float, float], outside: tuple[float, float], rise: float) -> float:
    """Where the rise reaches `rise` between a value inside and one outside, interpolated
    in the signed root of the rise, which is linear in the value for a quadratic cost."""
    (a, ra), (b, rb) = inside, outside
    if not math.isfinite(rb):
        return b
    sa, sb, target = math.sqrt(max(ra, 0.0)), math.sqrt(rb), math.sqrt(rise)
    return a + (b - a) * (target - sa) / (sb - sa) if sb > sa else b


def _clip(value: float, low: float, high: float) -> float:
    return min(max(value, low), high)


def summary_of(profiles: list[Profile]) -> dict[str, Any]:
    """fit.json's record of the profiles: the walked points and the threshold."""
    out = {}
    for pr in profiles:
        values, costs = pr.points()
        out[pr.name] = {"values": values, "cost": [c if math.isfinite(c) else None for c in costs],
                        "threshold": pr.threshold, "ci95": list(pr.interval),
                        "notes": [s.note for s in (pr.low, pr.high) if s.note]}
    return out
