"""The steady-cycle benchmark: a lightly damped 20 × 20 grid (the rocker's damper d34 from
0.1 to 0.4 N·m·s/rad, where a transient needs tens of revolutions to settle to 1e-6, by the
motor law's constant Mm_a0 from 60 to 140 N·m), its steady cycles found by shooting
(``[cycle]``) against the transient runs a user would otherwise make, side by side in this
process on the same two workers of one running local cluster.

    python bench/bench_cycle.py <CyclicMechanism.fmu> <output directory> [--quick]

A transient has reached the steady cycle to 1e-6 when its state at the end lies within
1e-6 of the cycle at the same crank angle (speeds over the cycle's mean crank speed,
spring twists over their largest twist on the cycle): then the metrics of its next
revolution are the cycle's to about 1e-6. The transient runs (the FMU's own
co-simulation, tol 1e-9, from rest) are timed at stop times doubling from 20 s until every
point of the grid is that close; the cycle sweep (tol 1e-9, shooting from each point's
transient or its neighbour's cycle) is timed with and without continuation. Writes
results.json and results.md, and docs/bench/cycle.md (not with --quick).
"""

import math
import pathlib
import shutil
import tempfile
import time

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from bench_sweep import arguments, write_results
from fmusweep import run_sweep

ROOT = pathlib.Path(__file__).resolve().parents[1]
TAU = 2 * math.pi
TOLERANCE = 1e-9
SETTLED = 1e-6
KEPT = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega4"]
METRICS = {"peak": {"variable": "rod_force", "kind": "max"},
           "swing": {"variable": "rod_force", "kind": "peak_to_peak"},
           "speed": {"variable": "omega2", "kind": "mean"},
           "second": {"variable": "rod_force", "kind": "harmonic", "order": 2}}


def design(n: int) -> dict:
    return {"parameters": {"d34": {"linspace": [0.1, 0.4, n]},
                           "Mm_a0": {"linspace": [60.0, 140.0, n]}}}


def timed_sweep(spec: dict, fmu, scheduler: str, out: pathlib.Path):
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    results = run_sweep(spec, fmu=str(fmu), out=str(out), scheduler=scheduler, progress=False,
                        plots=False)
    return time.perf_counter() - t0, results


def cycle_spec(n: int, continuation: bool) -> dict:
    return {"scenario": {"stop": 400.0, "step": 0.01, "tolerance": TOLERANCE},
            "design": design(n),
            "cycle": {"state": "loop_angle", "period": TAU, "shifted": ["phi1"], "keep": KEPT,
                      "continuation": continuation},
            "outputs": {"metrics": METRICS}}


def transient_spec(n: int, stop: float) -> dict:
    return {"scenario": {"stop": stop, "step": 0.01, "tolerance": TOLERANCE},
            "design": design(n),
            "outputs": {"metrics": {v: {"variable": v, "kind": "final"} for v in KEPT}}}


def cycle_curves(results) -> dict[int, dict[str, CubicSpline]]:
    """Each point's kept variables over its cycle as periodic splines of time (the crank
    angle less its steady advance), and its period."""
    series = results.series()
    curves = {}
    for point, rows in series.groupby("point"):
        period = float(results.points.set_index("point").loc[point, "cycle_period"])
        splines = {}
        for variable, column in rows.groupby("variable", observed=True):
            column = column.sort_values("time")
            t = np.append(column["time"].to_numpy(), period)
            v = column["value"].to_numpy()
            drift = TAU / period if variable in ("phi1", "phi2") else 0.0
            periodic = v - drift * t[:-1]
            splines[variable] = (CubicSpline(t, np.append(periodic, periodic[0]),
                                             bc_type="periodic"), drift)
        curves[point] = {"period": period, **splines}
    return curves


def distance(curve: dict, end: dict) -> float:
    """How far a transient's end state lies from the cycle at the same crank angle."""
    period = curve["period"]

    def at(variable, t):
        spline, drift = curve[variable]
        return float(spline(t)) + drift * t

    base = at("phi2", 0.0)
    target = base + math.fmod(end["phi2"] - base, TAU) % TAU
    tau = brentq(lambda t: at("phi2", t) - target, 0.0, period, xtol=1e-14)
    speed = TAU / period
    twists = {"12": ("phi1", "phi2"), "34": ("phi3", "phi4")}
    grid = np.linspace(0, period, 512)
    worst = max(abs(end[w] - at(w, tau)) / speed for w in ("omega1", "omega2", "omega4"))
    for a, b in twists.values():
        scale = max(np.abs([at(a, t) - at(b, t) for t in grid]).max(), 1e-3)
        worst = max(worst, abs((end[a] - end[b]) - (at(a, tau) - at(b, tau))) / scale)
    return worst


