"""Columns of a review table built as pandas would infer them from a list, without its inference per element.

The review's tables are kept as lists per column (`replay.review.collector`, `replay.review.track_table`);
a frame built from them column by column gets the same dtypes and bits as one built from the rows.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

_FLOATS = frozenset({float, np.float64})
_STR = pd.Series(["a"]).dtype     # the dtype pandas infers for strings (pyarrow's large strings, NaN missing)


def column(values: Sequence[Any]) -> Any:
    """One table column for a frame: plain floats, bools or ints as the numpy array pandas would infer from the
    list (the same dtype and bits, without its inference per element); anything else as the list."""
    kinds = set(map(type, values))
    if kinds and kinds <= _FLOATS:
        return np.array(values, dtype=np.float64)
    if kinds == {bool}:
        return np.array(values, dtype=bool)
    if kinds == {int}:
        return np.array(values, dtype=np.int64)
    if kinds == {str}:
        return strings(values)
    return list(values)


def strings(values: Sequence[str]) -> Any:
    """A column of strings as pandas infers it (its "str" dtype), built by pyarrow at once: pandas checks and
    converts the list row by row. One of few distinct values (names of vehicles, methods, sources) is taken from
    its distinct values. Without pyarrow storage, the list as it is."""
    if getattr(_STR, "storage", None) != "pyarrow":
        return list(values)
    import pyarrow as pa

    distinct = dict.fromkeys(values)
    try:
        if len(distinct) * 8 > len(values):
            arr = pa.array(values, type=pa.large_string())
        else:
            code = {v: i for i, v in enumerate(distinct)}
            codes = np.fromiter(map(code.__getitem__, values), dtype=np.int64, count=len(values))
            arr = pa.array(list(distinct), type=pa.large_string()).take(pa.array(codes))
    except (UnicodeError, pa.ArrowException):      # a lone surrogate (a damaged name): pandas decides, as before
        return list(values)
    return pd.arrays.ArrowStringArray(arr, dtype=_STR)
