"""The checks of a specification that need the FMU: every name is a variable of the right
kind, and every value the design and the scenario set is one the FMU accepts. The FMU is
asked itself (its values are set in initialisation mode, nothing runs), so its own rules
(J > 0, k ≥ 0, …) apply, whatever FMU it is; refusals become SpecErrors naming the field.
A sweep and a fit share these checks; each names its own fields.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import Collector, SpecError, did_you_mean
from .records import Plan, Rows

if TYPE_CHECKING:
    from .designs import Design
    from .native import NativeRunner
    from .spec import Scenario, Spec

__all__ = ["check_against_fmu", "Variables", "names_missing"]

SETTABLE = ("parameter", "input")
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

    def check_scenario(self, scenario: Scenario, errors: Collector) -> None:
        errors.run(lambda: self.check_interface(scenario))
        for name in scenario.parameters:
            errors.run(lambda: self.get(name, f"scenario.parameters.{name}", SETTABLE, VALUE_TYPES))
        for name in scenario.inputs:
            errors.run(lambda: self.driven(name, f"scenario.inputs.{name}"))

    def check_interface(self, scenario: Scenario) -> None:
        """The interface asked for is the FMU's; an integrator is asked for only where the
        runner integrates (Model Exchange)."""
        co_simulation = bool(self.description.get("model_identifier"))
        exchange = bool(self.description.get("exchange_identifier"))
        for name, has in (("co_simulation", co_simulation), ("model_exchange", exchange)):
            if scenario.interface == name and not has:
                raise SpecError("scenario.interface", f"the FMU has no {name} interface")
        runs_exchange = scenario.interface == "model_exchange" or (
            scenario.interface is None and not co_simulation)
        if scenario.integrator is not None and not runs_exchange:
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


def check_against_fmu(spec: Spec, design: Design, description: dict[str, Any],
                      runner: NativeRunner) -> None:
    """Every name against the FMU, every mistake reported at once; then the values."""
    variables = Variables(description)
    errors = Collector()
    variables.check_scenario(spec.scenario, errors)
    for m in spec.metrics:
        errors.run(lambda: variables.get(m.variable, f"outputs.metrics.{m.name}.variable", None,
                                         VALUE_TYPES))
    if spec.cycle is not None:
        spec.cycle.check(description, errors)
    for name in spec.series_variables if spec.cycle is None else []:
        errors.run(lambda: variables.get(name, "outputs.series.variables", None, VALUE_TYPES))
    refused_by_runner(runner, spec.plan(description), errors)
    columns = [design.column_values(j) for j in range(len(design.names))]
    errors.run(lambda: variables.check_columns(design.names, columns, "design.parameters"))
    first = design.rows_at(np.zeros(1, dtype=np.int64))
    plan, good = values_to_ask(spec.plan(description), design.names, "design.parameters", errors)
    if plan is not None:
        errors.run(lambda: ask_the_fmu(plan, [design.names[j] for j in good], first[:, good],
                                       [columns[j] for j in good], runner, "design.parameters",
                                       "scenario.parameters"))
    errors.raise_any()


def refused_by_runner(runner: NativeRunner, plan: Plan, errors: Collector) -> None:
    """The runner's own rules of the whole plan (a steady cycle's among them), every
    refusal at once, beside those already found here (a field refused here is not
    refused twice)."""
    found = Collector()
    found.run(lambda: runner.configure(plan))
    refused = {e.field for e in errors.errors}
    errors.errors.extend(e for e in found.errors if e.field not in refused)


def values_to_ask(plan: Plan, names: list[str], field: str,
                  errors: Collector) -> tuple[Plan | None, list[int]]:
    """What the FMU can still be asked after the names' mistakes in `errors`, so that one run
    reports both kinds: the plan without its reads and without the settings whose names
    were refused, and the columns whose names passed. No plan when the interface itself
    was refused."""
    refused = {e.field for e in errors.errors}
    if {"scenario.interface", "scenario.integrator"} & refused:
        return None, []
    fixed = {n: v for n, v in plan["fixed"].items() if f"scenario.parameters.{n}" not in refused}
    inputs = {n: t for n, t in plan["inputs"].items() if f"scenario.inputs.{n}" not in refused}
    asked: Plan = {**plan, "fixed": fixed, "inputs": inputs, "metrics": [], "series": None,
                   "cycle": None}
    if any(f == "cycle" or f.startswith("cycle.") for f in refused):
        # The cycle's interface was refused: the values are asked through the default one.
        asked["interface"] = None
    return asked, [j for j, n in enumerate(names) if f"{field}.{n}" not in refused]


# A column with more distinct values than this is probed at its extremes and this many
# values spread between them; fewer are each probed.
PROBED_VALUES = 256


def ask_the_fmu(plan: Plan, names: list[str], first: Rows, columns: Sequence[Rows],
                runner: NativeRunner, field: str, fixed_field: str,
                column_fields: Sequence[str] | None = None) -> None:
    """Set the fixed values, then the first point, then each column's values from it, and
    report every value the FMU refuses, at once: a fixed value's refusal under
    ``fixed_field.NAME``, a column's under ``column_fields[j].NAME`` where given, else
    ``field.NAME``. Single-variable rules are caught here; a combination that cannot run (a
    geometry that does not assemble) is a result of the sweep, not a mistake in it."""
    errors = Collector()
    plan = _without_refused_fixed(plan, runner, fixed_field, errors)
    where = [(column_fields[j] if column_fields is not None else field) for j in range(len(names))]
    answer = runner.check(names, first)[0]
    if answer["status"] == "ok":
        base = first[0]
    else:
        # The first point is refused: each column is probed from the FMU's own values, so
        # that a refusal names its column; a refusal that no column makes alone is the
        # combination's.
        base = None
    found = len(errors.errors)
    for j, (name, column) in enumerate(zip(names, columns)):
        errors.run(lambda: _probe_column(runner, names, base, j, column, f"{where[j]}.{name}"))
    if base is None and len(errors.errors) == found:
        point = ", ".join(f"{n} = {v:g}" for n, v in zip(names, first[0]))
        errors.run(lambda: _refuse_combination(field, point, answer["message"]))
    errors.raise_any()


def _without_refused_fixed(plan: Plan, runner: NativeRunner, fixed_field: str,
                           errors: Collector) -> Plan:
    """The plan configured in the runner; where the FMU refuses its fixed values, each
    refused one is reported by name and left out, so that the design is still checked."""
    runner.configure(plan)
    if runner.check([], [[]])[0]["status"] == "ok":
        return plan
    fixed = plan["fixed"]
    bare: Plan = {**plan, "fixed": {}}
    runner.configure(bare)
    kept = {}
    for name, value in fixed.items():
        answer = runner.check([name], [[value]])[0]
        if answer["status"] == "ok":
            kept[name] = value
        else:
            errors.run(lambda: _refuse_value(f"{fixed_field}.{name}", name, [value],
                                             answer["message"]))
    if len(kept) == len(fixed):
        # Each alone passes: the fixed values are refused together.
        errors.run(lambda: _refuse_combination(fixed_field, ", ".join(
            f"{n} = {v:g}" for n, v in fixed.items()), runner_message(runner, plan)))
    kept_plan: Plan = {**plan, "fixed": kept}
    runner.configure(kept_plan)
    return kept_plan


def runner_message(runner: NativeRunner, plan: Plan) -> str:
    runner.configure(plan)
    return runner.check([], [[]])[0]["message"]


def _probed(column: Rows) -> Rows:
    values = np.unique(column)
    if len(values) <= PROBED_VALUES:
        return values
    picks = np.linspace(0, len(values) - 1, PROBED_VALUES).round().astype(np.int64)
    return values[np.unique(picks)]


def _probe_column(runner: NativeRunner, names: list[str], base: Rows | None, j: int,
                  column: Rows, where: str) -> None:
    """Each probed value of column j set with the other columns at the base point (or
    alone, at the FMU's own values, without one); every refused value in one error."""
    values = _probed(column)
    if base is None:
        answers = runner.check([names[j]], values.reshape(-1, 1))
    else:
        probes = np.tile(base, (len(values), 1))
        probes[:, j] = values
        answers = runner.check(names, probes)
    refused = [(float(v), a["message"]) for v, a in zip(values, answers) if a["status"] != "ok"]
    if refused:
        _refuse_value(where, names[j], [v for v, _ in refused], refused[0][1])


def _refuse_value(where: str, name: str, values: list[float], message: str) -> None:
    shown = ", ".join(f"{v:g}" for v in values[:8]) + (", …" if len(values) > 8 else "")
    said = f"{name} = {shown}" if len(values) == 1 else f"{name} = {shown} ({len(values)} values)"
    raise SpecError(where, f"the FMU refuses {said}: {_reason(message)}")


def _refuse_combination(where: str, point: str, message: str) -> None:
    raise SpecError(where, f"the FMU refuses {point} together (each value alone passes): "
                           f"{_reason(message)}")


def _reason(message: str) -> str:
    """The FMU's own words, without the runner's wrapping of them."""
    for lead in ("setting the point's values returned Error: error: ",
                 "setting the point's values returned Error: "):
        if message.startswith(lead):
            return message[len(lead):]
    return message


def names_missing(raw: dict[str, Any], description: dict[str, Any]) -> list[SpecError]:
    """The names a spec's tables use that the FMU lacks (or cannot set or read as they are
    used), read from the tables as written: for a spec whose own fields have mistakes, so
    that one run reports both kinds."""
    variables = Variables(description)
    errors = Collector()

    for table, causalities, types in (("parameters", SETTABLE, VALUE_TYPES),
                                      ("inputs", ("input",), ("real",))):
        for name in _table(raw, "scenario", table):
            errors.run(lambda: variables.get(name, f"scenario.{table}.{name}", causalities, types))
    for where, names in (("design.parameters", _table(raw, "design", "parameters")),
                         ("fit.parameters", _table(raw, "fit", "parameters"))):
        for name in names:
            errors.run(lambda: variables.get(name, f"{where}.{name}", SETTABLE, VALUE_TYPES))
    for metric, entry in _table(raw, "outputs", "metrics").items():
        variable = entry.get("variable") if isinstance(entry, dict) else None
        if isinstance(variable, str):
            errors.run(lambda: variables.get(variable, f"outputs.metrics.{metric}.variable", None,
                                             VALUE_TYPES))
    listed = _table(raw, "outputs", "series").get("variables")
    for name in listed if isinstance(listed, list) else []:
        if isinstance(name, str):
            errors.run(lambda: variables.get(name, "outputs.series.variables", None, VALUE_TYPES))
    return errors.errors


def values_out_of_range(raw: dict[str, Any], description: dict[str, Any]) -> list[SpecError]:
    """The numbers a spec's tables set that lie outside the FMU's declared min and max,
    read from the tables as written: for a spec whose own fields have mistakes, so that one
    run reports these too (the FMU itself is asked about every value once the spec's own
    fields are right)."""
    bounds = {v["name"]: (_bound(v.get("min"), -np.inf), _bound(v.get("max"), np.inf))
              for v in description.get("variables", []) if v.get("type") in ("real", "integer")}
    errors: list[SpecError] = []

    def check(field: str, name: str, values: object) -> None:
        numbers = [v for v in (values if isinstance(values, list) else [values])
                   if isinstance(v, (int, float)) and not isinstance(v, bool)]
        low, high = bounds.get(name, (-np.inf, np.inf))
        outside = [v for v in numbers if not low <= v <= high]
        if outside:
            shown = ", ".join(f"{v:g}" for v in outside)
            errors.append(SpecError(field, f"{name} = {shown}: outside the FMU's range "
                                           f"[{low:g}, {high:g}]"))

    for name, value in _table(raw, "scenario", "parameters").items():
        check(f"scenario.parameters.{name}", name, value)
    for name, entry in _table(raw, "fit", "parameters").items():
        for key in ("start", "range"):
            if isinstance(entry, dict) and key in entry:
                check(f"fit.parameters.{name}.{key}", name, entry[key])
    for name, entry in _table(raw, "design", "parameters").items():
        if isinstance(entry, dict):
            values = entry.get("values", entry.get("range"))
            linspace = entry.get("linspace")
            if isinstance(linspace, list):
                values = linspace[:2]
            check(f"design.parameters.{name}", name, values)
    return errors


def _table(raw: dict[str, Any], *path: str) -> dict[str, Any]:
    """The table at `path` in a spec as written; empty where there is none."""
    found: object = raw
    for key in path:
        found = found.get(key) if isinstance(found, dict) else None
    return found if isinstance(found, dict) else {}


def _bound(text: object, default: float) -> float:
    try:
        return float(text) if isinstance(text, str) else default
    except ValueError:
        return default

