"""A finished (or partly finished) sweep as a user reads it."""

from __future__ import annotations

import json
import os
import pathlib
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from .store import ResultStore

__all__ = ["Results", "SweepSummary", "load_results"]


@dataclass
class SweepSummary:
    """What a run did: counts, times and where the results are."""
    out: str
    points: int
    computed: int
    resumed: int
    batch_size: int
    batches: int
    workers: int
    engine: str
    wall_s: float
    point_seconds: float  # the sum of the points' own wall times
    startup_s: float = 0.0  # connecting to (or starting) the cluster, shipping the FMU
    dispatch_s: float = 0.0  # from the first task submitted to the last batch saved
    statuses: dict[str, int] = field(default_factory=dict)
    # Finished batches whose results the Dask scheduler still held in memory when the last
    # batch was saved (its own accounting; 0: nothing of them stays on the workers). None
    # when the sweep ran without Dask.
    held_results: int | None = None
    # How the engine was chosen: "as asked", or the measurement that chose it.
    engine_choice: str = "as asked"


class Results:
    """``points``: one row per point (parameters, status, message, metrics, t_end, steps,
    wall_s, worker); ``series()``: the time series in long form; ``meta``: what
    ``sweep.json`` records; ``summary``: counts and times of the run that returned it;
    ``sensitivity``: indices per metric for sobol and morris designs; ``plots`` and
    ``report_html``: the pictures and the interactive report, where written."""

    def __init__(self, out: str | os.PathLike[str], points: pd.DataFrame | None,
                 meta: dict[str, Any], summary: SweepSummary | None = None):
        self.out = pathlib.Path(out)
        self._points = points
        self.meta = meta
        self.summary = summary
        path = self.out / "sensitivity.json"
        self.sensitivity: dict[str, Any] = json.loads(path.read_text()) if path.exists() else {}
        self.plots: list[pathlib.Path] = sorted((self.out / "plots").glob("*.png"))
        found = self.out / "report.html"
        self.report_html: pathlib.Path | None = found if found.exists() else None

    @property
    def points(self) -> pd.DataFrame:
        """Every point, read from points.parquet on first use (a sweep's client holds none
        of them until then)."""
        if self._points is None:
            self._points = pd.read_parquet(self.out / "points.parquet")
        return self._points

    def series(self) -> pd.DataFrame | None:
        """Columns point, variable, time, value; None when the sweep kept no series."""
        table = ResultStore.series_table_of(self.out)
        return None if table is None else table.to_pandas()

    def ok(self) -> pd.DataFrame:
        return self.points[self.points["status"] == "ok"]

    @property
    def notes(self) -> list[str]:
        """What the analysis could not do, per metric (indices that failed points rule out)."""
        return [f"{name}: {found['note']}" for name, found in self.sensitivity.items()
                if "note" in found]

    def __repr__(self) -> str:
        counts = self.points["status"].value_counts().to_dict()
        return f"Results({str(self.out)!r}, points={len(self.points)}, status={counts})"


def load_results(out: str | os.PathLike[str]) -> Results:
    """The results in an output directory, as far as they go (finished or not)."""
    out = pathlib.Path(out)
    meta = json.loads((out / "sweep.json").read_text())
    table = ResultStore.points_table_of(out)
    return Results(out, table.to_pandas(), meta)
