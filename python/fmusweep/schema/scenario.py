"""The ``[scenario]`` table a sweep and a fit share, and its inputs."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Literal

from ..errors import SpecError
from .core import Loc, Parts, Table, at, field
from .values import Name, Path, Setting, is_number

__all__ = ["ScenarioTable", "InputEntry", "InputPoints", "InputFile",
           "INTERFACES", "INTEGRATORS", "TOLERANCE_RANGE", "STEP_SLACK"]

# The interfaces a single FMU may run through: a Model Exchange FMU's states are integrated
# by the runner (DOP853 or Radau IIA) at the scenario's tolerance.
INTERFACES = ("co_simulation", "model_exchange")
INTEGRATORS = ("dop853", "radau5")
# A relative tolerance finer than this asks for digits a double does not hold; one coarser
# than this is no longer an integration's.
TOLERANCE_RANGE = (1e-13, 0.1)
# How far from a whole number of steps stop − start may lie (in steps).
STEP_SLACK = 1e-6


class InputPoints(Table):
    about = "An input's piecewise-linear table, held beyond its ends."
    times: list[float] = field("the breakpoints' times, strictly increasing", unit="s")
    values: list[float] = field("the input's value at each breakpoint")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        times, values = parts.get("times"), parts.get("values")
        if times is not None and values is not None and (not times or len(times) != len(values)):
            yield SpecError(at(where), "a table needs times and values: lists of equal, "
                                       "non-zero length")
        if times is not None and any(b <= a for a, b in zip(times, times[1:])):
            yield SpecError(at(where + ("times",)), "must be strictly increasing")


class InputFile(Table):
    about = "An input read from a CSV file: its time column and one other."
    file: Path = field("a CSV file with a time column, relative to the spec", shows="path")
    column: Name | None = field("the column (default: the input's name)", None, shows="name")


class InputEntry(Table):
    """A constant, an inline table or a CSV file's column."""

    @classmethod
    def variant(cls, raw: object) -> Any:
        if isinstance(raw, dict):
            return InputFile if "file" in raw else InputPoints
        if is_number(raw):
            return float
        raise SpecError("", "must be a number, a table of times and values, or "
                            "{ file = \"…csv\", column = \"…\" }")


class ScenarioTable(Table):
    about = "The run every point shares: its time grid, tolerance, budget and settings."
    start: float = field("when the run starts", 0.0, unit="s")
    stop: float = field("when the run ends", unit="s")
    step: float = field("the communication step; stop − start a whole number of them",
                        unit="s", gt=0)
    tolerance: float | None = field("the FMU's relative tolerance, as its master passes it "
                                    "(default: the FMU's own)", None,
                                    ge=TOLERANCE_RANGE[0], le=TOLERANCE_RANGE[1])
    timeout: float | None = field("each point's wall-time budget", None, unit="s", gt=0)
    parameters: dict[str, Setting] = field(
        "values fixed for every point: a number, true/false for a Boolean, an item's name "
        "for an Enumeration", {}, shows="table of name = value")
    inputs: dict[str, InputEntry] = field(
        "inputs driven over the run: a number, { times = […], values = […] }, or "
        "{ file = \"….csv\", column = \"…\" }", {}, shows="table of name = input")
    interface: Literal["co_simulation", "model_exchange"] | None = field(
        "the FMU's interface the points run through (default: co-simulation where the FMU "
        "has it)", None)
    integrator: Literal["dop853", "radau5"] | None = field(
        "what integrates a Model Exchange FMU (default: dop853)", None)

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        start, stop, step = parts.get("start"), parts.get("stop"), parts.get("step")
        if start is not None and stop is not None and stop <= start:
            yield SpecError(at(where + ("stop",)), f"must be > scenario.start ({start:g}), "
                                                   f"got {stop:g}")
        elif start is not None and stop is not None and step is not None:
            steps = (stop - start) / step
            if abs(steps - round(steps)) > STEP_SLACK:
                yield SpecError(at(where + ("step",)), f"stop − start = {stop - start:g} is not "
                                                       f"a whole number of steps of {step:g}")
