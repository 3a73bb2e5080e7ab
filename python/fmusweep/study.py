"""What a sweep and a fit share, in the order they do it: open what runs (an FMU, a coupled
[system] or an SSP file) and describe it, check the spec against it (each study its own
checks), open the output store with the record of what ran, and place batches of points on
a pool (serially or on Dask). The sweep (``sweep``) streams a design through a study, the
fit (``fitting.run``) asks it for a few points at a time; neither opens, stores or places
anything itself."""

from __future__ import annotations

import hashlib
import json
import os
import pathlib
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, TypeVar

import numpy as np

from .errors import SpecError
from .fields import typed_by
from .fmu import Archive, open_for_checks
from .native import NativeRunner, RunnerError
from .pool import Pool, without_message_log
from .records import BatchFunction, Plan, PrepareFunction, Rows
from .spec import raise_all, read_source, read_sweep
from .ssp import check_ssp, describe_ssp, prepare_ssp_worker, run_ssp_batch
from .store import FORMAT, ResultStore, versions
from .system import System
from .worker import prepare_worker, run_batch

if TYPE_CHECKING:
    from .fitting.spec import FitSpec
    from .spec import Spec

__all__ = ["Target", "Study", "point_ids", "checked", "checked_sweep", "checked_fit",
           "spec_name", "RESULTS"]

S = TypeVar("S")


def checked_sweep(source: object, fmu: str | None) -> tuple[Spec, Target]:
    """A sweep's spec and what it runs, checked in one pass (``checked``)."""
    spec, target = checked("sweep", source, fmu)
    return spec, target


def checked_fit(source: object, fmu: str | None) -> tuple[FitSpec, Target]:
    """A fit's spec and what it runs, checked in one pass (``checked``)."""
    spec, target = checked("fit", source, fmu)
    return spec, target


def checked(kind: str, source: object, fmu: str | None) -> tuple[Any, Target]:
    """The spec of `source` (a ``sweep`` or a ``fit``) and what it runs, checked in one pass:
    its tables, the rules between them, the file or system that runs, every name and value
    against it and the runner's rules of the plan, every mistake raised together."""
    from .check import fit_against_target, sweep_against_target
    from .fitting.spec import read_fit
    raw, base_dir = _source(source)
    read = read_sweep if kind == "sweep" else read_fit
    against = sweep_against_target if kind == "sweep" else fit_against_target
    first = read(raw, base_dir)
    errors: list[SpecError] = []
    target = Target.opened(first, raw, base_dir, fmu, errors)
    description = target.description if target is not None else {}
    types = {v["name"]: (v["type"], v.get("items", {}), v.get("unit"))
             for v in description.get("variables", []) if "type" in v}
    with typed_by(types):
        reading: Any = read(raw, base_dir) if types else first
        errors = reading.errors + errors
        if target is not None and target.local is not None:
            errors += against(reading, description, target.local)
        raise_all(errors)
        spec = reading.spec()
    assert target is not None
    if target.local is None:
        check_ssp(spec, spec.points, description)
    return spec, target


def _source(source: object) -> tuple[dict[str, Any], pathlib.Path]:
    """A spec's table and the folder its paths are relative to (a Spec's own, as read)."""
    raw, base_dir = getattr(source, "raw", None), getattr(source, "base_dir", None)
    if isinstance(raw, dict) and isinstance(base_dir, pathlib.Path):
        return raw, base_dir
    return read_source(source, None, "a spec")


# Where a study writes when the caller names no folder: one folder a run, below this one
# in the working directory (git ignores it in this repository).
RESULTS = "results"


def spec_name(source: object, kind: str) -> str:
    """A study's name for its default folder: its TOML file's stem, else its kind."""
    return pathlib.Path(source).stem if isinstance(source, (str, pathlib.Path)) else kind


def output_folder(kind: str, name: str | None, digest: str) -> pathlib.Path:
    """A new folder for a run: results/NAME-YYYYmmdd-HHMMSS (-2, -3… when taken)."""
    base = pathlib.Path(RESULTS) / f"{name or kind}-{time.strftime('%Y%m%d-%H%M%S')}"
    folder, n = base, 1
    while folder.exists():
        n += 1
        folder = base.with_name(f"{base.name}-{n}")
    return folder


def resumable_folder(kind: str, name: str | None, digest: str) -> pathlib.Path:
    """The newest run of the same spec below results/, for a resume that names no folder."""
    runs = sorted(pathlib.Path(RESULTS).glob(f"{name or kind}-*/sweep.json"),
                  key=lambda p: p.stat().st_mtime, reverse=True)
    for meta in runs:
        try:
            if json.loads(meta.read_text()).get("spec_digest") == digest:
                return meta.parent
        except (OSError, ValueError):
            continue
    raise SpecError("resume", f"no earlier run of this {kind} below {RESULTS}/ to resume: "
                              "name its folder with out (--out)")


def point_ids(fmu_sha: str, spec_digest: str, names: list[str], rows: Rows) -> list[str]:
    """A stable id per point: a hash of the FMU, the scenario and the point's values."""
    prefix = f"{fmu_sha}|{spec_digest}|{','.join(names)}|".encode()
    return [hashlib.blake2b(prefix + np.ascontiguousarray(row).tobytes(),
                            digest_size=8).hexdigest() for row in rows]


