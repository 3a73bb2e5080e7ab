"""An interactive report of a sweep or a fit: ``report.html`` beside ``points.parquet``, one
self-contained file (Plotly's JavaScript inlined, no network needed) that any browser
opens from disk.

A sweep's report: the design's points against each other, failed points marked with their
status and message; each metric against each varied parameter; hovering a point names it
(its number and id) and its parameter values; clicking it shows its time series where the
sweep kept series; Sobol' or Morris bars for a design that has them. A fit's report: the
estimates and both kinds of intervals, measured against fitted per output and experiment,
the residuals, the correlation matrix and the likelihood profiles.
"""

from __future__ import annotations

import html
import json
import math
import pathlib
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .campbell import Campbell, campbell, cycles_of, has_cycles, multipliers

if TYPE_CHECKING:
    from ..designs import IndexChart
    from ..fitting.problem import Evaluation
    from ..fitting.spec import FitSpec

__all__ = ["sweep_report", "fit_report", "first_series", "SERIES_POINTS", "SERIES_SAMPLES"]

# The time series a report embeds, at most: the points' whose series the sweep kept, the
# first this many (the Parquet store has them all), each thinned to this many samples.
SERIES_POINTS = 200
SERIES_SAMPLES = 1000
OK, FAILED = "#1f77b4", "#d62728"
# Markers as SVG up to this many in a trace, beyond it WebGL: SVG's cost grows with every
# marker, WebGL's mostly does not, but a browser without a GPU (a headless one, a remote
# desktop) starts WebGL in software, which a small trace does not repay.
WEBGL_ABOVE = 1000


def _scatter(n: int) -> str:
    return "scattergl" if n > WEBGL_ABOVE else "scatter"


def _page(title: str, intro: str, sections: list[str], script: str = "",
          eager: bool = False) -> str:
    """The page; its plots are drawn as they come near the window (``LAZY``), so that the
    first screen is drawn first, or all at once with `eager` (the report benchmark's
    comparison)."""
    from plotly.offline import get_plotlyjs
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            "<style>body{font-family:sans-serif;margin:1.5em;max-width:1400px}"
            "table{border-collapse:collapse;font-size:0.9em}td,th{border:1px solid #ccc;padding:2px 6px}"
            ".plot{width:100%;height:420px}.note{color:#555}</style>"
            f"<script>{get_plotlyjs()}</script><script>const EAGER={'true' if eager else 'false'};"
            f"{_LAZY_SCRIPT}</script></head><body>"
            f"<h1>{html.escape(title)}</h1><p>{intro}</p>{''.join(sections)}"
            f"<script>{script}</script></body></html>\n")


# A plot is drawn when it comes within a screen of the window, once; ON_DRAWN (the click
# handler, where a report has one) is then given it.
_LAZY_SCRIPT = """
function LAZY(id, draw){
  const gd = document.getElementById(id);
  const go = function(){ if(gd.dataset.drawn){return;} gd.dataset.drawn = '1'; draw();
    if(window.ON_DRAWN){ window.ON_DRAWN(gd); } };
  if(EAGER || !('IntersectionObserver' in window)){ go(); return; }
  const seen = new IntersectionObserver(function(entries){
    if(entries.some(function(e){ return e.isIntersecting; })){ seen.disconnect(); go(); }
  }, {rootMargin: '100% 0px'});
  seen.observe(gd);
}
"""


def _plot(div: str, data: list[dict[str, Any]], layout: dict[str, Any], height: int = 420) -> str:
    """A div and the script that draws it when it comes into view (the data as JSON, NaN
    as null)."""
    figure = json.dumps({"data": data, "layout": layout}, default=_json_default, allow_nan=False)
    return (f"<div id=\"{div}\" class=\"plot\" style=\"height:{height}px\"></div><script>"
            f"LAZY('{div}',function(){{const f={figure};{_LABEL_TRACES}Plotly.newPlot('{div}',"
            "f.data,f.layout,{responsive:true});});</script>")


