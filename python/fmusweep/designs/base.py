"""What every design kind shares: the design itself (a names list and rows taken by index),
what a kind is (``DesignKind``), how its indices are drawn (``IndexChart``), and the
readers of the fields the kinds have in common."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from ..errors import Collector, SpecError
from ..fields import finite as _finite
from ..fields import low_high, setting, whole
from ..records import Points, Rows

__all__ = ["Design", "DesignKind", "IndexChart", "chains_of"]

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

    def chain_rule(self, most: int) -> dict[str, int]:
        """How its points make chains (``chains``): along one row of a grid (its last
        parameter varying; a design of listed rows is one row), at most `most` long."""
        row = len(self.axes[-1]) if self.axes is not None else len(self)
        return {"row": row, "most": most}

    def chains(self, points: Points, most: int) -> list[Points]:
        """`points` (ascending) cut into chains by ``chain_rule``."""
        return chains_of(points, **self.chain_rule(most))

    def column_values(self, j: int) -> Rows:
        """Every value column j takes (a grid's axis: each value once)."""
        if self.axes is not None:
            return self.axes[j]
        assert self.stored is not None
        return self.stored[:, j]


def chains_of(points: Points, row: int, most: int) -> list[Points]:
    """`points` (ascending) cut into chains, each of consecutive points of a design along
    one of its rows of `row` points, at most `most` long: a chain starts at a row's start,
    every `most` points along a row, and where the points skip one. Where a chain starts
    depends on the design alone."""
    points = np.asarray(points, dtype=np.int64)
    if not len(points):
        return []
    starts = np.ones(len(points), dtype=bool)
    starts[1:] = (np.diff(points) != 1) | ((points[1:] % row) % most == 0)
    return np.split(points, np.flatnonzero(starts)[1:])


@dataclass(frozen=True)
class IndexChart:
    """How a kind's indices of one metric are drawn, in the terms both the pictures and
    the report draw them in: ``bars``, a group of bars per name (one bar for each of
    ``series``, with ``errors`` as half-widths), or ``points``, one labelled point per name
    at (``series["x"]``, ``series["y"]``)."""
    style: str
    metric: str
    title: str
    names: list[str]
    series: dict[str, list[float]]
    errors: dict[str, list[float]] = field(default_factory=dict)
    axes: tuple[str, str] = ("", "")


@dataclass(frozen=True)
class DesignKind:
    """One kind of design: its name, the fields of its table besides ``kind`` and
    ``parameters``, whether it needs a seed, and how its points are made
    (``make(names, parameters, table, seed)``). A kind whose points give indices has
    ``indices(design, values, seed)``, the indices of one metric's values over every point,
    and ``chart(metric, indices)``, how they are drawn. ``metric_view(varying)``: how the
    metrics are drawn against the ``varying`` columns (``lines``, ``heatmap``, ``scatter``)."""
    name: str
    fields: frozenset[str]
    needs_seed: bool
    make: Callable[[list[str], dict[str, Any], dict[str, Any], int | None], Design]
    indices: Callable[[Design, Rows, int], dict[str, Any]] | None = None
    chart: Callable[[str, dict[str, Any]], IndexChart] | None = None
    metric_view: Callable[[int], str] = lambda varying: "scatter"


def per_column(names: list[str], read: Callable[[str], T]) -> list[T]:
    """read(name) for each column, every column's mistake reported at once."""
    errors = Collector()
    found = [errors.run(lambda: read(name)) for name in names]
    errors.raise_any()
    return [f for f in found if f is not None]


def not_too_many(count: int) -> None:
    if count < 1:
        raise SpecError("design", "has no point")
    if count > MAX_POINTS:
        raise SpecError("design", f"has {count} points, more than the {MAX_POINTS} one sweep takes")


def count_of(d: dict[str, Any], key: str, where: str) -> int:
    return whole(d.get(key), where, 1)


def values_of(name: str, entry: object) -> list[float]:
    where = f"design.parameters.{name}"
    if not isinstance(entry, dict) or set(entry) != {"values"}:
        raise SpecError(where, "a list design takes values = [...] for each parameter")
    return value_list(entry["values"], f"{where}.values", name)


def value_list(values: object, where: str, name: str) -> list[float]:
    """Values of variable `name`: numbers, true/false for a Boolean, item names for an
    Enumeration (``fields.setting``)."""
    if not isinstance(values, list):
        raise SpecError(where, f"must be a list of values, got {values!r}")
    if not values:
        raise SpecError(where, "is empty")
    return [setting(v, where, name) for v in values]


def axis_of(name: str, entry: object) -> list[float]:
    where = f"design.parameters.{name}"
    if isinstance(entry, list):
        return value_list(entry, where, name)
    if not isinstance(entry, dict) or len(entry) != 1 or next(iter(entry)) not in ("values", "linspace", "logspace"):
        raise SpecError(where, "give exactly one of values = [...], linspace = [start, stop, count], "
                               "logspace = [start, stop, count]")
    (how, arg), = entry.items()
    where = f"{where}.{how}"
    if how == "values":
        return value_list(arg, where, name)
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


def salib_problem(names: list[str], params: dict[str, Any]) -> dict[str, Any]:
    """SALib's problem over each parameter's ``range = [low, high]``."""
    bounds = per_column(names, lambda name: range_of(name, params[name], allow_log=False))
    return {"num_vars": len(names), "names": names,
            "bounds": [[low, high] for low, high, _ in bounds]}


def range_of(name: str, entry: object, allow_log: bool) -> tuple[float, float, bool]:
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
