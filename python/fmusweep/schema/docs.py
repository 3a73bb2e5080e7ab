"""The docs' field tables, drawn from the declarations: every field of every table of a
sweep's and a fit's spec with its type, default, range and meaning, and the ``[cycle]``
table's from the runner's own declaration (its rules are the runner's).

``python -m fmusweep.schema.docs`` rewrites the tables in docs/sweeps.md, docs/fitting.md
and docs/cycle.md between their ``<!-- fields: NAME -->`` and ``<!-- /fields -->`` lines;
``--check`` says which are stale instead (a test runs it).
"""

from __future__ import annotations

import json
import pathlib
import re
import subprocess
import sys
import types
import typing
from collections.abc import Iterator
from typing import Any, Literal, Union, get_args, get_origin

from pydantic.fields import FieldInfo

from ..designs import KINDS
from ..designs.base import LinspaceEntry, LogRangeEntry, LogspaceEntry, RangeEntry, ValuesEntry
from .core import Table, bounds_of, unit_of, walk
from .fit import DataTable, ExperimentTable, FitParameterEntry, FitTable, FitTables
from .scenario import InputFile, InputPoints, ScenarioTable
from .sweep import MetricEntry, OutputsTable, SeriesTable, SweepTables, SystemTable

__all__ = ["SECTIONS", "section", "table_rows", "main"]

# Each generated block of the docs: its name and the tables it shows, with the heading each
# is shown under.
SECTIONS: dict[str, list[tuple[str, type[Table]]]] = {
    "sweep": [("the spec's top level", SweepTables),
              ("[scenario]", ScenarioTable),
              ("an input's table: { times, values }", InputPoints),
              ("an input from a file: { file, column }", InputFile),
              *[(f"[design], kind = \"{name}\"", kind.table) for name, kind in KINDS.items()],
              ("a grid's or list's column: { values }", ValuesEntry),
              ("a grid's column: { linspace }", LinspaceEntry),
              ("a grid's column: { logspace }", LogspaceEntry),
              ("a sobol or morris column: { range }", RangeEntry),
              ("an lhs column: { range, log }", LogRangeEntry),
              ("[outputs]", OutputsTable),
              ("[outputs.metrics.NAME]", MetricEntry),
              ("[outputs.series]", SeriesTable),
              ("[system]", SystemTable)],
    "fit": [("the spec's top level", FitTables),
            ("[data]", DataTable),
            ("[[experiment]]", ExperimentTable),
            ("[fit]", FitTable),
            ("[fit.parameters.NAME]", FitParameterEntry)],
}
DOCS = {"sweep": "docs/sweeps.md", "fit": "docs/fitting.md", "cycle": "docs/cycle.md"}


def type_name(info: FieldInfo) -> str:
    extra = info.json_schema_extra
    if isinstance(extra, dict) and isinstance(extra.get("shows"), str):
        return str(extra["shows"])
    return _type_name(info.annotation)


def _type_name(annotation: Any) -> str:
    origin, args = get_origin(annotation), get_args(annotation)
    if origin in (Union, types.UnionType):
        given = [a for a in args if a is not type(None)]
        return " | ".join(_type_name(a) for a in given)
    if origin is typing.Annotated:
        return _type_name(args[0])
    if origin is Literal:
        return " | ".join(str(a) for a in args)
    if origin is list:
        return f"list of {_type_name(args[0])}s"
    if origin is dict:
        return f"table of name = {_type_name(args[1])}"
    return {float: "number", int: "whole number", bool: "true/false", str: "text"}.get(
        annotation, "table" if isinstance(annotation, type) and issubclass(annotation, Table)
        else "value")


def _default(info: FieldInfo) -> str:
    if info.is_required():
        return "required"
    value = info.get_default(call_default_factory=True)
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if value in ({}, []):
        return "none"
    return f"{value!r}"


def _rule(info: FieldInfo) -> str:
    found = bounds_of(list(info.metadata))
    unit = unit_of(info)
    said = f"{found[1]}" if found is not None else ""
    if unit:
        said = f"{said} {unit}".strip() if said else f"in {unit}"
    return said


def table_rows(table: type[Table]) -> Iterator[tuple[str, str, str, str, str]]:
    """Each field's row: name, type, default, range or unit, meaning."""
    for key, info in walk(table):
        if not info.description:
            raise ValueError(f"{table.__name__}.{key} has no meaning: give field(meaning, …)")
        yield key, type_name(info), _default(info), _rule(info), info.description


def section(name: str) -> str:
    """The markdown of one generated block."""
    if name == "cycle":
        return _runner_section()
    out = []
    for heading, table in SECTIONS[name]:
        out.append(f"**{heading}**" + (f": {table.about}" if table.about else ""))
        out.append("")
        out += _markdown(table_rows(table))
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _markdown(rows: Iterator[tuple[str, str, str, str, str]]) -> list[str]:
    lines = ["| field | type | default | range, unit | meaning |", "|---|---|---|---|---|"]
    for row in rows:
        lines.append("| " + " | ".join(_cell(c) for c in row) + " |")
    return lines


def _cell(text: str) -> str:
    return text.replace("|", "\\|") if text else ""


def _runner_section() -> str:
    """The [cycle] table and a cycle's metrics, as the runner declares them."""
    from ..native import runner_path
    declared = json.loads(subprocess.run([str(runner_path()), "fields"], check=True,
                                         capture_output=True, text=True).stdout)
    from ..cycle import CycleStarts
    out = []
    for table in declared:
        out.append(f"**{table['table']}**: {table['about']}")
        out.append("")
        rows = [(f["name"], f["type"], f["default"], f["range"], f["meaning"])
                for f in table["fields"]]
        if table["table"] == "[cycle]":
            rows += list(table_rows(CycleStarts))
        out += _markdown(iter(rows))
        out.append("")
    return "\n".join(out).rstrip() + "\n"


BLOCK = re.compile(r"(<!-- fields: (\w+) -->\n)(.*?)(<!-- /fields -->)", re.S)


def rewritten(text: str) -> str:
    """The page with each generated block drawn again."""
    return BLOCK.sub(lambda m: m.group(1) + "\n" + section(m.group(2)) + "\n" + m.group(4), text)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    root = pathlib.Path(args[args.index("--root") + 1]) if "--root" in args else pathlib.Path(".")
    stale = []
    for name, page in DOCS.items():
        path = root / page
        text = path.read_text()
        if f"<!-- fields: {name} -->" not in text:
            stale.append(f"{page} has no <!-- fields: {name} --> block")
            continue
        new = rewritten(text)
        if new != text:
            if "--check" in args:
                stale.append(f"{page}: its field tables differ from the declarations")
            else:
                path.write_text(new)
    for said in stale:
        print(said, file=sys.stderr)
    if stale:
        print("run `python -m fmusweep.schema.docs` from the repository's root", file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
