"""The checks of a specification that need the FMU: every name is a variable of the right
kind, and every value the design and the scenario set is one the FMU accepts. The FMU is
asked itself (its values are set in initialisation mode, nothing runs), so its own rules
(J > 0, k ≥ 0, …) apply, whatever FMU it is; refusals become SpecErrors naming the field.
"""

from __future__ import annotations

import numpy as np

from .spec import SpecError

__all__ = ["check_against_fmu"]

SETTABLE = ("parameter", "input")


def check_against_fmu(spec, design, description: dict, runner) -> None:
    variables = {v["name"]: v for v in description["variables"]}

    def variable(name: str, where: str, causalities=None, types=None) -> dict:
        v = variables.get(name)
        if v is None:
            raise SpecError(where, f"the FMU has no variable {name!r}")
        if causalities and v["causality"] not in causalities:
            raise SpecError(where, f"{name} has causality {v['causality']}; "
                                   f"only {' or '.join(causalities)} variables can be set")
        if types and v["type"] not in types:
            raise SpecError(where, f"{name} is of type {v['type']}; expected {' or '.join(types)}")
        return v

    for name in spec.parameters:
        variable(name, f"scenario.parameters.{name}", SETTABLE, ("real", "integer", "enumeration", "boolean"))
    for name in spec.inputs:
        variable(name, f"scenario.inputs.{name}", ("input",), ("real",))
    for m in spec.metrics:
        variable(m.variable, f"outputs.metrics.{m.name}.variable", None, ("real", "integer", "enumeration", "boolean"))
    for name in spec.series_variables:
        variable(name, "outputs.series.variables", None, ("real", "integer", "enumeration", "boolean"))
    for j, name in enumerate(design.names):
        v = variable(name, f"design.parameters.{name}", SETTABLE, ("real", "integer", "enumeration", "boolean"))
        column = design.rows[:, j]
        if v["type"] in ("integer", "enumeration") and np.any(column != np.round(column)):
            raise SpecError(f"design.parameters.{name}", f"{name} is an Integer; the design gives "
                                                         f"{column[column != np.round(column)][0]}")
        if v["type"] == "boolean" and not np.all((column == 0) | (column == 1)):
            raise SpecError(f"design.parameters.{name}", f"{name} is a Boolean; the design must give 0 or 1")

    _ask_the_fmu(spec, design, runner)


def _ask_the_fmu(spec, design, runner):
    """Set the fixed values, then each design column's extremes, and report what the FMU
    refuses. Single-variable rules are caught here; a combination that cannot run (a
    geometry that does not assemble) is a result of the sweep, not a mistake in it."""
    runner.configure(spec.plan())
    fixed = runner.check([], [[]])[0]
    if fixed["status"] != "ok":
        raise SpecError("scenario.parameters", f"the FMU refuses the fixed values: {fixed['message']}")
    rows, columns = design.rows, design.names
    first = runner.check(columns, rows[:1])[0]
    if first["status"] != "ok":
        raise SpecError("design", f"the FMU refuses the first point: {first['message']}")
    # From the first point, which passed, change one column to its extreme values: a
    # refusal then belongs to that column.
    probes, owners = [], []
    for j, name in enumerate(columns):
        for value in np.unique([rows[:, j].min(), rows[:, j].max()]):
            probe = rows[0].copy()
            probe[j] = value
            probes.append(probe)
            owners.append((name, value))
    for (name, value), answer in zip(owners, runner.check(columns, probes)):
        if answer["status"] != "ok":
            raise SpecError(f"design.parameters.{name}",
                            f"the FMU refuses {name} = {value:g}: {answer['message']}")
