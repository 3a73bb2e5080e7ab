"""The sweep specification: what to run, over which points, and what to keep.

A specification is a TOML file or the equivalent dict::

    fmu = "path/to/Model.fmu"          # optional: the caller may name the FMU instead
    # or: ssp = "path/to/System.ssp"   # a coupled system in an SSP file, run natively
    #                                  # ([system] engine = "fmpy": through FMPy's SSP support)
    # or a coupled system run natively (fmusweep.system):
    # [system]
    # components = { motor = "DcMotor.fmu", mechanism = "CyclicMechanism.fmu" }
    # connections = [["motor.torque", "mechanism.M_m"], ["mechanism.omega1", "motor.omega"]]

    [scenario]
    start = 0.0
    stop = 10.0
    step = 0.01                        # communication step
    tolerance = 1e-8                   # optional: the FMU's tolerance, as its master passes it
    interface = "model_exchange"       # optional: the FMU's ME interface, integrated here
    integrator = "radau5"              # optional, Model Exchange: dop853 (default) or radau5
    timeout = 60.0                     # optional: wall-time budget per point, seconds
    parameters = { d34 = 0.5 }         # fixed for every point (a Boolean: true or false)
    inputs = { M_r = 5.0, M_m = { times = [0, 1], values = [0, 10] } }

    [design]
    kind = "grid"                      # grid | list | lhs | sobol | morris
    seed = 1                           # lhs, sobol, morris
    parameters = { k34 = { linspace = [10, 1000, 40] }, L = { values = [0.6, 0.7] } }

    [outputs.metrics]
    peak_force = { variable = "rod_force", kind = "peak_abs" }
    ripple = { variable = "omega1", kind = "peak_to_peak", from = 2.0 }

    [outputs.series]                   # optional: time series, decimated
    variables = ["omega1"]
    interval = 0.1

    [cycle]                            # optional: each point's steady cycle instead of a
    state = "loop_angle"               # transient (fmusweep.cycle); the metrics are then
    advance = 6.283185307179586        # over one cycle

Everything here is checked before anything runs, in one pass: the tables against their
declaration (``fmusweep.schema``), then the rules between tables over whatever was read;
each mistake is a SpecError that names the field (``design.parameters.k34.linspace``) and
the rule it breaks. Checks that need the FMU (variable names, causalities, the FMU's own
rules on values) are in ``fmusweep.check``, over the same reading, in the same pass.
"""

from __future__ import annotations

import copy
import csv
import hashlib
import json
import math
import os
import pathlib
import tomllib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .columns import SERIES_COLUMNS, SWEEP_COLUMNS, refuse_collisions
from .cycle import CHAIN_POINTS, CYCLE_COLUMNS, CycleSpec, CycleStarts
from .designs import KINDS, Design, DesignTable, make
from .designs.base import LogRangeEntry, RangeEntry, column_values
from .errors import Collector, SpecError, SpecErrors, Unread
from .fields import setting
from .records import InputTable, MetricPlan, Plan, SeriesPlan
from .schema.core import Parts, Table, read
from .schema.scenario import INTEGRATORS, INTERFACES, InputFile, InputPoints, ScenarioTable
from .schema.sweep import METRIC_KINDS, MetricEntry, sweep_tables
from .ssd import SspContents, read_ssp
from .system import System

__all__ = ["SpecError", "Spec", "Scenario", "MetricSpec", "METRIC_KINDS", "DESIGN_KINDS",
           "SweepReading", "read_sweep", "INTERFACES", "INTEGRATORS"]

# The FMUs' own tolerance under a coupling tolerance, as a fraction of it: on the DC motor
# and the mechanism the coupling error dominates the run's error over a wide range of FMU
# tolerances (bench-coupling's report), and a tenth keeps a margin.
FMU_TOLERANCE_RATIO = 0.1
DESIGN_KINDS = tuple(KINDS)
# A column of a sampled design whose table has mistakes is asked about at this many values
# spread over its range (fmusweep.check probes as many of a column's values).
CANDIDATES = 256


