"""The packed modelDescription.xml and the binary agree, and the interface is the one the
issue asks for (names, causalities, units, defaults, DefaultExperiment)."""

import math

import pytest

from test_fmi_api import ERROR, Harness

# The interface as specified (docs/model.md §1–§4), written out independently of the code.
INPUTS = {"M_m": "N.m", "M_r": "N.m"}
OUTPUTS = {**{f"phi{i}": "rad" for i in range(1, 5)}, **{f"omega{i}": "rad/s" for i in range(1, 5)},
           "rod_force": "N", "constraint_residual": "m", "energy": "J"}
PARAMETERS = {"J1": 0.5, "J2": 0.2, "J3": 0.3, "J4": 0.7, "k12": 100.0, "k34": 100.0, "d12": 0.0,
              "d34": 0.0, "c4": 0.0, "l": 0.5, "l2": 0.05, "l3": 0.5, "L": 0.7, "phi2_0": 0.0,
              "phi3_guess": math.pi / 2, "twist12_0": 0.0, "twist34_0": 0.0, "omega1_0": 0.0,
              "omega2_0": 0.0, "omega4_0": 0.0, "Mm_a0": 100.0, "Mm_a1": -20.0, "Mm_a2": -1.0,
              "Mr_b0": 20.0, "Mr_b1": -0.05}  # the laws default to the paper's case 1
INTEGER_OUTPUTS = {"n_steps", "n_rejected", "n_rhs", "active_solver"}
ENUMERATION_OUTPUTS = {"active_solver"}


SENSITIVITY_VARIABLES = {f"sensitivity_{k}.{v}" for k in range(1, 6)
                         for v in ["parameter", "phi1", "phi2", "phi3", "phi4",
                                   "omega1", "omega2", "omega3", "omega4"]}


def by_name(model_description):
    return {v.name: v for v in model_description.modelVariables}


TWINS = {"solver_code", "change_point_branch_code"} | {f"sensitivity_{k}.parameter_code"
                                                        for k in range(1, 6)}

# The Model Exchange variables (docs/model.md §6): unit, and whose derivative each is.
EXCHANGE = {"loop_angle": ("rad", None), "loop_speed": ("rad/s", None), "loop_chart": (None, None),
            "der(phi1)": ("rad/s", "phi1"), "der(loop_angle)": ("rad/s", "loop_angle"),
            "der(phi4)": ("rad/s", "phi4"), "der(omega1)": ("rad/s2", "omega1"),
            "der(loop_speed)": ("rad/s2", "loop_speed"), "der(omega4)": ("rad/s2", "omega4")}


