"""``lhs``: ``samples`` points of a seeded Latin hypercube over each parameter's ``range =
[low, high]`` (``log = true`` samples log-uniformly)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import Design, DesignKind, count_of, not_too_many, per_column, range_of


def make(names: list[str], params: dict[str, Any], d: dict[str, Any],
         seed: int | None) -> Design:
    bounds = per_column(names, lambda name: range_of(name, params[name], allow_log=True))
    n = count_of(d, "samples", "design.samples")
    not_too_many(n)
    from scipy.stats import qmc
    unit = qmc.LatinHypercube(d=len(names), seed=seed).random(n)
    rows = np.empty_like(unit)
    for j, (low, high, log) in enumerate(bounds):
        if log:
            rows[:, j] = np.exp(np.log(low) + unit[:, j] * (np.log(high) - np.log(low)))
        else:
            rows[:, j] = low + unit[:, j] * (high - low)
    return Design("lhs", names, stored=rows)


KIND = DesignKind("lhs", frozenset({"seed", "samples"}), needs_seed=True, make=make)
