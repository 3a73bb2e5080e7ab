"""A coupled communication step costs only what it needs: driven by the compiled DC motor
(a new torque at every step), the mechanism takes its short steps, about five right-hand
sides per step at H = 1 ms, and every output at every communication point stays within
the bound each row of the benchmark's grid states, against the same coupled run at tol
1e-12 (in units of each output's scale max(1, max |y|), as the accuracy benchmark
measures): the tolerance itself, but for the three rows where DOP853 takes the coupled
steps and the feedback through the motor carries its run a little further from the
1e-12 one (H = 5 ms at tol 1e-10, 10 ms at 1e-8 and 1e-10)."""

import sys

import numpy as np
import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "bench"))
from bench_coupled_step import OUTPUTS, coupled_run  # noqa: E402

# The benchmark's 10 s: the motor's run-up, the mechanism settling to its cycle, and the
# cycles after (where the run at H = 5 ms once missed the tolerance).
STOP = 10.0


@pytest.fixture(scope="module")
def references(fmu_path, motor_path):
    return {step: coupled_run(fmu_path, motor_path, step, 1e-12, STOP)[0]
            for step in sorted({case[0] for case in CASES})}


# (H, tol, most right-hand sides per communication step, most error in units of tol): the
# benchmark's whole grid. At H = 1 and 2 ms (tol 1e-6) and 5 ms (tol 1e-6, two steps per
# communication step) the short steps take the coupled steps (the run-up's first steps cost
# more than the 10 s average); elsewhere DOP853 does, as before them, and at H = 5 ms,
# tol 1e-10 and at 10 ms, tol 1e-8 and 1e-10 its coupled run departs from the 1e-12 one by
# more than tol (the same before the short steps): those rows hold their measured excess,
# with a tenth to spare, so that a change making them worse fails.
CASES = [(1e-3, 1e-6, 4.05, 1.0), (1e-3, 1e-8, 5.0, 1.0), (1e-3, 1e-10, 16.1, 1.0),
         (2e-3, 1e-6, 4.1, 1.0), (2e-3, 1e-8, 16.1, 1.0), (2e-3, 1e-10, 16.1, 1.0),
         (5e-3, 1e-6, 8.5, 1.0), (5e-3, 1e-8, 16.1, 1.0), (5e-3, 1e-10, 16.2, 2.6),
         (1e-2, 1e-6, 17.0, 1.0), (1e-2, 1e-8, 17.0, 1.3), (1e-2, 1e-10, 19.0, 1.7)]


@pytest.mark.parametrize("step, tol, most_rhs, most_error", CASES)
def test_a_coupled_step_costs_what_it_needs_and_stays_within_its_rows_bound(
        fmu_path, motor_path, references, step, tol, most_rhs, most_error):
    rows, rhs, _ = coupled_run(fmu_path, motor_path, step, tol, STOP)
    reference = references[step]
    scale = np.maximum(1.0, np.abs(reference).max(axis=0))
    error = np.abs(rows - reference) / scale / tol
    worst = np.unravel_index(np.argmax(error), error.shape)
    assert error[worst] <= most_error, f"{OUTPUTS[worst[1]]} at t = {(worst[0] + 1) * step:g}: {error[worst]:.3f} tol"
    assert rhs <= most_rhs, f"{rhs:.2f} right-hand sides per communication step"
