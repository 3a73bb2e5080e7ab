"""Results that are never lost: a directory of Parquet parts, one per finished batch, each
written to a temporary name and renamed into place (atomic on POSIX), so that a sweep
killed at any moment leaves only whole batches behind, and ``resume`` redoes only the
points that no part holds.

Layout of an output directory::

    sweep.json              the spec, seed, design, FMU checksum, package versions
    points/part-*.parquet   one row per point (a part per batch)
    series/part-*.parquet   the time series in long form, when the spec asks for them
    points.parquet          all points in point order, written when the sweep ends
    plots/*.png, sensitivity.json
"""

from __future__ import annotations

import json
import os
import pathlib
import platform
import secrets
import shutil
from importlib import metadata
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from .records import PointResult, Points

__all__ = ["ResultStore", "FORMAT", "versions"]

FORMAT = 1


def _text_columns(table: pa.Table) -> list[str]:
    """Dictionary pages only for text: on floats they cost 4× the write time for nothing."""
    return [f.name for f in table.schema
            if pa.types.is_string(f.type) or pa.types.is_dictionary(f.type)]


def coupling_columns(results: list[PointResult]) -> dict[str, pa.Array]:
    """The columns of a system with a coupling tolerance: each point's largest coupling
    error estimate, its accepted and rejected communication steps and its smallest step
    (null where the point reported none)."""
    reports = [r.get("coupling") for r in results]

    def column(key: str, kind: pa.DataType) -> pa.Array:
        return pa.array([None if c is None else c[key] for c in reports], kind)  # type: ignore[literal-required]

    return {"coupling_error": column("worst_estimate", pa.float64()),
            "coupling_steps": column("accepted", pa.int64()),
            "coupling_rejected": column("rejected", pa.int64()),
            "coupling_min_step": column("min_step", pa.float64())}


def atomic_write_table(table: pa.Table, path: pathlib.Path) -> None:
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    pq.write_table(table, tmp, use_dictionary=_text_columns(table))
    os.replace(tmp, path)


def _overlapping_groups(parts: list[pathlib.Path]) -> list[list[pathlib.Path]]:
    """The parts in groups whose point ranges overlap, the groups in point order: each
    group's points, sorted, follow the previous group's."""
    ranges = []
    for part in parts:
        points = pq.read_table(part, columns=["point"])["point"]
        ranges.append((pc.min(points).as_py(), pc.max(points).as_py(), part))
    ranges.sort(key=lambda r: r[0])
    groups: list[list[pathlib.Path]] = []
    reach = None
    for low, high, part in ranges:
        if reach is not None and low <= reach:
            groups[-1].append(part)
            reach = max(reach, high)
        else:
            groups.append([part])
            reach = high
    return groups


def atomic_write_text(text: str, path: pathlib.Path) -> None:
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def changed_fields(before: Any, after: Any, at: str = "") -> list[str]:
    """Each field of a spec that differs between two readings, with its two values: the
    words of a refused resume."""
    if isinstance(before, dict) and isinstance(after, dict):
        out = []
        for key in sorted(set(before) | set(after), key=str):
            where = f"{at}.{key}" if at else str(key)
            if key not in after:
                out.append(f"{where} removed (was {_short(before[key])})")
            elif key not in before:
                out.append(f"{where} added ({_short(after[key])})")
            else:
                out += changed_fields(before[key], after[key], where)
        return out
    if before != after:
        return [f"{at or 'the spec'} {_short(before)} → {_short(after)}"]
    return []


def _short(value: Any) -> str:
    said = repr(value)
    return said if len(said) <= 60 else said[:57] + "…"


