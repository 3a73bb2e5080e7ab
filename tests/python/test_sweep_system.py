"""Coupled systems swept natively: a [system] of the compiled DC motor and the mechanism
runs in the runner (its own engine, or a container FMU), gives an FMPy master loop's run
bit for bit (with input derivatives, the loop that passes them), addresses its variables
as component.variable, and is refused by field when a name, a file, a connection or a
loop is wrong; a component that crashes is one row, a worker killed mid-sweep loses no
point, and the coupling error against the monolithic reference falls with the order the
input derivatives give."""

import pathlib
import zipfile

import numpy as np
import pytest

from conftest import ROOT
from fmusweep import SpecError, run_sweep
from sweep_helpers import (environment_for_workers, faulty_fmu, in_description, kill_during,
                           repacked, start_cluster, stop_cluster)

MECHANISM = {"Mm_a0": 0.0, "Mm_a1": 0.0, "Mm_a2": 0.0, "Mr_b0": 20.0, "Mr_b1": -0.05, "c4": 0.5}


def system_spec(fmu_path, motor_path, stop=2.0, design=None, series=False, engine=None):
    spec = {
        "system": {"components": {"motor": str(motor_path), "mechanism": str(fmu_path)},
                   "connections": [["motor.torque", "mechanism.M_m"],
                                   ["mechanism.omega1", "motor.omega"]]},
        "scenario": {"stop": stop, "step": 0.001, "tolerance": 1e-8,
                     "parameters": {f"mechanism.{k}": v for k, v in MECHANISM.items()}},
        "design": {"kind": "list", "parameters": design or {
            "motor.voltage": {"values": [24.0, 30.0]}, "mechanism.d34": {"values": [1.0, 0.5]}}},
        "outputs": {"metrics": {"final_omega1": {"variable": "mechanism.omega1", "kind": "final"},
                                "peak_current": {"variable": "motor.current", "kind": "peak_abs"}}},
    }
    if series:
        spec["outputs"]["series"] = {"variables": ["mechanism.omega1", "motor.current"]}
    if engine is not None:
        spec["system"]["engine"], spec["system"]["input_derivatives"] = engine
    return spec


def fmpy_master_loop(fmu_path, motor_path, voltage, d34, stop, step=0.001, derivatives=0,
                     grid=False):
    """examples/dc_motor/coupling.py's loop (Jacobi: both step from the previous outputs),
    returning omega1 and the current after every step. With `derivatives` k, each
    connection in turn passes its value and then its output derivatives of orders 1..k.
    With `grid`, step k goes from k·H to (k + 1)·H, as the runner's own master steps (its
    size is not always H to the last bit); else by H, as the container's master does."""
    import sys
    sys.path.insert(0, str(ROOT / "bench"))
    from bench_coupled_step import load
    motor, mv = load(motor_path, "motor")
    mech, xv = load(fmu_path, "mechanism")
    for slave in (motor, mech):
        slave.instantiate()
        slave.setupExperiment(tolerance=1e-8, startTime=0.0, stopTime=stop)
        slave.enterInitializationMode()
    values = dict(MECHANISM, d34=d34)
    mech.setReal([xv[n] for n in values], list(values.values()))
    motor.setReal([mv["voltage"]], [voltage])
    for slave in (motor, mech):
        slave.exitInitializationMode()
    rows = []
    orders = list(range(1, derivatives + 1))
    for k in range(round(stop / step)):
        if derivatives:
            for source, out, target, into in ((motor, mv["torque"], mech, xv["M_m"]),
                                              (mech, xv["omega1"], motor, mv["omega"])):
                target.setReal([into], source.getReal([out]))
                rates = source.getRealOutputDerivatives([out] * derivatives, orders)
                target.setRealInputDerivatives([into] * derivatives, orders, rates)
        else:
            omega1 = mech.getReal([xv["omega1"]])[0]
            torque = motor.getReal([mv["torque"]])[0]
            motor.setReal([mv["omega"]], [omega1])
            mech.setReal([xv["M_m"]], [torque])
        h = (k + 1) * step - k * step if grid else step
        motor.doStep(k * step, h)
        mech.doStep(k * step, h)
        rows.append([mech.getReal([xv["omega1"]])[0], motor.getReal([mv["current"]])[0]])
    return np.array(rows)


