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
    jacobian = "sensitivities"        # optional: "differences" (the default), or the FMU's
                                      # sensitivities where it offers them
    intervals = "both"                # optional: "wald" (the default), "profile" or "both"
    profile = ["k34"]                 # optional: the parameters profiled (default: all)

    [fit.parameters]
    k34 = { start = 80.0, range = [10.0, 400.0] }
    d34 = { start = 0.1, range = [0.0, 5.0] }

Several experiments replace ``[data]`` by ``[[experiment]]`` tables, each a measured run
of its own: its name, its data table, the changes of its scenario to the shared
``[scenario]`` (``parameters`` and ``inputs`` merged entry by entry), and the parameters
fitted for it alone, such as a start value each run had but nobody measured::

    [[experiment]]
    name = "run_up"
    data = { file = "run_up.csv", sigma = { omega1 = 0.05 } }
    scenario = { stop = 3.0, parameters = { Mm_a0 = 80.0 } }
    parameters = { omega1_0 = { start = 0.0, range = [-5.0, 5.0] } }

``[fit.parameters]`` are then shared by every experiment; an experiment's own parameter is
called ``NAME.variable`` in the results (``run_up.omega1_0``).

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
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..columns import FIT_COLUMNS, refuse_collisions
from ..errors import Collector, SpecError, SpecErrors, refuse
from ..fields import finite, low_high, only, table, whole
from ..spec import Scenario, read_source, what_runs
from ..system import System
from ..records import Plan, SeriesPlan
from .data import Data

__all__ = ["FitSpec", "FitParameter", "Experiment", "INTERVALS", "SINGLE_EXPERIMENT"]

MAX_STARTS = 1000
DEFAULT_MAX_ITERATIONS = 100
# How a fit's 95 % intervals are found: from the Jacobian at the optimum (Wald), from the
# profile of the cost with the other parameters re-optimised, or both side by side.
INTERVALS = ("wald", "profile", "both")
# Where the Jacobian comes from: forward differences, or the FMU's own sensitivities
# wherever it offers them (docs/sensitivities.md) and differences for the rest.
JACOBIANS = ("differences", "sensitivities")
# The name of the one experiment a [data] table makes.
SINGLE_EXPERIMENT = "data"


@dataclass(frozen=True)
class FitParameter:
    """A fitted parameter: ``name`` in the fit's results, ``variable`` in the FMU (the
    same unless the parameter is one experiment's own, ``experiment``)."""
    name: str
    start: float
    low: float
    high: float
    variable: str
    experiment: str | None = None

    @property
    def width(self) -> float:
        return self.high - self.low


@dataclass
class Experiment:
    """One measured run: its scenario, its data, and the fitted parameters it runs with
    (``columns``: their places in the fit's parameter vector, ``variables``: the FMU's
    names of them)."""
    name: str
    scenario: Scenario
    data: Data
    columns: list[int]
    variables: list[str]

    def plan(self, system: System | None, extra: list[str] | None = None) -> Plan:
        """The runner's plan: the scenario, reading the measured variables (then `extra`
        ones) at every communication point that holds a data time (and at no other, where
        it can)."""
        return self.scenario.plan([], SeriesPlan(variables=self.data.columns + (extra or []),
                                                 every=self.data.every), system)


