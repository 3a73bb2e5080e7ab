"""What a study shows, in one room: the pictures (``plots/``, PNG files drawn with
matplotlib, for documents and quick looks) and the interactive ``report.html`` (Plotly,
inlined), of a sweep and of a fit, started the same way by both at the end of their run:
``show_sweep`` and ``show_fit``."""

from __future__ import annotations

import pathlib
from typing import TYPE_CHECKING, Any

from ..indices import charts
from .campbell import has_cycles
from .cycle_pictures import cycle_pictures
from .fit_pictures import fit_pictures
from .report import first_series, fit_report, sweep_report
from .sweep_pictures import sweep_pictures

if TYPE_CHECKING:
    import pandas as pd

    from ..designs import Design
    from ..fitting.problem import Evaluation
    from ..fitting.spec import FitSpec

__all__ = ["show_sweep", "show_fit"]


def show_sweep(out: pathlib.Path, design: Design, points: pd.DataFrame, metrics: list[str],
               indices: dict[str, Any], cyclic: list[str] | None = None,
               kept: list[str] | None = None) -> tuple[list[pathlib.Path], pathlib.Path]:
    """A sweep's pictures and report, beside its results in `out`; `cyclic` names the
    variables a sweep of steady cycles advances by a period each cycle (drawn from 0),
    `kept` the variables it keeps over one cycle, in the order drawn (the first two make
    the phase portrait)."""
    drawn = charts(design.kind, indices)
    pictures = sweep_pictures(design, points, metrics, drawn, out / "plots")
    series = first_series(out, points)
    if has_cycles(points):
        pictures += cycle_pictures(points, series, design.names, cyclic or [], kept or [],
                                   out / "plots")
    report = sweep_report(out, design.names, points, metrics, drawn, series, cyclic=cyclic or [],
                          cycle_kept=kept or [])
    return pictures, report


def show_fit(out: pathlib.Path, spec: FitSpec, runs: list[Evaluation] | None,
             summary: dict[str, Any]) -> list[pathlib.Path]:
    """A fit's pictures (of its best runs, where they reached their end) and report."""
    pictures = fit_pictures(spec, runs, summary, out / "plots") if runs is not None else []
    fit_report(out, spec, runs, summary)
    return pictures