ENGINES = [("native", 2), ("native", 1), ("native", 0), ("container", 0)]


@pytest.mark.parametrize("engine", ENGINES, ids=lambda e: f"{e[0]}-{e[1]}")
def test_a_coupled_system_sweeps_natively_as_an_fmpy_master_loop_runs_it(
        fmu_path, motor_path, tmp_path, engine):
    spec = system_spec(fmu_path, motor_path, series=True, engine=engine)
    results = run_sweep(spec, out=tmp_path / "out", serial=True, progress=False, plots=False)
    points = results.points
    assert list(points["status"]) == ["ok", "ok"]
    assert {"motor.voltage", "mechanism.d34"} <= set(points.columns)
    series = results.series()
    for point, (voltage, d34) in enumerate([(24.0, 1.0), (30.0, 0.5)]):
        expected = fmpy_master_loop(fmu_path, motor_path, voltage, d34, 2.0, derivatives=engine[1],
                                    grid=engine[0] == "native")
        mine = series[series["point"] == point]
        omega1 = mine[mine["variable"] == "mechanism.omega1"].sort_values("time")["value"].to_numpy()[1:]
        current = mine[mine["variable"] == "motor.current"].sort_values("time")["value"].to_numpy()[1:]
        assert len(omega1) == len(expected) == 2000
        # The same calls in the same order: the same numbers, to the last bit.
        np.testing.assert_array_equal(omega1, expected[:, 0])
        np.testing.assert_array_equal(current, expected[:, 1])
    assert points["final_omega1"][1] > points["final_omega1"][0]  # more voltage, more speed


def gain_fmu(directory, name):
    """A model description alone: an input u and an output y depending on it directly."""
    path = directory / f"{name}.fmu"
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{{gain-{name}}}">
  <CoSimulation modelIdentifier="{name}"/>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="0" causality="input" variability="continuous"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="1" causality="output" variability="continuous" initial="calculated"><Real/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="2" dependencies="1"/></Outputs><InitialUnknowns><Unknown index="2" dependencies="1"/></InitialUnknowns></ModelStructure>
