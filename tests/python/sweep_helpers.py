"""Shared pieces of the sweep tests: specs, the faulty FMU, comparisons."""

import os
import pathlib
import subprocess
import zipfile

import fmpy

HERE = pathlib.Path(__file__).parent
PAPER_LAWS = dict(Mm_a0=100.0, Mm_a1=-20.0, Mm_a2=-1.0, Mr_b0=20.0, Mr_b1=-0.05)
# Columns that depend only on the points, not on where or when they ran.
RESULT_COLUMNS = ["point", "point_id", "status", "message", "t_end", "steps"]


def grid_spec(stop=2.0, **design_parameters):
    parameters = design_parameters or {"k34": {"linspace": [50.0, 400.0, 4]},
                                       "L": {"values": [0.6, 0.7, 1.2]}}
    return {
        "scenario": {"stop": stop, "step": 0.01, "tolerance": 1e-8, "parameters": dict(PAPER_LAWS)},
        "design": {"kind": "grid", "parameters": parameters},
        "outputs": {"metrics": {
            "peak_rod_force": {"variable": "rod_force", "kind": "peak_abs"},
            "omega1_ripple": {"variable": "omega1", "kind": "peak_to_peak", "from": 1.0},
            "n_rhs": {"variable": "n_rhs", "kind": "final"},
        }},
    }


def same_results(a, b, metrics):
    """Bit for bit: every result column and metric (NaN equal to NaN)."""
    columns = RESULT_COLUMNS + metrics
    return a[columns].reset_index(drop=True).equals(b[columns].reset_index(drop=True))


def faulty_fmu(directory: pathlib.Path) -> pathlib.Path:
    """Compile tests/python/faulty_fmu/faulty.c against FMPy's copy of the FMI 2.0
    headers and pack it as Faulty.fmu."""
    headers = pathlib.Path(fmpy.__file__).parent / "c-code"
    library = directory / "Faulty.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O1", "-o", str(library), "-I", str(headers),
                    str(HERE / "faulty_fmu/faulty.c")], check=True)
    fmu = directory / "Faulty.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.write(HERE / "faulty_fmu/modelDescription.xml", "modelDescription.xml")
        z.write(library, "binaries/linux64/Faulty.so")
    return fmu


def environment_for_workers():
    """The test's environment for worker processes; the package comes from the wheel
    that `cargo xtask test` installs in the venv."""
    env = dict(os.environ)
    env.pop("FMUSWEEP_RUNNER", None)
    return env
