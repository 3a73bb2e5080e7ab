"""A fit's specification, table by table: what runs and the ``[scenario]`` as a sweep's,
the measured data (``[data]``, or ``[[experiment]]`` tables), and ``[fit]``."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated, Any, Literal

from annotated_types import Gt

from ..errors import SpecError
from .core import Loc, Parts, Table, absent, at, field
from .scenario import ScenarioTable
from .sweep import SspSystemOptions, SystemTable, one_target
from .values import Path, Range

__all__ = ["FitTables", "SspFitTables", "DataTable", "ExperimentTable", "FitTable",
           "FitParameterEntry", "fit_tables", "MAX_STARTS", "INTERVALS", "JACOBIANS"]

MAX_STARTS = 1000
# How a fit's 95 % intervals are found: from the Jacobian at the optimum (Wald), from the
# profile of the cost with the other parameters re-optimised, or both side by side.
INTERVALS = ("wald", "profile", "both")
# Where the Jacobian comes from: forward differences, or the FMU's own sensitivities
# wherever it offers them (docs/sensitivities.md) and differences for the rest.
JACOBIANS = ("differences", "sensitivities")


class FitParameterEntry(Table):
    about = "A fitted parameter: where its search starts, and the range it stays in."
    start: float = field("where the search starts, inside the range")
    range: Range = field("the least and greatest value tried", shows="[low, high]")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        start, bounds = parts.get("start"), parts.get("range")
        if start is not None and bounds is not None and not bounds[0] <= start <= bounds[1]:
            yield SpecError(at(where + ("start",)), f"must lie in its range [{bounds[0]:g}, "
                                                    f"{bounds[1]:g}], got {start:g}")


class DataTable(Table):
    about = "Measured data: a CSV file with a time column and one column per measured output."
    file: Path = field("the CSV file, relative to the spec", shows="path")
    sigma: dict[str, Annotated[float, Gt(0)]] = field(
        "each measured column's standard deviation (all or none)", {},
        shows="table of column = number > 0")


class ExperimentTable(Table):
    about = "One measured run of several: its data, its changes to [scenario], its own parameters."
    name: str = field("the experiment's name (letters, digits, _)", shows="name")
    data: DataTable = field("its measured data", shows="table")
    scenario: dict[str, Any] = field("its changes to the shared [scenario] (parameters and "
                                     "inputs merged entry by entry)", {}, shows="table")
    parameters: dict[str, FitParameterEntry] = field(
        "parameters fitted for this experiment alone (NAME.variable in the results)", {},
        shows="table of name = { start, range }")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        name = parts.get("name")
        if name is not None and not name.isidentifier():
            yield SpecError(at(where + ("name",)), f"must be a name (letters, digits, _), got "
                                                   f"{name!r}")


class FitTable(Table):
    about = "What is fitted, and how."
    parameters: dict[str, FitParameterEntry] = field(
        "the parameters fitted, shared by every experiment", {},
        shows="table of name = { start, range }")
    starts: int = field("searches from the start and from a Latin hypercube's points", 1,
                        ge=1, le=MAX_STARTS)
    seed: int | None = field("the hypercube's seed: needed when starts > 1", None, ge=0)
    max_iterations: int = field("trial points of each start, at most", 100, ge=1)
    relative_step: float | None = field("the Jacobian's perturbations, relative (default: "
                                        "√tolerance, else 1e-4)", None, gt=0, lt=0.1)
    intervals: Literal["wald", "profile", "both"] = field(
        "the 95 % intervals: from the Jacobian (wald), the cost's profile, or both", "wald")
    profile: list[str] | None = field("the parameters profiled (default: all)", None,
                                      shows="list of names")
    jacobian: Literal["differences", "sensitivities"] = field(
        "forward differences, or the FMU's own sensitivities where it offers them",
        "differences")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        starts = parts.get("starts")
        if isinstance(starts, int) and starts > 1 and absent(parts, "seed"):
            yield SpecError(at(where + ("seed",)), "more than one start needs a seed, so that "
                                                   "the fit can be repeated")
        if parts.get("profile") is not None and parts.get("intervals") == "wald":
            yield SpecError(at(where + ("profile",)), "profiles parameters for intervals = "
                                                      "\"profile\" or \"both\": set "
                                                      "fit.intervals too")
        if parts.get("profile") == []:
            yield SpecError(at(where + ("profile",)), "must name at least one fitted parameter")


class FitTables(Table):
    about = "A fit's specification."
    fmu: Path | None = field("the FMU, relative to the spec (or the caller's fmu)", None,
                             shows="path")
    ssp: Path | None = field("an SSP file's system instead (run natively)", None, shows="path")
    system: SystemTable | None = field("a coupled system instead", None, shows="table")
    scenario: ScenarioTable = field("the run every experiment shares", shows="table")
    data: DataTable | None = field("the measured data (or [[experiment]] tables)", None,
                                   shows="table")
    experiment: list[ExperimentTable] | None = field("several measured runs instead of [data]",
                                                     None, shows="list of tables")
    fit: FitTable = field("what is fitted, and how", shows="table")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        if not absent(parts, "data") and not absent(parts, "experiment"):
            yield SpecError("data", "give either one [data] table or [[experiment]] tables, "
                                    "not both")
        if absent(parts, "data") and absent(parts, "experiment"):
            yield SpecError("data", "is missing: give the measured data, a [data] table or "
                                    "[[experiment]] tables")
        if parts.get("experiment") == []:
            yield SpecError("experiment", "must be [[experiment]] tables, at least one")
        yield from one_target(parts)


class ExperimentsFitTables(FitTables):
    scenario: dict[str, Any] = field(  # type: ignore[assignment]
        "what every experiment's run shares (each completes it)", {}, shows="table")


class SspFitTables(FitTables):
    system: SspSystemOptions | None = field(  # type: ignore[assignment]
        "how the SSP file's system runs", None, shows="table")


class SspExperimentsFitTables(ExperimentsFitTables):
    system: SspSystemOptions | None = field(  # type: ignore[assignment]
        "how the SSP file's system runs", None, shows="table")


def fit_tables(raw: object) -> type[FitTables]:
    """The declaration of a fit spec as written: with [[experiment]] tables, with an SSP
    file."""
    ssp = isinstance(raw, dict) and raw.get("ssp") is not None
    experiments = isinstance(raw, dict) and "experiment" in raw
    choices: dict[tuple[bool, bool], type[FitTables]] = {
        (False, False): FitTables, (False, True): SspFitTables,
        (True, False): ExperimentsFitTables, (True, True): SspExperimentsFitTables}
    return choices[(experiments, ssp)]
