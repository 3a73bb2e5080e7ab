"""Checks of a specification's fields, shared by the sweep's and the fit's: each raises a
SpecError that names the field (``where``) and the rule."""

from __future__ import annotations

import math
from typing import Any

from .errors import SpecError

__all__ = ["only", "table", "number", "finite", "whole", "low_high"]


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