@dataclass(frozen=True)
class MetricSpec:
    name: str
    variable: str
    kind: str
    start: float | None
    end: float | None
    # A harmonic's order (a metric over a steady cycle).
    order: int | None = None
    # How its extremes are found: "refined" (between the samples, the runner's default)
    # or "sampled"; the runner holds the rule.
    extremes: str | None = None
    # The entry as written (a metric over a steady cycle, whose rules are the runner's).
    entry: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Scenario:
    """The ``[scenario]`` table: the time grid, the tolerance, the per-point budget and
    the settings every run shares (a sweep's and a fit's)."""
    start: float
    stop: float
    step: float
    tolerance: float | None
    timeout: float | None
    parameters: dict[str, Any]
    inputs: dict[str, Any]
    # "co_simulation" or "model_exchange": the interface an FMU with both runs through
    # (None: co-simulation where the FMU has it).
    interface: str | None = None
    # "dop853" or "radau5": what integrates a Model Exchange FMU (None: DOP853).
    integrator: str | None = None

    @property
    def steps(self) -> int:
        return round((self.stop - self.start) / self.step)

    @staticmethod
    def of(raw: dict[str, Any], base_dir: pathlib.Path = pathlib.Path("."),
           where: str = "scenario") -> "Scenario":
        """The [scenario] table of `raw` (its input files relative to `base_dir`), every
        mistake of it reported at once."""
        found = read(ScenarioTable, raw.get("scenario"), (where,))
        settled = SettledScenario.of(found.value, base_dir, where)
        raise_all(found.errors + settled.errors)
        assert settled.scenario is not None
        return settled.scenario

    def off_grid_breakpoints(self, system: System | None) -> list[str]:
        """A warning for each input table with breakpoints between communication points,
        which the runner does not see: it sets an input at each step's start and holds it
        over the step (a [system] with a coupling tolerance ends its steps on them)."""
        if system is not None and system.coupling_tolerance is not None:
            return []
        said = []
        for name, table in self.inputs.items():
            off = [t for t in table["times"] if self.start < t < self.stop
                   and abs((t - self.start) / self.step - round((t - self.start) / self.step))
                   > WINDOW_SLACK * 1e3]
            if off:
                shown = ", ".join(f"{t:g}" for t in off[:3]) + (", …" if len(off) > 3 else "")
                said.append(f"scenario.inputs.{name}: {len(off)} breakpoint(s) at t = {shown} lie "
                            f"between communication points (every {self.step:g} s): the FMU is "
                            "given the table's value at each step's start, held over the step")
        return said

    def refuse_also_set(self, name: str, where: str, what: str) -> None:
        """`name` is varied at `where` (a design column, a fitted parameter): refused if
        the scenario fixes it or drives it as an input, since one of the two would be
        ignored without a word."""
        also_set(name, where, what, self.parameters, self.inputs)

    def plan(self, metrics: list[MetricPlan], series: SeriesPlan | None,
             system: System | None = None, cycle: Any = None) -> Plan:
        """The native runner's plan: what every point shares, and what it reads. Without a
        tolerance of its own, a system with a coupling tolerance runs its FMUs at
        FMU_TOLERANCE_RATIO of it."""
        tolerance = self.tolerance
        if tolerance is None and system is not None and system.coupling_tolerance is not None:
            tolerance = FMU_TOLERANCE_RATIO * system.coupling_tolerance
        return {"start": self.start, "stop": self.stop, "step": self.step,
                "tolerance": tolerance, "fixed": self.parameters, "inputs": self.inputs,
                "metrics": metrics, "series": series, "timeout_s": self.timeout,
                "interface": self.interface, "integrator": self.integrator, "cycle": cycle}


def also_set(name: str, where: str, what: str, parameters: dict[str, Any],
             inputs: dict[str, Any]) -> None:
    for table, settings in (("parameters", parameters), ("inputs", inputs)):
        if name in settings:
            raise SpecError(where, f"{name} is also set in scenario.{table}: {what} it or "
                                   f"set it there, not both")


def named_fmu(tables: Any) -> str | None:
    """The FMU a spec's tables name, where they name one that was read."""
    fmu = tables.get("fmu") if tables is not None else None
    return fmu if isinstance(fmu, str) else None


def raise_all(errors: list[SpecError]) -> None:
    """Every mistake at once (each field's first rule, in the order found)."""
    kept: dict[tuple[str, str], SpecError] = {}
    for e in errors:
        if not isinstance(e, Unread):
            kept.setdefault((e.field, e.rule), e)
    found = list(kept.values())
    if len(found) == 1:
        raise found[0]
    if found:
        raise SpecErrors(found)


