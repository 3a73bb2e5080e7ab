"""The FMU's parameter sensitivities (docs/sensitivities.md) as FMPy's users read them:
slots set as start values, the sensitivity locals recorded like any variable, in both
FMI versions' archives."""

import fmpy
import numpy as np
import pytest

from conftest import simulate

K34 = 6  # the SensitivityParameter item k34: its value in the model description
CASE = {"d12": 0.5, "d34": 0.5}


def items(unzipped):
    md = fmpy.read_model_description(unzipped)
    slot = next(v for v in md.modelVariables if v.name == "sensitivity_1.parameter")
    return {item.name: int(item.value) for item in slot.declaredType.items}


def test_the_slots_items_name_the_parameters(unzipped):
    assert items(unzipped)["k34"] == K34
    assert "L" not in items(unzipped)


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_a_slot_read_through_fmpy_is_the_derivative_of_the_run(version, unzipped, unzipped3):
    path = unzipped if version == "2.0" else unzipped3
    outputs = ["omega2", "phi3", "sensitivity_1.omega2", "sensitivity_1.phi3"]
    run = fmpy.simulate_fmu(path, start_values={**CASE, "sensitivity_1.parameter": K34},
                            stop_time=5.0, output_interval=0.05, relative_tolerance=1e-10,
                            output=outputs)
    delta = 1e-3
    up, down = (simulate(unzipped, {**CASE, "k34": 100.0 + s * delta}, 5.0, 0.05, 1e-12,
                         ["omega2", "phi3"]) for s in (1, -1))
    for name in ("omega2", "phi3"):
        difference = (up[name] - down[name]) / (2 * delta)
        error = np.max(np.abs(run[f"sensitivity_1.{name}"] - difference))
        # The central difference's own truncation error is about 1e-6 of its scale here.
        assert error <= 1e-5 * np.max(np.abs(difference)), (name, error)
    # Asking for them changes no output.
    plain = fmpy.simulate_fmu(path, start_values=CASE, stop_time=5.0, output_interval=0.05,
                              relative_tolerance=1e-10, output=["omega2", "phi3"])
    assert np.array_equal(plain["omega2"], run["omega2"])


def test_model_exchange_refuses_a_slot(unzipped):
    with pytest.raises(Exception, match="ExitInitializationMode|status 3"):
        fmpy.simulate_fmu(unzipped, fmi_type="ModelExchange", stop_time=1.0,
                          start_values={"sensitivity_1.parameter": K34})
