"""A fit run as a study (``fmusweep.study``): the spec checked against what runs, then
bounded nonlinear least squares from each start, every trial point run on the study's
pool and kept in its store, and the summary and plots written."""

from __future__ import annotations

import json
import pathlib
import time
import warnings
from typing import Any

import numpy as np

from ..errors import SpecWarning, refuse_in_spawned_child
from ..pool import check_engine
from ..store import ResultStore, atomic_write_text
from ..study import Study, Target, checked_fit, spec_name
from .method import Start, solve_all, starting_points
from .problem import Problem
from .profile import Profile, profile_all
from .profile import summary_of as profile_summary
from .spec import FitSpec
from .statistics import uncertainty

__all__ = ["fit", "FitResult", "SERIAL_BELOW_S"]

# Without an engine named, a fit whose runs take less than this runs in this process: a
# fit waits for each batch before it chooses the next, and a round trip through Dask costs
# milliseconds, more than such a batch gains from running on several workers.
SERIAL_BELOW_S = 0.02

Summary = dict[str, Any]


class FitResult:
    """``summary``: what fit.json holds; ``out``: the output directory; ``points``: every
    evaluated run (a DataFrame); ``plots``: the pictures written."""

    def __init__(self, out: pathlib.Path, summary: Summary, plots: list[pathlib.Path]):
        self.out = out
        self.summary = summary
        self.plots = plots

    @property
    def points(self) -> Any:
        """Every evaluated run, a pandas DataFrame."""
        return ResultStore.points_table_of(self.out).to_pandas()

    def estimates(self) -> dict[str, float]:
        return {k: v["estimate"] for k, v in self.summary["parameters"].items()}

    def __repr__(self) -> str:
        return (f"FitResult({str(self.out)!r}, status={self.summary['status']!r}, "
                f"cost={self.summary['cost']!r})")


def fit(spec: FitSpec | str | pathlib.Path | dict[str, Any], *, fmu: str | None = None,
        out: str | None = None, workers: int | None = None, scheduler: str | None = None,
        serial: bool = False, resume: bool = False, plots: bool = True) -> FitResult:
    """Fit the spec's parameters to its data and return a FitResult.

    spec: a TOML path, a dict, or a FitSpec. fmu: the FMU's path, over the spec's own
    (default: the spec's FMU or coupled [system], else $FMUSWEEP_FMU). out: the output
    directory (default: a new ``results/NAME-DATE-TIME`` here, NAME the spec file's stem;
    with resume, the newest such folder of the same spec). workers, scheduler, serial: as for
    ``run_sweep``; given none, the fit runs here when one run takes less than
    SERIAL_BELOW_S, else on a LocalCluster of every core. resume: continue a fit that
    ``out`` holds; the points it evaluated are read, not run again.
    """
    started = time.perf_counter()
    refuse_in_spawned_child("fit")
    check_engine(workers, scheduler, serial)
    given = spec
    spec, target = checked_fit(given, fmu)
    for said in dict.fromkeys(w for e in spec.experiments
                              for w in e.scenario.off_grid_breakpoints(spec.system)):
        warnings.warn(said, SpecWarning, stacklevel=2)
    assert target.local is not None  # a fit runs an SSP file natively only
    plan = spec.experiments[0].plan(spec.system)
    target.local.configure(plan)
    serial, engine_note = _choose_engine(spec, target, serial, workers, scheduler)
    record = {"data_sha256": [e.data.sha256 for e in spec.experiments], "metrics": ["cost"],
              "design": {"kind": "fit", "names": spec.names, "points": None}}
    study = Study("fit", spec, target, plan, out=out, resume=resume, record=record,
                  workers=workers, scheduler=scheduler, serial=serial,
                  name=spec_name(given, "fit"))
    try:
        return _run(spec, study, started, serial=serial, engine_note=engine_note, plots=plots)
    except BaseException:
        study.abandon()
        raise


def _run(spec: FitSpec, study: Study, started: float, *, serial: bool, engine_note: str,
         plots: bool) -> FitResult:
    """The fit from each start, its intervals and its outputs, after the checks."""
    with study.running() as pool:
        problem = Problem(spec, study)
        solving = time.perf_counter()
        starts = solve_all(problem, starting_points(spec), 1 if serial else pool.workers)
        solve_s = time.perf_counter() - solving
        best = _best(starts)
        wald = _wald(spec, best)
        profiling = time.perf_counter()
        profiles = (profile_all(problem, best, {n: wald["parameters"][n]["stderr"] for n in spec.profiled},
                                1 if serial else pool.workers)
                    if best is not None and wald is not None and spec.profiled else [])
        profile_s = time.perf_counter() - profiling
    study.finish()
    summary = _summary(spec, problem, starts, best, wald, study, time.perf_counter() - started,
                       profiles)
    summary["solve_s"] = solve_s
    if profiles:
        summary["profile_s"] = profile_s
    summary["engine_choice"] = engine_note
    out_dir = study.store.out
    atomic_write_text(json.dumps(summary, indent=2), out_dir / "fit.json")
    written: list[pathlib.Path] = []
    if plots and best is not None and summary["status"] != "failed":
        from ..show import show_fit
        # The optimiser's last accepted point: run, and kept, on the way.
        assert best.estimate is not None
        at_best = problem.cached(best.estimate)
        runs = at_best.runs if at_best is not None and at_best.ok else None
        written = show_fit(out_dir, spec, runs, summary)
    return FitResult(out_dir, summary, written)