# A sweep's hover labels are written once (LABELS, by point number) and given to each trace
# that names its points in customdata (a heatmap's row by row), rather than repeated in
# every plot's JSON.
_LABEL_TRACES = ("if(typeof LABELS!=='undefined')for(const t of f.data){if(t.labelled){"
                 "t.text=Array.from(t.customdata,p=>Array.isArray(p)?p.map(q=>LABELS[q]):LABELS[p]);"
                 "delete t.labelled;}}")


def _labels_script(points: pd.DataFrame, labels: list[str]) -> str:
    by_point = dict(zip((str(p) for p in points["point"]), labels))
    return f"<script>const LABELS={json.dumps(by_point)};</script>"


def _json_default(value: Any) -> Any:
    """numpy's arrays and numbers as JSON; a value that is not finite as null."""
    if isinstance(value, np.ndarray):
        return [None if isinstance(v, float) and not math.isfinite(v) else v for v in value.tolist()]
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    raise TypeError(f"not JSON: {type(value).__name__}")


def _hover(points: pd.DataFrame, names: list[str]) -> list[str]:
    """Each point's label: its number, id and parameter values, and why it failed."""
    labels = []
    for row in points[["point", "point_id", "status", "message", *names]].to_dict("records"):
        values = "<br>".join(f"{html.escape(n)} = {float(row[n]):.6g}" for n in names)
        label = f"point {row['point']} ({row['point_id']})<br>{values}"
        if row["status"] != "ok":
            label += f"<br><b>{html.escape(str(row['status']))}</b>: {html.escape(str(row['message']))[:200]}"
        labels.append(label)
    return labels


def sweep_report(out: pathlib.Path, names: list[str], points: pd.DataFrame, metrics: list[str],
                 charts: list[IndexChart], series: pd.DataFrame | None,
                 eager: bool = False, cyclic: list[str] | None = None,
                 cycle_kept: list[str] | None = None) -> pathlib.Path:
    """Write ``out/report.html`` for a sweep's points (parameters `names`), with the charts
    of its design's indices, and return it; `eager` draws every plot on opening instead of
    as it comes into view; a sweep of steady cycles draws its `cycle_kept` variables in
    that order."""
    points = points.sort_values("point").reset_index(drop=True)
    varied = [n for n in names if points[n].nunique() > 1] or names[:1]
    labels = _hover(points, names)
    failed = points["status"] != "ok"
    counts = points["status"].value_counts().to_dict()
    kept = _series_json(series, points) if series is not None else {}
    intro = (f"{_count(len(points), 'point')}: "
             + ", ".join(f"{v} {html.escape(k)}" for k, v in counts.items())
             + ". Hover a point for its number, id and values"
             + ("; click one to see its time series (kept for the first points of the sweep)."
                if kept else "."))
    grid = _grid_of(points, varied)
    sections = [_labels_script(points, labels), _design_section(points, varied, failed, grid)]
    for k, metric in enumerate(metrics):
        if grid is not None:
            sections.append(_heatmap_section(k, metric, points, varied, grid))
        sections.append(_metric_section(k, metric, points, varied, failed))
    sections += [_index_section(chart) for chart in charts]
    if has_cycles(points):
        sections += _cycle_sections(points, series, names, cyclic or [], cycle_kept or [])
    sections.append(_failed_table(points, names))
    if kept:
        sections.append("<h2>Time series of the chosen point</h2><p id=\"series-note\" class=\"note\">"
                        "Click a point above.</p><div id=\"series\" class=\"plot\"></div>")
    script = (f"const SERIES={json.dumps(kept, default=_json_default, allow_nan=False)};"
              + _CLICK_SCRIPT) if kept else ""
    path = out / "report.html"
    path.write_text(_page(f"Sweep {out.name}", intro, sections, script, eager))
    return path


