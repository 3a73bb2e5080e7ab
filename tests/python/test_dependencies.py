"""ModelStructure's `dependencies` are exact: perturb each known (the inputs at a
communication point; the inputs and continuous states in Model Exchange; every input and
parameter in initialisation mode) and exactly the unknowns that declare it move. A master
that feeds `energy` back to `M_r` then sees no feedthrough there, so no algebraic loop."""

import ctypes

from test_fmi_api import Harness
from test_model_exchange import CONTINUOUS, Model

# A generic point: nothing zero that could hide a dependency.
GENERIC = dict(Mm_a0=100.0, Mm_a1=-20.0, Mm_a2=-1.0, Mr_b0=20.0, Mr_b1=-0.05, d12=0.1,
               d34=0.2, c4=0.1, twist12_0=0.2, twist34_0=-0.1, omega1_0=1.0, omega2_0=0.5,
               omega4_0=-0.3, phi2_0=0.4)
INPUTS = dict(M_m=1.0, M_r=0.5)


def read(fmu, variables):
    values = {}
    for v in variables:
        get = fmu.slave.getReal if v.type == "Real" else fmu.slave.getInteger
        values[v.name] = get([v.valueReference])[0]
    return values


def declared(unknowns):
    return {u.variable.name: {d.name for d in u.dependencies} for u in unknowns}


def moved(before, after, rounding=0.0):
    """The unknowns that changed; with `rounding`, by more than that relative amount (φ2 − φ1
    is a difference of two angles that both contain phi2_0: it moves with phi2_0 at the
    level of rounding, which is not a dependency)."""
    return {name for name in before
            if abs(after[name] - before[name]) > rounding * max(1.0, abs(before[name]))}


def test_outputs_feel_exactly_their_declared_inputs(unzipped, model_description):
    fmu = Harness(unzipped, model_description).instantiate().initialise(**GENERIC)
    fmu.slave.doStep(0.0, 0.1)
    outputs = [u.variable for u in model_description.outputs]
    # In Co-Simulation the knowns are the inputs (the states listed are Model Exchange's).
    deps = {o: d & set(INPUTS) for o, d in declared(model_description.outputs).items()}
    base = read(fmu, outputs)
    for name in ("M_m", "M_r"):
        fmu.set(name, 7.5)
        assert moved(base, read(fmu, outputs)) == {o for o, d in deps.items() if name in d}, name
        fmu.slave.doStep(0.1, 0.1)
        # ... and after a step, they all do (the test can see a dependency).
        assert "rod_force" in moved(base, read(fmu, outputs))
        fmu.free()
        fmu = Harness(unzipped, model_description).instantiate().initialise(**GENERIC)
        fmu.slave.doStep(0.0, 0.1)
    # No output feels an input before a step: the torques act on bodies 1 and 4, which
    # reach the rest through springs. So a master feeding energy back to M_r sees no loop.
    assert all(d == set() for d in deps.values())
    fmu.free()


def test_initial_unknowns_depend_on_exactly_their_declared_knowns(unzipped, model_description):
    unknowns = [u.variable for u in model_description.initialUnknowns]
    deps = declared(model_description.initialUnknowns)
    knowns = [v for v in model_description.modelVariables if v.causality in ("input", "parameter")]
    fmu = Harness(unzipped, model_description).instantiate()
    fmu.slave.setupExperiment(tolerance=1e-8, startTime=0.0)
    fmu.slave.enterInitializationMode()
    for name, value in dict(GENERIC, **INPUTS).items():
        fmu.set(name, value)
    base = read(fmu, unknowns)
    for known in knowns:
        if known.type == "Real":
            value = fmu.get(known.name)
            # phi3_guess only chooses between the two assemblies: move it to the other.
            moved_to = -value if known.name == "phi3_guess" else value * (1 + 1e-3) + 2e-3
            fmu.set(known.name, moved_to)
            changed = moved(base, read(fmu, unknowns), rounding=1e-12)
            fmu.set(known.name, value)
        elif known.type == "Boolean":  # builtin_laws: on -> off
            fmu.slave.setBoolean([known.valueReference], [False])
            changed = moved(base, read(fmu, unknowns))
            fmu.slave.setBoolean([known.valueReference], [True])
        else:  # solver: auto (1) -> implicit (3); change_point_branch: straight (1) -> turn (2);
            # a sensitivity slot: none (0) -> k12 (5)
            start = int(known.start)
            # The Integer twins likewise: 0 (the Enumeration decides) -> an item.
            other = {"change_point_branch": 2, "solver": 3, "solver_code": 3,
                     "change_point_branch_code": 2}.get(known.name, 5)
            fmu.slave.setInteger([known.valueReference], [other])
            changed = moved(base, read(fmu, unknowns))
            fmu.slave.setInteger([known.valueReference], [start])
        expected = {u for u, d in deps.items() if known.name in d}
        # Nothing moves that does not declare the known ...
        assert changed <= expected, (known.name, changed - expected)
        # ... and every continuous unknown that declares it moves. (The residual sits at
        # rounding level, the class changes only across a class boundary, and the lengths
        # move the loop's coordinates only where the rocker leads; here the crank does.)
        chart_bound = {"loop_angle", "loop_speed", "der(loop_angle)", "loop_chart"}
        continuous = expected - {"constraint_residual", "linkage_class"} - chart_bound
        assert continuous <= changed, (known.name, continuous - changed)
    assert read(fmu, unknowns) == base
    fmu.free()


