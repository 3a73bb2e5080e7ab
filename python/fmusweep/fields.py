"""The settings of a specification read by the FMU's types: a number, true or false for a
Boolean, an item's name for an Enumeration (the schema keeps them as written; what they
mean is the FMU's to say); and the FMU's variables by name, each name a spec uses checked
against them. Each mistake raises a SpecError naming the field."""

from __future__ import annotations

import contextlib
import contextvars
import math
from collections.abc import Collection, Iterator, Sequence
from typing import Any

import numpy as np

from .errors import Collector, SpecError, did_you_mean
from .records import Rows

__all__ = ["finite", "setting", "typed_by", "VariableTypes", "Variables", "SETTABLE", "READABLE",
           "VALUE_TYPES"]

# The FMU's variables' types, Enumeration items and units by name, while a spec is read
# against it: a setting may then be an item's name or true/false, checked against the
# variable.
VariableTypes = dict[str, tuple[str, dict[str, int], str | None]]
_TYPES: contextvars.ContextVar[VariableTypes] = contextvars.ContextVar("types", default={})


@contextlib.contextmanager
def typed_by(types: VariableTypes) -> Iterator[None]:
    """Settings read inside take item names and Booleans by the FMU's variables' types."""
    token = _TYPES.set(types)
    try:
        yield
    finally:
        _TYPES.reset(token)


def setting(value: object, where: str, name: str) -> float:
    """A value that variable `name` takes: a number; true or false for a Boolean (1 or 0, as
    the runner passes Booleans); an item's name for an Enumeration (its value)."""
    known = _TYPES.get().get(name)
    kind, items, unit = known if known is not None else (None, {}, None)
    if isinstance(value, bool):
        if kind is not None and kind != "boolean":
            raise SpecError(where, f"{name} is of type {kind}: true and false set a Boolean")
        return float(value)
    if isinstance(value, str):
        if kind == "boolean" and value.lower() in ("true", "false"):
            raise SpecError(where, f"write {value.lower()} without quotes: {name} is a Boolean, "
                                   f"not the string {value!r}")
        if kind in ("real", "integer"):
            raise SpecError(where, f"expected a number{_unit(unit)}, got the string {value!r}")
        if not items:
            what = "an Enumeration of the FMU" if kind is None else f"of type {kind}"
            raise SpecError(where, f"{value!r} names an item, and {name} is not {what} with "
                                   "items: give a number")
        if value not in items:
            raise SpecError(where, f"{name} has no item {value!r} (its items: "
                                   f"{', '.join(items)}){did_you_mean(value, items)}")
        return float(items[value])
    if kind == "boolean":
        raise SpecError(where, f"{name} is a Boolean: write true or false, got {value!r}")
    return finite(value, where)


def _unit(unit: str | None) -> str:
    """ " (N·m·s/rad)" for the FMU's unit "N.m.s/rad"; "" without one."""
    return f" ({unit.replace('.', '·')})" if unit else ""


def finite(value: object, where: str) -> float:
    """A finite number, in a list of values or a range."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SpecError(where, f"must be a finite number, got {value!r}")
    return float(value)


SETTABLE = ("parameter", "input")
# What a fit may measure.
READABLE = ("output", "local")
VALUE_TYPES = ("real", "integer", "enumeration", "boolean")

# A variable as the runner describes it: name, causality, type, …
Variable = dict[str, Any]


class Variables:
    """The FMU's variables by name, as the runner describes them."""

    def __init__(self, description: dict[str, Any]):
        self.by_name: dict[str, Variable] = {v["name"]: v for v in description["variables"]}
        self.description = description

    def get(self, name: str, where: str, causalities: Sequence[str] | None = None,
            types: Sequence[str] | None = None, what: str = "variable") -> Variable:
        v = self.by_name.get(name)
        if v is None:
            raise SpecError(where, f"the FMU has no {what} {name!r}{did_you_mean(name, self.by_name)}")
        if causalities and v["causality"] not in causalities:
            raise SpecError(where, f"{name} has causality {v['causality']}; "
                                   f"only {' or '.join(causalities)} variables can be {what_for(causalities)}")
        if types and v["type"] not in types:
            raise SpecError(where, f"{name} is of type {v['type']}; expected {' or '.join(types)}")
        return v

    def check_interface(self, asked: tuple[str | None, str | None]) -> None:
        """The interface asked for is the FMU's; an integrator is asked for only where the
        runner integrates (Model Exchange)."""
        interface, integrator = asked
        co_simulation = bool(self.description.get("model_identifier"))
        exchange = bool(self.description.get("exchange_identifier"))
        for name, has in (("co_simulation", co_simulation), ("model_exchange", exchange)):
            if interface == name and not has:
                raise SpecError("scenario.interface", f"the FMU has no {name} interface")
        runs_exchange = interface == "model_exchange" or (
            interface is None and not co_simulation)
        if integrator is not None and not runs_exchange:
            raise SpecError("scenario.integrator", "applies to Model Exchange only: this FMU "
                                                   "runs through its co_simulation interface, "
                                                   "which integrates itself (set interface = "
                                                   "\"model_exchange\")")

    def driven(self, name: str, where: str) -> Variable:
        """A variable a table may drive over the run: a Real input, or a tunable Real
        parameter (which the runner sets in event mode where the FMU has one)."""
        v = self.get(name, where, ("input", "parameter"), ("real",), what="input")
        if v["causality"] == "parameter" and v["variability"] != "tunable":
            raise SpecError(where, f"{name} is a {v['variability']} parameter; only inputs and "
                                   f"tunable parameters can change during a run")
        return v

    def check_columns(self, names: list[str], columns: Sequence[Rows], field: str) -> None:
        """Each column of a design (or a fit's parameters) is a settable variable, and the
        values it takes suit the variable's type; every mistake reported at once."""
        errors = Collector()
        for name, column in zip(names, columns):
            errors.run(lambda: self._check_column(name, column, field))
        errors.raise_any()

    def _check_column(self, name: str, column: Rows, field: str) -> None:
        v = self.get(name, f"{field}.{name}", SETTABLE, VALUE_TYPES)
        if v["type"] in ("integer", "enumeration") and np.any(column != np.round(column)):
            raise SpecError(f"{field}.{name}", f"{name} is an Integer; the design gives "
                                               f"{column[column != np.round(column)][0]}")
        if v["type"] == "boolean" and not np.all((column == 0) | (column == 1)):
            raise SpecError(f"{field}.{name}", f"{name} is a Boolean; the design must give 0 or 1")


def what_for(causalities: Collection[str]) -> str:
    return "set" if set(causalities) <= set(SETTABLE) else "read"
