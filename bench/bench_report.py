"""The interactive reports' benchmark: a 10⁴-point sweep's report.html (a grid of the
rod length and the load spring, a fifth of the points failing to assemble, series kept)
and the two-experiment fit's report: each file's size and the time headless Chromium takes
to open it until its first screen is drawn and interactive (the plots are drawn as they
come into view) and, written with every plot drawn at once, until every plot is drawn
(the fastest of three each). Beside them, the time from a later `cargo xtask sweep` call
to its first point saved.

    python bench/bench_report.py <CyclicMechanism.fmu> <output directory> [--quick]

Writes results.json and results.md.
"""

import pathlib
import sys
import tempfile
import time
import tomllib

from bench_sweep import arguments, write_results
from fmusweep import fit, run_sweep

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests/python"))
from browser import Browser  # noqa: E402  (the tests' driver of headless Chromium)

TWO_EXPERIMENTS = ROOT / "examples/fit/two_experiments.toml"
DRAWN = ("Array.from(document.querySelectorAll('.plot:not(#series)')).every("
         "e => e.querySelector('.main-svg') !== null)")
# The first screen: every plot that begins inside the window is drawn.
FIRST_SCREEN = ("Array.from(document.querySelectorAll('.plot:not(#series)')).filter("
                "e => e.getBoundingClientRect().top < window.innerHeight).every("
                "e => e.querySelector('.main-svg') !== null)")


def sweep_spec(side: int) -> dict:
    # L beyond about 0.945 m does not assemble: the top fifth of the range fails.
    return {"scenario": {"stop": 0.5, "step": 0.01, "tolerance": 1e-6},
            "design": {"kind": "grid", "parameters": {"k34": {"linspace": [10.0, 1000.0, side]},
                                                      "L": {"linspace": [0.6, 1.02, side]}}},
            "outputs": {"metrics": {"peak_rod_force": {"variable": "rod_force", "kind": "peak_abs"},
                                    "omega1_ripple": {"variable": "omega1", "kind": "peak_to_peak"}},
                        "series": {"variables": ["omega1"], "interval": 0.01}}}


def opened(path: pathlib.Path, drawn: str = FIRST_SCREEN) -> dict:
    """Seconds to open the file until `drawn` holds and the page answers a script (its main
    thread is free), the fastest of three; console errors."""
    times, errors = [], []
    for _ in range(3):
        with Browser() as browser:
            started = time.perf_counter()
            browser.open(path)
            browser.wait_for(drawn, timeout=120)
            browser.evaluate("1")
            times.append(time.perf_counter() - started)
            errors += browser.errors
    return {"open_s": min(times), "errors": errors}


def eager_copy(results, directory: pathlib.Path) -> pathlib.Path:
    """The same sweep's report with every plot drawn on opening (the report before the
    plots were drawn as they come into view)."""
    from fmusweep.indices import charts
    from fmusweep.show.report import first_series, sweep_report
    directory.mkdir()
    design = results.meta["design"]
    return sweep_report(directory, design["names"], results.points, results.meta["metrics"],
                        charts(design["kind"], results.sensitivity),
                        first_series(results.out, results.points), eager=True)


