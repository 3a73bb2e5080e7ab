"""The interactive reports, opened in headless Chromium as a user opens them: a sweep's
report names the point under the mouse and its values, marks failed points with their
status and message, shows a clicked point's time series; a fit's report shows the
estimates, the curves and the profiles; no console error, no network."""

import pathlib
import re

import numpy as np
import pytest

from browser import Browser, chromium
from fmusweep import fit, run_sweep

pytestmark = pytest.mark.skipif(chromium() is None, reason="Debian's chromium is not installed "
                                "(cargo xtask test installs it)")

EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "examples/fit"

# Rod lengths above about 0.945 m do not assemble: the last column of the grid fails.
SWEEP = {"scenario": {"stop": 1.0, "step": 0.01, "tolerance": 1e-8},
         "design": {"kind": "grid", "parameters": {"k34": {"linspace": [50.0, 250.0, 5]},
                                                   "L": {"values": [0.7, 0.8, 0.9, 1.0]}}},
         "outputs": {"metrics": {"peak_rod_force": {"variable": "rod_force", "kind": "peak_abs"}},
                     "series": {"variables": ["omega1", "rod_force"], "interval": 0.02}}}

# Where a trace's k-th point is on the screen, after scrolling its plot into view.
POSITION = """(function(div, trace, k){
  const gd = document.getElementById(div); gd.scrollIntoView({block: 'center'});
  const t = gd._fullData[trace];
  const xa = gd._fullLayout[t.xaxis.replace('x', 'xaxis')], ya = gd._fullLayout[t.yaxis.replace('y', 'yaxis')];
  const r = gd.getBoundingClientRect();
  return [r.left + xa._offset + xa.l2p(t.x[k]), r.top + ya._offset + ya.l2p(t.y[k]), t.customdata[k]];
})"""
HOVER_TEXT = "Array.from(document.querySelectorAll('.hoverlayer .hovertext')).map(e => e.textContent).join(' | ')"


@pytest.fixture(scope="module")
def sweep(fmu_path, tmp_path_factory):
    return run_sweep(SWEEP, fmu=str(fmu_path), out=str(tmp_path_factory.mktemp("sweep") / "out"),
                     serial=True, progress=False)


def test_a_sweep_writes_one_self_contained_report(sweep):
    page = sweep.report_html.read_text()
    assert page.startswith("<!DOCTYPE html>") and sweep.report_html == sweep.out / "report.html"
    assert not re.search(r"<script[^>]+src=|<link[^>]+href=\"http", page)  # nothing fetched
    assert "Plotly" in page


def test_hovering_a_point_names_it_and_clicking_shows_its_series(sweep, tmp_path):
    points = sweep.points.sort_values("point")
    ok = points[points["status"] == "ok"]
    with Browser() as browser:
        browser.open(sweep.report_html)
        browser.wait_for("document.querySelectorAll('.main-svg').length > 0")
        x, y, point = browser.evaluate(f"{POSITION}('metric-0', 0, 3)")
        browser.mouse_move(x, y)
        said = browser.wait_for(HOVER_TEXT)
        row = ok[ok["point"] == point].iloc[0]
        assert f"point {point} ({row['point_id']})" in said, said
        assert f"k34 = {row['k34']:.6g}" in said and f"L = {row['L']:.6g}" in said, said
        browser.screenshot(tmp_path / "hover.png")
        browser.click(x, y)
        browser.wait_for("document.getElementById('series').data && "
                         "document.getElementById('series').data.length == 2")
        assert browser.evaluate("document.getElementById('series-note').textContent") == f"point {point}"
        shown = browser.evaluate("document.getElementById('series').data[0].y.slice(0, 3)")
        kept = sweep.series()
        mine = kept[(kept["point"] == point) & (kept["variable"] == "omega1")].sort_values("time")
        assert shown == pytest.approx(mine["value"].to_numpy()[:3], rel=1e-15)
        assert browser.errors == []


