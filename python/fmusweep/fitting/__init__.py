"""Fit an FMU's parameters to measurements, on the sweep's engine::

    from fmusweep import fit
    result = fit("examples/fit/fit.toml", workers=2)
    result.summary["parameters"]["k34"]   # estimate, stderr, ci95, identifiable

Bounded nonlinear least squares (``method``), each iteration one parallel batch of runs
on the sweep's pool, every run kept in the sweep's Parquet format (``problem``), the
uncertainty from the Jacobian at the optimum (``statistics``), and plots. The result is
written to ``OUT/fit.json``.
"""

from __future__ import annotations

import json
import pathlib
import time

import numpy as np

from ..system import open_target
from ..pool import Pool, without_message_log
from ..store import FORMAT, ResultStore, atomic_write_text, versions
from ..worker import prepare_worker, run_batch
from .method import solve_all, starting_points
from .problem import Problem, check_fit_against_fmu
from .spec import FitParameter, FitSpec
from .statistics import uncertainty

__all__ = ["fit", "FitResult", "FitSpec", "FitParameter", "SERIAL_BELOW_S"]

# Without an engine named, a fit whose runs take less than this runs in this process: a
# fit waits for each batch before it chooses the next, and a round trip through Dask costs
# milliseconds, more than such a batch gains from running on several workers.
SERIAL_BELOW_S = 0.02


class FitResult:
    """``summary``: what fit.json holds; ``out``: the output directory; ``points``: every
    evaluated run (a DataFrame); ``plots``: the pictures written."""

    def __init__(self, out: pathlib.Path, summary: dict, plots: list[pathlib.Path]):
        self.out = out
        self.summary = summary
        self.plots = plots

    @property
    def points(self):
        return ResultStore.points_table_of(self.out).to_pandas()

    def estimates(self) -> dict[str, float]:
        return {k: v["estimate"] for k, v in self.summary["parameters"].items()}

    def __repr__(self):
        return (f"FitResult({str(self.out)!r}, status={self.summary['status']!r}, "
                f"cost={self.summary['cost']!r})")


def fit(spec, *, fmu=None, out=None, workers: int | None = None, scheduler: str | None = None,
        serial: bool = False, resume: bool = False, plots: bool = True) -> FitResult:
    """Fit the spec's parameters to its data and return a FitResult.

    spec: a TOML path, a dict, or a FitSpec. fmu: the FMU's path, over the spec's own
    (default: the spec's FMU or coupled [system], else $FMUSWEEP_FMU). out: the output directory (default
    ``fit-<digest>`` here). workers, scheduler, serial: as for ``run_sweep``; given none,
    the fit runs here when one run takes less than SERIAL_BELOW_S, else on a LocalCluster
    of every core. resume: continue a fit that ``out`` holds; the points it evaluated are
    read, not run again.
    """
    started = time.perf_counter()
    spec = FitSpec.load(spec)
    target, local, description = open_target(spec.system, fmu, spec.fmu, spec.scenario.step)
    check_fit_against_fmu(spec, description, local)
    plan = spec.plan()
    local.configure(plan)
    serial, engine_note = _choose_engine(spec, local, serial, workers, scheduler)
    digest = spec.digest()
    out = pathlib.Path(out or f"fit-{digest[:10]}")
    store = ResultStore(out, _meta(spec, digest, target, description), resume)
    pool = Pool(target, (run_batch, prepare_worker), plan, workers=workers, scheduler=scheduler,
                serial=serial, prefix=f"fmusweep-fit-{digest[:8]}-")
    with without_message_log(serial), pool:
        problem = Problem(spec, pool, store, target.sha256)
        solving = time.perf_counter()
        starts = solve_all(problem, starting_points(spec), 1 if serial else pool.workers)
        solve_s = time.perf_counter() - solving
    store.consolidate()
    summary = _summary(spec, problem, starts, pool, time.perf_counter() - started)
    summary["solve_s"] = solve_s
    summary["engine_choice"] = engine_note
    atomic_write_text(json.dumps(summary, indent=2), out / "fit.json")
    written = []
    if plots and summary["status"] != "failed":
        from .plots import plot_fit
        best = min(starts, key=lambda s: s.cost)
        # The optimiser's last accepted point: run, and kept, on the way.
        at_best = problem.cached(best.estimate)
        if at_best is not None and at_best.ok:
            written = plot_fit(spec, at_best, summary, out / "plots")
    return FitResult(out, summary, written)


def _choose_engine(spec, local, serial: bool, workers, scheduler) -> tuple[bool, str]:
    """Serial or not, and why, when the caller named no engine: one run at the start says
    what a run costs."""
    if serial or workers is not None or scheduler is not None:
        return serial, "as asked"
    [probe] = local.run(spec.names, [[p.start for p in spec.parameters]])
    run_s = probe["wall_s"] or 0.0
    if run_s < SERIAL_BELOW_S:
        return True, (f"serial: a run takes {run_s * 1e3:.1f} ms, less than a round trip "
                      "through Dask gains (name --workers or --scheduler to use one)")
    return False, f"a LocalCluster: a run takes {run_s * 1e3:.0f} ms"


def _meta(spec, digest: str, target, description: dict) -> dict:
    return {
        "format": FORMAT, "kind": "fit", "spec": spec.raw, "spec_digest": digest,
        "seed": spec.seed, "fmu_sha256": target.sha256, "fmu_name": target.name,
        "fmu_guid": description["guid"], "data_sha256": spec.data.sha256,
        "design": {"kind": "fit", "names": spec.names, "points": None},
        "metrics": ["cost"], "versions": versions(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def _summary(spec, problem, starts, pool, wall_s: float) -> dict:
    finished = [s for s in starts if s.estimate is not None]
    best = min(finished, key=lambda s: s.cost) if finished else None
    summary = {
        "status": best.status if best else "failed",
        "message": best.message if best else "; ".join(f"start {s.index}: {s.message}" for s in starts),
        "cost": best.cost if best else None,
        "evaluations": problem.computed + problem.reused,
        "computed": problem.computed, "resumed": problem.reused,
        "iterations": best.iterations if best else None,
        "start": best.index if best else None,
        "data": {"file": str(spec.data.path), "times": len(spec.data.times),
                 "columns": spec.data.columns},
        "engine": pool.engine, "workers": pool.workers, "wall_s": wall_s,
        "startup_s": pool.startup_s,
        "starts": [{"start": dict(zip(spec.names, map(float, s.start))), "status": s.status,
                    "cost": s.cost if s.estimate is not None else None,
                    "estimate": (dict(zip(spec.names, map(float, s.estimate)))
                                 if s.estimate is not None else None),
                    "iterations": s.iterations, "message": s.message, "notes": s.notes}
                   for s in starts],
    }
    if best is None:
        summary.update(parameters={}, correlation={}, residual_rms={}, warnings=[summary["message"]])
        return summary
    summary.update(uncertainty(spec, best.estimate, best.jacobian, best.residuals))
    weighted = best.residuals.reshape(spec.data.values.shape)
    summary["residual_rms"] = {c: float(np.sqrt(np.mean((weighted[:, j] * spec.data.sigma[j]) ** 2)))
                               for j, c in enumerate(spec.data.columns)}
    summary["warnings"] = summary["warnings"] + [n for s in starts for n in s.notes]
    return summary