@dataclass
class FitSpec:
    """A fit's specification: what runs, its experiments (one for a [data] table), the
    parameters fitted (``fitted``: the shared ones, then each experiment's own), and how."""
    raw: dict[str, Any]
    base_dir: pathlib.Path
    fmu: pathlib.Path | None
    system: System | None
    experiments: list[Experiment]
    fitted: list[FitParameter]
    starts: int
    seed: int | None
    max_iterations: int
    relative_step: float
    intervals: str = "wald"
    profiled: list[str] = field(default_factory=list)
    jacobian: str = "differences"

    @property
    def scenario(self) -> Scenario:
        """The first experiment's scenario: what opening the FMU needs of one."""
        return self.experiments[0].scenario

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.fitted]

    @property
    def lows(self) -> np.ndarray:
        return np.array([p.low for p in self.fitted])

    @property
    def highs(self) -> np.ndarray:
        return np.array([p.high for p in self.fitted])

    @property
    def measured_columns(self) -> list[str]:
        """Every experiment's measured variables, each once, in order of appearance."""
        return list(dict.fromkeys(c for e in self.experiments for c in e.data.columns))

    @property
    def absolute_sigma(self) -> bool:
        """Whether every measured column of every experiment has its standard deviation."""
        return all(all(e.data.sigma_given) for e in self.experiments)

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
        errors.run(lambda: only(raw, "spec", {"fmu", "ssp", "system", "scenario", "data",
                                              "experiment", "fit"}))
        runs = errors.run(lambda: what_runs(raw, base))
        shared = errors.run(lambda: _shared_parameters(raw)) or []
        experiments = errors.run(lambda: _experiments(raw, base, shared, errors)) or []
        settings = errors.run(lambda: _fit_table(raw, experiments, shared))
        errors.raise_any()
        assert runs is not None and settings is not None
        fmu, ssp, system = runs
        if ssp is not None and system is None:
            raise SpecError("system.engine", "a fit runs an SSP file natively only: not "
                                             "with engine = \"fmpy\"")
        shared_fitted, starts, seed, max_iterations, relative_step, intervals, profiled, \
            jacobian = settings
        numbered, fitted = _numbered(experiments, shared_fitted)
        return FitSpec(raw, base, (base / fmu) if fmu else None, system, numbered, fitted,
                       starts, seed, max_iterations, relative_step, intervals, profiled, jacobian)

    def digest(self) -> str:
        """A hash of everything that decides the results: the spec and the data files'
        contents (not where the FMU or the data files lie)."""
        canonical = {k: v for k, v in self.raw.items() if k not in ("fmu", "ssp")}
        if "data" in canonical:
            canonical["data"] = {k: v for k, v in canonical["data"].items() if k != "file"}
        if "experiment" in canonical:
            canonical["experiment"] = [
                dict(e, data={k: v for k, v in e["data"].items() if k != "file"})
                for e in canonical["experiment"]]
        if self.system is not None:  # the components' contents count, not where they lie
            canonical["system"] = self.system.digest()
        canonical["inputs"] = [e.scenario.inputs for e in self.experiments]
        text = json.dumps(canonical, sort_keys=True, separators=(",", ":"))
        data = "".join(e.data.sha256 for e in self.experiments)
        return hashlib.sha256(text.encode() + data.encode()).hexdigest()


@dataclass
class _Parsed:
    """An experiment as read, before its parameters have their places in the vector."""
    name: str
    scenario: Scenario
    data: Data
    own: list[FitParameter]


def _shared_parameters(raw: dict[str, Any]) -> list[tuple[str, Any]]:
    fit = table(raw, "fit", "spec", required=True)
    entries = table(fit, "parameters", "fit", required=True)
    return list(entries.items())


def _experiments(raw: dict[str, Any], base: pathlib.Path, shared: list[tuple[str, Any]],
                 errors: Collector) -> list[_Parsed]:
    """The [data] table's one experiment, or the [[experiment]] tables' (their mistakes
    collected in `errors`, each by field)."""
    listed = raw.get("experiment")
    if listed is None:
        scenario = errors.run(lambda: Scenario.of(raw, base))
        data_table = errors.run(lambda: table(raw, "data", "spec", required=True))
        if data_table is None:
            return []
        if scenario is None:
            # The data file is read even when the scenario has mistakes.
            errors.run(lambda: Data.check(data_table, base))
            return []
        data = errors.run(lambda: Data.of(data_table, base, scenario))
        return [_Parsed(SINGLE_EXPERIMENT, scenario, data, [])] if data is not None else []
    if "data" in raw:
        raise SpecError("data", "give either one [data] table or [[experiment]] tables, not both")
    if not isinstance(listed, list) or not listed or not all(isinstance(e, dict) for e in listed):
        raise SpecError("experiment", "must be [[experiment]] tables, at least one")
    shared_names = {name for name, _ in shared}
    parsed: list[_Parsed] = []
    for k, entry in enumerate(listed):
        one = errors.run(lambda: _experiment(raw, entry, k, base, shared_names,
                                             {e.name for e in parsed}))
        if one is not None:
            parsed.append(one)
    weighed = [e.name for e in parsed if all(e.data.sigma_given)]
    if weighed and len(weighed) < len(parsed):
        unweighed = next(e.name for e in parsed if e.name not in weighed)
        errors.run(lambda: refuse(f"experiment.{unweighed}.data.sigma",
                                  f"is missing while experiment {weighed[0]} gives σ: give "
                                  "every experiment's columns a σ, or none (then they share "
                                  "one σ estimated from the residuals)"))
    return parsed