</fmiModelDescription>"""
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("modelDescription.xml", xml)
    return path


def _bad_systems(fmu_path, motor_path, tmp):
    def connections(*pairs):
        return lambda s: s["system"].update(connections=[list(p) for p in pairs])

    def components(**more):
        return lambda s: s["system"]["components"].update(**more)

    # Files are made when a case is applied, so that the cases can be listed without them.
    def not_an_fmu(s):
        (tmp / "broken.fmu").write_text("not an FMU")
        components(pump=str(tmp / "broken.fmu"))(s)

    def loop(s):
        s["system"] = {"components": {"a": str(gain_fmu(tmp, "gain_a")),
                                      "b": str(gain_fmu(tmp, "gain_b"))},
                       "connections": [["a.y", "b.u"], ["b.y", "a.u"]]}
        s["scenario"]["parameters"] = {}
        s["design"]["parameters"] = {"a.u": {"values": [0.0]}}
        s["outputs"]["metrics"] = {"y": {"variable": "b.y", "kind": "final"}}

    return {
        "an unknown component": ("system.connections[1]", connections(
            ["motor.torque", "mechanism.M_m"], ["mechanism.omega1", "pump.omega"])),
        "an unknown variable": ("system.connections[0]", connections(["motor.torque", "mechanism.M_x"])),
        "from an input": ("system.connections[0]", connections(["motor.omega", "mechanism.M_m"])),
        "to an output": ("system.connections[0]", connections(["motor.torque", "mechanism.omega2"])),
        "an Integer into a Real": ("system.connections[0]", connections(["mechanism.n_steps", "motor.voltage"])),
        "an input fed twice": ("system.connections[1]", connections(
            ["motor.torque", "mechanism.M_m"], ["motor.current", "mechanism.M_m"])),
        "not component.variable": ("system.connections[0]", connections(["torque", "mechanism.M_m"])),
        "a bad component name": ("system.components.Motor", components(Motor=str(motor_path))),
        "a missing file": ("system.components.pump", components(pump=str(tmp / "pump.fmu"))),
        "a file that is not an FMU": ("system.components.pump", not_an_fmu),
        "an algebraic loop": ("system.connections", loop),
        "a parameter the system lacks": ("design.parameters.mechanism.k99", lambda s: s["design"].update(
            parameters={"mechanism.k99": {"values": [1.0]}})),
        "a bare name": ("design.parameters.d34", lambda s: s["design"].update(
            parameters={"d34": {"values": [1.0]}})),
        "an FMU and a system": ("system", lambda s: s.update(fmu=str(fmu_path))),
        "a component that cannot be loaded": (
            "system", lambda s: components(gain=str(gain_fmu(tmp, "gain_a")))(s)),
        "an unknown engine": ("system.engine", lambda s: s["system"].update(engine="ssp")),
        "input derivatives beyond 2": ("system.input_derivatives",
                                       lambda s: s["system"].update(input_derivatives=3)),
        "input derivatives for the container": (
            "system.input_derivatives",
            lambda s: s["system"].update(engine="container", input_derivatives=1)),
        "an unknown field": ("system.solver", lambda s: s["system"].update(solver="rk4")),
        "a coupling tolerance of zero": ("system.coupling_tolerance",
                                         lambda s: s["system"].update(coupling_tolerance=0.0)),
        "a coupling tolerance for the container": (
            "system.coupling_tolerance",
            lambda s: s["system"].update(engine="container", input_derivatives=0,
                                         coupling_tolerance=1e-4)),
        "a component written in Python": (
            "system.components.motor",
            lambda s: components(motor=str(python_written(motor_path, tmp)))(s)),
        "a coupling tolerance with a component that cannot roll back": (
            "system.components.motor",
            lambda s: s["system"].update(coupling_tolerance=1e-4, components={
                "motor": str(without_state(motor_path, tmp)), "mechanism": str(fmu_path)})),
    }


def python_written(fmu, directory):
    """A copy of `fmu` whose description says PythonFMU wrote it."""
    return repacked(fmu, directory / "pythonfmu.fmu",
                    in_description(b'generationTool="', b'generationTool="PythonFMU 0.6.5, '))


def without_state(fmu, directory):
    """A copy of `fmu` whose description says it cannot save its state."""
    return repacked(fmu, directory / "stateless.fmu",
                    in_description(b'canGetAndSetFMUstate="true"', b'canGetAndSetFMUstate="false"'))


BAD = list(_bad_systems(None, None, pathlib.Path(".")))


@pytest.mark.parametrize("case", BAD)
def test_a_bad_system_is_refused_by_field_before_anything_runs(fmu_path, motor_path, tmp_path, case):
    field, change = _bad_systems(fmu_path, motor_path, tmp_path)[case]
    spec = system_spec(fmu_path, motor_path)
    change(spec)
    with pytest.raises(SpecError) as refused:
        run_sweep(spec, out=tmp_path / "out", serial=True, progress=False, plots=False)
    assert refused.value.field == field, str(refused.value)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("engine", ["native", "container"])
def test_a_component_that_fails_crashes_or_hangs_is_one_row(fmu_path, motor_path, tmp_path, engine,
                                                            monkeypatch):
    """The faulty FMU beside the motor: at x = 13 it dereferences NULL, which takes the
    runner down (`crashed`); at x = 5 it discards a step (`discard`, and the FMU's message
    says why, with the native engine); at x = 3 it is slow past the
    point's budget and at x = 7 it hangs in a step (both `timeout`, the hung one killed).
    The others finish, with the right values."""
    from fmusweep import native
    monkeypatch.setattr(native, "HARD_DEADLINE_GRACE_S", 0.5)
    faulty = faulty_fmu(tmp_path)
    xs = [1.0, 13.0, 2.0, 5.0, 3.0, 7.0, 4.0, 6.0]
    spec = {"system": {"components": {"faulty": str(faulty), "motor": str(motor_path)},
                       "connections": [], "engine": engine},
            "scenario": {"stop": 1.0, "step": 0.01, "timeout": 0.05},
            "design": {"kind": "list", "parameters": {"faulty.x": {"values": xs}}},
            "outputs": {"metrics": {"y": {"variable": "faulty.y", "kind": "final"},
                                    "i": {"variable": "motor.current", "kind": "final"}}}}
    points = run_sweep(spec, out=tmp_path / "out", serial=True, progress=False, plots=False).points
    # The container reports its component's discard as an error of its own.
    discarded = "discard" if engine == "native" else "error"
    assert list(points["status"]) == ["ok", "crashed", "ok", discarded, "timeout", "timeout",
                                      "ok", "ok"]
    by_x = points.set_index("faulty.x")
    assert "SIGSEGV" in by_x.loc[13.0, "message"] and "killed" in by_x.loc[7.0, "message"]
    if engine == "native":  # the FMU's message, and which component said it
        assert "x = 5 cannot pass t = 0.5" in by_x.loc[5.0, "message"]
        assert "component faulty: fmi2DoStep returned Discard" in by_x.loc[5.0, "message"]
    ok = points[points["status"] == "ok"]
    np.testing.assert_allclose(ok["y"], ok["faulty.x"], rtol=1e-12)  # y = x·t at t = 1


def test_a_worker_killed_mid_coupled_sweep_loses_no_point(fmu_path, motor_path, tmp_path):
    """`kill -9` of one of two `dask worker` processes (no nanny) while the coupled sweep
    runs: the other worker finishes, every point is there once, all ok."""
    env = dict(environment_for_workers(), FMUSWEEP_TRACE=str(tmp_path / "trace"))
    address, processes = start_cluster(tmp_path, env, ["--no-nanny"])
    victim = processes[1]
    design = {"motor.voltage": {"linspace": [12.0, 36.0, 20]}, "mechanism.d34": {"linspace": [0.2, 2.0, 10]}}
    spec = system_spec(fmu_path, motor_path, stop=1.0, design=design)
    spec["design"]["kind"] = "grid"
    trace = tmp_path / "trace"
    try:
        results = kill_during(
            lambda: run_sweep(spec, out=tmp_path / "out", scheduler=address, batch_size=5,
                              progress=False, plots=False),
            victim, lambda: trace.exists() and trace.read_text().count("start") >= 10)
    finally:
        stop_cluster(processes)
    points = results.points
    assert len(points) == 200 and points["point"].is_unique
    assert (points["status"] == "ok").all()


# (engine, input derivatives, the observed order's range, the most error at H = 1 ms).
ORDERS = [("container", 0, (0.8, 1.3), 2e-2), ("native", 0, (0.8, 1.3), 2e-2),
          ("native", 1, (1.7, 2.4), 5e-4), ("native", 2, (2.6, 3.6), 1e-5)]


@pytest.mark.parametrize("engine, derivatives, orders, most", ORDERS,
                         ids=[f"{e}-{k}" for e, k, _, _ in ORDERS])
def test_the_coupling_error_against_the_monolithic_reference_has_the_engines_order(
        fmu_path, motor_path, tmp_path, engine, derivatives, orders, most):
    """Motor and mechanism as one ODE (tests/python/reference.py, scipy at rtol 1e-11) against
    the coupled sweep at H = 1 and 2 ms over 1 s: holding inputs over a step the error
    halves with the step (order 1); passing the output derivatives of orders 1..k as input
    derivatives, it falls as H^(k+1)."""
    import reference
    p = reference.Params(**MECHANISM, d34=1.0)
    names = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4"]
    errors = []
    for step in (1e-3, 2e-3):
        spec = system_spec(fmu_path, motor_path, stop=1.0, design={"mechanism.d34": {"values": [1.0]}},
                           engine=(engine, derivatives))
        spec["scenario"]["step"] = step
        spec["outputs"]["series"] = {"variables": [f"mechanism.{n}" for n in names] + ["motor.current"]}
        series = run_sweep(spec, out=tmp_path / f"out{step}", serial=True, progress=False,
                           plots=False).series()
        columns = [series[series["variable"] == v].sort_values("time")
                   for v in [f"mechanism.{n}" for n in names] + ["motor.current"]]
        times = columns[0]["time"].to_numpy()
        mine = np.column_stack([c["value"].to_numpy() for c in columns])
        exact = reference.solve_with_motor(p, reference.Motor(), times, rtol=1e-11)
        errors.append(float((np.abs(mine - exact) / np.maximum(1.0, np.abs(exact).max(axis=0))).max()))
    order = np.log2(errors[1] / errors[0])
    assert orders[0] < order < orders[1], errors
    assert errors[0] < most, errors


@pytest.mark.parametrize("tolerance", [1e-4, 1e-6])
def test_a_coupling_tolerance_holds_the_error_and_reports_the_steps(
        fmu_path, motor_path, tmp_path, tolerance):
    """With a coupling tolerance the system chooses its communication steps inside a grid of
    10 ms: against the monolithic reference over 1 s, the worst scaled error stays within
    3 × the tolerance at every grid point, and each row reports the steps taken."""
    import reference
    p = reference.Params(**MECHANISM, d34=1.0)
    names = [f"mechanism.{n}" for n in ("phi1", "phi2", "phi3", "phi4", "omega1", "omega2",
                                        "omega3", "omega4")] + ["motor.current"]
    spec = system_spec(fmu_path, motor_path, stop=1.0, design={"mechanism.d34": {"values": [1.0]}})
    spec["system"]["coupling_tolerance"] = tolerance
    spec["scenario"]["step"] = 0.01
    spec["outputs"]["series"] = {"variables": names}
    results = run_sweep(spec, out=tmp_path / "out", serial=True, progress=False, plots=False)
    row = results.points.iloc[0]
    assert row["status"] == "ok", row["message"]
    series = results.series()
    columns = [series[series["variable"] == v].sort_values("time") for v in names]
    times = columns[0]["time"].to_numpy()
    assert np.allclose(times, np.arange(101) * 0.01)
    mine = np.column_stack([c["value"].to_numpy() for c in columns])
    exact = reference.solve_with_motor(p, reference.Motor(), times, rtol=1e-11)
    error = float((np.abs(mine - exact) / np.maximum(1.0, np.abs(exact).max(axis=0))).max())
    assert error <= 3 * tolerance, error
    # More steps than the grid's, each estimate within the tolerance, few rejected.
    assert row["coupling_steps"] > 100 and row["coupling_error"] <= tolerance
    assert row["coupling_rejected"] <= 0.1 * row["coupling_steps"]
    assert 0 < row["coupling_min_step"] < 0.01


def _held_point(fmu_path, motor_path, out, tolerance, derivatives, stop=0.3, fmu_tolerance=None):
    """The motor system over its current's transient under a coupling tolerance: the worst
    scaled error against the monolithic reference at the 10 ms grid's points, and the row."""
    import reference
    names = [f"mechanism.{n}" for n in ("phi1", "phi2", "phi3", "phi4", "omega1", "omega2",
                                        "omega3", "omega4")] + ["motor.current"]
    spec = system_spec(fmu_path, motor_path, stop=stop, design={"mechanism.d34": {"values": [1.0]}},
                       engine=("native", derivatives))
    spec["system"]["coupling_tolerance"] = tolerance
    spec["scenario"].update(step=0.01, tolerance=fmu_tolerance or tolerance / 10)
    spec["outputs"]["series"] = {"variables": names}
    results = run_sweep(spec, out=out, serial=True, progress=False, plots=False)
    row = results.points.iloc[0]
    if row["status"] != "ok":
        return None, row
    series = results.series()
    columns = [series[series["variable"] == v].sort_values("time") for v in names]
    mine = np.column_stack([c["value"].to_numpy() for c in columns])
    exact = reference.solve_with_motor(reference.Params(**MECHANISM, d34=1.0), reference.Motor(),
                                       columns[0]["time"].to_numpy(), rtol=1e-11)
    return float((np.abs(mine - exact) / np.maximum(1.0, np.abs(exact).max(axis=0))).max()), row


