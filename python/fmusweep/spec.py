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

Everything here is checked before anything runs: each mistake is a SpecError that names
the field (``design.parameters.k34.linspace``) and the rule it breaks. Checks that need
the FMU (variable names, causalities, the FMU's own rules on values) are in
``fmusweep.check``.
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
from typing import Any, Callable, TypeVar

from .cycle import CHAIN_POINTS, CYCLE_COLUMNS, CycleSpec
from .designs import KINDS, Design, generate, kind_of
from .columns import SERIES_COLUMNS, SWEEP_COLUMNS, refuse_collisions
from .errors import Collector, SpecError, refuse
from .ssd import SspContents, read_ssp
from .system import System
from .fields import number as _number
from .fields import only as _only
from .fields import setting
from .fields import table as _table
from .records import InputTable, MetricPlan, Plan, SeriesPlan

T = TypeVar("T")

__all__ = ["SpecError", "Spec", "Scenario", "MetricSpec", "METRIC_KINDS", "DESIGN_KINDS"]

METRIC_KINDS = ("final", "min", "max", "peak_abs", "mean", "rms", "peak_to_peak")
# The FMUs' own tolerance under a coupling tolerance, as a fraction of it: on the DC motor
# and the mechanism the coupling error dominates the run's error over a wide range of FMU
# tolerances (bench-coupling's report), and a tenth keeps a margin.
FMU_TOLERANCE_RATIO = 0.1
DESIGN_KINDS = tuple(KINDS)


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


# The interfaces a single FMU may run through (``[scenario] interface``): a Model Exchange
# FMU's states are integrated by the runner (DOP853 or Radau IIA, as ``integrator`` says) at
# the scenario's tolerance.
INTERFACES = ("co_simulation", "model_exchange")
# What integrates a Model Exchange FMU (``[scenario] integrator``): DOP853 by default, or
# Radau IIA for a stiff one.
INTEGRATORS = ("dop853", "radau5")


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
    def of(raw: dict[str, Any], base_dir: pathlib.Path = pathlib.Path(".")) -> "Scenario":
        """The [scenario] table (its input files relative to `base_dir`), every mistake of
        its fields reported at once."""
        scenario = _table(raw, "scenario", "spec", required=True)
        errors = Collector()
        errors.run(lambda: _only(scenario, "scenario", {
            "start", "stop", "step", "tolerance", "timeout", "parameters", "inputs",
            "interface", "integrator"}))
        times = errors.run(lambda: _times(scenario))
        tolerance = errors.run(lambda: _positive(scenario, "tolerance"))
        timeout = errors.run(lambda: _positive(scenario, "timeout", " seconds"))
        parameters = _each(scenario, "parameters", errors,
                           lambda name, value, where: _setting(value, where, name))
        inputs = _each(scenario, "inputs", errors,
                       lambda name, value, where: _input(value, where, name, base_dir))
        interface = errors.run(lambda: _one_of(scenario, "interface", INTERFACES))
        integrator = errors.run(lambda: _one_of(scenario, "integrator", INTEGRATORS))
        errors.raise_any()
        assert times is not None
        return Scenario(*times, tolerance, timeout, parameters, inputs, interface, integrator)

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
        for table, settings in (("parameters", self.parameters), ("inputs", self.inputs)):
            if name in settings:
                raise SpecError(where, f"{name} is also set in scenario.{table}: {what} it or "
                                       f"set it there, not both")

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


def _times(scenario: dict[str, Any]) -> tuple[float, float, float]:
    """start, stop and step: a whole number of steps from start to stop."""
    start = _number(scenario.get("start", 0.0), "scenario.start")
    stop = _number(scenario.get("stop"), "scenario.stop")
    step = _number(scenario.get("step"), "scenario.step")
    if step <= 0:
        raise SpecError("scenario.step", f"must be > 0, got {step}")
    if stop <= start:
        raise SpecError("scenario.stop", f"must be > scenario.start ({start}), got {stop}")
    steps = (stop - start) / step
    if abs(steps - round(steps)) > 1e-6:
        raise SpecError("scenario.step", f"stop − start = {stop - start} is not a whole number of steps of {step}")
    return start, stop, step


def _positive(scenario: dict[str, Any], key: str, unit: str = "") -> float | None:
    """An optional number > 0."""
    value = scenario.get(key)
    if value is None:
        return None
    value = _number(value, f"scenario.{key}")
    if value <= 0:
        raise SpecError(f"scenario.{key}", f"must be > 0{unit}, got {value}")
    return value


def _one_of(scenario: dict[str, Any], key: str, allowed: tuple[str, ...]) -> str | None:
    value = scenario.get(key)
    if value is not None and value not in allowed:
        raise SpecError(f"scenario.{key}", f"must be one of {', '.join(map(repr, allowed))}, "
                                           f"got {value!r}")
    return value


def _each(scenario: dict[str, Any], key: str, errors: Collector,
          read: Callable[[str, object, str], T]) -> dict[str, T]:
    """The entries of table scenario.KEY, each read by `read(name, value, field)`; each
    entry's mistake kept in `errors`."""
    entries = errors.run(lambda: _table(scenario, key, "scenario")) or {}
    found: dict[str, T] = {}
    for name, value in entries.items():
        where = f"scenario.{key}.{name}"
        read_one = errors.run(lambda: read(name, value, where))
        if read_one is not None:
            found[name] = read_one
    return found


def what_runs(raw: dict[str, Any], base_dir: pathlib.Path) -> tuple[str | None, str | None, System | None]:
    """The spec's FMU path, SSP path or [system], at most one of them (each checked); a
    [system] beside an SSP file chooses how the file's system runs. For an SSP file, the
    system it describes natively (None on FMPy's path), its default experiment and
    parameter values taken into `raw`'s scenario where the spec sets none."""
    fmu, ssp = raw.get("fmu"), raw.get("ssp")
    for key, value in (("fmu", fmu), ("ssp", ssp)):
        if value is not None and not isinstance(value, str):
            raise SpecError(key, "must be a path (a string)")
    named = [key for key in ("fmu", "ssp", "system") if raw.get(key) is not None]
    if ssp is not None and "system" in named:
        named.remove("system")
    if len(named) > 1:
        raise SpecError(named[1], f"a spec names one of an FMU, an SSP system or a [system], "
                                  f"not {' and '.join(named)}")
    if ssp is not None:
        return fmu, ssp, _ssp_system(raw, base_dir / ssp)
    system = System.of(raw["system"], base_dir) if "system" in raw else None
    return fmu, ssp, system


def _ssp_system(raw: dict[str, Any], path: pathlib.Path) -> System | None:
    """The SSP file's system for the native runner, or None for FMPy's path
    (``[system] engine = "fmpy"``)."""
    contents = read_ssp(path)
    _take_ssp_defaults(raw, contents)
    table = raw.get("system")
    if isinstance(table, dict) and table.get("engine") == "fmpy":
        extra = sorted(set(table) - {"engine"})
        if extra:
            raise SpecError(f"system.{extra[0]}", "FMPy's SSP path holds inputs over each step "
                                                  "at the scenario's step: it takes no other option")
        return None
    return System.from_ssp(path, contents, table)


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
        are checked against the FMU afterwards, also all at once)."""
        raw = copy.deepcopy(raw)
        base_dir = pathlib.Path(base_dir)
        errors = Collector()
        errors.run(lambda: _only(raw, "spec", {"fmu", "ssp", "system", "scenario", "design",
                                               "outputs", "cycle"}))
        cycle = errors.run(lambda: CycleSpec.of(raw))
        on_cycle = isinstance(raw.get("cycle"), dict)
        runs = errors.run(lambda: what_runs(raw, base_dir))
        scenario = errors.run(lambda: Scenario.of(raw, base_dir))
        header = errors.run(lambda: _design_header(raw, scenario))
        # The design's own fields are checked where its points are generated.
        points = errors.run(lambda: generate(header[1], header[0], header[2])
                            if header is not None else None)
        outputs = errors.run(lambda: _outputs(raw, scenario, on_cycle))
        if header is not None and outputs is not None:
            own = SWEEP_COLUMNS + SERIES_COLUMNS + (CYCLE_COLUMNS if on_cycle else ())
            refuse_collisions(_column_names(header[0], outputs), own, errors)
        errors.raise_any()
        assert runs and scenario and header and outputs
        fmu, ssp, system = runs
        if system is not None and scenario.interface == "model_exchange":
            raise SpecError("scenario.interface", "a coupled system runs its components' "
                                                  "co-simulation interfaces")
        design, kind, seed = header
        metrics, series_variables, every = outputs
        if cycle is not None:
            series_variables, every = cycle.keep, 0
        assert points is not None
        return Spec(raw=raw, base_dir=base_dir, fmu=(base_dir / fmu) if fmu else None,
                    ssp=(base_dir / ssp) if ssp else None, system=system, scenario=scenario,
                    design_kind=kind, design=design, seed=seed, metrics=metrics, points=points,
                    series_variables=series_variables, series_every=every, cycle=cycle)

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


def _design_header(raw: dict[str, Any],
                   scenario: Scenario | None) -> tuple[dict[str, Any], str, int | None]:
    """The [design] table, its kind and seed; its columns must not be set by the scenario
    too (whose own mistakes are reported apart)."""
    design = _table(raw, "design", "spec", required=True)
    kind = design.get("kind", "grid")
    needs_seed = kind_of(kind).needs_seed
    seed = design.get("seed")
    if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool) or seed < 0):
        raise SpecError("design.seed", f"must be a whole number ≥ 0, got {seed!r}")
    if needs_seed and seed is None:
        raise SpecError("design.seed", f"a {kind} design needs a seed, so that it can be repeated")
    if not _table(design, "parameters", "design"):
        raise SpecError("design.parameters", "names no parameter: the design is empty")
    if scenario is not None:
        errors = Collector()
        for name in design["parameters"]:
            errors.run(lambda: scenario.refuse_also_set(name, f"design.parameters.{name}", "vary"))
        errors.raise_any()
    return design, kind, seed


def _outputs(raw: dict[str, Any], scenario: Scenario | None,
             on_cycle: bool = False) -> tuple[list[MetricSpec], list[str], int]:
    """The [outputs] table: the metrics, and the series' variables and interval (as a
    number of the scenario's steps, once the scenario is known); with a [cycle], metrics
    over one cycle and no series (the cycle keeps its own)."""
    outputs = _table(raw, "outputs", "spec", required=True)
    _only(outputs, "outputs", {"metrics", "series"})
    errors = Collector()
    read = _cycle_metric if on_cycle else _metric
    metrics = [errors.run(lambda: read(name, m, scenario))
               for name, m in _table(outputs, "metrics", "outputs").items()]
    series = _table(outputs, "series", "outputs")
    if series and on_cycle:
        errors.run(lambda: refuse("outputs.series", "a sweep of steady cycles has no transient "
                                                    "to record: cycle.keep keeps variables over "
                                                    "one cycle"))
        series = {}
    series_variables: list[str] = []
    every = 0
    if series:
        _only(series, "outputs.series", {"variables", "interval"})
        listed = series.get("variables")
        if isinstance(listed, list) and listed and all(isinstance(v, str) for v in listed):
            series_variables = listed
        else:
            errors.run(lambda: refuse("outputs.series.variables",
                                       "must be a non-empty list of variable names"))
        if scenario is not None:
            step = scenario.step
            interval = _number(series.get("interval", step), "outputs.series.interval")
            every = round(interval / step)
            if every < 1 or abs(interval / step - every) > 1e-6:
                errors.run(lambda: refuse("outputs.series.interval",
                                           f"must be a whole multiple of scenario.step ({step}), "
                                           f"got {interval}"))
    errors.raise_any()
    if not metrics and not series_variables and not on_cycle:
        raise SpecError("outputs", "asks for nothing: give outputs.metrics or outputs.series")
    return [m for m in metrics if m is not None], series_variables, every



# --- field checks -----------------------------------------------------------------------
def _setting(value: object, where: str, name: str) -> float:
    """A fixed parameter's value (``fields.setting``), which must be there."""
    if value is None:
        raise SpecError(where, "is missing")
    return setting(value, where, name)


