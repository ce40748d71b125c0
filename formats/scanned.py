"""Names for the values of scanned tuples: the hot paths' plain tuples hold a record's fields in field order.

A `scan` function yields, instead of a record, its field values as a tuple
or list (the fields after `where`, and after `header` for NovAtel). The
converters name them through the record class itself, so a field added to
or moved in a record moves its name with it:
`positions(UsblLong).address` is the index of `address` in a scanned
USBLLONG's values; `values_view(BestPos)._make(values)` names every value.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import fields
from types import SimpleNamespace
from typing import Any


def positions(record: type, skip: int = 1) -> Any:
    """Field name -> index among a record's scanned values (its fields after the first `skip`)."""
    return SimpleNamespace(**{f.name: i for i, f in enumerate(fields(record)[skip:])})


def values_view(record: type, skip: int = 2) -> Any:
    """A namedtuple type naming a record's scanned values (its fields after the first `skip`)."""
    return namedtuple(record.__name__ + "Values", [f.name for f in fields(record)[skip:]])
