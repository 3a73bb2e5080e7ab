"""SSP files swept natively: the file's components, connections, parameter values and
default experiment become the coupled system a [system] table describes, and the runner
steps it, giving the table's results bit for bit; what the native runner cannot run (a
Python-written component, a nested system, a connection to the system's own connector
or one that transforms its value, an enumeration given by name) is refused by name
before anything runs, and FMPy's path stays available on request."""

import pathlib
import sys

import numpy as np
import pytest

from fmusweep import SpecError, run_sweep
from sweep_helpers import in_description, repacked
from test_sweep_system import MECHANISM, system_spec

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples/dc_motor"))
import ssp as example  # noqa: E402  examples/dc_motor/ssp.py

LOAD = {"Mm_a0": 0.0, "Mm_a1": 0.0, "Mm_a2": 0.0, "Mr_b0": 20.0, "Mr_b1": -0.05, "c4": 0.5,
        "d34": 1.0}  # examples/dc_motor/ssp/load.ssv
METRICS = {"final_omega1": {"variable": "mechanism.omega1", "kind": "final"},
           "peak_current": {"variable": "motor.current", "kind": "peak_abs"}}
DESIGN = {"motor.voltage": {"values": [24.0, 30.0]}, "mechanism.d34": {"values": [1.0, 0.5]}}


@pytest.fixture(scope="module")
def compiled_ssp(fmu_path, motor_path, tmp_path_factory):
    return example.build_ssp(fmu_path, tmp_path_factory.mktemp("ssp"), motor_path)


def ssp_spec(path, stop=1.0, **more):
    spec = {"ssp": str(path), "scenario": {"stop": stop, "step": 0.001, "tolerance": 1e-8},
            "design": {"kind": "list", "parameters": DESIGN},
            "outputs": {"metrics": METRICS,
                        "series": {"variables": ["mechanism.omega1", "motor.current"]}}}
    spec.update(more)
    return spec


def sweep(spec, out):
    return run_sweep(spec, out=out, serial=True, progress=False, plots=False)


def test_an_ssp_file_sweeps_natively_as_its_system_table(compiled_ssp, fmu_path, motor_path,
                                                         tmp_path):
    """The file's load values (load.ssv, never named in the spec) hold; the same system as
    a [system] table with those values set by hand gives the same numbers to the last bit."""
    native = sweep(ssp_spec(compiled_ssp), tmp_path / "ssp")
    table = system_spec(fmu_path, motor_path, stop=1.0, series=True)
    table["scenario"]["parameters"] = {f"mechanism.{k}": v for k, v in LOAD.items() if k != "d34"}
    # In the file's order: where a connection's target gives output derivatives, whether it
    # is passed before or after they are read changes the last digits.
    table["system"]["connections"] = [["mechanism.omega1", "motor.omega"],
                                      ["motor.torque", "mechanism.M_m"]]
    by_table = sweep(table, tmp_path / "table")
    a, b = native.points, by_table.points
    assert list(a["status"]) == ["ok", "ok"], a["message"]
    columns = ["final_omega1", "peak_current", "t_end", "steps"]
    assert a[columns].equals(b[columns])
    assert native.series().equals(by_table.series())
    assert native.meta["ssp_sha256"] and native.meta["spec"]["scenario"]["parameters"]["mechanism.c4"] == 0.5
    # The file's values are the defaults only: the spec's own win.
    heavier = ssp_spec(compiled_ssp)
    heavier["scenario"]["parameters"] = {"mechanism.Mr_b0": 40.0}
    loaded = sweep(heavier, tmp_path / "heavier")
    fixed = loaded.meta["spec"]["scenario"]["parameters"]
    assert fixed["mechanism.Mr_b0"] == 40.0 and fixed["mechanism.c4"] == 0.5
    assert (loaded.points["final_omega1"] != a["final_omega1"]).all()


def test_the_default_experiment_gives_the_stop_time(compiled_ssp, tmp_path):
    spec = ssp_spec(compiled_ssp, design={"kind": "list",
                                          "parameters": {"motor.voltage": {"values": [24.0]}}})
    del spec["scenario"]["stop"]
    p = sweep(spec, tmp_path / "out").points
    assert (p["status"] == "ok").all() and p["t_end"].iloc[0] == 5.0  # stopTime="5"


def test_a_coupling_tolerance_applies_to_an_ssp_system(compiled_ssp, tmp_path):
    spec = ssp_spec(compiled_ssp, system={"coupling_tolerance": 1e-5})
    spec["scenario"]["step"] = 0.01
    p = sweep(spec, tmp_path / "out").points
    assert (p["status"] == "ok").all() and (p["coupling_error"] <= 1e-5).all()


def _ssd_changed(path, directory, old, new):
    def change(name, data):
        return data.replace(old, new) if name == "SystemStructure.ssd" else data
    return repacked(path, directory / "Changed.ssp", change)


NESTED = (b'<ssd:Elements>', b'<ssd:Elements><ssd:System name="inner"/>')
OWN_CONNECTOR = (b'<ssd:Connection startElement="mechanism" startConnector="omega1"',
                 b'<ssd:Connection startConnector="omega1"')
TRANSFORM = (b'endElement="motor" endConnector="omega"/>',
             b'endElement="motor" endConnector="omega"><ssd:LinearTransformation factor="2"/>'
             b'</ssd:Connection>')
MISSING = (b'source="resources/DcMotor.fmu"', b'source="resources/Nothing.fmu"')
ENUMERATION = (b'<ssd:ParameterBinding source="resources/load.ssv" prefix="mechanism."/>',
               b'<ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet '
               b'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
               b'version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="solver">'
               b'<ssv:Enumeration value="implicit"/></ssv:Parameter></ssv:Parameters>'
               b'</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>')


