"""``python -m fmusweep SPEC.toml [--fmu F] [--workers N] [--scheduler ADDRESS] [--out DIR]
[--resume] [--serial] [--batch-size N]``: run a sweep and print where its results are.
``python -m fmusweep fit SPEC.toml [same engine options]``: fit parameters to data."""

from __future__ import annotations

import argparse
import logging
import os
import signal
import threading
import sys
import warnings
from typing import Any, Callable, Sequence, TypeVar

from . import __version__
from .errors import EngineError, SpecError, SpecErrors
from .native import RunnerError
from .sweep import run_sweep

DESCRIPTION = ("Run a sweep of an FMU's parameters and print where its results are; "
               "'fmusweep fit SPEC' fits parameters to measured data instead.")

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

ENGINE_ERRORS = (SpecError, RunnerError, EngineError, FileExistsError, FileNotFoundError,
                 ValueError)


class Terminated(KeyboardInterrupt):
    """SIGTERM (or the parent's end), ending a run as Ctrl-C does: what finished is kept."""


# Set once a run is being interrupted: what the cluster's event loop then logs of the
# calls cut short (distributed's `sync` may fail to cancel a call not yet started, a
# NameError its own callback logs) is the interrupt's, not a fault to show.
_ENDING = threading.Event()


def _on_sigterm(signum: int, frame: object) -> None:
    _ENDING.set()
    raise Terminated()


def _on_sigint(signum: int, frame: object) -> None:
    _ENDING.set()
    raise KeyboardInterrupt()


