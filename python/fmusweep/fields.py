"""The settings of a specification read by the FMU's types: a number, true or false for a
Boolean, an item's name for an Enumeration (the schema keeps them as written; what they
mean is the FMU's to say). Each mistake raises a SpecError naming the field."""

from __future__ import annotations

import contextlib
import contextvars
import math
from collections.abc import Iterator

from .errors import SpecError, did_you_mean

__all__ = ["finite", "setting", "typed_by", "VariableTypes"]

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