def _cycle_sections(points: pd.DataFrame, series: pd.DataFrame | None, names: list[str],
                    cyclic: list[str], kept: list[str]) -> list[str]:
    """A sweep of steady cycles: the multipliers on the unit circle, the Campbell diagram
    and one cycle of the kept variables of a few points, with a phase portrait."""
    re, im, which = multipliers(points)
    turn = np.linspace(0, 2 * np.pi, 361)
    sections = ["<h2>Floquet multipliers</h2><p class=\"note\">Each cycle's multipliers "
                "(the flow's own, 1, left out): inside the unit circle the cycle is stable; "
                "the largest per point is the column cycle_multiplier.</p>" + _plot(
                    "cycle-multipliers",
                    [{"type": "scatter", "x": np.cos(turn), "y": np.sin(turn), "mode": "lines",
                      "name": "unit circle", "line": {"color": "#999"}},
                     {"type": _scatter(len(re)), "x": re, "y": im, "mode": "markers",
                      "name": "multipliers", "customdata": which, "labelled": True,
                      "hoverinfo": "text"}],
                    {"xaxis": {"title": {"text": "Re μ"}, "range": [-1.1, 1.1]},
                     "yaxis": {"title": {"text": "Im μ"}, "scaleanchor": "x"}}, 520)]
    diagram = campbell(points, names)
    if diagram is not None:
        sections.append(_campbell_section(diagram))
    drawn = cycles_of(points, series, cyclic, kept)
    if drawn:
        sections.append(_cycle_section(drawn))
    return sections


def _campbell_section(diagram: Campbell) -> str:
    """The Campbell diagram: a curve per slice of the design, each with its crossings; or,
    where no design parameter orders the cycles, why there is none."""
    head = "<h2>Campbell diagram</h2>"
    if not diagram.slices:
        return f"{head}<p class=\"note\">{html.escape(diagram.caption)}.</p>"
    right = max(float(s.cycle_hz.max()) for s in diagram.slices) * 1.05
    top = max(float(np.nanmax(s.modes_hz)) for s in diagram.slices) * 1.1
    data: list[dict[str, Any]] = []
    for i, piece in enumerate(diagram.slices):
        colour = _COLOURS[i % len(_COLOURS)]
        name = piece.label or "modes"
        for m in range(piece.modes_hz.shape[1]):
            data.append({"type": "scatter", "x": piece.cycle_hz, "y": piece.modes_hz[:, m],
                         "mode": "lines+markers", "name": name, "legendgroup": name,
                         "showlegend": m == 0, "line": {"color": colour, "width": 1},
                         "marker": {"size": 5}, "customdata": piece.points,
                         "labelled": True, "hoverinfo": "text"})
        if piece.crossings:
            data.append({"type": "scatter", "x": [c[0] for c in piece.crossings],
                         "y": [c[1] for c in piece.crossings], "mode": "markers",
                         "name": name, "legendgroup": name, "showlegend": False,
                         "text": [f"{name}: order {c[2]} meets a mode at {c[0]:.4g} Hz"
                                  for c in piece.crossings],
                         "marker": {"symbol": "x", "size": 11, "color": colour}})
    span = [0.0, right]
    data += [{"type": "scatter", "x": span, "y": [k * x for x in span], "mode": "lines",
              "name": "k × the cycle's frequency",
              "line": {"dash": "dash", "width": 1, "color": "#999"},
              "showlegend": k == 1, "hoverinfo": "skip"} for k in diagram.orders]
    axis = "cycle frequency 1/T (Hz)" + (f", along {diagram.along}" if diagram.along else "")
    return (f"{head}<p class=\"note\">{html.escape(diagram.caption[:1].upper() + diagram.caption[1:])}: the "
            "modes of the state equations linearised along each cycle (mean frequency), "
            "against the cycle's frequency; dashed, k times the cycle's frequency; crosses, "
            "where a harmonic of order k meets a mode in that slice (a resonance).</p>"
            + _plot("campbell", data,
                    {"xaxis": {"title": {"text": axis}, "range": span},
                     "yaxis": {"title": {"text": "mode frequency (Hz)"}, "range": [0, top]}},
                    520))


