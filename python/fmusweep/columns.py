"""The names of the columns a study writes of its own, beside the ones a spec names (a
sweep's design parameters and metrics, a fit's parameters): a name a spec gives that is one
of these, or another of the spec's own, would put two things in one column, so the
specification refuses it (docs/sweeps.md and docs/fitting.md list them)."""

from __future__ import annotations

from collections.abc import Iterable

from .errors import Collector, SpecError

__all__ = ["SWEEP_COLUMNS", "FIT_COLUMNS", "COUPLING_COLUMNS", "SERIES_COLUMNS",
           "refuse_collisions"]

# Of a coupled system with a coupling tolerance (``store.coupling_columns``).
COUPLING_COLUMNS = ("coupling_error", "coupling_steps", "coupling_rejected",
                    "coupling_min_step")
# Of the series' long table (``series/``), which a reader joins with the points on
# ``point``.
SERIES_COLUMNS = ("point", "variable", "time", "value")
# Of a sweep's points.parquet, in the order written.
SWEEP_COLUMNS = ("point", "point_id", "status", "message", "t_end", "steps", "events",
                 "wall_s", "worker") + COUPLING_COLUMNS
# Of a fit's points.parquet.
FIT_COLUMNS = ("point", "point_id", "experiment", "status", "message", "cost", "start",
               "role", "t_end", "steps", "wall_s", "worker") + COUPLING_COLUMNS


def refuse_collisions(named: Iterable[tuple[str, str, str]], reserved: Iterable[str],
                      errors: Collector) -> None:
    """Each (name, field, what) of `named` in order: refused by its field when the study
    writes a column of that name itself, or when an earlier entry took the name already."""
    own = set(reserved)
    taken: dict[str, str] = {}
    for name, field, what in named:
        if name in own:
            errors.run(lambda: _refuse(field, f"{what} {name!r} is a column the results hold "
                                              f"already ({', '.join(sorted(own))} are taken)"))
        elif name in taken:
            errors.run(lambda: _refuse(field, f"{what} {name!r} is also {taken[name]}: the two "
                                              "would share one column of the results"))
        else:
            taken[name] = field


def _refuse(field: str, rule: str) -> None:
    raise SpecError(field, f"{rule}; choose another name")
