"""The ``[cycle]`` table: a sweep of steady cycles instead of transients. Each point's
periodic steady state is found by the runner (docs/cycle.md), and its metrics are taken
over one cycle::

    [cycle]
    state = "loop_angle"           # the continuous state whose advance closes a cycle
    advance = 6.283185307179586    # its advance over one cycle (> 0)
    shifted = ["phi1"]             # other states that advance by the same amount
    monodromy = "variational"      # or "differences" (default: variational where the FMU
                                   # gives directional derivatives)
    samples = 2048                 # points along the cycle the metrics are read at
    modes = 8                      # points along the cycle its modes are computed at
    keep = ["rod_force"]           # variables kept over one cycle (series/, the pictures)
    continuation = true            # start from the previous point's cycle (the default)

    [outputs.metrics]
    peak = { variable = "rod_force", kind = "max" }
    first = { variable = "rod_force", kind = "harmonic", order = 1 }

``scenario.stop − scenario.start`` bounds the transient the search may start from.

Or through the FMU's Co-Simulation interface, where it offers sensitivities to start values
(docs/sensitivities.md): ``starts`` names the start values that set the state on the
section, and ``state`` and ``shifted`` name variables whose sensitivities it gives::

    [cycle]
    state = "phi2"
    advance = 6.283185307179586
    shifted = ["phi1"]
    starts = ["twist12_0", "twist34_0", "omega1_0", "omega2_0", "omega4_0"]

The table's rules are the runner's, which refuses every mistake of it by field when the
sweep's plan is checked; this package only reads the start values off the FMU's offer of
sensitivities (its convention), and what it draws and deals out.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, overload

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from .errors import Collector, SpecError, SpecErrors, did_you_mean, refuse
from .fields import SETTABLE, Variables, finite
from .schema.core import Loc, Parts, Table, at, read
from .schema.core import field as declared
from .sensitivity_slots import Offer, read_offer, slot_parameter, slot_variable
from .native import RunnerError
from .records import PointResult, new_plan

__all__ = ["CycleSpec", "CycleStarts", "CYCLE_COLUMNS", "CHAIN_POINTS", "cycle_columns", "Linearisation",
           "linearise"]

# A sweep of steady cycles that continues each point from its neighbours' cycles does so
# in chains of at most this many points along a row of its design (fmusweep.designs'
# chains): a point's start is then the design's alone, and the sweep the same bit for bit
# however its batches are dealt out.
CHAIN_POINTS = 32

# The columns a sweep of cycles writes of its own (the multipliers and modes as lists).
CYCLE_COLUMNS = ("cycle_period", "cycle_multiplier", "cycle_mode", "cycle_margin",
                 "cycle_residual", "cycle_iterations", "cycle_runs", "cycle_continued",
                 "cycle_state",
                 "cycle_multipliers_re", "cycle_multipliers_im", "cycle_modes_hz",
                 "cycle_modes_damping")


def _names(value: object) -> list[str]:
    """The names of a list (what the runner refuses, read as none meanwhile)."""
    return [v for v in value if isinstance(v, str)] if isinstance(value, list) else []


class CycleStarts(Table):
    """The one field of ``[cycle]`` the client reads itself: the start values, whose slots
    it finds in the FMU's offer of sensitivities (the runner holds the table's other rules)."""
    starts: list[str] = declared(
        "through the Co-Simulation interface: the start values that set the state on the "
        "section (the FMU offers sensitivities to each)", [], shows="list of names")

    @classmethod
    def rules(cls, parts: Parts, where: Loc) -> Iterator[SpecError]:
        if any(not name for name in parts.get("starts") or []):
            yield SpecError(at(where + ("starts",)), "must be a list of start values' names")


@dataclass(frozen=True)
class CycleSpec:
    """The ``[cycle]`` table as written; what this package reads of it."""
    table: dict[str, Any]

    @staticmethod
    def of(raw: dict[str, Any]) -> CycleSpec | None:
        """The [cycle] table, None without one; `starts` a list of names (the runner checks
        the rest)."""
        if "cycle" not in raw:
            return None
        table = raw["cycle"]
        if not isinstance(table, dict):
            raise SpecError("cycle", f"must be a table, got {table!r}")
        found = read(CycleStarts, {k: v for k, v in table.items() if k == "starts"}, ("cycle",))
        if found.errors:
            raise found.errors[0] if len(found.errors) == 1 else SpecErrors(found.errors)
        return CycleSpec(table)

    @property
    def state(self) -> str:
        state = self.table.get("state")
        return state if isinstance(state, str) else ""

    @property
    def shifted(self) -> list[str]:
        return _names(self.table.get("shifted"))

    @property
    def keep(self) -> list[str]:
        return _names(self.table.get("keep"))

    @property
    def starts(self) -> list[str]:
        return _names(self.table.get("starts"))

    @property
    def continued(self) -> bool:
        """Whether a point's search starts from its neighbours' cycles."""
        return self.table.get("continuation", True) is not False

    def check(self, description: dict[str, Any], errors: Collector) -> None:
        """Through the start values: the FMU offers sensitivities to each one named, in as
        many slots (the offer's convention, which the runner does not know)."""
        if not self.starts:
            return
        offer = read_offer(description)
        if offer is None:
            errors.run(lambda: refuse("cycle.starts", "the FMU offers no sensitivities "
                                                       "(sensitivity_<k>.parameter slots): the "
                                                       "cycle through the start values needs "
                                                       "them; leave `starts` out to shoot on "
                                                       "Model Exchange"))
            return
        for k, name in enumerate(self.starts):
            if name not in offer.items:
                errors.run(lambda: refuse(f"cycle.starts[{k}]", f"the FMU offers no sensitivity "
                                          f"to {name!r}{did_you_mean(name, offer.items)} (it "
                                          f"offers: {', '.join(sorted(offer.items))})"))
        if len(self.starts) > offer.slots:
            errors.run(lambda: refuse("cycle.starts", f"{len(self.starts)} start values, but "
                                                       f"the FMU has {offer.slots} sensitivity "
                                                       f"slots"))

    def plan(self, metrics: list[dict[str, Any]], description: dict[str, Any],
             linearise: bool = False) -> dict[str, Any]:
        """The runner's plan of the cycle: the table as written (less `starts`), the metrics
        over one cycle (each with its field), and through the start values their slots, the
        closing variables and their sensitivities, from the FMU's offer."""
        table = {k: v for k, v in self.table.items() if k != "starts"}
        starts = None
        offer = read_offer(description) if self.starts else None
        if self.starts:
            closing = _closing(description, offer) if offer is not None else []
            slots = offer.slots if offer is not None else 0
            # A name the FMU does not offer is refused by check(); its slot stays `none`.
            items = offer.items if offer is not None else {}
            starts = {"parameters": self.starts,
                      "slots": [(slot_parameter(k + 1), items.get(name, 0))
                                for k, name in enumerate(self.starts[:slots])],
                      "closing": closing,
                      "columns": [[slot_variable(k + 1, c) for c in closing]
                                  for k in range(min(len(self.starts), slots))]}
        return {"table": table, "metrics": metrics, "starts": starts, "linearise": linearise}


def _closing(description: dict[str, Any], offer: Offer) -> list[str]:
    """The Real outputs every sensitivity slot covers: the variables whose return closes a
    cycle through the start values, in the description's order."""
    return [v["name"] for v in description["variables"]
            if v["causality"] == "output" and v["type"] == "real" and offer.covers(v["name"])]


def cycle_columns(results: list[PointResult]) -> dict[str, pa.Array]:
    """Each point's cycle: its period, its largest Floquet multiplier's modulus and the
    states its mode moves most (``omega4 94%, loop_speed 5%``), the margin to the unit
    circle (1 − that modulus: negative for an unstable cycle), the periodicity residual, the Newton
    iterations and runs spent, whether it continued from its neighbour's cycle; its
    state on the section (in the order of the FMU's Model Exchange states), its
    multipliers, and its modes' frequencies and damping ratios averaged along the cycle
    (null where the point has no cycle)."""
    cycles = [r.get("cycle") for r in results]

    def column(key: str, kind: pa.DataType) -> pa.Array:
        return pa.array([None if c is None else c[key] for c in cycles], kind)

    def listed(read: Any) -> pa.Array:
        return pa.array([None if c is None else read(c) for c in cycles],
                        pa.list_(pa.float64()))

    return {"cycle_period": column("period", pa.float64()),
            "cycle_multiplier": column("largest_multiplier", pa.float64()),
            "cycle_mode": pa.array([None if c is None else _leading(c) for c in cycles],
                                   pa.string()),
            "cycle_margin": column("margin", pa.float64()),
            "cycle_residual": column("residual", pa.float64()),
            "cycle_iterations": column("iterations", pa.int64()),
            "cycle_runs": column("runs", pa.int64()),
            "cycle_continued": column("continued", pa.bool_()),
            "cycle_state": listed(lambda c: c["state"]),
            "cycle_multipliers_re": listed(lambda c: [m["re"] for m in c["multipliers"]]),
            "cycle_multipliers_im": listed(lambda c: [m["im"] for m in c["multipliers"]]),
            "cycle_modes_hz": listed(lambda c: _along(c, "frequency")),
            "cycle_modes_damping": listed(lambda c: _along(c, "damping"))}


def _leading(cycle: dict[str, Any]) -> str:
    """The states the largest multiplier's eigenvector moves most, with their shares."""
    multipliers = cycle["multipliers"]
    if not multipliers:
        return ""
    return ", ".join(f"{name} {share:.0%}" for name, share in multipliers[0]["states"])


def _along(cycle: dict[str, Any], key: str) -> list[float]:
    """A mode quantity averaged over the points along the cycle, modes matched by their
    rank in frequency (as many modes as every point has)."""
    points = [modes for _, modes in cycle.get("modes", [])]
    if not points:
        return []
    count = min(len(modes) for modes in points)
    return [math.fsum(modes[k][key] for modes in points) / len(points) for k in range(count)]


@dataclass(frozen=True)
class Linearisation:
    """The FMU's state equations and outputs linearised at a state: x' ≈ A x + B u,
    y ≈ C x + D u, with u its Real inputs and y its Real outputs (their names in
    ``states``, ``inputs``, ``outputs``), from its directional derivatives; and the
    oscillating modes of A (frequency in Hz, damping ratio), by frequency. ``t`` and ``x``:
    where it was made (the time into the cycle along a cycle)."""
    states: list[str]
    inputs: list[str]
    outputs: list[str]
    A: npt.NDArray[np.float64]
    B: npt.NDArray[np.float64]
    C: npt.NDArray[np.float64]
    D: npt.NDArray[np.float64]
    frequencies: list[float]
    dampings: list[float]
    t: float = 0.0
    x: list[float] = field(default_factory=list)


@overload
def linearise(fmu: str | os.PathLike[str], parameters: dict[str, float] | None = None, *,
              along: None = None) -> Linearisation: ...


@overload
def linearise(fmu: str | os.PathLike[str], parameters: dict[str, float] | None = None, *,
              along: dict[str, Any]) -> list[Linearisation]: ...


def linearise(fmu: str | os.PathLike[str], parameters: dict[str, float] | None = None, *,
              along: dict[str, Any] | None = None) -> Linearisation | list[Linearisation]:
    """The FMU's Model Exchange interface linearised at the initial state that
    `parameters` (start values among them) give it; or, `along` a steady cycle (a
    ``[cycle]`` table, its ``modes`` the number of points), at that many points evenly
    spaced in time along the point's steady cycle, in order."""
    from .fmu import Archive, local_runner
    runner = local_runner(Archive.read(fmu))
    names = list(parameters or {})
    variables, errors = Variables(runner.describe()), Collector()
    for name, value in (parameters or {}).items():
        where = f"parameters.{name}"
        errors.run(lambda: variables.get(name, where, SETTABLE, what="parameter or input"))
        errors.run(lambda: finite(value, where))
    errors.raise_any()
    row = [[float((parameters or {})[n]) for n in names]]
    if along is None:
        runner.configure(new_plan(0.0, 1.0, 1.0, interface="model_exchange"))
        found = runner.linearise(names, row)[0]
        if found["status"] != "ok":
            raise RunnerError(found["message"])
        return _linearisation(found["linearisation"])
    search = {k: along[k] for k in ("stop", "step", "tolerance") if k in along}
    table = {k: v for k, v in along.items() if k not in search}
    spec = CycleSpec.of({"cycle": table})
    assert spec is not None
    errors = Collector()
    if not isinstance(table.get("modes"), int) or table["modes"] < 1:
        errors.run(lambda: refuse("cycle.modes", "the number of points along the cycle to "
                                                  "linearise at, at least 1"))
    spec.check(runner.describe(), errors)
    errors.raise_any()
    cycle = spec.plan([], runner.describe(), linearise=True)
    runner.configure(new_plan(0.0, float(search.get("stop", 400.0)),
                              float(search.get("step", 0.01)),
                              tolerance=float(search.get("tolerance", 1e-9)), cycle=cycle))
    result = runner.run(names, row)[0]
    found_cycle = result.get("cycle")
    if result["status"] != "ok" or found_cycle is None:
        raise RunnerError(f"{result['status']}: {result['message']}")
    return [_linearisation(lin) for lin in found_cycle["linearisations"]]


def _linearisation(lin: dict[str, Any]) -> Linearisation:
    n, m, p = len(lin["states"]), len(lin["inputs"]), len(lin["outputs"])

    def matrix(key: str, rows: int, columns: int) -> npt.NDArray[np.float64]:
        return np.asarray(lin[key], dtype=float).reshape(rows, columns)

    return Linearisation(lin["states"], lin["inputs"], lin["outputs"], matrix("a", n, n),
                         matrix("b", n, m), matrix("c", p, n), matrix("d", p, m),
                         [mode["frequency"] for mode in lin["modes"]],
                         [mode["damping"] for mode in lin["modes"]], float(lin["t"]),
                         [float(v) for v in lin["x"]])