def _cycle_section(drawn: dict[int, pd.DataFrame]) -> str:
    variables = list(dict.fromkeys(v for rows in drawn.values() for v in rows["variable"]))
    lines, portrait = [], []
    for i, (point, rows) in enumerate(drawn.items()):
        by = {v: rows[rows["variable"] == v].sort_values("time") for v in variables}
        colour = _COLOURS[i % len(_COLOURS)]
        for j, v in enumerate(variables):
            t = by[v]["time"].to_numpy()
            period = t[-1] + (t[1] - t[0]) if len(t) > 1 else 1.0
            lines.append({"type": "scatter", "x": t / period, "y": by[v]["value"].to_numpy(),
                          "mode": "lines", "name": f"point {point}", "legendgroup": str(point),
                          "showlegend": j == 0, "line": {"color": colour},
                          "yaxis": "y" if j == 0 else f"y{j + 1}"})
        if len(variables) >= 2:
            portrait.append({"type": "scatter", "x": by[variables[0]]["value"].to_numpy(),
                             "y": by[variables[1]]["value"].to_numpy(), "mode": "lines",
                             "name": f"point {point}", "line": {"color": colour}})
    count = len(variables)
    layout: dict[str, Any] = {"xaxis": {"title": {"text": "time into the cycle / period"}},
                              "grid": {"rows": count, "columns": 1, "pattern": "coupled"}}
    for j, v in enumerate(variables):
        layout[f"yaxis{'' if j == 0 else j + 1}"] = {"title": {"text": v}}
    html_ = ("<h2>One cycle</h2><p class=\"note\">The kept variables over one cycle of "
             f"{len(drawn)} points spread over the sweep.</p>"
             + _plot("cycle-kept", lines, layout, 260 * count))
    if portrait:
        html_ += _plot("cycle-portrait", portrait,
                       {"title": {"text": "phase portrait"},
                        "xaxis": {"title": {"text": variables[0]}},
                        "yaxis": {"title": {"text": variables[1]}}}, 480)
    return html_


# Plotly's own colours, named so that a point keeps its colour over several plots.
_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
            "#7f7f7f", "#bcbd22", "#17becf"]


def _count(n: int, what: str) -> str:
    return f"{n} {what}" if n == 1 else f"{n} {what}s"


# Where a two-parameter grid's points lie: its axes' values and each point's cell.
Grid = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _grid_of(points: pd.DataFrame, varied: list[str]) -> Grid | None:
    """x values, y values and each point's column and row, when the points fill a grid of
    the two varied parameters, one point a cell; else None."""
    if len(varied) != 2:
        return None
    xs, ix = np.unique(points[varied[0]].to_numpy(), return_inverse=True)
    ys, iy = np.unique(points[varied[1]].to_numpy(), return_inverse=True)
    if len(xs) * len(ys) != len(points) or len(np.unique(iy * len(xs) + ix)) != len(points):
        return None
    return xs, ys, ix, iy


def _cells(grid: Grid, values: np.ndarray) -> list[list[Any]]:
    """`values` of the points laid out by cell, a row per y value (missing: None)."""
    xs, ys, ix, iy = grid
    z = np.full((len(ys), len(xs)), np.nan)
    z[iy, ix] = values
    return [[None if not math.isfinite(v) else v for v in row] for row in z.tolist()]


# A metric spanning this many decades or more is coloured (or drawn) on a log scale.
LOG_ABOVE_RATIO = 1e3


def _log_scale(values: np.ndarray) -> bool:
    finite = values[np.isfinite(values)]
    return bool(len(finite) and finite.min() > 0 and finite.max() >= LOG_ABOVE_RATIO * finite.min())


