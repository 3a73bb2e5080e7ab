"""``list``: each parameter gives ``values``, all of one length; point i takes the i-th."""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from typing import Any, Literal

import numpy as np

from ..errors import SpecError, SpecWarning
from ..schema.core import Loc, Parts, at
from ..schema.core import field as declared
from .base import Design, DesignKind, DesignTable, ValuesEntry, column_values, same_setting


class ListTable(DesignTable):
    about = "Listed points: point i takes each column's i-th value."
    kind: Literal["list"] = declared("the kind of design")
    parameters: dict[str, ValuesEntry] = declared("each column: values = [...], all of one "
                                                  "length", shows="table of name = { values }")

    @classmethod
    def count(cls, parts: Parts) -> int | None:
        lengths = {len(entry.values) for entry in parts.get("parameters").values()}
        return lengths.pop() if len(lengths) == 1 else None

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        yield from super().rules(parts, where)
        lengths = {name: len(entry.values) for name, entry in
                   (parts.get("parameters") or {}).items()}
        if len(set(lengths.values())) > 1:
            shown = ", ".join(f"{name} {n}" for name, n in lengths.items())
            yield SpecError(at(where + ("parameters",)), f"a list design needs values of one "
                                                         f"length, got {shown}")
            return
        # Points listed twice run twice (a repeat may be meant: a flaky unit's, a timing's);
        # said, not refused.
        entries = parts.get("parameters") or {}
        rows = list(zip(*(entry.values for entry in entries.values())))
        first: dict[tuple[tuple[bool, Any], ...], int] = {}
        for i, row in enumerate(rows):
            key = tuple(same_setting(v) for v in row)
            if key in first:
                shown = ", ".join(f"{n} = {v}" for n, v in zip(entries, row))
                warnings.warn(f"{at(where + ('parameters',))}: points {first[key]} and {i} are "
                              f"the same ({shown}): each runs", SpecWarning, stacklevel=2)
            else:
                first[key] = i


def make(table: ListTable, names: list[str]) -> Design:
    columns = [column_values(table.parameters[name], name) for name in names]
    return Design("list", names, stored=np.array(columns, dtype=float).T.copy())


KIND = DesignKind("list", ListTable, make=make)
