"""A fit's specification: the sweep's ``fmu`` and ``[scenario]``, the measured data, and
the parameters to estimate::

    fmu = "CyclicMechanism.fmu"       # or a coupled [system], as a sweep names one
    [scenario]
    stop = 5.0
    step = 0.01
    tolerance = 1e-8
    parameters = { Mm_a0 = 100.0 }    # fixed for every run

    [data]
    file = "measured.csv"             # relative to the spec: a time column, one per output
    sigma = { omega1 = 1e-3 }         # optional: each column's standard deviation

    [fit]
    starts = 4                        # optional: the start below and 3 from a Latin hypercube
    seed = 1                          # needed when starts > 1
    max_iterations = 100              # optional: trial points of each start, at most
    relative_step = 1e-4              # optional: of the Jacobian's perturbations

    [fit.parameters]
    k34 = { start = 80.0, range = [10.0, 400.0] }
    d34 = { start = 0.1, range = [0.0, 5.0] }

Each mistake is a SpecError naming the field; the checks that need the FMU are in
``fmusweep.fitting.problem``.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import pathlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import Collector, SpecError, refuse
from ..fields import finite, low_high, only, table, whole
from ..spec import Scenario, read_source, what_runs
from ..system import System
from ..records import Plan, SeriesPlan
from .data import Data

__all__ = ["FitSpec", "FitParameter"]

MAX_STARTS = 1000
DEFAULT_MAX_ITERATIONS = 100


@dataclass(frozen=True)
class FitParameter:
    name: str
    start: float
    low: float
    high: float

    @property
    def width(self) -> float:
        return self.high - self.low


@dataclass
class FitSpec:
    """A fit's specification: what runs, the scenario every run shares (its fixed
    parameters are ``scenario.parameters``), the data, and the parameters fitted
    (``fitted``, the ``[fit.parameters]`` table)."""
    raw: dict[str, Any]
    base_dir: pathlib.Path
    fmu: pathlib.Path | None
    system: System | None
    scenario: Scenario
    data: Data
    fitted: list[FitParameter]
    starts: int
    seed: int | None
    max_iterations: int
    relative_step: float

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.fitted]

    @property
    def lows(self) -> np.ndarray:
        return np.array([p.low for p in self.fitted])

    @property
    def highs(self) -> np.ndarray:
        return np.array([p.high for p in self.fitted])

    @staticmethod
    def load(source: FitSpec | str | os.PathLike[str] | dict[str, Any],
             base_dir: str | os.PathLike[str] | None = None) -> FitSpec:
        if isinstance(source, FitSpec):
            return source
        return FitSpec.from_dict(*read_source(source, base_dir, "a FitSpec"))

    @staticmethod
    def from_dict(raw: dict[str, Any], base_dir: str | os.PathLike[str]) -> FitSpec:
        """The fit spec of `raw`, every mistake of its own fields reported at once (the
        names are checked against the FMU afterwards, also all at once)."""
        raw = copy.deepcopy(raw)
        base = pathlib.Path(base_dir)
        errors = Collector()
        errors.run(lambda: only(raw, "spec", {"fmu", "ssp", "system", "scenario", "data", "fit"}))
        runs = errors.run(lambda: what_runs(raw, base))
        scenario = errors.run(lambda: Scenario.of(raw))
        data = (errors.run(lambda: Data.of(table(raw, "data", "spec", required=True), base,
                                           scenario)) if scenario is not None else None)
        settings = errors.run(lambda: _fit_table(raw, scenario)) if scenario is not None else None
        errors.raise_any()
        assert runs is not None and scenario is not None and data is not None
        assert settings is not None
        fmu, ssp, system = runs
        if ssp is not None and system is None:
            raise SpecError("system.engine", "a fit runs an SSP file natively only: not "
                                             "with engine = \"fmpy\"")
        return FitSpec(raw, base, (base / fmu) if fmu else None, system, scenario, data,
                       *settings)

    def digest(self) -> str:
        """A hash of everything that decides the results: the spec and the data file's
        content (not where the FMU or the data file lie)."""
        canonical = {k: v for k, v in self.raw.items() if k not in ("fmu", "ssp")}
        canonical["data"] = {k: v for k, v in canonical["data"].items() if k != "file"}
        if self.system is not None:  # the components' contents count, not where they lie
            canonical["system"] = self.system.digest()
        text = json.dumps(canonical, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode() + self.data.sha256.encode()).hexdigest()

    def plan(self) -> Plan:
        """The runner's plan: the scenario, reading the measured variables at every
        communication point that holds a data time (and at no other, where it can)."""
        return self.scenario.plan([], SeriesPlan(variables=self.data.columns,
                                                 every=self.data.every), self.system)


def _fit_table(raw: dict[str, Any],
               scenario: Scenario) -> tuple[list[FitParameter], int, int | None, int, float]:
    """The [fit] table: the parameters fitted, the starts, the seed, the iterations and the
    Jacobian's relative step; every mistake of it reported at once."""
    fit = table(raw, "fit", "spec", required=True)
    errors = Collector()
    errors.run(lambda: only(fit, "fit", {"parameters", "starts", "seed", "max_iterations",
                                         "relative_step"}))
    entries = errors.run(lambda: table(fit, "parameters", "fit", required=True)) or {}
    fitted = [errors.run(lambda: _parameter(name, entry, scenario))
              for name, entry in entries.items()]
    if not entries:
        errors.run(lambda: refuse("fit.parameters", "names no parameter: there is nothing to fit"))
    starts = errors.run(lambda: whole(fit.get("starts", 1), "fit.starts", 1, MAX_STARTS))
    seed = fit.get("seed")
    if seed is not None:
        seed = errors.run(lambda: whole(seed, "fit.seed", 0, None))
    elif starts is not None and starts > 1:
        errors.run(lambda: refuse("fit.seed", "more than one start needs a seed, so that the "
                                               "fit can be repeated"))
    max_iterations = errors.run(lambda: whole(fit.get("max_iterations", DEFAULT_MAX_ITERATIONS),
                                              "fit.max_iterations", 1, None))
    # A forward difference's error is the step plus the model's own error over the step;
    # the square root of the integrator's tolerance balances the two.
    default_step = math.sqrt(scenario.tolerance) if scenario.tolerance else 1e-4
    relative_step = fit.get("relative_step", default_step)
    if (isinstance(relative_step, bool) or not isinstance(relative_step, (int, float))
            or not 0 < relative_step < 0.1):
        errors.run(lambda: refuse("fit.relative_step",
                                   f"must be a number in (0, 0.1), got {relative_step!r}"))
    errors.raise_any()
    assert starts is not None and max_iterations is not None
    return ([p for p in fitted if p is not None], starts, seed, max_iterations,
            float(relative_step))



def _parameter(name: str, entry: object, scenario: Scenario) -> FitParameter:
    where = f"fit.parameters.{name}"
    if not isinstance(entry, dict) or set(entry) != {"start", "range"}:
        raise SpecError(where, "give start = x and range = [low, high]")
    scenario.refuse_also_set(name, where, "fit")
    low, high = low_high(entry["range"], f"{where}.range")
    start = finite(entry["start"], f"{where}.start")
    if not low <= start <= high:
        raise SpecError(f"{where}.start", f"must lie in its range [{low}, {high}], got {start}")
    return FitParameter(name, start, low, high)
