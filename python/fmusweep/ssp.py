"""SSP files run through FMPy's SSP support (``fmpy.ssp.simulation.simulate_ssp``), when a
spec asks for it (``[system] engine = "fmpy"``; by default an SSP file runs natively, see
``fmusweep.ssd``): one call per point in the worker's Python, which extracts the archive,
instantiates every FMU and runs FMPy's own master loop. This path trades the native
runner's speed for what only FMPy runs: Python-written components, the system's own
connectors (the benchmark measures it). Design parameters and fixed parameters are named
``component.variable``; metrics and series may name any connector of the system
(``mechanism.omega1``). There is no per-point time budget and no crash isolation on this
path: an FMU that crashes takes its Dask worker with it, and that batch's rows say
``crashed``.
"""

from __future__ import annotations

import atexit
import io
import pathlib
import shutil
import tempfile
import time
import zipfile
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import SpecError
from .fmu import Archive
from .records import Batch, Plan, PointResult, Points, Rows
from .worker import trace, worker_name

if TYPE_CHECKING:
    from .designs import Design
    from .spec import Spec

__all__ = ["describe_ssp", "check_ssp", "run_ssp_batch", "metrics_of"]

# Per process: checksum -> the SSP written to a file (simulate_ssp takes a file name).
_FILES: dict[str, pathlib.Path] = {}


def _file(system: Archive) -> pathlib.Path:
    path = _FILES.get(system.sha256)
    if path is None:
        directory = pathlib.Path(tempfile.mkdtemp(prefix=f"fmusweep-ssp-{system.sha256[:12]}-"))
        path = directory / system.name
        path.write_bytes(system.data)
        _FILES[system.sha256] = path
    return path


@atexit.register
def _remove_files() -> None:
    for path in _FILES.values():
        shutil.rmtree(path.parent, ignore_errors=True)


def describe_ssp(system: Archive) -> dict[str, Any]:
    """The system's connectors (paths) and, per component, its FMU's variables."""
    try:
        from fmpy import read_model_description
    except ImportError:
        raise SpecError("ssp", "an SSP file runs through FMPy: pip install "
                               "'fmusweep[systems]'") from None
    from fmpy.ssp.simulation import add_path, find_components, find_connectors
    from fmpy.ssp.ssd import read_ssd
    path = _file(system)
    ssd = read_ssd(str(path))
    add_path(ssd.system)
    components = {}
    with zipfile.ZipFile(path) as archive:
        for component in find_components(ssd.system):
            fmu = io.BytesIO(archive.read(component.source))
            md = read_model_description(fmu, validate=False)
            components[component.name] = {v.name: (v.causality, v.type) for v in md.modelVariables}
    return {"connectors": [c.path for c in find_connectors(ssd.system)], "components": components}


def check_ssp(spec: Spec, design: Design, description: dict[str, Any]) -> None:
    if spec.scenario.inputs:
        raise SpecError("scenario.inputs", "an SSP system takes no inputs here; "
                                           "set parameters of its components instead")

    def parameter(name: str, where: str) -> None:
        component, _, variable = name.partition(".")
        variables = description["components"].get(component)
        if variables is None or not variable:
            raise SpecError(where, f"{name!r} is not component.variable of a component of the "
                                   f"system ({', '.join(description['components'])})")
        if variable not in variables:
            raise SpecError(where, f"component {component} has no variable {variable!r}")
        causality, kind = variables[variable]
        if causality not in ("parameter", "input") or kind not in ("Real", "Integer", "Boolean", "Enumeration"):
            raise SpecError(where, f"{name} is a {kind} {causality}; only parameters and inputs can be set")

    for name in spec.scenario.parameters:
        parameter(name, f"scenario.parameters.{name}")
    for name in design.names:
        parameter(name, f"design.parameters.{name}")
    connectors = set(description["connectors"])
    for m in spec.metrics:
        if m.variable not in connectors:
            raise SpecError(f"outputs.metrics.{m.name}.variable",
                            f"{m.variable!r} is not a connector of the system "
                            f"({', '.join(sorted(connectors))})")
    for name in spec.series_variables:
        if name not in connectors:
            raise SpecError("outputs.series.variables", f"{name!r} is not a connector of the system")