def _heatmap_section(k: int, metric: str, points: pd.DataFrame, varied: list[str],
                     grid: Grid) -> str:
    """A two-parameter grid's metric as a heatmap: failed points are grey cells, and a
    metric spanning three decades or more is coloured by its logarithm."""
    values = points[metric].to_numpy(dtype=float)
    log = _log_scale(values)
    shown = np.log10(np.where(values > 0, values, np.nan)) if log else values
    trace: dict[str, Any] = {
        "type": "heatmap", "x": grid[0], "y": grid[1], "z": _cells(grid, shown),
        "customdata": _cells(grid, points["point"].to_numpy(dtype=float)), "labelled": True,
        "hoverinfo": "text", "hoverongaps": True, "colorscale": "Viridis",
        "colorbar": {"title": {"text": metric}}}
    if log:
        decades = np.arange(math.floor(np.nanmin(shown)), math.ceil(np.nanmax(shown)) + 1)
        trace["colorbar"].update(tickvals=decades.tolist(), ticktext=[f"1e{d:d}" for d in decades])
    layout = {"title": {"text": metric + (" (log colour scale)" if log else "")},
              "xaxis": {"title": {"text": varied[0]}}, "yaxis": {"title": {"text": varied[1]}},
              "plot_bgcolor": FAILED_CELL}
    failed = bool((points["status"] != "ok").any())
    note = ("<p class=\"note\">Grey cells: failed points (hover one for why).</p>" if failed
            else "")
    return (f"<h2>{html.escape(metric)} over the grid</h2>{note}"
            + _plot(f"heatmap-{k}", [trace], layout))


FAILED_CELL = "#c8c8c8"


def _design_section(points: pd.DataFrame, varied: list[str], failed: pd.Series,
                    grid: Grid | None) -> str:
    if grid is not None:
        trace = {"type": "heatmap", "x": grid[0], "y": grid[1],
                 "z": _cells(grid, failed.to_numpy(dtype=float)), "zmin": 0, "zmax": 1,
                 "colorscale": [[0, "#c6dbef"], [1, FAILED]], "showscale": False,
                 "customdata": _cells(grid, points["point"].to_numpy(dtype=float)),
                 "labelled": True, "hoverinfo": "text"}
        grid_layout = {"xaxis": {"title": {"text": varied[0]}},
                       "yaxis": {"title": {"text": varied[1]}}}
        return ("<h2>The design</h2><p class=\"note\">A grid of "
                f"{len(grid[0])} × {len(grid[1])} points"
                f"{'; red cells failed' if failed.any() else ''}.</p>"
                + _plot("design", [trace], grid_layout, 420))
    groups = [("ok", ~failed, OK, "circle"), ("failed", failed, FAILED, "x")]
    if len(varied) <= 2:
        one = len(varied) == 1
        data = [{"type": _scatter(int(mask.sum())), "mode": "markers", "name": name,
                 "x": points.loc[mask, varied[0]].to_numpy(),
                 "y": np.zeros(int(mask.sum())) if one else points.loc[mask, varied[1]].to_numpy(),
                 "customdata": points.loc[mask, "point"].to_numpy(), "labelled": True,
                 "hoverinfo": "text", "marker": {"color": color, "symbol": symbol, "size": 7}}
                for name, mask, color, symbol in groups if mask.any()]
        layout = {"xaxis": {"title": {"text": varied[0]}}, "hovermode": "closest",
                  "yaxis": {"visible": False} if one else {"title": {"text": varied[1]}}}
        return "<h2>The design</h2>" + _plot("design", data, layout, 220 if one else 420)
    dimensions = [{"label": n, "values": points[n].to_numpy()} for n in varied]
    data = [{"type": "splom", "name": name, "dimensions": [dict(d, values=d["values"][mask.to_numpy()]) for d in dimensions],
             "customdata": points.loc[mask, "point"].to_numpy(), "labelled": True,
             "hoverinfo": "text", "diagonal": {"visible": False},
             "showupperhalf": False,
             "marker": {"color": color, "symbol": symbol, "size": 5}}
            for name, mask, color, symbol in groups if mask.any()]
    size = 180 * len(varied) + 120
    return "<h2>The design</h2>" + _plot("design", data, {"height": size, "hovermode": "closest"}, size)


