"""Designs: the parameter points of a sweep. Each kind is one module here, with all that
kind is: the fields of its ``[design]`` table, whether it needs a seed, how its points are
made, and, for the kinds that give them, its indices and how they are drawn, as the
module's ``KIND``. ``KINDS`` finds them: a new kind is a new module here, nothing else.

- ``grid`` (``grid.py``): the full-factorial product of each parameter's values.
- ``list`` (``listed.py``): point i takes each parameter's i-th value.
- ``lhs`` (``lhs.py``): a seeded Latin hypercube over each parameter's range.
- ``sobol`` (``sobol.py``): Saltelli's design, and Sobol' indices of every metric.
- ``morris`` (``morris.py``): Morris' trajectories, and elementary effects of every metric.

A grid keeps only its axes and makes a point's values from its index when a batch needs
them, so that the client's memory does not grow with the number of points; the sampled
designs are held whole (their generators make them so).
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any

from ..errors import SpecErrors
from ..schema.core import read
from .base import KINDS as _KNOWN
from .base import Design, DesignKind, DesignTable, IndexChart

__all__ = ["Design", "DesignKind", "DesignTable", "IndexChart", "KINDS", "kind_of", "generate",
           "make"]



def _kinds() -> dict[str, DesignKind]:
    """The ``KIND`` of every module of this package, by name."""
    found: dict[str, DesignKind] = {}
    for module in sorted(m.name for m in pkgutil.iter_modules(__path__)):
        kind = getattr(importlib.import_module(f"{__name__}.{module}"), "KIND", None)
        if isinstance(kind, DesignKind):
            found[kind.name] = kind
    return found


# The one registry the [design] table reads its kind from (``base.KINDS``), filled here.
KINDS: dict[str, DesignKind] = _KNOWN
KINDS.update(_kinds())


def kind_of(name: str) -> DesignKind:
    """The kind a design names."""
    return KINDS[name]


def generate(kind: str, d: dict[str, Any], seed: int | None = None) -> Design:
    """The points of a `kind` design from its table `d` (``[design]``; `seed` over its own),
    every mistake of the table raised together."""
    raw = {**d, "kind": kind, **({"seed": seed} if seed is not None else {})}
    found = read(DesignTable, raw, ("design",))
    if found.errors:
        raise SpecErrors(found.errors) if len(found.errors) > 1 else found.errors[0]
    return make(found.value)


def make(table: DesignTable) -> Design:
    """The points of a design table read without mistakes."""
    return KINDS[table.kind].make(table, list(table.parameters))
