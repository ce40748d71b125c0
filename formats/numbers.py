"""The rule for numbers written as text, for every text decoder: finite, and of a size a field can hold.

Python's `float` reads "nan", "inf", "Infinity" and "1e400" (infinity) as
numbers, and `int` reads a 400-digit integer; a checksum only proves a line
is what someone wrote. A decoder that reads a number field through
`finite` or `integer` gets a ValueError naming the field and the text for
any of those, which it turns into a counted Reject like any other bad
field; a value that is NaN in a decoded record therefore only ever means
"not given" (an empty field). What is physically possible for each field
(a latitude within ±90°, a range above 0) is a record-time rule, written in
`recorders.value_checks`.

`texts_finite` is the column form of `finite` for the whole-log fast paths:
True only when `finite` would accept every string, else the caller leaves
the log to its per-line path, which words the reject.
"""

from __future__ import annotations

import math
from collections.abc import Collection

import numpy as np

MAX_INT_DIGITS = 18  # an int64 holds every integer of 18 digits; a field of more is no field of ours
_FLOAT_MAX_CHARS = 300  # below this many characters, a number without an exponent cannot overflow a double

# a byte's value as a hexadecimal digit (either case), -1 for any other byte: checksums read as columns
HEX_VALUE = np.full(256, -1, dtype=np.int64)
HEX_VALUE[np.frombuffer(b"0123456789abcdef", dtype=np.uint8)] = np.arange(16)
HEX_VALUE[np.frombuffer(b"ABCDEF", dtype=np.uint8)] = np.arange(10, 16)
HEX_VALUE.setflags(write=False)


def finite(text: str, name: str = "field") -> float:
    """float(text) when it is a finite number; ValueError naming `name` for "nan", "inf", "1e400" or no number."""
    value = float(text)
    if value - value != 0.0:  # infinite or NaN: one subtraction, cheaper than math.isfinite's call
        raise ValueError(f"{name} is not finite: {text[:40]!r}")
    return value


def optional(text: str, name: str = "field") -> float:
    """`finite`, with an empty field NaN (not given)."""
    if not text:
        return math.nan
    value = float(text)  # `finite` inline: this is the per-field call of every NMEA sentence
    if value - value != 0.0:
        raise ValueError(f"{name} is not finite: {text[:40]!r}")
    return value


def integer(text: str, name: str = "field", base: int = 10) -> int:
    """int(text, base) of at most MAX_INT_DIGITS digits; ValueError naming `name` for any other text."""
    if len(text) > MAX_INT_DIGITS and len(text.strip().lstrip("+-")) > MAX_INT_DIGITS:  # the short text at once
        raise ValueError(f"{name} has more than {MAX_INT_DIGITS} digits: {text[:40]!r}")
    return int(text, base)


def optional_integer(text: str, name: str = "field", empty: int = -1) -> int:
    """`integer`, with an empty field `empty` (not given)."""
    if not text:
        return empty
    return int(text) if len(text) <= MAX_INT_DIGITS else integer(text, name)  # a count field: one call, inline


def texts_integer(texts: Collection[str]) -> bool:
    """Whether no string of `texts` is longer than `integer` takes (the column form of its digit limit)."""
    return max(map(len, texts), default=0) <= MAX_INT_DIGITS


def texts_finite(texts: Collection[str]) -> bool:
    """Whether `finite` accepts every non-empty string of `texts` that float() reads, told from the text alone.

    Conservative: False for any spelling of NaN or infinity (they all hold an 'n'), an exponent, or a string
    long enough to overflow; the per-line path then decides those one by one.
    """
    joined = "".join(texts)
    return not any(c in joined for c in "nNeE") and max(map(len, texts), default=0) < _FLOAT_MAX_CHARS
