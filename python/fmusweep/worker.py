"""The work of one batch, wherever it runs: this process (serial), a LocalCluster worker,
or a worker of an existing cluster. It needs only this package and the FMU's bytes."""

from __future__ import annotations

import os

import numpy as np

from .fmu import FmuBytes, local_runner

__all__ = ["run_batch", "worker_name"]


def worker_name() -> str:
    try:
        from distributed import get_worker
        return str(get_worker().name)
    except (ImportError, ValueError):
        return f"local-{os.getpid()}"


def run_batch(fmu: FmuBytes, plan: dict, names: list[str], rows: np.ndarray,
              points: np.ndarray) -> dict:
    _trace("start", points)
    runner = local_runner(fmu)
    if runner.plan != plan:
        runner.configure(plan)
    results = runner.run(names, rows)
    _trace("end", points)
    return {"points": points, "results": results, "worker": worker_name()}


def _trace(event: str, points):
    """With $FMUSWEEP_TRACE naming a file, an audit line per batch started and ended
    (event, first point, count): how the tests count recomputation after a kill."""
    trace = os.environ.get("FMUSWEEP_TRACE")
    if trace:
        with open(trace, "a") as f:
            f.write(f"{event} {int(points[0])} {len(points)}\n")
