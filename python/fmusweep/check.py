"""The checks of a specification that need the FMU, over whatever of the spec was read
(``spec.SweepReading``, ``fitting.spec.FitReading``), in the same pass as the spec's own:
every name is a variable of the right kind, and every value the design and the scenario set
is one the FMU accepts. The FMU is asked itself (its values are set in initialisation mode,
nothing runs), so its own rules (J > 0, k ≥ 0, …) apply, whatever FMU it is; refusals
become SpecErrors naming the field. The runner is asked for its own rules of the plan (a
steady cycle's) the same way.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import Collector, SpecError, did_you_mean
from .fields import READABLE, SETTABLE, VALUE_TYPES, Variable, Variables
from .records import MetricPlan, Plan, Rows, new_plan

if TYPE_CHECKING:
    from .fitting.spec import FitReading
    from .native import NativeRunner
    from .spec import SweepReading

__all__ = ["sweep_against_target", "fit_against_target", "Variables", "out_of_range"]



def sweep_against_target(reading: SweepReading, description: dict[str, Any],
                         runner: NativeRunner) -> list[SpecError]:
    """Every name the sweep's spec uses against the FMU, every value it sets against the
    FMU's declared range and its own rules, and the runner's rules of the plan, over
    whatever of the spec was read: every mistake at once."""
    variables = Variables(description)
    errors = Collector()
    raw = reading.raw
    table = reading.scenario.table
    if reading.system is None:  # a system's interface is the runner's rule
        errors.run(lambda: variables.check_interface(_interface_of(table)))
    for name in _keys(raw, "scenario", "parameters"):
        errors.run(lambda: variables.get(name, f"scenario.parameters.{name}", SETTABLE,
                                         VALUE_TYPES))
    for name in _keys(raw, "scenario", "inputs"):
        errors.run(lambda: variables.driven(name, f"scenario.inputs.{name}"))
    for name in _keys(raw, "design", "parameters"):
        errors.run(lambda: variables.get(name, f"design.parameters.{name}", SETTABLE,
                                         VALUE_TYPES))
    if reading.cycle is None:
        _readable(raw, variables, errors)
    else:
        reading.cycle.check(description, errors)
    named = [n for n in reading.columns if f"design.parameters.{n}" not in _fields(errors)]
    errors.run(lambda: variables.check_columns(named, [reading.columns[n] for n in named],
                                               "design.parameters"))
    refused = _fields(errors) | {e.field for e in reading.errors}
    refused_by_runner(runner, _probe_plan(reading, description, refused), errors)
    plan, good = values_to_ask(_probe_plan(reading, description, set(), reads=False),
                               list(reading.columns), "design.parameters", errors)
    if plan is not None:
        names = [list(reading.columns)[j] for j in good]
        first = np.array([[reading.columns[n][0] for n in names]])
        errors.run(lambda: ask_the_fmu(plan, names, first, [reading.columns[n] for n in names],
                                       runner, "design.parameters", "scenario.parameters"))
    # What the FMU took of its declared range (an FMU need not hold its own min and max).
    errors.errors += out_of_range(description, [(f"scenario.parameters.{n}", n, [v])
                                                for n, v in reading.scenario.fixed.items()]
                                  + [(f"design.parameters.{n}", n, list(values))
                                     for n, values in reading.columns.items()], errors)
    return errors.errors


def _interface_of(table: Any) -> tuple[str | None, str | None]:
    if table is None:
        return None, None
    return table.get("interface"), table.get("integrator")


def _keys(raw: dict[str, Any], *path: str) -> list[str]:
    """The names of the table at `path` of a spec as written."""
    return list(_table(raw, *path))


def _fields(errors: Collector) -> set[str]:
    return {e.field for e in errors.errors}


def _readable(raw: dict[str, Any], variables: Variables, errors: Collector) -> None:
    """The variables a transient's metrics and series read, as written."""
    for metric, entry in _table(raw, "outputs", "metrics").items():
        variable = entry.get("variable") if isinstance(entry, dict) else None
        if isinstance(variable, str):
            errors.run(lambda: variables.get(variable, f"outputs.metrics.{metric}.variable",
                                             None, VALUE_TYPES))
    listed = _table(raw, "outputs", "series").get("variables")
    for name in listed if isinstance(listed, list) else []:
        if isinstance(name, str):
            errors.run(lambda: variables.get(name, "outputs.series.variables", None,
                                             VALUE_TYPES))


def _probe_plan(reading: SweepReading, description: dict[str, Any], refused: set[str],
                reads: bool = True) -> Plan:
    """The plan of what was read, for the runner's rules and the FMU's: the scenario's
    times where they were read (else a short run), and, with `reads`, the metrics (but
    those with a field `refused` already) and the cycle."""
    table = reading.scenario.table
    times = reading.scenario.times()
    start, stop, step = times if times is not None else (0.0, 1.0, 1.0)
    interface, integrator = _interface_of(table)
    plan = new_plan(start, stop, step, tolerance=table.get("tolerance") if table else None,
                    interface=interface)
    plan["fixed"], plan["inputs"] = dict(reading.scenario.fixed), dict(reading.scenario.inputs)
    plan["integrator"] = integrator
    if not reads:
        return plan
    if reading.cycle is not None:
        plan["cycle"] = reading.cycle.plan([{"field": f"outputs.metrics.{m.name}", **m.entry}
                                            for m in reading.metrics], description)
    elif times is not None:
        plan["metrics"] = [MetricPlan({"variable": m.variable, "kind": m.kind, "from": m.start,
                                       "to": m.end, "field": f"outputs.metrics.{m.name}",
                                       "extremes": m.extremes}) for m in reading.metrics
                           if not any(f == f"outputs.metrics.{m.name}"
                                      or f.startswith(f"outputs.metrics.{m.name}.")
                                      for f in refused)]
    return plan