@pytest.mark.parametrize("derivatives, per_decade", [(0, (7, 14)), (1, (2.2, 4.5))])
def test_held_inputs_meet_a_coupling_tolerance_at_the_cost_of_their_order(
        fmu_path, motor_path, tmp_path, derivatives, per_decade):
    """The motor's torque rises from zero at k·V/L = 4800 N·m/s: held over a step its drift
    is 4800 N·m/s × the step, so a tolerance of 1e-5 asks for steps of 2e-9 s at the start.
    Held inputs (order 1) meet every tolerance down to 1e-5, within 3 × the tolerance of
    the reference, at ten times the steps per decade; one derivative (order 2) at √10."""
    steps = []
    for tolerance in (1e-3, 1e-4, 1e-5):
        error, row = _held_point(fmu_path, motor_path, tmp_path / f"{tolerance}", tolerance,
                                 derivatives)
        assert error is not None, row["message"]
        assert error <= 3 * tolerance, (tolerance, error)
        assert row["coupling_error"] <= tolerance
        steps.append(row["coupling_steps"])
    ratios = np.array(steps[1:]) / np.array(steps[:-1])
    assert ((per_decade[0] < ratios) & (ratios < per_decade[1])).all(), steps


def test_a_tolerance_out_of_reach_names_the_connection_and_what_would_reach_it(
        fmu_path, motor_path, tmp_path):
    error, row = _held_point(fmu_path, motor_path, tmp_path / "out", 1e-13, 0, stop=0.05,
                             fmu_tolerance=1e-10)
    assert error is None and row["status"] == "error"
    message = row["message"]
    for part in ("tolerance 1e-13", "at t = 0", "motor.torque → mechanism.M_m", "held",
                 "coupling_tolerance", "input_derivatives", "output grid's step"):
        assert part in message, message


