"""Pictures of a sweep of steady cycles: the Floquet multipliers on the unit circle, the
Campbell diagram (mode frequencies against the cycle's frequency, the order lines of the
cycle's frequency and where they cross a mode), and one cycle of the kept variables of a
few points with the phase portrait of the first two."""

from __future__ import annotations

import pathlib
import textwrap
import warnings
from typing import TYPE_CHECKING

import numpy as np

from .campbell import campbell, cycles_of, multipliers
from .drawing import pyplot, save

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["cycle_pictures"]


def cycle_pictures(points: pd.DataFrame, series: pd.DataFrame | None, names: list[str],
                   cyclic: list[str], kept: list[str],
                   out: pathlib.Path) -> list[pathlib.Path]:
    """The pictures of a sweep of steady cycles over the design parameters `names`."""
    written = [_multipliers(points, out / "cycle_multipliers.png")]
    diagram = campbell(points, names)
    if diagram is not None and diagram.slices:
        written.append(_campbell(diagram, out / "campbell.png"))
    elif diagram is not None:
        warnings.warn(f"campbell.png: {diagram.caption}", stacklevel=2)
    drawn = cycles_of(points, series, cyclic, kept)
    if drawn:
        written.append(_cycles(drawn, out / "cycle.png"))
    return written


def _multipliers(points: pd.DataFrame, path: pathlib.Path) -> pathlib.Path:
    plt = pyplot()
    re, im, _ = multipliers(points)
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    turn = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(turn), np.sin(turn), color="0.5", lw=1, label="unit circle")
    ax.scatter(re, im, s=10, alpha=0.6, label="multipliers")
    ax.set_aspect("equal")
    ax.set_xlim(-1.1, 1.1)
    ax.set_ylim(-1.1, 1.1)
    ax.axhline(0, color="0.85", lw=0.8)
    ax.axvline(0, color="0.85", lw=0.8)
    ok = int(points["cycle_period"].notna().sum())
    largest = float(np.nanmax(np.hypot(re, im))) if len(re) else float("nan")
    ax.set_title(f"Floquet multipliers of {ok} cycles (largest |μ| = {largest:.4f})")
    ax.set_xlabel("Re μ")
    ax.set_ylabel("Im μ")
    ax.legend(loc="lower left", fontsize=8)
    return save(fig, path)


# The markers of a diagram's modes, in order.
MODE_MARKERS = "os^Dv"


def _campbell(diagram: object, path: pathlib.Path) -> pathlib.Path:
    from .campbell import Campbell
    assert isinstance(diagram, Campbell)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9.5, 5.5))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    right = max(float(s.cycle_hz.max()) for s in diagram.slices) * 1.05
    top = max(float(np.nanmax(s.modes_hz)) for s in diagram.slices) * 1.1
    for i, piece in enumerate(diagram.slices):
        colour = colours[i % len(colours)]
        for m in range(piece.modes_hz.shape[1]):
            ax.plot(piece.cycle_hz, piece.modes_hz[:, m], marker=MODE_MARKERS[m % 5], ms=3,
                    lw=0.8, color=colour, label=(piece.label or "modes") if m == 0 else None)
        if piece.crossings:
            x, y, _ = zip(*piece.crossings)
            ax.plot(x, y, "x", color=colour, ms=8, mew=2)
    span = np.array([0.0, right])
    for k in diagram.orders:
        ax.plot(span, k * span, color="0.6", lw=0.8, ls="--")
    _label_orders(ax, diagram.orders, right, top)
    ax.plot([], [], "x", color="0.3", ms=8, mew=2, label="an order line meets a mode")
    ax.set_xlim(0, right)
    ax.set_ylim(0, top)
    ax.set_xlabel("cycle frequency 1/T (Hz)" + (f", along {diagram.along}" if diagram.along
                                                 else ""))
    ax.set_ylabel("mode frequency (Hz), mean along the cycle")
    ax.set_title("\n".join(textwrap.wrap(f"Campbell diagram, {diagram.caption}", 100)),
                 fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0)
    return save(fig, path)


def _label_orders(ax: object, orders: list[int], right: float, top: float) -> None:
    """Each order line's label where it leaves the plot (the right edge, or the top), the
    labels along each edge kept apart (a label too close to the last one placed on its
    edge is left out: its line is the next one's neighbour)."""
    along_top: list[float] = []
    along_right: list[float] = []
    for k in orders:
        end = min(right, top / k)
        at_top = end < right
        placed, at, room = (along_top, end, 0.035 * right) if at_top else (
            along_right, k * end, 0.05 * top)
        if placed and abs(at - placed[-1]) < room:
            continue
        placed.append(at)
        ax.annotate(f"{k}×", (end, k * end), fontsize=7, color="0.4",  # type: ignore[attr-defined]
                    xytext=(2, -9) if at_top else (-14, 2), textcoords="offset points")


def _cycles(drawn: dict[int, pd.DataFrame], path: pathlib.Path) -> pathlib.Path:
    """One cycle of each kept variable against the time into it, a panel a variable, and
    beside them, where there are two or more, the phase portrait of the first two, as tall
    as the panels together."""
    plt = pyplot()
    variables = list(dict.fromkeys(v for rows in drawn.values() for v in rows["variable"]))
    portrait = len(variables) >= 2
    fig = plt.figure(figsize=(11 if portrait else 7, max(2.4 * len(variables), 3.6)))
    grid = fig.add_gridspec(len(variables), 2 if portrait else 1)
    left = [fig.add_subplot(grid[j, 0]) for j in range(len(variables))]
    phase = fig.add_subplot(grid[:, 1]) if portrait else None
    for point, rows in drawn.items():
        by = {v: rows[rows["variable"] == v].sort_values("time") for v in variables}
        for j, v in enumerate(variables):
            t = by[v]["time"].to_numpy()
            period = t[-1] + (t[1] - t[0]) if len(t) > 1 else 1.0
            left[j].plot(t / period, by[v]["value"], lw=1, label=f"point {point}")
            left[j].set_ylabel(v)
        if phase is not None:
            a, b = variables[:2]
            phase.plot(by[a]["value"], by[b]["value"], lw=1)
    left[-1].set_xlabel("time into the cycle / period")
    left[0].set_title("one cycle of the kept variables")
    left[0].legend(fontsize=7, ncol=2)
    if phase is not None:
        phase.set_xlabel(variables[0])
        phase.set_ylabel(variables[1])
        phase.set_title("phase portrait")
    return save(fig, path)
