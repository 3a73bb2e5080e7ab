"""``grid``: each parameter takes ``values = [...]``, ``linspace = [start, stop, count]`` or
``logspace = [start, stop, count]`` (the values themselves, evenly spaced in log: ``[0.01,
10, 4]`` gives 0.01, 0.1, 1, 10); the points are the full-factorial product, the first
parameter varying slowest. Only the axes are kept: a point's values are made from its
index."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any, Literal

import numpy as np

from ..errors import SpecError
from ..schema.core import Loc, Parts, at
from ..schema.core import field as declared
from .base import Design, DesignKind, DesignTable, GridAxis, LinspaceEntry, LogspaceEntry, \
    ValuesEntry, same_setting


class GridTable(DesignTable):
    about = "A full-factorial grid: every combination of the columns' values."
    kind: Literal["grid"] = declared("the kind of design", "grid")
    parameters: dict[str, GridAxis] = declared(
        "each column: values = [...], linspace = [start, stop, count] or logspace = [start, "
        "stop, count] (or a list of values)", shows="table of name = axis")

    @classmethod
    def count(cls, parts: Parts) -> int | None:
        return math.prod(_length(axis) for axis in parts.get("parameters").values())

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        yield from super().rules(parts, where)
        for name, axis in (parts.get("parameters") or {}).items():
            values = axis.values if isinstance(axis, ValuesEntry) else axis
            if isinstance(values, list):
                twice = repeated(values)
                if twice:
                    field = ("parameters", name) + (("values",) if values is not axis else ())
                    yield SpecError(at(where + field), f"lists {_shown(twice)} more than once: "
                                                       "the grid would run the same points again")
            elif isinstance(axis, (LinspaceEntry, LogspaceEntry)):
                key = "linspace" if isinstance(axis, LinspaceEntry) else "logspace"
                start, stop, count = getattr(axis, key)
                if start == stop and count > 1:
                    yield SpecError(at(where + ("parameters", name, key)),
                                    f"gives {start:g} {count} times (start = stop): the grid "
                                    "would run the same points again")


def repeated(values: list[Any]) -> list[Any]:
    """The values a list holds more than once, each as first written, in their order."""
    first: dict[tuple[bool, Any], Any] = {}
    twice: dict[tuple[bool, Any], Any] = {}
    for v in values:
        key = same_setting(v)
        if key in first:
            twice.setdefault(key, first[key])
        else:
            first[key] = v
    return list(twice.values())


def _shown(values: list[Any]) -> str:
    return ", ".join(str(v).lower() if isinstance(v, bool) else f"{v!r}" for v in values)


def _length(axis: Any) -> int:
    if isinstance(axis, ValuesEntry):
        return len(axis.values)
    if isinstance(axis, (LinspaceEntry, LogspaceEntry)):
        return int((axis.linspace if isinstance(axis, LinspaceEntry) else axis.logspace)[2])
    return len(axis) if isinstance(axis, list) else 1


def make(table: GridTable, names: list[str]) -> Design:
    from .base import column_values
    axes = [np.asarray(column_values(table.parameters[name], name), dtype=float)
            for name in names]
    return Design("grid", names, axes=axes)


def metric_view(varying: int) -> str:
    """One varying column: lines; two: a heatmap per metric; more: a scatter matrix."""
    return {1: "lines", 2: "heatmap"}.get(varying, "scatter")


KIND = DesignKind("grid", GridTable, make=make, metric_view=metric_view)