class ResultStore:
    def __init__(self, out: str | os.PathLike[str], meta: dict[str, Any], resume: bool):
        self.out = pathlib.Path(out)
        self.kind = meta.get("kind", "sweep")
        self.points_dir = self.out / "points"
        self.series_dir = self.out / "series"
        meta_path = self.out / "sweep.json"
        if meta_path.exists():
            if not resume:
                raise FileExistsError(
                    f"{self.out} already holds a {self.kind}: pass resume=True (--resume) to "
                    "finish it, or choose another output directory")
            self._check_same_sweep(json.loads(meta_path.read_text()), meta)
        self.made = not self.out.exists()
        self.out.mkdir(parents=True, exist_ok=True)
        self.points_dir.mkdir(exist_ok=True)
        self.series_dir.mkdir(exist_ok=True)
        if not meta_path.exists():
            atomic_write_text(json.dumps(meta, indent=2, sort_keys=True), meta_path)
        self.meta = json.loads(meta_path.read_text())
        self._drop_orphans()

    def _check_same_sweep(self, stored: dict[str, Any], meta: dict[str, Any]) -> None:
        spec = "the specification or its data" if self.kind == "fit" else "the specification"
        for key, what in (("spec_digest", spec), ("fmu_sha256", "the FMU"),
                          ("format", "the results format")):
            if stored.get(key) != meta.get(key):
                changed = (changed_fields(stored.get("spec"), meta.get("spec"))
                           if key == "spec_digest" else [])
                said = (f": {', '.join(changed)}" if changed else
                        f" ({key} {stored.get(key)} → {meta.get(key)})")
                raise ValueError(f"cannot resume in {self.out}: {what} changed since the "
                                 f"{self.kind} began{said}")

    def _drop_orphans(self) -> None:
        """Temporary files of a killed write, and series parts whose points part never
        landed (the points part is written last and marks a batch as done)."""
        for d in (self.points_dir, self.series_dir):
            for tmp in d.glob(".*.tmp"):
                tmp.unlink(missing_ok=True)
        done = {p.name for p in self.points_dir.glob("part-*.parquet")}
        for part in self.series_dir.glob("part-*.parquet"):
            if part.name not in done:
                part.unlink()

    def remove_if_empty(self) -> None:
        """The folder removed when this store made it and no batch landed in it."""
        if self.made and not any(self.points_dir.glob("part-*.parquet")):
            shutil.rmtree(self.out, ignore_errors=True)

    def done_points(self) -> Points:
        parts = sorted(self.points_dir.glob("part-*.parquet"))
        if not parts:
            return np.empty(0, dtype=np.int64)
        return np.concatenate([pq.read_table(p, columns=["point"])["point"].to_numpy() for p in parts])

    def write_batch(self, points: pa.Table, series: pa.Table | None) -> None:
        first = int(points["point"][0].as_py())
        name = f"part-{first:010d}-{secrets.token_hex(4)}.parquet"
        if series is not None and series.num_rows:
            atomic_write_table(series, self.series_dir / name)
        atomic_write_table(points, self.points_dir / name)

    def consolidate(self) -> int:
        """Write points.parquet, every point in point order, from the parts, streamed: a
        group of parts at a time (the parts whose point ranges overlap, which only a
        resumed sweep makes; otherwise one part), so that the client holds no more than
        the largest group, however many points. Returns the number of points."""
        parts = sorted(self.points_dir.glob("part-*.parquet"))
        if not parts:
            raise FileNotFoundError(f"{self.out} holds no finished point")
        path = self.out / "points.parquet"
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
        rows = 0
        writer = None
        try:
            for group in _overlapping_groups(parts):
                table = pa.concat_tables([pq.read_table(p) for p in group]).sort_by("point")
                if writer is None:
                    writer = pq.ParquetWriter(tmp, table.schema, use_dictionary=_text_columns(table))
                writer.write_table(table)
                rows += table.num_rows
        finally:
            if writer is not None:
                writer.close()
        os.replace(tmp, path)
        return rows

    @staticmethod
    def points_table_of(out: str | os.PathLike[str]) -> pa.Table:
        parts = sorted((pathlib.Path(out) / "points").glob("part-*.parquet"))
        if not parts:
            raise FileNotFoundError(f"{out} holds no finished point")
        return pa.concat_tables([pq.read_table(p) for p in parts]).sort_by("point")

    @staticmethod
    def series_table_of(out: str | os.PathLike[str]) -> pa.Table | None:
        parts = sorted((pathlib.Path(out) / "series").glob("part-*.parquet"))
        if not parts:
            return None
        table = pa.concat_tables([pq.read_table(p) for p in parts])
        variable = table.column("variable")
        if pa.types.is_dictionary(variable.type):
            table = table.set_column(table.schema.get_field_index("variable"), "variable",
                                     variable.cast(pa.string()))
        return table.sort_by([("point", "ascending"), ("variable", "ascending"), ("time", "ascending")])


def versions() -> dict[str, str | None]:
    """The versions of the packages that make the results, recorded beside them."""
    names = ["fmusweep", "numpy", "pyarrow", "dask", "distributed", "SALib", "scipy"]
    found: dict[str, str | None] = {"python": platform.python_version()}
    for name in names:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = None
    return found
