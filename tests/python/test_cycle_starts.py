"""The steady cycle through the FMU's Co-Simulation interface, its start values and its own
sensitivities to them (``cycle.starts``, docs/cycle.md): the same cycle, multipliers and
modes as the shooting on Model Exchange, from fewer runs; points without a cycle say why;
mistakes are refused by field, all in one run."""

import math

import numpy as np
import pytest

from fmusweep import SpecError, run_sweep
from sweep_helpers import stopped_mid_way

TAU = 2 * math.pi
STARTS = ["twist12_0", "twist34_0", "omega1_0", "omega2_0", "omega4_0"]
EXCHANGE = {"state": "loop_angle", "advance": TAU, "shifted": ["phi1"]}
THROUGH_STARTS = {"state": "phi2", "advance": TAU, "shifted": ["phi1"], "starts": STARTS}
METRICS = {"peak": {"variable": "rod_force", "kind": "max"},
           "swing": {"variable": "rod_force", "kind": "peak_to_peak"},
           "speed": {"variable": "omega2", "kind": "mean"},
           "rms": {"variable": "rod_force", "kind": "rms"},
           "third": {"variable": "rod_force", "kind": "harmonic", "order": 3}}


def listed(**columns):
    return {"kind": "list", "parameters": {k: {"values": v} for k, v in columns.items()}}


def spec_of(cycle, design, parameters, metrics=None, stop=100.0):
    return {"scenario": {"stop": stop, "step": 0.01, "tolerance": 1e-9,
                         "parameters": parameters},
            "design": design, "cycle": cycle,
            "outputs": {"metrics": METRICS if metrics is None else metrics}}


def sweep(spec, fmu, out):
    return run_sweep(spec, fmu=fmu, out=out, serial=True, progress=False, plots=False)


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_through_the_start_values_is_the_model_exchange_cycle(fmu_path, fmu3_path, tmp_path,
                                                              version):
    """Over a row of motor constants, continued from point to point: the metrics, the
    period, the state on the section, the multipliers and the modes along the cycle agree
    with the shooting on Model Exchange within 1e-7 (the multipliers and modes 1e-6),
    from fewer runs over the cycle."""
    fmu = fmu_path if version == "2.0" else fmu3_path
    design = listed(Mm_a0=[80.0, 95.0, 110.0, 125.0])
    parameters = {"d12": 0.1, "d34": 0.1}
    exchange = sweep(spec_of({**EXCHANGE, "modes": 4}, design, parameters), fmu,
                     tmp_path / "exchange").points
    starts = sweep(spec_of({**THROUGH_STARTS, "modes": 4}, design, parameters), fmu,
                   tmp_path / "starts").points
    assert (starts["status"] == "ok").all(), list(starts["message"])
    assert (exchange["status"] == "ok").all(), list(exchange["message"])
    for name in [*METRICS, "cycle_period", "cycle_multiplier"]:
        a, b = exchange[name].to_numpy(), starts[name].to_numpy()
        assert np.abs(a - b).max() <= 1e-7 * np.abs(a).max(), (name, a, b)
    for (_, e), (_, s) in zip(exchange.iterrows(), starts.iterrows()):
        for part in ("re", "im"):
            a, b = (np.asarray(p[f"cycle_multipliers_{part}"]) for p in (e, s))
            assert len(a) == len(b) == 5 and np.abs(a - b).max() <= 1e-6, (part, a, b)
        for part in ("hz", "damping"):
            a, b = (np.asarray(p[f"cycle_modes_{part}"]) for p in (e, s))
            assert np.abs(a - b).max() <= 1e-6 * np.abs(a).max(), (part, a, b)
        # The state on the section: Model Exchange's (phi1, loop_angle, phi4, omega1,
        # loop_speed, omega4) against the closing variables (phi1 … phi4, omega1 … omega4).
        x, y = e["cycle_state"], s["cycle_state"]
        pairs = [(x[2], y[3]), (x[3], y[4]), (x[4], y[5]), (x[5], y[7]), (x[0] - x[1], y[0] - y[1])]
        assert all(abs(a - b) <= 1e-7 * max(1.0, abs(a)) for a, b in pairs), pairs
        assert s["cycle_mode"].startswith("omega4"), s["cycle_mode"]
    assert list(starts["cycle_continued"]) == [False, True, True, True]
    assert starts["cycle_runs"].sum() < exchange["cycle_runs"].sum()