def test_failed_points_are_marked_with_their_status_and_message(sweep):
    failed = sweep.points[sweep.points["status"] != "ok"]
    assert len(failed) == 5  # the L = 1.0 column
    with Browser() as browser:
        browser.open(sweep.report_html)
        browser.wait_for("document.querySelectorAll('.main-svg').length > 0")
        assert browser.evaluate("document.getElementById('metric-0').data[1].name") == "failed"
        x, y, point = browser.evaluate(f"{POSITION}('metric-0', 1, 0)")
        browser.mouse_move(x, y)
        said = browser.wait_for(HOVER_TEXT)
        row = failed[failed["point"] == point].iloc[0]
        assert f"point {point}" in said and f"{row['status']}:" in said and "L = 1" in said, said
        table = browser.evaluate("document.body.innerText")
        assert f"Failed points ({len(failed)})" in table and row["message"][:40] in table
        assert browser.errors == []


def test_a_fits_report_shows_estimates_curves_and_profiles(fmu_path, tmp_path):
    import tomllib
    spec = tomllib.loads((EXAMPLE / "two_experiments.toml").read_text())
    for e in spec["experiment"]:
        e["data"]["file"] = str(EXAMPLE / e["data"]["file"])
    result = fit(spec, fmu=str(fmu_path), out=str(tmp_path / "out"), serial=True)
    with Browser() as browser:
        browser.open(result.out / "report.html")
        browser.wait_for("document.querySelectorAll('.main-svg').length > 0")
        text = browser.evaluate("document.body.innerText")
        for name, p in result.summary["parameters"].items():
            assert name in text and f"{p['estimate']:.6g}" in text, name
        plots = browser.evaluate("Array.from(document.querySelectorAll('.plot')).map(e => e.id)")
        assert {"fit-braked-omega1", "fit-boosted-omega4", "correlation", "profile-Mm_a0"} <= set(plots)
        fitted = browser.evaluate("document.getElementById('fit-braked-omega1').data[1].y.length")
        assert fitted == 201
        browser.screenshot(tmp_path / "fit.png")
        assert browser.errors == []


def test_no_report_without_plots(fmu_path, tmp_path):
    results = run_sweep(dict(SWEEP, design={"kind": "list", "parameters": {"k34": {"values": [100.0]}}}),
                        fmu=str(fmu_path), out=str(tmp_path / "out"), serial=True, progress=False,
                        plots=False)
    assert results.report_html is None and not (tmp_path / "out/report.html").exists()
    assert np.isfinite(results.points["peak_rod_force"]).all()


def test_a_sobol_sweeps_report_draws_its_indices_and_design_matrix(fmu_path, tmp_path):
    spec = {"scenario": {"stop": 0.5, "step": 0.01, "tolerance": 1e-6},
            "design": {"kind": "sobol", "seed": 3, "samples": 16, "second_order": False,
                       "parameters": {"J1": {"range": [0.25, 0.75]}, "k12": {"range": [50.0, 150.0]},
                                      "k34": {"range": [50.0, 150.0]}}},
            "outputs": {"metrics": {"peak_rod_force": {"variable": "rod_force", "kind": "peak_abs"}}}}
    results = run_sweep(spec, fmu=str(fmu_path), out=str(tmp_path / "out"), serial=True, progress=False)
    with Browser() as browser:
        browser.open(results.report_html)
        browser.wait_for("document.querySelectorAll('.main-svg').length > 0")
        bars = browser.evaluate("document.getElementById('indices-peak_rod_force').data.map(t => t.name)")
        assert bars == ["S1 (first order)", "ST (total)"]
        assert browser.evaluate("document.getElementById('design').data[0].type") == "splom"
        # Every point of the matrix is labelled with its number and values.
        texts = browser.evaluate("document.getElementById('design').data[0].text")
        assert len(texts) == len(results.points) and texts[0].startswith("point ")
        assert "J1 = " in texts[0] and "k34 = " in texts[0]
        assert browser.evaluate("document.getElementById('series') === null")  # no series kept
        assert browser.errors == []


HEATMAP_CELL = """(function(div, row, column){
  const gd = document.getElementById(div); gd.scrollIntoView({block: 'center'});
  const t = gd._fullData[0];
  const xa = gd._fullLayout.xaxis, ya = gd._fullLayout.yaxis;
  const r = gd.getBoundingClientRect();
  return [r.left + xa._offset + xa.l2p(t.x[column]), r.top + ya._offset + ya.l2p(t.y[row]),
          t.customdata[row][column], t.z[row][column]];
})"""


