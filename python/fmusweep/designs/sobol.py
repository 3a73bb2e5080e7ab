"""``sobol``: Saltelli's design for Sobol' indices (SALib): ``samples`` = N, a power of two,
gives N·(D + 2) points (N·(2D + 2) with ``second_order = true``), over each parameter's
``range = [low, high]``; a finished sweep gives each metric's first-order and total
indices, S1 and ST, with their 95 % confidence half-widths."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
import numpy.typing as npt

from ..records import Rows
from ..schema.core import Parts, checked
from ..schema.core import field as declared
from .base import Design, DesignKind, SampledTable, IndexChart, RangeEntry, salib_problem


def _power_of_two(n: int) -> int:
    if n & (n - 1):
        raise ValueError(f"a Sobol' design needs a power of two, got {n}")
    return n


class SobolTable(SampledTable):
    about = "Saltelli's design for Sobol' indices, over each column's range."
    kind: Literal["sobol"] = declared("the kind of design")
    samples: Annotated[int, checked(_power_of_two)] = declared(
        "N, a power of two: N·(D + 2) points for D columns", ge=1)
    second_order: bool = declared("second-order indices too: N·(2D + 2) points", False)
    parameters: dict[str, RangeEntry] = declared("each column: range = [low, high]",
                                                 shows="table of name = { range }")

    @classmethod
    def count(cls, parts: Parts) -> int | None:
        n, d = parts.get("samples"), len(parts.get("parameters"))
        if not isinstance(n, int):
            return None
        return n * (2 * d + 2 if parts.get("second_order") else d + 2)


def make(table: SobolTable, names: list[str]) -> Design:
    problem = salib_problem(names, table)
    from SALib.sample import sobol
    rows = sobol.sample(problem, table.samples, calc_second_order=table.second_order,
                        seed=table.seed)
    return Design("sobol", names, stored=np.asarray(rows, dtype=float), problem=problem,
                  second_order=table.second_order)


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


KIND = DesignKind("sobol", SobolTable, make=make, indices=indices, chart=chart)
