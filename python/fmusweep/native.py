"""The client of the native runner (`fmu-runner`, the Rust program in ``runner/``).

One runner process per FMU per worker: it loads the FMU's binary once, keeps one
instance and resets it between points, and runs each point's master loop, metrics and
decimation natively. This module only sends it batches and reads its replies. A crash of
the FMU kills only the runner. The runner answers point by point but flushes its replies
every 20 ms, so the replies of the last few points may die with it: the points without a
reply are run again by a new runner that flushes after every point, and the first point
without a reply then is the one that crashed (``crashed``); the batch goes on after it. A
point whose single step hangs past the hard deadline is ``timeout`` the same way.
"""

from __future__ import annotations

import json
import os
import pathlib
import select
import shutil
import signal
import subprocess
import sys
import sysconfig
import tempfile
import time
from typing import IO, Any

import numpy as np

from .errors import SpecError, SpecErrors
from .records import Plan, PointResult

__all__ = ["RunnerError", "NativeRunner", "runner_path", "failed_result"]

RUNNER = "fmu-runner"


class RunnerError(RuntimeError):
    """The runner could not start, or refused a request (the message says why)."""


def runner_path() -> pathlib.Path:
    """The `fmu-runner` program: $FMUSWEEP_RUNNER, else the one installed with this package
    (among the environment's scripts, beside the `fmusweep` command)."""
    override = os.environ.get("FMUSWEEP_RUNNER")
    if override:
        candidates = [pathlib.Path(override)]
    else:
        # The interpreter's own scripts directory first: a venv's Python run by its path
        # has no bin/ of its own on PATH.
        candidates = [pathlib.Path(sysconfig.get_path("scripts")) / RUNNER,
                      pathlib.Path(sys.executable).parent / RUNNER,
                      pathlib.Path(sysconfig.get_path("scripts", f"{os.name}_user")) / RUNNER]
        found = shutil.which(RUNNER)
        if found:
            candidates.append(pathlib.Path(found))
    path = next((c for c in candidates if c.is_file()), candidates[0])
    if not path.is_file():
        raise RunnerError(
            f"the native runner is missing ({path}): install the package (`pip install ./python`, "
            "or the wheel that `cargo xtask wheel` builds), or point FMUSWEEP_RUNNER at "
            "target/release/fmu-runner")
    return path


