"""Review table columns built by replay.review.track_table equal what pandas infers from the plain lists."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.review.columns import column
from replay.review.track_table import TrackTable

NAMES = st.sampled_from(["auv1", "auv2", "ckf", "ackf", "gps", "dead_reckoning", ""])
VALUES = st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=1, max_size=60),
    st.lists(st.booleans(), min_size=1, max_size=60),
    st.lists(st.integers(-2**40, 2**40), min_size=1, max_size=60),
    st.lists(NAMES, min_size=1, max_size=60),
    st.lists(st.text(max_size=8), min_size=1, max_size=60),
    st.lists(st.one_of(st.floats(allow_nan=False), st.integers(-5, 5), st.none()), min_size=1, max_size=20),
)


def _same(a: pd.Series, b: pd.Series) -> None:
    assert a.dtype == b.dtype and len(a) == len(b)
    if a.dtype.kind == "f":
        np.testing.assert_array_equal(a.to_numpy().view(np.int64), b.to_numpy().view(np.int64))   # bit for bit
    else:
        assert a.equals(b)
        assert [type(x) for x in a.tolist()] == [type(x) for x in b.tolist()]


@settings(max_examples=150, deadline=None)
@given(VALUES)
def test_a_column_is_what_pandas_infers_from_the_list(values: list[object]) -> None:
    _same(pd.DataFrame({"c": column(values)})["c"], pd.DataFrame({"c": values})["c"])


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(NAMES, st.floats(-1.0, 1.0), st.floats(-1e-3, 1e-3)), min_size=1, max_size=40))
def test_track_rows_and_a_later_slice(rows: list[tuple[str, float, float]]) -> None:
    t = TrackTable()
    t.add(0.0, "auv1", "gps", 0.1, 0.2)          # before the origin: no east/north
    t.set_origin(0.7, -1.2)
    for k, (name, var, d) in enumerate(rows):
        t.add_many([float(k)], "auv1", [name], [0.7 + d], [-1.2 - d], [var], [-var])
    whole = t.frame()
    assert whole is not None and len(whole) == len(rows) + 1
    assert math.isnan(whole.east_m[0]) and math.isnan(whole.std_east_m[0])
    for k, (_, var, _) in enumerate(rows, start=1):
        # sqrt(max(v, 0)) as one row at a time
        assert whole.std_east_m[k] == math.sqrt(max(var, 0.0)) and whole.std_north_m[k] == math.sqrt(max(-var, 0.0))
    tail = t.frame(1)
    assert tail is not None and tail.equals(whole.iloc[1:].reset_index(drop=True))
    assert t.frame(len(rows) + 1) is None


def test_a_string_pyarrow_refuses_is_left_to_pandas() -> None:
    values = ["a", "b\udc80"] * 10       # a lone surrogate: the list goes to pandas as it is
    out = column(values)
    assert isinstance(out, list) and out == values