def test_without_a_coupling_tolerance_the_rows_are_as_before(fmu_path, motor_path, tmp_path):
    """No tolerance: no coupling columns, and the steps are the grid's."""
    spec = system_spec(fmu_path, motor_path, stop=0.5)
    points = run_sweep(spec, out=tmp_path / "out", serial=True, progress=False, plots=False).points
    assert not any(c.startswith("coupling_") for c in points.columns)
    assert (points["steps"] == 500).all()


def test_under_a_coupling_tolerance_the_fmus_run_at_a_tenth_of_it(fmu_path, motor_path, tmp_path):
    """Without a tolerance of its own the scenario passes a tenth of the coupling tolerance
    to the FMUs; one it gives is kept."""
    from fmusweep import Spec
    spec = system_spec(fmu_path, motor_path)
    spec["system"]["coupling_tolerance"] = 1e-5
    del spec["scenario"]["tolerance"]
    assert Spec.from_dict(spec, tmp_path).plan()["tolerance"] == pytest.approx(1e-6)
    spec["scenario"]["tolerance"] = 1e-9
    assert Spec.from_dict(spec, tmp_path).plan()["tolerance"] == 1e-9
    del spec["system"]["coupling_tolerance"], spec["scenario"]["tolerance"]
    assert Spec.from_dict(spec, tmp_path).plan()["tolerance"] is None


