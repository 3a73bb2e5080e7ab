"""``morris``: Morris' elementary effects (SALib): ``trajectories`` = r gives r·(D + 1)
points on a grid of ``levels`` (default 4) over each parameter's ``range = [low, high]``; a
finished sweep gives each metric's μ, μ* and σ per parameter."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
import numpy.typing as npt

from ..records import Rows
from ..schema.core import Parts, checked
from ..schema.core import field as declared
from .base import Design, DesignKind, SampledTable, IndexChart, RangeEntry, salib_problem


def _even(levels: int) -> int:
    if levels % 2:
        raise ValueError(f"must be an even whole number ≥ 2, got {levels}")
    return levels


class MorrisTable(SampledTable):
    about = "Morris' trajectories for elementary effects, over each column's range."
    kind: Literal["morris"] = declared("the kind of design")
    trajectories: int = declared("r: r·(D + 1) points for D columns", ge=1)
    levels: Annotated[int, checked(_even)] = declared("the grid's levels, even", 4, ge=2)
    parameters: dict[str, RangeEntry] = declared("each column: range = [low, high]",
                                                 shows="table of name = { range }")

    @classmethod
    def count(cls, parts: Parts) -> int | None:
        r = parts.get("trajectories")
        return r * (len(parts.get("parameters")) + 1) if isinstance(r, int) else None


def make(table: MorrisTable, names: list[str]) -> Design:
    problem = salib_problem(names, table)
    from SALib.sample.morris import sample as morris_sample
    rows = morris_sample(problem, table.trajectories, num_levels=table.levels, seed=table.seed)
    return Design("morris", names, stored=np.asarray(rows, dtype=float), problem=problem,
                  levels=table.levels)


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


KIND = DesignKind("morris", MorrisTable, make=make, indices=indices, chart=chart)
