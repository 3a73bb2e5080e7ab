"""``list``: each parameter gives ``values``, all of one length; point i takes the i-th."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import SpecError
from .base import Design, DesignKind, per_column, values_of


def make(names: list[str], params: dict[str, Any], d: dict[str, Any],
         seed: int | None) -> Design:
    columns = per_column(names, lambda name: values_of(name, params[name]))
    lengths = {len(c) for c in columns}
    if len(lengths) != 1:
        raise SpecError("design.parameters",
                        f"a list design needs values of one length, got {sorted(lengths)}")
    return Design("list", names, stored=np.array(columns, dtype=float).T.copy())


KIND = DesignKind("list", frozenset(), needs_seed=False, make=make)
