"""The FMU's physics against an independent reference, the published values of docs/model.md §4, and the
energy laws of docs/model.md §2; all through FMPy with the packed FMU."""

import numpy as np
import pytest
from scipy.integrate import simpson

import reference
from conftest import simulate, states

SPEC_CASE_1_AT_10S = dict(phi1=41.24994319, phi2=41.25007318, phi3=1.71429998,
                          phi4=1.60546713, omega1=4.12779271)


@pytest.fixture(scope="session")
def paper_runs(unzipped):
    """Both paper cases: FMU at tolerance 1e-10 and the reference at 1e-12, every 0.01 s."""
    times = np.linspace(0.0, 10.0, 1001)
    runs = {}
    for case, k34 in (("case1", 100.0), ("case2", 40.0)):
        values = dict(reference.PAPER_LAWS, k34=k34)
        fmu = simulate(unzipped, values, 10.0, 0.01)
        expected = reference.solve(reference.Params(**values), times)
        runs[case] = (fmu, expected)
    return runs


# What this build measured (docs/bench/accuracy.md quotes the runs of `cargo xtask
# accuracy`): each figure below is held to HELD_MARGIN times it, so that a regression shows
# long before the promises (1e-6, 1e-12 m, 1e-8) are broken, and a document quoting the
# report cannot fall far from what the tests see.
HELD_MARGIN = 4
MEASURED = {"case1": 5.13e-10, "case2": 1.24e-9, "residual_m": 6.22e-16, "free_run_drift": 1.93e-10}


@pytest.mark.parametrize("case", ["case1", "case2"])
def test_paper_case_matches_independent_reference(paper_runs, case, report):
    fmu, expected = paper_runs[case]
    np.testing.assert_allclose(fmu["time"], np.linspace(0.0, 10.0, 1001), atol=1e-12)
    error = np.abs(states(fmu) - expected)
    report[f"{case}_max_error_rad_or_rad_per_s"] = float(error.max())
    report[f"{case}_final_error"] = float(error[-1].max())
    assert error.max() < HELD_MARGIN * MEASURED[case], f"{case}: max deviation {error.max():.3e}"
    # The run is not trivial: the motor spins up to about 4.1 rad/s (docs/model.md §4).
    assert 4.0 < fmu["omega1"][-1] < 4.3


def test_case_1_matches_spec_published_values(paper_runs):
    fmu, _ = paper_runs["case1"]
    for name, value in SPEC_CASE_1_AT_10S.items():
        assert abs(fmu[name][-1] - value) < 2e-8, (name, fmu[name][-1], value)


@pytest.mark.parametrize("case", ["case1", "case2"])
def test_constraint_residual_at_every_communication_point(paper_runs, case, report):
    fmu, _ = paper_runs[case]
    worst = float(np.max(np.abs(fmu["constraint_residual"])))
    report[f"{case}_max_constraint_residual_m"] = worst
    assert worst < HELD_MARGIN * MEASURED["residual_m"]


def test_rod_force_against_reference_multiplier(paper_runs):
    """rod_force = −λ·L, with λ recomputed from the reference formulation's 5×5 solve."""
    fmu, expected = paper_runs["case1"]
    p = reference.Params(**reference.PAPER_LAWS)
    for i in range(0, 1001, 50):
        y = states(fmu)[i]
        A2, A3, u2, u3, n2, n3 = reference.pins(p, y[1], y[2])
        d = A2 - A3
        G = np.array([0.0, d @ (p.l2 * n2), -(d @ (p.l3 * n3)), 0.0])
        w_dot = reference.rhs(0.0, y, p)[4:]
        motor, load = reference.torques(p, y[4])
        Q = np.array([motor + p.k12 * (y[1] - y[0]), -p.k12 * (y[1] - y[0]),
                      -p.k34 * (y[2] - y[3]), p.k34 * (y[2] - y[3]) - load])
        lam = np.linalg.lstsq(G[:, None], np.diag(p.J) @ w_dot - Q, rcond=None)[0][0]
        assert abs(fmu["rod_force"][i] - (-lam * p.L)) < 1e-6 * max(1.0, abs(lam)), i


FREE_RUN = reference.FREE_RUN


def test_free_undamped_run_conserves_energy(unzipped, report):
    result = simulate(unzipped, FREE_RUN, 100.0, 0.01)
    energy = result["energy"]
    e0 = reference.energy(reference.Params(**FREE_RUN), reference.initial_state(reference.Params(**FREE_RUN)))
    assert abs(energy[0] - e0) < 1e-12 * e0
    drift = float(np.max(np.abs(energy - e0)) / e0)
    report["free_run_100s_relative_energy_drift"] = drift
    assert drift < HELD_MARGIN * MEASURED["free_run_drift"]
    residual = float(np.max(np.abs(result["constraint_residual"])))
    report["free_run_100s_max_constraint_residual_m"] = residual
    assert residual < HELD_MARGIN * MEASURED["residual_m"]
    # Energy moves between the springs and the bodies: the run is not at rest.
    assert np.ptp(result["omega1"]) > 1.0


def test_energy_balance_with_torques_and_dampers(unzipped, report):
    """E(t) − E(0) = ∫ dE/dt, with dE/dt of docs/model.md §2 from the outputs (Simpson's rule)."""
    values = dict(reference.PAPER_LAWS, d12=0.5, d34=0.8, c4=0.3, M_m=3.0, M_r=-1.0)
    step = 1e-3
    result = simulate(unzipped, values, 5.0, step)
    p = reference.Params(**values)
    w1, w2, w3, w4 = (result[f"omega{i}"] for i in range(1, 5))
    motor, load = reference.torques(p, w1)
    power = motor * w1 - (load + p.c4 * w4) * w4 - p.d12 * (w2 - w1) ** 2 - p.d34 * (w3 - w4) ** 2
    work = simpson(power, x=result["time"])
    gained = result["energy"][-1] - result["energy"][0]
    scale = simpson(np.abs(power), x=result["time"])
    report["energy_balance_relative_error"] = float(abs(gained - work) / scale)
    assert abs(gained - work) < 1e-7 * scale, (gained, work, scale)
    assert scale > 10.0  # torques and dampers really did work
