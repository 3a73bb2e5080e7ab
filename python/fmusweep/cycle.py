"""The ``[cycle]`` table: a sweep of steady cycles instead of transients. Each point's
periodic steady state is found by the runner by shooting on the FMU's Model Exchange
interface (docs/cycle.md), and its metrics are taken over one cycle::

    [cycle]
    state = "loop_angle"           # the continuous state whose advance closes a cycle
    period = 6.283185307179586     # its advance over one cycle (> 0)
    shifted = ["phi1"]             # other states that advance by the same period
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
    period = 6.283185307179586
    shifted = ["phi1"]
    starts = ["twist12_0", "twist34_0", "omega1_0", "omega2_0", "omega4_0"]
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any, TypedDict, overload

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from .errors import Collector, SpecError, did_you_mean, refuse
from .fields import number, only, table, whole
from .sensitivity_slots import Offer, read_offer, slot_parameter, slot_variable
from .native import RunnerError
from .records import Plan, PointResult

__all__ = ["CycleSpec", "CYCLE_METRIC_KINDS", "CYCLE_COLUMNS", "cycle_columns",
           "Linearisation", "linearise"]

# The metrics of an output over one cycle (the runner's, runner/src/cycle_plan.rs).
CYCLE_METRIC_KINDS = ("min", "max", "peak_abs", "peak_to_peak", "mean", "rms", "harmonic")
MONODROMY = ("variational", "differences")
# The columns a sweep of cycles writes of its own (the multipliers and modes as lists).
CYCLE_COLUMNS = ("cycle_period", "cycle_multiplier", "cycle_mode", "cycle_stability",
                 "cycle_margin",
                 "cycle_residual", "cycle_iterations", "cycle_runs", "cycle_continued",
                 "cycle_state",
                 "cycle_multipliers_re", "cycle_multipliers_im", "cycle_modes_hz",
                 "cycle_modes_damping")
MOST_SAMPLES = 1 << 20
MOST_MODE_POINTS = 4096


class CyclePlan(TypedDict):
    """The runner's cycle plan (its keys are the runner's)."""
    state: str
    period: float
    shifted: list[str]
    metrics: list[dict[str, Any]]
    samples: int | None
    monodromy: str | None
    modes: int
    keep: list[str]
    continuation: bool
    starts: dict[str, Any] | None


@dataclass(frozen=True)
class CycleSpec:
    state: str
    period: float
    shifted: list[str] = field(default_factory=list)
    monodromy: str | None = None
    samples: int | None = None
    modes: int = 0
    keep: list[str] = field(default_factory=list)
    continuation: bool = True
    # The start values the Co-Simulation path varies (none: Model Exchange).
    starts: list[str] = field(default_factory=list)

    @staticmethod
    def of(raw: dict[str, Any]) -> CycleSpec | None:
        """The [cycle] table, every mistake of its fields at once; None without one."""
        cycle = table(raw, "cycle", "spec")
        if not cycle and "cycle" not in raw:
            return None
        errors = Collector()
        errors.run(lambda: only(cycle, "cycle", {"state", "period", "shifted", "monodromy",
                                                 "samples", "modes", "keep",
                                                 "continuation", "starts"}))
        state = errors.run(lambda: _name(cycle.get("state"), "cycle.state"))
        period = errors.run(lambda: _period(cycle.get("period")))
        shifted = errors.run(lambda: _names(cycle.get("shifted", []), "cycle.shifted"))
        keep = errors.run(lambda: _names(cycle.get("keep", []), "cycle.keep"))
        starts = errors.run(lambda: _names(cycle.get("starts", []), "cycle.starts"))
        monodromy = cycle.get("monodromy")
        if monodromy is not None and monodromy not in MONODROMY:
            errors.run(lambda: refuse("cycle.monodromy", f"must be one of "
                                       f"{', '.join(map(repr, MONODROMY))}, got {monodromy!r}"))
        samples = errors.run(lambda: None if cycle.get("samples") is None else
                             whole(cycle["samples"], "cycle.samples", 8, MOST_SAMPLES))
        modes = errors.run(lambda: whole(cycle.get("modes", 0), "cycle.modes", 0,
                                         MOST_MODE_POINTS))
        continuation = cycle.get("continuation", True)
        if not isinstance(continuation, bool):
            errors.run(lambda: refuse("cycle.continuation", f"must be true or false, got "
                                                             f"{continuation!r}"))
        errors.raise_any()
        assert state is not None and period is not None
        return CycleSpec(state, period, shifted or [], monodromy, samples, modes or 0, keep or [],
                         bool(continuation), starts or [])

    def check(self, description: dict[str, Any], errors: Collector) -> None:
        """Against the FMU: through Model Exchange, the states named are its continuous
        states, directional derivatives where the variational monodromy is asked for;
        through the start values, the FMU's sensitivities cover them and the closing
        variables named."""
        by_name = {v["name"]: v for v in description["variables"]}
        if self.starts:
            self._check_starts(description, by_name, errors)
        elif not description.get("has_model_exchange"):
            errors.run(lambda: refuse("cycle", "the steady cycle is found by integrating the "
                                                "FMU's Model Exchange interface, which this FMU "
                                                "does not have"))
            return
        else:
            states = _states(description)
            for where, name in [("cycle.state", self.state)] + [
                    (f"cycle.shifted[{k}]", n) for k, n in enumerate(self.shifted)]:
                errors.run(lambda: _a_state(name, where, states, by_name))
        for k, name in enumerate(self.shifted):
            if name == self.state or name in self.shifted[:k]:
                errors.run(lambda: refuse(f"cycle.shifted[{k}]", f"{name!r} is named twice"))
        for k, name in enumerate(self.keep):
            v = by_name.get(name)
            if v is None or v["type"] != "real":
                rule = (f"the FMU has no variable {name!r}{did_you_mean(name, by_name)}"
                        if v is None else f"{name} is of type {v['type']}; a cycle keeps Real "
                                          "variables")
                errors.run(lambda: refuse(f"cycle.keep[{k}]", rule))
        if self.monodromy == "variational" and not self.starts and not description.get(
                "exchange_directional_derivatives"):
            errors.run(lambda: refuse("cycle.monodromy", "\"variational\" needs the FMU's "
                                       "directional derivatives under Model Exchange, which it "
                                       "does not give"))

    def _check_starts(self, description: dict[str, Any], by_name: dict[str, Any],
                      errors: Collector) -> None:
        """The Co-Simulation path's fields against the FMU's offer of sensitivities."""
        offer = read_offer(description)
        if description.get("model_identifier") is None:
            errors.run(lambda: refuse("cycle.starts", "the cycle through the start values runs "
                                                       "the FMU's Co-Simulation interface, which "
                                                       "this FMU does not have"))
            return
        if offer is None:
            errors.run(lambda: refuse("cycle.starts", "the FMU offers no sensitivities "
                                                       "(sensitivity_<k>.parameter slots): the "
                                                       "cycle through the start values needs "
                                                       "them; leave `starts` out to shoot on "
                                                       "Model Exchange"))
            return
        if not description.get("max_output_derivative_order"):
            errors.run(lambda: refuse("cycle.starts", "the cycle through the start values reads "
                                                       "the closing outputs' rates at its end "
                                                       "(output derivatives), which this FMU does "
                                                       "not give"))
        if self.monodromy is not None:
            errors.run(lambda: refuse("cycle.monodromy", "through the start values the "
                                                          "monodromy comes from the FMU's own "
                                                          "sensitivities"))
        for k, name in enumerate(self.starts):
            if name not in offer.items:
                errors.run(lambda: refuse(f"cycle.starts[{k}]", f"the FMU offers no sensitivity "
                                          f"to {name!r}{did_you_mean(name, offer.items)} (it "
                                          f"offers: {', '.join(sorted(offer.items))})"))
            elif name in self.starts[:k]:
                errors.run(lambda: refuse(f"cycle.starts[{k}]", f"{name!r} is named twice"))
        if len(self.starts) > offer.slots:
            errors.run(lambda: refuse("cycle.starts", f"{len(self.starts)} start values, but "
                                                       f"the FMU has {offer.slots} sensitivity "
                                                       f"slots"))
        states = _states(description) if description.get("has_model_exchange") else []
        if states and len(self.starts) != len(states) - 1:
            errors.run(lambda: refuse("cycle.starts", f"the state on the section has "
                                                       f"{len(states) - 1} free coordinates (the "
                                                       f"FMU's {len(states)} continuous states "
                                                       f"less the cyclic one): name as many "
                                                       f"start values, not {len(self.starts)}"))
        closing = _closing(description, offer)
        for where, name in [("cycle.state", self.state)] + [
                (f"cycle.shifted[{k}]", n) for k, n in enumerate(self.shifted)]:
            if name not in by_name:
                errors.run(lambda: refuse(where, f"the FMU has no variable {name!r}"
                                                 f"{did_you_mean(name, by_name)}"))
            elif name not in closing:
                errors.run(lambda: refuse(where, f"{name} is not among the outputs whose "
                                                 f"sensitivities the FMU gives (those that close "
                                                 f"the cycle: {', '.join(closing) or 'none'})"))
        if self.modes and not (description.get("has_model_exchange")
                               and description.get("exchange_directional_derivatives")):
            errors.run(lambda: refuse("cycle.modes", "the modes along the cycle linearise the "
                                                      "state equations on the FMU's Model "
                                                      "Exchange interface, whose directional "
                                                      "derivatives this FMU does not give"))

    def plan(self, metrics: list[tuple[str, str, int | None]],
             description: dict[str, Any]) -> CyclePlan:
        """The runner's plan, with the metrics (variable, kind, order) over one cycle; the
        Co-Simulation path's start values, slots and closing variables from the FMU's
        offer of sensitivities (its `description`)."""
        starts = None
        offer = read_offer(description) if self.starts else None
        if offer is not None:
            closing = _closing(description, offer)
            # A name the FMU does not offer is refused by check(), which reports it with the
            # other mistakes; its slot stays `none` meanwhile.
            starts = {"parameters": self.starts,
                      "slots": [(slot_parameter(k + 1), offer.items.get(name, 0))
                                for k, name in enumerate(self.starts)],
                      "closing": closing,
                      "columns": [[slot_variable(k + 1, c) for c in closing]
                                  for k in range(len(self.starts))]}
        return {"state": self.state, "period": self.period, "shifted": self.shifted,
                "metrics": [{"variable": v, "kind": k, "order": o} for v, k, o in metrics],
                "samples": self.samples, "monodromy": self.monodromy, "modes": self.modes,
                "keep": self.keep, "continuation": self.continuation, "starts": starts}


def _states(description: dict[str, Any]) -> list[str]:
    """The FMU's continuous states' names, in Model Exchange's order."""
    names = {v["value_reference"]: v["name"] for v in reversed(description["variables"])}
    return [names.get(s["value_reference"], "?") for s in description.get("states", [])]