@dataclass
class SettledScenario:
    """What was read of a [scenario] table (complete or not): its fixed values as numbers
    (by the FMU's types, ``fields.setting``) and its inputs' tables (files read), each
    mistake kept; the Scenario where nothing is wrong."""
    table: Any
    fixed: dict[str, float]
    inputs: dict[str, InputTable]
    errors: list[SpecError]
    scenario: Scenario | None

    @staticmethod
    def of(table: Any, base_dir: pathlib.Path, where: str = "scenario") -> SettledScenario:
        errors = Collector()
        fixed: dict[str, float] = {}
        for name, value in ((table.get("parameters") if table is not None else None) or {}).items():
            number = errors.run(lambda: setting(value, f"{where}.parameters.{name}", name))
            if number is not None:
                fixed[name] = number
        inputs: dict[str, InputTable] = {}
        for name, entry in ((table.get("inputs") if table is not None else None) or {}).items():
            found = errors.run(lambda: _input(entry, f"{where}.inputs.{name}", name, base_dir))
            if found is not None:
                inputs[name] = found
        scenario = None
        if isinstance(table, ScenarioTable) and not errors.errors:
            scenario = Scenario(table.start, table.stop, table.step, table.tolerance,
                                table.timeout, fixed, inputs, table.interface, table.integrator)
        return SettledScenario(table, fixed, inputs, errors.errors, scenario)

    def times(self) -> tuple[float, float, float] | None:
        """start, stop and step, where they were read and agree."""
        t = self.table
        if t is None or not all(t.get(k) is not None for k in ("start", "stop", "step")):
            return None
        start, stop, step = t.get("start"), t.get("stop"), t.get("step")
        if stop <= start or abs((stop - start) / step - round((stop - start) / step)) > 1e-6:
            return None
        return start, stop, step


def _input(entry: Any, where: str, name: str, base_dir: pathlib.Path) -> InputTable:
    """A constant, a table of times and values, or a CSV file's time column and a column
    of it (named like the input unless ``column`` says)."""
    if isinstance(entry, InputPoints):
        return {"times": list(entry.times), "values": list(entry.values)}
    if isinstance(entry, InputFile):
        return _input_file(entry.file, entry.column or name, where, base_dir)
    if isinstance(entry, float):
        return {"times": [0.0], "values": [entry]}
    raise Unread(where)


def _input_file(file: str, column: str, where: str, base_dir: pathlib.Path) -> InputTable:
    path = base_dir / file
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise SpecError(f"{where}.file", f"cannot read {path}: {e}") from None
    rows = [row for row in csv.reader(text.splitlines()) if any(cell.strip() for cell in row)]
    header = [cell.strip() for cell in rows[0]] if rows else []
    for needed in ("time", column):
        if needed not in header:
            raise SpecError(f"{where}.file", f"{path} has no {needed} column (its header: "
                                             f"{', '.join(header)})")
    t, v = header.index("time"), header.index(column)
    times, values = [], []
    for line, row in enumerate(rows[1:], start=2):
        try:
            at_time, value = float(row[t]), float(row[v])
        except (ValueError, IndexError):
            at_time = value = math.nan
        if not (math.isfinite(at_time) and math.isfinite(value)):
            raise SpecError(f"{where}.file", f"{path} line {line}: time and {column} must be "
                                             "finite numbers")
        times.append(at_time)
        values.append(value)
    if not times:
        raise SpecError(f"{where}.file", f"{path} has a header and no data")
    if any(b <= a for a, b in zip(times, times[1:])):
        raise SpecError(f"{where}.file", f"{path}: the times must be strictly increasing")
    return {"times": times, "values": values}


# --- a sweep's spec, read ---------------------------------------------------------------
@dataclass
class SweepReading:
    """One pass over a sweep's spec without the FMU: what was read (complete or not) and
    every mistake found; the checks against the FMU (``fmusweep.check``) take it from
    here, and ``spec()`` makes the Spec of a reading without mistakes."""
    raw: dict[str, Any]
    base_dir: pathlib.Path
    tables: Any
    errors: list[SpecError]
    scenario: SettledScenario
    # Each design column read (and its values as numbers): its values, or where the design
    # has mistakes, the values its entry gives (a range's spread over it).
    columns: dict[str, np.ndarray]
    design: Design | None
    metrics: list[MetricSpec]
    series_variables: list[str]
    series_every: int
    cycle: CycleSpec | None
    system: System | None
    ssp: str | None

    @property
    def fmu(self) -> str | None:
        return named_fmu(self.tables)

    def spec(self) -> Spec:
        raise_all(self.errors)
        assert self.scenario.scenario is not None and self.design is not None
        design_table = self.tables.design
        series = self.series_variables if self.cycle is None else self.cycle.keep
        return Spec(raw=self.raw, base_dir=self.base_dir,
                    fmu=(self.base_dir / self.fmu) if self.fmu else None,
                    ssp=(self.base_dir / self.ssp) if self.ssp else None, system=self.system,
                    scenario=self.scenario.scenario, design_kind=design_table.kind,
                    design=self.raw.get("design", {}), seed=design_table.get("seed"),
                    metrics=self.metrics, points=self.design, series_variables=series,
                    series_every=self.series_every if self.cycle is None else 0,
                    cycle=self.cycle)