def first_point_of_later_calls(tmp: pathlib.Path) -> dict:
    """Seconds from `cargo xtask sweep examples/sweeps/rod_force_grid.toml` to its first
    saved point: a first call (which may build) and two later ones."""
    import subprocess
    times = []
    for k in range(3):
        out = tmp / f"call-{k}"
        started = time.perf_counter()
        call = subprocess.Popen(["cargo", "xtask", "sweep", "examples/sweeps/rod_force_grid.toml",
                                 "--out", str(out), "--no-progress", "--no-plots"], cwd=ROOT,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        while not any((out / "points").glob("part-*")) and call.poll() is None:
            time.sleep(0.002)
        times.append(time.perf_counter() - started)
        if call.wait() != 0:
            raise RuntimeError(f"cargo xtask sweep failed ({call.returncode})")
    return {"first_call_s": times[0], "later_calls_s": times[1:]}


def plotly_alone(tmp: pathlib.Path) -> dict:
    """The floor of any such report here: a page with Plotly's JavaScript and one plot of
    two points, opened the same way."""
    from fmusweep.show.report import _page, _plot
    page = tmp / "plotly_alone.html"
    page.write_text(_page("Plotly alone", "", [_plot("one", [{"x": [0, 1], "y": [0, 1]}], {})]))
    return {"bytes": page.stat().st_size, **opened(page)}


def say(doing: str) -> None:
    """A line before each step, none of which is short."""
    print(f"bench-report: {doing}", flush=True)


def main():
    fmu, out, quick, r = arguments()
    with tempfile.TemporaryDirectory() as tmp:
        say("opening a page of Plotly alone in headless Chromium")
        r["plotly_alone"] = plotly_alone(pathlib.Path(tmp))
        side = 30 if quick else 100
        say(f"sweeping a {side} × {side} grid with series on 2 workers, then opening its report")
        t0 = time.perf_counter()
        results = run_sweep(sweep_spec(side), fmu=str(fmu), out=str(pathlib.Path(tmp) / "sweep"),
                            workers=2, progress=False)
        counts = results.points["status"].value_counts().to_dict()
        r["sweep"] = {"points": side * side, "statuses": counts, "wall_s": time.perf_counter() - t0,
                      "bytes": results.report_html.stat().st_size, **opened(results.report_html)}
        say("opening the report with every plot drawn at once")
        eager = eager_copy(results, pathlib.Path(tmp) / "eager")
        r["sweep_eager"] = {"bytes": eager.stat().st_size, **opened(eager, DRAWN)}
        say("timing later calls of `cargo xtask sweep` to their first point")
        r["later_call"] = first_point_of_later_calls(pathlib.Path(tmp))
        say("fitting examples/fit/two_experiments.toml, then opening its report")
        spec = tomllib.loads(TWO_EXPERIMENTS.read_text())
        for e in spec["experiment"]:
            e["data"]["file"] = str(TWO_EXPERIMENTS.parent / e["data"]["file"])
        done = fit(spec, fmu=str(fmu), out=str(pathlib.Path(tmp) / "fit"), serial=True)
        page = done.out / "report.html"
        r["fit"] = {"bytes": page.stat().st_size, **opened(page)}
    write_results(out, r, report(r))


def report(r: dict) -> str:
    s, f, a, e, c = r["sweep"], r["fit"], r["plotly_alone"], r["sweep_eager"], r["later_call"]
    return "\n".join([
        "# Report benchmark", "",
        f"Machine: {r['machine']}. Headless Chromium (Debian's package) opens each report.html "
        "from disk; the time runs from the navigation to the moment the plots of the first "
        "screen (1400 × 1000) are drawn and the page answers a script, the fastest of three "
        "fresh browsers. The plots below are drawn as they are scrolled to.", "",
        "| report | points | file size | time to interactive | console errors |",
        "| --- | --- | --- | --- | --- |",
        f"| sweep (grid of k34 and L, series kept) | {s['points']:,} "
        f"({', '.join(f'{v:,} {k}' for k, v in s['statuses'].items())}) | {s['bytes'] / 1e6:.2f} MB | "
        f"{s['open_s']:.2f} s | {len(s['errors'])} |",
        f"| the same, every plot drawn on opening (as before) | {s['points']:,} | "
        f"{e['bytes'] / 1e6:.2f} MB | {e['open_s']:.2f} s | {len(e['errors'])} |",
        f"| fit (examples/fit/two_experiments.toml) | – | {f['bytes'] / 1e6:.2f} MB | {f['open_s']:.2f} s | "
        f"{len(f['errors'])} |",
        f"| Plotly alone (its JavaScript and one plot of two points) | – | {a['bytes'] / 1e6:.2f} MB | "
        f"{a['open_s']:.2f} s | {len(a['errors'])} |", "",
        f"Of the sweep report's time, {a['open_s']:.2f} s is what any page with Plotly's JavaScript "
        "inlined takes here to parse it (the last row); the rest is the first screen's plots "
        "(a heatmap of the design's statuses and one of the first metric, for this grid).", "",
        "## A later `cargo xtask sweep`", "",
        "From the call of `cargo xtask sweep examples/sweeps/rod_force_grid.toml` to its first "
        "point saved (the builds and the venv checked, Python started, the spec checked "
        "against the FMU):", "",
        "| call | time to the first point |", "| --- | --- |",
        f"| first (after the benchmark's own builds) | {c['first_call_s']:.2f} s |",
        *[f"| later call {k + 1} | {t:.2f} s |" for k, t in enumerate(c["later_calls_s"])],
        "", "Each file holds Plotly's JavaScript (about 4.8 MB of it) and the data; it needs no network.", ""])


if __name__ == "__main__":
    main()