def main():
    fmu, out, quick, r = arguments()
    from distributed import LocalCluster
    n = 6 if quick else 20
    work = pathlib.Path(tempfile.mkdtemp(prefix="bench-cycle-"))
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0",
                      processes=True) as cluster:
        address = cluster.scheduler_address
        # The workers load the FMU once before anything is timed.
        timed_sweep(cycle_spec(2, True), fmu, address, work / "warm")
        steady = {}
        for continuation in (True, False):
            seconds, results = timed_sweep(cycle_spec(n, continuation), fmu, address,
                                           work / f"cycle-{continuation}")
            points = results.points
            assert (points["status"] == "ok").all(), points["message"].unique()
            steady[continuation] = (seconds, results)
            r[f"cycle_{'continued' if continuation else 'own_transient'}"] = {
                "seconds": seconds, "points": len(points),
                "runs": int(points["cycle_runs"].sum()),
                "iterations": float(points["cycle_iterations"].mean()),
                "continued": int(points["cycle_continued"].sum()),
                "worst_residual": float(points["cycle_residual"].max()),
                "largest_multiplier": float(points["cycle_multiplier"].max()),
                "smallest_multiplier": float(points["cycle_multiplier"].min())}
        results = steady[True][1]
        curves = cycle_curves(results)
        revolutions = np.log(SETTLED) / np.log(results.points["cycle_multiplier"].to_numpy())
        r["revolutions_to_settle"] = [float(revolutions.min()), float(revolutions.max())]
        ladder = []
        stop = 20.0
        while True:
            seconds, transient = timed_sweep(transient_spec(n, stop), fmu, address,
                                             work / f"transient-{stop:g}")
            p = transient.points.set_index("point")
            far = [distance(curves[point], {v: p.loc[point, v] for v in KEPT})
                   for point in p.index]
            ladder.append({"stop": stop, "seconds": seconds, "worst": max(far),
                           "settled": int(sum(d <= SETTLED for d in far))})
            print(f"transient {stop:g} s: {seconds:.1f} s, worst {max(far):.2e}", flush=True)
            if max(far) <= SETTLED or stop >= 1280:
                break
            stop *= 2
        r["transient_ladder"] = ladder
        r["grid"] = n
        metrics_agree = {}
        settled = ladder[-1]
        r["transient"] = settled
        best = min(steady[True][0], steady[False][0])
        r["speedup"] = settled["seconds"] / best
        own = steady[False][1].points.set_index("point")
        continued = results.points.set_index("point")
        for name in METRICS:
            metrics_agree[name] = float((own[name] / continued[name] - 1).abs().max())
        r["continuation_changes_metrics_by"] = metrics_agree
    shutil.rmtree(work, ignore_errors=True)
    text = report(r)
    write_results(out, r, text)
    if not quick:
        (ROOT / "docs/bench/cycle.md").write_text(text)


def report(r: dict) -> str:
    n, t = r["grid"], r["transient"]
    c, o = r["cycle_continued"], r["cycle_own_transient"]
    lines = [
        "# Steady-cycle benchmark", "",
        f"Machine: {r['machine']}. The mechanism's paper case with the damper d34 from 0.1 to 0.4 "
        f"N·m·s/rad by the motor law's constant Mm_a0 from 60 to 140 N·m, a {n} × {n} grid; "
        f"tol {TOLERANCE:g}; both on the same 2 workers of one running local cluster, side by "
        "side in one run (bench/bench_cycle.py).", "",
        f"The cycles' largest Floquet multipliers lie between {c['smallest_multiplier']:.3f} "
        f"and {c['largest_multiplier']:.3f} per revolution: a perturbation shrinks to "
        f"{SETTLED:g} in {r['revolutions_to_settle'][0]:.0f} to "
        f"{r['revolutions_to_settle'][1]:.0f} revolutions.", "",
        "| way to the steady cycle's metrics (2 workers) | seconds | against the transients |",
        "| --- | --- | --- |",
        f"| steady cycles, each from its neighbour's | {c['seconds']:.2f} | "
        f"{t['seconds'] / c['seconds']:.1f}× faster |",
        f"| steady cycles, each from its own transient | {o['seconds']:.2f} | "
        f"{t['seconds'] / o['seconds']:.1f}× faster |",
        f"| transient runs to {t['stop']:g} s, every point settled to {SETTLED:g} | "
        f"{t['seconds']:.2f} | 1× |", "",
        f"Shooting: {c['runs']} runs over a cycle or part of one for {c['points']} points "
        f"from neighbours ({c['continued']} points continued, {c['iterations']:.1f} Newton "
        f"iterations a point), {o['runs']} from each point's own transient "
        f"({o['iterations']:.1f} iterations); largest periodicity residual "
        f"{max(c['worst_residual'], o['worst_residual']):.1e}. The two ways' metrics differ by "
        f"at most {max(r['continuation_changes_metrics_by'].values()):.1e} (relative).", "",
        "Transient runs, from rest, their stop times doubled until every point's end state "
        f"lay within {SETTLED:g} of its cycle at the same crank angle:", "",
        "| stop (s) | seconds | points settled | farthest from its cycle |",
        "| --- | --- | --- | --- |"]
    for row in r["transient_ladder"]:
        lines.append(f"| {row['stop']:g} | {row['seconds']:.2f} | {row['settled']} of {n * n} | "
                     f"{row['worst']:.1e} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
