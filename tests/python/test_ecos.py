"""Ecos (ecospy), a master with FMI 3.0 that lists no Enumeration variable: its users
choose the method through `solver_code`, the Integer twin of `solver`, and get the run
FMPy gives with `solver = 3`."""

import ctypes
import pathlib
import sys

import fmpy
import numpy as np
import pytest

STATES = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4"]


@pytest.fixture(scope="module")
def ecos():
    # Ecos's library needs TBB's, which the `tbb` package puts in the environment's lib/.
    lib = pathlib.Path(sys.prefix) / "lib"
    for name in ("libtbb.so.12",):
        if (lib / name).exists():
            ctypes.CDLL(str(lib / name), mode=ctypes.RTLD_GLOBAL)
    import ecospy
    return ecospy


def run_ecos(ecos, archive, code, steps=100):
    with ecos.EcosSimulationStructure() as structure:
        structure.add_model("mechanism", str(archive))
        structure.add_parameter_set("initials", {"mechanism::solver_code": code})
        with ecos.EcosSimulation(structure=structure, step_size=0.01) as sim:
            sim.init(parameter_set="initials")
            sim.step(steps)
            values = [sim.get_real(f"mechanism::{n}") for n in STATES]
            taken = sim.get_integer("mechanism::n_steps")
            sim.terminate()
    return np.array(values), taken


@pytest.mark.parametrize("archive", ["2.0", "3.0"])
def test_ecos_chooses_the_implicit_method_through_the_integer_twin(ecos, archive, fmu_path,
                                                                    fmu3_path):
    path = fmu_path if archive == "2.0" else fmu3_path
    implicit = fmpy.simulate_fmu(path, start_values={"solver": 3}, stop_time=1.0,
                                 output_interval=0.01, output=STATES + ["n_steps"])
    explicit = fmpy.simulate_fmu(path, stop_time=1.0, output_interval=0.01, output=["n_steps"])
    values, taken = run_ecos(ecos, path, 3)
    assert taken == implicit["n_steps"][-1] != explicit["n_steps"][-1]
    expected = np.array([implicit[n][-1] for n in STATES])
    assert (np.abs(values - expected) / np.maximum(1.0, np.abs(expected))).max() < 1e-9
    # 0, the twin's start: the Enumeration decides (auto, the explicit method here).
    _, taken = run_ecos(ecos, path, 0)
    assert taken == explicit["n_steps"][-1]