def read_sweep(raw: dict[str, Any], base_dir: pathlib.Path) -> SweepReading:
    """Every table of a sweep's spec read, and the rules between them checked over whatever
    was read: every mistake in one list. Settings are read by the FMU's types where the
    caller reads inside ``fields.typed_by``."""
    raw = copy.deepcopy(raw)
    errors: list[SpecError] = []
    contents = _ssp_contents(raw, base_dir, errors)
    found = read(sweep_tables(raw), raw)
    errors += found.errors
    tables = found.value
    part = (lambda name: tables.get(name)) if tables is not None else (lambda name: None)
    scenario = SettledScenario.of(part("scenario"), base_dir)
    errors += scenario.errors
    columns, design = _design(part("design"), errors)
    cycle_table = part("cycle")
    cycle = CycleSpec(cycle_table) if isinstance(cycle_table, dict) else None
    if cycle is not None:
        errors += read(CycleStarts, {k: v for k, v in cycle.table.items() if k == "starts"},
                       ("cycle",)).errors
    metrics, series, every = _outputs(part("outputs"), scenario, cycle is not None, errors)
    _between_tables(scenario, list(columns) or list(_names(part("design"))), metrics, cycle,
                    errors)
    system = _system(raw, part("system"), contents, base_dir, errors)
    return SweepReading(raw, base_dir, tables, errors, scenario, columns, design, metrics,
                        series, every, cycle, system, part("ssp"))


def _names(design: Any) -> dict[str, Any]:
    parameters = design.get("parameters") if design is not None else None
    return parameters if isinstance(parameters, dict) else {}


def _design(table: Any, errors: list[SpecError]) -> tuple[dict[str, np.ndarray], Design | None]:
    """The design's points where its table was read whole, and each column's values (a
    sampled design with mistakes: its entries' ranges, spread)."""
    collector = Collector()
    columns: dict[str, np.ndarray] = {}
    for name, entry in _names(table).items():
        values = collector.run(lambda: _candidates(entry, name))
        if values is not None:
            columns[name] = np.asarray(values, dtype=float)
    errors += collector.errors
    if not isinstance(table, DesignTable) or collector.errors:
        return columns, None
    design = make(table)
    return {name: design.column_values(j) for j, name in enumerate(design.names)}, design


def _candidates(entry: Any, name: str) -> list[float]:
    if isinstance(entry, (RangeEntry, LogRangeEntry)):
        low, high = entry.range
        if isinstance(entry, LogRangeEntry) and entry.log and low > 0:
            return [float(x) for x in np.geomspace(low, high, CANDIDATES)]
        return [float(x) for x in np.linspace(low, high, CANDIDATES)]
    if isinstance(entry, Parts):
        raise Unread(f"design.parameters.{name}")
    return column_values(entry, name)


def _outputs(table: Any, scenario: SettledScenario, on_cycle: bool, errors: list[SpecError]
             ) -> tuple[list[MetricSpec], list[str], int]:
    """The metrics read (each window against the run), and the series' variables and
    interval (a number of the scenario's steps)."""
    if table is None:
        return [], [], 0
    times = scenario.times()
    metrics = []
    for name, entry in (table.get("metrics") or {}).items():
        if on_cycle:
            variable, kind = entry.get("variable"), entry.get("kind")
            metrics.append(MetricSpec(name, variable if isinstance(variable, str) else "",
                                      kind if isinstance(kind, str) else "", None, None,
                                      entry=dict(entry)))
        elif isinstance(entry, MetricEntry):
            if times is not None:
                errors += _window_mistakes(times, entry.start, entry.end,
                                           f"outputs.metrics.{name}")
            metrics.append(MetricSpec(name, entry.variable, entry.kind, entry.start, entry.end,
                                      extremes=entry.extremes))
    series = table.get("series") if not on_cycle else None
    variables: list[str] = []
    every = 0
    if series is not None:
        listed = series.get("variables")
        variables = list(listed) if isinstance(listed, list) else []
        interval = series.get("interval")
        if times is not None:
            step = times[2]
            interval = step if interval is None else interval
            every = round(interval / step)
            if every < 1 or abs(interval / step - every) > 1e-6:
                errors.append(SpecError("outputs.series.interval", f"must be a whole multiple of "
                                        f"scenario.step ({step:g}), got {interval:g}"))
    return metrics, variables, every