def _choose_engine(spec: FitSpec, target: Target, serial: bool, workers: int | None,
                   scheduler: str | None) -> tuple[bool, str]:
    """Serial or not, and why, when the caller named no engine: one run at the start says
    what a run costs."""
    if serial or workers is not None or scheduler is not None:
        return serial, "as asked"
    assert target.local is not None
    first = spec.experiments[0]
    [probe] = target.local.run(first.variables, [[spec.fitted[j].start for j in first.columns]])
    run_s = probe["wall_s"] or 0.0
    if run_s < SERIAL_BELOW_S:
        return True, (f"serial: a run takes {run_s * 1e3:.1f} ms, less than a round trip "
                      "through Dask gains (name --workers or --scheduler to use one)")
    return False, f"a LocalCluster: a run takes {run_s * 1e3:.0f} ms"


def _best(starts: list[Start]) -> Start | None:
    finished = [s for s in starts if s.estimate is not None]
    return min(finished, key=lambda s: s.cost) if finished else None


def _wald(spec: FitSpec, best: Start | None) -> dict[str, Any] | None:
    """The statistics from the Jacobian at the best estimate (``statistics``); none when no
    start finished. The profiles take their first steps from its standard errors."""
    if best is None:
        return None
    assert best.estimate is not None and best.jacobian is not None and best.residuals is not None
    return uncertainty(spec, best.estimate, best.jacobian, best.residuals)


def _with_profiles(spec: FitSpec, summary: Summary, profiles: list[Profile]) -> None:
    """Each parameter's Wald interval as ``wald_ci95`` and its profile interval, where it
    has one, as ``profile_ci95``; ``ci95`` is the profile's with intervals = "profile"."""
    for name, p in summary["parameters"].items():
        p["wald_ci95"] = list(p["ci95"])
    for pr in profiles:
        p = summary["parameters"][pr.name]
        p["profile_ci95"] = list(pr.interval)
        if spec.intervals == "profile":
            p["ci95"] = list(pr.interval)
        for side in (pr.low, pr.high):
            # An estimate at its bound is warned of once, by the Wald statistics.
            if side.note and not (side.at_bound and p["at_bound"]):
                summary["warnings"].append(side.note)
    if profiles:
        summary["profiles"] = profile_summary(profiles)


def _summary(spec: FitSpec, problem: Problem, starts: list[Start], best: Start | None,
             wald: dict[str, Any] | None, study: Study, wall_s: float,
             profiles: list[Profile]) -> Summary:
    pool = study.pool
    summary: Summary = {
        "status": best.status if best else "failed",
        "message": best.message if best else "; ".join(f"start {s.index}: {s.message}" for s in starts),
        "cost": best.cost if best else None,
        "evaluations": problem.computed + problem.reused,
        "computed": problem.computed, "resumed": problem.reused,
        "iterations": best.iterations if best else None,
        "start": best.index if best else None,
        "experiments": {e.name: {"file": str(e.data.path), "times": len(e.data.times),
                                 "columns": e.data.columns} for e in spec.experiments},
        "engine": pool.engine, "workers": pool.workers, "wall_s": wall_s,
        "startup_s": pool.startup_s,
        "starts": [{"start": dict(zip(spec.names, map(float, s.start))), "status": s.status,
                    "cost": s.cost if s.estimate is not None else None,
                    "estimate": (dict(zip(spec.names, map(float, s.estimate)))
                                 if s.estimate is not None else None),
                    "iterations": s.iterations, "message": s.message, "notes": s.notes}
                   for s in starts],
    }
    if best is None or wald is None:
        summary.update(parameters={}, correlation={}, residual_rms={}, warnings=[summary["message"]])
        return summary
    assert best.residuals is not None
    summary.update(wald)
    summary["residual_rms"] = _residual_rms(spec, best.residuals)
    summary["warnings"] = summary["warnings"] + [n for s in starts for n in s.notes]
    _with_profiles(spec, summary, profiles)
    return summary


def _residual_rms(spec: FitSpec, weighted: np.ndarray) -> dict[str, Any]:
    """Each measured column's root mean square residual in its own units; per experiment
    where there are several."""
    by_experiment: dict[str, dict[str, float]] = {}
    offset = 0
    for e in spec.experiments:
        size = e.data.values.size
        part = weighted[offset:offset + size].reshape(e.data.values.shape)
        offset += size
        by_experiment[e.name] = {c: float(np.sqrt(np.mean((part[:, j] * e.data.sigma[j]) ** 2)))
                                 for j, c in enumerate(e.data.columns)}
    if len(spec.experiments) == 1:
        return by_experiment[spec.experiments[0].name]
    return by_experiment