def test_a_two_parameter_grid_draws_heatmaps_with_its_failed_cells(sweep):
    points = sweep.points.sort_values("point")
    with Browser() as browser:
        browser.open(sweep.report_html)
        browser.wait_for("document.getElementById('heatmap-0').data !== undefined")
        assert browser.evaluate("document.getElementById('design').data[0].type") == "heatmap"
        assert browser.evaluate("document.getElementById('heatmap-0').data[0].type") == "heatmap"
        # L = 1.0 (the last row) does not assemble: its cells have no value.
        x, y, point, z = browser.evaluate(f"{HEATMAP_CELL}('heatmap-0', 3, 2)")
        row = points[points["point"] == point].iloc[0]
        assert row["L"] == 1.0 and row["status"] == "error" and z is None
        browser.mouse_move(x, y)
        said = browser.wait_for(HOVER_TEXT)
        assert f"point {point} " in said and "error" in said, said
        x, y, point, z = browser.evaluate(f"{HEATMAP_CELL}('heatmap-0', 1, 4)")
        assert z == pytest.approx(points[points["point"] == point]["peak_rod_force"].iloc[0])
        browser.mouse_move(x, y)  # a click takes the point under the hover
        browser.wait_for(f"{HOVER_TEXT}.includes('point {point} ')")
        browser.click(x, y)
        browser.wait_for("document.getElementById('series').data && "
                         "document.getElementById('series').data.length == 2")
        assert browser.evaluate("document.getElementById('series-note').textContent") == f"point {point}"
        assert browser.errors == []


def _synthetic_report(directory, metrics):
    """A report of a 30 × 20 grid whose metrics are written here (no FMU run)."""
    import pandas as pd
    from fmusweep.show.report import sweep_report
    k, L = np.meshgrid(np.linspace(1.0, 2.0, 30), np.linspace(0.1, 0.2, 20), indexing="ij")
    n = k.size
    points = pd.DataFrame({"point": np.arange(n), "point_id": [f"id{i}" for i in range(n)],
                           "k": k.ravel(), "L": L.ravel(), "status": ["ok"] * n,
                           "message": [""] * n})
    for name, values in metrics.items():
        points[name] = values(points)
    directory.mkdir(parents=True, exist_ok=True)
    return sweep_report(directory, ["k", "L"], points, list(metrics), [], None)


def test_a_metric_spanning_decades_is_coloured_on_a_log_scale_and_says_so(tmp_path):
    page = _synthetic_report(tmp_path / "wide", {
        "wide": lambda p: 10.0 ** (6 * (p["k"] - 1.0)), "narrow": lambda p: p["k"] + p["L"]})
    with Browser() as browser:
        browser.open(page)
        browser.wait_for("document.getElementById('heatmap-1').data !== undefined")
        titles = browser.evaluate("[0, 1].map(k => document.getElementById('heatmap-' + k).layout.title.text)")
        assert titles == ["wide (log colour scale)", "narrow"], titles
        ticks = browser.evaluate("document.getElementById('heatmap-0').data[0].colorbar.ticktext")
        assert ticks[0] == "1e0" and ticks[-1] == "1e6", ticks
        assert browser.evaluate("document.getElementById('metric-0').layout.yaxis.type") == "log"
        text = browser.evaluate("document.body.innerText")
        assert "click one" not in text  # no series kept: no click is promised
        assert browser.errors == []


def test_plots_below_the_first_screens_are_drawn_when_scrolled_to(tmp_path):
    page = _synthetic_report(tmp_path / "long", {f"m{i}": (lambda p, i=i: p["k"] * i + p["L"])
                                                 for i in range(8)})
    with Browser() as browser:
        browser.open(page)
        browser.wait_for("document.getElementById('design').dataset.drawn === '1'")
        assert browser.evaluate("document.getElementById('metric-7').dataset.drawn") is None
        browser.evaluate("document.getElementById('metric-7').scrollIntoView()")
        browser.wait_for("document.getElementById('metric-7').querySelector('.main-svg') !== null")
        assert browser.errors == []
