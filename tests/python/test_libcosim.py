"""An independent master: the same scenario through OSP libcosim
(libcosimpy; integer-nanosecond time) and through FMPy agree within the solver tolerance,
and both match the independent reference."""

import numpy as np
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

import reference
from conftest import simulate, states

STATES = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4"]
STEP_NS = 10_000_000  # 0.01 s
STOP_NS = 10_000_000_000  # 10 s


def run_libcosim(fmu_path, values):
    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_step_size(step_size=STEP_NS)
    index = execution.add_local_slave(local_slave=CosimLocalSlave(fmu_path=str(fmu_path), instance_name="mechanism"))
    refs = {v.name.decode() if isinstance(v.name, bytes) else v.name: v.reference
            for v in execution.slave_variables(index)}
    for name, value in values.items():
        execution.real_initial_value(slave_index=index, variable_reference=refs[name], value=value)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    assert execution.simulate_until(target_time=STOP_NS)
    assert execution.status().current_time == STOP_NS
    return np.array(observer.last_real_values(slave_index=index, variable_references=[refs[n] for n in STATES]))


def test_libcosim_and_fmpy_agree(fmu_path, unzipped, report):
    values = dict(reference.PAPER_LAWS)
    cosim = run_libcosim(fmu_path, values)
    fmpy_run = states(simulate(unzipped, values, 10.0, 0.01, tolerance=1e-8))[-1]
    exact = reference.solve(reference.Params(**values), np.array([0.0, 10.0]))[-1]
    report["libcosim_vs_fmpy_max_difference"] = float(np.max(np.abs(cosim - fmpy_run)))
    report["libcosim_vs_reference_max_error"] = float(np.max(np.abs(cosim - exact)))
    # Both at the default tolerance 1e-8: agreement at the tolerance's level, in units of
    # each component's scale.
    scaled = np.abs(cosim - fmpy_run) / np.maximum(1.0, np.abs(exact))
    report["libcosim_vs_fmpy_scaled_difference"] = float(scaled.max())
    assert scaled.max() < 10 * 1e-8
    assert np.max(np.abs(cosim - fmpy_run)) < 1e-6
    assert np.max(np.abs(cosim - exact)) < 1e-6
    assert 4.0 < cosim[4] < 4.3  # the motor did spin up


def test_libcosim_chooses_the_implicit_method_through_the_integer_twin(fmu_path, unzipped):
    """libcosim lists no Enumeration variable, so its users set `solver_code`, the Integer
    twin of `solver`: 3 runs the implicit method, as `solver = 3` does in FMPy."""
    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_step_size(step_size=STEP_NS)
    index = execution.add_local_slave(local_slave=CosimLocalSlave(fmu_path=str(fmu_path),
                                                                  instance_name="mechanism"))
    refs = {v.name.decode() if isinstance(v.name, bytes) else v.name: v.reference
            for v in execution.slave_variables(index)}
    assert "solver" not in refs and "solver_code" in refs
    execution.integer_initial_value(slave_index=index, variable_reference=refs["solver_code"],
                                    value=3)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    assert execution.simulate_until(target_time=1_000_000_000)
    cosim = np.array(observer.last_real_values(slave_index=index,
                                               variable_references=[refs[n] for n in STATES]))
    steps = observer.last_integer_values(slave_index=index, variable_references=[refs["n_steps"]])[0]
    implicit = simulate(unzipped, {"solver": 3}, 1.0, 0.01, tolerance=1e-8,
                        outputs=STATES + ["n_steps"])
    explicit = simulate(unzipped, {}, 1.0, 0.01, tolerance=1e-8, outputs=["n_steps"])
    assert steps == implicit["n_steps"][-1] != explicit["n_steps"][-1]
    scaled = np.abs(cosim - states(implicit)[-1]) / np.maximum(1.0, np.abs(cosim))
    assert scaled.max() < 1e-9, scaled
