"""How a specification's tables are declared and read.

A table is a pydantic model (``Table``): its fields, their types, units, defaults and
ranges, and the rules between its fields (``rules``). ``read`` walks a spec as written
against its declaration and returns what it could read and every mistake, each a SpecError
naming the field by its path and the rule: pydantic checks each value against its field's
type and range, and the walk goes on past a wrong value, so that one pass finds every
mistake of every table and still hands the checks that come after (against the FMU, between
tables) whatever was read. The docs' field tables are drawn from the same declarations
(``fmusweep.schema.docs``).
"""

from __future__ import annotations

import math
import types
import typing
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, ClassVar, Union, get_args, get_origin

import annotated_types
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError
from pydantic.fields import FieldInfo

from ..errors import SpecError, did_you_mean

__all__ = ["Table", "field", "read", "Reading", "Loc", "at", "shown", "bounds_of", "Parts",
           "LEAF_CONFIG", "absent", "checked", "walk", "Unit", "unit_of"]

# A path to a field: table names and keys, list positions as ints.
Loc = tuple[str | int, ...]

# Every value is checked strictly: a string is not a number, 0 is not false, and no number
# is infinite or NaN.
LEAF_CONFIG = ConfigDict(strict=True, allow_inf_nan=False)


def at(loc: Loc) -> str:
    """A path as the messages name it: ``design.parameters.k34.range``, ``system.connections[0]``."""
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else part)
    return text or "spec"


def field(meaning: str, default: Any = ..., *, unit: str | None = None, alias: str | None = None,
          ge: float | None = None, gt: float | None = None, le: float | None = None,
          lt: float | None = None, shows: str | None = None) -> Any:
    """A table's field: what it means (the docs' line and the "is missing" message), its
    unit, its default (none: required) and its range. `shows` is how the docs write its
    type where the annotation would say it poorly."""
    extra: dict[str, Any] = {}
    if unit is not None:
        extra["unit"] = unit
    if shows is not None:
        extra["shows"] = shows
    return Field(default, description=meaning, alias=alias, ge=ge, gt=gt, le=le, lt=lt,
                 json_schema_extra=extra or None)


class Table(BaseModel):
    """A table of a spec. Its fields are declared with ``field``; ``rules`` checks what
    involves several of them, over whatever of them was read."""
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False,
                              populate_by_name=True, arbitrary_types_allowed=True)

    # What the docs say of the table as a whole.
    about: ClassVar[str] = ""
    # What to say of a field this table does not take where another table does (``log``
    # in a Sobol' design's range), instead of the list of its own fields.
    hints: ClassVar[dict[str, str]] = {}

    @classmethod
    def variant(cls, raw: object) -> Any:
        """The declaration that reads `raw` when this one stands for several (a design's
        kinds, an input's forms); raise SpecError for a value that fits none."""
        return cls

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        """The mistakes between this table's fields, over those read (``parts``)."""
        return iter(())

    def get(self, name: str, default: Any = None) -> Any:
        return getattr(self, name, default)


class Parts:
    """What was read of a table with mistakes: its fields that passed (``get`` gives None for
    the others), as a table without mistakes gives all of its own."""

    def __init__(self, table: type[Table], values: dict[str, Any]):
        self.table = table
        self.values = values

    def get(self, name: str, default: Any = None) -> Any:
        return self.values.get(name, default)

    def has(self, *names: str) -> bool:
        return all(self.values.get(n) is not None for n in names)


def absent(parts: Parts, name: str) -> bool:
    """Whether an optional field was left out (not given wrong)."""
    return name in parts.values and parts.values[name] is None


@dataclass
class Reading:
    """What ``read`` made of a value: the value (a Table, a Parts where the table has
    mistakes, None where nothing could be read) and every mistake found in it."""
    value: Any
    errors: list[SpecError]

    @property
    def complete(self) -> Any:
        """The value where it has no mistake, else None."""
        return None if self.errors else self.value


def read(declared: Any, raw: object, loc: Loc = (), context: dict[str, Any] | None = None
         ) -> Reading:
    """`raw` read against `declared` (a Table, a dict or list of them, or a leaf type)."""
    return _Reader(context or {}).read(declared, raw, loc)


