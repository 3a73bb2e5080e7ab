"""``python -m fmusweep SPEC.toml [--fmu F] [--workers N] [--scheduler ADDRESS] [--out DIR]
[--resume] [--serial] [--batch-size N]``: run a sweep and print where its results are."""

from __future__ import annotations

import argparse
import sys

from . import __version__
from .engine import run_sweep
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="fmusweep", description=__doc__.split("\n\n")[0],
                                     epilog=EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"fmusweep {__version__}")
    parser.add_argument("spec", help="the sweep specification (TOML)")
    parser.add_argument("--fmu", help="the FMU, when the spec names none (or to override it)")
    parser.add_argument("--out", help="output directory (default: sweep-<spec digest>)")
    parser.add_argument("--workers", type=int, help="LocalCluster worker processes (default: every core)")
    parser.add_argument("--scheduler", help="address of an existing Dask scheduler, tcp://HOST:PORT")
    parser.add_argument("--serial", action="store_true", help="no Dask: run in this process")
    parser.add_argument("--resume", action="store_true", help="finish the sweep in --out, redoing only missing points")
    parser.add_argument("--batch-size", type=int, help="points per task (default: about 0.5 s of work)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--no-plots", action="store_true", help="no plots or sensitivity indices")
    args = parser.parse_args(argv)
    try:
        results = run_sweep(args.spec, fmu=args.fmu, out=args.out, workers=args.workers,
                            scheduler=args.scheduler, serial=args.serial, resume=args.resume,
                            batch_size=args.batch_size, progress=not args.no_progress,
                            plots=not args.no_plots)
    except (SpecError, RunnerError, FileExistsError, FileNotFoundError, ValueError) as e:
        print(f"fmusweep: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fmusweep: interrupted; every finished batch is saved: run again with --resume",
              file=sys.stderr)
        return 130
    r = results.report
    counts = ", ".join(f"{n} {s}" for s, n in sorted(r.statuses.items())) or "nothing new"
    print(f"fmusweep: {r.points} points ({r.resumed} already done; computed: {counts}) in "
          f"{r.wall_s:.1f} s on {r.workers} worker(s), {r.engine}, batches of {r.batch_size}")
    print(f"fmusweep: results in {r.out}/points.parquet"
          + (f", series in {r.out}/series/" if results.meta["spec"].get("outputs", {}).get("series") else ""))
    for path in results.plots:
        print(f"fmusweep: plot {path}")
    return 0
