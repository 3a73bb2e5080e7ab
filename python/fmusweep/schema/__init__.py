"""The declared schema of every specification: each table's fields, their types, units,
defaults and ranges, and the rules between them, from which the specs are read (every
mistake in one pass, ``core.read``) and the docs' field tables are drawn (``docs``)."""

from .core import Loc, Parts, Reading, Table, absent, at, field, read

__all__ = ["Loc", "Parts", "Reading", "Table", "absent", "at", "field", "read"]
