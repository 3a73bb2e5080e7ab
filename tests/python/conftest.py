"""Shared fixtures: the packed FMU (built by `cargo xtask test`), unpacked once."""

import json
import os
import pathlib

import fmpy
import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
STATES = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4"]


def packed(variable, default, job):
    """A packed FMU: the path in environment `variable`, else `default`; a failure that says
    which xtask job packs it when it is missing."""
    path = pathlib.Path(os.environ.get(variable, ROOT / default))
    if not path.exists():
        pytest.fail(f"{path} does not exist: run `cargo xtask {job}` (or `cargo xtask test`)")
    return path


def compiled_slave(path, identifier, directory):
    """An instance of a compiled co-simulation component of examples/ through FMPy, with
    `vr` (value references by name) and `messages` (what it logged)."""
    unzipped = fmpy.extract(str(path), unzipdir=str(directory))
    description = fmpy.read_model_description(unzipped)
    slave = fmpy.fmi2.FMU2Slave(guid=description.guid, unzipDirectory=unzipped,
                                modelIdentifier=identifier, instanceName=identifier.lower())
    slave.vr = {v.name: v.valueReference for v in description.modelVariables}
    slave.messages = []
    logger = fmpy.fmi2.fmi2CallbackLoggerTYPE(
        lambda env, name, status, category, message: slave.messages.append(message.decode()))
    callbacks = fmpy.fmi2.fmi2CallbackFunctions()
    callbacks.logger = logger
    callbacks.allocateMemory = fmpy.fmi2.fmi2CallbackAllocateMemoryTYPE(fmpy.fmi2.calloc)
    callbacks.freeMemory = fmpy.fmi2.fmi2CallbackFreeMemoryTYPE(fmpy.fmi2.free)
    slave.instantiate(callbacks=callbacks)
    slave.keep = (logger, callbacks)  # alive as long as the instance
    return slave


@pytest.fixture(scope="session")
def motor_path():
    return packed("DC_MOTOR_FMU", "target/fmu/DcMotor.fmu", "motor")


@pytest.fixture(scope="session")
def load_path():
    return packed("FLYWHEEL_LOAD_FMU", "target/fmu/FlywheelLoad.fmu", "motor")


@pytest.fixture(scope="session")
def ball_path():
    return packed("BOUNCING_BALL_FMU", "target/fmu/BouncingBall.fmu", "motor")


@pytest.fixture(scope="session")
def ball_me_paths():
    """The bouncing ball's Model Exchange FMUs: FMI 2.0 and FMI 3.0."""
    return {"2.0": packed("BOUNCING_BALL_ME_FMU", "target/fmu/BouncingBallME.fmu", "motor"),
            "3.0": packed("BOUNCING_BALL_ME_FMU3", "target/fmu/BouncingBallME-fmi3.fmu", "motor")}


@pytest.fixture(scope="session")
def fmu_path():
    return packed("CYCLIC_MECHANISM_FMU", "target/fmu/CyclicMechanism.fmu", "fmu")


@pytest.fixture(scope="session")
def unzipped(fmu_path, tmp_path_factory):
    return fmpy.extract(str(fmu_path), unzipdir=str(tmp_path_factory.mktemp("fmu")))


@pytest.fixture(scope="session")
def model_description(unzipped):
    return fmpy.read_model_description(unzipped)


def simulate(unzipped, start_values, stop_time, step, tolerance=1e-10, outputs=None):
    """Run the FMU through FMPy's high-level API, as users do."""
    return fmpy.simulate_fmu(
        unzipped,
        start_values=start_values,
        stop_time=stop_time,
        output_interval=step,
        relative_tolerance=tolerance,
        output=outputs,
    )


def states(result):
    return np.column_stack([result[name] for name in STATES])


@pytest.fixture(scope="session")
def report():
    """Measured figures, written to target/test-reports/measurements.json at the end (or to
    $MEASUREMENTS: the valgrind run's partial figures must not replace the full run's)."""
    figures = {}
    yield figures
    path = pathlib.Path(os.environ.get("MEASUREMENTS", ROOT / "target/test-reports/measurements.json"))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(figures, indent=2, sort_keys=True))


@pytest.fixture(scope="session")
def fmu3_path():
    return packed("CYCLIC_MECHANISM_FMU3", "target/fmu/CyclicMechanism-fmi3.fmu", "fmu")


@pytest.fixture(scope="session")
def unzipped3(fmu3_path, tmp_path_factory):
    return fmpy.extract(str(fmu3_path), unzipdir=str(tmp_path_factory.mktemp("fmu3")))


@pytest.fixture(scope="session")
def model_description3(unzipped3):
    return fmpy.read_model_description(unzipped3)
