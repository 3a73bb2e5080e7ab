"""Fit an FMU's parameters to measurements, on the sweep's engine::

    from fmusweep import fit
    result = fit("examples/fit/fit.toml", workers=2)
    result.summary["parameters"]["k34"]   # estimate, stderr, ci95, identifiable

Bounded nonlinear least squares (``method``), each iteration one parallel batch of runs
on the sweep's pool, every run kept in the sweep's Parquet format (``problem``), the
uncertainty from the Jacobian at the optimum (``statistics``), and plots. The result is
written to ``OUT/fit.json``.
"""

from __future__ import annotations

from .run import SERIAL_BELOW_S, FitResult, fit
from .spec import FitParameter, FitSpec

__all__ = ["fit", "FitResult", "FitSpec", "FitParameter", "SERIAL_BELOW_S"]