def _metric_section(k: int, metric: str, points: pd.DataFrame, varied: list[str],
                    failed: pd.Series) -> str:
    """The metric against each varied parameter; failed points drawn below the others."""
    values = points[metric].to_numpy(dtype=float)
    finite = values[np.isfinite(values)]
    log = _log_scale(values)
    floor = (float(finite.min() / 3) if log else
             float(finite.min() - 0.05 * (np.ptp(finite) or 1.0)) if len(finite) else 0.0)
    data, layout = [], {"hovermode": "closest", "title": {"text": metric}, "showlegend": False,
                        "grid": {"rows": 1, "columns": len(varied), "pattern": "independent"}}
    for j, name in enumerate(varied):
        axis = "" if j == 0 else str(j + 1)
        for group, mask, color, symbol in (("ok", ~failed, OK, "circle"), ("failed", failed, FAILED, "x")):
            if not mask.any():
                continue
            y = values[mask.to_numpy()] if group == "ok" else np.full(int(mask.sum()), floor)
            data.append({"type": _scatter(int(mask.sum())), "mode": "markers",
                         "x": points.loc[mask, name].to_numpy(),
                         "y": y, "xaxis": f"x{axis}", "yaxis": f"y{axis}", "name": group,
                         "customdata": points.loc[mask, "point"].to_numpy(), "labelled": True,
                         "hoverinfo": "text",
                         "marker": {"color": color, "symbol": symbol, "size": 6}})
        layout[f"xaxis{axis}"] = {"title": {"text": name}}
        layout[f"yaxis{axis}"] = {"title": {"text": metric if j == 0 else ""},
                                  **({"type": "log"} if log else {})}
    note = ("<p class=\"note\">Failed points (✕, red) are drawn below the others: they have "
            "no value.</p>" if failed.any() else "")
    return f"<h2>{html.escape(metric)}</h2>{note}" + _plot(f"metric-{k}", data, layout)


def _index_section(chart: IndexChart) -> str:
    """A kind's indices of one metric: grouped bars with their half-widths, or labelled
    points."""
    if chart.style == "bars":
        data = [{"type": "bar", "name": label, "x": chart.names, "y": values,
                 "error_y": {"type": "data", "array": chart.errors.get(label, [])}}
                for label, values in chart.series.items()]
        layout: dict[str, Any] = {"barmode": "group"}
    else:
        data = [{"type": "scatter", "mode": "markers+text", "x": chart.series["x"],
                 "y": chart.series["y"], "text": chart.names, "textposition": "top right"}]
        layout = {}
    layout.update({"title": {"text": chart.title}, "xaxis": {"title": {"text": chart.axes[0]}},
                   "yaxis": {"title": {"text": chart.axes[1]}}})
    return _plot(f"indices-{html.escape(chart.metric)}", data, layout)


def _failed_table(points: pd.DataFrame, names: list[str]) -> str:
    failed = points[points["status"] != "ok"]
    if failed.empty:
        return ""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in ["point", *names, "status", "message"])
    rows = "".join("<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in
                                    [r["point"], *(f"{r[n]:.6g}" for n in names), r["status"], r["message"]])
                   + "</tr>" for _, r in failed.head(500).iterrows())
    more = f"<p class=\"note\">… and {len(failed) - 500} more.</p>" if len(failed) > 500 else ""
    return f"<h2>Failed points ({len(failed)})</h2><table><tr>{head}</tr>{rows}</table>{more}"


