"""Record-time checks on every archive message: values in physical ranges, or a counted reject.

Text decoders refuse number text that is no finite number ("nan", "inf",
"1e400", 400 digits) themselves (`formats.numbers`); what they give is a
number, but a range of 0 m, -5 m or 1e12 m is a number too, and binary
formats carry IEEE infinities and NaNs as they are. So before a message is
archived its values are checked here against what is physically possible,
one rule per field, written once for every format: a value outside its
range (or NaN where it must be given) turns the message into a Reject with
the field, the value and the limit. NaN stays allowed where a field means
"not given". Ranges must be above 0 and at most the log's `max_range_m`
(default MAX_RANGE_M, configurable per log).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from operator import attrgetter
from typing import Any

import numpy as np

from formats.units import TIME_MAX_NS, TIME_MIN_NS, archivable_ns

MAX_RANGE_M = 20_000.0
RANGE_FIELDS = frozenset({"range_m"})
_ABOVE_ZERO = 1e-9  # ranges must be above 0: the closed interval's low end

# schema name -> (field, low, high, NaN allowed); the limits are physical, never tuned to a trial
_RULES: dict[str, tuple[tuple[str, float, float, bool], ...]] = {
    "foxglove.LocationFix": (
        ("latitude", -90.0, 90.0, False), ("longitude", -180.0, 180.0, False), ("altitude", -1e5, 1e6, True),
    ),
    "auvreplay.GnssStatus": (
        ("hdop", 0.0, 1e4, True), ("speed_over_ground_mps", 0.0, 3e3, True),
        ("course_over_ground_deg", -720.0, 720.0, True), ("heading_deg", -720.0, 720.0, True),
    ),
    "auvreplay.GnssVelocity": (
        ("velocity_north_mps", -3e3, 3e3, True), ("velocity_east_mps", -3e3, 3e3, True),
        ("velocity_up_mps", -3e3, 3e3, True), ("speed_over_ground_mps", 0.0, 3e3, True),
        ("course_over_ground_deg", -720.0, 720.0, True), ("speed_std_mps", 0.0, 1e4, True),
    ),
    "auvreplay.InsState": (
        ("latitude", -90.0, 90.0, True), ("longitude", -180.0, 180.0, True), ("depth_m", -1e5, 1.2e4, True),
        ("roll_deg", -720.0, 720.0, True), ("pitch_deg", -720.0, 720.0, True), ("heading_deg", -720.0, 720.0, True),
        ("velocity_north_mps", -3e3, 3e3, True), ("velocity_east_mps", -3e3, 3e3, True),
        ("velocity_down_mps", -3e3, 3e3, True), ("heading_std_deg", 0.0, 1e4, True),
        ("position_std_north_m", 0.0, 1e7, True), ("position_std_east_m", 0.0, 1e7, True),
        ("roll_std_deg", 0.0, 1e4, True), ("pitch_std_deg", 0.0, 1e4, True), ("altitude_m", -1e5, 1e6, True),
    ),
    "auvreplay.DvlVelocity": (
        ("velocity_x_mps", -100.0, 100.0, True), ("velocity_y_mps", -100.0, 100.0, True),
        ("velocity_z_mps", -100.0, 100.0, True), ("error_velocity_mps", -100.0, 100.0, True),
        ("altitude_m", 0.0, 1.2e4, True), ("figure_of_merit", -1e6, 1e6, True),
        ("sound_speed_mps", 0.0, 1e4, True), ("temperature_c", -100.0, 200.0, True),
    ),
    "auvreplay.AcousticRange": (
        ("travel_time_s", 0.0, 100.0, True), ("sound_speed_mps", 1000.0, 2000.0, True),
    ),
    "auvreplay.UsblObservation": (
        ("travel_time_s", 0.0, 100.0, True), ("bearing_deg", -720.0, 720.0, True),
        ("elevation_deg", -720.0, 720.0, True), ("phase_x_rad", -1e3, 1e3, True), ("phase_y_rad", -1e3, 1e3, True),
        ("relative_east_m", -1e6, 1e6, True), ("relative_north_m", -1e6, 1e6, True),
        ("relative_up_m", -1e6, 1e6, True), ("integrity", -1e9, 1e9, True), ("rssi_db", -1e4, 1e4, True),
    ),
}
# range fields: NaN allowed for a USBL fix by angles only, never for an acoustic range
_RANGE_NAN_OK = {"auvreplay.AcousticRange": False, "auvreplay.UsblObservation": True}


def _covariance(kind: int, cov: Any) -> str | None:
    """A LocationFix's covariance: finite (or NaN where not given), variances not negative."""
    if not kind:
        return None
    if len(cov) == 9 and cov[0] >= 0.0 and cov[4] >= 0.0 and cov[8] >= 0.0 and -math.inf < sum(cov) < math.inf:
        return None  # the usual case in one look: no infinity among them, variances not negative
    for i, v in enumerate(cov):
        if v in (math.inf, -math.inf) or (i % 4 == 0 and v < 0.0):
            return f"position_covariance[{i}] = {v:g} is not a variance"
    return None


def _position_pair(latitude: float, longitude: float) -> str | None:
    """An INS position is both coordinates or neither: one NaN beside a number is a field that did not parse."""
    if (latitude != latitude) != (longitude != longitude):
        return f"latitude {latitude:g} with longitude {longitude:g}"
    return None