class _Reader:
    def __init__(self, context: dict[str, Any]):
        self.context = context

    def read(self, declared: Any, raw: object, loc: Loc) -> Reading:
        origin, args = get_origin(declared), get_args(declared)
        if origin is typing.Annotated and _is_table(args[0]):
            return self.read(args[0], raw, loc)
        if _is_table(declared):
            return self.table(declared, raw, loc)
        if origin is dict and _holds_tables(args[1]):
            return self.mapping(args[1], raw, loc)
        if origin is list and _holds_tables(args[0]):
            return self.sequence(args[0], raw, loc)
        if _optional_table(declared) is not None:
            return Reading(None, []) if raw is None else self.read(_optional_table(declared),
                                                                    raw, loc)
        return self.leaf(declared, raw, loc)

    def table(self, declared: type[Table], raw: object, loc: Loc) -> Reading:
        try:
            chosen = declared.variant(raw)
        except SpecError as e:
            return Reading(None, [SpecError(_join(at(loc), e.field), e.rule)])
        if not _is_table(chosen):
            return self.read(chosen, raw, loc)
        if not isinstance(raw, dict):
            return Reading(None, [SpecError(at(loc), f"must be a table ({_fields_of(chosen)}), "
                                                     f"got {shown(raw)}")])
        errors: list[SpecError] = []
        known = {_key(name, info): name for name, info in chosen.model_fields.items()}
        for key in raw:
            if key in chosen.hints:
                errors.append(SpecError(at(loc + (key,)), chosen.hints[key]))
            elif key not in known:
                errors.append(SpecError(at(loc + (key,)), f"unknown field; expected one of "
                                        f"{', '.join(sorted(known))}{did_you_mean(key, known)}"))
        values: dict[str, Any] = {}
        for key, name in known.items():
            info = chosen.model_fields[name]
            if key not in raw or raw[key] is None:
                if info.is_required():
                    errors.append(SpecError(at(loc + (key,)), _missing(info)))
                else:
                    values[name] = info.get_default(call_default_factory=True)
                continue
            found = self.read(_declared(info), raw[key], loc + (key,))
            errors += found.errors
            if found.value is not None and not found.errors:
                values[name] = found.value
            elif isinstance(found.value, (Parts, dict, list)):
                values[name] = found.value  # partly read: the rules and checks take what is
        parts = Parts(chosen, values)
        errors += chosen.rules(parts, loc)
        if errors:
            return Reading(parts, errors)
        return Reading(chosen.model_construct(**values), [])

    def mapping(self, declared: Any, raw: object, loc: Loc) -> Reading:
        if not isinstance(raw, dict):
            return Reading(None, [SpecError(at(loc), f"must be a table of name = value, got "
                                                     f"{shown(raw)}")])
        errors: list[SpecError] = []
        values = {}
        for key, entry in raw.items():
            found = self.read(declared, entry, loc + (key,))
            errors += found.errors
            if found.value is not None:
                values[key] = found.value
        return Reading(values, errors)

    def sequence(self, declared: Any, raw: object, loc: Loc) -> Reading:
        if not isinstance(raw, list):
            return Reading(None, [SpecError(at(loc), f"must be a list, got {shown(raw)}")])
        errors: list[SpecError] = []
        values = []
        for k, entry in enumerate(raw):
            found = self.read(declared, entry, loc + (k,))
            errors += found.errors
            values.append(found.value)
        return Reading(values, errors)

    def leaf(self, declared: Any, raw: object, loc: Loc) -> Reading:
        try:
            return Reading(_adapter(declared).validate_python(raw, context=self.context), [])
        except ValidationError as refused:
            return Reading(None, _phrased(refused, declared, raw, loc))


def _declared(info: FieldInfo) -> Any:
    """A field's type with its range and unit, as one annotation (an optional field's value
    type: a field left out, or null, takes its default before any type is checked)."""
    annotation = info.annotation
    if get_origin(annotation) in (Union, types.UnionType):
        given = [a for a in get_args(annotation) if a is not type(None)]
        if len(given) == 1:
            annotation = given[0]
    unit = unit_of(info)
    metadata = [*info.metadata, *([Unit(unit)] if unit else [])]
    return typing.Annotated[(annotation, *metadata)] if metadata else annotation


_ADAPTERS: dict[Any, TypeAdapter[Any]] = {}


def _adapter(declared: Any) -> TypeAdapter[Any]:
    key = repr(declared)
    if key not in _ADAPTERS:
        _ADAPTERS[key] = TypeAdapter(declared, config=LEAF_CONFIG)
    return _ADAPTERS[key]


def _is_table(declared: Any) -> bool:
    return isinstance(declared, type) and issubclass(declared, Table)


def _holds_tables(declared: Any) -> bool:
    if get_origin(declared) is typing.Annotated:
        declared = get_args(declared)[0]
    return _is_table(declared)


def _optional_table(declared: Any) -> Any:
    if get_origin(declared) in (Union, types.UnionType):
        tables = [a for a in get_args(declared) if a is not type(None)]
        if len(tables) == 1 and _holds_tables(tables[0]):
            return tables[0]
    return None


def _key(name: str, info: FieldInfo) -> str:
    return info.alias or name


def _join(where: str, field_name: str) -> str:
    return where if not field_name else (field_name if where == "spec" else f"{where}.{field_name}")


def _fields_of(table: type[Table]) -> str:
    keys = [_key(n, i) for n, i in table.model_fields.items()]
    return ", ".join(keys[:6]) + (", …" if len(keys) > 6 else "")


def _missing(info: FieldInfo) -> str:
    unit = unit_of(info)
    return f"is missing: give {info.description}" + (f" ({unit})" if unit else "")


def unit_of(info: FieldInfo) -> str | None:
    extra = info.json_schema_extra
    unit = extra.get("unit") if isinstance(extra, dict) else None
    return unit if isinstance(unit, str) else None


