"""The bouncing ball's FMUs, written here in C as subjects with known solutions (the
ball's exact motion, tests/python/test_sweep_events.py): each passes FMPy's checks of its
model description, and the Model Exchange ones (FMI 2.0 and 3.0), integrated by FMPy's
CVODE, follow the exact motion through every bounce and the kick."""

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from test_sweep_events import DV, exact

CASES = [(0.5, 0.5), (0.7, 1.234), (0.9, 2.0)]


def test_every_ball_passes_fmpys_checks(ball_path, ball_me_paths):
    for path in (ball_path, *ball_me_paths.values()):
        assert validate_fmu(str(path)) == [], path


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("e, t_kick", CASES)
def test_model_exchange_follows_the_exact_motion_under_cvode(ball_me_paths, version, e, t_kick):
    r = fmpy.simulate_fmu(str(ball_me_paths[version]), fmi_type="ModelExchange",
                          start_values={"e": e, "t_kick": t_kick, "dv": DV}, stop_time=3.0,
                          output_interval=0.01, relative_tolerance=1e-10,
                          output=["h", "v", "n_bounces", "n_kicks"], record_events=False)
    want = exact(e, t_kick, r["time"])
    # CVODE locates each bounce to its tolerance: the motion after it is that close.
    assert np.abs(r["h"] - want[:, 0]).max() < 1e-6
    assert np.abs(r["v"] - want[:, 1]).max() < 1e-5
    assert (r["n_bounces"][-1], r["n_kicks"][-1]) == tuple(want[-1, 2:])
    assert r["n_bounces"][-1] >= 2