@pytest.mark.parametrize("change, words", [
    (NESTED, ["'inner'", "nested system"]),
    (OWN_CONNECTOR, ["connection 0", "system's own connector 'omega1'"]),
    (TRANSFORM, ["connection 0 (mechanism.omega1 → motor.omega)", "LinearTransformation"]),
    (MISSING, ["component motor", "resources/Nothing.fmu"]),
    (ENUMERATION, ["solver", "Enumeration"]),
], ids=["nested", "own-connector", "transform", "missing", "enumeration"])
def test_what_the_native_runner_cannot_run_is_refused_by_name(compiled_ssp, tmp_path, change,
                                                              words):
    bad = _ssd_changed(compiled_ssp, tmp_path, *change)
    with pytest.raises(SpecError) as refused:
        sweep(ssp_spec(bad), tmp_path / "out")
    assert refused.value.field == "ssp"
    for word in words:
        assert word in str(refused.value), str(refused.value)
    assert not (tmp_path / "out").exists()


def test_a_python_written_component_is_refused_unless_fmpy_is_asked_for(fmu_path, tmp_path):
    python_written = example.build_ssp(fmu_path, tmp_path / "python")
    with pytest.raises(SpecError) as refused:
        sweep(ssp_spec(python_written), tmp_path / "out")
    said = str(refused.value)
    assert refused.value.field == "ssp.components.motor", said
    assert "Python" in said and 'engine = "fmpy"' in said, said
    spec = ssp_spec(python_written, stop=0.05, system={"engine": "fmpy"})
    del spec["outputs"]["series"]
    p = sweep(spec, tmp_path / "fmpy").points
    assert (p["status"] == "ok").all()


def test_a_system_table_beside_an_ssp_file_only_chooses_how_it_runs(compiled_ssp, tmp_path):
    spec = ssp_spec(compiled_ssp, system={"components": {"motor": "x.fmu"}})
    with pytest.raises(SpecError) as refused:
        sweep(spec, tmp_path / "out")
    assert refused.value.field == "system.components"
    with pytest.raises(SpecError, match="system.input_derivatives"):
        sweep(ssp_spec(compiled_ssp, system={"engine": "fmpy", "input_derivatives": 2}),
              tmp_path / "out")


def test_an_ssp_file_fits_as_its_system(compiled_ssp, tmp_path):
    """A fit names the SSP file as a sweep does: the motor's resistance and the load
    spring's damping from the mechanism's speed and the motor's current, made by the same
    file at known values with noise; both 95 % intervals hold the truth."""
    from fmusweep import fit
    columns = ["mechanism.omega1", "motor.current"]
    made = sweep(ssp_spec(compiled_ssp, design={"kind": "list", "parameters": {
        "motor.R": {"values": [0.6]}, "mechanism.d34": {"values": [0.8]}}},
        outputs={"metrics": METRICS, "series": {"variables": columns}}), tmp_path / "made")
    series = made.series()
    rows = np.column_stack([series[series["variable"] == c].sort_values("time")[k].to_numpy()
                            for c, k in ((columns[0], "time"), (columns[0], "value"),
                                         (columns[1], "value"))])[::10]
    rows[:, 1:] += np.random.default_rng(21).normal(0.0, [0.02, 0.05], size=rows[:, 1:].shape)
    np.savetxt(tmp_path / "measured.csv", rows, delimiter=",", header="time," + ",".join(columns),
               comments="")
    spec = {"ssp": str(compiled_ssp), "scenario": {"stop": 1.0, "step": 0.001, "tolerance": 1e-8},
            "data": {"file": str(tmp_path / "measured.csv"),
                     "sigma": {"mechanism.omega1": 0.02, "motor.current": 0.05}},
            "fit": {"parameters": {"motor.R": {"start": 1.0, "range": [0.1, 5.0]},
                                   "mechanism.d34": {"start": 0.3, "range": [0.0, 5.0]}}}}
    summary = fit(spec, out=tmp_path / "out", serial=True, plots=False).summary
    assert summary["status"] == "converged"
    for name, true in {"motor.R": 0.6, "mechanism.d34": 0.8}.items():
        low, high = summary["parameters"][name]["ci95"]
        assert low <= true <= high, (name, low, high)


def test_an_ssp_sweep_on_dask_resumes_what_was_lost(compiled_ssp, tmp_path):
    """On two Dask workers: the same rows as serially; a batch's part lost and the sweep
    resumed, only its points run again."""
    spec = ssp_spec(compiled_ssp, stop=0.5, design={"kind": "grid", "parameters": {
        "motor.voltage": {"values": [20.0, 24.0, 28.0]}, "mechanism.d34": {"values": [0.5, 1.0]}}})
    del spec["outputs"]["series"]
    serial = sweep(spec, tmp_path / "serial").points
    out = tmp_path / "dask"
    first = run_sweep(spec, out=out, workers=2, batch_size=2, progress=False, plots=False)
    columns = ["point", "status", "final_omega1", "peak_current", "t_end", "steps"]
    assert first.points[columns].equals(serial[columns])
    sorted((out / "points").glob("part-*.parquet"))[0].unlink()
    (out / "points.parquet").unlink()
    again = run_sweep(spec, out=out, workers=2, batch_size=2, progress=False, plots=False,
                      resume=True)
    assert again.summary.computed < 6 and again.points[columns].equals(serial[columns])
