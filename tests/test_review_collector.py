"""The review collector's tracks table: rows collected one by one or by block, east/north over the column at the end."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.engine.layout import TrialLayout
from replay.events import Fix
from replay.review.collector import RAD, ReviewCollector
from replay.stack.model import horizontal_offset_m

ORIGIN = (math.radians(45.2), math.radians(-70.1))


def _collector() -> ReviewCollector:
    return ReviewCollector("r1", {"name": "t"}, 0, TrialLayout(roles={"auv1": "follower"}, topics={}))


@settings(max_examples=20, deadline=None)
@given(st.lists(st.tuples(st.floats(-2e-4, 2e-4), st.floats(-2e-4, 2e-4)), min_size=1, max_size=40),
       st.integers(0, 3))
def test_tracks_east_north_are_those_of_each_row_alone(offsets: list[tuple[float, float]], before: int) -> None:
    c = _collector()
    lat = [ORIGIN[0] + d for d, _ in offsets]
    lon = [ORIGIN[1] + d for _, d in offsets]
    # rows before the origin is known have no east/north; after it, each row's as horizontal_offset_m gives it
    for k in range(min(before, len(lat))):
        c.position("auv1", "gps", Fix(float(k), lat[k], lon[k]))
    c.origin(*ORIGIN)
    for k in range(min(before, len(lat)), len(lat)):
        c.position("auv1", "gps", Fix(float(k), lat[k], lon[k]))
    t = np.arange(len(lat), dtype=float) + 100.0
    c.positions("auv1", "gps", t, np.array(lat), np.array(lon), np.zeros(len(lat)))
    tracks = c.table("tracks")
    assert tracks is not None and len(tracks) == 2 * len(lat)
    for i, row in enumerate(tracks.itertuples()):
        k = i % len(lat)
        if i < before and i < len(lat):
            assert math.isnan(row.east_m) and math.isnan(row.north_m)
            continue
        n, e = horizontal_offset_m(lat[k], lon[k], *ORIGIN)
        assert (row.east_m, row.north_m) == (float(e), float(n))       # bit for bit
        assert (row.lat_deg, row.lon_deg) == (lat[k] * RAD, lon[k] * RAD)
    # a later slice (what a streamed stretch takes) holds the same rows
    tail = c.table("tracks", len(lat))
    assert tail is not None and tail.reset_index(drop=True).equals(tracks.iloc[len(lat):].reset_index(drop=True))
    assert c.table("tracks", 2 * len(lat)) is None and c.count("tracks") == 2 * len(lat)