@dataclass
class Target:
    """What a study runs: the bytes shipped to every worker, what the output records of
    it, its description, this process's runner for it (None for an SSP file, which runs
    through FMPy) and the functions a worker runs it with."""
    archive: Archive
    identity: dict[str, Any]
    description: dict[str, Any]
    local: NativeRunner | None
    run_batch: BatchFunction
    prepare: PrepareFunction

    @staticmethod
    def opened(reading: Any, raw: dict[str, Any], base_dir: pathlib.Path, fmu: str | None,
               errors: list[SpecError]) -> Target | None:
        """The FMU the caller names, else the spec's SSP file, [system] or FMU, else
        $FMUSWEEP_FMU, opened for the checks; its mistakes added to `errors` (None where it
        cannot be opened, or a [system] or SSP file whose own tables have mistakes)."""
        ssp = reading.ssp
        system: System | None = reading.system
        if fmu is None and (ssp is not None or raw.get("system") is not None) and system is None:
            if ssp is None or raw.get("system") is None or _engine(raw) != "fmpy":
                return None
            archive = _archive_of(base_dir / ssp, errors)
            if archive is None:
                return None
            return Target(archive, {"ssp_name": archive.name, "ssp_sha256": archive.sha256},
                          describe_ssp(archive), None, run_ssp_batch, prepare_ssp_worker)
        if system is not None and fmu is None:
            times = _times_of(reading)
            opened = system.opened(times[2] if times is not None else 1.0, errors)
            if opened is None:
                return None
            archive, local, description = opened
            identity: dict[str, Any] = {
                "system": {name: str(path) for name, path in system.components.items()},
                "connections": [str(c) for c in system.connections]}
            if ssp is not None:
                file = _archive_of(base_dir / ssp, errors)
                if file is not None:
                    identity.update(ssp_name=file.name, ssp_sha256=file.sha256)
            return Target(archive, identity, description, local, run_batch, prepare_worker)
        try:
            archive, local, description = open_for_checks(
                fmu, base_dir / reading.fmu if reading.fmu else None)
        except SpecError as e:
            errors.append(e)
            return None
        return Target(archive, {"fmu_name": archive.name, "fmu_guid": description["guid"]},
                      description, local, run_batch, prepare_worker)

    @property
    def sha256(self) -> str:
        return self.archive.sha256


def _archive_of(path: pathlib.Path, errors: list[SpecError]) -> Archive | None:
    try:
        return Archive.read(path)
    except (OSError, ValueError) as e:
        errors.append(SpecError("ssp", str(e)))
        return None


def _engine(raw: dict[str, Any]) -> object:
    table = raw.get("system")
    return table.get("engine") if isinstance(table, dict) else None


def _times_of(reading: Any) -> tuple[float, float, float] | None:
    """The scenario's start, stop and step where they were read (a fit's first
    experiment's)."""
    scenario = reading.scenario if hasattr(reading, "scenario") else reading.experiments[0].scenario
    return scenario.times()  # type: ignore[no-any-return]


class Study:
    """One sweep's or fit's run of a checked target: its output store (``out``, or
    ``<kind>-<digest>`` here; ``resume`` continues what it holds) and its pool of
    ``workers`` on a LocalCluster, an existing ``scheduler``, or ``serial`` here."""

    def __init__(self, kind: str, spec: Spec | FitSpec, target: Target, plan: Plan, *,
                 out: str | os.PathLike[str] | None, resume: bool, record: dict[str, Any],
                 workers: int | None, scheduler: str | None, serial: bool,
                 name: str | None = None):
        self.kind = kind
        self.target = target
        self.plan = plan
        self.digest = spec.digest()
        meta = {"format": FORMAT, "kind": kind, "spec": spec.raw, "spec_digest": self.digest,
                "seed": spec.seed, "fmu_sha256": target.sha256, **target.identity, **record,
                "versions": versions(), "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        folder = output_folder(kind, name, self.digest) if out is None and not resume else (
            out if out is not None else resumable_folder(kind, name, self.digest))
        self.store = ResultStore(folder, meta, resume)
        prefix = "fmusweep-" + ("fit-" if kind == "fit" else "")
        self.pool = Pool(target.archive, (target.run_batch, target.prepare), plan,
                         workers=workers, scheduler=scheduler, serial=serial,
                         prefix=f"{prefix}{self.digest[:8]}-")

    def ids(self, names: list[str], rows: Rows) -> list[str]:
        return point_ids(self.target.sha256, self.digest, names, rows)

    @contextmanager
    def running(self) -> Iterator[Pool]:
        """The pool, started (a cluster connected and every worker prepared) and closed
        at the end."""
        with without_message_log(self.pool.serial), self.pool:
            yield self.pool

    def abandon(self) -> None:
        """After a failure: the output folder removed if this study made it and no point
        landed in it, so that no folder claims to hold a study that never ran a point."""
        self.store.remove_if_empty()

    def finish(self) -> int:
        """Write the final table from the parts; the number of points it holds."""
        return self.store.consolidate()
