"""A sweep's specification, table by table: what runs (an FMU, an SSP file, a coupled
``[system]``), the ``[scenario]``, the ``[design]`` (its kinds' tables live with the kinds,
``fmusweep.designs``), the ``[outputs]``, and a ``[cycle]``, whose rules are the runner's."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Annotated, Any, Literal

from pydantic import PlainValidator

from ..designs import DesignTable
from ..errors import SpecError
from .core import Loc, Parts, Table, at, field
from .scenario import ScenarioTable
from .values import Name, Names, Path

__all__ = ["SweepTables", "OutputsTable", "MetricEntry", "SeriesTable", "SystemTable",
           "SystemOptions", "METRIC_KINDS", "ENGINES", "COMPONENT_NAME", "sweep_tables"]

METRIC_KINDS = ("final", "min", "max", "peak_abs", "mean", "rms", "peak_to_peak")
ENGINES = ("native", "container")
# A component's name prefixes its variables' names.
COMPONENT_NAME = re.compile(r"[a-z][a-z0-9_]*\Z")


class MetricEntry(Table):
    about = "A metric: one number per point, computed by the runner over the run."
    variable: Name = field("the variable measured (any Real, Integer or Boolean)",
                           shows="name")
    kind: Literal["final", "min", "max", "peak_abs", "mean", "rms", "peak_to_peak"] = field(
        "what is measured")
    start: float | None = field("the window's start (default: the run's)", None, unit="s",
                                alias="from")
    end: float | None = field("the window's end (default: the run's)", None, unit="s",
                              alias="to")
    extremes: Literal["refined", "sampled"] | None = field(
        "min, max, peak_abs, peak_to_peak: found between the samples (refined, the default) "
        "or the largest sample", None)

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        start, end = parts.get("start"), parts.get("end")
        if start is not None and end is not None and end < start:
            yield SpecError(at(where + ("to",)), f"must be ≥ from ({start:g}), got {end:g}")


class SeriesTable(Table):
    about = "Time series kept of every point, decimated."
    variables: Names = field("the variables kept", shows="list of names")
    interval: float | None = field("every how long a row is kept: a whole multiple of "
                                   "scenario.step (default: every step)", None, unit="s", gt=0)


class OutputsTable(Table):
    about = "What each point gives: metrics, and time series."
    metrics: dict[str, MetricEntry] = field("name = { variable, kind, from, to, extremes }",
                                            {}, shows="table of name = metric")
    series: SeriesTable | None = field("time series to keep", None, shows="table")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        if parts.get("metrics") == {} and parts.get("series") is None:
            yield SpecError(at(where), "asks for nothing: give outputs.metrics or "
                                       "outputs.series")


class CycleOutputsTable(Table):
    about = "What each point's steady cycle gives: metrics over one cycle (the runner's rules)."
    hints = {"series": "a sweep of steady cycles has no transient to record: cycle.keep "
                       "keeps variables over one cycle"}
    metrics: dict[str, dict[str, Any]] = field(
        "name = { variable, kind, order, extremes }, over one cycle", {},
        shows="table of name = metric")


def _connection(value: object) -> tuple[tuple[str, str], tuple[str, str]]:
    """["component.output", "component.input"]."""
    if not (isinstance(value, list) and len(value) == 2 and all(isinstance(v, str) for v in value)):
        raise ValueError(f"must be [\"component.output\", \"component.input\"], got {value!r}")
    ends = []
    for end in value:
        component, dot, variable = end.partition(".")
        if not dot or not component or not variable:
            raise ValueError(f"{end!r} is not component.variable")
        ends.append((component, variable))
    return ends[0], ends[1]


Connection = Annotated[Any, PlainValidator(_connection)]


class SystemOptions(Table):
    about = "How a coupled system runs."
    engine: Literal["native", "container"] = field(
        "native: the runner steps the components together; container: one container FMU",
        "native")
    input_derivatives: int | None = field(
        "native: pass the sources' output derivatives up to this order (default 2 native, "
        "0 container)", None, ge=0, le=2)
    coupling_tolerance: float | None = field(
        "native: the coupling error each communication step keeps under (the runner's rule: "
        "in (0, 1), components that can save their state)", None)

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        derivatives = parts.get("input_derivatives")
        if parts.get("engine") == "container" and derivatives:
            yield SpecError(at(where + ("input_derivatives",)), "the container holds inputs "
                            "over a step: only 0 with engine = \"container\"")
        if parts.get("engine") == "container" and parts.get("coupling_tolerance") is not None:
            yield SpecError(at(where + ("coupling_tolerance",)), "only the native engine "
                            "chooses its steps: not with engine = \"container\"")


class SspSystemOptions(SystemOptions):
    about = "How an SSP file's system runs."
    hints = {key: "the SSP file gives the components and connections; beside ssp, [system] "
                  "takes engine, input_derivatives, coupling_tolerance"
             for key in ("components", "connections")}
    engine: Literal["native", "container", "fmpy"] = field(  # type: ignore[assignment]
        "native, container, or fmpy: through FMPy's SSP support, inputs held over each step",
        "native")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        yield from super().rules(parts, where)
        if parts.get("engine") == "fmpy":
            for key in ("input_derivatives", "coupling_tolerance"):
                if parts.get(key) is not None:
                    yield SpecError(at(where + (key,)), "FMPy's SSP path holds inputs over "
                                    "each step at the scenario's step: it takes no other option")


class SystemTable(SystemOptions):
    about = "A coupled system: components and the connections between them."
    components: dict[str, Path] = field("name = \"file.fmu\", relative to the spec",
                                        shows="table of name = path")
    connections: list[Connection] = field("[\"component.output\", \"component.input\"] pairs",
                                          [], shows="list of pairs")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        yield from super().rules(parts, where)
        components = parts.get("components")
        if components == {}:
            yield SpecError(at(where + ("components",)), "must name at least one component: "
                                                         "name = \"file.fmu\"")
        for name in components or {}:
            if not COMPONENT_NAME.match(name):
                yield SpecError(at(where + ("components", name)), "a component's name is "
                                "lowercase letters, digits and _, starting with a letter (it "
                                "prefixes its variables' names)")
        for k, pair in enumerate(parts.get("connections") or []):
            for component, _ in pair or ():
                if components is not None and component not in components:
                    yield SpecError(at(where + ("connections", k)), f"no component "
                                    f"{component!r} (the components: "
                                    f"{', '.join(sorted(components))})")


def one_target(parts: Parts) -> Iterator[SpecError]:
    """A spec runs one thing: an FMU, an SSP file or a [system] (with an SSP file, the
    [system] table only says how it runs)."""
    named = [key for key in ("fmu", "ssp") if parts.get(key) is not None]
    if parts.get("system") is not None and "ssp" not in named:
        named.append("system")
    if len(named) > 1:
        yield SpecError(named[1], f"a spec names one of an FMU, an SSP system or a "
                                  f"[system], not {' and '.join(named)}")


class SweepTables(Table):
    about = "A sweep's specification."
    fmu: Path | None = field("the FMU, relative to the spec (or the caller's fmu, or "
                             "$FMUSWEEP_FMU)", None, shows="path")
    ssp: Path | None = field("an SSP file's system instead, relative to the spec", None,
                             shows="path")
    system: SystemTable | None = field("a coupled system instead", None, shows="table")
    scenario: ScenarioTable = field("the run every point shares", shows="table")
    design: DesignTable = field("the points", shows="table")
    outputs: OutputsTable = field("what each point gives", shows="table")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        yield from one_target(parts)


class SspSweepTables(SweepTables):
    system: SspSystemOptions | None = field(  # type: ignore[assignment]
        "how the SSP file's system runs", None, shows="table")


class CycleSweepTables(SweepTables):
    outputs: CycleOutputsTable = field("what each point's cycle gives",  # type: ignore[assignment]
                                       shows="table")
    cycle: dict[str, Any] = field("each point's steady cycle instead of its transient (the "
                                  "runner's rules)", shows="table")


class SspCycleSweepTables(CycleSweepTables):
    system: SspSystemOptions | None = field(  # type: ignore[assignment]
        "how the SSP file's system runs", None, shows="table")


def sweep_tables(raw: object) -> type[SweepTables]:
    """The declaration of a sweep spec as written: with a [cycle], with an SSP file."""
    cycle = isinstance(raw, dict) and "cycle" in raw
    ssp = isinstance(raw, dict) and raw.get("ssp") is not None
    choices: dict[tuple[bool, bool], type[SweepTables]] = {
        (False, False): SweepTables, (False, True): SspSweepTables,
        (True, False): CycleSweepTables, (True, True): SspCycleSweepTables}
    return choices[(cycle, ssp)]
