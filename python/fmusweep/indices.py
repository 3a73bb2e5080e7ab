"""Sobol' and Morris indices of a finished sweep (SALib's estimators), per metric, with their
confidence intervals: how much of a metric's variance each design column explains. (The
FMU's own sensitivities, ∂y/∂p, are another thing: docs/sensitivities.md.)"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    import pandas as pd

    from .design import Design

__all__ = ["sobol_indices", "morris_effects", "analyse"]


def sobol_indices(problem: dict[str, Any], values: npt.ArrayLike, second_order: bool = False,
                  seed: int = 0) -> dict[str, Any]:
    """S1, ST and their 95 % confidence half-widths for one output over a Saltelli
    design (the rows in SALib's order)."""
    from SALib.analyze import sobol
    result = sobol.analyze(problem, np.asarray(values, dtype=float),
                           calc_second_order=second_order, seed=seed)
    keys = ["S1", "S1_conf", "ST", "ST_conf"]
    return {"method": "sobol", "names": list(problem["names"]),
            **{k: np.asarray(result[k]).tolist() for k in keys}}


def morris_effects(problem: dict[str, Any], rows: npt.ArrayLike, values: npt.ArrayLike,
                   levels: int = 4, seed: int = 0) -> dict[str, Any]:
    from SALib.analyze import morris
    result = morris.analyze(problem, np.asarray(rows, dtype=float),
                            np.asarray(values, dtype=float), num_levels=levels, seed=seed)
    keys = ["mu", "mu_star", "sigma", "mu_star_conf"]
    return {"method": "morris", "names": list(problem["names"]),
            **{k: np.asarray(result[k], dtype=float).tolist() for k in keys}}


def has_indices(design: Design) -> bool:
    """Whether the design is one whose points give sensitivity indices."""
    return design.kind in ("sobol", "morris")


def analyse(design: Design, points: pd.DataFrame, metric_names: list[str],
            seed: int) -> dict[str, Any]:
    """Indices for every metric of a sobol or morris design; a metric with failed points
    gets a note instead (the estimators need every point of the design)."""
    if not has_indices(design):
        return {}
    found: dict[str, Any] = {}
    for name in metric_names:
        values = points[name].to_numpy(dtype=float)
        failed = int(np.sum(~np.isfinite(values)))
        if failed:
            found[name] = {"method": design.kind,
                           "note": f"{failed} of {len(values)} points have no value; "
                                   "the indices need every point of the design"}
        elif design.problem is None:
            raise AssertionError("a sampled design keeps its SALib problem")
        elif design.kind == "sobol":
            found[name] = sobol_indices(design.problem, values, design.second_order, seed)
        else:
            found[name] = morris_effects(design.problem, design.rows, values, design.levels, seed)
    return found
