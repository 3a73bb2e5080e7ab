"""The coupling example (issue 5 §7) runs and reaches the steady state physics predicts."""

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
