"""``grid``: each parameter takes ``values = [...]``, ``linspace = [start, stop, count]`` or
``logspace = [start, stop, count]`` (the values themselves, evenly spaced in log: ``[0.01,
10, 4]`` gives 0.01, 0.1, 1, 10); the points are the full-factorial product, the first
parameter varying slowest. Only the axes are kept: a point's values are made from its
index."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .base import Design, DesignKind, axis_of, not_too_many, per_column


def make(names: list[str], params: dict[str, Any], d: dict[str, Any],
         seed: int | None) -> Design:
    axes = per_column(names, lambda name: axis_of(name, params[name]))
    not_too_many(math.prod(len(a) for a in axes))
    return Design("grid", names, axes=[np.asarray(a, dtype=float) for a in axes])


def metric_view(varying: int) -> str:
    """One varying column: lines; two: a heatmap per metric; more: a scatter matrix."""
    return {1: "lines", 2: "heatmap"}.get(varying, "scatter")


KIND = DesignKind("grid", frozenset(), needs_seed=False, make=make, metric_view=metric_view)
