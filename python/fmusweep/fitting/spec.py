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

Every table is read against its declaration (``fmusweep.schema.fit``) and the rules between
tables checked over whatever was read, in one pass; each mistake is a SpecError naming the
field. The checks that need the FMU are in ``fmusweep.check``, in the same pass.
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
from ..errors import Collector, SpecError
from ..records import Plan, SeriesPlan
from ..schema.core import Table, read
from ..schema.fit import INTERVALS, JACOBIANS, MAX_STARTS, FitParameterEntry, fit_tables
from ..schema.scenario import ScenarioTable
from ..spec import Scenario, SettledScenario, _ssp_contents, _system, named_fmu, raise_all, \
    read_source
from ..system import System
from .data import Data

__all__ = ["FitSpec", "FitParameter", "Experiment", "INTERVALS", "SINGLE_EXPERIMENT",
           "FitReading", "read_fit", "MAX_STARTS", "JACOBIANS"]

DEFAULT_MAX_ITERATIONS = 100
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
        names are checked against the FMU by ``fmusweep.study``, in the same pass)."""
        return read_fit(raw, pathlib.Path(base_dir)).spec()

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
class ParsedExperiment:
    """An experiment as read (complete or not), before its parameters have their places in
    the parameter vector."""
    name: str
    where: str  # "" for the [data] table's, else "experiment.NAME."
    scenario: SettledScenario
    data: Data | None
    own: list[FitParameter]


@dataclass
class FitReading:
    """One pass over a fit's spec without the FMU: what was read and every mistake found;
    the checks against the FMU take it from here, ``spec()`` makes the FitSpec."""
    raw: dict[str, Any]
    base_dir: pathlib.Path
    tables: Any
    errors: list[SpecError]
    experiments: list[ParsedExperiment]
    shared: list[FitParameter]
    system: System | None
    ssp: str | None

    @property
    def fmu(self) -> str | None:
        return named_fmu(self.tables)

    @property
    def fitted(self) -> list[FitParameter]:
        return self.shared + [p for e in self.experiments for p in e.own]

    def spec(self) -> FitSpec:
        raise_all(self.errors)
        fit = self.tables.fit
        experiments, fitted = _numbered(self.experiments, self.shared)
        names = [p.name for p in fitted]
        profiled = (list(dict.fromkeys(fit.profile)) if fit.profile is not None
                    else (names if fit.intervals != "wald" else []))
        tolerance = experiments[0].scenario.tolerance
        # A forward difference's error is the step plus the model's own error over the step;
        # the square root of the integrator's tolerance balances the two.
        step = fit.relative_step if fit.relative_step is not None else (
            math.sqrt(tolerance) if tolerance else 1e-4)
        return FitSpec(self.raw, self.base_dir,
                       (self.base_dir / self.fmu) if self.fmu else None, self.system,
                       experiments, fitted, fit.starts, fit.seed, fit.max_iterations,
                       float(step), fit.intervals, profiled, fit.jacobian)


def read_fit(raw: dict[str, Any], base_dir: pathlib.Path) -> FitReading:
    """Every table of a fit's spec read, and the rules between them checked over whatever
    was read: every mistake in one list."""
    raw = copy.deepcopy(raw)
    errors: list[SpecError] = []
    contents = _ssp_contents(raw, base_dir, errors)
    found = read(fit_tables(raw), raw)
    errors += [_by_experiment_name(e, raw) for e in found.errors]
    tables = found.value
    part = (lambda name: tables.get(name)) if tables is not None else (lambda name: None)
    options = part("system")
    if raw.get("ssp") is not None and options is not None and options.get("engine") == "fmpy":
        errors.append(SpecError("system.engine", "a fit runs an SSP file natively only: not "
                                                 "with engine = \"fmpy\""))
    fit = part("fit")
    shared_entries = (fit.get("parameters") if fit is not None else None) or {}
    experiments = _experiments(raw, part, base_dir, set(shared_entries), errors)
    shared = _shared(shared_entries, experiments, errors)
    _between_tables(fit, shared, experiments, errors)
    system = _system(raw, part("system"), contents, base_dir, errors)
    return FitReading(raw, base_dir, tables, errors, experiments, shared, system, part("ssp"))


def _by_experiment_name(error: SpecError, raw: dict[str, Any]) -> SpecError:
    """A mistake in the k-th [[experiment]] named by the experiment's name, where it has
    one (experiment.braked.data, not experiment[0].data)."""
    if not error.field.startswith("experiment["):
        return error
    index, _, rest = error.field[len("experiment["):].partition("]")
    listed = raw.get("experiment")
    if not index.isdigit() or not isinstance(listed, list) or int(index) >= len(listed):
        return error
    entry = listed[int(index)]
    name = entry.get("name") if isinstance(entry, dict) else None
    if not isinstance(name, str) or rest == ".name" or not name.isidentifier():
        return error
    return SpecError(f"experiment.{name}{rest}", error.rule)


def _experiments(raw: dict[str, Any], part: Any, base_dir: pathlib.Path, shared: set[str],
                 errors: list[SpecError]) -> list[ParsedExperiment]:
    """The [data] table's one experiment, or each [[experiment]] table's."""
    listed = part("experiment")
    if listed is None:
        scenario = SettledScenario.of(part("scenario"), base_dir)
        errors += scenario.errors
        return [ParsedExperiment(SINGLE_EXPERIMENT, "", scenario,
                                 _data(part("data"), base_dir, scenario, "data", errors), [])]
    parsed: list[ParsedExperiment] = []
    for k, entry in enumerate(listed):
        name = entry.get("name") if entry is not None else None
        if not isinstance(name, str):
            continue
        where = f"experiment.{name}"
        if name in {e.name for e in parsed}:
            errors.append(SpecError(f"{where}.name", "names another experiment too"))
            continue
        scenario = _merged_scenario(raw, (raw.get("experiment") or [{}])[k], where, base_dir,
                                    errors)
        data = _data(entry.get("data"), base_dir, scenario, f"{where}.data", errors)
        own = []
        for variable, fitted in (entry.get("parameters") or {}).items():
            field_name = f"{where}.parameters.{variable}"
            if variable in shared:
                errors.append(SpecError(field_name, f"{variable} is fitted for every "
                                        "experiment in fit.parameters: fit it there or here, "
                                        "not both"))
                continue
            parameter = _parameter(variable, fitted, scenario, field_name,
                                   f"{name}.{variable}", name, errors)
            if parameter is not None:
                own.append(parameter)
        parsed.append(ParsedExperiment(name, f"{where}.", scenario, data, own))
    weighed = [e.name for e in parsed if e.data is not None and all(e.data.sigma_given)]
    unweighed = [e.name for e in parsed if e.data is not None and e.name not in weighed]
    if weighed and unweighed:
        errors.append(SpecError(f"experiment.{unweighed[0]}.data.sigma",
                                f"is missing while experiment {weighed[0]} gives σ: give every "
                                "experiment's columns a σ, or none (then they share one σ "
                                "estimated from the residuals)"))
    return parsed


def _merged_scenario(raw: dict[str, Any], entry: Any, where: str, base_dir: pathlib.Path,
                     errors: list[SpecError]) -> SettledScenario:
    """The shared [scenario] with an experiment's changes; a mistake in a field the
    experiment sets is named as the experiment's."""
    shared, changes = raw.get("scenario"), entry.get("scenario") if isinstance(entry, dict) else None
    base: dict[str, Any] = shared if isinstance(shared, dict) else {}
    own: dict[str, Any] = changes if isinstance(changes, dict) else {}
    merged = {**base, **own}
    for key in ("parameters", "inputs"):
        if isinstance(base.get(key), dict) and isinstance(own.get(key), dict):
            merged[key] = {**base[key], **own[key]}
    found = read(ScenarioTable, merged, ("scenario",))
    scenario = SettledScenario.of(found.value, base_dir)
    for e in found.errors + scenario.errors:
        parts = e.field.split(".")
        in_own = len(parts) > 1 and parts[1] in own and (
            len(parts) < 4 or parts[1] not in ("parameters", "inputs")
            or parts[2] in own[parts[1]])
        errors.append(SpecError(f"{where}.{e.field}", e.rule) if in_own else e)
    return scenario