def describe_unpacked(directory: str | os.PathLike[str]) -> dict[str, Any]:
    """The description of the FMU unpacked in `directory`, as the runner reads it (its one
    reader of modelDescription.xml) without loading the FMU's binary."""
    done = subprocess.run([str(runner_path()), "describe", str(directory)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RunnerError(done.stderr.strip() or f"the runner exited with {done.returncode}")
    description: dict[str, Any] = json.loads(done.stdout)["description"]
    return description


# How much longer than the per-point budget a point may go without any answer before the
# runner is killed: the runner itself checks the budget after every communication step,
# so only a step that never returns reaches this.
HARD_DEADLINE_FACTOR = 2.0
HARD_DEADLINE_GRACE_S = 5.0


class _Pipe:
    """Lines and exact byte counts from a pipe, each with a deadline."""

    def __init__(self, fd: int):
        self.fd = fd
        self.buffer = bytearray()

    def _fill(self, deadline: float | None) -> bool:
        timeout = None if deadline is None else max(0.0, deadline - time.monotonic())
        ready, _, _ = select.select([self.fd], [], [], timeout)
        if not ready:
            raise TimeoutError
        chunk = os.read(self.fd, 1 << 20)
        if not chunk:
            return False
        self.buffer += chunk
        return True

    def line(self, deadline: float | None) -> bytes | None:
        while True:
            end = self.buffer.find(b"\n")
            if end >= 0:
                line = bytes(self.buffer[:end])
                del self.buffer[:end + 1]
                return line
            if not self._fill(deadline):
                return None

    def exactly(self, n: int, deadline: float | None) -> bytes | None:
        while len(self.buffer) < n:
            if not self._fill(deadline):
                return None
        data = bytes(self.buffer[:n])
        del self.buffer[:n]
        return data


class NativeRunner:
    """One `fmu-runner serve DIR` process for the FMU unpacked in `fmu_dir`."""

    def __init__(self, fmu_dir: str | os.PathLike[str]):
        self.fmu_dir = pathlib.Path(fmu_dir)
        self.plan: Plan | None = None
        self.series_width = 0
        self.restarts = 0
        self._start()

    # --- process ---------------------------------------------------------------------
    def _start(self) -> None:
        self._stderr = tempfile.TemporaryFile()
        self.process = subprocess.Popen(
            [str(runner_path()), "serve", str(self.fmu_dir)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._stderr)
        self.pipe = _Pipe(_opened(self.process.stdout).fileno())
        hello = self._reply(deadline=time.monotonic() + 60)
        if hello is None or "ready" not in hello:
            reason = (hello or {}).get("error") or self._died()
            self.close()
            raise RunnerError(f"the runner could not load the FMU: {reason}")
        if self.plan is not None:
            self._configure(self.plan)

    def _died(self) -> str:
        """Why the process ended, with the end of what it wrote to standard error."""
        code = self.process.wait()
        what = (f"signal {signal.Signals(-code).name}" if code < 0 else f"exit code {code}")
        self._stderr.seek(0)
        tail = self._stderr.read().decode(errors="replace").strip().splitlines()[-3:]
        return f"the runner process died ({what})" + (f"; it said: {' / '.join(tail)}" if tail else "")

    def _restart(self) -> None:
        self.close()
        self.restarts += 1
        self._start()

    def close(self) -> None:
        process = getattr(self, "process", None)
        if process is not None and process.poll() is None:
            try:
                _opened(process.stdin).close()
                process.wait(timeout=2)
            except (OSError, subprocess.TimeoutExpired):
                process.kill()
                process.wait()
        if process is not None:
            _opened(process.stdout).close()

    def __enter__(self) -> NativeRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- requests --------------------------------------------------------------------
    def _send(self, request: dict[str, Any]) -> None:
        stdin = _opened(self.process.stdin)
        stdin.write(json.dumps(request).encode() + b"\n")
        stdin.flush()

    def _reply(self, deadline: float | None = None) -> dict[str, Any] | None:
        line = self.pipe.line(deadline)
        if line is None:
            return None
        reply: dict[str, Any] = json.loads(line)
        return reply

    def _request(self, request: dict[str, Any]) -> dict[str, Any]:
        try:
            self._send(request)
            reply = self._reply()
        except BrokenPipeError:
            reply = None
        if reply is None:
            raise RunnerError(self._died())
        if reply.get("refusals"):
            refused = [SpecError(r["field"], r["rule"]) for r in reply["refusals"]]
            raise refused[0] if len(refused) == 1 else SpecErrors(refused)
        if "error" in reply:
            raise RunnerError(reply["error"])
        return reply

    def describe(self) -> dict[str, Any]:
        description: dict[str, Any] = self._request({"op": "describe"})["description"]
        return description

    def _configure(self, plan: Plan) -> list[str]:
        # The chains are the client's: the runner hears of them with each run.
        theirs = {k: v for k, v in plan.items() if k != "chain"}
        answer = self._request({"op": "configure", "plan": theirs})
        # The numbers in a row of a point's series (its time first): the runner's count.
        self.series_width = int(answer["series_width"])
        reads: list[str] = answer["reads"]
        return reads

    def configure(self, plan: Plan) -> list[str]:
        """Set the plan of the following runs; returns the variables read per point."""
        reads = self._configure(plan)
        self.plan = plan
        return reads

    def check(self, names: list[str], rows: Any) -> list[dict[str, str]]:
        """Each row set (in initialisation mode, nothing runs): status and message."""
        listed = np.asarray(rows, dtype=float).tolist()
        checked: list[dict[str, str]] = self._request(
            {"op": "check", "names": names, "rows": listed})["checked"]
        return checked

    def linearise(self, names: list[str], rows: Any) -> list[dict[str, Any]]:
        """Each row's point linearised at its initial state (a plan through the Model
        Exchange interface): status, and the linearisation or the message."""
        listed = np.asarray(rows, dtype=float).tolist()
        found: list[dict[str, Any]] = self._request(
            {"op": "linearise", "names": names, "rows": listed})["linearised"]
        return found

    def bare(self, names: list[str], rows: Any) -> float:
        listed = np.asarray(rows, dtype=float).tolist()
        return float(self._request({"op": "bare", "names": names, "rows": listed})["seconds"])

    def run(self, names: list[str], rows: Any,
            chains: list[int] | None = None) -> list[PointResult]:
        """Run every row; one result dict per row, in order, whatever happens to the
        runner on the way. Each has status, message, metrics, t_end, steps, wall_s and,
        when the plan records one, series (an array of rows t, variables…). `chains` are
        the lengths of the runs of rows that continue each other's steady cycles (by
        default the rows are one)."""
        values = np.asarray(rows, dtype=float)
        starts = np.zeros(len(values), dtype=bool)
        starts[np.cumsum([0] + list(chains or [len(values)]))[:-1]] = True
        results: list[PointResult] = []
        while len(results) < len(values):
            answered, lost = self._run_until_failure(names, values[len(results):],
                                                     _lengths(starts[len(results):]), False)
            results += answered
            if lost:
                # Which point was it? Only a runner that flushes every reply can say.
                rest = starts[len(results):]
                results += self._run_until_failure(names, values[len(results):],
                                                   _lengths(rest), True)[0]
        return results

    def _hard_deadline(self) -> float | None:
        budget = self.plan.get("timeout_s") if self.plan is not None else None
        if budget is None:
            return None
        return time.monotonic() + HARD_DEADLINE_FACTOR * budget + HARD_DEADLINE_GRACE_S

    def _run_until_failure(self, names: list[str], rows: Any, chains: list[int],
                           careful: bool) -> tuple[list[PointResult], bool]:
        """The rows' results in order, and whether the runner was lost (killed by the FMU
        or by the hard deadline; it is then restarted). With `careful` the runner flushes
        every reply, so the point after the last reply is the one that failed, and its row
        ends the results; without, the results stop at the last reply received."""
        plan = self.plan
        assert plan is not None, "configure the runner before running points"
        width = self.series_width
        results: list[PointResult] = []
        try:
            self._send({"op": "run", "names": names, "rows": rows.tolist(), "flush_each": careful,
                        "chains": chains})
            while True:
                header = self._reply(self._hard_deadline())
                if header is None:
                    break
                if "error" in header:
                    raise RunnerError(header["error"])
                if "done" in header:
                    return results, False
                rows_n = header.pop("series_rows")
                if rows_n:
                    data = self.pipe.exactly(rows_n * width * 8, self._hard_deadline())
                    if data is None:
                        break
                    header["series"] = np.frombuffer(data, dtype="<f8").reshape(rows_n, width)
                results.append(PointResult(**header))  # type: ignore[typeddict-item]
        except TimeoutError:
            self.process.kill()
            if careful:
                message = (f"no answer within {HARD_DEADLINE_FACTOR} × the budget of "
                           f"{plan['timeout_s']} s + {HARD_DEADLINE_GRACE_S} s: the runner "
                           "was killed")
                results.append(failed_result("timeout", message, plan))
            self._restart()
            return results, True
        except BrokenPipeError:
            pass
        if careful:
            message = self._died() + " while running this point"
            results.append(failed_result("crashed", message, plan))
        self._restart()
        return results, True


def _lengths(starts: Any) -> list[int]:
    """The lengths of the chains that `starts` (where a row starts one) cut rows into; the
    first row starts one whatever it says (nothing before it ran in the request)."""
    at = np.flatnonzero(starts).tolist()
    if len(starts) and (not at or at[0] != 0):
        at = [0] + at
    return np.diff(at + [len(starts)]).tolist()


def failed_result(status: str, message: str, plan: Plan) -> PointResult:
    """The result of a point that ended without a reply of the runner's."""
    cycle = plan.get("cycle")
    metrics = cycle["metrics"] if cycle else plan.get("metrics") or []
    return {"status": status, "message": message, "metrics": [None] * len(metrics),
            "t_end": None, "steps": None, "wall_s": None}


def _opened(stream: IO[bytes] | None) -> IO[bytes]:
    """A pipe of the runner's process, which Popen opened (it asked for PIPE)."""
    assert stream is not None
    return stream