def _input(value: object, where: str, name: str, base_dir: pathlib.Path) -> InputTable:
    """A constant, a table of times and values, or a CSV file's time column and a column
    of it (named like the input unless ``column`` says)."""
    if not isinstance(value, dict):
        return {"times": [0.0], "values": [_number(value, where)]}
    if "file" in value:
        _only(value, where, {"file", "column"})
        return _input_file(value, where, name, base_dir)
    _only(value, where, {"times", "values", "file", "column"})
    times, values = value.get("times"), value.get("values")
    if not (isinstance(times, list) and isinstance(values, list) and times and len(times) == len(values)):
        raise SpecError(where, "a table needs times and values: lists of equal, non-zero length")
    times = [_number(t, f"{where}.times") for t in times]
    values = [_number(v, f"{where}.values") for v in values]
    if any(b <= a for a, b in zip(times, times[1:])):
        raise SpecError(f"{where}.times", "must be strictly increasing")
    return {"times": times, "values": values}


def _input_file(value: dict[str, Any], where: str, name: str,
                base_dir: pathlib.Path) -> InputTable:
    file, column = value.get("file"), value.get("column", name)
    if not isinstance(file, str):
        raise SpecError(f"{where}.file", "must name a CSV file (a path relative to the spec)")
    if not isinstance(column, str):
        raise SpecError(f"{where}.column", f"must name a column of {file}, got {column!r}")
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
            times.append(_number(float(row[t]), f"{where}.file"))
            values.append(_number(float(row[v]), f"{where}.file"))
        except (ValueError, IndexError, SpecError):
            raise SpecError(f"{where}.file", f"{path} line {line}: time and {column} must be "
                                             "finite numbers") from None
    if not times:
        raise SpecError(f"{where}.file", f"{path} has a header and no data")
    if any(b <= a for a, b in zip(times, times[1:])):
        raise SpecError(f"{where}.file", f"{path}: the times must be strictly increasing")
    return {"times": times, "values": values}


