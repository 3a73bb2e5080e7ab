"""What a sweep of steady cycles shows beside its metrics, computed once for its pictures
and its report alike: the Floquet multipliers of every point, the Campbell diagram's
modes against the cycle's frequency with the order lines and where they cross, and one
cycle of the kept variables of a few points."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["Campbell", "campbell", "multipliers", "cycles_of", "has_cycles"]

# The most order lines drawn, and the points whose kept cycle is drawn.
MOST_ORDERS = 12
DRAWN_CYCLES = 8


def has_cycles(points: pd.DataFrame) -> bool:
    return "cycle_period" in points.columns and bool(points["cycle_period"].notna().any())


def multipliers(points: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every multiplier of every point with a cycle (real parts, imaginary parts) and the
    point each belongs to."""
    ok = points[points["cycle_period"].notna()]
    re = [np.asarray(v, dtype=float) for v in ok["cycle_multipliers_re"]]
    im = [np.asarray(v, dtype=float) for v in ok["cycle_multipliers_im"]]
    which = [np.full(len(v), p) for v, p in zip(re, ok["point"])]
    if not re:
        return np.empty(0), np.empty(0), np.empty(0)
    return np.concatenate(re), np.concatenate(im), np.concatenate(which)


@dataclass(frozen=True)
class Campbell:
    """Mode frequencies (Hz) against the cycle's frequency (Hz), a column per mode, the
    order lines' orders, and their crossings: (cycle frequency, mode frequency, order)."""
    cycle_hz: np.ndarray
    modes_hz: np.ndarray
    points: np.ndarray
    orders: list[int]
    crossings: list[tuple[float, float, int]]


def campbell(points: pd.DataFrame) -> Campbell | None:
    """The Campbell diagram of the points whose cycles have modes (None without any):
    where a mode's frequency, fitted as a smooth function of the cycle's frequency (a
    polynomial of degree up to 2), meets k times the cycle's frequency."""
    ok = points[points["cycle_period"].notna()]
    if "cycle_modes_hz" not in ok.columns:
        return None
    modes = [np.asarray(m, dtype=float) for m in ok["cycle_modes_hz"] if m is not None]
    count = min((len(m) for m in modes), default=0)
    if count == 0:
        return None
    cycle_hz = 1.0 / ok["cycle_period"].to_numpy(dtype=float)
    table = np.array([np.asarray(m, dtype=float)[:count] for m in ok["cycle_modes_hz"]])
    top = float(np.nanmax(table))
    lowest = float(cycle_hz.min())
    orders = list(range(1, min(MOST_ORDERS, int(top / lowest) + 1) + 1))
    crossings = []
    low, high = float(cycle_hz.min()), float(cycle_hz.max())
    if high > low:
        degree = min(2, len(np.unique(cycle_hz)) - 1)
        for m in range(count):
            fit = np.polyfit(cycle_hz, table[:, m], degree)
            for k in orders:
                gap = fit.copy()
                gap[-2] -= k  # the mode's fit less k times the cycle's frequency
                for root in np.roots(gap):
                    if abs(root.imag) < 1e-9 and low <= root.real <= high:
                        crossings.append((float(root.real), float(np.polyval(fit, root.real)), k))
    return Campbell(cycle_hz, table, ok["point"].to_numpy(), orders, sorted(crossings))


def cycles_of(points: pd.DataFrame, series: pd.DataFrame | None,
              cyclic: list[str], kept: list[str]) -> dict[int, pd.DataFrame]:
    """One cycle of the kept variables for up to DRAWN_CYCLES points spread over the
    sweep: {point: its rows (variable, time into the cycle, value)}, the variables in the
    order `kept` names them, the `cyclic` ones (which advance by a period each cycle, from
    a whole number of periods) from their value at the cycle's start."""
    if series is None or series.empty:
        return {}
    order = {name: k for k, name in enumerate(kept)}
    with_series = np.sort(series["point"].unique())
    spread = np.linspace(0, len(with_series) - 1, min(DRAWN_CYCLES, len(with_series)))
    chosen = with_series[np.unique(spread.round().astype(int))]
    drawn = {}
    for p in chosen:
        rows = series[series["point"] == p].copy()
        rows["order"] = rows["variable"].map(lambda v: order.get(v, len(order)))
        rows = rows.sort_values(["order", "variable", "time"]).drop(columns="order")
        for name in cyclic:
            at = rows["variable"] == name
            if at.any():
                rows.loc[at, "value"] -= rows.loc[at, "value"].iloc[0]
        drawn[int(p)] = rows
    return drawn
