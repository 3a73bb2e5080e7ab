"""Where batches of points run: this process (serial) or Dask (a LocalCluster of
single-threaded worker processes, or an existing cluster). A sweep streams its batches
through a pool; a fit asks it for a few points at a time and waits for them. What a
batch does lives in ``worker`` (or ``ssp``); the pool only places and collects it."""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any, ContextManager

import numpy as np

from .errors import EngineError, SpecError
from .native import failed_result
from .records import Batch, BatchFunction, Plan, PointResult, Points, PrepareFunction, Rows

__all__ = ["Pool", "Task", "IN_FLIGHT_PER_WORKER", "without_message_log", "check_engine"]

# What a chunk of points runs: its plan, the names it sets and its rows.
Task = tuple[Plan, list[str], Rows]

# Batches in flight per worker on Dask: one running and the next ones queued, so that no
# worker waits; the rest stay with the caller as indices until a slot frees.
IN_FLIGHT_PER_WORKER = 3


class Pool:
    """Runs ``batch_function(target, plan, names, rows, points)`` on chunks of points.

    Use as a context manager: entering starts (or connects to) the cluster, ships the
    target to every worker once and has each worker prepare itself (unpack, start its
    runner); leaving closes what entering opened. With ``serial`` nothing starts and
    batches run here, one at a time (``run`` is then safe to call from several threads:
    they take turns)."""

    def __init__(self, target: object, functions: tuple[BatchFunction, PrepareFunction],
                 plan: Plan, *, workers: int | None = None, scheduler: str | None = None,
                 serial: bool = False, prefix: str = "fmusweep-"):
        self.target = target
        self.batch_function, self.prepare_function = functions
        self.plan = plan
        self.serial = serial
        self.scheduler = scheduler
        self.requested_workers = workers
        self.prefix = prefix
        self.workers = 1
        self._addresses: list[str] = []
        self.startup_s = 0.0
        self.client: Any = None
        self._cluster: Any = None
        self._target_future: Any = None
        self._serial_lock = threading.Lock()
        self._keys = itertools.count()

    @property
    def named(self) -> bool:
        """Whether the caller chose the engine (serial, a number of workers, a scheduler)."""
        return self.serial or self.requested_workers is not None or self.scheduler is not None

    @property
    def engine(self) -> str:
        return "serial" if self.serial else (self.scheduler or "LocalCluster")

    # --- life ------------------------------------------------------------------------
    def __enter__(self) -> Pool:
        if not self.serial:
            t0 = time.perf_counter()
            self._connect()
            self.startup_s = time.perf_counter() - t0
        return self

    def __exit__(self, *exc: object) -> None:
        if self.client is not None:
            self.client.close()
        if self._cluster is not None:
            self._cluster.close()
        self.client = self._cluster = None

    def _connect(self) -> None:
        try:
            self._start()
        except (KeyboardInterrupt, EngineError):
            raise
        except Exception as e:
            self.__exit__()
            if self.scheduler:
                raise EngineError(f"cannot use the Dask scheduler at {self.scheduler}: "
                                  f"{_reason(e)}") from None
            raise EngineError(f"the LocalCluster of {self.requested_workers or os.cpu_count()} "
                              f"worker(s) did not start: {_reason(e)} (a script that starts "
                              "a study calls it under `if __name__ == \"__main__\":`)") from None

    def _start(self) -> None:
        from distributed import Client, LocalCluster
        if self.scheduler:
            self.client = Client(self.scheduler, timeout="10s")
        else:
            with _children_ignore_interrupts():
                self._cluster = LocalCluster(
                    n_workers=self.requested_workers or os.cpu_count() or 1,
                    threads_per_worker=1, processes=True, dashboard_address=":0",
                    silence_logs=logging.ERROR)
            self.client = Client(self._cluster)
        client = self.client
        if not client.scheduler_info()["workers"]:
            client.wait_for_workers(1, timeout=60)
        addresses = list(client.scheduler_info()["workers"])
        self.workers = len(addresses)
        self._addresses = addresses
        # The target travels to every worker once; tasks carry only a reference to it.
        [self._target_future] = client.scatter([self.target], broadcast=True, hash=False)
        warm = [client.submit(self.prepare_function, self._target_future, self.plan,
                              workers=[address], pure=False, key=f"{self.prefix}warm-{i}")
                for i, address in enumerate(addresses)]
        client.gather(warm)
        for future in warm:
            future.release()

    # --- work ------------------------------------------------------------------------
    def stream(self, names: list[str], rows_of: Callable[[Points], Rows],
               chunks: Iterable[Points],
               key: Callable[[Points], str] | None = None) -> Iterator[Batch]:
        """Yield each chunk's batch as it finishes; `rows_of` gives a chunk's values, made
        only when the chunk is submitted.

        On Dask at most IN_FLIGHT_PER_WORKER batches per worker are submitted at a time,
        and each batch's future is released as soon as it is yielded, so that neither the
        workers nor the scheduler keep its result: memory stays flat whatever the count.
        A batch whose worker was lost again and again comes back as rows ``crashed``."""
        return self._stream(lambda chunk: (self.plan, names, rows_of(chunk)), chunks, key)

    def _stream(self, task_of: Callable[[Points], Task], chunks: Iterable[Points],
                key: Callable[[Points], str] | None = None) -> Iterator[Batch]:
        """``stream`` of chunks that each bring their own plan and names (`task_of`)."""
        if self.serial:
            for chunk in chunks:
                plan, names, rows = task_of(chunk)
                with self._serial_lock:
                    batch = self.batch_function(self.target, plan, names, rows, chunk)
                yield batch
            return
        from distributed import as_completed
        from distributed.scheduler import KilledWorker
        name = key or (lambda chunk: f"{self.prefix}{next(self._keys)}")
        waiting = iter(chunks)
        finished = as_completed()
        pending: dict[Any, tuple[Points, Plan]] = {}

        def submit_next(worker: str | None = None) -> None:
            chunk = next(waiting, None)
            if chunk is not None:
                plan, names, rows = task_of(chunk)
                future = self.client.submit(self.batch_function, self._target_future, plan,
                                            names, rows, chunk, key=name(chunk), pure=False,
                                            workers=[worker] if worker else None,
                                            allow_other_workers=worker is not None)
                pending[future] = (chunk, plan)
                finished.add(future)

        try:
            # The first batches dealt to the workers in turn, so that every worker starts
            # busy: left to itself, the scheduler may queue them all on one worker while
            # its estimate of their length is still unknown. A worker that is lost hands
            # its batch on (allow_other_workers); later batches go wherever one frees up.
            for i in range(IN_FLIGHT_PER_WORKER * max(self.workers, 1)):
                submit_next(self._addresses[i % len(self._addresses)] if self._addresses else None)
            for future in finished:
                chunk, plan = pending.pop(future)
                try:
                    batch = future.result()
                except KilledWorker as e:
                    lost = failed_result("crashed", f"the batch failed on the cluster: {e!r}",
                                         plan)
                    batch = {"points": chunk, "worker": "",
                             "results": [PointResult(**lost) for _ in chunk]}
                future.release()
                del future
                submit_next()
                yield batch
        finally:
            for future in pending:
                future.cancel()

    def run(self, names: list[str], rows: Rows, plan: Plan | None = None) -> list[PointResult]:
        """Every row's result, in order: the rows cut into one batch per worker, run at
        once (under `plan`, else the pool's), and gathered."""
        return self.run_each([(plan or self.plan, names, rows)])[0]

    def run_each(self, tasks: list[Task]) -> list[list[PointResult]]:
        """Each task's results, in order, every task's rows in flight at once: the rows cut
        into about one batch per worker overall, none of them mixing two tasks."""
        tasks = [(plan, names, np.asarray(rows, dtype=float).reshape(len(rows), len(names)))
                 for plan, names, rows in tasks]
        offsets = np.cumsum([0] + [len(rows) for _, _, rows in tasks])
        total = int(offsets[-1])
        chunks: list[Points] = []
        for k, (_, names, rows) in enumerate(tasks):
            share = 1 if self.serial else max(1, round(self.workers * len(rows) / max(total, 1)))
            parts = min(len(rows), share)
            chunks += [c + offsets[k] for c in np.array_split(np.arange(len(rows)), max(parts, 1))
                       if len(c)]

        def task_of(chunk: Points) -> Task:
            k = int(np.searchsorted(offsets, chunk[0], side="right")) - 1
            plan, names, rows = tasks[k]
            return plan, names, rows[chunk - offsets[k]]

        results: list[PointResult | None] = [None] * total
        for batch in self._stream(task_of, chunks):
            for i, result in zip(batch["points"], batch["results"]):
                results[int(i)] = PointResult(**result, worker=batch["worker"])
        return [[r for r in results[offsets[k]:offsets[k + 1]] if r is not None]
                for k in range(len(tasks))]

    def held_by_scheduler(self) -> int | None:
        """How many finished batches of this pool the scheduler still holds in memory
        (its own accounting; None without Dask)."""
        if self.client is None:
            return None
        prefix = self.prefix

        def held(dask_scheduler: Any = None) -> int:
            # Defined here to travel by value: the scheduler need not have this package.
            return sum(1 for key, task in dask_scheduler.tasks.items()
                       if str(key).startswith(prefix) and task.state == "memory")

        # The releases travel on the client's batched stream and the question on another
        # connection: a second to let them arrive. A result held for good stays counted.
        deadline = time.monotonic() + 1.0
        while (count := int(self.client.run_on_scheduler(held))) and time.monotonic() < deadline:
            time.sleep(0.02)
        return count


