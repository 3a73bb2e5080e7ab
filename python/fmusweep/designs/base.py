"""What every design kind shares: the design itself (a names list and rows taken by index),
what a kind is (``DesignKind``), how its indices are drawn (``IndexChart``), and the
readers of the fields the kinds have in common."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Annotated, Any

import numpy as np
from annotated_types import MinLen

from ..errors import SpecError, did_you_mean
from ..fields import setting
from ..records import Points, Rows
from ..schema.core import Loc, Parts, Table, at
from ..schema.core import field as declared
from ..schema.values import Range, Setting, Spacing

__all__ = ["Design", "DesignKind", "DesignTable", "IndexChart", "chains_of", "column_values",
           "SettingList", "ValuesEntry", "GridAxis", "RangeEntry", "LogRangeEntry",
           "salib_problem", "MAX_POINTS"]

MAX_POINTS = 100_000_000
# A non-empty list of a variable's values.
SettingList = Annotated[list[Setting], MinLen(1)]


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
    """One kind of design: its name, its ``[design]`` table (a ``DesignTable``: its fields,
    their rules and how many points they make), and how its points are made
    (``make(table, names)``). A kind whose points give indices has
    ``indices(design, values, seed)``, the indices of one metric's values over every point,
    and ``chart(metric, indices)``, how they are drawn. ``metric_view(varying)``: how the
    metrics are drawn against the ``varying`` columns (``lines``, ``heatmap``, ``scatter``)."""
    name: str
    table: type[DesignTable]
    make: Callable[[Any, list[str]], Design]
    indices: Callable[[Design, Rows, int], dict[str, Any]] | None = None
    chart: Callable[[str, dict[str, Any]], IndexChart] | None = None
    metric_view: Callable[[int], str] = lambda varying: "scatter"


# Every kind by name: filled by the package from its modules (``designs.KINDS``).
KINDS: dict[str, DesignKind] = {}


# --- the [design] table ---------------------------------------------------------------------
class DesignTable(Table):
    """What every kind's table has: its kind and its parameters; each kind's table adds its
    own fields and says how many points they make (``count``)."""
    about = "The points of the sweep: a kind, its parameters and the kind's own fields."
    kind: str = declared("the kind of design", "grid", shows="grid | list | lhs | sobol | morris")
    parameters: dict[str, Any] = declared("the design's columns: each varied parameter")

    @classmethod
    def variant(cls, raw: object) -> Any:
        if cls is not DesignTable:
            return cls
        kind = raw.get("kind", "grid") if isinstance(raw, dict) else "grid"
        found = KINDS.get(kind) if isinstance(kind, str) else None
        if found is None:
            raise SpecError("kind", f"must be one of {', '.join(KINDS)}, got {kind!r}"
                                    f"{did_you_mean(str(kind), KINDS)}")
        return found.table

    @classmethod
    def count(cls, parts: Parts) -> int | None:
        """How many points the table's fields make (None while one it needs is wrong)."""
        return None

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        parameters = parts.get("parameters")
        if parameters == {}:
            yield SpecError(at(where + ("parameters",)), "names no parameter: the design is "
                                                         "empty")
        count = cls.count(parts) if parameters else None
        if count is not None and count > MAX_POINTS:
            yield SpecError(at(where), f"has {count} points, more than the {MAX_POINTS} one "
                                       "sweep takes")


class SampledTable(DesignTable):
    """A design drawn by a seeded sampler (lhs, sobol, morris)."""
    seed: int = declared("the sampler's seed, so that the design can be repeated", ge=0)


class ValuesEntry(Table):
    about = "A column's values, listed."
    values: SettingList = declared("the values it takes: numbers, true/false for a Boolean, "
                                "items' names for an Enumeration", shows="list of values")


class LinspaceEntry(Table):
    about = "A column's values evenly spaced."
    linspace: Spacing = declared("count values from start to stop, evenly spaced",
                              shows="[start, stop, count]")


class LogspaceEntry(Table):
    about = "A column's values evenly spaced in log."
    logspace: Spacing = declared("count values from start to stop (both > 0, the values "
                              "themselves, not exponents), evenly spaced in log",
                              shows="[start, stop, count]")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        spacing = parts.get("logspace")
        if spacing is not None and (spacing[0] <= 0 or spacing[1] <= 0):
            yield SpecError(at(where + ("logspace",)), f"takes values > 0 (not exponents), got "
                                                       f"{spacing[0]:g} and {spacing[1]:g}")


AXES: dict[str, Any] = {"values": ValuesEntry, "linspace": LinspaceEntry, "logspace": LogspaceEntry}


class GridAxis(Table):
    """A grid's column: a list of values, or one of ``values``, ``linspace``, ``logspace``."""

    @classmethod
    def variant(cls, raw: object) -> Any:
        if isinstance(raw, list):
            return SettingList
        given = [key for key in AXES if isinstance(raw, dict) and key in raw]
        if len(given) != 1 or (isinstance(raw, dict) and len(raw) != 1):
            raise SpecError("", "give exactly one of values = [...], linspace = [start, stop, "
                                "count], logspace = [start, stop, count]")
        return AXES[given[0]]


class RangeEntry(Table):
    about = "A column's range, sampled uniformly."
    hints = {"log": "a sobol or morris design samples each range uniformly: log = true is an "
                    "lhs design's"}
    range: Range = declared("the least and greatest value sampled", shows="[low, high]")


class LogRangeEntry(Table):
    about = "A column's range, sampled uniformly or log-uniformly."
    range: Range = declared("the least and greatest value sampled", shows="[low, high]")
    log: bool = declared("sample log-uniformly (low > 0)", False)

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        bounds = parts.get("range")
        if parts.get("log") and bounds is not None and bounds[0] <= 0:
            yield SpecError(at(where + ("range",)), f"a log range needs low > 0, got "
                                                    f"{bounds[0]:g}")


def same_setting(value: Any) -> tuple[bool, Any]:
    """What makes two settings of a column the same point: their value, a Boolean apart
    from a number (true is not 1 in a spec; 1 and 1.0 are one value)."""
    return isinstance(value, bool), value


def column_values(entry: Any, name: str) -> list[float]:
    """The values a column's entry gives (a grid's axis, a list's values): numbers, the
    settings converted by the FMU's types (``fields.setting``)."""
    where = f"design.parameters.{name}"
    if isinstance(entry, list):
        return [setting(v, where, name) for v in entry]
    if isinstance(entry, ValuesEntry):
        return [setting(v, f"{where}.values", name) for v in entry.values]
    if isinstance(entry, LinspaceEntry):
        start, stop, count = entry.linspace
        return [float(x) for x in np.linspace(start, stop, count)]
    if isinstance(entry, LogspaceEntry):
        start, stop, count = entry.logspace
        return [float(x) for x in np.geomspace(start, stop, count)]
    raise TypeError(f"not a column's values: {entry!r}")


def salib_problem(names: list[str], table: Any) -> dict[str, Any]:
    """SALib's problem over each parameter's ``range = [low, high]``."""
    return {"num_vars": len(names), "names": names,
            "bounds": [list(table.parameters[name].range) for name in names]}


