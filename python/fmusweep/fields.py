"""Checks of a specification's fields, shared by the sweep's and the fit's: each raises a
SpecError that names the field (``where``) and the rule."""

from __future__ import annotations

import contextlib
import contextvars
import math
from collections.abc import Iterator
from typing import Any

from .errors import SpecError, did_you_mean

__all__ = ["only", "table", "number", "finite", "whole", "low_high", "setting", "typed_by",
           "VariableTypes"]

# The FMU's variables' types and Enumeration items by name, while a spec is read against
# it: a setting may then be an item's name or true/false, checked against the variable.
VariableTypes = dict[str, tuple[str, dict[str, int]]]
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
    if isinstance(value, bool):
        if known is not None and known[0] != "boolean":
            raise SpecError(where, f"{name} is of type {known[0]}: true and false set a Boolean")
        return float(value)
    if isinstance(value, str):
        if known is None or not known[1]:
            kind = "an Enumeration of the FMU" if known is None else f"of type {known[0]}"
            raise SpecError(where, f"{value!r} names an item, and {name} is not {kind} with "
                                   "items: give a number")
        items = known[1]
        if value not in items:
            raise SpecError(where, f"{name} has no item {value!r} (its items: "
                                   f"{', '.join(items)}){did_you_mean(value, items)}")
        return float(items[value])
    return finite(value, where)


def only(table_: dict[str, Any], where: str, allowed: set[str]) -> None:
    """No field but the allowed ones (``where`` "spec": the top level)."""
    unknown = sorted(set(table_) - allowed)
    if unknown:
        raise SpecError(f"{where}.{unknown[0]}" if where != "spec" else unknown[0],
                        f"unknown field; expected one of {', '.join(sorted(allowed))}")


def table(parent: dict[str, Any], key: str, where: str, required: bool = False) -> dict[str, Any]:
    value = parent.get(key)
    name = key if where == "spec" else f"{where}.{key}"
    if value is None:
        if required:
            raise SpecError(name, "is missing")
        return {}
    if not isinstance(value, dict):
        raise SpecError(name, f"must be a table, got {type(value).__name__}")
    return value


def number(value: object, where: str) -> float:
    """A finite number, which must be there."""
    if value is None:
        raise SpecError(where, "is missing")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecError(where, f"must be a number, got {value!r}")
    converted = float(value)
    if not math.isfinite(converted):
        raise SpecError(where, f"must be finite, got {converted}")
    return converted


def finite(value: object, where: str) -> float:
    """A finite number, in a list of values or a range."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SpecError(where, f"must be a finite number, got {value!r}")
    return float(value)


def whole(value: object, where: str, low: int, high: int | None = None) -> int:
    if (not isinstance(value, int) or isinstance(value, bool) or value < low
            or (high is not None and value > high)):
        bound = f"in [{low}, {high}]" if high is not None else f"≥ {low}"
        raise SpecError(where, f"must be a whole number {bound}, got {value!r}")
    return value


def low_high(r: object, where: str) -> tuple[float, float]:
    """A range = [low, high] with low < high."""
    if not (isinstance(r, list) and len(r) == 2):
        raise SpecError(where, f"must be [low, high], got {r!r}")
    low, high = finite(r[0], where), finite(r[1], where)
    if not low < high:
        raise SpecError(where, f"needs low < high, got [{low}, {high}]")
    return low, high