def _closing(description: dict[str, Any], offer: Offer) -> list[str]:
    """The Real outputs every sensitivity slot covers: the variables whose return closes a
    cycle through the start values, in the description's order."""
    return [v["name"] for v in description["variables"]
            if v["causality"] == "output" and v["type"] == "real" and offer.covers(v["name"])]


def _name(value: object, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise SpecError(where, "must name a continuous state of the FMU" if value is None
                        else f"must be a variable's name, got {value!r}")
    return value


def _names(value: object, where: str) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise SpecError(where, f"must be a list of variable names, got {value!r}")
    return list(value)


def _period(value: object) -> float:
    period = number(value, "cycle.period")
    if period <= 0:
        raise SpecError("cycle.period", f"must be > 0 (the cyclic state's advance over one "
                                        f"cycle, such as 2π for a revolution), got {period}")
    return period


def _a_state(name: str, where: str, states: list[str], by_name: dict[str, Any]) -> None:
    if name not in by_name:
        raise SpecError(where, f"the FMU has no variable {name!r}{did_you_mean(name, by_name)}")
    if name not in states:
        raise SpecError(where, f"{name} is not a continuous state of the FMU (its states: "
                               f"{', '.join(states) or 'none'})")


def cycle_columns(results: list[PointResult]) -> dict[str, pa.Array]:
    """Each point's cycle: its period, its largest Floquet multiplier's modulus and the
    states its mode moves most (``omega4 94%, loop_speed 5%``), the verdict and the margin to the unit circle, the periodicity residual, the Newton
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
            "cycle_stability": column("stability", pa.string()),
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
    a: npt.NDArray[np.float64]
    b: npt.NDArray[np.float64]
    c: npt.NDArray[np.float64]
    d: npt.NDArray[np.float64]
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
    row = [[float((parameters or {})[n]) for n in names]]
    plan: Plan = {"start": 0.0, "stop": 1.0, "step": 1.0, "tolerance": None, "fixed": {},
                  "inputs": {}, "metrics": [], "series": None, "timeout_s": None,
                  "interface": "model_exchange"}
    if along is None:
        runner.configure(plan)
        found = runner.linearise(names, row)[0]
        if found["status"] != "ok":
            raise RunnerError(found["message"])
        return _linearisation(found["linearisation"])
    cycle = _cycle_to_linearise(along, runner.describe())
    plan["stop"], plan["step"] = float(along.get("stop", 400.0)), float(along.get("step", 0.01))
    plan["tolerance"] = float(along.get("tolerance", 1e-9))
    plan["cycle"] = cycle
    plan["interface"] = "co_simulation" if cycle["starts"] else "model_exchange"
    runner.configure(plan)
    result = runner.run(names, row)[0]
    found_cycle = result.get("cycle")
    if result["status"] != "ok" or found_cycle is None:
        raise RunnerError(f"{result['status']}: {result['message']}")
    return [_linearisation(lin) for lin in found_cycle["linearisations"]]


def _cycle_to_linearise(along: dict[str, Any], description: dict[str, Any]) -> dict[str, Any]:
    """The runner's cycle plan for linearisations along a steady cycle: `along` is a
    ``[cycle]`` table (with ``stop``, ``step`` and ``tolerance`` of the search beside it),
    every mistake refused at once."""
    table = {k: v for k, v in along.items() if k not in ("stop", "step", "tolerance")}
    spec = CycleSpec.of({"cycle": table})
    assert spec is not None
    errors = Collector()
    if spec.modes < 1:
        errors.run(lambda: refuse("cycle.modes", "the number of points along the cycle to "
                                                  "linearise at, at least 1"))
    spec.check(description, errors)
    errors.raise_any()
    return {**spec.plan([], description), "linearise": True}


def _linearisation(lin: dict[str, Any]) -> Linearisation:
    n, m, p = len(lin["states"]), len(lin["inputs"]), len(lin["outputs"])

    def matrix(key: str, rows: int, columns: int) -> npt.NDArray[np.float64]:
        return np.asarray(lin[key], dtype=float).reshape(rows, columns)

    return Linearisation(lin["states"], lin["inputs"], lin["outputs"], matrix("a", n, n),
                         matrix("b", n, m), matrix("c", p, n), matrix("d", p, m),
                         [mode["frequency"] for mode in lin["modes"]],
                         [mode["damping"] for mode in lin["modes"]], float(lin["t"]),
                         [float(v) for v in lin["x"]])