def test_interface_is_as_specified(model_description):
    variables = by_name(model_description)
    assert set(variables) == (set(INPUTS) | set(OUTPUTS) | set(PARAMETERS) | INTEGER_OUTPUTS
                              | {"solver", "linkage_class", "builtin_laws", "handover_indicator",
                                 "change_point_branch"}
                              | set(EXCHANGE) | SENSITIVITY_VARIABLES | TWINS)
    # The Integer twins of the Enumeration parameters, for masters that cannot set those:
    # 0 by default (the Enumeration decides), up to the Enumeration's last item.
    for twin in TWINS:
        enumeration = variables[twin.removesuffix("_code")]
        v = variables[twin]
        assert (v.causality, v.variability, v.type, v.start, v.min) == (
            "parameter", enumeration.variability, "Integer", "0", "0")
        assert int(v.max) == max(int(i.value) for i in enumeration.declaredType.items)
    # The sensitivity slots (docs/sensitivities.md): a fixed Enumeration parameter each,
    # whose items are none and the parameters with a sensitivity, and eight Real locals.
    slot = variables["sensitivity_3.parameter"]
    assert (slot.causality, slot.variability, slot.type, slot.start) == (
        "parameter", "fixed", "Enumeration", "0")
    items = {item.name: int(item.value) for item in slot.declaredType.items}
    names = [v.name for v in model_description.modelVariables if v.causality == "parameter"]
    assert items == {"none": 0} | {n: names.index(n) + 1 for n in PARAMETERS
                                   if n not in ("l", "l2", "l3", "L", "phi3_guess")}
    local = variables["sensitivity_5.omega4"]
    assert (local.causality, local.variability, local.type) == ("local", "continuous", "Real")
    branch = variables["change_point_branch"]
    assert (branch.causality, branch.variability, branch.type, branch.start) == (
        "parameter", "tunable", "Enumeration", "1")
    assert [item.name for item in branch.declaredType.items] == ["straight", "turn"]
    indicator = variables["handover_indicator"]
    assert (indicator.causality, indicator.variability, indicator.unit) == ("local", "continuous", None)
    for name, (unit, derivative_of) in EXCHANGE.items():
        v = variables[name]
        assert (v.causality, v.unit, v.initial) == ("local", unit, "calculated"), name
        assert (v.derivative.name if v.derivative else None) == derivative_of, name
    # Model Exchange: six states, in the order of their derivatives, and one event indicator.
    assert [d.variable.derivative.name for d in model_description.derivatives] == [
        "phi1", "loop_angle", "phi4", "omega1", "loop_speed", "omega4"]
    assert model_description.numberOfEventIndicators == 1
    assert model_description.modelExchange.providesDirectionalDerivative
    assert model_description.coSimulation.providesDirectionalDerivative
    for name, unit in INPUTS.items():
        v = variables[name]
        assert (v.causality, v.variability, v.unit, float(v.start)) == ("input", "continuous", unit, 0.0)
    for name, unit in OUTPUTS.items():
        v = variables[name]
        assert (v.causality, v.unit, v.initial) == ("output", unit, "calculated"), name
    for name, default in PARAMETERS.items():
        v = variables[name]
        assert (v.causality, v.variability) == ("parameter", "fixed"), name
        assert float(v.start) == default, name
    for v in variables.values():
        assert v.description, f"{v.name} has no description"
    for name in INTEGER_OUTPUTS:
        v = variables[name]
        kind = "Enumeration" if name in ENUMERATION_OUTPUTS else "Integer"
        assert (v.type, v.causality, v.variability, v.initial) == (kind, "output", "discrete", "calculated")
    assert variables["active_solver"].declaredType.name == "SolverKind"
    # What a tool's dialog shows: angles in degrees, speeds in rpm; who made it, under which licence.
    assert variables["phi1"].displayUnit == "deg" and variables["omega1"].displayUnit == "rpm"
    assert (float(variables["J1"].min), float(variables["J1"].max)) == (1e-9, 1e9)
    assert model_description.license == "MIT" and model_description.author
    solver = variables["solver"]
    assert (solver.type, solver.causality, solver.variability, int(solver.start)) == ("Enumeration", "parameter", "fixed", 1)
    assert [(i.name, int(i.value)) for i in solver.declaredType.items] == [("auto", 1), ("dop853", 2), ("implicit", 3)]
    laws = variables["builtin_laws"]
    assert (laws.type, laws.causality, laws.variability, laws.start) == ("Boolean", "parameter", "fixed", "true")
    linkage = variables["linkage_class"]
    assert (linkage.type, linkage.causality, linkage.variability) == ("Enumeration", "output", "discrete")
    assert [i.name for i in linkage.declaredType.items][:2] == ["crank_rocker", "double_crank"]
    outputs = {u.variable.name for u in model_description.outputs}
    assert outputs == set(OUTPUTS) | INTEGER_OUTPUTS | {"linkage_class"}


def test_default_experiment_and_capabilities(model_description):
    experiment = model_description.defaultExperiment
    assert (float(experiment.startTime), float(experiment.stopTime)) == (0.0, 10.0)
    assert (float(experiment.stepSize), float(experiment.tolerance)) == (1e-3, 1e-8)
    cs = model_description.coSimulation
    assert cs.modelIdentifier == "CyclicMechanism"
    assert cs.canHandleVariableCommunicationStepSize
    categories = {c.name for c in model_description.logCategories}
    assert {"logStatusError", "logCalls"} <= categories


def test_binary_serves_every_declared_variable_with_its_start(unzipped, model_description):
    fmu = Harness(unzipped, model_description).instantiate()
    fmu.slave.setupExperiment(startTime=0.0)
    fmu.slave.enterInitializationMode()
    accessors = {"Real": (fmu.slave.getReal, fmu.slave.setReal, float),
                 "Boolean": (fmu.slave.getBoolean, fmu.slave.setBoolean, lambda s: s == "true")}
    for v in model_description.modelVariables:
        real = v.type == "Real"
        get, set_, parse = accessors.get(v.type, (fmu.slave.getInteger, fmu.slave.setInteger, int))
        value = get([v.valueReference])[0]
        if v.start is not None:
            assert value == parse(v.start), v.name
        assert math.isfinite(value), v.name
        if v.causality in ("output", "local"):
            with pytest.raises(Exception):
                set_([v.valueReference], [1])
        else:
            set_([v.valueReference], [value])  # writable in initialisation mode
        # The other accessor types are refused.
        wrong = fmu.slave.getInteger if real else fmu.slave.getReal
        assert f"{v.name} is of type" in fmu.expect(ERROR, wrong, [v.valueReference])
        wrong = fmu.slave.getReal if v.type == "Boolean" else fmu.slave.getBoolean
        assert f"{v.name} is of type" in fmu.expect(ERROR, wrong, [v.valueReference])
    references = sorted(v.valueReference for v in model_description.modelVariables)
    assert references == list(range(len(references))), "the binary's table is dense"
    assert "unknown value reference" in fmu.expect(ERROR, fmu.slave.getReal, [len(references)])
    fmu.free()