def _experiment(raw: dict[str, Any], entry: dict[str, Any], k: int, base: pathlib.Path,
                shared: set[str], taken: set[str]) -> _Parsed:
    name = entry.get("name")
    if not isinstance(name, str) or not name.isidentifier():
        raise SpecError(f"experiment[{k}].name", f"must be a name (letters, digits, _), got {name!r}")
    if name in taken:
        raise SpecError(f"experiment.{name}.name", "names another experiment too")
    where = f"experiment.{name}"
    only(entry, where, {"name", "data", "scenario", "parameters"})
    own = table(entry, "scenario", where)
    scenario = _scenario_of(raw, own, where, base)
    data = Data.of(table(entry, "data", where, required=True), base, scenario, f"{where}.data")
    errors = Collector()
    fitted = [errors.run(lambda: _own_parameter(variable, value, scenario, where, shared))
              for variable, value in table(entry, "parameters", where).items()]
    errors.raise_any()
    return _Parsed(name, scenario, data, [p for p in fitted if p is not None])


def _scenario_of(raw: dict[str, Any], own: dict[str, Any], where: str,
                 base_dir: pathlib.Path) -> Scenario:
    """The shared [scenario] with an experiment's changes; a mistake in a field the
    experiment sets is named as the experiment's."""
    base = table(raw, "scenario", "spec")
    merged = {**base, **own}
    for key in ("parameters", "inputs"):
        if isinstance(base.get(key), dict) and isinstance(own.get(key), dict):
            merged[key] = {**base[key], **own[key]}
    try:
        return Scenario.of({"scenario": merged}, base_dir)
    except SpecError as refused:
        each = refused.errors if isinstance(refused, SpecErrors) else [refused]
        named = [_as_experiments(e, own, where) for e in each]
        raise (named[0] if len(named) == 1 else SpecErrors(named)) from None


def _as_experiments(refused: SpecError, own: dict[str, Any], where: str) -> SpecError:
    """A scenario's mistake in a field the experiment sets, named as the experiment's."""
    parts = refused.field.split(".")
    if parts[0] == "scenario" and (len(parts) == 1 or parts[1] in own):
        return SpecError(f"{where}.{refused.field}", refused.rule)
    return refused


def _own_parameter(variable: str, entry: object, scenario: Scenario, where: str,
                   shared: set[str]) -> FitParameter:
    field_name = f"{where}.parameters.{variable}"
    if variable in shared:
        raise SpecError(field_name, f"{variable} is fitted for every experiment in "
                                    "fit.parameters: fit it there or here, not both")
    experiment = where.split(".", 1)[1]
    return _parameter(variable, entry, scenario, field_name, f"{experiment}.{variable}",
                      experiment)


def _numbered(parsed: list[_Parsed],
              shared: list[FitParameter]) -> tuple[list[Experiment], list[FitParameter]]:
    """The experiments with their columns of the parameter vector: the shared parameters
    first, then each experiment's own."""
    fitted = list(shared)
    experiments = []
    for e in parsed:
        columns = list(range(len(shared))) + list(range(len(fitted), len(fitted) + len(e.own)))
        fitted.extend(e.own)
        experiments.append(Experiment(e.name, e.scenario, e.data, columns,
                                      [fitted[j].variable for j in columns]))
    return experiments, fitted