def bounds_of(metadata: list[Any]) -> tuple[str, str] | None:
    """A field's range as the messages write it: "[1e-13, 0.1]", "> 0", …"""
    low = high = None
    for m in metadata:
        if isinstance(m, annotated_types.Ge):
            low = f"[{m.ge:g}"
        elif isinstance(m, annotated_types.Gt):
            low = f"({m.gt:g}"
        elif isinstance(m, annotated_types.Le):
            high = f"{m.le:g}]"
        elif isinstance(m, annotated_types.Lt):
            high = f"{m.lt:g})"
    if low and high:
        return "must lie in", f"{low}, {high}"
    if low:
        return "must be", ("≥ " if low[0] == "[" else "> ") + low[1:]
    if high:
        return "must be", ("≤ " if high[-1] == "]" else "< ") + high[:-1]
    return None


def shown(value: object) -> str:
    """A value as a message shows it, with what it is: "the string '0.5 N.m.s/rad'"."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, (int, float)):
        return f"{value!r}" if not isinstance(value, float) or math.isfinite(value) else str(value)
    if isinstance(value, list):
        return f"the list {value!r}"
    if isinstance(value, dict):
        return f"the table {value!r}"
    return repr(value)


# What each of pydantic's error types means, as a rule.
_EXPECTED = {
    "float_type": "a number", "int_type": "a whole number", "bool_type": "true or false",
    "string_type": "a name (a string)", "list_type": "a list", "dict_type": "a table",
    "tuple_type": "a list", "literal_error": None, "finite_number": "a finite number",
}


def _phrased(refused: ValidationError, declared: Any, raw: object, loc: Loc) -> list[SpecError]:
    """pydantic's errors of one value, each as a rule of the field it names."""
    said: dict[str, str] = {}
    for error in refused.errors():
        inner = tuple(p for p in error["loc"] if not _is_variant_tag(p))
        where = at(loc + inner)
        rule = _rule(error, declared)
        said.setdefault(where, rule)
    return [SpecError(where, rule) for where, rule in said.items()]


def _is_variant_tag(part: object) -> bool:
    """pydantic's names of a union's members in a path (``float``, ``function-after[…]``)."""
    return isinstance(part, str) and (part in {"float", "int", "str", "bool", "list", "dict"}
                                      or "[" in part or part.startswith("function-"))


def _rule(error: Any, declared: Any) -> str:
    kind, value, ctx = error["type"], error.get("input"), error.get("ctx") or {}
    if kind == "value_error":
        return str(ctx.get("error", error["msg"]))
    if kind == "literal_error":
        allowed = ctx.get("expected", "")
        close = did_you_mean(value, [a.strip("'") for a in str(allowed).replace(" or ", ", ")
                                     .split(", ")]) if isinstance(value, str) else ""
        return f"must be one of {allowed}, got {shown(value)}{close}"
    if kind in ("greater_than_equal", "greater_than", "less_than_equal", "less_than"):
        range_ = bounds_of(_metadata_of(declared))
        unit = _unit_of_declared(declared)
        if range_ is not None:
            return f"{range_[0]} {range_[1]}{' ' + unit if unit else ''}, got {value!r}"
        sign = {"greater_than_equal": "≥", "greater_than": ">", "less_than_equal": "≤",
                "less_than": "<"}[kind]
        bound = next(iter(ctx.values()), "its bound")
        bound = f"{bound:g}" if isinstance(bound, (int, float)) else bound
        return f"must be {sign} {bound}{' ' + unit if unit else ''}, got {value!r}"
    if kind == "bool_type" and isinstance(value, str) and value.lower() in ("true", "false"):
        return f"write {value.lower()} without quotes: a Boolean, not the string {value!r}"
    if kind in ("too_short", "too_long"):
        return f"{error['msg'].lower()}, got {shown(value)}"
    if kind in ("missing",):
        return "is missing"
    expected = _EXPECTED.get(kind)
    if expected is not None:
        unit = _unit_of_declared(declared)
        return f"expected {expected}{f' ({unit})' if unit else ''}, got {shown(value)}"
    return f"{error['msg']}, got {shown(value)}"


def _metadata_of(declared: Any) -> list[Any]:
    if get_origin(declared) is typing.Annotated:
        return list(get_args(declared)[1:])
    return []


def _unit_of_declared(declared: Any) -> str | None:
    for m in _metadata_of(declared):
        if isinstance(m, Unit):
            return str(m.unit)
    return None


@dataclass(frozen=True)
class Unit:
    """A leaf type's unit, as Annotated metadata (``Annotated[float, Unit("s")]``)."""
    unit: str


def walk(table: type[Table]) -> Iterator[tuple[str, FieldInfo]]:
    """A table's fields as written in a spec, in their order."""
    for name, info in table.model_fields.items():
        yield _key(name, info), info


def checked(check: Callable[[Any], Any]) -> Any:
    """An AfterValidator from a function that returns the value or raises ValueError with
    the rule (pydantic then names the field)."""
    from pydantic import AfterValidator
    return AfterValidator(check)