@contextlib.contextmanager
def _children_ignore_interrupts() -> Iterator[None]:
    """Ctrl-C reaches every process of the terminal's group: the LocalCluster's worker
    processes, started meanwhile, inherit an ignored SIGINT (Python then installs no
    handler of its own), so that only this process hears it and closes them, without their
    tracebacks. Outside the main thread signals cannot be changed, and nothing is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _reason(e: BaseException) -> str:
    said = str(e).strip().splitlines()
    return f"{type(e).__name__}: {said[0]}" if said else type(e).__name__


def check_engine(workers: object, scheduler: object, serial: bool) -> None:
    """The engine's options, before anything runs: one engine at a time, and a number of
    workers that is one (a LocalCluster's size, not the workers of another cluster)."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise SpecError("workers", f"must be a whole number ≥ 1, got {workers!r} (--serial "
                                   "runs in this process without Dask)")
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise SpecError("scheduler", f"must be a Dask scheduler's address, tcp://HOST:PORT, "
                                     f"got {scheduler!r}")
    if serial and (workers is not None or scheduler is not None):
        other = "workers" if workers is not None else "scheduler"
        raise SpecError("serial", f"runs in this process without Dask: give it or {other}, "
                                  "not both")
    if workers is not None and scheduler is not None:
        raise SpecError("workers", "sizes the LocalCluster started here; with scheduler the "
                                   "points run on that cluster's own workers: give one of the two")
    if isinstance(scheduler, str) and scheduler.strip():
        _reachable(scheduler.strip())


