"""What the data say about the estimates: covariance from the Jacobian of the weighted
residuals at the optimum, standard errors, 95 % intervals, correlations, and the
parameters the data cannot decide.

- With a standard deviation given for every measured column, the weights are taken as
  true: covariance (JᵀJ)⁻¹ and intervals from the normal law.
- Otherwise the weights are relative and the residuals' own variance s² = Σr²/(m − p)
  scales them: covariance s²·(JᵀJ)⁻¹ and intervals from Student's t with m − p degrees.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..records import Rows

if TYPE_CHECKING:
    from .spec import FitSpec

__all__ = ["uncertainty", "CORRELATION_LIMIT", "SINGULAR_RATIO"]

CORRELATION_LIMIT = 0.99
# Singular values below this fraction of the largest are taken as zero: the data do not
# move the combination of parameters they belong to beyond the Jacobian's own noise.
SINGULAR_RATIO = 1e-8


def uncertainty(spec: FitSpec, estimate: Rows, jacobian: Rows, residuals: Rows) -> dict[str, Any]:
    from scipy import stats
    names = spec.names
    m, p = jacobian.shape
    dof = m - p
    absolute = spec.absolute_sigma
    _, s, vt = np.linalg.svd(jacobian, full_matrices=False)
    singular = s <= SINGULAR_RATIO * s[0] if s[0] > 0 else np.ones_like(s, dtype=bool)
    variance = 1.0 if absolute else (float(residuals @ residuals) / dof if dof > 0 else np.inf)
    warnings: list[str] = []
    if dof <= 0:
        warnings.append(f"{m} residuals for {p} parameters: no degree of freedom is left to "
                        "estimate the uncertainty")
    quantile = stats.norm.ppf(0.975) if absolute else (stats.t.ppf(0.975, dof) if dof > 0 else np.inf)
    undecided: set[str] = set()
    if singular.any():
        involved = sorted({names[j] for v in vt[singular] for j in np.flatnonzero(np.abs(v) > 0.1)})
        undecided.update(involved)
        warnings.append(f"the Jacobian is singular: the data depend on {', '.join(involved)} only "
                        "through a combination of them, which leaves them undetermined")
        covariance = np.full((p, p), np.nan)
    else:
        covariance = variance * (vt.T / s**2) @ vt
    stderr = np.sqrt(np.diag(covariance))
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(stderr, stderr)
    parameters = {}
    for j, name in enumerate(names):
        low, high = estimate[j] - quantile * stderr[j], estimate[j] + quantile * stderr[j]
        spec_p = spec.fitted[j]
        if np.isfinite(stderr[j]) and high - low > spec_p.width:
            undecided.add(name)
            warnings.append(f"{name}'s 95 % interval [{low:.6g}, {high:.6g}] is wider than its "
                            f"range [{spec_p.low:g}, {spec_p.high:g}]: the data hardly decide it")
        at_bound = bool(min(estimate[j] - spec_p.low, spec_p.high - estimate[j]) <= 1e-6 * spec_p.width)
        if at_bound:
            warnings.append(f"{name} ended at a bound of its range: its interval assumes a free "
                            "parameter and may not hold")
        parameters[name] = {"estimate": float(estimate[j]), "stderr": _number(stderr[j]),
                            "ci95": [_number(low), _number(high)], "at_bound": at_bound,
                            "range": [spec_p.low, spec_p.high]}
    for i in range(p):
        for j in range(i + 1, p):
            if np.isfinite(correlation[i, j]) and abs(correlation[i, j]) > CORRELATION_LIMIT:
                undecided.update((names[i], names[j]))
                warnings.append(f"{names[i]} and {names[j]} cannot be told apart by the data: "
                                f"correlation {correlation[i, j]:+.4f}")
    for name in names:
        parameters[name]["identifiable"] = name not in undecided
    return {
        "parameters": parameters,
        "correlation": {a: {b: _number(correlation[i, j]) for j, b in enumerate(names) if j != i}
                        for i, a in enumerate(names)},
        "covariance": "from the given standard deviations" if absolute
                      else "scaled by the residuals' variance",
        "degrees_of_freedom": dof,
        "singular_values": [float(x) for x in s],
        "warnings": warnings,
        "unidentifiable": sorted(undecided),
    }


def _number(x: float) -> float | None:
    """A JSON number, or null where there is none (a singular Jacobian)."""
    return float(x) if np.isfinite(x) else None
