"""The error every check of a sweep or its specification raises: it names the field and
the rule. A module of its own, so that the spec and the design both use it without
importing each other."""

from __future__ import annotations


class SpecError(ValueError):
    """A specification that cannot run; the message names the field and the rule."""

    def __init__(self, field_name: str, rule: str):
        super().__init__(f"{field_name}: {rule}")
        self.field = field_name
