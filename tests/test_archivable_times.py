"""One rule for which times are archived (1970 <= t < 2200): every message builder applies it the same way."""

from __future__ import annotations

import math

from hypothesis import example, given, settings
from hypothesis import strategies as st

from formats import acoustic_messages as AM
from formats import schemas as S
from formats.units import NS, TIME_MAX_NS, TIME_MIN_NS, archivable_ns
from recorders import dvl
from recorders.base import LogContext
from recorders.value_checks import ValueChecks

NAN = math.nan


def _built(t_ns: int) -> list:
    """One message of each builder that sets a time, fast (wire bytes) and keyword-constructed alike."""
    return [
        S.location_fix(t_ns, "a", 45.0, 126.0),
        S.ins_state(t_ns, "a", "src", "ok", *([0.0] * 15)),
        S.gnss_status(t_ns, "a", 1, 9, 0.9, "src", NAN, NAN, NAN),
        AM.acoustic_range(t_ns, "a", "b", 1, 2, 0.4, 600.0, 1500.0, "ping", "src"),
        AM.usbl_observation(t_ns, "a", "b", "src", *([0.0] * 11)),
        dvl.message(LogContext("a"), t_ns, "BODY_FRD", (0.0, 0.0, 0.0)),
        S.DvlVelocity(timestamp=S.timestamp(t_ns)),
    ]


def test_the_bounds_are_1970_and_2200() -> None:
    assert (TIME_MIN_NS, TIME_MAX_NS) == (0, 7_258_118_400 * NS)  # calendar.timegm((2200, 1, 1, 0, 0, 0))
    assert archivable_ns(0) and archivable_ns(TIME_MAX_NS - 1)
    assert not archivable_ns(-1) and not archivable_ns(TIME_MAX_NS) and not archivable_ns(10**400)


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.integers(TIME_MIN_NS - 10 * NS, TIME_MAX_NS + 10 * NS), st.integers(-(10**30), 10**30)))
@example(TIME_MAX_NS - 1)
@example(TIME_MAX_NS)
@example(-1)
@example(10**400)
def test_every_builder_sets_an_archivable_time_and_leaves_any_other_unset(t_ns: int) -> None:
    for msg in _built(t_ns):
        if archivable_ns(t_ns):
            assert S.to_ns(msg.timestamp) == t_ns
        else:
            assert not msg.HasField("timestamp"), type(msg).__name__
    assert (ValueChecks().problem(_built(t_ns)[0], t_ns) is None) == archivable_ns(t_ns)
