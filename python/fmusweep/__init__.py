"""fmusweep: sweeps and fits of an FMI 2.0 or 3.0 FMU (Co-Simulation or Model Exchange), or of
a coupled system of them, at the FMU's own speed.

    from fmusweep import run_sweep
    results = run_sweep("examples/sweeps/rod_force_grid.toml", fmu="Model.fmu")
    results.points            # a pandas DataFrame, one row per point

    from fmusweep import fit
    result = fit("examples/fit/fit.toml", fmu="Model.fmu")
    result.summary            # estimates, intervals, correlations: what fit.json holds

A sweep whose spec has a ``[cycle]`` table finds each point's steady cycle instead of
running a transient (``fmusweep.cycle``); ``linearise(fmu, parameters)`` gives an FMU's
A, B, C, D and modes at a point's initial state.

The per-point work runs in the native runner (``fmu-runner``), one process per worker,
so no Python runs per communication step; Dask spreads batches of points over the cores
of this machine or over an existing cluster; results land in Parquet as batches finish.
"""

from importlib import metadata as _metadata

from .cycle import Linearisation, linearise
from .designs import Design, generate
from .sweep import SweepSummary, run_sweep
from .fitting import FitResult, FitSpec, fit
from .native import NativeRunner, RunnerError
from .results import Results, load_results
from .indices import morris_effects, sobol_indices
from .spec import Spec, SpecError
from .errors import SpecWarning

__all__ = ["run_sweep", "fit", "FitResult", "FitSpec", "load_results", "Results", "SweepSummary", "Spec", "SpecError", "SpecWarning",
           "Design", "generate", "NativeRunner", "RunnerError", "sobol_indices",
           "morris_effects", "linearise", "Linearisation"]

try:
    __version__ = _metadata.version("fmusweep")
except _metadata.PackageNotFoundError:  # run from the source tree, not installed
    __version__ = "0.0.0+source"
