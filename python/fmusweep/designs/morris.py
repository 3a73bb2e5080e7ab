"""``morris``: Morris' elementary effects (SALib): ``trajectories`` = r gives r·(D + 1)
points on a grid of ``levels`` (default 4) over each parameter's ``range = [low, high]``; a
finished sweep gives each metric's μ, μ* and σ per parameter."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import SpecError
from ..records import Rows
from .base import Design, DesignKind, IndexChart, count_of, not_too_many, salib_problem


def make(names: list[str], params: dict[str, Any], d: dict[str, Any],
         seed: int | None) -> Design:
    problem = salib_problem(names, params)
    r = count_of(d, "trajectories", "design.trajectories")
    levels = d.get("levels", 4)
    if not isinstance(levels, int) or isinstance(levels, bool) or levels < 2 or levels % 2:
        raise SpecError("design.levels", f"must be an even whole number ≥ 2, got {levels!r}")
    not_too_many(r * (len(names) + 1))
    from SALib.sample.morris import sample as morris_sample
    rows = morris_sample(problem, r, num_levels=levels, seed=seed)
    return Design("morris", names, stored=np.asarray(rows, dtype=float), problem=problem,
                  levels=levels)


def morris_effects(problem: dict[str, Any], rows: npt.ArrayLike, values: npt.ArrayLike,
                   levels: int = 4, seed: int = 0) -> dict[str, Any]:
    """μ, μ*, σ and μ*'s confidence half-width for one output over Morris' trajectories."""
    from SALib.analyze import morris
    result = morris.analyze(problem, np.asarray(rows, dtype=float),
                            np.asarray(values, dtype=float), num_levels=levels, seed=seed)
    keys = ["mu", "mu_star", "sigma", "mu_star_conf"]
    return {"method": "morris", "names": list(problem["names"]),
            **{k: np.asarray(result[k], dtype=float).tolist() for k in keys}}


def indices(design: Design, values: Rows, seed: int) -> dict[str, Any]:
    assert design.problem is not None, "a Morris design keeps its SALib problem"
    return morris_effects(design.problem, design.rows, values, design.levels, seed)


def chart(metric: str, found: dict[str, Any]) -> IndexChart:
    return IndexChart("points", metric, f"Morris screening of {metric}", found["names"],
                      {"x": found["mu_star"], "y": found["sigma"]},
                      axes=("μ* (mean |elementary effect|)",
                            "σ (spread: interaction or nonlinearity)"))


KIND = DesignKind("morris", frozenset({"seed", "trajectories", "levels"}), needs_seed=True,
                  make=make, indices=indices, chart=chart)
