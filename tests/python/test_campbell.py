"""The Campbell diagram of a sweep of steady cycles is a function of one speed-like
parameter: a curve per slice of the design's other parameters, each with its own
crossings, along the parameter that orders the cycles' frequencies in every slice; none
where no parameter does, with a caption that says why."""

import numpy as np
import pandas as pd
import pytest

from fmusweep.show.campbell import campbell


def grid_points(speeds, stiffnesses):
    """A 2-D grid: the cycle's frequency grows with the speed; the mode's frequency grows
    with the stiffness alone (a spring mode), so each slice has its own crossings."""
    rows = []
    for i, k in enumerate(stiffnesses):
        for j, a in enumerate(speeds):
            rows.append({"point": i * len(speeds) + j, "Mm_a0": a, "k34": k,
                         "cycle_period": 1.0 / (0.01 * a),
                         "cycle_modes_hz": [np.sqrt(k) / 5.0, 3.6]})
    return pd.DataFrame(rows)


def test_a_grid_draws_a_curve_per_slice_with_its_own_crossings():
    points = grid_points(np.linspace(60, 200, 15), [60.0, 100.0, 160.0])
    diagram = campbell(points, ["Mm_a0", "k34"])
    assert diagram.along == "Mm_a0"
    assert [s.label for s in diagram.slices] == ["k34 = 60", "k34 = 100", "k34 = 160"]
    assert "one curve per k34" in diagram.caption
    for piece, k in zip(diagram.slices, [60.0, 100.0, 160.0]):
        mode = np.sqrt(k) / 5.0
        # Order 2 meets the spring's mode where twice the cycle's frequency is the mode's.
        crossings = [c for c in piece.crossings if c[2] == 2 and abs(c[1] - mode) < 0.2]
        assert len(crossings) == 1, piece.crossings
        assert crossings[0][0] == pytest.approx(mode / 2, rel=1e-9)
        assert list(piece.cycle_hz) == sorted(piece.cycle_hz)
    # No crossing lies at a frequency no slice has: each slice's are its own.
    spring = {round(c[1], 6) for s in diagram.slices for c in s.crossings if c[1] < 3.0}
    assert spring == {round(np.sqrt(k) / 5.0, 6) for k in [60.0, 100.0, 160.0]}


def test_the_parameter_that_orders_the_cycles_is_chosen_whatever_its_place():
    points = grid_points(np.linspace(60, 200, 6), [60.0, 100.0])
    diagram = campbell(points, ["k34", "Mm_a0"])
    assert diagram.along == "Mm_a0" and len(diagram.slices) == 2


def test_no_diagram_where_no_parameter_orders_the_cycles():
    """Scattered points (a design whose cycle frequency goes up and down along every
    parameter): no curve, and a caption that says why."""
    rng = np.random.default_rng(3)
    a, b = rng.uniform(0, 1, 30), rng.uniform(0, 1, 30)
    points = pd.DataFrame({"point": range(30), "x": a, "y": b,
                           "cycle_period": 1.0 / (1.0 + np.sin(9 * a) + np.cos(7 * b)),
                           "cycle_modes_hz": [[2.0]] * 30})
    diagram = campbell(points, ["x", "y"])
    assert diagram.slices == [] and "no design parameter" in diagram.caption


def test_many_slices_are_spread_and_counted():
    points = grid_points(np.linspace(60, 200, 5), list(np.linspace(40, 200, 20)))
    diagram = campbell(points, ["Mm_a0", "k34"])
    assert len(diagram.slices) == 8 and "8 of 20 slices" in diagram.caption
