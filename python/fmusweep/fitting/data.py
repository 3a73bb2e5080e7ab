"""Measured data: a CSV file with a ``time`` column and one column per measured output.

The model is compared with the data at the data's own times, which must lie on the
scenario's communication grid (start + k·step, to a millionth of a step): there the FMU's
values are exact to its tolerance, while an interpolation between communication points
would add an error of its own that the fit would read as a wrong parameter. Data sampled
at 1 kHz fits a step of 1 ms (or 0.5 ms, …); data on another clock is resampled first.
"""

from __future__ import annotations

import csv
import hashlib
import math
import pathlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import Collector, SpecError
from ..fields import only
from ..records import Points, Rows

if TYPE_CHECKING:
    from ..spec import Scenario

__all__ = ["Data"]

GRID_SLACK = 1e-6  # of a step: how far a data time may sit from its communication point


@dataclass
class Data:
    path: pathlib.Path
    sha256: str
    times: np.ndarray    # (n,)
    columns: list[str]   # the measured variables, in the file's order
    values: np.ndarray   # (n, columns)
    sigma: np.ndarray    # (columns,): each column's standard deviation
    sigma_given: list[bool]
    steps: np.ndarray    # (n,): each time's communication point k
    every: int           # the runner records every this many points: each data time's

    @property
    def rows(self) -> np.ndarray:
        """Each data time's row in the runner's series."""
        return self.steps // self.every

    @staticmethod
    def check(table: dict[str, Any], base_dir: pathlib.Path, where: str = "data") -> None:
        """The data table's file and σ alone, for a scenario with mistakes of its own."""
        path, content = _read(table, base_dir, where)
        columns, _, _ = _parse(content, path, where)
        _sigma(table.get("sigma"), columns, where)

    @staticmethod
    def of(table: dict[str, Any], base_dir: pathlib.Path, scenario: Scenario,
           where: str = "data") -> Data:
        """The data table at `where` (``data``, or an experiment's ``experiment.NAME.data``),
        the mistakes of its σ and of its times raised together."""
        path, content = _read(table, base_dir, where)
        columns, times, values = _parse(content, path, where)
        errors = Collector()
        steps = errors.run(lambda: _grid_steps(times, scenario, path, where))
        sigma_given = errors.run(lambda: _sigma(table.get("sigma"), columns, where))
        errors.raise_any()
        assert sigma_given is not None and steps is not None
        sigma, given = sigma_given
        every = math.gcd(scenario.steps, *steps.tolist())
        return Data(path, hashlib.sha256(content).hexdigest(), times, columns, values, sigma,
                    given, steps, every)


def _read(table: dict[str, Any], base_dir: pathlib.Path, where: str) -> tuple[pathlib.Path, bytes]:
    only(table, where, {"file", "sigma"})
    name = table.get("file")
    if not isinstance(name, str):
        raise SpecError(f"{where}.file", "must name a CSV file (a path relative to the spec)")
    path = base_dir / name
    try:
        return path, path.read_bytes()
    except OSError as e:
        raise SpecError(f"{where}.file", f"cannot read {path}: {e.strerror}") from None


def _parse(content: bytes, path: pathlib.Path, where: str) -> tuple[list[str], Rows, Rows]:
    try:
        text = content.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise SpecError(f"{where}.file", f"{path} is not UTF-8 text") from None
    lines = list(csv.reader(text.splitlines()))
    while lines and not any(cell.strip() for cell in lines[-1]):
        lines.pop()
    if not lines:
        raise SpecError(f"{where}.file", f"{path} is empty")
    header = [cell.strip() for cell in lines[0]]
    if "time" not in header:
        raise SpecError(f"{where}.file", f"{path} has no time column (its header: {', '.join(header)})")
    if len(set(header)) != len(header):
        twice = sorted({h for h in header if header.count(h) > 1})
        raise SpecError(f"{where}.file", f"{path} names the column {twice[0]!r} twice")
    if any(not h for h in header):
        raise SpecError(f"{where}.file", f"{path} has a column without a name")
    columns = [h for h in header if h != "time"]
    if not columns:
        raise SpecError(f"{where}.file", f"{path} has a time column and no measured column")
    body = lines[1:]
    if not body:
        raise SpecError(f"{where}.file", f"{path} has a header and no data")
    table = np.empty((len(body), len(header)))
    for i, row in enumerate(body):
        line = i + 2
        if len(row) != len(header):
            raise SpecError(f"{where}.file", f"{path} line {line}: {len(row)} cells, the header has {len(header)}")
        for j, cell in enumerate(row):
            try:
                x = float(cell)
            except ValueError:
                x = math.nan
            if not math.isfinite(x):
                raise SpecError(f"{where}.file", f"{path} line {line}, column {header[j]}: "
                                             f"{cell.strip()!r} is not a finite number")
            table[i, j] = x
    t = table[:, header.index("time")]
    keep = [j for j, h in enumerate(header) if h != "time"]
    return columns, t, table[:, keep]


def _grid_steps(times: Rows, scenario: Scenario, path: pathlib.Path, where: str) -> Points:
    decreasing = np.flatnonzero(np.diff(times) <= 0)
    if len(decreasing):
        line = int(decreasing[0]) + 3
        raise SpecError(f"{where}.file", f"{path} line {line}: time {times[decreasing[0] + 1]} does "
                                     f"not increase (the times must be strictly increasing)")
    for i, t in enumerate(times):
        if not scenario.start - GRID_SLACK * scenario.step <= t <= scenario.stop + GRID_SLACK * scenario.step:
            raise SpecError(f"{where}.file", f"{path} line {i + 2}: time {t} lies outside the scenario "
                                         f"[{scenario.start}, {scenario.stop}]")
    k = (times - scenario.start) / scenario.step
    steps = np.round(k).astype(np.int64)
    off = np.flatnonzero(np.abs(k - steps) > GRID_SLACK)
    if len(off):
        i = int(off[0])
        raise SpecError(f"{where}.file", f"{path} line {i + 2}: time {times[i]} is not on the "
                                     f"scenario's communication grid (start {scenario.start} + k·"
                                     f"{scenario.step}); the model is compared at communication "
                                     "points: choose a step that divides the sampling interval, "
                                     "or resample the data")
    return steps


def _sigma(table: object, columns: list[str], where: str) -> tuple[Rows, list[bool]]:
    sigma = np.ones(len(columns))
    given = [False] * len(columns)
    if table is None:
        return sigma, given
    if not isinstance(table, dict):
        raise SpecError(f"{where}.sigma", f"must be a table of column = standard deviation, got {table!r}")
    for name, value in table.items():
        field = f"{where}.sigma.{name}"
        if name not in columns:
            raise SpecError(field, f"names no measured column of {where}.file ({', '.join(columns)})")
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or not math.isfinite(value) or value <= 0):
            raise SpecError(field, f"must be a finite number > 0, got {value!r}")
        j = columns.index(name)
        sigma[j], given[j] = float(value), True
    missing = [c for c, g in zip(columns, given) if not g]
    if missing:
        # A column without σ would count in its own units beside columns weighed by theirs,
        # and one variance scale estimated over both would mix the two.
        raise SpecError(f"{where}.sigma", f"gives no standard deviation for "
                                          f"{', '.join(missing)}: give one for every measured "
                                          "column, or for none (then every column shares one "
                                          "σ estimated from the residuals)")
    return sigma, given
