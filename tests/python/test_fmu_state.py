"""FMU state: get/set/free and serialization through FMPy, bit for bit, in
the same instance, another instance and another process; bad buffers are refused."""

import ctypes
import json
import subprocess
import sys

import pytest

from test_fmi_api import ERROR, Harness

LAWS = dict(Mm_a0=100.0, Mm_a1=-20.0, Mm_a2=-1.0, Mr_b0=20.0, Mr_b1=-0.05)
WATCH = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4", "rod_force", "energy"]


def started(unzipped, model_description):
    fmu = Harness(unzipped, model_description).instantiate().initialise(**LAWS)
    for k in range(37):  # mid-way through integration steps: dense output in play
        fmu.slave.doStep(k * 0.013, 0.013)
    return fmu


def continue_run(fmu, t0, steps=50, h=0.013, torque=None):
    """Step on from t0 (changing an input half-way), returning every value seen."""
    seen = []
    for k in range(steps):
        if torque is not None and k == steps // 2:
            fmu.set("M_m", torque)
        fmu.slave.doStep(t0 + k * h, h)
        seen.append(list(fmu.get(*WATCH)) + fmu.slave.getInteger([fmu.vr[n] for n in ("n_steps", "n_rhs")]))
    return seen


def test_get_step_set_step_reproduces_bit_for_bit(unzipped, model_description):
    fmu = started(unzipped, model_description)
    t0 = 37 * 0.013
    state = fmu.slave.getFMUstate()
    first = continue_run(fmu, t0, torque=3.0)
    fmu.slave.setFMUstate(state)
    assert fmu.get("M_m") == 0.0, "inputs are part of the state"
    second = continue_run(fmu, t0, torque=3.0)
    assert first == second
    fmu.slave.freeFMUstate(state)
    fmu.free()


def test_serialized_state_restores_in_another_instance(unzipped, model_description):
    source = started(unzipped, model_description)
    t0 = 37 * 0.013
    buffer = source.slave.serializeFMUstate(source.slave.getFMUstate())
    expected = continue_run(source, t0)
    target = Harness(unzipped, model_description).instantiate()  # fresh, not even initialised
    state = target.slave.deSerializeFMUstate(buffer)
    target.slave.setFMUstate(state)
    assert continue_run(target, t0) == expected
    source.free()
    target.free()


def test_serialized_state_restores_in_another_process(unzipped, model_description, tmp_path):
    source = started(unzipped, model_description)
    t0 = 37 * 0.013
    (tmp_path / "state.bin").write_bytes(source.slave.serializeFMUstate(source.slave.getFMUstate()))
    expected = continue_run(source, t0)
    unzipped = str(unzipped)
    script = f"""
import json, fmpy, sys
sys.path.insert(0, {str(__import__('pathlib').Path(__file__).parent)!r})
from test_fmu_state import continue_run
from test_fmi_api import Harness
md = fmpy.read_model_description({unzipped!r})
fmu = Harness({unzipped!r}, md).instantiate()
fmu.slave.setFMUstate(fmu.slave.deSerializeFMUstate(open({str(tmp_path / 'state.bin')!r}, 'rb').read()))
print(json.dumps([[v.hex() if isinstance(v, float) else v for v in row] for row in continue_run(fmu, {t0!r})]))
"""
    output = subprocess.run([sys.executable, "-c", script], check=True, capture_output=True, text=True).stdout
    other = [[float.fromhex(v) if isinstance(v, str) else v for v in row] for row in json.loads(output)]
    assert other == expected
    source.free()


@pytest.mark.parametrize("damage", ["truncate", "flip", "foreign", "empty"])
def test_bad_buffers_are_refused_and_nothing_changes(unzipped, model_description, damage):
    fmu = started(unzipped, model_description)
    buffer = bytearray(fmu.slave.serializeFMUstate(fmu.slave.getFMUstate()))
    if damage == "truncate":
        buffer = buffer[: len(buffer) // 2]
    elif damage == "flip":
        buffer[len(buffer) // 2] ^= 0x10
    elif damage == "foreign":
        buffer = bytearray(b"PK\x03\x04" + bytes(200))
    else:
        buffer = bytearray(b"")
    before = fmu.get(*WATCH)
    message = fmu.expect(ERROR, fmu.slave.deSerializeFMUstate, bytes(buffer) if buffer else b"\0")
    assert "fmi2DeSerializeFMUstate" in message
    assert fmu.get(*WATCH) == before
    fmu.slave.doStep(37 * 0.013, 0.013)  # the instance keeps working
    fmu.free()


def test_freed_or_foreign_state_pointers_are_errors(unzipped, model_description):
    fmu = started(unzipped, model_description)
    state = fmu.slave.getFMUstate()
    saved = ctypes.c_void_p(state.value)
    fmu.slave.freeFMUstate(state)
    assert state.value is None, "fmi2FreeFMUstate sets the pointer to NULL"
    assert "freed already" in fmu.expect(ERROR, fmu.slave.setFMUstate, saved)
    other = Harness(unzipped, model_description).instantiate()
    foreign = other.slave.getFMUstate()
    assert "not created by this instance" in fmu.expect(ERROR, fmu.slave.setFMUstate, foreign)
    other.free()  # frees its unfreed state with it
    fmu.free()


def test_get_fmu_state_overwrites_a_given_state(unzipped, model_description):
    fmu = started(unzipped, model_description)
    state = fmu.slave.getFMUstate()
    pointer = state.value
    fmu.slave.doStep(37 * 0.013, 0.013)
    after = fmu.get(*WATCH)
    fmu.slave.fmi2GetFMUstate(fmu.slave.component, ctypes.byref(state))
    assert state.value == pointer
    fmu.slave.doStep(38 * 0.013, 0.013)
    fmu.slave.setFMUstate(state)
    assert fmu.get(*WATCH) == after
    fmu.free()


def test_state_restores_the_fmi_state_too(unzipped, model_description):
    fmu = started(unzipped, model_description)
    state = fmu.slave.getFMUstate()
    fmu.slave.terminate()
    fmu.expect(ERROR, fmu.slave.doStep, 37 * 0.013, 0.013)
    fmu.slave.setFMUstate(state)  # back to stepping
    fmu.slave.doStep(37 * 0.013, 0.013)
    fmu.free()
