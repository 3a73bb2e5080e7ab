"""FMI 3.0's model description (generated from the variable table, packed in
CyclicMechanism-fmi3.fmu) against FMPy's validation (the FMI 3.0 schema,
variable names, the model structure) and against the FMI 2.0 description of the FMU
under test: the same variables with their value references plus one after `time`, the
same attributes, the same dependencies."""

from xml.etree import ElementTree

import pytest
from fmpy import read_model_description

from conftest import ROOT

XML = ROOT / "modelDescription/fmi3/modelDescription.xml"
TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "Enumeration": "Enumeration"}


@pytest.fixture(scope="module")
def fmi3():
    return read_model_description(str(XML), validate=True, validate_variable_names=True,
                                  validate_model_structure=True)


def test_fmpy_validates_it(fmi3):
    assert fmi3.fmiVersion == "3.0"
    assert fmi3.instantiationToken.startswith("{")
    time = fmi3.modelVariables[0]
    assert (time.name, time.valueReference, time.causality, time.unit) == ("time", 0, "independent", "s")


def test_the_variables_are_fmi2s_one_reference_later(fmi3, model_description):
    fmi2 = {v.name: v for v in model_description.modelVariables}
    variables = fmi3.modelVariables[1:]
    assert [v.name for v in variables] == [v.name for v in model_description.modelVariables]
    for v in variables:
        old = fmi2[v.name]
        assert v.valueReference == old.valueReference + 1, v.name
        assert v.type == TYPES[old.type], v.name
        same = ("causality", "variability", "initial", "unit", "displayUnit", "min", "max")
        assert [getattr(v, a) for a in same] == [getattr(old, a) for a in same], v.name
        if old.start is not None:
            assert float(v.start) == float(old.start) if old.type != "Boolean" else v.start == old.start
        if old.derivative is not None:
            assert v.derivative.name == old.derivative.name, v.name


def test_the_model_structure_is_fmi2s(fmi3, model_description):
    def listed(unknowns):
        return [(u.variable.name, sorted(d.name for d in (u.dependencies or [])),
                 sorted(u.dependenciesKind or [])) for u in unknowns]

    assert listed(fmi3.outputs) == listed(model_description.outputs)
    assert listed(fmi3.derivatives) == listed(model_description.derivatives)
    assert listed(fmi3.initialUnknowns) == listed(model_description.initialUnknowns)
    assert [(u.variable.name, [d.name for d in u.dependencies]) for u in fmi3.eventIndicators] == [
        ("handover_indicator", ["loop_angle"])]
    assert model_description.numberOfEventIndicators == len(fmi3.eventIndicators)


def test_capabilities_are_those_provided(model_description):
    """Declared: FMU states, their serialization, directional and adjoint derivatives,
    variable steps and output derivatives to order 2; in Co-Simulation event mode and a
    step that may return early (at a change point). Not declared, because not provided:
    intermediate update, per-element dependencies, evaluation of discrete states."""
    root = ElementTree.parse(XML).getroot()
    common = {"needsExecutionTool": "false", "canBeInstantiatedOnlyOncePerProcess": "false",
              "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
              "providesDirectionalDerivatives": "true", "providesAdjointDerivatives": "true",
              "modelIdentifier": "CyclicMechanism"}
    assert root.find("ModelExchange").attrib == dict(common, needsCompletedIntegratorStep="false")
    assert root.find("CoSimulation").attrib == dict(
        common, canHandleVariableCommunicationStepSize="true", maxOutputDerivativeOrder="2",
        mightReturnEarlyFromDoStep="true", hasEventMode="true")
    assert model_description.coSimulation.providesDirectionalDerivative
    assert model_description.coSimulation.maxOutputDerivativeOrder == 2