def first_series(out: pathlib.Path, points: pd.DataFrame) -> pd.DataFrame | None:
    """The kept series of the first SERIES_POINTS points, read part by part with a filter,
    so that a large sweep's series are never all in memory; None when none were kept."""
    import pyarrow.parquet as pq
    parts = sorted((out / "series").glob("part-*.parquet"))
    if not parts:
        return None
    cutoff = int(np.sort(points["point"].to_numpy())[:SERIES_POINTS].max()) + 1
    frames = [pq.read_table(p, filters=[("point", "<", cutoff)]).to_pandas() for p in parts]
    frame = pd.concat([f for f in frames if len(f)] or frames[:1])
    frame["variable"] = frame["variable"].astype(str)
    return frame


def _series_json(series: pd.DataFrame, points: pd.DataFrame) -> dict[str, Any]:
    """The kept series of the first SERIES_POINTS points, thinned: {point: {variable: [t, v]}}."""
    chosen = set(points["point"].head(SERIES_POINTS).tolist())
    kept: dict[str, Any] = {}
    frame = series[series["point"].isin(chosen)]
    for (point, variable), group in frame.groupby(["point", "variable"], observed=True):
        group = group.sort_values("time")
        step = max(1, math.ceil(len(group) / SERIES_SAMPLES))
        kept.setdefault(str(int(point)), {})[str(variable)] = [
            group["time"].to_numpy(dtype=float)[::step], group["value"].to_numpy(dtype=float)[::step]]
    return kept


# Clicking a point of any plot with its point number in customdata draws that point's
# series, or says that the report does not hold it.
_CLICK_SCRIPT = """
window.ON_DRAWN = function(gd){
  if(!gd.on || gd.id === 'series'){return;}
  gd.on('plotly_click', function(ev){
    const p = ev.points[0];
    if(p.customdata === undefined && Array.isArray(p.pointNumber) && p.data.customdata){
      p.customdata = p.data.customdata[p.pointNumber[0]][p.pointNumber[1]];  // a heatmap's cell
    }
    if(p.customdata === undefined || p.customdata === null){return;}
    const kept = SERIES[String(p.customdata)];
    const note = document.getElementById('series-note');
    if(!kept){ note.textContent = 'point ' + p.customdata + ': its series is not in this report (see series/).'; return; }
    note.textContent = 'point ' + p.customdata;
    const traces = Object.keys(kept).map(function(v){ return {x: kept[v][0], y: kept[v][1], name: v, mode: 'lines'}; });
    Plotly.react('series', traces, {title: {text: 'point ' + p.customdata}, xaxis: {title: {text: 'time (s)'}}});
  });
};
document.querySelectorAll('.plot').forEach(function(gd){ if(gd.dataset.drawn){ window.ON_DRAWN(gd); } });
"""


def fit_report(out: pathlib.Path, spec: FitSpec, best: list[Evaluation] | None,
               summary: dict[str, Any]) -> pathlib.Path:
    """Write ``out/report.html`` for a fit and return it."""
    sections = [_estimates_table(summary)]
    if best is not None:
        for experiment, run in zip(spec.experiments, best):
            if run.predictions is not None:
                sections.append(_experiment_section(experiment.name, experiment.data, run.predictions,
                                                    len(spec.experiments) > 1))
    if len(summary.get("parameters", {})) > 1:
        names = list(summary["parameters"])
        matrix = [[1.0 if a == b else summary["correlation"][a][b] for b in names] for a in names]
        sections.append("<h2>Correlation of the estimates</h2>" + _plot(
            "correlation", [{"type": "heatmap", "z": matrix, "x": names, "y": names, "zmin": -1, "zmax": 1,
                             "colorscale": "RdBu", "reversescale": True,
                             "text": [[f"{v:+.3f}" if v is not None else "n/a" for v in row] for row in matrix],
                             "texttemplate": "%{text}"}],
            {"yaxis": {"autorange": "reversed"}}, 120 + 60 * len(names)))
    for name, profile in summary.get("profiles", {}).items():
        sections.append(_profile_section(name, profile, summary))
    warnings = "".join(f"<li>{html.escape(w)}</li>" for w in summary.get("warnings", []))
    intro = (f"Status {html.escape(str(summary['status']))}, cost {summary['cost']}, "
             f"{summary['evaluations']} runs. " + (f"<ul>{warnings}</ul>" if warnings else "No warnings."))
    path = out / "report.html"
    path.write_text(_page(f"Fit {out.name}", intro, sections))
    return path


