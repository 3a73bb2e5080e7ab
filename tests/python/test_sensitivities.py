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


def _fmi3(unzipped3, kind):
    from fmpy.fmi3 import FMU3Model, FMU3Slave
    md = fmpy.read_model_description(unzipped3)
    interface = md.coSimulation if kind is FMU3Slave else md.modelExchange
    fmu = kind(guid=md.instantiationToken, unzipDirectory=unzipped3,
               modelIdentifier=interface.modelIdentifier, instanceName="slots")
    fmu.instantiate()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    return fmu, vr


def test_slots_are_set_in_any_order_and_two_may_follow_one_parameter(unzipped3):
    """A slot's set is judged on its own value: a master may swap two slots one set at a
    time, or point two at one parameter, in Instantiated and in Initialization Mode; two
    slots following k34 give the same column."""
    from fmpy.fmi3 import FMU3Slave
    fmu, vr = _fmi3(unzipped3, FMU3Slave)
    s1, s2 = vr["sensitivity_1.parameter"], vr["sensitivity_2.parameter"]
    k12 = items(unzipped3)["k12"]
    fmu.setInt64([s1, s2], [K34, K34])
    fmu.setInt64([s1, s2], [k12, K34])
    for state in ("instantiated", "initialization"):
        if state == "initialization":
            fmu.enterInitializationMode(tolerance=1e-8)
        fmu.setInt64([s1], [K34])  # for a moment both follow k34
        fmu.setInt64([s2], [k12])
        fmu.setInt64([s2, s1], [K34, k12])
    assert fmu.getInt64([s1, s2]) == [k12, K34]
    fmu.setInt64([s1, s2], [K34, K34])
    fmu.exitInitializationMode()
    for k in range(50):
        fmu.doStep(k * 0.01, 0.01)
    one, two = (fmu.getFloat64([vr[f"sensitivity_{j}.phi3"], vr[f"sensitivity_{j}.omega2"]])
                for j in (1, 2))
    assert one == two and one[0] != 0.0
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_model_exchange_refuses_a_slot_at_its_set_and_every_later_call_goes_on(
        version, unzipped, unzipped3, capsys):
    """Model Exchange has no sensitivities: a slot's parameter is refused at the set that
    asks for it, with the reason; the slot stays 0 and the getters of Initialization Mode
    answer."""
    if version == "2.0":
        from fmpy.fmi2 import FMU2Model
        md = fmpy.read_model_description(unzipped)
        fmu = FMU2Model(guid=md.guid, unzipDirectory=unzipped,
                        modelIdentifier=md.modelExchange.modelIdentifier, instanceName="slots")
        fmu.instantiate()
        vr = {v.name: v.valueReference for v in md.modelVariables}
        with pytest.raises(Exception, match="status 3"):
            fmu.setInteger([vr["sensitivity_1.parameter"]], [K34])
        fmu.setupExperiment(tolerance=1e-8)
        fmu.enterInitializationMode()
        assert fmu.getInteger([vr["sensitivity_1.parameter"]]) == [0]
        assert fmu.getReal([vr["phi3"]])[0] != 0.0
        fmu.exitInitializationMode()
    else:
        from fmpy.fmi3 import FMU3Model
        fmu, vr = _fmi3(unzipped3, FMU3Model)
        with pytest.raises(Exception, match="status 3"):
            fmu.setInt64([vr["sensitivity_1.parameter"]], [K34])
        assert "in Model Exchange the master integrates" in capsys.readouterr().out
        fmu.enterInitializationMode(tolerance=1e-8)
        assert fmu.getInt64([vr["sensitivity_1.parameter"]]) == [0]
        assert fmu.getFloat64([vr["phi3"]])[0] != 0.0
        fmu.exitInitializationMode()
    fmu.terminate()
    fmu.freeInstance()
