"""Pictures of a sweep, written next to its results, as its design's kind says: a metric
against its parameter (one varying parameter), heatmaps (a two-parameter grid),
metric-against-parameter scatter matrices (the other designs), and the indices of the
kinds that give them, as each kind's chart says (bars with confidence intervals, or
labelled points)."""

from __future__ import annotations

import pathlib
from typing import TYPE_CHECKING, Any

import numpy as np

from ..designs import kind_of
from .drawing import pyplot, save

if TYPE_CHECKING:
    import pandas as pd

    from ..designs import Design, IndexChart

__all__ = ["sweep_pictures"]


def _failed_note(points: pd.DataFrame) -> str:
    failed = int((points["status"] != "ok").sum())
    return f" ({failed} of {len(points)} points failed)" if failed else ""


def sweep_pictures(design: Design, points: pd.DataFrame, metric_names: list[str],
                   charts: list[IndexChart], out: pathlib.Path) -> list[pathlib.Path]:
    """The metrics against the design's columns as its kind draws them, and each chart of
    its indices."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    varying = [n for n in design.names if points[n].nunique() > 1]
    view = kind_of(design.kind).metric_view(len(varying)) if varying else "none"
    written = []
    if view == "lines":
        written.append(_lines(points, varying[0], metric_names, out / "metrics.png"))
    elif view == "heatmap":
        written += [_heatmap(points, varying, m, out / f"heatmap_{m}.png") for m in metric_names]
    elif view == "scatter":
        written.append(_scatter_matrix(points, varying, metric_names, out / "scatter.png"))
    written += [_index_chart(chart, out / f"{design.kind}_{chart.metric}.png")
                for chart in charts]
    return written


def _spans_decades(values: Any) -> bool:
    """Positive values over more than three decades: a log axis shows them all."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return len(v) > 1 and v.min() > 0 and v.max() / v.min() > 1e3


def _lines(points: pd.DataFrame, name: str, metrics: list[str],
           path: pathlib.Path) -> pathlib.Path:
    plt = pyplot()
    fig, axes = plt.subplots(len(metrics), 1, figsize=(7, 2.6 * len(metrics)), sharex=True,
                             squeeze=False)
    ordered = points.sort_values(name)
    for ax, metric in zip(axes[:, 0], metrics):
        ax.plot(ordered[name], ordered[metric], marker=".", lw=1)
        ax.set_ylabel(metric)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel(name)
    fig.suptitle(f"Metrics against {name}{_failed_note(points)}")
    return save(fig, path)


def _cell_edges(values: np.ndarray) -> tuple[np.ndarray, bool]:
    """The edges of the cells around a grid axis's sorted values, and whether the axis is
    drawn in log scale (values positive and evenly spaced in log, as ``logspace`` makes
    them): each edge halfway between neighbours, in log or linear terms."""
    if len(values) == 1:
        return np.array([values[0] - 0.5, values[0] + 0.5]), False
    ratios = values[1:] / values[:-1] if (values > 0).all() else np.array([np.nan])
    log = len(values) > 2 and bool(np.allclose(ratios, ratios[0], rtol=1e-6)) and ratios[0] > 1.5
    axis = np.log(values) if log else values
    middles = 0.5 * (axis[1:] + axis[:-1])
    edges = np.concatenate([[2 * axis[0] - middles[0]], middles, [2 * axis[-1] - middles[-1]]])
    return (np.exp(edges) if log else edges), log


def _heatmap(points: pd.DataFrame, names: list[str], metric: str,
             path: pathlib.Path) -> pathlib.Path:
    plt = pyplot()
    x_name, y_name = names
    table = points.pivot_table(index=y_name, columns=x_name, values=metric, aggfunc="first",
                               dropna=False)
    (x_edges, x_log), (y_edges, y_log) = (_cell_edges(table.columns.to_numpy(float)),
                                          _cell_edges(table.index.to_numpy(float)))
    fig, ax = plt.subplots(figsize=(7, 5.5))
    mesh = ax.pcolormesh(x_edges, y_edges, np.ma.masked_invalid(table.to_numpy(float)),
                         shading="flat", cmap="viridis")
    if x_log:
        ax.set_xscale("log")
    if y_log:
        ax.set_yscale("log")
    ax.set_facecolor("0.75")  # failed points show grey
    fig.colorbar(mesh, ax=ax, label=metric)
    ax.set_xlabel(x_name)
    ax.set_ylabel(y_name)
    ax.set_title(f"{metric} over {x_name} × {y_name}{_failed_note(points)}")
    return save(fig, path)


def marker_for(count: int) -> tuple[float, float]:
    """A scatter's marker area (points²) and opacity: small and light where thousands of
    points overlap, large and solid where a few must stay visible."""
    if count > 2000:
        return 4.0, 0.5
    if count > 200:
        return 10.0, 0.7
    return 30.0, 0.9


def _scatter_matrix(points: pd.DataFrame, names: list[str], metrics: list[str],
                    path: pathlib.Path) -> pathlib.Path:
    plt = pyplot()
    fig, axes = plt.subplots(len(metrics), len(names), figsize=(2.6 * len(names) + 1, 2.4 * len(metrics) + 0.8),
                             squeeze=False, sharey="row")
    ok = points[points["status"] == "ok"]
    size, alpha = marker_for(len(ok))
    for i, metric in enumerate(metrics):
        for j, name in enumerate(names):
            ax = axes[i, j]
            ax.scatter(ok[name], ok[metric], s=size, alpha=alpha, lw=0)
            ax.grid(alpha=0.3)
            if _spans_decades(ok[metric]):
                ax.set_yscale("log")
            if i == len(metrics) - 1:
                ax.set_xlabel(name)
            if j == 0:
                ax.set_ylabel(metric)
    fig.suptitle(f"Each metric against each parameter{_failed_note(points)}")
    return save(fig, path)


def _index_chart(chart: IndexChart, path: pathlib.Path) -> pathlib.Path:
    """A kind's indices of one metric: grouped bars with their half-widths, or labelled
    points."""
    plt = pyplot()
    names = chart.names
    if chart.style == "bars":
        x = np.arange(len(names))
        width = 0.8 / len(chart.series)
        fig, ax = plt.subplots(figsize=(1.1 * len(names) + 3, 4))
        for k, (label, values) in enumerate(chart.series.items()):
            offset = (k - (len(chart.series) - 1) / 2) * width
            ax.bar(x + offset, values, width, yerr=chart.errors.get(label), capsize=3,
                   label=label)
        ax.set_xticks(x, names)
        ax.axhline(0, color="k", lw=0.6)
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0))
        ax.grid(axis="y", alpha=0.3)
    else:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        ax.scatter(chart.series["x"], chart.series["y"])
        for name, at_x, at_y in zip(names, chart.series["x"], chart.series["y"]):
            ax.annotate(name, (at_x, at_y), textcoords="offset points", xytext=(4, 4))
        ax.grid(alpha=0.3)
    ax.set_xlabel(chart.axes[0])
    ax.set_ylabel(chart.axes[1])
    ax.set_title(chart.title)
    return save(fig, path)
