"""Designs: the parameter points of a sweep, as a names list and rows taken by index.

- ``grid``: each parameter takes ``values = [...]``, ``linspace = [start, stop, count]``
  or ``logspace = [start, stop, count]`` (the values themselves, evenly spaced in log:
  ``[0.01, 10, 4]`` gives 0.01, 0.1, 1, 10); the points are the full-factorial product,
  the first parameter varying slowest.
- ``list``: each parameter gives ``values``, all of one length; point i takes the i-th.
- ``lhs``: ``samples`` points of a seeded Latin hypercube over each parameter's
  ``range = [low, high]`` (``log = true`` samples log-uniformly).
- ``sobol``: Saltelli's design for Sobol' indices (SALib): ``samples`` = N, a power of
  two, gives N·(D + 2) points (N·(2D + 2) with ``second_order = true``).
- ``morris``: Morris' elementary effects (SALib): ``trajectories`` = r gives r·(D + 1)
  points on a grid of ``levels`` (default 4).

A grid keeps only its axes and makes a point's values from its index when a batch needs
them, so that the client's memory does not grow with the number of points; the sampled
designs are held whole (their generators make them so).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from .errors import Collector, SpecError
from .fields import finite as _finite
from .fields import low_high, setting, whole
from .records import Points, Rows

__all__ = ["Design", "generate"]

MAX_POINTS = 100_000_000
T = TypeVar("T")


@dataclass
class Design:
    """The points of a sweep: ``rows_at(points)`` gives their values (one row per point,
    a column per name), ``len(design)`` their number."""
    kind: str
    names: list[str]
    # Either the axes of a full-factorial grid (the first varying slowest), or every row.
    axes: list[Rows] | None = field(default=None, repr=False)
    stored: Rows | None = field(default=None, repr=False)
    problem: dict[str, Any] | None = None  # SALib's problem, for sobol and morris
    second_order: bool = False
    levels: int = 4  # morris

    def __len__(self) -> int:
        if self.axes is not None:
            return math.prod(len(a) for a in self.axes)
        assert self.stored is not None
        return len(self.stored)

    def rows_at(self, points: Points) -> Rows:
        """The values of the points with these indices, a row each."""
        points = np.asarray(points, dtype=np.int64)
        if self.axes is None:
            assert self.stored is not None
            return self.stored[points]
        shape = tuple(len(a) for a in self.axes)
        indices = np.unravel_index(points, shape)
        return np.column_stack([a[i] for a, i in zip(self.axes, indices)]).reshape(
            len(points), len(self.names))

    @property
    def rows(self) -> Rows:
        """Every row at once (a grid's made for the asking: only what needs them all, the
        sensitivity estimators and small designs, should ask)."""
        return self.rows_at(np.arange(len(self), dtype=np.int64))

    def column_values(self, j: int) -> Rows:
        """Every value column j takes (a grid's axis: each value once)."""
        if self.axes is not None:
            return self.axes[j]
        assert self.stored is not None
        return self.stored[:, j]


def generate(kind: str, d: dict[str, Any], seed: int | None) -> Design:
    """The points of a `kind` design from its table `d` (``[design]``) and seed."""
    params = d["parameters"]
    allowed = {"grid": {"kind", "parameters"}, "list": {"kind", "parameters"},
               "lhs": {"kind", "parameters", "seed", "samples"},
               "sobol": {"kind", "parameters", "seed", "samples", "second_order"},
               "morris": {"kind", "parameters", "seed", "trajectories", "levels"}}[kind]
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise SpecError(f"design.{unknown[0]}", f"is not a field of a {kind} design; "
                        f"expected {', '.join(sorted(allowed))}")
    names = list(params)
    if kind == "grid":
        axes = _per_column(names, lambda name: _axis(name, params[name]))
        count = math.prod(len(a) for a in axes)
        _not_too_many(count)
        return Design(kind, names, axes=[np.asarray(a, dtype=float) for a in axes])
    if kind == "list":
        columns = _per_column(names, lambda name: _values(name, params[name]))
        lengths = {len(c) for c in columns}
        if len(lengths) != 1:
            raise SpecError("design.parameters", f"a list design needs values of one length, got {sorted(lengths)}")
        return Design(kind, names, stored=np.array(columns, dtype=float).T.copy())
    bounds = _per_column(names, lambda name: _range(name, params[name], allow_log=(kind == "lhs")))
    if kind == "lhs":
        n = _count(d, "samples", "design.samples")
        _not_too_many(n)
        from scipy.stats import qmc
        unit = qmc.LatinHypercube(d=len(names), seed=seed).random(n)
        rows = np.empty_like(unit)
        for j, (low, high, log) in enumerate(bounds):
            if log:
                rows[:, j] = np.exp(np.log(low) + unit[:, j] * (np.log(high) - np.log(low)))
            else:
                rows[:, j] = low + unit[:, j] * (high - low)
        return Design(kind, names, stored=rows)
    problem = {"num_vars": len(names), "names": names,
               "bounds": [[low, high] for low, high, _ in bounds]}
    if kind == "sobol":
        n = _count(d, "samples", "design.samples")
        if n & (n - 1):
            raise SpecError("design.samples", f"a Sobol' design needs a power of two, got {n}")
        second = d.get("second_order", False)
        if not isinstance(second, bool):
            raise SpecError("design.second_order", f"must be true or false, got {second!r}")
        _not_too_many(n * (2 * len(names) + 2 if second else len(names) + 2))
        from SALib.sample import sobol
        rows = sobol.sample(problem, n, calc_second_order=second, seed=seed)
        return Design(kind, names, stored=np.asarray(rows, dtype=float), problem=problem,
                      second_order=second)
    r = _count(d, "trajectories", "design.trajectories")
    levels = d.get("levels", 4)
    if not isinstance(levels, int) or isinstance(levels, bool) or levels < 2 or levels % 2:
        raise SpecError("design.levels", f"must be an even whole number ≥ 2, got {levels!r}")
    _not_too_many(r * (len(names) + 1))
    from SALib.sample.morris import sample as morris_sample
    rows = morris_sample(problem, r, num_levels=levels, seed=seed)
    return Design(kind, names, stored=np.asarray(rows, dtype=float), problem=problem,
                  levels=levels)


def _per_column(names: list[str], read: Callable[[str], T]) -> list[T]:
    """read(name) for each column, every column's mistake reported at once."""
    errors = Collector()
    found = [errors.run(lambda: read(name)) for name in names]
    errors.raise_any()
    return [f for f in found if f is not None]


def _not_too_many(count: int) -> None:
    if count < 1:
        raise SpecError("design", "has no point")
    if count > MAX_POINTS:
        raise SpecError("design", f"has {count} points, more than the {MAX_POINTS} one sweep takes")


def _count(d: dict[str, Any], key: str, where: str) -> int:
    return whole(d.get(key), where, 1)


def _values(name: str, entry: object) -> list[float]:
    where = f"design.parameters.{name}"
    if not isinstance(entry, dict) or set(entry) != {"values"}:
        raise SpecError(where, "a list design takes values = [...] for each parameter")
    return _value_list(entry["values"], f"{where}.values", name)


def _value_list(values: object, where: str, name: str) -> list[float]:
    """Values of variable `name`: numbers, true/false for a Boolean, item names for an
    Enumeration (``fields.setting``)."""
    if not isinstance(values, list):
        raise SpecError(where, f"must be a list of values, got {values!r}")
    if not values:
        raise SpecError(where, "is empty")
    return [setting(v, where, name) for v in values]


def _axis(name: str, entry: object) -> list[float]:
    where = f"design.parameters.{name}"
    if isinstance(entry, list):
        return _value_list(entry, where, name)
    if not isinstance(entry, dict) or len(entry) != 1 or next(iter(entry)) not in ("values", "linspace", "logspace"):
        raise SpecError(where, "give exactly one of values = [...], linspace = [start, stop, count], "
                               "logspace = [start, stop, count]")
    (how, arg), = entry.items()
    where = f"{where}.{how}"
    if how == "values":
        return _value_list(arg, where, name)
    if not (isinstance(arg, list) and len(arg) == 3):
        raise SpecError(where, f"must be [start, stop, count], got {arg!r}")
    start, stop = _finite(arg[0], where), _finite(arg[1], where)
    count = arg[2]
    if not isinstance(count, int) or isinstance(count, bool) or count < 1:
        raise SpecError(where, f"count must be a whole number ≥ 1, got {count!r}")
    if how == "linspace":
        return [float(x) for x in np.linspace(start, stop, count)]
    if start <= 0 or stop <= 0:
        raise SpecError(where, f"logspace takes values > 0 (not exponents), got {start} and {stop}")
    return [float(x) for x in np.geomspace(start, stop, count)]


def _range(name: str, entry: object, allow_log: bool) -> tuple[float, float, bool]:
    where = f"design.parameters.{name}"
    keys = {"range", "log"} if allow_log else {"range"}
    if not isinstance(entry, dict) or "range" not in entry or set(entry) - keys:
        raise SpecError(where, f"give range = [low, high]{' (and log = true)' if allow_log else ''}")
    low, high = low_high(entry["range"], f"{where}.range")
    log = entry.get("log", False)
    if not isinstance(log, bool):
        raise SpecError(f"{where}.log", f"must be true or false, got {log!r}")
    if log and low <= 0:
        raise SpecError(f"{where}.range", f"a log range needs low > 0, got {low}")
    return low, high, log