def _between_tables(scenario: SettledScenario, columns: list[str], metrics: list[MetricSpec],
                    cycle: CycleSpec | None, errors: list[SpecError]) -> None:
    """A design column the scenario sets too; a column of the results two names claim."""
    collector = Collector()
    table = scenario.table
    parameters = (table.get("parameters") if table is not None else None) or {}
    inputs = (table.get("inputs") if table is not None else None) or {}
    for name in columns:
        collector.run(lambda: also_set(name, f"design.parameters.{name}", "vary", parameters,
                                       inputs))
    named = ([(name, f"design.parameters.{name}", "the design parameter") for name in columns]
             + [(m.name, f"outputs.metrics.{m.name}", "the metric name") for m in metrics])
    own = SWEEP_COLUMNS + SERIES_COLUMNS + (CYCLE_COLUMNS if cycle is not None else ())
    refuse_collisions(named, own, collector)
    errors += collector.errors


def _ssp_contents(raw: dict[str, Any], base_dir: pathlib.Path,
                  errors: list[SpecError]) -> SspContents | None:
    """An SSP file's contents, its default experiment and parameter values taken into the
    scenario where the spec sets none."""
    ssp = raw.get("ssp")
    if not isinstance(ssp, str):
        return None
    try:
        contents = read_ssp(base_dir / ssp)
    except SpecError as e:
        errors.append(e)
        return None
    _take_ssp_defaults(raw, contents)
    return contents


def _system(raw: dict[str, Any], table: Any, contents: SspContents | None,
            base_dir: pathlib.Path, errors: list[SpecError]) -> System | None:
    """The coupled system a spec runs: its [system] table, or its SSP file's (None on
    FMPy's SSP path)."""
    ssp = raw.get("ssp")
    if isinstance(ssp, str):
        if contents is None or (table is not None and not isinstance(table, Table)):
            return None
        if table is not None and table.get("engine") == "fmpy":
            return None
        try:
            return System.from_ssp(base_dir / ssp, contents, table)
        except SpecError as e:
            errors.append(e)
            return None
    if table is None:
        return None
    return System.from_table(table, base_dir)


def _take_ssp_defaults(raw: dict[str, Any], contents: SspContents) -> None:
    """The SSP file's default experiment (start, stop) and parameter values, into the
    scenario where the spec gives none; a parameter the design or the fit varies is theirs."""
    scenario = raw.setdefault("scenario", {})
    if not isinstance(scenario, dict):
        return
    for key, value in (("start", contents.start), ("stop", contents.stop)):
        if value is not None:
            scenario.setdefault(key, value)
    varied: set[str] = set()
    for owner in ("design", "fit"):
        table = raw.get(owner)
        parameters = table.get("parameters") if isinstance(table, dict) else None
        if isinstance(parameters, dict):
            varied.update(parameters)
    fixed = scenario.setdefault("parameters", {})
    if isinstance(fixed, dict):
        for name, value in contents.parameters.items():
            if name not in varied:
                fixed.setdefault(name, value)