def test_model_exchange_unknowns_feel_exactly_their_declared_knowns(unzipped, model_description):
    """Perturb each input and each continuous state in continuous-time mode: only the
    outputs and derivatives that declare it move, and each declared one moves in one of
    the two charts (where the crank leads, omega2 is loop_speed and ignores loop_angle;
    where the rocker leads, it is (C1/B1)·loop_speed)."""
    unknowns = [u.variable for u in model_description.outputs + model_description.derivatives]
    deps = declared(model_description.outputs + model_description.derivatives)
    seen = {known: set() for known in list(INPUTS) + CONTINUOUS}
    charts = []
    for start in (GENERIC, dict(GENERIC, L=0.96, phi2_0=1.5)):
        model = Model(unzipped, model_description).start(**start)
        charts += model.fmu.getInteger([model.vr["loop_chart"]])
        model.fmu.setReal([model.vr[n] for n in INPUTS], list(INPUTS.values()))
        x = model.states()
        get = lambda: {v.name: (model.fmu.getReal if v.type == "Real" else model.fmu.getInteger)(
            [v.valueReference])[0] for v in unknowns}
        base = get()
        for known in seen:
            if known in INPUTS:
                model.fmu.setReal([model.vr[known]], [INPUTS[known] + 0.5])
            else:
                moved_x = x.copy()
                moved_x[CONTINUOUS.index(known)] += 1e-3
                model.set_states(moved_x)
            changed = moved(base, get())
            expected = {u for u, d in deps.items() if known in d}
            assert changed <= expected, (known, changed - expected)
            seen[known] |= changed
            model.fmu.setReal([model.vr[n] for n in INPUTS], list(INPUTS.values()))
            model.set_states(x)
        model.fmu.freeInstance()
    assert charts == [2, 3], "one start where the crank leads, one where the rocker does"
    for known, changed in seen.items():
        # The residual stays at rounding level whatever the states: it is closed exactly.
        expected = {u for u, d in deps.items() if known in d} - {"constraint_residual"}
        assert expected <= changed, (known, expected - changed)
    # The false loop: energy, fed back to M_r, does not depend on M_r.
    assert "M_r" not in deps["energy"] and "M_r" in deps["der(omega4)"]


def test_the_class_and_the_method_move_with_their_knowns(unzipped, model_description):
    fmu = Harness(unzipped, model_description).instantiate()
    fmu.slave.setupExperiment(startTime=0.0)
    fmu.slave.enterInitializationMode()
    assert fmu.slave.getInteger([fmu.vr["linkage_class"]]) == [1]
    fmu.set("L", 0.96)
    fmu.set("phi2_0", 3.14159)  # s + g = 1.01 > p + q = 1: a triple-rocker
    assert fmu.slave.getInteger([fmu.vr["linkage_class"]]) == [5]
    assert fmu.slave.getInteger([fmu.vr["active_solver"]]) == [2]
    fmu.slave.setInteger([fmu.vr["solver"]], [3])
    assert fmu.slave.getInteger([fmu.vr["active_solver"]]) == [3]
    fmu.free()