def fit_against_target(reading: FitReading, description: dict[str, Any],
                       runner: NativeRunner) -> list[SpecError]:
    """Every name a fit's spec uses against the FMU, and every value it sets against the
    FMU's declared range and its own rules, over whatever was read: every mistake at once."""
    variables = Variables(description)
    errors = Collector()
    for e in reading.experiments:
        _scenario_names(e.scenario, e.where, variables, errors)
        for name in _measured(reading, e):
            errors.run(lambda: variables.get(name, f"{e.where}data.file", READABLE, VALUE_TYPES,
                                             what="output"))
    for p in reading.fitted:
        column = np.array([p.start, p.low, p.high])
        errors.run(lambda: variables.check_columns([p.variable], [column],
                                                   _parameters_field(p.experiment)))
    for e in reading.experiments:
        errors.run(lambda: _ask_about_experiment(reading, e, runner, errors))
    # What the FMU took of its declared range (an FMU need not hold its own min and max).
    fixed = [(f"{e.where}scenario.parameters.{n}" if e.where else f"scenario.parameters.{n}",
              n, [v]) for e in reading.experiments for n, v in e.scenario.fixed.items()]
    fitted = [(f"{_parameters_field(p.experiment)}.{p.variable}", p.variable,
               [p.start, p.low, p.high]) for p in reading.fitted]
    errors.errors += out_of_range(description, fixed + fitted, errors)
    return errors.errors


def _scenario_names(scenario: Any, where: str, variables: Variables, errors: Collector) -> None:
    table = scenario.table
    if table is None:
        return
    prefix = f"{where}scenario" if where else "scenario"
    errors.run(lambda: variables.check_interface(_interface_of(table)))
    for name in table.get("parameters") or {}:
        errors.run(lambda: variables.get(name, f"{prefix}.parameters.{name}", SETTABLE,
                                         VALUE_TYPES))
    for name in table.get("inputs") or {}:
        errors.run(lambda: variables.driven(name, f"{prefix}.inputs.{name}"))


def _measured(reading: FitReading, e: Any) -> list[str]:
    """An experiment's measured columns: its data's, or its file's header where the data
    could not be read against the scenario."""
    if e.data is not None:
        return list(e.data.columns)
    return []


def _parameters_field(experiment: str | None) -> str:
    return "fit.parameters" if experiment is None else f"experiment.{experiment}.parameters"


def _ask_about_experiment(reading: FitReading, e: Any, runner: NativeRunner,
                          errors: Collector) -> None:
    """The values of experiment `e` the FMU refuses, but for those whose names `errors`
    holds refused already."""
    fitted = [p for p in reading.fitted if p.experiment in (None, e.name)]
    fields = [_parameters_field(p.experiment) for p in fitted]
    times = e.scenario.times()
    start, stop, step = times if times is not None else (0.0, 1.0, 1.0)
    table = e.scenario.table
    interface, integrator = _interface_of(table)
    plan = new_plan(start, stop, step, tolerance=table.get("tolerance") if table else None,
                    interface=interface)
    plan["fixed"], plan["inputs"] = dict(e.scenario.fixed), dict(e.scenario.inputs)
    plan["integrator"] = integrator
    asked, _ = values_to_ask(plan, [], "", errors)
    if asked is None:
        return
    refused = _fields(errors)
    good = [k for k, p in enumerate(fitted) if f"{fields[k]}.{p.variable}" not in refused]
    rows = np.array([[fitted[k].start for k in good], [fitted[k].low for k in good],
                     [fitted[k].high for k in good]])
    ask_the_fmu(asked, [fitted[k].variable for k in good], rows[:1], list(rows.T), runner,
                "fit.parameters", "scenario.parameters", [fields[k] for k in good])


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


def out_of_range(description: dict[str, Any], values: list[tuple[str, str, list[float]]],
                 errors: Collector) -> list[SpecError]:
    """Each (field, variable, values) whose values lie outside the variable's declared min
    and max, but for fields refused already."""
    bounds = {v["name"]: (_bound(v.get("min"), -np.inf), _bound(v.get("max"), np.inf))
              for v in description.get("variables", []) if v.get("type") in ("real", "integer")}
    refused = _fields(errors)
    found = []
    for field, name, numbers in values:
        low, high = bounds.get(name, (-np.inf, np.inf))
        outside = sorted({float(v) for v in numbers if not low <= v <= high})
        if outside and field not in refused:
            shown = ", ".join(f"{v:g}" for v in outside[:8]) + (", …" if len(outside) > 8 else "")
            found.append(SpecError(field, f"{name} = {shown}: outside the FMU's range "
                                          f"[{low:g}, {high:g}]"))
    return found


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