@dataclass
class Spec:
    """A sweep's specification: what runs, the scenario every point shares (its fixed
    parameters are ``scenario.parameters``), the design, and the outputs wanted."""
    raw: dict[str, Any]
    base_dir: pathlib.Path
    fmu: pathlib.Path | None
    ssp: pathlib.Path | None
    system: System | None
    scenario: Scenario
    design_kind: str
    design: dict[str, Any]
    seed: int | None
    metrics: list[MetricSpec]
    # The design's points, made when the spec is checked (sampling a large design costs
    # seconds).
    points: Design = field(repr=False)
    series_variables: list[str] = field(default_factory=list)
    series_every: int = 0
    # Each point's steady cycle instead of its transient.
    cycle: CycleSpec | None = None

    # --- loading -------------------------------------------------------------------
    @staticmethod
    def load(source: Spec | str | os.PathLike[str] | dict[str, Any],
             base_dir: str | os.PathLike[str] | None = None) -> Spec:
        """A Spec from a TOML path, a TOML string's dict, or a Spec (returned as is)."""
        if isinstance(source, Spec):
            return source
        return Spec.from_dict(*read_source(source, base_dir, "a Spec"))

    @staticmethod
    def from_dict(raw: dict[str, Any], base_dir: str | os.PathLike[str]) -> Spec:
        """The spec of `raw`, every mistake of its own fields reported at once (the names
        are checked against the FMU by ``fmusweep.study``, in the same pass)."""
        return read_sweep(raw, pathlib.Path(base_dir)).spec()

    # --- derived ---------------------------------------------------------------------
    def plan(self, description: dict[str, Any] | None = None) -> Plan:
        """The native runner's plan: everything every point shares (a steady cycle's reads
        the FMU's offer of sensitivities in its `description`)."""
        if self.cycle is not None:
            assert description is not None, "a steady cycle's plan reads the FMU's description"
            cycle = self.cycle.plan([{"field": f"outputs.metrics.{m.name}", **m.entry}
                                     for m in self.metrics], description)
            plan = self.scenario.plan([], None, self.system, cycle)
            if self.cycle.continued:
                plan["chain"] = self.points.chain_rule(CHAIN_POINTS)
            return plan
        metrics = [MetricPlan({"variable": m.variable, "kind": m.kind, "from": m.start,
                                "to": m.end, "field": f"outputs.metrics.{m.name}",
                                "extremes": m.extremes}) for m in self.metrics]
        series = (SeriesPlan(variables=self.series_variables, every=self.series_every)
                  if self.series_variables else None)
        return self.scenario.plan(metrics, series, self.system)

    def digest(self) -> str:
        """A hash of everything that decides the results (not the FMU's path)."""
        canonical = {k: v for k, v in self.raw.items() if k not in ("fmu", "ssp")}
        if self.system is not None:  # the components' contents count, not where they lie
            canonical["system"] = self.system.digest()
        # An input file's contents count (its tables as read), not where it lies.
        canonical["inputs"] = self.scenario.inputs
        text = json.dumps(canonical, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


def read_source(source: object, base_dir: str | os.PathLike[str] | None,
                also: str) -> tuple[dict[str, Any], pathlib.Path]:
    """A specification's table and the directory its paths are relative to, from a TOML
    path (its own directory) or a dict (the current directory), unless base_dir says."""
    if isinstance(source, (str, pathlib.Path)):
        path = pathlib.Path(source)
        try:
            raw = tomllib.loads(path.read_text())
        except FileNotFoundError:
            raise SpecError("spec", f"no file {path}") from None
        except tomllib.TOMLDecodeError as e:
            raise SpecError("spec", f"{path} is not valid TOML: {e}") from None
        return raw, pathlib.Path(base_dir or path.parent)
    if isinstance(source, dict):
        return source, pathlib.Path(base_dir or pathlib.Path.cwd())
    raise SpecError("spec", f"expected a path, a dict or {also}, got {type(source).__name__}")


# A communication point this close to a window's end, in steps, belongs to the window (the
# runner's own slack, runner/src/metrics.rs).
WINDOW_SLACK = 1e-9


def _window_mistakes(times: tuple[float, float, float], start: float | None, end: float | None,
                     where: str) -> list[SpecError]:
    """A metric's window lies in the run and holds at least one communication point, which
    the metric is computed from (else every row would say NaN with status ok)."""
    run_start, run_stop, step = times
    found = []
    for key, value in (("from", start), ("to", end)):
        if value is not None and not run_start <= value <= run_stop:
            found.append(SpecError(f"{where}.{key}", f"must lie in the run [scenario.start, "
                                                     f"scenario.stop] = [{run_start:g}, "
                                                     f"{run_stop:g}], got {value:g}"))
    if found:
        return found
    low = run_start if start is None else start
    high = run_stop if end is None else end
    first = math.ceil((low - run_start) / step - WINDOW_SLACK)
    last = math.floor((high - run_start) / step + WINDOW_SLACK)
    if first > last:
        found.append(SpecError(where, f"the window [{low:g}, {high:g}] holds no communication "
                                      f"point (every {step:g} s from {run_start:g}): widen it "
                                      "or shorten scenario.step"))
    return found