def _flywheel_error(fmu_path, load_path, out, step, derivatives=2, tolerance=None, stop=1.0):
    """The mechanism driving the flywheel on its stiff shaft (the benchmark's system): the
    worst scaled error against the monolithic reference, and the point's row."""
    import sys
    sys.path.insert(0, str(ROOT / "bench"))
    import bench_coupled_sweep as coupled
    spec = coupled.system_spec(fmu_path, load_path, stop, step, 1, series=True,
                               engine=("native", derivatives), tolerance=tolerance,
                               system=coupled.FLYWHEEL,
                               fmu_tolerance=1e-10 if tolerance is None else None)
    return coupled.worst_error(spec, out, coupled.FLYWHEEL)


def test_on_the_stiff_flywheel_held_inputs_diverge_and_derivatives_converge_at_order_three(
        fmu_path, load_path, tmp_path):
    """Holding inputs over 10 ms the stiff shaft's loop is unstable; passing two output
    derivatives it converges at order 3 (order 2 while the mechanism's rates at a step's
    end took the torque as it was at the step's start)."""
    held, _ = _flywheel_error(fmu_path, load_path, tmp_path / "held", 0.01, derivatives=0)
    assert held > 1.0
    fine, _ = _flywheel_error(fmu_path, load_path, tmp_path / "fine", 0.002)
    coarse, _ = _flywheel_error(fmu_path, load_path, tmp_path / "coarse", 0.004)
    assert 2.6 < np.log2(coarse / fine) < 3.6, (fine, coarse)
    assert fine < 1e-6


