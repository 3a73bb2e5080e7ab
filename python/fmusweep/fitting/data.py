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

import numpy as np

from ..errors import Collector, SpecError
from ..records import Points, Rows

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
    def of(file: str, sigma: dict[str, float], base_dir: pathlib.Path,
           times: tuple[float, float, float] | None, where: str = "data") -> Data | None:
        """The measured `file` of the data table at `where` (``data``, or an experiment's
        ``experiment.NAME.data``) with its σ, on the scenario's grid `times` (start, stop,
        step), the mistakes of its σ and of its times raised together; None where the grid
        is not known (the file and σ are still checked)."""
        path, content = _read(file, base_dir, where)
        columns, data_times, values = _parse(content, path, where)
        errors = Collector()
        sigma_given = errors.run(lambda: _sigma(sigma, columns, where))
        steps = errors.run(lambda: _grid_steps(data_times, times, path, where)) if times else None
        errors.raise_any()
        if times is None:
            return None
        assert sigma_given is not None and steps is not None
        weights, given = sigma_given
        start, stop, step = times
        every = math.gcd(round((stop - start) / step), *steps.tolist())
        return Data(path, hashlib.sha256(content).hexdigest(), data_times, columns, values,
                    weights, given, steps, every)


def _read(name: str, base_dir: pathlib.Path, where: str) -> tuple[pathlib.Path, bytes]:
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


def _grid_steps(times: Rows, grid: tuple[float, float, float], path: pathlib.Path,
                where: str) -> Points:
    start, stop, step = grid
    decreasing = np.flatnonzero(np.diff(times) <= 0)
    if len(decreasing):
        line = int(decreasing[0]) + 3
        raise SpecError(f"{where}.file", f"{path} line {line}: time {times[decreasing[0] + 1]} does "
                                     f"not increase (the times must be strictly increasing)")
    for i, t in enumerate(times):
        if not start - GRID_SLACK * step <= t <= stop + GRID_SLACK * step:
            raise SpecError(f"{where}.file", f"{path} line {i + 2}: time {t} lies outside the scenario "
                                         f"[{start}, {stop}]")
    k = (times - start) / step
    steps = np.round(k).astype(np.int64)
    off = np.flatnonzero(np.abs(k - steps) > GRID_SLACK)
    if len(off):
        i = int(off[0])
        raise SpecError(f"{where}.file", f"{path} line {i + 2}: time {times[i]} is not on the "
                                     f"scenario's communication grid (start {start} + k·"
                                     f"{step}); the model is compared at communication "
                                     "points: choose a step that divides the sampling interval, "
                                     "or resample the data")
    return steps


def _sigma(table: dict[str, float], columns: list[str], where: str) -> tuple[Rows, list[bool]]:
    sigma = np.ones(len(columns))
    given = [False] * len(columns)
    if not table:
        return sigma, given
    for name, value in table.items():
        field = f"{where}.sigma.{name}"
        if name not in columns:
            raise SpecError(field, f"names no measured column of {where}.file ({', '.join(columns)})")
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