def _column_names(design: dict[str, Any],
                  outputs: tuple[list[MetricSpec], list[str], int]) -> list[tuple[str, str, str]]:
    """The names the spec gives columns of the results, each with its field, in the order
    they are claimed."""
    metrics = outputs[0]
    return ([(name, f"design.parameters.{name}", "the design parameter")
             for name in design.get("parameters", {})]
            + [(m.name, f"outputs.metrics.{m.name}", "the metric name") for m in metrics])


def _metric(name: str, m: object, scenario: Scenario | None) -> MetricSpec:
    where = f"outputs.metrics.{name}"
    if not isinstance(m, dict):
        raise SpecError(where, "must be a table with variable and kind")
    _only(m, where, {"variable", "kind", "from", "to", "extremes"})
    if not isinstance(m.get("variable"), str):
        raise SpecError(f"{where}.variable", "must name a variable")
    extremes = m.get("extremes")
    if extremes is not None and not isinstance(extremes, str):
        raise SpecError(f"{where}.extremes", f"must be \"refined\" or \"sampled\", got "
                                             f"{extremes!r}")
    if m.get("kind") not in METRIC_KINDS:
        raise SpecError(f"{where}.kind", f"must be one of {', '.join(METRIC_KINDS)}, got {m.get('kind')!r}")
    start = _number(m["from"], f"{where}.from") if "from" in m else None
    end = _number(m["to"], f"{where}.to") if "to" in m else None
    if start is not None and end is not None and end < start:
        raise SpecError(f"{where}.to", f"must be ≥ from ({start}), got {end}")
    if scenario is not None:
        _window_holds_a_point(scenario, start, end, where)
    return MetricSpec(name, m["variable"], m["kind"], start, end, extremes=extremes)