def _covariance_rows(kind: np.ndarray, cov: np.ndarray) -> np.ndarray | None:
    """`_covariance` refusing, per row of columns: an infinity, or a negative variance (None unless `kind` is a
    value per row and `cov` an (n, k) array)."""
    if kind.ndim != 1 or cov.ndim != 2:
        return None
    with np.errstate(invalid="ignore"):
        return (kind != 0) & (np.isinf(cov).any(axis=1) | (cov[:, ::4] < 0.0).any(axis=1))


def _position_pair_rows(latitude: np.ndarray, longitude: np.ndarray) -> np.ndarray | None:
    """`_position_pair` refusing, per row of columns (None unless both are a value per row)."""
    if latitude.ndim != 1 or longitude.ndim != 1:
        return None
    return np.isnan(latitude) != np.isnan(longitude)


# schema name -> (the fields it reads, a rule over their values, the rule's refusals over columns as arrays):
# rules across fields, for a message and for columns (tests/test_record_batches.py holds the two forms together)
_EXTRA: dict[str, tuple[tuple[str, ...], Callable[..., str | None], Callable[..., np.ndarray | None]]] = {
    "foxglove.LocationFix": (("position_covariance_type", "position_covariance"), _covariance, _covariance_rows),
    "auvreplay.InsState": (("latitude", "longitude"), _position_pair, _position_pair_rows),
}
Extra = tuple[Callable[[Any], Any], tuple[str, ...], Callable[..., str | None], Callable[..., np.ndarray | None]] | None


class ValueChecks:
    """The checks of one log: its range limit, the rules by schema name, and counts of what they refused."""

    def __init__(self, max_range_m: float = MAX_RANGE_M):
        self.max_range_m = max_range_m
        self.bad_ranges = 0
        self.out_of_range = 0
        self._by_class: dict[type, tuple[tuple[tuple[str, float, float, bool], ...], Extra]] = {}

    def _rules(self, cls: type) -> tuple[tuple[tuple[str, float, float, bool], ...], Extra]:
        name = getattr(getattr(cls, "DESCRIPTOR", None), "full_name", "")  # JSON messages have no rules
        rules = _RULES.get(name, ())
        if name in _RANGE_NAN_OK:
            rules = (("range_m", _ABOVE_ZERO, self.max_range_m, _RANGE_NAN_OK[name]), *rules)
        extra: Extra = None
        if name in _EXTRA:
            fields, rule, rows_rule = _EXTRA[name]
            extra = (attrgetter(*fields), fields, rule, rows_rule)
        self._by_class[cls] = found = (rules, extra)
        return found

    def problem(self, message: Any, log_time_ns: int) -> str | None:
        """Why a message cannot be archived (field, value, limits), or None when every value is in range."""
        if not archivable_ns(log_time_ns):  # anything else is a parse of garbage
            self.out_of_range += 1
            return f"time {log_time_ns} ns is outside 1970-2200"
        cls = type(message)
        found = self._by_class.get(cls)
        rules, extra = found if found is not None else self._rules(cls)
        for name, low, high, nan_ok in rules:
            v = getattr(message, name)
            if low <= v <= high:
                continue
            if v != v and nan_ok:
                continue
            self.out_of_range += 1
            if name in RANGE_FIELDS:
                self.bad_ranges += 1
                if v == 0.0 or (v == v and v < 0.0):
                    return f"range {v:g} m is not above 0"
                if math.isfinite(v):
                    return f"range {v:g} m is beyond max_range_m = {high:g}"
            return f"{name} = {v:g} is outside [{low:g}, {high:g}]" if v == v else f"{name} is NaN"
        if extra is not None:
            why = extra[2](*extra[0](message))
            if why is not None:
                self.out_of_range += 1
                return why
        return None

    def refused_rows(self, cls: type, n: int, columns: Mapping[str, Any], log_times_ns: np.ndarray) -> np.ndarray:
        """Per row of a block given as columns (`formats.proto_encode.encode_columns`' columns), whether `problem`
        would refuse its message: the same table and rules, over columns. A field not given is its default 0.

        Nothing is counted here: a refused row's message goes through `problem`, which counts it and says why.
        """
        t = np.asarray(log_times_ns, dtype=np.int64)
        bad = (t < TIME_MIN_NS) | (t >= TIME_MAX_NS)
        found = self._by_class.get(cls)
        rules, extra = found if found is not None else self._rules(cls)
        with np.errstate(invalid="ignore"):
            for name, low, high, nan_ok in rules:
                v = np.broadcast_to(np.asarray(columns.get(name, 0.0), dtype=np.float64), (n,))
                inside = (v >= low) & (v <= high)
                bad |= ~(inside | np.isnan(v)) if nan_ok else ~inside
        if extra is not None:
            _, fields, rule, rows_rule = extra
            arrays = [columns.get(f) for f in fields]
            if all(type(a) is np.ndarray and len(a) == n and a.dtype.kind in "fiu" for a in arrays):
                refused = rows_rule(*(np.asarray(a, dtype=np.float64) for a in arrays))  # a value per row each
                if refused is not None:
                    return bad | refused
            values = [_rows(columns.get(f, 0), n) for f in fields]
            bad |= np.fromiter((rule(*row) is not None for row in zip(*values)), dtype=bool, count=n)
        return bad


def _rows(values: Any, n: int) -> list:
    """A column's values row by row as Python values (an (n, k) array's rows as lists), for a rule over fields:
    an array or a list is a value per row, anything else one value for every row."""
    if isinstance(values, np.ndarray) and values.ndim:
        return values.tolist()
    return values if isinstance(values, list) else [values] * n
