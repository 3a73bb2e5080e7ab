"""The work of one batch, wherever it runs: this process (serial), a LocalCluster worker,
or a worker of an existing cluster. It needs only this package and the FMU's bytes."""

from __future__ import annotations

import os
import sys

from .designs.base import chains_of
from .fmu import Archive, local_runner
from .native import NativeRunner
from .records import Batch, Plan, Points, Rows

__all__ = ["prepare_worker", "run_batch", "worker_name", "trace"]


def worker_name() -> str:
    """Where a batch ran, as the ``worker`` column says it: ``worker-NAME`` on a Dask
    worker (a LocalCluster's are numbered from 0), ``client`` in the process that runs the
    study (serially, or the first points that measure a batch's size)."""
    # Only a process that Dask started has a worker; importing distributed costs 0.3 s.
    if "distributed" in sys.modules:
        try:
            return f"worker-{sys.modules['distributed'].get_worker().name}"
        except ValueError:
            pass
    return "client"


def _configured_runner(fmu: Archive, plan: Plan) -> NativeRunner:
    runner = local_runner(fmu)
    if runner.plan != plan:
        runner.configure(plan)
    return runner


def prepare_worker(fmu: Archive, plan: Plan) -> str:
    """Unpack the FMU, start and configure this worker's runner: the one-off costs."""
    _configured_runner(fmu, plan)
    return worker_name()


def run_batch(fmu: Archive, plan: Plan, names: list[str], rows: Rows, points: Points) -> Batch:
    trace("start", points)
    rule = plan.get("chain")
    chains = [len(c) for c in chains_of(points, **rule)] if rule else None
    results = _configured_runner(fmu, plan).run(names, rows, chains)
    trace("end", points)
    return {"points": points, "results": results, "worker": worker_name()}


def trace(event: str, points: Points) -> None:
    """With $FMUSWEEP_TRACE naming a file, an audit line per batch started and ended
    (event, first point, count): how the tests count recomputation after a kill."""
    path = os.environ.get("FMUSWEEP_TRACE")
    if path:
        with open(path, "a") as f:
            f.write(f"{event} {int(points[0])} {len(points)}\n")