def test_through_the_start_values_points_without_a_cycle_say_why(fmu_path, tmp_path):
    """A conservative run, a free run that dies away, a change-point linkage: rows that say
    why, with no number in a metric or a cycle column; the good point beside them runs."""
    spec = spec_of(THROUGH_STARTS,
                   listed(builtin_laws=[False, False, False, True], d34=[0.0, 0.5, 0.0, 0.05],
                          L=[0.7, 0.7, 0.95, 0.7]),
                   {"omega1_0": 4.0, "omega2_0": 4.0, "phi2_0": math.pi / 2},
                   metrics={"swing": METRICS["swing"]}, stop=60.0)
    points = sweep(spec, fmu_path, tmp_path / "out").points
    assert list(points["status"]) == ["no_cycle", "no_cycle", "no_cycle", "ok"]
    said = list(points["message"])
    assert "unit circle" in said[0] and "undamped" in said[0]
    assert "did not converge" in said[1] or "did not advance" in said[1]
    assert "change_point" in said[2]
    failed = points.iloc[:3]
    assert failed["swing"].isna().all() and failed["cycle_period"].isna().all()
    assert points["swing"].iloc[3] > 0


def test_start_values_that_do_not_set_the_state_say_so(fmu_path, tmp_path):
    """A parameter the FMU offers sensitivities to that is no start value (an inertia):
    its column of the sensitivities at the start is zero, and the row says which values
    do not move the state on the section."""
    cycle = {**THROUGH_STARTS, "starts": ["twist12_0", "twist34_0", "omega1_0", "J1",
                                          "omega4_0"]}
    point = sweep(spec_of(cycle, listed(d34=[0.2]), {"d12": 0.2}), fmu_path,
                  tmp_path / "out").points.iloc[0]
    assert point["status"] == "no_cycle"
    assert "do not move the state on the section independently" in point["message"]
    assert "J1" in point["message"]


def test_mistakes_through_the_start_values_are_refused_by_field_in_one_run(fmu_path,
                                                                         motor_path,
                                                                         tmp_path):
    cycle = {"state": "loop_angle", "advance": TAU, "shifted": ["phi9"],
             "starts": ["J9", "l", "twist12_0", "twist12_0"], "monodromy": "differences"}
    with pytest.raises(SpecError) as raised:
        sweep(spec_of(cycle, listed(d34=[0.2]), {}), fmu_path, tmp_path / "out")
    fields = {e.field: e.rule for e in raised.value.errors}
    assert set(fields) == {"cycle.monodromy", "cycle.starts[0]", "cycle.starts[1]",
                           "cycle.starts[3]", "cycle.starts", "cycle.state",
                           "cycle.shifted[0]"}, fields
    assert "offers no sensitivity to 'J9'" in fields["cycle.starts[0]"]
    assert "twist34_0" in fields["cycle.starts[1]"]  # what it offers, listed
    assert "named twice" in fields["cycle.starts[3]"]
    assert "5 free coordinates" in fields["cycle.starts"]
    assert "phi2" in fields["cycle.state"] and "close the cycle" in fields["cycle.state"]
    assert 'no variable named "phi9": did you mean phi1?' in fields["cycle.shifted[0]"]
    assert not (tmp_path / "out").exists()
    # The interface the spec asks for must be the one the cycle runs through.
    spec = spec_of(THROUGH_STARTS, listed(d34=[0.2]), {})
    spec["scenario"]["interface"] = "model_exchange"
    with pytest.raises(SpecError) as raised:
        sweep(spec, fmu_path, tmp_path / "out")
    assert raised.value.field == "scenario.interface"
    assert "Co-Simulation" in raised.value.rule
    # An FMU that offers no sensitivities.
    spec = spec_of({**THROUGH_STARTS, "state": "w"}, listed(R=[1.0]), {}, metrics={})
    with pytest.raises(SpecError) as raised:
        sweep(spec, motor_path, tmp_path / "out")
    fields = {e.field: e.rule for e in raised.value.errors}
    assert "offers no sensitivities" in fields["cycle.starts"]
    assert "no variable named \"w\"" in fields["cycle.state"]


def test_through_the_start_values_a_cycle_keeps_to_the_points_time_budget(fmu_path,
                                                                         tmp_path):
    """scenario.timeout stops a search through the start values where it is, mid-way."""
    spec = spec_of(THROUGH_STARTS, listed(d34=[0.05]), {}, metrics={"swing": METRICS["swing"]})
    spec["scenario"]["tolerance"] = 1e-10
    free, budget, row = stopped_mid_way(spec, fmu_path, tmp_path)
    assert row["status"] == "timeout" and row["message"].startswith("over the budget of")
    assert budget <= row["wall_s"] < 0.9 * free["wall_s"], (budget, row["wall_s"], free["wall_s"])
    assert np.isnan(row["swing"])