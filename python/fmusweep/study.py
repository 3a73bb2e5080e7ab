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

from .check import names_missing, values_out_of_range
from .errors import SpecError, SpecErrors
from .fields import typed_by
from .fmu import Archive, open_for_checks
from .native import NativeRunner, RunnerError
from .pool import Pool, without_message_log
from .records import BatchFunction, Plan, PrepareFunction, Rows
from .spec import read_source
from .ssp import describe_ssp, prepare_ssp_worker, run_ssp_batch
from .store import FORMAT, ResultStore, versions
from .system import System, open_target
from .worker import prepare_worker, run_batch

if TYPE_CHECKING:
    from .fitting.spec import FitSpec
    from .spec import Spec

__all__ = ["Target", "Study", "point_ids", "load_spec", "spec_name", "RESULTS"]

S = TypeVar("S")


def load_spec(load: Callable[[], S], source: object, fmu: str | None) -> S:
    """load()'s spec, read against the FMU's variables where it can be opened (so that a
    setting may name an Enumeration's item or be true/false); when its own fields have
    mistakes, those and every name the FMU lacks, in one error, so that one run reports
    both kinds."""
    description = _description(source, fmu)
    types = {v["name"]: (v["type"], v.get("items", {}))
             for v in (description or {}).get("variables", [])}
    try:
        with typed_by(types):
            return load()
    except SpecError as refused:
        raw = _raw(source)
        if not description or not raw:
            raise
        raise _with_names_missing(refused, raw, description) from None


def _with_names_missing(refused: SpecError, raw: dict[str, Any],
                        description: dict[str, Any]) -> SpecError:
    """The refusal, with every name of the spec that `description` lacks and every number
    outside the FMU's declared range (under a field the refusal does not name already)."""
    known = refused.errors if isinstance(refused, SpecErrors) else [refused]
    fields = {e.field for e in known}
    found = names_missing(raw, description)
    named = {e.field for e in found}
    # A name the FMU lacks says enough of its values.
    found += [e for e in values_out_of_range(raw, description)
              if not any(e.field.startswith(n) for n in named)]
    extra = [e for e in found if e.field not in fields]
    return SpecErrors(known + extra) if extra else refused


def _raw(source: object) -> dict[str, Any] | None:
    try:
        return read_source(source, None, "a spec")[0]
    except SpecError:
        return None


def _description(source: object, fmu: str | None) -> dict[str, Any] | None:
    """The description of the spec's FMU; None when the spec cannot be read or its FMU
    opened (a [system] or an SSP file is not opened for this)."""
    try:
        raw, base_dir = read_source(source, None, "a spec")
        named = raw.get("fmu")
        if fmu is None and (raw.get("system") is not None or raw.get("ssp") is not None):
            return None
        spec_fmu = base_dir / named if isinstance(named, str) else None
        return open_for_checks(fmu, spec_fmu)[2]
    except (SpecError, OSError, ValueError, RunnerError):
        return None


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
    def open(spec: Spec | FitSpec, fmu: str | None) -> Target:
        """The FMU the caller names, else the spec's SSP file, [system] or FMU, else
        $FMUSWEEP_FMU."""
        ssp = getattr(spec, "ssp", None)
        system: System | None = spec.system
        if ssp is not None and system is None and fmu is None:
            archive = _read_ssp(ssp)
            return Target(archive, {"ssp_name": archive.name, "ssp_sha256": archive.sha256},
                          describe_ssp(archive), None, run_ssp_batch, prepare_ssp_worker)
        try:
            archive, local, description = open_target(system, fmu, spec.fmu, spec.scenario.step)
        except SpecError as refused:
            if system is None or fmu is not None:
                raise
            raise _with_names_missing(refused, spec.raw, system.described()) from None
        if system is not None and fmu is None:
            identity: dict[str, Any] = {
                "system": {name: str(path) for name, path in system.components.items()},
                "connections": [str(c) for c in system.connections]}
            if ssp is not None:
                file = _read_ssp(ssp)
                identity.update(ssp_name=file.name, ssp_sha256=file.sha256)
        else:
            identity = {"fmu_name": archive.name, "fmu_guid": description["guid"]}
        return Target(archive, identity, description, local, run_batch, prepare_worker)

    @property
    def sha256(self) -> str:
        return self.archive.sha256


def _read_ssp(path: str | pathlib.Path) -> Archive:
    try:
        return Archive.read(path)
    except (OSError, ValueError) as e:
        raise SpecError("ssp", str(e)) from None


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
