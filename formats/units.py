"""Time units and the span of times an archive holds, written once for every layer.

Times are integer nanoseconds since the Unix epoch (UTC) everywhere. A time
outside 1970-01-01 .. 2200-01-01 is no time of a trial: it is a parse of
garbage (a 400-digit field, a corrupt RTC century), never archived, and a
protobuf Timestamp is never set from it (`formats.schemas.set_timestamp`).
"""

from __future__ import annotations

NS = 1_000_000_000
"""Nanoseconds per second."""
DAY_NS = 86_400 * NS
"""Nanoseconds per day (UTC days: no leap seconds)."""

TIME_MIN_NS = 0
"""1970-01-01T00:00Z, the earliest archivable time (inclusive)."""
TIME_MAX_NS = 7_258_118_400 * NS
"""2200-01-01T00:00Z, the end of archivable times (exclusive)."""


def archivable_ns(t_ns: int) -> bool:
    """True for a time a trial can have (1970 <= t < 2200); the one rule every converter and builder applies."""
    return TIME_MIN_NS <= t_ns < TIME_MAX_NS
