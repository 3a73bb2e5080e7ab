"""``python -m fmusweep SPEC.toml [--fmu F] [--workers N] [--scheduler ADDRESS] [--out DIR]
[--resume] [--serial] [--batch-size N]``: run a sweep and print where its results are.
``python -m fmusweep fit SPEC.toml [same engine options]``: fit parameters to data."""

from __future__ import annotations

import argparse
import sys
from typing import Callable, Sequence, TypeVar

from . import __version__
from .sweep import run_sweep
from .native import RunnerError
from .spec import SpecError

EXAMPLE = """example:
  python -m fmusweep sweep.toml --workers 4 --out results/k34

with sweep.toml:
  fmu = "CyclicMechanism.fmu"
  [scenario]
  stop = 10.0
  step = 0.01
  [design]
  kind = "grid"
  [design.parameters]
  k34 = { linspace = [20.0, 200.0, 10] }
  [outputs.metrics]
  rod_force_peak = { variable = "rod_force", kind = "peak_abs" }
"""


FIT_EXAMPLE = """example:
  python -m fmusweep fit fit.toml --workers 2 --out results/fit

with fit.toml:
  fmu = "CyclicMechanism.fmu"
  [scenario]
  stop = 5.0
  step = 0.01
  tolerance = 1e-8
  [data]
  file = "measured.csv"     # a time column and one column per measured output
  sigma = { omega1 = 0.05 }
  [fit.parameters]
  k34 = { start = 80.0, range = [10.0, 400.0] }
  d34 = { start = 0.1, range = [0.0, 5.0] }
"""

ENGINE_ERRORS = (SpecError, RunnerError, FileExistsError, FileNotFoundError, ValueError)

T = TypeVar("T")


def _engine_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fmu", help="the FMU, when the spec names none (or to override it)")
    parser.add_argument("--workers", type=int, help="LocalCluster worker processes (default: every core)")
    parser.add_argument("--scheduler", help="address of an existing Dask scheduler, tcp://HOST:PORT")
    parser.add_argument("--serial", action="store_true", help="no Dask: run in this process")
    parser.add_argument("--no-plots", action="store_true", help="no plots and no report.html")


def _guarded(prog: str, kept: str, run: Callable[[], T]) -> T | int:
    """run()'s result, or the exit code after a refusal (2) or an interrupt (130), each
    said on standard error."""
    try:
        return run()
    except ENGINE_ERRORS as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; {kept}: run again with --resume", file=sys.stderr)
        return 130


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["fit"]:
        return fit_main(argv[1:])
    parser = argparse.ArgumentParser(prog="fmusweep", description=__doc__.split("\n\n")[0],
                                     epilog=EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"fmusweep {__version__}")
    parser.add_argument("spec", help="the sweep specification (TOML); `python -m fmusweep fit "
                                     "SPEC` runs a fit (see `fit --help`)")
    _engine_arguments(parser)
    parser.add_argument("--out", help="output directory (default: sweep-<spec digest>)")
    parser.add_argument("--resume", action="store_true", help="finish the sweep in --out, redoing only missing points")
    parser.add_argument("--batch-size", type=int, help="points per task (default: about 0.5 s of work)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    results = _guarded("fmusweep", "every finished batch is saved", lambda: run_sweep(
        args.spec, fmu=args.fmu, out=args.out, workers=args.workers, scheduler=args.scheduler,
        serial=args.serial, resume=args.resume, batch_size=args.batch_size,
        progress=not args.no_progress, plots=not args.no_plots))
    if isinstance(results, int):
        return results
    r = results.report
    assert r is not None  # a sweep just run reports itself
    counts = ", ".join(f"{n} {s}" for s, n in sorted(r.statuses.items())) or "nothing new"
    print(f"fmusweep: {r.points} points ({r.resumed} already done; computed: {counts}) in "
          f"{r.wall_s:.1f} s on {r.workers} worker(s), {r.engine}, batches of {r.batch_size}")
    print(f"fmusweep: results in {r.out}/points.parquet"
          + (f", series in {r.out}/series/" if results.meta["spec"].get("outputs", {}).get("series") else ""))
    for path in results.plots:
        print(f"fmusweep: plot {path}")
    if results.report_html is not None:
        print(f"fmusweep: report {results.report_html} (open it in a browser)")
    return 0


def _interval(bounds: list[float | None], profile: bool) -> str:
    """A printed interval; a profile's missing bound is open, a Wald one's undetermined."""
    low, high = bounds
    if not profile and (low is None or high is None):
        return "undetermined"
    return (f"[{'open' if low is None else f'{low:.6g}'}, "
            f"{'open' if high is None else f'{high:.6g}'}]")


def fit_main(argv: Sequence[str]) -> int:
    from .fitting import fit
    parser = argparse.ArgumentParser(prog="fmusweep fit", description="Fit an FMU's parameters "
                                     "to measurements on the sweep engine; writes OUT/fit.json "
                                     "and plots.", epilog=FIT_EXAMPLE,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("spec", help="the fit specification (TOML)")
    _engine_arguments(parser)
    parser.add_argument("--out", help="output directory (default: fit-<spec digest>)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the fit in --out: points it evaluated are read, not run")
    args = parser.parse_args(argv)
    result = _guarded("fmusweep fit", "every evaluated point is saved", lambda: fit(
        args.spec, fmu=args.fmu, out=args.out, workers=args.workers, scheduler=args.scheduler,
        serial=args.serial, resume=args.resume, plots=not args.no_plots))
    if isinstance(result, int):
        return result
    s = result.summary
    print(f"fmusweep fit: {s['status']} after {s['iterations']} iterations, cost {s['cost']}, "
          f"{s['evaluations']} runs ({s['resumed']} made before or reused) in {s['wall_s']:.1f} s on "
          f"{s['workers']} worker(s), {s['engine']}")
    if s["engine_choice"] != "as asked":
        print(f"fmusweep fit: engine: {s['engine_choice']}")
    for name, p in s["parameters"].items():
        wald, profile = p["wald_ci95"], p.get("profile_ci95")
        said = (_interval(p["ci95"], False) if profile is None
                else f"Wald {_interval(wald, False)}, profile {_interval(profile, True)}")
        print(f"  {name} = {p['estimate']:.6g}  (95 %: {said})")
    for warning in s["warnings"]:
        print(f"fmusweep fit: warning: {warning}")
    print(f"fmusweep fit: results in {result.out}/fit.json, every run in {result.out}/points.parquet")
    for path in result.plots:
        print(f"fmusweep fit: plot {path}")
    if (result.out / "report.html").exists():
        print(f"fmusweep fit: report {result.out / 'report.html'} (open it in a browser)")
    return 0 if s["status"] != "failed" else 1
