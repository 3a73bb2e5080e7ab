"""``sobol``: Saltelli's design for Sobol' indices (SALib): ``samples`` = N, a power of two,
gives N·(D + 2) points (N·(2D + 2) with ``second_order = true``), over each parameter's
``range = [low, high]``; a finished sweep gives each metric's first-order and total
indices, S1 and ST, with their 95 % confidence half-widths."""

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
    n = count_of(d, "samples", "design.samples")
    if n & (n - 1):
        raise SpecError("design.samples", f"a Sobol' design needs a power of two, got {n}")
    second = d.get("second_order", False)
    if not isinstance(second, bool):
        raise SpecError("design.second_order", f"must be true or false, got {second!r}")
    not_too_many(n * (2 * len(names) + 2 if second else len(names) + 2))
    from SALib.sample import sobol
    rows = sobol.sample(problem, n, calc_second_order=second, seed=seed)
    return Design("sobol", names, stored=np.asarray(rows, dtype=float), problem=problem,
                  second_order=second)


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


def indices(design: Design, values: Rows, seed: int) -> dict[str, Any]:
    assert design.problem is not None, "a Sobol' design keeps its SALib problem"
    return sobol_indices(design.problem, values, design.second_order, seed)


def chart(metric: str, found: dict[str, Any]) -> IndexChart:
    return IndexChart("bars", metric, f"Sobol' indices of {metric} (bars: 95 % confidence)",
                      found["names"],
                      {"S1 (first order)": found["S1"], "ST (total)": found["ST"]},
                      {"S1 (first order)": found["S1_conf"], "ST (total)": found["ST_conf"]},
                      ("", "Sobol' index"))


KIND = DesignKind("sobol", frozenset({"seed", "samples", "second_order"}), needs_seed=True,
                  make=make, indices=indices, chart=chart)
