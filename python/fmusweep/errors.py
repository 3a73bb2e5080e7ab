"""The error every check of a sweep or its specification raises: it names the field and
the rule. A module of its own, so that the spec and the design both use it without
importing each other."""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import Callable, TypeVar

T = TypeVar("T")


class SpecError(ValueError):
    """A specification that cannot run; the message names the field and the rule."""

    def __init__(self, field_name: str, rule: str):
        super().__init__(f"{field_name}: {rule}")
        self.field = field_name
        self.rule = rule


class Unread(SpecError):
    """A value a later check needs but which was not read, its own mistakes reported
    where it was read: stops that check, and is not reported again."""

    def __init__(self, field_name: str):
        super().__init__(field_name, "was not read")


def refuse(field_name: str, rule: str) -> None:
    """Raise the SpecError: for a check written as a lambda, which cannot raise."""
    raise SpecError(field_name, rule)


class SpecErrors(SpecError):
    """Several mistakes of one specification, found in one pass: each a SpecError (the
    first one's field is this error's field)."""

    def __init__(self, errors: list[SpecError]):
        lines = "\n".join(f"  {e}" for e in errors)
        ValueError.__init__(self, f"{len(errors)} problems:\n{lines}")
        self.field = errors[0].field
        self.errors = errors


class Collector:
    """Checks that do not depend on each other, run one after another; every SpecError
    they raise is kept, and :meth:`raise_any` raises them together."""

    def __init__(self) -> None:
        self.errors: list[SpecError] = []

    def run(self, check: Callable[[], T]) -> T | None:
        """check()'s result, or None after keeping the SpecError(s) it raised."""
        try:
            return check()
        except SpecErrors as e:
            self.errors.extend(e.errors)
        except SpecError as e:
            self.errors.append(e)
        return None

    def raise_any(self) -> None:
        if len(self.errors) == 1:
            raise self.errors[0]
        if self.errors:
            raise SpecErrors(self.errors)


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """", did you mean 'x'?" for the known name closest to a misspelt one, else "". In a
    coupled system a name given without its component ('k34') is told the one name that
    ends with it ('mechanism.k34'), or the choice when several components have it."""
    known = list(known)
    prefixed = sorted(k for k in known if "." not in name and k.endswith("." + name)
                      and "." not in k[:-len(name) - 1])
    if len(prefixed) == 1:
        return f"; did you mean {prefixed[0]!r}?"
    if prefixed:
        return "; did you mean one of " + ", ".join(repr(k) for k in prefixed) + "?"
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


class SpecWarning(UserWarning):
    """A specification that runs, but not quite as written may suggest (the message names
    the field)."""


class EngineError(RuntimeError):
    """The engine that places the points (a Dask cluster) could not start or be reached;
    the message says why and what to do."""


def refuse_in_spawned_child(call: str) -> None:
    """A script that starts a study without the ``__main__`` guard is run again by every
    worker process that multiprocessing spawns (it imports the script as ``__mp_main__``):
    there the call must not run a second study into the same folder."""
    import sys
    frame = sys._getframe(1)
    while frame is not None and not (frame.f_code.co_name == "<module>"
                                     and frame.f_globals.get("__name__") == "__mp_main__"):
        frame = frame.f_back  # type: ignore[assignment]
    if frame is not None:
        raise EngineError(
            f"{call} was called again while a worker process imported the script that calls "
            f"it: put the call under `if __name__ == \"__main__\":`, so that the workers "
            "Dask starts do not run it")