def loop_stop(plan: Plan) -> float:
    """The stop time to hand simulate_ssp. Its loop adds the step to an accumulated time
    while that is below the stop time, and the sum of 10 000 steps of 1 ms falls just
    short of 10 s: given the stop time itself, it takes one step more. Half a step short
    of it, the loop takes exactly the steps the plan asks for. (The FMUs get no stop time
    from simulate_ssp either way.)"""
    return float(plan["stop"] - 0.5 * plan["step"])


def metrics_of(t: Rows, columns: dict[str, Any], plan: Plan) -> list[float | None]:
    """The runner's metrics (same windows and definitions) over recorded rows."""
    slack = 1e-9 * plan["step"]
    found: list[float | None] = []
    for m in plan["metrics"]:
        start = plan["start"] if m["from"] is None else m["from"]
        end = plan["stop"] if m["to"] is None else m["to"]
        inside = (t >= start - slack) & (t <= end + slack)
        x, ti = np.asarray(columns[m["variable"]], dtype=float)[inside], t[inside]
        if not len(x):
            found.append(None)
            continue
        kind = m["kind"]
        y = x * x if kind == "rms" else x
        span = ti[-1] - ti[0]
        average = y[-1] if len(y) == 1 or span <= 0 else float(np.sum(0.5 * np.diff(ti) * (y[1:] + y[:-1])) / span)
        found.append(float({
            "final": x[-1], "min": x.min(), "max": x.max(), "peak_abs": np.abs(x).max(),
            "peak_to_peak": x.max() - x.min(), "mean": average, "rms": np.sqrt(average),
        }[kind]))
    return found


def _one_point(path: pathlib.Path, plan: Plan, values: dict[str, float]) -> PointResult:
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet
    started = time.perf_counter()
    parameters = ParameterSet(parameters=[Parameter(name=k, value=v) for k, v in values.items()])
    try:
        rows = simulate_ssp(str(path), start_time=plan["start"], stop_time=loop_stop(plan),
                            step_size=plan["step"], parameter_set=parameters)
    except Exception as e:  # FMPy raises on any FMU status above Warning
        return {"status": "error", "message": f"{type(e).__name__}: {e}",
                "metrics": [None] * len(plan["metrics"]), "t_end": None, "steps": None,
                "wall_s": time.perf_counter() - started}
    # simulate_ssp labels each row with its step's start; the values are those after it.
    t: Rows = plan["start"] + plan["step"] * np.arange(1, len(rows) + 1, dtype=np.float64)
    columns = {name: rows[name] for name in rows.dtype.names[1:]}
    result: PointResult = {"status": "ok", "message": "", "metrics": metrics_of(t, columns, plan),
                           "t_end": float(t[-1]), "steps": len(rows),
                           "wall_s": time.perf_counter() - started}
    series = plan.get("series")
    if series:
        keep = np.arange(len(t)) % series["every"] == series["every"] - 1
        result["series"] = np.column_stack([t[keep]] + [np.asarray(columns[v], float)[keep]
                                                        for v in series["variables"]])
    return result


def run_ssp_batch(system: Archive, plan: Plan, names: list[str], rows: Rows,
                  points: Points) -> Batch:
    trace("start", points)
    path = _file(system)
    results = [_one_point(path, plan, dict(plan["fixed"], **dict(zip(names, map(float, row)))))
               for row in rows]
    trace("end", points)
    return {"points": points, "results": results, "worker": worker_name()}


def prepare_ssp_worker(system: Archive, plan: Plan) -> str:
    _file(system)
    return worker_name()
