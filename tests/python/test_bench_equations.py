"""The benchmark's scipy baseline integrates the same equations as the reference.

`cargo xtask test` runs the benchmark harness only for the FMU; this keeps bench.py's
plain-Python right-hand side honest without a benchmark run.
"""

import dataclasses
import pathlib
import sys

import numpy as np
import pytest

import reference

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "bench"))
import bench  # noqa: E402


def states_on_the_orbit(p):
    """The initial state, and one later (velocities and twists all nonzero)."""
    return [reference.initial_state(p), reference.solve(p, np.array([0.0, 0.7]), rtol=1e-10)[-1]]


@pytest.mark.parametrize("name", sorted(bench.SCENARIOS))
def test_the_scipy_baseline_has_the_reference_equations(name):
    p = reference.Params(**bench.SCENARIOS[name]["values"])
    for y in states_on_the_orbit(p):
        bench.check_spec_rhs(p, y)


def test_the_check_sees_a_different_model(monkeypatch):
    p = reference.Params(**bench.SCENARIOS["case1"]["values"])
    stiffer = dataclasses.replace(p, k12=1.01 * p.k12)
    real = bench.spec_rhs
    monkeypatch.setattr(bench, "spec_rhs", lambda _: real(stiffer))
    with pytest.raises(ValueError, match="spec_rhs differs"):
        bench.check_spec_rhs(p, states_on_the_orbit(p)[1])
