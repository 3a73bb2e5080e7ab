"""Sobol' and Morris indices of a finished sweep, per metric, each kind's own (its module in
``designs``): how much of a metric's variance each design column explains. (The FMU's own
sensitivities, ∂y/∂p, are another thing: docs/sensitivities.md.)"""

from __future__ import annotations

import json
import pathlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from .designs import kind_of
from .designs.morris import morris_effects
from .designs.sobol import sobol_indices
from .store import atomic_write_text

if TYPE_CHECKING:
    import pandas as pd

    from .designs import Design, IndexChart

__all__ = ["sobol_indices", "morris_effects", "analyse", "has_indices", "charts", "write_indices"]


def has_indices(design: Design) -> bool:
    """Whether the design is one whose points give indices."""
    return kind_of(design.kind).indices is not None


def analyse(design: Design, points: pd.DataFrame, metric_names: list[str],
            seed: int) -> dict[str, Any]:
    """Indices for every metric of a design whose kind gives them; a metric with failed
    points gets a note instead (the estimators need every point of the design)."""
    estimate = kind_of(design.kind).indices
    if estimate is None:
        return {}
    found: dict[str, Any] = {}
    for name in metric_names:
        values = points[name].to_numpy(dtype=float)
        failed = int(np.sum(~np.isfinite(values)))
        if failed:
            found[name] = {"method": design.kind,
                           "note": f"{failed} of {len(values)} points have no value; "
                                   "the indices need every point of the design"}
        else:
            found[name] = estimate(design, values, seed)
    return found


def write_indices(design: Design, points: Callable[[], pd.DataFrame], metric_names: list[str],
                  seed: int, out: pathlib.Path) -> dict[str, Any]:
    """The indices of a finished sweep, written to ``out/sensitivity.json`` where its kind
    gives any: `points` is asked for only then (a grid of 10⁶ points is not loaded for no
    index)."""
    if not has_indices(design):
        return {}
    found = analyse(design, points(), metric_names, seed)
    if found:
        atomic_write_text(json.dumps(found, indent=2), out / "sensitivity.json")
    return found


def charts(kind: str, found: dict[str, Any]) -> list[IndexChart]:
    """How the indices `found` (by metric) of a `kind` design are drawn; none for a metric
    that has a note instead."""
    chart = kind_of(kind).chart
    if chart is None:
        return []
    return [chart(metric, indices) for metric, indices in found.items() if "names" in indices]
