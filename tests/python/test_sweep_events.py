"""An FMI 3.0 Co-Simulation FMU with state and time events, written here in C
(examples/bouncing_ball): a ball that bounces (a state event at each contact) and is
kicked at t_kick (a time event). Swept by the runner, which handles each event in the
FMU's event mode, every communication point equals the ball's exact motion, the events
the runner counts are the bounces and the kick, and a kick on a communication point
and one between them both land."""

import numpy as np
import pytest

from fmusweep import SpecError, run_sweep

G, H0, V_MIN, DV = 9.81, 1.0, 0.1, 3.0


def exact(e, t_kick, times, e_after=None, t_change=np.inf):
    """(h, v, bounces, kicks) at each of `times`, event by event in closed form: between
    events h = h0 + v0·τ − g·τ²/2; a contact reverses v times e (at rest below V_MIN), e
    becoming `e_after` from `t_change` on; the kick adds DV to v."""
    rows, t, h, v, bounces, kicks, resting = [], 0.0, H0, 0.0, 0, 0, False
    for target in times:
        while True:
            ground = np.inf if resting else t + (v + np.sqrt(v * v + 2 * G * h)) / G
            kick = t_kick if kicks == 0 and t_kick > t else np.inf
            when = min(ground, kick)
            if when > target:
                break
            if not resting:
                h, v = h + (when - t) * (v - 0.5 * G * (when - t)), v - G * (when - t)
            t = when
            if when == kick:
                v, kicks, resting = v + DV, kicks + 1, resting and v + DV <= 0
            else:
                h, v, bounces = 0.0, -(e if when < t_change else e_after) * v, bounces + 1
                if v < V_MIN:
                    v, resting = 0.0, True
        if not resting:
            h, v = h + (target - t) * (v - 0.5 * G * (target - t)), v - G * (target - t)
        t = target
        rows.append((h, v, bounces, kicks))
    return np.array(rows)


def assert_exact(results, h_within, v_within, e=None, **change):
    """Every point's h and v at every communication point equal the exact motion (e the
    point's own unless given; with `change`, exact()'s e_after and t_change) within the
    bounds, its bounce and kick
    counts equal, and its events are its bounces and kick (each one an event the runner
    handled)."""
    p, series = results.points, results.series()
    times = 0.01 * np.arange(301)
    for point, row in p.iterrows():
        want = exact(row["e"] if e is None else e, row["t_kick"], times, **change)
        mine = series[series["point"] == point]
        h = mine[mine["variable"] == "h"].sort_values("time")["value"].to_numpy()
        v = mine[mine["variable"] == "v"].sort_values("time")["value"].to_numpy()
        np.testing.assert_allclose(h, want[:, 0], rtol=0, atol=h_within)
        np.testing.assert_allclose(v, want[:, 1], rtol=0, atol=v_within)
        assert (row["bounces"], row["kicks"]) == tuple(want[-1, 2:]), row
        assert row["events"] == row["bounces"] + row["kicks"], row


def spec(**design):
    return {"scenario": {"stop": 3.0, "step": 0.01,
                         "parameters": {"h0": H0, "g": G, "v_min": V_MIN, "dv": DV}},
            "design": {"kind": "grid", "parameters": design or {
                "e": {"values": [0.5, 0.7, 0.9]}, "t_kick": {"values": [0.5, 1.234]}}},
            "outputs": {"metrics": {"h_end": {"variable": "h", "kind": "final"},
                                    "bounces": {"variable": "n_bounces", "kind": "final"},
                                    "kicks": {"variable": "n_kicks", "kind": "final"},
                                    "h_max": {"variable": "h", "kind": "max"}},
                        "series": {"variables": ["h", "v"]}}}


def test_every_point_is_the_exact_motion_and_every_event_is_counted(ball_path, tmp_path):
    results = run_sweep(spec(), fmu=ball_path, out=tmp_path / "out", serial=True,
                        progress=False, plots=False)
    p = results.points
    assert (p["status"] == "ok").all(), p["message"]
    assert_exact(results, h_within=1e-12, v_within=1e-11)
    assert (p["kicks"] == 1).all() and (p["bounces"] >= 2).all() and p["events"].sum() > 30
    # More restitution, more height kept: the highest bounce after the kick grows with e.
    assert p.groupby("t_kick")["h_max"].apply(lambda s: s.is_monotonic_increasing).all()


def test_a_value_the_fmu_refuses_is_named_before_anything_runs(ball_path, tmp_path):
    with pytest.raises(SpecError) as refused:
        run_sweep(spec(e={"values": [0.5, 1.5]}), fmu=ball_path, out=tmp_path / "out",
                  serial=True, progress=False, plots=False)
    said = str(refused.value)
    assert "e" in said and "0 <= e < 1" in said, said
