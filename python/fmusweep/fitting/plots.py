"""Pictures of a fit: measured against fitted per output, the residuals over time, and
the parameters' correlation matrix."""

from __future__ import annotations

import pathlib
from typing import TYPE_CHECKING, Any

import numpy as np

from ..plots import _pyplot, _save
from ..records import Rows

if TYPE_CHECKING:
    from .problem import Evaluation
    from .spec import FitSpec

__all__ = ["plot_fit"]


def plot_fit(spec: FitSpec, best: Evaluation, summary: dict[str, Any],
             out: pathlib.Path) -> list[pathlib.Path]:
    assert best.predictions is not None, "plotted only after a run that reached its end"
    out.mkdir(parents=True, exist_ok=True)
    written = [_trajectories(spec, best.predictions, summary, out / "fit_trajectories.png"),
               _residuals(spec, best.predictions, out / "fit_residuals.png")]
    if len(spec.names) > 1:
        written.append(_correlation(spec, summary, out / "fit_correlation.png"))
    return written


def _estimates_text(summary: dict[str, Any]) -> str:
    parts = []
    for name, p in summary["parameters"].items():
        low, high = p["ci95"]
        half = None if low is None or high is None else (high - low) / 2
        parts.append(f"{name} = {p['estimate']:.5g}" + (f" ± {half:.2g}" if half is not None else ""))
    return ", ".join(parts)


def _trajectories(spec: FitSpec, predictions: Rows, summary: dict[str, Any],
                  path: pathlib.Path) -> pathlib.Path:
    plt = _pyplot()
    data = spec.data
    n = len(data.columns)
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.6 * n + 0.6), sharex=True, squeeze=False)
    for j, (ax, name) in enumerate(zip(axes[:, 0], data.columns)):
        ax.plot(data.times, predictions[:, j], "-", lw=1.0, color="C0", label="fitted")
        ax.plot(data.times, data.values[:, j], ".", ms=2.0, color="0.25", label="measured")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(f"Measured and fitted (95 % intervals): {_estimates_text(summary)}", fontsize=9)
    return _save(fig, path)


def _residuals(spec: FitSpec, predictions: Rows, path: pathlib.Path) -> pathlib.Path:
    plt = _pyplot()
    data = spec.data
    n = len(data.columns)
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.2 * n + 0.6), sharex=True, squeeze=False)
    for j, (ax, name) in enumerate(zip(axes[:, 0], data.columns)):
        r = predictions[:, j] - data.values[:, j]
        ax.plot(data.times, r, ".", ms=2.5, color="C3")
        ax.axhline(0.0, color="0.2", lw=0.8)
        if data.sigma_given[j]:
            for sign in (-1, 1):
                ax.axhline(sign * 2 * data.sigma[j], color="0.5", lw=0.8, ls="--")
        ax.set_ylabel(f"{name}: fitted − measured", fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("Residuals (dashed: ± 2 σ where σ is given)", fontsize=9)
    return _save(fig, path)


def _correlation(spec: FitSpec, summary: dict[str, Any], path: pathlib.Path) -> pathlib.Path:
    plt = _pyplot()
    names = spec.names
    p = len(names)
    matrix = np.eye(p)
    for i, a in enumerate(names):
        for j, b in enumerate(names):
            if i != j:
                value = summary["correlation"][a][b]
                matrix[i, j] = np.nan if value is None else value
    fig, ax = plt.subplots(figsize=(1.3 * p + 2.5, 1.1 * p + 1.8))
    image = ax.imshow(matrix, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(p), names)
    ax.set_yticks(range(p), names)
    for i in range(p):
        for j in range(p):
            text = "n/a" if np.isnan(matrix[i, j]) else f"{matrix[i, j]:+.3f}"
            dark = not np.isnan(matrix[i, j]) and abs(matrix[i, j]) > 0.6
            ax.text(j, i, text, ha="center", va="center", fontsize=9,
                    color="white" if dark else "black")
    fig.colorbar(image, ax=ax, shrink=0.8)
    ax.set_title("Correlation of the estimates", fontsize=10)
    return _save(fig, path)
