"""The coupling example runs and reaches the steady state physics predicts."""

import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples/dc_motor"))
import coupling  # noqa: E402


def test_dc_motor_runs_the_mechanism_below_its_no_load_speed(fmu_path, tmp_path):
    result = coupling.run(fmu_path, tmp_path, stop_time=4.0)
    assert (tmp_path / "coupling.png").exists() and (tmp_path / "coupling.csv").exists()
    last = result["time"] > 3.0
    speed, current = np.mean(result["omega1"][last]), np.mean(result["current"][last])
    # The motor runs up towards its no-load speed V/k = 12 rad/s and stays below it on
    # average, drawing a positive mean current: it supplies the power the dampers consume.
    assert 0.7 * 12.0 < speed < 12.0, speed
    assert current > 0.1, current
    assert result["omega1"][0] == 0.0 and np.all(np.isfinite(result["rod_force"]))


def test_ssp_description_of_the_same_system_runs_in_fmpy_and_agrees(fmu_path, tmp_path):
    import ssp  # examples/dc_motor/ssp.py

    scripted = coupling.run(fmu_path, tmp_path / "script", stop_time=1.0)
    packaged = ssp.run(fmu_path, tmp_path / "ssp", stop_time=1.0)
    assert (tmp_path / "ssp" / "MotorDrivenMechanism.ssp").exists()
    # simulate_ssp records each row after the step; the script records before it.
    after_step = np.array(packaged["mechanism.omega1"][:-1])
    assert len(after_step) == len(scripted["omega1"]) - 1
    # Identical at first; the script sets a stop time and FMPy's SSP runner does not, so
    # the integrator's steps near the end differ: agreement at the tolerance's (1e-8) level.
    assert np.max(np.abs(after_step - scripted["omega1"][1:])) < 1e-7
    assert np.max(np.abs(np.array(packaged["motor.current"][:-1]) - scripted["current"][1:])) < 1e-7