# How long the scheduler's address may take to answer before the run is refused, seconds.
REACH_S = 5.0


def _reachable(address: str) -> None:
    """A scheduler at a TCP address answers within REACH_S, or the run is refused before
    anything runs (Dask's own connect waits 30 s, after the first points have run)."""
    import socket
    from urllib.parse import urlsplit
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    if parts.scheme not in ("tcp", "tls"):
        return  # another transport (inproc, ucx): Dask's own connect says
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if not host or port is None:
        raise SpecError("scheduler", f"must be a Dask scheduler's address, tcp://HOST:PORT, "
                                     f"got {address!r}")
    try:
        socket.create_connection((host, port), timeout=REACH_S).close()
    except OSError as e:
        reason = "no answer" if isinstance(e, TimeoutError) else (e.strerror or str(e))
        raise EngineError(f"cannot reach the Dask scheduler at {address}: {reason} within "
                          f"{REACH_S:g} s (start one with `dask scheduler`, or leave out "
                          "--scheduler to run on a LocalCluster here)") from None


def without_message_log(serial: bool = False) -> ContextManager[object]:
    """Dask keeps the last messages of every connection for debugging (1000 by default),
    and a task's message carries its batch's rows: the sweep's client and, in a
    LocalCluster, the scheduler and workers would grow by each batch up to that many.
    A serial run does not import Dask at all."""
    if serial:
        return contextlib.nullcontext()
    import dask
    import distributed  # noqa: F401  (its defaults must be in dask's config before the set)
    return dask.config.set({"distributed.admin.low-level-log-length": 0})
