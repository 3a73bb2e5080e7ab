"""Pictures of a fit: measured against fitted per output, the residuals over time, and
the parameters' correlation matrix."""

from __future__ import annotations

import pathlib
from typing import TYPE_CHECKING, Any

import numpy as np

from .drawing import pyplot, save
from ..records import Rows

if TYPE_CHECKING:
    from ..fitting.data import Data
    from ..fitting.problem import Evaluation
    from ..fitting.spec import FitSpec

__all__ = ["fit_pictures"]


def fit_pictures(spec: FitSpec, best: list[Evaluation], summary: dict[str, Any],
             out: pathlib.Path) -> list[pathlib.Path]:
    """The pictures of the best fit's runs (`best`, one per experiment): each experiment's
    own pair, named after it where there are several, and the correlation matrix."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    several = len(spec.experiments) > 1
    for experiment, run in zip(spec.experiments, best):
        assert run.predictions is not None, "plotted only after runs that reached their end"
        suffix = f"_{experiment.name}" if several else ""
        title = f"{experiment.name}: " if several else ""
        written += [_trajectories(experiment.data, run.predictions, summary, title,
                                  out / f"fit_trajectories{suffix}.png"),
                    _residuals(experiment.data, run.predictions, title,
                               out / f"fit_residuals{suffix}.png")]
    if len(spec.names) > 1:
        written.append(_correlation(spec, summary, out / "fit_correlation.png"))
    if summary.get("profiles"):
        written.append(_profiles(summary, out / "fit_profiles.png"))
    return written


def _estimates_text(summary: dict[str, Any]) -> str:
    parts = []
    for name, p in summary["parameters"].items():
        low, high = p["ci95"]
        half = None if low is None or high is None else (high - low) / 2
        parts.append(f"{name} = {p['estimate']:.5g}" + (f" ± {half:.2g}" if half is not None else ""))
    return ", ".join(parts)


def _trajectories(data: Data, predictions: Rows, summary: dict[str, Any], title: str,
                  path: pathlib.Path) -> pathlib.Path:
    plt = pyplot()
    n = len(data.columns)
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.6 * n + 0.6), sharex=True, squeeze=False)
    for j, (ax, name) in enumerate(zip(axes[:, 0], data.columns)):
        ax.plot(data.times, predictions[:, j], "-", lw=1.0, color="C0", label="fitted")
        ax.plot(data.times, data.values[:, j], ".", ms=2.0, color="0.25", label="measured")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(f"{title or 'M'}{'m' if title else ''}easured and fitted (95 % intervals): "
                 f"{_estimates_text(summary)}", fontsize=9, wrap=True)
    return save(fig, path)


def _residuals(data: Data, predictions: Rows, title: str, path: pathlib.Path) -> pathlib.Path:
    plt = pyplot()
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
    fig.suptitle(f"{title or 'R'}{'r' if title else ''}esiduals (dashed: ± 2 σ where σ is given)", fontsize=9)
    return save(fig, path)


def _correlation(spec: FitSpec, summary: dict[str, Any], path: pathlib.Path) -> pathlib.Path:
    plt = pyplot()
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
    long = max(len(n) for n in names) > 8  # an experiment's own parameter: turned, not overlapping
    ax.set_xticks(range(p), names, rotation=30 if long else 0, ha="right" if long else "center")
    ax.set_yticks(range(p), names)
    for i in range(p):
        for j in range(p):
            text = "n/a" if np.isnan(matrix[i, j]) else f"{matrix[i, j]:+.3f}"
            dark = not np.isnan(matrix[i, j]) and abs(matrix[i, j]) > 0.6
            ax.text(j, i, text, ha="center", va="center", fontsize=9,
                    color="white" if dark else "black")
    fig.colorbar(image, ax=ax, shrink=0.8)
    ax.set_title("Correlation of the estimates", fontsize=10)
    return save(fig, path)


def _profiles(summary: dict[str, Any], path: pathlib.Path) -> pathlib.Path:
    """Each profiled parameter's cost rise against its value, the 95 % threshold, and the
    two intervals: the profile's (where the curve crosses) and the Wald one."""
    plt = pyplot()
    profiles = summary["profiles"]
    n = len(profiles)
    columns = min(n, 3)
    rows = -(-n // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns + 0.6, 3.4 * rows + 0.4),
                             squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    for ax, (name, pr) in zip(axes.ravel(), profiles.items()):
        ax.xaxis.set_major_locator(plt.MaxNLocator(5))
        best = summary["cost"]
        values = np.array(pr["values"])
        rise = np.array([np.nan if c is None else c - best for c in pr["cost"]])
        limit = pr["threshold"] - best
        ax.plot(values, rise, "o-", ms=3, lw=1.0, color="C0", label="profile")
        ax.axhline(limit, color="0.3", lw=0.8, ls=":", label="95 % threshold")
        wald = summary["parameters"][name]["wald_ci95"]
        if wald[0] is not None and wald[1] is not None:
            ax.axvspan(wald[0], wald[1], color="C1", alpha=0.15, label="Wald 95 %")
        for k, bound in enumerate(b for b in pr["ci95"] if b is not None):
            ax.axvline(bound, color="C0", lw=1.0, ls="--", label=None if k else "profile 95 %")
        open_sides = [side for side, b in zip(("below", "above"), pr["ci95"]) if b is None]
        ax.set_title(name + (f" (open {' and '.join(open_sides)})" if open_sides else ""), fontsize=9)
        ax.set_xlabel(name)
        ax.set_ylim(bottom=min(0.0, float(np.nanmin(rise))) if np.isfinite(rise).any() else 0.0,
                    top=2.5 * limit)
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("cost − least cost")
    axes[0, 0].legend(loc="upper center", fontsize=7)
    fig.suptitle("Likelihood profiles: the other parameters re-optimised at each point", fontsize=9)
    return save(fig, path)
