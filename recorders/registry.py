"""Which converter handles which (sensor family, format): a plain typed mapping."""

from __future__ import annotations

import importlib

from . import csvlog
from .base import Converter
from .manifest import SENSORS

# sensor family -> module with a CONVERTERS mapping
FAMILY_MODULES: dict[str, str] = {
    "gps": "recorders.gps",
    "ins": "recorders.ins",
    "dvl": "recorders.dvl",
    "modem": "recorders.modem",
    "usbl": "recorders.usbl",
}


def converters() -> dict[tuple[str, str], Converter]:
    """Every (sensor, format) -> converter, the csv mapping included for every family."""
    table: dict[tuple[str, str], Converter] = {}
    for family in SENSORS:
        module = importlib.import_module(FAMILY_MODULES[family])
        for fmt, fn in module.CONVERTERS.items():
            table[(family, fmt)] = fn
        table[(family, "csv")] = csvlog.converter_for(family)
    return table


def describe(fn: Converter) -> str:
    """First line of a converter's docstring."""
    return (fn.__doc__ or "").strip().splitlines()[0] if fn.__doc__ else ""