def _bound(x: float | None) -> str:
    return "open" if x is None else f"{x:.6g}"


def _estimates_table(summary: dict[str, Any]) -> str:
    """Estimates and intervals; a profile column only where a profile was asked for."""
    parameters = summary.get("parameters", {})
    profiled = any(p.get("profile_ci95") is not None for p in parameters.values())
    rows = []
    for name, p in parameters.items():
        wald = p.get("wald_ci95", p["ci95"])
        profile = p.get("profile_ci95")
        cells = [html.escape(name), f"{p['estimate']:.6g}", f"[{_bound(wald[0])}, {_bound(wald[1])}]"]
        if profiled:
            cells.append("" if profile is None else f"[{_bound(profile[0])}, {_bound(profile[1])}]")
        rows.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    heads = ["parameter", "estimate", "Wald 95 %"] + (["profile 95 %"] if profiled else [])
    return ("<h2>Estimates</h2><table><tr>" + "".join(f"<th>{h}</th>" for h in heads)
            + f"</tr>{''.join(rows)}</table>")


def _experiment_section(name: str, data: Any, predictions: np.ndarray, several: bool) -> str:
    title = f"Experiment {name}" if several else "Measured and fitted"
    parts = [f"<h2>{html.escape(title)}</h2>"]
    for j, column in enumerate(data.columns):
        div = f"fit-{name}-{column}"
        parts.append(_plot(div, [
            {"type": "scatter", "mode": "markers", "name": "measured", "x": data.times, "y": data.values[:, j],
             "marker": {"size": 3, "color": "#444"}},
            {"type": "scatter", "mode": "lines", "name": "fitted", "x": data.times, "y": predictions[:, j]},
            {"type": "scatter", "mode": "markers", "name": "fitted − measured", "x": data.times,
             "y": predictions[:, j] - data.values[:, j], "yaxis": "y2", "marker": {"size": 3, "color": FAILED}}],
            {"title": {"text": column}, "yaxis": {"domain": [0.35, 1.0], "title": {"text": column}},
             "yaxis2": {"domain": [0.0, 0.25], "title": {"text": "residual"}}, "hovermode": "closest"}, 460))
    return "".join(parts)


def _profile_section(name: str, profile: dict[str, Any], summary: dict[str, Any]) -> str:
    best = summary["cost"]
    rise = [None if c is None else c - best for c in profile["cost"]]
    limit = profile["threshold"] - best
    data = [{"type": "scatter", "mode": "lines+markers", "name": "profile", "x": profile["values"], "y": rise},
            {"type": "scatter", "mode": "lines", "name": "95 % threshold", "line": {"dash": "dot"},
             "x": [min(profile["values"]), max(profile["values"])], "y": [limit, limit]}]
    wald = summary["parameters"][name]["wald_ci95"]
    shapes = [{"type": "rect", "xref": "x", "yref": "paper", "x0": wald[0], "x1": wald[1], "y0": 0, "y1": 1,
               "fillcolor": "orange", "opacity": 0.15, "line": {"width": 0}}] if None not in wald else []
    layout = {"title": {"text": f"{name}: profile (line) and Wald interval (shaded)"}, "shapes": shapes,
              "xaxis": {"title": {"text": name}}, "yaxis": {"title": {"text": "cost − least cost"},
                                                            "range": [0, 2.5 * limit]}}
    return _plot(f"profile-{name}", data, layout, 360)