def _data(table: Any, base_dir: pathlib.Path, scenario: SettledScenario, where: str,
          errors: list[SpecError]) -> Data | None:
    """The measured data, its times against the scenario's grid where that was read."""
    if table is None:
        return None
    complete = isinstance(table, Table)
    file = table.file if complete else table.get("file")
    if not isinstance(file, str):
        return None
    # A table with mistakes: its file is still read, against whatever σ was read, and
    # gives no data.
    sigma = table.sigma if complete else table.get("sigma")
    collector = Collector()
    data = collector.run(lambda: Data.of(file, sigma or {}, base_dir,
                                         scenario.times() if complete else None, where))
    errors += collector.errors
    return data


def _shared(entries: dict[str, Any], experiments: list[ParsedExperiment],
            errors: list[SpecError]) -> list[FitParameter]:
    """The parameters fitted for every experiment, each checked against every experiment's
    scenario."""
    shared = []
    scenarios: list[SettledScenario | None] = [e.scenario for e in experiments] or [None]
    for name, entry in entries.items():
        found = [_parameter(name, entry, scenario, f"fit.parameters.{name}", name, None, errors)
                 for scenario in scenarios]
        if found[0] is not None and all(p is not None for p in found):
            shared.append(found[0])
    return shared


def _between_tables(fit: Any, shared: list[FitParameter],
                    experiments: list[ParsedExperiment], errors: list[SpecError]) -> None:
    """Something to fit; the profiled parameters among those fitted; no fitted parameter
    named like a column of the results."""
    own = [p for e in experiments for p in e.own]
    entries = (fit.get("parameters") if fit is not None else None)
    if entries == {} and not any(e.own for e in experiments):
        errors.append(SpecError("fit.parameters", "names no parameter: there is nothing to fit"))
    names = [p.name for p in shared + own]
    for name in (fit.get("profile") if fit is not None else None) or []:
        if name not in names and names:
            errors.append(SpecError("fit.profile", f"{name!r} is not fitted (fitted: "
                                                   f"{', '.join(names)})"))
    fields = ([f"fit.parameters.{p.name}" for p in shared]
              + [f"experiment.{p.experiment}.parameters.{p.variable}" for p in own])
    collector = Collector()
    refuse_collisions([(name, where, "the fitted parameter")
                       for name, where in zip(names, fields)], FIT_COLUMNS, collector)
    errors += collector.errors