def _fit_table(raw: dict[str, Any], experiments: list[_Parsed], shared: list[tuple[str, Any]]
               ) -> tuple[list[FitParameter], int, int | None, int, float, str, list[str], str]:
    """The [fit] table: the shared parameters (each checked against every experiment's
    scenario), the starts, the seed, the iterations, the Jacobian's relative step and the
    intervals; every mistake of it reported at once."""
    fit = table(raw, "fit", "spec", required=True)
    errors = Collector()
    errors.run(lambda: only(fit, "fit", {"parameters", "starts", "seed", "max_iterations",
                                         "relative_step", "intervals", "profile", "jacobian"}))
    fitted: list[FitParameter] = []
    scenarios: list[Scenario | None] = [e.scenario for e in experiments] or [None]
    for name, entry in shared:
        each = errors.run(lambda: [_parameter(name, entry, scenario, f"fit.parameters.{name}",
                                              name, None) for scenario in scenarios])
        if each:
            fitted.append(each[0])
    if not shared and not any(e.own for e in experiments):
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
    tolerance = experiments[0].scenario.tolerance if experiments else None
    default_step = math.sqrt(tolerance) if tolerance else 1e-4
    relative_step = fit.get("relative_step", default_step)
    if (isinstance(relative_step, bool) or not isinstance(relative_step, (int, float))
            or not 0 < relative_step < 0.1):
        errors.run(lambda: refuse("fit.relative_step",
                                   f"must be a number in (0, 0.1), got {relative_step!r}"))
    names = ([name for name, _ in shared]
             + [f"{e.name}.{p.variable}" for e in experiments for p in e.own])
    fields = ([f"fit.parameters.{name}" for name, _ in shared]
              + [f"experiment.{e.name}.parameters.{p.variable}" for e in experiments for p in e.own])
    refuse_collisions([(name, where, "the fitted parameter") for name, where in zip(names, fields)],
                      FIT_COLUMNS, errors)
    intervals, profiled = errors.run(lambda: _intervals(fit, names)) or ("wald", [])
    jacobian = fit.get("jacobian", "differences")
    if jacobian not in JACOBIANS:
        errors.run(lambda: refuse("fit.jacobian", f"must be one of {', '.join(map(repr, JACOBIANS))}, "
                                                  f"got {jacobian!r}"))
    errors.raise_any()
    assert starts is not None and max_iterations is not None
    return (fitted, starts, seed, max_iterations, float(relative_step), intervals, profiled,
            str(jacobian))


def _intervals(fit: dict[str, Any], names: list[str]) -> tuple[str, list[str]]:
    intervals = fit.get("intervals", "wald")
    if intervals not in INTERVALS:
        raise SpecError("fit.intervals", f"must be one of {', '.join(map(repr, INTERVALS))}, "
                                         f"got {intervals!r}")
    profile = fit.get("profile")
    if profile is None:
        return intervals, (names if intervals != "wald" else [])
    if intervals == "wald":
        raise SpecError("fit.profile", "profiles parameters for intervals = \"profile\" or "
                                       "\"both\": set fit.intervals too")
    if not isinstance(profile, list) or not profile or not all(isinstance(n, str) for n in profile):
        raise SpecError("fit.profile", f"must be a list of fitted parameters' names, got {profile!r}")
    for name in profile:
        if name not in names:
            raise SpecError("fit.profile", f"{name!r} is not fitted (fitted: {', '.join(names)})")
    return intervals, list(dict.fromkeys(profile))


def _parameter(variable: str, entry: object, scenario: Scenario | None, where: str, name: str,
               experiment: str | None) -> FitParameter:
    """A fitted parameter's entry (checked against `scenario` where there is one)."""
    if not isinstance(entry, dict) or set(entry) != {"start", "range"}:
        raise SpecError(where, "give start = x and range = [low, high]")
    if scenario is not None:
        scenario.refuse_also_set(variable, where, "fit")
    low, high = low_high(entry["range"], f"{where}.range")
    start = finite(entry["start"], f"{where}.start")
    if not low <= start <= high:
        raise SpecError(f"{where}.start", f"must lie in its range [{low}, {high}], got {start}")
    return FitParameter(name, start, low, high, variable, experiment)
