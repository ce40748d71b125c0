"""Which converter handles which (sensor family, format): a plain typed mapping."""

from __future__ import annotations

import importlib

from . import csvlog
from .base import BlockConverter, Converter, blockwise
from .manifest import SENSORS

# sensor family -> module with a CONVERTERS mapping
FAMILY_MODULES: dict[str, str] = {
    "gps": "recorders.gps",
    "ins": "recorders.ins",
    "dvl": "recorders.dvl",
    "modem": "recorders.modem",
    "usbl": "recorders.usbl",
}
# container format (one file, several sensors; manifest sensor "") -> module with a CONVERTERS mapping
CONTAINER_MODULES: dict[str, str] = {
    "rosbag": "recorders.rosbag",
    "alog": "recorders.alog",
    "mavlink": "recorders.mavlink",
}


def converters() -> dict[tuple[str, str], Converter]:
    """Every (sensor, format) -> converter, the csv mapping included for every family."""
    table: dict[tuple[str, str], Converter] = {}
    for family in SENSORS:
        module = importlib.import_module(FAMILY_MODULES[family])
        for fmt, fn in module.CONVERTERS.items():
            table[(family, fmt)] = fn
        table[(family, "csv")] = csvlog.converter_for(family)
    for fmt, name in CONTAINER_MODULES.items():
        table[("", fmt)] = importlib.import_module(name).CONVERTERS[fmt]
    return table


def block_converters() -> dict[tuple[str, str], BlockConverter]:
    """The (sensor, format)s whose converters also take the log in blocks (their modules' BLOCK_CONVERTERS, csv)."""
    table: dict[tuple[str, str], BlockConverter] = {}
    for family in SENSORS:
        module = importlib.import_module(FAMILY_MODULES[family])
        for fmt, fn in getattr(module, "BLOCK_CONVERTERS", {}).items():
            table[(family, fmt)] = fn
        table[(family, "csv")] = blockwise(csvlog.converter_for(family))
    for fmt, name in CONTAINER_MODULES.items():
        fn = getattr(importlib.import_module(name), "BLOCK_CONVERTERS", {}).get(fmt)
        if fn is not None:
            table[("", fmt)] = fn
    return table


def binary_formats() -> frozenset[tuple[str, str]]:
    """The (sensor, format)s whose logs are (or may be) binary: their modules' BINARY_FORMATS (csv never is)."""
    found: set[tuple[str, str]] = set()
    for family in SENSORS:
        module = importlib.import_module(FAMILY_MODULES[family])
        found.update((family, fmt) for fmt in getattr(module, "BINARY_FORMATS", ()))
    for fmt, name in CONTAINER_MODULES.items():
        if fmt in getattr(importlib.import_module(name), "BINARY_FORMATS", ()):
            found.add(("", fmt))
    return frozenset(found)


def is_binary(sensor: str, fmt: str) -> bool:
    """Whether a (sensor, format)'s log is (or may be) binary: read as bytes, never cut into lines or stamped."""
    return (sensor, fmt) in binary_formats()


def family_converter(sensor: str, fmt: str) -> Converter:
    """The converter of one sensor family's vendor format, for containers that carry such logs inside them."""
    return importlib.import_module(FAMILY_MODULES[sensor]).CONVERTERS[fmt]


def describe(fn: Converter) -> str:
    """First line of a converter's docstring."""
    return (fn.__doc__ or "").strip().splitlines()[0] if fn.__doc__ else ""


def manifest_examples() -> dict[str, str]:
    """A manifest `[[vehicles.logs]]` example for each container format (its module's MANIFEST_EXAMPLE)."""
    return {fmt: importlib.import_module(name).MANIFEST_EXAMPLE for fmt, name in CONTAINER_MODULES.items()}
