"""``lhs``: ``samples`` points of a seeded Latin hypercube over each parameter's ``range =
[low, high]`` (``log = true`` samples log-uniformly)."""

from __future__ import annotations

from typing import Literal

import numpy as np

from ..schema.core import Parts
from ..schema.core import field as declared
from .base import Design, DesignKind, SampledTable, LogRangeEntry


class LhsTable(SampledTable):
    about = "A seeded Latin hypercube over each column's range."
    kind: Literal["lhs"] = declared("the kind of design")
    samples: int = declared("the number of points", ge=1)
    parameters: dict[str, LogRangeEntry] = declared(
        "each column: range = [low, high], and log = true to sample log-uniformly",
        shows="table of name = { range, log }")

    @classmethod
    def count(cls, parts: Parts) -> int | None:
        samples = parts.get("samples")
        return samples if isinstance(samples, int) else None


def make(table: LhsTable, names: list[str]) -> Design:
    from scipy.stats import qmc
    unit = qmc.LatinHypercube(d=len(names), seed=table.seed).random(table.samples)
    rows = np.empty_like(unit)
    bounds = [(*table.parameters[name].range, table.parameters[name].log) for name in names]
    for j, (low, high, log) in enumerate(bounds):
        if log:
            rows[:, j] = np.exp(np.log(low) + unit[:, j] * (np.log(high) - np.log(low)))
        else:
            rows[:, j] = low + unit[:, j] * (high - low)
    return Design("lhs", names, stored=rows)


KIND = DesignKind("lhs", LhsTable, make=make)