@pytest.mark.parametrize("tolerance", [1e-4, 1e-6])
def test_a_coupling_tolerance_holds_on_the_stiff_flywheel(fmu_path, load_path, tmp_path, tolerance):
    error, row = _flywheel_error(fmu_path, load_path, tmp_path / "out", 0.01, tolerance=tolerance)
    assert error <= 3 * tolerance, error
    assert row["coupling_error"] <= tolerance and row["coupling_steps"] > 100
    assert row["coupling_rejected"] <= 0.1 * row["coupling_steps"]


def test_under_a_coupling_tolerance_a_tabulated_input_moves_along_its_table(
        fmu_path, motor_path, tmp_path):
    """The motor's voltage ramps up over 13 ms and again later, its breakpoints between the
    10 ms grid's points: under a coupling tolerance the steps end on every breakpoint and
    the voltage moves along each segment's slope, so the run stays within 3 × the
    tolerance of the monolithic reference with the same voltage (held over grid steps, the
    ramp alone would be off by volts)."""
    import reference
    table = ((0.0, 0.013, 0.2, 0.237), (0.0, 24.0, 24.0, 30.0))
    names = [f"mechanism.{n}" for n in ("phi1", "phi2", "phi3", "phi4", "omega1", "omega2",
                                        "omega3", "omega4")] + ["motor.current"]
    spec = system_spec(fmu_path, motor_path, stop=0.5, design={"mechanism.d34": {"values": [1.0]}})
    spec["system"]["coupling_tolerance"] = 1e-5
    spec["scenario"]["step"] = 0.01
    spec["scenario"]["inputs"] = {"motor.voltage": {"times": list(table[0]), "values": list(table[1])}}
    spec["outputs"]["series"] = {"variables": names}
    results = run_sweep(spec, out=tmp_path / "out", serial=True, progress=False, plots=False)
    assert results.points.iloc[0]["status"] == "ok", results.points.iloc[0]["message"]
    series = results.series()
    columns = [series[series["variable"] == v].sort_values("time") for v in names]
    times = columns[0]["time"].to_numpy()
    mine = np.column_stack([c["value"].to_numpy() for c in columns])
    p = reference.Params(**MECHANISM, d34=1.0)
    exact = reference.solve_with_motor(p, reference.Motor(V_table=table), times, rtol=1e-11)
    error = float((np.abs(mine - exact) / np.maximum(1.0, np.abs(exact).max(axis=0))).max())
    assert error <= 3e-5, error
