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

__all__ = ["Campbell", "Slice", "campbell", "multipliers", "cycles_of", "has_cycles"]

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
class Slice:
    """One curve of a Campbell diagram: the points whose other design parameters take one
    set of values (`label` names them; empty where nothing else varies), their cycles'
    frequencies and mode frequencies (Hz, a column per mode), and where an order line
    meets a mode: (cycle frequency, mode frequency, order)."""
    label: str
    cycle_hz: np.ndarray
    modes_hz: np.ndarray
    points: np.ndarray
    crossings: list[tuple[float, float, int]]


@dataclass(frozen=True)
class Campbell:
    """Mode frequencies against the cycle's frequency along one design parameter (`along`,
    None where the design varies none), a slice per set of values of the others (at most
    MOST_SLICES of them drawn), the order lines' orders, and what the caption says: which
    slices are drawn, or why there is no diagram (then no slice)."""
    along: str | None
    slices: list[Slice]
    orders: list[int]
    caption: str


# The most slices one diagram draws (spread over them where there are more).
MOST_SLICES = 8


def _ordered_by(ok: pd.DataFrame, name: str, others: list[str]) -> float | None:
    """How far the cycle's frequency moves along `name` within each slice of the `others`
    (its relative span, the smallest over the slices), where it moves one way along it in
    every slice of two points or more; None where it does not."""
    spans = []
    groups = ok.groupby(others, sort=True) if others else [((), ok)]
    for _, group in groups:
        if len(group) < 2:
            continue
        ordered = group.sort_values(name)
        if ordered[name].duplicated().any():
            return None
        hz = ordered["cycle_hz"].to_numpy()
        steps = np.diff(hz)
        if not (np.all(steps > 0) or np.all(steps < 0)):
            return None
        spans.append(float(np.ptp(hz) / np.mean(np.abs(hz))))
    return min(spans) if spans else None


def _crossings(cycle_hz: np.ndarray, table: np.ndarray,
               orders: list[int]) -> list[tuple[float, float, int]]:
    """Where each mode's frequency, fitted as a smooth function of the cycle's frequency (a
    polynomial of degree up to 2), meets k times the cycle's frequency."""
    low, high = float(cycle_hz.min()), float(cycle_hz.max())
    if not high > low:
        return []
    degree = min(2, len(np.unique(cycle_hz)) - 1)
    found = []
    for m in range(table.shape[1]):
        fit = np.polyfit(cycle_hz, table[:, m], degree)
        for k in orders:
            gap = fit.copy()
            gap[-2] -= k  # the mode's fit less k times the cycle's frequency
            for root in np.roots(gap):
                if abs(root.imag) < 1e-9 and low <= root.real <= high:
                    found.append((float(root.real), float(np.polyval(fit, root.real)), k))
    return sorted(found)


def campbell(points: pd.DataFrame, names: list[str]) -> Campbell | None:
    """The Campbell diagram of the points whose cycles have modes (None without any): a
    function of one speed-like parameter, so one curve per slice of the design's other
    parameters, along the one that orders the cycles' frequencies in every slice (of the
    several that do, the one that moves them most); no slice where none does."""
    ok = points[points["cycle_period"].notna()].copy()
    if "cycle_modes_hz" not in ok.columns or ok.empty:
        return None
    modes = [np.asarray(m, dtype=float) for m in ok["cycle_modes_hz"] if m is not None]
    count = min((len(m) for m in modes), default=0)
    if count == 0:
        return None
    ok["cycle_hz"] = 1.0 / ok["cycle_period"].to_numpy(dtype=float)
    table = np.array([np.asarray(m, dtype=float)[:count] for m in ok["cycle_modes_hz"]])
    top, lowest = float(np.nanmax(table)), float(ok["cycle_hz"].min())
    orders = list(range(1, min(MOST_ORDERS, int(top / lowest) + 1) + 1))
    varying = [n for n in names if n in ok.columns and ok[n].nunique() > 1]
    if not varying:
        return Campbell(None, [Slice("", ok["cycle_hz"].to_numpy(), table,
                                     ok["point"].to_numpy(),
                                     _crossings(ok["cycle_hz"].to_numpy(), table, orders))],
                        orders, "one design point")
    spans = {n: _ordered_by(ok, n, [o for o in varying if o != n]) for n in varying}
    ordering = {n: span for n, span in spans.items() if span is not None}
    if not ordering:
        return Campbell(None, [], orders,
                        f"no design parameter ({', '.join(varying)}) moves the cycle's "
                        "frequency one way in every slice of the others: a Campbell diagram "
                        "needs one, so none is drawn")
    along = max(ordering, key=lambda n: ordering[n])
    others = [o for o in varying if o != along]
    slices = []
    groups = ok.groupby(others, sort=True) if others else [((), ok)]
    for key, group in groups:
        values = key if isinstance(key, tuple) else (key,)
        label = ", ".join(f"{o} = {v:g}" for o, v in zip(others, values))
        rows = group.sort_values("cycle_hz")
        at = ok.index.get_indexer(rows.index)
        hz = rows["cycle_hz"].to_numpy()
        slices.append(Slice(label, hz, table[at], rows["point"].to_numpy(),
                            _crossings(hz, table[at], orders)))
    drawn = slices
    if len(slices) > MOST_SLICES:
        picks = np.unique(np.linspace(0, len(slices) - 1, MOST_SLICES).round().astype(int))
        drawn = [slices[i] for i in picks]
    caption = (f"along {along}" if not others else
               f"along {along}, one curve per {', '.join(others)}"
               + (f" ({len(drawn)} of {len(slices)} slices, spread over them)"
                  if len(drawn) < len(slices) else ""))
    return Campbell(along, drawn, orders, caption)


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
