"""The FMU's own parameter sensitivities, where it offers them: a fit's Jacobian from one
run instead of one run per parameter.

An FMU offers them by a convention its model description shows (the mechanism's FMU
follows it; docs/sensitivities.md): Enumeration parameters ``sensitivity_<k>.parameter``,
k = 1, 2, …, whose items name the parameters a slot can follow, and Real variables
``sensitivity_<k>.<variable>`` that hold ∂variable/∂(slot k's parameter) along the run.
Nothing here knows which FMU it reads."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Offer", "read_offer", "slot_parameter", "slot_variable"]


def slot_parameter(slot: int) -> str:
    """The parameter that chooses what slot `slot` (1-based) follows."""
    return f"sensitivity_{slot}.parameter"


def slot_variable(slot: int, variable: str) -> str:
    """The variable that holds ∂`variable`/∂(slot `slot`'s parameter)."""
    return f"sensitivity_{slot}.{variable}"


@dataclass(frozen=True)
class Offer:
    """What an FMU offers: its number of slots, the value that selects each parameter a
    slot can follow, and the names of its sensitivity variables."""
    slots: int
    items: dict[str, int]
    variables: frozenset[str]

    def covers(self, variable: str) -> bool:
        """Whether every slot has ∂`variable`/∂p."""
        return all(slot_variable(k, variable) in self.variables for k in range(1, self.slots + 1))


def read_offer(description: dict[str, Any]) -> Offer | None:
    """The sensitivities an FMU offers, from its description (the runner's reading of its
    modelDescription.xml, each Enumeration with its items); None where it has no slot."""
    by_name = {v["name"]: v for v in description.get("variables", [])}
    slots, items = 0, dict[str, int]()
    while (slot := by_name.get(slot_parameter(slots + 1))) is not None:
        found = {str(name): int(value) for name, value in (slot.get("items") or {}).items()}
        if not found:
            break
        if slots and found != items:
            break  # every slot must offer the same parameters
        items = found
        slots += 1
    if not slots:
        return None
    items = {name: value for name, value in items.items() if name != "none"}
    prefixes = tuple(f"sensitivity_{k}." for k in range(1, slots + 1))
    variables = frozenset(n for n in by_name if isinstance(n, str) and n.startswith(prefixes))
    return Offer(slots, items, variables)
