"""The kinds of value a spec's fields take, each checked where it is read: a setting of a
variable, a range, a list of names, a pair of connected ends."""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import PlainValidator

from .core import shown

__all__ = ["Setting", "Range", "Names", "Name", "Path", "Spacing", "is_number"]


def is_number(value: object) -> bool:
    """A finite int or float (not a Boolean)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _setting(value: object) -> float | bool | str:
    """A value a variable is set to: a number, true or false (a Boolean), or the name of
    one of an Enumeration's items; which of them the variable takes is the FMU's to say."""
    if isinstance(value, (bool, str)) or is_number(value):
        return value  # type: ignore[return-value]
    raise ValueError(f"expected a number, true or false, or an item's name, got {shown(value)}")


# Kept as written: the FMU's type of the variable decides what it means.
Setting = Annotated[Any, PlainValidator(_setting)]


def _range(value: object) -> tuple[float, float]:
    if not (isinstance(value, list) and len(value) == 2 and all(is_number(v) for v in value)):
        raise ValueError(f"must be [low, high], two finite numbers, got {shown(value)}")
    low, high = float(value[0]), float(value[1])
    if not low < high:
        raise ValueError(f"needs low < high, got [{low:g}, {high:g}]")
    return low, high


Range = Annotated[Any, PlainValidator(_range)]


def _names(value: object) -> list[str]:
    if not (isinstance(value, list) and value and all(isinstance(v, str) and v for v in value)):
        raise ValueError(f"must be a non-empty list of variables' names, got {shown(value)}")
    return list(value)


Names = Annotated[Any, PlainValidator(_names)]


def _name(value: object) -> str:
    if not (isinstance(value, str) and value):
        raise ValueError(f"must be a variable's name, got {shown(value)}")
    return value


Name = Annotated[Any, PlainValidator(_name)]


def _path(value: object) -> str:
    if not (isinstance(value, str) and value):
        raise ValueError(f"must be a path (a string), got {shown(value)}")
    return value


Path = Annotated[Any, PlainValidator(_path)]


def _spacing(value: object) -> tuple[float, float, int]:
    """[start, stop, count] of a linspace or a logspace."""
    if not (isinstance(value, list) and len(value) == 3):
        raise ValueError(f"must be [start, stop, count], got {shown(value)}")
    start, stop, count = value
    if not (is_number(start) and is_number(stop)):
        raise ValueError(f"start and stop must be finite numbers, got {shown(value)}")
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"count must be a whole number ≥ 1, got {shown(count)}")
    return float(start), float(stop), count


Spacing = Annotated[Any, PlainValidator(_spacing)]