def _numbered(parsed: list[ParsedExperiment],
              shared: list[FitParameter]) -> tuple[list[Experiment], list[FitParameter]]:
    """The experiments with their columns of the parameter vector: the shared parameters
    first, then each experiment's own."""
    fitted = list(shared)
    experiments = []
    for e in parsed:
        assert e.scenario.scenario is not None and e.data is not None
        columns = list(range(len(shared))) + list(range(len(fitted), len(fitted) + len(e.own)))
        fitted.extend(e.own)
        experiments.append(Experiment(e.name, e.scenario.scenario, e.data, columns,
                                      [fitted[j].variable for j in columns]))
    return experiments, fitted


def _parameter(variable: str, entry: Any, scenario: SettledScenario | None, where: str,
               name: str, experiment: str | None, errors: list[SpecError]) -> FitParameter | None:
    """A fitted parameter's entry, read without mistakes (its own are reported by the
    schema), that its experiment's scenario does not set too."""
    if scenario is not None and scenario.table is not None:
        parameters = scenario.table.get("parameters") or {}
        inputs = scenario.table.get("inputs") or {}
        for table, settings in (("parameters", parameters), ("inputs", inputs)):
            if variable in settings:
                errors.append(SpecError(where, f"{variable} is also set in scenario.{table}: "
                                               "fit it or set it there, not both"))
                return None
    if not isinstance(entry, FitParameterEntry):
        return None
    low, high = entry.range
    return FitParameter(name, entry.start, low, high, variable, experiment)