class _QuietWhileEnding(logging.Filter):
    """Drops the event loop's records once the run is being interrupted."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not _ENDING.is_set()


# Where the cluster's event loop logs calls cut short by an interrupt (a closed comm's
# traceback among them). A logger's filter does not reach its children: each is named.
_EVENT_LOOP_LOGGERS = ("tornado.application", "asyncio", "distributed", "distributed.client",
                       "distributed.core", "distributed.comm.tcp", "distributed.batched",
                       "distributed.utils", "distributed.worker", "distributed.nanny",
                       "distributed.scheduler", "distributed.deploy.spec")


def _end_with_parent() -> None:
    """SIGTERM when the process that started this one ends (``cargo xtask sweep`` killed),
    so that no sweep goes on as an orphan; Linux only, asked for by FMUSWEEP_END_WITH_PARENT."""
    if os.environ.get("FMUSWEEP_END_WITH_PARENT") != "1" or not sys.platform.startswith("linux"):
        return
    import ctypes
    pr_set_pdeathsig = 1
    ctypes.CDLL(None).prctl(pr_set_pdeathsig, signal.SIGTERM)
    if os.getppid() == 1:  # the parent ended before the request took effect
        raise Terminated()

T = TypeVar("T")


ENGINE_CHOICE = ("Without --serial, --workers or --scheduler the engine is chosen after the "
                 "first points, which run here: serial when the rest would take less time "
                 "serially than starting a LocalCluster and sharing the rest among its "
                 "workers, else a LocalCluster of one worker per core; the run's last lines "
                 "say which and why.")


def _engine_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fmu", help="the FMU, when the spec names none (or to override it)")
    engine = parser.add_argument_group("engine", ENGINE_CHOICE)
    engine.add_argument("--workers", type=int, help="LocalCluster worker processes (default: every core)")
    engine.add_argument("--scheduler", help="address of an existing Dask scheduler, tcp://HOST:PORT")
    engine.add_argument("--serial", action="store_true", help="no Dask: run in this process")
    parser.add_argument("--no-plots", action="store_true",
                        help="no plots and no report.html (sensitivity indices are still computed)")


def _guarded(prog: str, kept: str, run: Callable[[], T]) -> T | int:
    """run()'s result, or the exit code after a refusal (2) or an interrupt (130), each
    said on standard error."""
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    # As Python's own, but marking the interrupt first; left alone where SIGINT is ignored.
    interrupt = signal.getsignal(signal.SIGINT)
    if interrupt is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
    quiet = _QuietWhileEnding()
    for name in _EVENT_LOOP_LOGGERS:
        logging.getLogger(name).addFilter(quiet)
    shown = warnings.showwarning
    warnings.showwarning = lambda message, category, *_: print(
        f"{prog}: warning: {message}", file=sys.stderr)
    try:
        _end_with_parent()
        return run()
    except ENGINE_ERRORS as e:
        print(f"{prog}: {_as_option(e)}", file=sys.stderr)
        return 2
    except Exception:
        if not _ENDING.is_set():
            raise
        # A call cut short by the interrupt (a closed comm, a cancelled future) is the
        # interrupt's own end, said as such.
        return _interrupted(prog, kept, False)
    except KeyboardInterrupt as e:
        return _interrupted(prog, kept, isinstance(e, Terminated))
    finally:
        signal.signal(signal.SIGTERM, previous)
        if interrupt is signal.default_int_handler:
            signal.signal(signal.SIGINT, interrupt)
        for name in _EVENT_LOOP_LOGGERS:
            logging.getLogger(name).removeFilter(quiet)
        _ENDING.clear()
        warnings.showwarning = shown


def _interrupted(prog: str, kept: str, terminated: bool) -> int:
    ended = "terminated" if terminated else "interrupted"
    print(f"{prog}: {ended}; {kept}: run the same command again with --resume", file=sys.stderr)
    return 143 if terminated else 130


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["fit"]:
        return fit_main(argv[1:])
    parser = argparse.ArgumentParser(prog="fmusweep", description=DESCRIPTION,
                                     epilog=EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"fmusweep {__version__}")
    parser.add_argument("spec", help="the sweep specification (TOML); 'python -m fmusweep fit "
                                     "SPEC' runs a fit (see 'fit --help')")
    _engine_arguments(parser)
    parser.add_argument("--out", help="output directory (default: a new results/SPEC-DATE-TIME)")
    parser.add_argument("--resume", action="store_true", help="finish the sweep in --out (default: "
                        "the newest one of this spec in results/), redoing only missing points")
    parser.add_argument("--batch-size", type=int, help="points per task (default: about 0.5 s of work)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    results = _guarded("fmusweep", "every finished batch is saved", lambda: run_sweep(
        args.spec, fmu=args.fmu, out=args.out, workers=args.workers, scheduler=args.scheduler,
        serial=args.serial, resume=args.resume, batch_size=args.batch_size,
        progress=not args.no_progress, plots=not args.no_plots))
    if isinstance(results, int):
        return results
    r = results.summary
    assert r is not None  # a sweep just run reports itself
    counts = ", ".join(f"{n} {s}" for s, n in sorted(r.statuses.items())) or "nothing new"
    print(f"fmusweep: {_count(r.points, 'point')} ({r.resumed} already done; computed: "
          f"{counts}) in {r.wall_s:.1f} s on {_count(r.workers, 'worker')}, {r.engine}, "
          f"batches of {r.batch_size}")
    if r.engine_choice != "as asked":
        print(f"fmusweep: engine: {r.engine_choice}")
    for note in results.notes:
        print(f"fmusweep: no indices for {note}")
    print(f"fmusweep: results in {r.out}/points.parquet"
          + (f", series in {r.out}/series/" if results.meta["spec"].get("outputs", {}).get("series") else ""))
    for path in results.plots:
        print(f"fmusweep: plot {path}")
    if results.report_html is not None:
        print(f"fmusweep: report {results.report_html} (open it in a browser)")
    return 0


def _beyond(p: dict[str, Any]) -> str:
    """A word when an interval reaches past the parameter's range, which bounds the fit
    but not the linearised (Wald) interval."""
    low, high = p.get("range", (None, None))
    bounds = [b for b in (p.get("wald_ci95") or p["ci95"]) if b is not None]
    if low is None or high is None or not bounds:
        return ""
    if min(bounds) < low or max(bounds) > high:
        return f"; the interval reaches past the range [{low:g}, {high:g}] the fit keeps to"
    return ""


# The engine's arguments, which the command line gives as options.
OPTIONS = ("workers", "scheduler", "serial", "batch_size", "resume")


def _as_option(e: Exception) -> str:
    """A refusal of an engine argument names its option (--workers, not workers)."""
    if isinstance(e, SpecError) and not isinstance(e, SpecErrors) and e.field in OPTIONS:
        return f"--{e.field.replace('_', '-')}: {e.rule}"
    return str(e)


def _count(n: int, what: str) -> str:
    return f"{n} {what}" if n == 1 else f"{n} {what}s"


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
    parser.add_argument("--out", help="output directory (default: a new results/SPEC-DATE-TIME)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the fit in --out (default: the newest one of this spec "
                             "in results/): points it evaluated are read, not run")
    args = parser.parse_args(argv)
    result = _guarded("fmusweep fit", "every evaluated point is saved", lambda: fit(
        args.spec, fmu=args.fmu, out=args.out, workers=args.workers, scheduler=args.scheduler,
        serial=args.serial, resume=args.resume, plots=not args.no_plots))
    if isinstance(result, int):
        return result
    s = result.summary
    cost = "none" if s["cost"] is None else f"{s['cost']:.6g}"
    print(f"fmusweep fit: {s['status']} after {_count(s['iterations'] or 0, 'iteration')}, cost "
          f"{cost}, {_count(s['computed'], 'run')} made ({s['resumed']} repeated points answered "
          f"without a run) in {s['wall_s']:.1f} s on {_count(s['workers'], 'worker')}, "
          f"{s['engine']}")
    if s["engine_choice"] != "as asked":
        print(f"fmusweep fit: engine: {s['engine_choice']}")
    for name, p in s["parameters"].items():
        wald, profile = p["wald_ci95"], p.get("profile_ci95")
        said = (_interval(p["ci95"], False) if profile is None
                else f"Wald {_interval(wald, False)}, profile {_interval(profile, True)}")
        print(f"  {name} = {p['estimate']:.6g}  (95 %: {said}){_beyond(p)}")
    for warning in s["warnings"]:
        print(f"fmusweep fit: warning: {warning}")
    print(f"fmusweep fit: results in {result.out}/fit.json, every run in {result.out}/points.parquet")
    for path in result.plots:
        print(f"fmusweep fit: plot {path}")
    if (result.out / "report.html").exists():
        print(f"fmusweep fit: report {result.out / 'report.html'} (open it in a browser)")
    return 0 if s["status"] != "failed" else 1