def _cycle_metric(name: str, m: object, scenario: Scenario | None) -> MetricSpec:
    """A metric over one steady cycle, as written: the runner holds its rules (no window,
    a kind the cycle has, an order for a harmonic)."""
    if not isinstance(m, dict):
        raise SpecError(f"outputs.metrics.{name}", "must be a table with variable and kind")
    variable, kind = m.get("variable"), m.get("kind")
    return MetricSpec(name, variable if isinstance(variable, str) else "",
                      kind if isinstance(kind, str) else "", None, None, entry=dict(m))


# A communication point this close to a window's end, in steps, belongs to the window (the
# runner's own slack, runner/src/metrics.rs).
WINDOW_SLACK = 1e-9


def _window_holds_a_point(scenario: Scenario, start: float | None, end: float | None,
                          where: str) -> None:
    """A metric's window lies in the run and holds at least one communication point, which
    the metric is computed from (else every row would say NaN with status ok)."""
    for key, value in (("from", start), ("to", end)):
        if value is not None and not scenario.start <= value <= scenario.stop:
            raise SpecError(f"{where}.{key}", f"must lie in the run [scenario.start, "
                                              f"scenario.stop] = [{scenario.start:g}, "
                                              f"{scenario.stop:g}], got {value:g}")
    low = scenario.start if start is None else start
    high = scenario.stop if end is None else end
    first = math.ceil((low - scenario.start) / scenario.step - WINDOW_SLACK)
    last = math.floor((high - scenario.start) / scenario.step + WINDOW_SLACK)
    if first > last:
        raise SpecError(where, f"the window [{low:g}, {high:g}] holds no communication point "
                               f"(every {scenario.step:g} s from {scenario.start:g}): widen it "
                               "or shorten scenario.step")
